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

/// `x` with `digits` significant digits and no trailing zeros, for numbers computed or typed, in labels and titles:
/// 70.40055891942245 reads "70.4" (3 digits), 0.05 "0.05", 1.234e-7 "1.23e-7". Magnitudes outside
/// 1e-3..1e6 are written in scientific notation; NaN and infinities as Rust writes them.
pub fn sig(x: f64, digits: usize) -> String {
    let digits = digits.clamp(1, 17);
    if !x.is_finite() {
        return x.to_string();
    }
    if x.abs() < f64::MIN_POSITIVE {
        return "0".to_owned();
    }
    let mag = x.abs().log10().floor() as i64;
    if !(-3..6).contains(&mag) {
        let s = format!("{:.*e}", digits - 1, x);
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        return format!("{}e{exp}", trim_zeros(mantissa));
    }
    let decimals = usize::try_from(i64::try_from(digits).unwrap_or(i64::MAX) - 1 - mag).unwrap_or(0);
    trim_zeros(&format!("{x:.decimals$}")).to_owned()
}

/// "70.400" -> "70.4", "100.0" -> "100", "120" -> "120".
fn trim_zeros(s: &str) -> &str {
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s }
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
    fn sig_gives_units_appropriate_precision() {
        assert_eq!(sig(70.400_558_919_422_45, 3), "70.4");
        assert_eq!(sig(70.400_558_919_422_45, 4), "70.4");
        assert_eq!(sig(70.46, 3), "70.5");
        assert_eq!(sig(0.05, 3), "0.05");
        assert_eq!(sig(0.050_000_000_000_01, 3), "0.05");
        assert_eq!(sig(99.96, 3), "100");
        assert_eq!(sig(1.234e-7, 3), "1.23e-7");
        assert_eq!(sig(-2.5e7, 2), "-2.5e7");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(f64::NAN, 3), "NaN");
    }
}
