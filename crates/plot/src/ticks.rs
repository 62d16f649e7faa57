//! Axis ranges, "nice" tick selection and compact tick labels: the one tick rule of every figure, the PNG
//! renderer's and the console's on-screen plots' alike ([`axis_ticks`]).

use crate::Scale;

/// Largest magnitude a linear axis end may take; keeps pixel arithmetic finite for absurd data.
const MAX_LINEAR: f64 = 1e300;

/// Ticks of one axis: labelled major ticks (value, label) and unlabelled minor ticks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Ticks {
    /// Labelled ticks, ascending: the value and its label.
    pub major: Vec<(f64, String)>,
    /// Unlabelled ticks between the labelled ones (log axes: 2..9 x 10^k).
    pub minor: Vec<f64>,
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

/// The 1-2-5 step nearest above `span / max_ticks`: `m * 10^e` with `m` in {1, 2, 5}; at least 1 when
/// `integer` (an axis that counts things, such as cone pairs, never gets a tick between two of them).
/// Returns `(step, e)`.
fn nice_step(span: f64, max_ticks: usize, integer: bool) -> Option<(f64, i32)> {
    let raw = span / max_ticks.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return None;
    }
    if integer && raw <= 1.0 {
        return Some((1.0, 0));
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
/// Labels all carry the decimals the step needs, no more and no fewer (a step of 0.5 labels
/// `0.0, 0.5, 1.0`; 0.1 + 0.2 prints as 0.3; zero is never `-0`); axes whose values reach 1e5 or stay below
/// 1e-3 use compact scientific labels such as `2.5e-7`.
///
/// A range that would get a single label at `max_ticks` (0.54e4..1.24e4 at two: only 10000) takes the next
/// finer step, so every axis with room for two labels shows at least two.
pub(crate) fn linear_ticks(lo: f64, hi: f64, max_ticks: usize, integer: bool) -> Ticks {
    let mut ticks = linear_ticks_at(lo, hi, max_ticks, integer);
    let mut n = max_ticks.max(1);
    while ticks.major.len() < 2 && n < max_ticks.max(1) * 3 + 3 {
        n += 1;
        let finer = linear_ticks_at(lo, hi, n, integer);
        if finer.major.len() > ticks.major.len() {
            ticks = finer;
        }
    }
    ticks
}

fn linear_ticks_at(lo: f64, hi: f64, max_ticks: usize, integer: bool) -> Ticks {
    let Some((step, e)) = nice_step(hi - lo, max_ticks, integer) else {
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
        let label = if v == 0.0 && scientific {
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
        let linear = linear_ticks(lo, hi, max_ticks.clamp(2, 5), false);
        ticks.major = linear.major.into_iter().filter(|(v, _)| *v > 0.0).collect();
        ticks.minor.clear();
    }
    ticks
}

/// Ticks for an axis of `scale` showing `lo..=hi`, with at most about `max_ticks` labels.
///
/// Linear axes: multiples of the 1-2-5 step nearest above `(hi - lo) / max_ticks` (at least 1 when
/// `integer`), each labelled with the decimals the step needs. Log axes: decades, or 1-2-5 x 10^k inside
/// fewer than two decades. The PNG figures and the console's plots both take their ticks from here, so a
/// figure on screen and its export are numbered alike.
///
/// ```
/// let t = vestnav_plot::axis_ticks(vestnav_plot::Scale::Linear, 0.0, 2.5, 6, false);
/// let labels: Vec<&str> = t.major.iter().map(|(_, l)| l.as_str()).collect();
/// assert_eq!(labels, ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5"]);
/// ```
pub fn axis_ticks(scale: Scale, lo: f64, hi: f64, max_ticks: usize, integer: bool) -> Ticks {
    match scale {
        Scale::Linear => linear_ticks(lo, hi, max_ticks, integer),
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
        let t = linear_ticks(0.0, 1.0, 6, false);
        assert_eq!(labels(&t), ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
        for ((v, _), expected) in t.major.iter().zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0]) {
            assert_relative_eq!(*v, expected, epsilon = 1e-12);
        }
    }

    #[test]
    fn seven_point_three_gets_ones_or_twos() {
        assert_eq!(labels(&linear_ticks(0.0, 7.3, 8, false)), ["0", "1", "2", "3", "4", "5", "6", "7"]);
        assert_eq!(labels(&linear_ticks(0.0, 7.3, 5, false)), ["0", "2", "4", "6"]);
    }

    #[test]
    fn no_float_noise_in_labels() {
        let t = linear_ticks(0.0, 0.35, 8, false);
        assert_eq!(labels(&t), ["0.00", "0.05", "0.10", "0.15", "0.20", "0.25", "0.30", "0.35"]);
        let t = linear_ticks(-0.3, 0.3, 6, false);
        assert_eq!(labels(&t), ["-0.3", "-0.2", "-0.1", "0.0", "0.1", "0.2", "0.3"]);
    }

    #[test]
    fn tiny_and_huge_values_use_scientific_labels() {
        assert_eq!(labels(&linear_ticks(0.0, 3e-7, 4, false)), ["0", "1e-7", "2e-7", "3e-7"]);
        assert_eq!(labels(&linear_ticks(0.0, 2.5e5, 5, false)), ["0", "5e4", "1e5", "1.5e5", "2e5", "2.5e5"]);
        assert_eq!(labels(&linear_ticks(100.0, 300.0, 3, false)), ["100", "200", "300"]);
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

    /// Closed form: 0..2.5 with room for six labels is stepped by 0.5 (2.5 / 6 = 0.417, the next 1-2-5 value
    /// above is 0.5), so the ticks are k / 2 for k = 0..=5, all labelled with exactly one decimal.
    #[test]
    fn half_steps_carry_one_decimal() {
        let t = axis_ticks(Scale::Linear, 0.0, 2.5, 6, false);
        assert_eq!(labels(&t), ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5"]);
        for ((v, _), k) in t.major.iter().zip(0..) {
            assert_relative_eq!(*v, f64::from(k) * 0.5, epsilon = 1e-12);
        }
        // The same about zero: -1.2..1.2 at six labels is stepped by 0.5, and zero is "0.0", never "-0.0".
        assert_eq!(
            labels(&axis_ticks(Scale::Linear, -1.2, 1.2, 6, false)),
            ["-1.0", "-0.5", "0.0", "0.5", "1.0"]
        );
    }

    #[test]
    fn counting_axes_get_whole_numbers() {
        // Nine cone pairs padded by 4 % each side: a step of 0.2 by the plain rule, 1 on a counting axis.
        let t = axis_ticks(Scale::Linear, 0.68, 9.32, 12, true);
        assert_eq!(labels(&t), ["1", "2", "3", "4", "5", "6", "7", "8", "9"]);
        // Wider counting axes keep the 1-2-5 rule above 1.
        assert_eq!(labels(&axis_ticks(Scale::Linear, 0.0, 40.0, 5, true)), ["0", "10", "20", "30", "40"]);
    }

    proptest::proptest! {
        /// For any range: labelled values are consecutive multiples of one 1-2-5 step; every label reads back
        /// as its value to within a thousandth of the step; all labels carry the same number of decimals; no
        /// label is a negative zero.
        #[test]
        fn labels_follow_the_step(lo in -1e4f64..1e4, span in 1e-2f64..1e4, max_ticks in 2usize..12) {
            let hi = lo + span;
            let t = axis_ticks(Scale::Linear, lo, hi, max_ticks, false);
            proptest::prop_assert!(t.major.len() >= 2, "{lo}..{hi}: {t:?}");
            let step = t.major[1].0 - t.major[0].0;
            let e = step.log10().floor();
            let mantissa = step / 10f64.powf(e);
            proptest::prop_assert!(
                [1.0, 2.0, 5.0, 10.0].iter().any(|m| (mantissa - m).abs() < 1e-6),
                "step {step}"
            );
            let decimals = |l: &str| l.split_once('.').map_or(0, |(_, d)| d.len());
            let scientific = t.major.iter().any(|(_, l)| l.contains('e'));
            for pair in t.major.windows(2) {
                proptest::prop_assert!((pair[1].0 - pair[0].0 - step).abs() < step * 1e-6);
            }
            for (v, l) in &t.major {
                proptest::prop_assert!(*v >= lo - step * 1e-6 && *v <= hi + step * 1e-6);
                let parsed: f64 = l.parse().map_err(|_| proptest::test_runner::TestCaseError::fail(l.clone()))?;
                proptest::prop_assert!((parsed - v).abs() <= step * 1e-3, "{l} for {v}");
                proptest::prop_assert!(!(l.starts_with('-') && parsed == 0.0), "negative zero {l}");
                if !scientific {
                    proptest::prop_assert_eq!(decimals(l), decimals(&t.major[0].1), "{:?}", t.major);
                    let needed = if e < 0.0 { (-e) as usize } else { 0 };
                    proptest::prop_assert_eq!(decimals(l), needed, "{} for step {}", l, step);
                }
            }
        }
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
        assert!(linear_ticks(0.0, 0.0, 5, false).major.len() <= 1);
        assert!(linear_ticks(f64::NAN, 1.0, 5, false).major.is_empty());
    }
}
