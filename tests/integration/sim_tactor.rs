//! Integration tests of `vestnav sim tactor | sweep | damping-for`: the binary against the physics.md §1
//! reference table and the closed forms, CSV/PNG outputs, and clear rejections of bad input.

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
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("key {key} missing or not a number in {v}"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vestnav-sim-tactor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn assert_png(path: &PathBuf) {
    let bytes = std::fs::read(path).expect("PNG written");
    assert!(bytes.len() > 1000, "PNG too small: {} bytes", bytes.len());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn tactor_json_matches_reference_table() {
    // physics.md §1: thesis-sim preset, unencased, b = 6.3e-8, 10 s from rest, window 5..10 s.
    let v = json_of(&["sim", "tactor", "--json"]);
    assert_eq!(v["preset"], "thesis-sim");
    assert_relative_eq!(num(&v, "omega_mean_rad_s"), 833.5334, max_relative = 1e-4);
    assert_relative_eq!(num(&v, "f_rot_hz"), 132.6610, max_relative = 1e-4);
    assert_relative_eq!(num(&v, "omega_min_rad_s"), 801.404, max_relative = 5e-4);
    assert_relative_eq!(num(&v, "omega_max_rad_s"), 873.969, max_relative = 5e-4);
    assert_relative_eq!(num(&v, "fft_peak_1s_hz"), 133.0);
    assert_relative_eq!(num(&v, "accel_peak_m_s2"), 245.798, max_relative = 5e-4);
    assert_relative_eq!(num(&v, "force_amplitude_n"), 0.90945, max_relative = 5e-4);
    assert_relative_eq!(num(&v, "x_amplitude_m"), 0.382_027e-3, max_relative = 1e-4);
    assert!((num(&v, "settling_time_s") - 0.1067).abs() <= 3e-3);
    // Closed forms: start current u/R (just below it, back-emf), torque = Kt i, u = R <i> + Kt <omega>.
    assert_relative_eq!(num(&v, "current_peak_a"), 3.3 / 62.0, max_relative = 5e-3);
    assert_relative_eq!(num(&v, "torque_peak_n_m"), 0.0019 * num(&v, "current_peak_a"), max_relative = 1e-9);
    assert_relative_eq!(num(&v, "torque_mean_n_m"), 0.0019 * num(&v, "current_mean_a"), max_relative = 1e-9);
    assert_relative_eq!(
        62.0 * num(&v, "current_mean_a") + 0.0019 * num(&v, "omega_mean_rad_s"),
        3.3,
        max_relative = 1e-4
    );
    assert_relative_eq!(num(&v["steady_state"], "omega_rad_s"), 834.2203, max_relative = 1e-6);
    assert_relative_eq!(num(&v["params"], "resistance_ohm"), 62.0);
}

#[test]
fn tactor_options_change_the_model() {
    // Encased, measured preset, 3.2 mm: x amplitude = m l / Mt exactly; R = 67 lowers the speed.
    let v = json_of(&[
        "sim",
        "tactor",
        "--json",
        "--preset",
        "measured",
        "--mass",
        "encased",
        "--radius-mm",
        "3.2",
        "--duration-s",
        "2",
    ]);
    assert_eq!(v["preset"], "measured");
    assert_relative_eq!(num(&v, "x_amplitude_m"), 0.55 * 3.2 / 4.95 * 1e-3, max_relative = 1e-4);
    let w_cf = 0.0019 * 3.3 / (67.0 * 6.3e-8 + 0.0019 * 0.0019);
    assert_relative_eq!(num(&v["steady_state"], "omega_rad_s"), w_cf, max_relative = 1e-9);
    assert_relative_eq!(num(&v, "omega_mean_rad_s"), w_cf, max_relative = 5e-3);
    let v =
        json_of(&["sim", "tactor", "--json", "--damping", "1e-7", "--voltage", "3.0", "--duration-s", "2"]);
    let w_cf = 0.0019 * 3.0 / (62.0 * 1e-7 + 0.0019 * 0.0019);
    assert_relative_eq!(num(&v, "omega_mean_rad_s"), w_cf, max_relative = 5e-3);
}

#[test]
fn tactor_writes_csv_and_png() {
    let csv = scratch("tactor.csv");
    let png = scratch("tactor.png");
    let out = vestnav(&[
        "sim",
        "tactor",
        "--duration-s",
        "1",
        "--csv",
        csv.to_str().expect("utf-8 path"),
        "--png",
        png.to_str().expect("utf-8 path"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("mean omega"));
    let text = std::fs::read_to_string(&csv).expect("CSV written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,theta_rad,omega_rad_s,x_m,v_m_s,accel_m_s2,force_n,torque_n_m,current_a")
    );
    let rows: Vec<Vec<f64>> =
        lines.map(|l| l.split(',').map(|c| c.parse().expect("numeric cell")).collect()).collect();
    assert_eq!(rows.len(), 10_001);
    assert!(rows.iter().all(|r| r.len() == 9));
    // x = -(m l/Mt) sin(theta) (momentum conservation), force = Mt a, torque = Kt i.
    let r = &rows[7777];
    assert_relative_eq!(r[3], -(0.55 * 2.57 / 3.7e3) * r[1].sin(), max_relative = 1e-9, epsilon = 1e-15);
    assert_relative_eq!(r[6], 3.7e-3 * r[5], max_relative = 1e-9);
    assert_relative_eq!(r[7], 0.0019 * r[8], max_relative = 1e-9);
    assert_png(&png);
}

#[test]
fn sweep_json_has_fits_and_points() {
    let png = scratch("sweep.png");
    let v =
        json_of(&["sim", "sweep", "--json", "--points", "12", "--png", png.to_str().expect("utf-8 path")]);
    let pl = &v["power_law"];
    assert!((num(pl, "exponent") - 0.5).abs() < 0.01, "{pl}");
    assert!(num(pl, "r2") > 0.999);
    assert!(num(pl, "coefficient") > 100.0 && num(pl, "coefficient") < 160.0);
    let cl = &v["current_line"];
    assert_relative_eq!(num(cl, "intercept_hz"), 3.3 / (std::f64::consts::TAU * 0.0019), max_relative = 1e-4);
    assert_relative_eq!(
        num(cl, "slope_hz_per_a"),
        -62.0 / (std::f64::consts::TAU * 0.0019),
        max_relative = 1e-3
    );
    let points = v["points"].as_array().expect("points array");
    assert_eq!(points.len(), 12);
    assert_relative_eq!(num(&points[0], "closed_form_hz"), 80.0, max_relative = 1e-9);
    assert_png(&png);
}

#[test]
fn damping_for_133_hz_round_trips() {
    let v = json_of(&["sim", "damping-for", "--frequency-hz", "133.2", "--json"]);
    assert_relative_eq!(num(&v, "achieved_f_rot_hz"), 133.2, max_relative = 1e-6);
    let b = num(&v, "damping_n_m_s");
    // Exact closed form b = (Kt u/(2 pi f) - Kt^2)/R; the simulated one differs by the ripple's ~0.2 %.
    let b_cf = (0.0019 * 3.3 / (std::f64::consts::TAU * 133.2) - 0.0019 * 0.0019) / 62.0;
    assert_relative_eq!(num(&v, "damping_closed_form_n_m_s"), b_cf, max_relative = 1e-12);
    assert_relative_eq!(b, b_cf, max_relative = 0.01);
    // Simulating that damping lands on the frequency.
    let s = json_of(&["sim", "tactor", "--json", "--damping", &format!("{b:e}"), "--duration-s", "2"]);
    // (over whole revolutions; delta theta / delta t over 1 s carries the ripple's phase, ~5e-5)
    assert_relative_eq!(num(&s, "omega_mean_revs_rad_s") / std::f64::consts::TAU, 133.2, max_relative = 1e-6);
    assert_relative_eq!(num(&s, "f_rot_hz"), 133.2, max_relative = 2e-4);
    // The plain form prints the number alone on stdout.
    let out = vestnav(&["sim", "damping-for", "--frequency-hz", "133.2"]);
    assert!(out.status.success());
    let printed: f64 = String::from_utf8_lossy(&out.stdout).trim().parse().expect("a number");
    assert_relative_eq!(printed, b, max_relative = 1e-9);
}

#[test]
fn bad_input_is_rejected_with_a_message() {
    for args in [
        &["sim", "tactor", "--duration-s", "-1"][..],
        &["sim", "tactor", "--duration-s", "NaN"],
        &["sim", "tactor", "--damping", "-3e-8"],
        &["sim", "tactor", "--voltage", "inf"],
        &["sim", "tactor", "--radius-mm", "0"],
        &["sim", "sweep", "--points", "2"],
        &["sim", "sweep", "--max-hz", "400"],
        &["sim", "damping-for", "--frequency-hz", "500"],
        &["sim", "damping-for", "--frequency-hz", "-5"],
    ] {
        let out = vestnav(args);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("vestnav:") || err.contains("error:"), "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?} printed {}", String::from_utf8_lossy(&out.stdout));
    }
}

/// `vestnav sim tactor --json --png` writes what `vestnav_report` makes of the same inputs, byte for byte: the
/// console's tactor export calls the same functions (`crates/app/src/sim_panel/mod.rs`
/// `save_buttons_write_the_report_of_the_shown_inputs`, whose default inputs are these).
#[test]
fn tactor_cli_output_is_the_report_of_the_same_inputs() {
    use vestnav_core::tactor::{BodyMass, DEFAULT_STEP_ANGLE_RAD, Preset, SimOptions, TactorParams};
    use vestnav_report::tactor::{DEFAULT_SPAN_S, TactorReport, TactorRuns, tactor_figure};
    let png = scratch("tactor-report.png");
    let out = vestnav(&[
        "sim",
        "tactor",
        "--duration-s",
        "1",
        "--json",
        "--png",
        png.to_str().expect("utf-8 path"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let params = TactorParams::preset(Preset::ThesisSim).with_body(BodyMass::Unencased);
    let options = SimOptions { duration_s: 1.0, output_rate_hz: 10_000.0 };
    let runs = TactorRuns::simulate(&params, &options, DEFAULT_STEP_ANGLE_RAD, true).unwrap();
    let want = vestnav_report::to_json(&TactorReport::new(&runs.main.summary)).unwrap();
    assert_eq!(String::from_utf8_lossy(&out.stdout), want);
    let figure = tactor_figure(&runs, DEFAULT_SPAN_S);
    // physics.md §7: Fig 28 is the eccentric angle theta (it ramps up, then grows linearly at omega).
    let Some(vestnav_plot::Panel::Chart(fig28)) = figure.panels.first() else { panic!("chart expected") };
    assert!(fig28.title.contains("Fig 28: eccentric angle"), "{}", fig28.title);
    let theta = &fig28.series[0].y;
    assert!(theta.windows(2).all(|w| w[1] >= w[0] - 1e-9), "theta never decreases");
    assert!(std::fs::read(&png).unwrap() == figure.render_png().unwrap(), "the PNG is the report's figure");
}

/// `vestnav sim sweep --json --png` is the report of the same sweep (keys as before: `current_line` has
/// `intercept_hz` and `slope_hz_per_a`).
#[test]
fn sweep_cli_output_is_the_report_of_the_same_inputs() {
    use vestnav_core::sweep::SweepOptions;
    use vestnav_core::tactor::{BodyMass, Preset, TactorParams};
    use vestnav_report::sweep::{SweepReport, SweepSet, sweep_figure};
    let png = scratch("sweep-report.png");
    let args = ["sim", "sweep", "--points", "5", "--min-hz", "100", "--max-hz", "160", "--json", "--png"];
    let out = vestnav(&[&args[..], &[png.to_str().expect("utf-8 path")]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let params = TactorParams::preset(Preset::ThesisSim).with_body(BodyMass::Unencased);
    let options = SweepOptions { min_hz: 100.0, max_hz: 160.0, points: 5, ..SweepOptions::default() };
    let set = SweepSet::compute(&params, &options).unwrap();
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        vestnav_report::to_json(&SweepReport::new(&set.main)).unwrap()
    );
    assert!(std::fs::read(&png).unwrap() == sweep_figure(&set).render_png().unwrap());
    // The schema reads back, and the closed-form points sit where the sweep put them (80..200 -> 100..160 Hz).
    let back: SweepReport = serde_json::from_slice(&out.stdout).unwrap();
    assert_relative_eq!(back.points[0].closed_form_hz, 100.0, max_relative = 1e-9);
    assert_relative_eq!(back.points[4].closed_form_hz, 160.0, max_relative = 1e-9);
}
