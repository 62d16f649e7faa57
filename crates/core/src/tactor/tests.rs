//! Unit tests of the tactor model: reference figures, solver accuracy, steady state and input checks.

use approx::assert_relative_eq;
use proptest::prelude::*;

use super::*;

fn thesis() -> TactorParams {
    TactorParams::preset(Preset::ThesisSim)
}

/// physics.md §1 reference table (scipy DOP853 at rtol 1e-12), thesis-sim, unencased, b = 6.3e-8.
#[test]
fn reference_table_within_tolerance() {
    let s = simulate_summary(&thesis(), &SimOptions::default()).unwrap();
    assert_relative_eq!(s.omega_mean_rad_s, 833.5334, max_relative = 1e-4);
    assert_relative_eq!(s.f_rot_hz, 132.6610, max_relative = 1e-4);
    assert_relative_eq!(s.omega_min_rad_s, 801.404, max_relative = 5e-4);
    assert_relative_eq!(s.omega_max_rad_s, 873.969, max_relative = 5e-4);
    assert_relative_eq!(s.fft_peak_1s_hz, 133.0, max_relative = 1e-12);
    assert_relative_eq!(s.fft_window_s, 1.0, max_relative = 1e-12);
    assert_relative_eq!(s.accel_peak_m_s2, 245.798, max_relative = 5e-4);
    assert_relative_eq!(s.force_amplitude_n, 0.90945, max_relative = 5e-4);
    assert_relative_eq!(s.x_amplitude_m, 0.382_027e-3, max_relative = 1e-4);
    let settling = s.settling_time_s.unwrap();
    assert!((settling - 0.1067).abs() <= 3e-3, "settling {settling}");
    // Thesis's own (rounded) numbers.
    assert!((s.steady_state.omega_rad_s - 834.2).abs() < 0.05);
    assert!((s.force_amplitude_n - 0.91).abs() < 0.005);
}

#[test]
fn whole_revolution_speed_does_not_depend_on_the_window() {
    let long = simulate_summary(&thesis(), &SimOptions::default()).unwrap();
    let short =
        simulate_summary(&thesis(), &SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 }).unwrap();
    assert_relative_eq!(long.omega_mean_revs_rad_s, short.omega_mean_revs_rad_s, max_relative = 5e-6);
    assert_relative_eq!(long.omega_mean_revs_rad_s, 833.5334, max_relative = 5e-5);
}

#[test]
fn smaller_step_angle_converges() {
    // RK4: halving the step divides the error by ~16; the converged value is the reference's.
    let o = SimOptions::default();
    let coarse = simulate_with_step_angle(&thesis(), &o, 0.26).unwrap().summary;
    let fine = simulate_with_step_angle(&thesis(), &o, 0.13).unwrap().summary;
    let err = |s: &Summary| (s.accel_peak_m_s2 / 245.798 - 1.0).abs();
    assert!(err(&fine) < err(&coarse));
    assert_relative_eq!(fine.omega_mean_rad_s, 833.5334, max_relative = 2e-6);
    assert!(simulate_with_step_angle(&thesis(), &o, 0.0).is_err());
    assert!(simulate_with_step_angle(&thesis(), &o, 1.5).is_err());
}

#[test]
fn traced_and_summary_paths_agree() {
    let o = SimOptions { duration_s: 1.0, output_rate_hz: 10_000.0 };
    let run = simulate(&thesis(), &o).unwrap();
    let s = simulate_summary(&thesis(), &o).unwrap();
    assert_eq!(run.summary, s);
    assert_eq!(run.traces.len(), 10_001);
    assert_relative_eq!(run.traces.t_s[10_000], 1.0, max_relative = 1e-12);
    let last = run.traces.len() - 1;
    assert_relative_eq!(run.traces.force_n[last], run.traces.accel_m_s2[last] * 3.7e-3, max_relative = 1e-12);
}

#[test]
fn closed_form_steady_state() {
    let p = thesis();
    let ss = p.steady_state();
    // omega = Kt u / (R b + Kt^2) by hand: 0.00627 / (62 * 6.3e-8 + 3.61e-6) = 834.2203 rad/s.
    assert_relative_eq!(ss.omega_rad_s, 0.00627 / (62.0 * 6.3e-8 + 3.61e-6), max_relative = 1e-12);
    assert_relative_eq!(ss.omega_rad_s, 834.2203, max_relative = 1e-7);
    // Torque balance Kt i = b omega.
    assert_relative_eq!(ss.torque_n_m, p.damping_n_m_s * ss.omega_rad_s, max_relative = 1e-12);
    assert_relative_eq!(ss.start_current_a, 3.3 / 62.0, max_relative = 1e-12);
    assert_relative_eq!(ss.x_amplitude_m, 0.55 * 2.57 / 3.7 * 1e-3, max_relative = 1e-12);
    assert_relative_eq!(ss.electrical_time_constant_s, 17.74e-6, max_relative = 1e-3);
}

#[test]
fn window_means_obey_the_averaged_circuit_equation() {
    // Averaging L i' = u - R i - Kt omega over the periodic steady state: u = R <i> + Kt <omega>.
    let s = simulate_summary(&thesis(), &SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 }).unwrap();
    let u = s.params.resistance_ohm * s.current_mean_a + 0.0019 * s.omega_mean_rad_s;
    assert_relative_eq!(u, 3.3, max_relative = 1e-4);
    // The start current peaks just below u/R (back-emf), the start torque at Kt u/R.
    assert_relative_eq!(s.current_peak_a, 3.3 / 62.0, max_relative = 5e-3);
    assert!(s.current_peak_a < 3.3 / 62.0);
    assert_relative_eq!(s.torque_peak_n_m, 0.0019 * s.current_peak_a, max_relative = 1e-12);
}

/// Independent truth for the transient: classical RK4 on the full 5-state equations
/// ([`TactorParams::derivatives`], x and v integrated too) with a step far below L/R.
fn fine_rk4(p: &TactorParams, h: f64, steps: usize) -> Vec<[f64; 5]> {
    let mut y = [0.0; 5];
    let mut out = vec![y];
    let add = |a: &[f64; 5], k: &[f64; 5], s: f64| -> [f64; 5] { std::array::from_fn(|j| a[j] + s * k[j]) };
    for _ in 0..steps {
        let k1 = p.derivatives(&y);
        let k2 = p.derivatives(&add(&y, &k1, h / 2.0));
        let k3 = p.derivatives(&add(&y, &k2, h / 2.0));
        let k4 = p.derivatives(&add(&y, &k3, h));
        y = std::array::from_fn(|j| y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]));
        out.push(y);
    }
    out
}

#[test]
fn start_transient_resolves_the_current_rise() {
    let p = thesis();
    let tau = p.electrical_time_constant_s();
    // 1 MHz output over the first 0.5 ms; truth: RK4 at 10 ns steps.
    let run = simulate(&p, &SimOptions { duration_s: 5e-4, output_rate_hz: 1e6 }).unwrap();
    let truth = fine_rk4(&p, 1e-8, 50_000);
    let tr = &run.traces;
    for n in (0..tr.len()).step_by(10) {
        let y = truth[n * 100];
        assert_relative_eq!(tr.current_a[n], y[4], epsilon = 1e-7 * 0.053);
        assert_relative_eq!(tr.omega_rad_s[n], y[3], epsilon = 1e-6 * 15.0);
        assert_relative_eq!(tr.theta_rad[n], y[2], epsilon = 1e-9);
        assert_relative_eq!(tr.v_m_s[n], y[1], max_relative = 1e-6, epsilon = 1e-12);
    }
    // Closed form of the rise with the (still tiny) back-emf ignored: i = u/R (1 - e^{-t/tau}).
    let k = (tau * 1e6).round() as usize;
    assert_relative_eq!(
        tr.current_a[k],
        3.3 / 62.0 * (1.0 - (-(k as f64) * 1e-6 / tau).exp()),
        max_relative = 2e-3
    );
    assert_relative_eq!(tr.current_a[2], 3.3 / 62.0 * (1.0 - (-2e-6 / tau).exp()), max_relative = 1e-3);
}

#[test]
fn spin_up_matches_fine_full_state_integration() {
    // 0.3 s through the whole spin-up (settling ~0.107 s); truth: full 5-state RK4 at 2 us.
    let p = thesis().with_body(BodyMass::Encased);
    let run = simulate(&p, &SimOptions { duration_s: 0.3, output_rate_hz: 1000.0 }).unwrap();
    let truth = fine_rk4(&p, 2e-6, 150_000);
    for n in [10, 50, 100, 200, 300] {
        let y = truth[n * 500];
        let tr = &run.traces;
        assert_relative_eq!(tr.theta_rad[n], y[2], max_relative = 1e-6);
        // The 250 us steps at full speed leave errors of a few 1e-5 (a tenth of the reference tolerances).
        assert_relative_eq!(tr.omega_rad_s[n], y[3], max_relative = 5e-5);
        assert_relative_eq!(tr.current_a[n], y[4], max_relative = 1e-4);
        // x, v are recovered from the conserved momentum and centre of mass: same as integrating them.
        assert_relative_eq!(tr.x_m[n], y[0], epsilon = 1e-4 * 0.3e-3);
        assert_relative_eq!(tr.v_m_s[n], y[1], epsilon = 1e-4 * 0.3);
    }
}

#[test]
fn encased_force_nearly_equals_unencased() {
    // Thesis Fig 31: the force amplitude (acceleration x mass) barely depends on the body mass (~ m l w^2).
    let o = SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 };
    let a = simulate_summary(&thesis(), &o).unwrap();
    let b = simulate_summary(&thesis().with_body(BodyMass::Encased), &o).unwrap();
    assert_relative_eq!(a.force_amplitude_n, b.force_amplitude_n, max_relative = 0.05);
    assert!(b.accel_peak_m_s2 < a.accel_peak_m_s2);
    assert_relative_eq!(b.x_amplitude_m, 0.55 * 2.57 / 4.95 * 1e-3, max_relative = 1e-4);
}

#[test]
fn settling_of_a_first_order_rise() {
    // omega = w (1 - e^{-t/T}) => theta = w (t - T (1 - e^{-t/T})); 2 % settling at T ln 50.
    let (w, t_c, dt) = (800.0, 0.1, 1e-4);
    let theta: Vec<f64> =
        (0..10_000).map(|k| f64::from(k) * dt).map(|t| w * (t - t_c * (1.0 - (-t / t_c).exp()))).collect();
    let s = settling_time_s(&theta, dt, w, 0.02).unwrap();
    assert!((s - t_c * 50f64.ln()).abs() < 2e-4, "{s}");
    assert_eq!(settling_time_s(&theta[..3000], dt, w, 0.02), None);
    assert_eq!(settling_time_s(&[0.0; 100], dt, w, 0.02), None);
}

#[test]
fn bad_inputs_are_rejected() {
    let o = SimOptions::default();
    assert!(matches!(
        simulate(&thesis().with_damping(f64::NAN), &o),
        Err(TactorError::Negative { name: "damping [N m s]", .. })
    ));
    assert!(matches!(simulate(&thesis().with_voltage(-1.0), &o), Err(TactorError::NotPositive { .. })));
    let mut p = thesis();
    p.body_mass_kg = 0.5e-3;
    assert!(matches!(simulate(&p, &o), Err(TactorError::BodyLighterThanEccentric { .. })));
    for d in [-1.0, 0.0, f64::INFINITY, 1e9] {
        assert!(simulate_summary(&thesis(), &SimOptions { duration_s: d, ..o }).is_err(), "{d}");
    }
    assert!(simulate(&thesis(), &SimOptions { duration_s: 1000.0, output_rate_hz: 1e5 }).is_err());
}

#[test]
fn stalled_rotor_has_no_settling_and_stays_finite() {
    // Below ~0.45 V the start torque Kt u/R cannot lift the eccentric over the top (m g l): a pendulum.
    let s =
        simulate_summary(&thesis().with_voltage(0.2), &SimOptions { duration_s: 1.0, output_rate_hz: 1e4 })
            .unwrap();
    assert!(s.omega_mean_rad_s.abs() < 1.0);
    assert_eq!(s.settling_time_s, None);
}

proptest! {
    #[test]
    fn steady_speed_falls_with_damping_and_rises_with_voltage(
        b in 1e-9..1e-6f64, db in 1e-10..1e-7f64, u in 0.5..6.0f64, du in 0.01..1.0f64,
    ) {
        let p = thesis().with_damping(b).with_voltage(u);
        let w = p.steady_state().omega_rad_s;
        prop_assert!(p.with_damping(b + db).steady_state().omega_rad_s < w);
        prop_assert!(p.with_voltage(u + du).steady_state().omega_rad_s > w);
        let ss = p.steady_state();
        prop_assert!(ss.current_a > 0.0 && ss.current_a < ss.start_current_a);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(6))]
    #[test]
    fn simulated_speed_is_near_the_closed_form(b in 3e-8..1.5e-7f64, u in 2.5..3.8f64) {
        // The speed ripple shifts the mean by well under 1 %; energy flows in (mean torque > 0).
        let p = thesis().with_damping(b).with_voltage(u);
        let s = simulate_summary(&p, &SimOptions { duration_s: 1.5, output_rate_hz: 10_000.0 }).unwrap();
        prop_assert!((s.omega_mean_rad_s / p.steady_state().omega_rad_s - 1.0).abs() < 0.01);
        prop_assert!(s.torque_mean_n_m > 0.0);
        prop_assert!((s.x_amplitude_m / p.steady_state().x_amplitude_m - 1.0).abs() < 1e-3);
    }
}
