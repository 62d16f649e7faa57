//! Small series helpers every figure uses: evenly spaced axes, time windows and the per-revolution envelope.

use std::f64::consts::TAU;

/// `n` evenly spaced values from `lo` to `hi`, both included (`n` below 2 is taken as 2).
///
/// `x_k = lo + (hi - lo) k / (n - 1)`, `k = 0..n`.
pub fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let n = n.max(2);
    (0..n).map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64).collect()
}

/// The samples of `(t, y)` with `t0 <= t <= t1`, scaled by `scale`.
pub fn time_window(t: &[f64], y: &[f64], t0: f64, t1: f64, scale: f64) -> (Vec<f64>, Vec<f64>) {
    t.iter().zip(y).filter(|(t, _)| **t >= t0 && **t <= t1).map(|(t, y)| (*t, y * scale)).unzip()
}

/// Amplitude envelope of `y` per revolution of the eccentric: the largest `|y|` while `theta` runs from
/// `2 pi k` to `2 pi (k + 1)`, placed at the revolution's mid time (thesis Figs 30, 31 and 39 plot this
/// envelope). Unlike a fixed-length window it follows the speed as the motor spins up. Nothing is returned
/// before the first full revolution; `t`, `theta` and `y` are samples at the same times.
pub fn revolution_envelope(t: &[f64], theta: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = t.len().min(theta.len()).min(y.len());
    let mut ts = Vec::new();
    let mut env = Vec::new();
    let mut start = 0usize;
    let mut next = TAU;
    for k in 1..n {
        if theta[k] >= next {
            let peak = y[start..=k].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            ts.push(0.5 * (t[start] + t[k]));
            env.push(peak);
            start = k;
            next = ((theta[k] / TAU).floor() + 1.0) * TAU;
        }
    }
    (ts, env)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn linspace_has_both_ends_and_even_steps() {
        let v = linspace(80.0, 200.0, 41);
        assert_eq!(v.len(), 41);
        assert_relative_eq!(v[0], 80.0);
        assert_relative_eq!(v[40], 200.0);
        assert!(v.windows(2).all(|w| (w[1] - w[0] - 3.0).abs() < 1e-12));
        assert_eq!(linspace(1.0, 2.0, 0), vec![1.0, 2.0]);
    }

    #[test]
    fn envelope_of_a_constant_speed_sinusoid_is_its_amplitude() {
        // theta = omega t at 133 Hz, y = 2 sin(theta + 0.3) sampled at 10 kHz: every revolution's peak is 2
        // (within the sampling error 1 - cos(pi f / fs)).
        let omega = TAU * 133.0;
        let t: Vec<f64> = (0..10_000).map(|k| f64::from(k) * 1e-4).collect();
        let theta: Vec<f64> = t.iter().map(|t| omega * t).collect();
        let y: Vec<f64> = theta.iter().map(|a| 2.0 * (a + 0.3).sin()).collect();
        let (te, ye) = revolution_envelope(&t, &theta, &y);
        assert_eq!(te.len(), 132, "133 Hz over 1 s: 132 whole revolutions after the first crossing");
        for v in ye {
            assert_relative_eq!(v, 2.0, max_relative = 3e-3);
        }
        // Mid times: revolution k spans [k/133, (k+1)/133] s.
        assert_relative_eq!(te[0], 0.5 / 133.0, epsilon = 1e-4);
    }

    #[test]
    fn window_keeps_the_interval_and_scales() {
        let (t, y) = time_window(&[0.0, 1.0, 2.0, 3.0], &[1.0, 2.0, 3.0, 4.0], 1.0, 2.0, 1e3);
        assert_eq!(t, vec![1.0, 2.0]);
        assert_eq!(y, vec![2000.0, 3000.0]);
    }
}
