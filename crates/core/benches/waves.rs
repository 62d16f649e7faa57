//! Benchmarks of the wave and two-point code behind the console's sliders: one two-point fit, the 101-point
//! RMSE sweep, the vest field on a 121 x 121 grid, and the trial analysis of 1 s at 10 kHz.

#![allow(missing_docs)] // criterion_main! generates an undocumented `main`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_core::analysis::{Butterworth, analyze_trace};
use vestnav_core::twopoint::{TwoPointSetup, simulate, sweep};
use vestnav_core::vest::TactorMask;
use vestnav_core::wave::{DVec2, Skin, WaveSource, vest_sources};

fn two_point(c: &mut Criterion) {
    let setup = TwoPointSetup::THESIS;
    c.bench_function("two-point fit, d = 11 mm", |b| b.iter(|| simulate(&setup, black_box(11.0))));
    let d: Vec<f64> = (0..=100).map(f64::from).collect();
    c.bench_function("two-point RMSE sweep, 0..=100 mm", |b| b.iter(|| sweep(&setup, black_box(&d))));
}

fn vest_field(c: &mut Criterion) {
    let skin = Skin::MEASURED;
    let sources = vest_sources(TactorMask::CORNERS, 0.06, &WaveSource::measured(DVec2::ZERO));
    c.bench_function("vest peak field, 121 x 121, 4 tactors", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for j in 0..121 {
                for i in 0..121 {
                    let p = DVec2::new(f64::from(i) * 0.0025 - 0.15, f64::from(j) * 0.0025 - 0.15);
                    sum += skin.peak_amplitude_m_s2(black_box(&sources), p);
                }
            }
            sum
        });
    });
}

fn trial_analysis(c: &mut Criterion) {
    let fs = 10_000.0;
    let x: Vec<f64> =
        (0..10_000).map(|i| (2.0 * std::f64::consts::PI * 133.0 * f64::from(i) / fs).sin()).collect();
    let lp = Butterworth::lowpass(5, 400.0, fs).expect("valid design");
    c.bench_function("low-pass + analyse one 1 s trial at 10 kHz", |b| {
        b.iter(|| lp.filtfilt(black_box(&x)).and_then(|y| analyze_trace(&y, fs)));
    });
}

criterion_group!(benches, two_point, vest_field, trial_analysis);
criterion_main!(benches);
