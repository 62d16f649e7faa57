//! Small series helpers every figure uses: evenly spaced axes and time windows. (The per-revolution envelope
//! is `vestnav_core::analysis::revolution_envelope`, beside the measured-trace envelope.)

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
}
