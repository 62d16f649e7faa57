//! Criterion benchmarks of the tactor model: one 10 s simulation (summary only, and with traces) and a
//! 40-point damping sweep. Goals (issue 2): <= 5 ms per 10 s simulation, <= 0.1 s per sweep.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_core::sweep::{SweepOptions, sweep};
use vestnav_core::tactor::{Preset, SimOptions, TactorParams, simulate, simulate_summary};

fn bench_tactor(c: &mut Criterion) {
    let p = TactorParams::preset(Preset::ThesisSim);
    let o = SimOptions::default();
    c.bench_function("tactor 10 s summary", |b| b.iter(|| simulate_summary(black_box(&p), black_box(&o))));
    c.bench_function("tactor 10 s traces", |b| b.iter(|| simulate(black_box(&p), black_box(&o))));
    let mut group = c.benchmark_group("sweep");
    group.sample_size(20);
    let so = SweepOptions::default();
    group.bench_function("40-point sweep (2 s each)", |b| b.iter(|| sweep(black_box(&p), black_box(&so))));
    group.finish();
}

criterion_group!(benches, bench_tactor);
criterion_main!(benches);
