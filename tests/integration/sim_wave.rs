//! Integration tests of `vestnav sim two-point`, `vestnav sim wave` and `vestnav analyze tactor-data`: the
//! binary against the reference numbers (physics.md §3) and against synthetic traces with known parameters.

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::{Command, Output};

use approx::assert_relative_eq;
use serde_json::Value;

fn vestnav(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().expect("vestnav runs")
}

fn json_of(args: &[&str]) -> Value {
    let out = vestnav(args);
    assert!(out.status.success(), "{args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vestnav-sim-wave-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

#[test]
fn two_point_reference_at_11_mm() {
    // physics.md §3: A = 19.546, mu = 5.500, w = 37.045, RMSE = 0.001727 (thesis 19.55, 5.5, 37.05,
    // 0.001727).
    let v = json_of(&["sim", "two-point", "--distance-mm", "11", "--json"]);
    assert_relative_eq!(v["amplitude"].as_f64().unwrap(), 19.546, max_relative = 1e-4);
    assert_relative_eq!(v["center_mm"].as_f64().unwrap(), 5.5, max_relative = 1e-4);
    assert_relative_eq!(v["width_mm"].as_f64().unwrap(), 37.045, max_relative = 1e-4);
    assert_relative_eq!(v["rmse"].as_f64().unwrap(), 0.001_727, max_relative = 1e-3);
}

#[test]
fn two_point_sweep_is_an_array_growing_from_zero() {
    let v = json_of(&["sim", "two-point", "--sweep", "--max-mm", "40", "--json"]);
    let rows = v.as_array().expect("array");
    assert_eq!(rows.len(), 41);
    // d = 0: one exact Gaussian of 2 x 10 m/s^2 and width b.
    assert!(rows[0]["rmse"].as_f64().unwrap() < 1e-8);
    assert_relative_eq!(rows[0]["amplitude"].as_f64().unwrap(), 20.0, max_relative = 1e-9);
    let rmse: Vec<f64> = rows.iter().map(|r| r["rmse"].as_f64().unwrap()).collect();
    assert!(rmse.windows(2).all(|w| w[1] >= w[0]));
}

#[test]
fn two_point_figure_is_a_png() {
    let path = scratch("two-point.png");
    let out = vestnav(&["sim", "two-point", "--distance-mm", "11,50", "--png", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn wave_arrival_recovers_speed_and_midpoint_the_thesis_amplitudes() {
    let v = json_of(&["sim", "wave", "--view", "arrival", "--json"]);
    assert_relative_eq!(v["speed_m_s"].as_f64().unwrap(), 3.023, max_relative = 1e-3);
    let m = json_of(&["sim", "wave", "--view", "midpoint", "--json"]);
    let c = m["components"].as_array().unwrap();
    // Thesis: 3.02 sin(334.3 t + c1) + 3.45 sin(444.8 t + c2).
    assert_relative_eq!(c[0]["amplitude_m_s2"].as_f64().unwrap(), 3.02, max_relative = 0.01);
    assert_relative_eq!(c[1]["amplitude_m_s2"].as_f64().unwrap(), 3.45, max_relative = 0.01);
}

#[test]
fn wave_refuses_options_of_other_views_and_bad_tactors() {
    let out = vestnav(&["sim", "wave", "--view", "attenuation", "--tactors", "1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--tactors"));
    let out = vestnav(&["sim", "wave", "--view", "vest", "--tactors", "16"]);
    assert!(!out.status.success());
}

fn write_trials(name: &str, header: &str, freqs: &[f64], amps: &[f64]) -> PathBuf {
    // 1 s at 10 kHz, a time column in seconds, one sine per trial.
    let fs = 10_000.0;
    let mut text = format!("{header}\n");
    for i in 0..10_000 {
        let t = f64::from(i) / fs;
        let row: Vec<String> =
            freqs.iter().zip(amps).map(|(f, a)| format!("{:.6}", a * (2.0 * PI * f * t).sin())).collect();
        writeln!(text, "{t:.4},{}", row.join(",")).expect("write to a String");
    }
    let path = scratch(name);
    std::fs::write(&path, text).expect("write the CSV");
    path
}

#[test]
fn analyze_recovers_known_sines_and_compares_two_files() {
    let a = write_trials("a.csv", "time,t1,t2,t3", &[133.0, 128.0, 140.0], &[1.2, 1.1, 1.3]);
    let b = write_trials("b.csv", "time,u1,u2,u3", &[95.0, 99.0, 92.0], &[0.6, 0.7, 0.55]);
    let v = json_of(&["analyze", "tactor-data", a.to_str().unwrap(), b.to_str().unwrap(), "--json"]);
    let files = v["files"].as_array().unwrap();
    assert_relative_eq!(files[0]["sample_rate_hz"].as_f64().unwrap(), 10_000.0, max_relative = 1e-6);
    let t1 = &files[0]["trials"][0];
    assert_eq!(t1["name"], "t1");
    assert!((t1["peak_frequency_hz"].as_f64().unwrap() - 133.0).abs() < 0.05);
    assert_relative_eq!(t1["steady_amplitude"].as_f64().unwrap(), 1.2, max_relative = 2e-3);
    // Per-file mean of the three peak frequencies: (133 + 128 + 140) / 3.
    assert!((files[0]["peak_frequency_hz"]["mean"].as_f64().unwrap() - 401.0 / 3.0).abs() < 0.05);
    assert!(v["power_law"]["exponent"].as_f64().is_some());
    let welch = &v["t_test"]["peak_frequency_hz"]["welch"];
    assert!(welch["p_value"].as_f64().unwrap() < 0.01);
    assert!(welch["t"].as_f64().unwrap() > 0.0);
}

#[test]
fn analyze_reports_malformed_csv_with_line_number() {
    let path = scratch("bad.csv");
    std::fs::write(&path, "time,a\n0,1\n0.0001,2\n0.0002,oops\n").unwrap();
    let out = vestnav(&["analyze", "tactor-data", path.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 4"), "{err}");
}

/// `vestnav sim two-point --json --png` is the report of the same fit; the console's two-point export calls
/// the same functions.
#[test]
fn two_point_cli_output_is_the_report_of_the_same_inputs() {
    use vestnav_core::twopoint::TwoPointSetup;
    use vestnav_report::twopoint::{fits, fits_figure, fits_json};
    let path = scratch("two-point-report.png");
    let out =
        vestnav(&["sim", "two-point", "--distance-mm", "11", "--json", "--png", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let results = fits(&TwoPointSetup::THESIS, &[11.0]).unwrap();
    assert_eq!(String::from_utf8_lossy(&out.stdout), fits_json(&results).unwrap());
    assert!(
        std::fs::read(&path).unwrap() == fits_figure(&TwoPointSetup::THESIS, &results).render_png().unwrap()
    );
}

/// The vest view: 60 mm default spacing on both sides (the console's `WaveInputs::thesis` uses the same
/// `VestFieldInputs::default`), the JSON is the report's `VestField`, and one firing tactor's field is its
/// Gaussian `a0 exp(-(r/b)^2)` with a0 = 26.02 m/s^2, b = 28.18 mm (physics.md §2).
#[test]
fn vest_field_cli_output_is_the_report_with_60_mm_spacing() {
    use vestnav_report::wave::{VestField, VestFieldInputs};
    let path = scratch("vest-report.png");
    let out = vestnav(&["sim", "wave", "--view", "vest", "--json", "--png", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let field = VestField::compute(&VestFieldInputs::default()).unwrap();
    assert_eq!(String::from_utf8_lossy(&out.stdout), vestnav_report::to_json(&field).unwrap());
    assert!(std::fs::read(&path).unwrap() == field.figure().render_png().unwrap());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_relative_eq!(v["spacing_mm"].as_f64().unwrap(), 60.0);
    // Tactor 5 fires at (-30, +30) mm; tactor 6 is one spacing to its right: 26.02 exp(-(60/28.18)^2).
    let at = v["at_tactors"].as_array().unwrap();
    assert_relative_eq!(at[5]["peak_m_s2"].as_f64().unwrap(), 26.02, max_relative = 1e-9);
    assert_relative_eq!(
        at[6]["peak_m_s2"].as_f64().unwrap(),
        26.02 * (-(60.0_f64 / 28.18).powi(2)).exp(),
        max_relative = 1e-9
    );
}
