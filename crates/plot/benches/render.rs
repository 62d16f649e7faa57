//! Rendering speed: a 100k-point and a 1M-point trace on one 900x560 panel, and a 200x200 heatmap.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_plot::{Chart, Figure, Heatmap, Series};

fn trace(n: u32) -> Chart {
    let t: Vec<f64> = (0..n).map(|i| f64::from(i) * 1e-4).collect();
    let y: Vec<f64> = t.iter().map(|t| (t * 700.0).sin() * (-t).exp()).collect();
    Chart::new("trace").x_label("time [s]").y_label("a [m/s^2]").series(Series::line("a", t, y))
}

fn bench(c: &mut Criterion) {
    let small = Figure::single(trace(100_000));
    c.bench_function("line_100k_900x560", |b| b.iter(|| black_box(small.render_pixmap())));
    let big = Figure::single(trace(1_000_000));
    c.bench_function("line_1M_900x560", |b| b.iter(|| black_box(big.render_pixmap())));
    let n = 200;
    let values: Vec<f64> = (0..n * n).map(|i| (i as f64 * 0.001).sin()).collect();
    let heat =
        Figure::single(Heatmap::new("field", (0.0, 1.0), (0.0, 1.0), n, n, values).colorbar_label("v"));
    c.bench_function("heatmap_200x200_900x560", |b| b.iter(|| black_box(heat.render_pixmap())));
    c.bench_function("png_encode_900x560", |b| b.iter(|| black_box(small.render_png())));
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
