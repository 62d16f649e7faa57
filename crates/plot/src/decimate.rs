//! Thinning long series for drawing while keeping their extremes.

/// Reduces `(x, y)` to at most about `max_points` points, keeping each bucket's minimum and maximum in their
/// original order, so peaks and envelopes survive (an oscillation thinned this way keeps its amplitude).
///
/// The samples are cut into `max_points / 2` consecutive buckets of equal size; each bucket contributes its
/// smallest and its largest `y` (one point if they are the same sample). Series no longer than `max_points`
/// (or `max_points < 4`) are returned unchanged; extra values of the longer vector are ignored. Non-finite
/// values are never chosen as an extreme unless a bucket has nothing else.
pub fn decimate_minmax(x: &[f64], y: &[f64], max_points: usize) -> (Vec<f64>, Vec<f64>) {
    let n = x.len().min(y.len());
    if n <= max_points || max_points < 4 {
        return (x[..n].to_vec(), y[..n].to_vec());
    }
    let buckets = max_points / 2;
    let size = n.div_ceil(buckets);
    let mut xs = Vec::with_capacity(2 * buckets + 2);
    let mut ys = Vec::with_capacity(2 * buckets + 2);
    let mut start = 0;
    while start < n {
        let end = (start + size).min(n);
        let (mut lo, mut hi) = (start, start);
        for k in start..end {
            if y[k] < y[lo] || !y[lo].is_finite() {
                lo = k;
            }
            if y[k] > y[hi] || !y[hi].is_finite() {
                hi = k;
            }
        }
        xs.push(x[lo.min(hi)]);
        ys.push(y[lo.min(hi)]);
        if lo != hi {
            xs.push(x[lo.max(hi)]);
            ys.push(y[lo.max(hi)]);
        }
        start = end;
    }
    (xs, ys)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn keeps_the_extremes_of_a_growing_sine_and_bounds_the_size() {
        let x: Vec<f64> = (0..100_000).map(|k| f64::from(k) * 1e-4).collect();
        let y: Vec<f64> = x.iter().map(|t| (std::f64::consts::TAU * 133.0 * t).sin() * (1.0 + t)).collect();
        let (xs, ys) = decimate_minmax(&x, &y, 4000);
        assert!(xs.len() <= 4002 && xs.len() > 3000, "{}", xs.len());
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "x stays increasing");
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        assert_relative_eq!(max(&ys), max(&y));
        assert_relative_eq!(min(&ys), min(&y));
        // Every kept point is a sample of the series.
        for (xk, yk) in xs.iter().zip(&ys) {
            let k = (xk * 1e4).round() as usize;
            assert_relative_eq!(*yk, y[k]);
        }
    }

    #[test]
    fn short_series_pass_through() {
        let (xs, ys) = decimate_minmax(&[1.0, 2.0, 3.0], &[4.0, 5.0], 4000);
        assert_eq!((xs, ys), (vec![1.0, 2.0], vec![4.0, 5.0]));
    }

    #[test]
    fn nan_is_not_an_extreme() {
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let mut y: Vec<f64> = x.iter().map(|v| v.sin()).collect();
        y[0] = f64::NAN;
        let (_, ys) = decimate_minmax(&x, &y, 10);
        assert!(ys.iter().all(|v| v.is_finite()), "{ys:?}");
    }
}
