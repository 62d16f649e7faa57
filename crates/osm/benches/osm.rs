//! Benchmarks of the offline map on the Helsinki extract (tests/data/osm; © OpenStreetMap contributors,
//! ODbL): reading and indexing the extract, one ~1 km walk planned, one zoom-17 tile drawn (uncached).

#![allow(missing_docs)] // criterion_main! generates an undocumented `main`.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_core::geo::LatLon;
use vestnav_osm::{Extract, Profile, TileId, render_tile};

fn helsinki() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/osm/helsinki.osm.pbf")
}

fn load(c: &mut Criterion) {
    let path = helsinki();
    let mut g = c.benchmark_group("extract");
    g.sample_size(10);
    g.bench_function("read + index Helsinki (685 kB)", |b| {
        b.iter(|| Extract::read(black_box(&path)).unwrap());
    });
    g.finish();
}

fn plan(c: &mut Criterion) {
    let e = Extract::read(&helsinki()).unwrap();
    let (from, to) = (LatLon::new(60.1700, 24.9400), LatLon::new(60.1660, 24.9500));
    c.bench_function("plan ~1 km walk, shortest", |b| {
        b.iter(|| e.graph.plan(black_box(from), black_box(to), Profile::Shortest).unwrap());
    });
    c.bench_function("plan ~1 km walk, prefer footways", |b| {
        b.iter(|| e.graph.plan(black_box(from), black_box(to), Profile::PreferFootways).unwrap());
    });
}

fn tile(c: &mut Criterion) {
    let e = Extract::read(&helsinki()).unwrap();
    let centre = LatLon::new(60.1680, 24.9450);
    for z in [15, 17, 19] {
        let id = TileId::containing(centre, z).unwrap();
        c.bench_function(&format!("render one tile, zoom {z} (city centre)"), |b| {
            b.iter(|| render_tile(black_box(&e.map), id));
        });
    }
}

criterion_group!(benches, load, plan, tile);
criterion_main!(benches);
