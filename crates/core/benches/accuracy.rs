//! Benchmark of the receivers comparison at the console's cap: 86,400 fixes (24 h at 1 Hz) from each of
//! five receivers, against a reference. The station recomputes it at most once a second while receivers
//! are compared side by side (`station::receivers`).

#![allow(missing_docs)] // criterion_main! generates an undocumented `main`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_core::accuracy::{Receiver, Reference, Sample, compare};
use vestnav_core::geo::{Earth, LatLon};

fn receivers(n: usize, count: usize) -> Vec<Receiver> {
    (0..count)
        .map(|k| Receiver {
            name: format!("rx{k}"),
            samples: (0..n)
                .map(|i| {
                    let w = i as f64 * 0.001 + k as f64;
                    Sample::new(i as f64, LatLon::new(60.17 + 1e-5 * w.sin(), 24.94 + 1e-5 * w.cos()))
                })
                .collect(),
        })
        .collect()
}

fn compare_at_the_cap(c: &mut Criterion) {
    let rx = receivers(86_400, 5);
    let reference = Reference::typed(LatLon::new(60.17, 24.94), 0.02);
    let mut g = c.benchmark_group("receivers compared");
    g.sample_size(10);
    g.bench_function("5 x 86,400 fixes, WGS-84, with a reference", |b| {
        b.iter(|| compare(black_box(&rx), Some(&reference), 0.5, Earth::Wgs84));
    });
    g.finish();
}

criterion_group!(benches, compare_at_the_cap);
criterion_main!(benches);
