//! Axis ranges, "nice" tick selection and compact tick labels.

use crate::Scale;

/// Largest magnitude a linear axis end may take; keeps pixel arithmetic finite for absurd data.
const MAX_LINEAR: f64 = 1e300;

/// Ticks of one axis: labelled major ticks (value, label) and unlabelled minor ticks.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Ticks {
    pub(crate) major: Vec<(f64, String)>,
    pub(crate) minor: Vec<f64>,
}

/// Minimum and maximum of the finite values usable on `scale` (positive ones on a log axis).
pub(crate) fn extent(values: impl IntoIterator<Item = f64>, scale: Scale) -> Option<(f64, f64)> {
    values.into_iter().filter(|v| v.is_finite() && (scale == Scale::Linear || *v > 0.0)).fold(
        None,
        |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((f64::min(lo, v), f64::max(hi, v))),
        },
    )
}

/// Merge two optional extents.
pub(crate) fn merge(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// The axis range to draw.
///
/// An explicit range is honoured when it is usable (finite, non-empty, positive on a log axis; a log range
/// with a non-positive lower end keeps its upper end and takes the lower end from the data, or three decades
/// below). Otherwise the data extent is widened by `pad_fraction` of its span on each side (of its decades on
/// a log axis); a zero-width extent is widened to a visible interval, and no data gives 0..1 (1..10 on log).
pub(crate) fn resolve_range(
    explicit: Option<(f64, f64)>,
    data: Option<(f64, f64)>,
    scale: Scale,
    pad_fraction: f64,
) -> (f64, f64) {
    if let Some((a, b)) = explicit
        && a.is_finite()
        && b.is_finite()
        && (b - a).abs() > 0.0
    {
        let (lo, hi) = (a.min(b), a.max(b));
        match scale {
            Scale::Linear => return (lo.max(-MAX_LINEAR), hi.min(MAX_LINEAR)),
            Scale::Log10 if lo > 0.0 => return (lo, hi),
            Scale::Log10 if hi > 0.0 => {
                let data_lo = data.map(|(d0, _)| d0).filter(|d0| *d0 < hi);
                return (data_lo.unwrap_or(hi * 1e-3), hi);
            }
            Scale::Log10 => {}
        }
    }
    match scale {
        Scale::Linear => {
            let (lo, hi) = data.unwrap_or((0.0, 1.0));
            let (lo, hi) = (lo.max(-MAX_LINEAR), hi.min(MAX_LINEAR));
            let (lo, hi) = if hi - lo > f64::EPSILON * lo.abs().max(hi.abs()) * 4.0 && hi > lo {
                (lo, hi)
            } else {
                let half = if lo == 0.0 { 1.0 } else { (lo.abs() * 0.1).min(MAX_LINEAR) };
                (lo - half, hi + half)
            };
            let pad = (hi / 2.0 - lo / 2.0) * 2.0 * pad_fraction;
            ((lo - pad).max(-MAX_LINEAR), (hi + pad).min(MAX_LINEAR))
        }
        Scale::Log10 => {
            let (lo, hi) = data.unwrap_or((1.0, 10.0));
            let (l0, l1) = (lo.log10(), hi.log10());
            let (l0, l1) = if l1 - l0 > 1e-9 { (l0, l1) } else { (l0 - 0.5, l1 + 0.5) };
            let pad = (l1 - l0) * pad_fraction;
            (10f64.powf(l0 - pad).max(f64::MIN_POSITIVE), 10f64.powf(l1 + pad).min(f64::MAX))
        }
    }
}

/// The 1-2-5 step nearest above `span / max_ticks`: `m * 10^e` with `m` in {1, 2, 5}.
/// Returns `(step, e)`.
fn nice_step(span: f64, max_ticks: usize) -> Option<(f64, i32)> {
    let raw = span / max_ticks.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return None;
    }
    let e = raw.log10().floor() as i32;
    let magnitude = 10f64.powi(e);
    for m in [1.0, 2.0, 5.0] {
        if m * magnitude >= raw * (1.0 - 1e-9) {
            return Some((m * magnitude, e));
        }
    }
    Some((10.0 * magnitude, e + 1))
}

/// Linear ticks on `lo..=hi`: multiples of a 1-2-5 step, at most about `max_ticks` of them.
///
/// Labels use as many decimals as the step needs (so 0.1 + 0.2 prints as 0.3); axes whose values reach
/// 1e5 or stay below 1e-3 use compact scientific labels such as `2.5e-7`.
pub(crate) fn linear_ticks(lo: f64, hi: f64, max_ticks: usize) -> Ticks {
    let Some((step, e)) = nice_step(hi - lo, max_ticks) else {
        return Ticks {
            major: if lo.is_finite() { vec![(lo, format_general(lo))] } else { vec![] },
            minor: vec![],
        };
    };
    let k0 = (lo / step - 1e-9).ceil();
    let k1 = (hi / step + 1e-9).floor();
    if !(k0.is_finite() && k1.is_finite()) || k1 - k0 > 1000.0 {
        return Ticks::default();
    }
    let magnitude = lo.abs().max(hi.abs());
    let scientific = !(1e-3..1e5).contains(&magnitude);
    let mut major = Vec::new();
    let mut k = k0;
    while k <= k1 {
        let v = k * step;
        // Snap values that are zero up to rounding (e.g. -1.3e-17) to exactly zero.
        let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
        let label = if v == 0.0 {
            "0".to_string()
        } else if scientific {
            let digits = (v.abs().log10().floor() as i32 - e).clamp(0, 15) as usize;
            format_scientific(v, digits)
        } else {
            let decimals = (-e).clamp(0, 15) as usize;
            format!("{v:.decimals$}")
        };
        major.push((v, label));
        k += 1.0;
    }
    Ticks { major, minor: Vec::new() }
}

/// `v` as `m.mmme±x` with `digits` mantissa decimals, trailing zeros dropped (`1e-7`, `2.5e3`).
fn format_scientific(v: f64, digits: usize) -> String {
    let s = format!("{v:.digits$e}");
    match s.split_once('e') {
        Some((mantissa, exponent)) => {
            let mantissa = if mantissa.contains('.') {
                mantissa.trim_end_matches('0').trim_end_matches('.')
            } else {
                mantissa
            };
            format!("{mantissa}e{exponent}")
        }
        None => s,
    }
}

/// A short label for an arbitrary value (used when no step is known).
pub(crate) fn format_general(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_finite() { "0".into() } else { format!("{v}") };
    }
    let e = v.abs().log10().floor() as i32;
    if (-3..5).contains(&e) {
        let decimals = (3 - e).clamp(0, 6) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
    } else {
        format_scientific(v, 3)
    }
}

/// Label of `m * 10^k` on a log axis: plain for 0.001..9000, else `m`e`k` (`1e-7`, `2e5`).
fn format_log(m: u32, k: i32) -> String {
    if (-3..=3).contains(&k) {
        let decimals = (-k).max(0) as usize;
        format!("{:.decimals$}", f64::from(m) * 10f64.powi(k))
    } else {
        format!("{m}e{k}")
    }
}

/// Log10 ticks on `lo..=hi` (both > 0).
///
/// Several decades: labelled decades (every n-th if more than `max_ticks`), minor ticks at 2..9 x 10^k.
/// Less than two decades inside: labelled 1, 2, 5 x 10^k; if that still gives fewer than two ticks, linear
/// 1-2-5 ticks.
pub(crate) fn log_ticks(lo: f64, hi: f64, max_ticks: usize) -> Ticks {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Ticks::default();
    }
    let k0 = (lo.log10() - 1e-9).ceil() as i32;
    let k1 = (hi.log10() + 1e-9).floor() as i32;
    let inside = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let decades = (k1 - k0 + 1).max(0);
    if decades >= 2 {
        let per_label = i32::try_from(max_ticks.max(2)).unwrap_or(i32::MAX);
        let stride = ((decades + per_label - 1) / per_label).max(1);
        let mut ticks = Ticks::default();
        let first = k0.div_euclid(stride) * stride;
        let first = if first < k0 { first + stride } else { first };
        for k in k0..=k1 {
            if (k - first).rem_euclid(stride) == 0 {
                ticks.major.push((10f64.powi(k), format_log(1, k)));
            } else {
                ticks.minor.push(10f64.powi(k));
            }
        }
        if stride == 1 && decades <= 12 {
            for k in (k0 - 1)..=k1 {
                for m in 2..=9 {
                    let v = f64::from(m) * 10f64.powi(k);
                    if inside(v) {
                        ticks.minor.push(v);
                    }
                }
            }
        }
        return ticks;
    }
    let mut ticks = Ticks::default();
    let (e0, e1) = (lo.log10().floor() as i32, hi.log10().floor() as i32);
    for k in e0..=e1 {
        for m in 1..=9 {
            let v = f64::from(m) * 10f64.powi(k);
            if inside(v) {
                if matches!(m, 1 | 2 | 5) {
                    ticks.major.push((v, format_log(m, k)));
                } else {
                    ticks.minor.push(v);
                }
            }
        }
    }
    if ticks.major.len() < 2 {
        let linear = linear_ticks(lo, hi, max_ticks.clamp(2, 5));
        ticks.major = linear.major.into_iter().filter(|(v, _)| *v > 0.0).collect();
        ticks.minor.clear();
    }
    ticks
}

/// Ticks for an axis of the given scale.
pub(crate) fn ticks(scale: Scale, lo: f64, hi: f64, max_ticks: usize) -> Ticks {
    match scale {
        Scale::Linear => linear_ticks(lo, hi, max_ticks),
        Scale::Log10 => log_ticks(lo, hi, max_ticks),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn labels(t: &Ticks) -> Vec<&str> {
        t.major.iter().map(|(_, l)| l.as_str()).collect()
    }

    #[test]
    fn unit_range_gets_fifths() {
        let t = linear_ticks(0.0, 1.0, 6);
        assert_eq!(labels(&t), ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
        for ((v, _), expected) in t.major.iter().zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0]) {
            assert_relative_eq!(*v, expected, epsilon = 1e-12);
        }
    }

    #[test]
    fn seven_point_three_gets_ones_or_twos() {
        assert_eq!(labels(&linear_ticks(0.0, 7.3, 8)), ["0", "1", "2", "3", "4", "5", "6", "7"]);
        assert_eq!(labels(&linear_ticks(0.0, 7.3, 5)), ["0", "2", "4", "6"]);
    }

    #[test]
    fn no_float_noise_in_labels() {
        let t = linear_ticks(0.0, 0.35, 8);
        assert_eq!(labels(&t), ["0", "0.05", "0.10", "0.15", "0.20", "0.25", "0.30", "0.35"]);
        let t = linear_ticks(-0.3, 0.3, 6);
        assert_eq!(labels(&t), ["-0.3", "-0.2", "-0.1", "0", "0.1", "0.2", "0.3"]);
    }

    #[test]
    fn tiny_and_huge_values_use_scientific_labels() {
        assert_eq!(labels(&linear_ticks(0.0, 3e-7, 4)), ["0", "1e-7", "2e-7", "3e-7"]);
        assert_eq!(labels(&linear_ticks(0.0, 2.5e5, 5)), ["0", "5e4", "1e5", "1.5e5", "2e5", "2.5e5"]);
        assert_eq!(labels(&linear_ticks(100.0, 300.0, 3)), ["100", "200", "300"]);
    }

    #[test]
    fn log_decades_with_minor_ticks() {
        let t = log_ticks(1e-3, 1e2, 8);
        assert_eq!(labels(&t), ["0.001", "0.01", "0.1", "1", "10", "100"]);
        for ((v, _), k) in t.major.iter().zip(-3..=2) {
            assert_relative_eq!(*v, 10f64.powi(k), max_relative = 1e-12);
        }
        // 2..9 in each of the five full decades.
        assert_eq!(t.minor.len(), 5 * 8);
        // 19 decades at most 6 labels: every 4th decade, aligned so that 1 is labelled.
        let t = log_ticks(1e-9, 1e9, 6);
        assert_eq!(labels(&t), ["1e-8", "1e-4", "1", "1e4", "1e8"]);
        assert_eq!(t.minor.len(), 19 - 5);
    }

    #[test]
    fn narrow_log_range_uses_one_two_five() {
        let t = log_ticks(1.5, 12.0, 6);
        assert_eq!(labels(&t), ["2", "5", "10"]);
        let t = log_ticks(2.1, 4.9, 6);
        assert!(t.major.len() >= 2, "{t:?}");
    }

    #[test]
    fn ranges_are_robust() {
        assert_eq!(resolve_range(None, None, Scale::Linear, 0.0), (0.0, 1.0));
        assert_eq!(resolve_range(Some((2.0, 1.0)), None, Scale::Linear, 0.1), (1.0, 2.0));
        let (lo, hi) = resolve_range(None, Some((5.0, 5.0)), Scale::Linear, 0.0);
        assert!(lo < 5.0 && hi > 5.0);
        let (lo, hi) = resolve_range(Some((0.0, 100.0)), Some((0.5, 50.0)), Scale::Log10, 0.0);
        assert_relative_eq!(lo, 0.5);
        assert_relative_eq!(hi, 100.0);
        let (lo, hi) = resolve_range(None, Some((-f64::MAX, f64::MAX)), Scale::Linear, 0.05);
        assert!(lo.is_finite() && hi.is_finite() && hi > lo);
        assert_eq!(extent([f64::NAN, -1.0, 3.0, f64::INFINITY], Scale::Log10), Some((3.0, 3.0)));
        assert!(linear_ticks(0.0, 0.0, 5).major.len() <= 1);
        assert!(linear_ticks(f64::NAN, 1.0, 5).major.is_empty());
    }
}
