//! Tests of `analysis`.

use approx::assert_relative_eq;

use super::*;

/// Deterministic uniform noise in [-1, 1) (a 64-bit LCG), so the tests do not depend on a generator's
/// stream.
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

fn sine(f: f64, fs: f64, n: usize, amp: f64) -> Vec<f64> {
    (0..n).map(|i| amp * (2.0 * PI * f * i as f64 / fs).sin()).collect()
}

#[test]
fn spectrum_of_a_sine() {
    let rate = 1000.0;
    let x: Vec<f64> =
        (0..1000).map(|k| 2.5 * (std::f64::consts::TAU * 50.0 * f64::from(k) / rate).sin()).collect();
    let (f, a) = amplitude_spectrum(&x, rate);
    assert_relative_eq!(f[50], 50.0);
    assert_relative_eq!(a[50], 2.5, max_relative = 1e-9);
    assert_relative_eq!(spectrum_peak_hz(&x, rate).unwrap(), 50.0);
    assert!(spectrum_peak_hz(&x[..2], rate).is_none());
}

#[test]
fn peak_frequency_of_noisy_sine() {
    let fs = 10_000.0;
    for f in [133.0, 133.37, 92.9, 162.0] {
        let x: Vec<f64> =
            sine(f, fs, 10_000, 1.0).iter().zip(noise(10_000, 7)).map(|(s, e)| s + 0.3 * e).collect();
        let p = peak_frequency(&x, fs).unwrap();
        assert!((p.frequency_hz - f).abs() < 0.05, "{f} -> {}", p.frequency_hz);
        assert_relative_eq!(p.bin_width_hz, 1.0);
    }
    assert_eq!(peak_frequency(&[1.0; 64], fs), Err(AnalysisError::NoOscillation));
    assert!(matches!(peak_frequency(&[f64::NAN; 64], fs), Err(AnalysisError::NonFinite { index: 0 })));
}

#[test]
fn revolution_envelope_of_a_constant_speed_sinusoid_is_its_amplitude() {
    // theta = omega t at 133 Hz, y = 2 sin(theta + 0.3) + 0.5 sampled at 10 kHz: every revolution's half
    // peak-to-peak is 2 (within the sampling error 1 - cos(pi f / fs)); the offset cancels.
    let omega = std::f64::consts::TAU * 133.0;
    let t: Vec<f64> = (0..10_000).map(|k| f64::from(k) * 1e-4).collect();
    let theta: Vec<f64> = t.iter().map(|t| omega * t).collect();
    let y: Vec<f64> = theta.iter().map(|a| 2.0 * (a + 0.3).sin() + 0.5).collect();
    let env = revolution_envelope(&t, &theta, &y);
    assert_eq!(env.time_s.len(), 132, "133 Hz over 1 s: 132 whole revolutions after the first crossing");
    for v in &env.amplitude {
        assert_relative_eq!(*v, 2.0, max_relative = 3e-3);
    }
    // Mid times: revolution k spans [k/133, (k+1)/133] s.
    assert_relative_eq!(env.time_s[0], 0.5 / 133.0, epsilon = 1e-4);
    assert_relative_eq!(env.window_s, 1.0 / 133.0, max_relative = 1e-2);
    assert!(revolution_envelope(&t[..10], &theta[..10], &y[..10]).time_s.is_empty());
}

#[test]
fn overshoot_and_settling_of_known_envelope() {
    // Envelope E(t): linear rise to A(1+O) at t0, then A(1 + O exp(-(t-t0)/tau)).
    // Overshoot = 100 O %; 2 % settling where O exp(-(t-t0)/tau) = 0.02: t = t0 + tau ln(O/0.02).
    let (fs, f, a, o, t0, tau) = (10_000.0, 133.0, 0.9, 0.3, 0.2, 0.05);
    let x: Vec<f64> = (0..20_000)
        .map(|i| {
            let t = f64::from(i) / fs;
            let e = if t < t0 { a * (1.0 + o) * t / t0 } else { a * (1.0 + o * (-(t - t0) / tau).exp()) };
            e * (2.0 * PI * f * t).sin() + 0.05
        })
        .collect();
    let s = analyze_trace(&x, fs).unwrap();
    let expected_settling = t0 + tau * (o / 0.02f64).ln();
    let period = 1.0 / f;
    assert!((s.settling_time_s - expected_settling).abs() < period, "{}", s.settling_time_s);
    // The window straddling the peak averages it down by at most exp(-P/tau) of the excess.
    assert!(s.overshoot_pct <= 100.0 * o + 0.1 && s.overshoot_pct >= 100.0 * o * (-period / tau).exp() - 0.1);
    assert_relative_eq!(s.steady_amplitude, a, max_relative = 1e-3);
    assert!((s.peak_time_s - t0).abs() < period);
}

#[test]
fn t_test_matches_scipy() {
    // Expected values from scipy.stats.ttest_ind(a, b, equal_var=False / True), scipy 1.17.
    let a = [1.2, 1.5, 0.9, 1.1, 1.3, 1.4];
    let b = [0.8, 1.0, 0.7, 1.1, 0.9];
    let w = t_test(&a, &b, TTestKind::Welch).unwrap();
    assert_relative_eq!(w.t, 2.948_839_123_097_943, max_relative = 1e-10);
    assert_relative_eq!(w.df, 8.898_233_809_924_305, max_relative = 1e-10);
    assert_relative_eq!(w.p_value, 0.016_449_098_984_119_125, max_relative = 1e-6);
    let p = t_test(&a, &b, TTestKind::Pooled).unwrap();
    assert_relative_eq!(p.t, 2.860_387_767_736_776_6, max_relative = 1e-10);
    assert_relative_eq!(p.df, 9.0);
    assert_relative_eq!(p.p_value, 0.018_768_522_060_029_734, max_relative = 1e-6);
    assert_eq!(t_test(&[1.0, 1.0], &[1.0, 1.0], TTestKind::Welch), Err(AnalysisError::ZeroVariance));
    assert!(t_test(&[1.0], &[1.0, 2.0], TTestKind::Welch).is_err());
}

#[test]
fn butterworth_matches_scipy_design() {
    // scipy.signal.butter(5, 0.1) (cutoff 0.1 x Nyquist = 500 Hz at 10 kHz).
    let b_ref = [
        5.979_578_037_000_323e-5,
        2.989_789_018_500_161e-4,
        5.979_578_037_000_323e-4,
        5.979_578_037_000_323e-4,
        2.989_789_018_500_161e-4,
        5.979_578_037_000_323e-5,
    ];
    let a_ref = [
        1.0,
        -3.984_543_119_612_336,
        6.434_867_090_275_868,
        -5.253_615_170_352_268,
        2.165_132_909_724_132_3,
        -0.359_928_245_063_556_14,
    ];
    let f = Butterworth::lowpass(5, 500.0, 10_000.0).unwrap();
    let (b, a) = f.transfer_function();
    for (x, y) in b.iter().zip(b_ref) {
        assert_relative_eq!(*x, y, max_relative = 1e-9);
    }
    for (x, y) in a.iter().zip(a_ref) {
        assert_relative_eq!(*x, y, max_relative = 1e-9, epsilon = 1e-12);
    }
}

#[test]
fn butterworth_dc_and_cutoff() {
    let f = Butterworth::lowpass(5, 400.0, 10_000.0).unwrap();
    assert_relative_eq!(f.magnitude(0.0), 1.0, max_relative = 1e-12);
    // Zero-phase response |H|^2 is exactly 1/2 (-6 dB) at the cutoff.
    assert_relative_eq!(f.magnitude(400.0).powi(2), 0.5, max_relative = 1e-9);
    // And measured on a signal: a long sine at the cutoff comes out at half amplitude, in phase.
    let x = sine(400.0, 10_000.0, 20_000, 1.0);
    let y = f.filtfilt(&x).unwrap();
    let mid = &y[5_000..15_000];
    let amp = mid.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert_relative_eq!(amp, 0.5, max_relative = 2e-3);
    let err: f64 = x[5_000..15_000].iter().zip(mid).map(|(a, b)| (0.5 * a - b).abs()).fold(0.0, f64::max);
    assert!(err < 2e-3, "zero phase: {err}");
    assert!(Butterworth::lowpass(5, 5_000.0, 10_000.0).is_err());
    assert!(Butterworth::lowpass(0, 100.0, 10_000.0).is_err());
}

#[test]
fn filtfilt_matches_scipy_sosfiltfilt() {
    // scipy.signal.sosfiltfilt(butter(5, 0.1, output='sos'), x), x[n] = sin(0.1 n) + 0.5 sin(1.3 n) +
    // 0.01 n.
    let x: Vec<f64> =
        (0..100).map(f64::from).map(|n| (0.1 * n).sin() + 0.5 * (1.3 * n).sin() + 0.01 * n).collect();
    let y = Butterworth::lowpass(5, 500.0, 10_000.0).unwrap().filtfilt(&x).unwrap();
    let expected = [
        (0, 0.009_839_219_408_030_22),
        (1, 0.123_152_046_479_912_3),
        (17, 1.159_245_118_897_179_7),
        (50, -0.458_660_598_598_394_7),
        (98, 0.624_442_661_158_888_9),
        (99, 0.537_482_617_816_901_4),
    ];
    for (i, v) in expected {
        assert_relative_eq!(y[i], v, max_relative = 1e-8, epsilon = 1e-10);
    }
}

#[test]
fn csv_with_header_and_time() {
    let text = "time_ms,a,b\n0,1,2\n0.1,3,4\n0.2,5,6\n\n";
    let s = parse_csv(text, TimeColumn::Auto, 1.0).unwrap();
    assert!(s.time_from_file);
    assert_relative_eq!(s.sample_rate_hz, 10_000.0, max_relative = 1e-9);
    assert_eq!(s.names, vec!["a", "b"]);
    assert_eq!(s.traces, vec![vec![1.0, 3.0, 5.0], vec![2.0, 4.0, 6.0]]);
}

#[test]
fn csv_without_header_or_time() {
    let s = parse_csv("1;2\n-3;4\n1;0.5\n", TimeColumn::Auto, 10_000.0).unwrap();
    assert!(!s.time_from_file);
    assert_eq!(s.names, vec!["trial1", "trial2"]);
    let s = parse_csv("0.0 5\n0.001 6\n0.002 7\n", TimeColumn::Auto, 1.0).unwrap();
    assert!(s.time_from_file);
    assert_relative_eq!(s.sample_rate_hz, 1000.0, max_relative = 1e-9);
}

#[test]
fn csv_errors_name_the_line() {
    assert_eq!(parse_csv("", TimeColumn::Auto, 1.0), Err(CsvError::Empty));
    assert_eq!(parse_csv("a,b\n1,2\n\n3,4\n", TimeColumn::Auto, 1.0), Err(CsvError::BlankLine { line: 3 }));
    assert_eq!(
        parse_csv("a,b\n1,2\n3\n", TimeColumn::Auto, 1.0),
        Err(CsvError::ColumnCount { line: 3, expected: 2, got: 1 })
    );
    assert!(matches!(
        parse_csv("1,2\n3,x\n", TimeColumn::Auto, 1.0),
        Err(CsvError::BadNumber { line: 2, column: 2, .. })
    ));
    assert!(matches!(
        parse_csv("1,2\n3,NaN\n", TimeColumn::Auto, 1.0),
        Err(CsvError::BadNumber { line: 2, .. })
    ));
    assert!(matches!(
        parse_csv("t,a\n0,1\n0.1,2\n0.5,3\n", TimeColumn::Auto, 1.0),
        Err(CsvError::NonUniformTime { line: 4, .. })
    ));
    assert_eq!(parse_csv("1,2\n", TimeColumn::Absent, 0.0), Err(CsvError::BadSampleRate(0.0)));
    assert_eq!(parse_csv("t\n0\n1\n", TimeColumn::Auto, 1.0), Err(CsvError::NoTrials));
    // Arbitrary bytes never panic.
    let junk = String::from_utf8_lossy(&[0xff, b',', b'\n', 0x00, b'1', b'e', b'9', b'9', b'9']).to_string();
    assert!(parse_csv(&junk, TimeColumn::Auto, 1.0).is_err());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    #[test]
    fn csv_parser_never_panics(text in "[0-9a-z,;. \\t\\r\\n#eE+-]{0,200}") {
        let _ = parse_csv(&text, TimeColumn::Auto, 10_000.0);
    }

    #[test]
    fn analysis_never_panics(x in proptest::collection::vec(-1e6..1e6f64, 0..400), fs in 1.0..20_000.0f64) {
        let _ = analyze_trace(&x, fs);
        if let Ok(f) = Butterworth::lowpass(5, fs / 10.0, fs) {
            let _ = f.filtfilt(&x);
        }
    }
}

#[test]
fn stats_and_power_law() {
    let s = Stats::of(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]).unwrap();
    assert_relative_eq!(s.mean, 5.0);
    assert_relative_eq!(s.sd, (32.0f64 / 7.0).sqrt(), max_relative = 1e-12);
    assert_relative_eq!(s.range, 7.0);
    assert!(Stats::of(&[]).is_none());
    let trials: Vec<TraceSummary> = [0.6, 0.9, 1.2, 1.5]
        .iter()
        .map(|n: &f64| TraceSummary {
            peak_frequency_hz: 124.7 * n.powf(0.4839),
            steady_amplitude: *n,
            peak_amplitude: *n,
            peak_time_s: 0.0,
            overshoot_pct: 0.0,
            settling_time_s: 0.0,
            samples: 1,
            duration_s: 1.0,
        })
        .collect();
    let fit = frequency_power_law(&trials).unwrap();
    assert_relative_eq!(fit.exponent, 0.4839, max_relative = 1e-8);
}
