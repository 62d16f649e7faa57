//! The two-point simulation (thesis §4.2): Figs 60–63, RMSE against distance, and their JSON.
//!
//! The JSON of a fit is [`TwoPointResult`] itself (keys `distance_mm, amplitude, center_mm, width_mm, rmse,
//! sse, points`); one distance gives one object, several an array, and a sweep an array of them.

use vestnav_core::fit::FitError;
use vestnav_core::twopoint::{self, TwoPointResult, TwoPointSetup};
use vestnav_plot::{Chart, Figure, Marker, Scale, Series};

/// Distance up to which the console's RMSE sweep runs by default [mm].
pub const DEFAULT_SWEEP_MAX_MM: f64 = 100.0;
/// Every how many grid points the sum is drawn as a marker in the fitted panel.
const MARKER_STEP: usize = 6;

/// Fits at each of `distances_mm` (thesis §4.2: two Gaussians of the setup summed and fitted by one).
pub fn fits(setup: &TwoPointSetup, distances_mm: &[f64]) -> Result<Vec<TwoPointResult>, FitError> {
    distances_mm.iter().map(|d| twopoint::simulate(setup, *d)).collect()
}

/// RMSE of the single-Gaussian fit against distance, with the detection threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct RmseSweep {
    /// The setup swept.
    pub setup: TwoPointSetup,
    /// One fit per whole millimetre from 0 to the largest distance.
    pub results: Vec<TwoPointResult>,
    /// Detection level: RMSE as a fraction of one tactor's amplitude.
    pub relative_rmse: f64,
    /// Smallest distance whose RMSE reaches the level [mm], if reached.
    pub threshold_mm: Option<f64>,
}

impl RmseSweep {
    /// Sweeps 0, 1, ..., `floor(max_mm)` mm and finds the threshold at `relative_rmse`.
    pub fn compute(setup: &TwoPointSetup, max_mm: f64, relative_rmse: f64) -> Result<Self, FitError> {
        let distances: Vec<f64> = (0..=max_mm.max(0.0).floor() as usize).map(|d| d as f64).collect();
        let results = twopoint::sweep(setup, &distances)?;
        let threshold_mm = twopoint::threshold_mm(setup, relative_rmse, max_mm)?;
        Ok(Self { setup: *setup, results, relative_rmse, threshold_mm })
    }
}

/// For one fit: each tactor and their sum (Figs 60/62), the sum with the fit (Figs 61/63), and the residual.
fn fit_panels(setup: &TwoPointSetup, r: &TwoPointResult) -> [Chart; 3] {
    let x = setup.grid_mm();
    let d = r.distance_mm;
    let g1: Vec<f64> = x.iter().map(|v| setup.single_m_s2(*v, 0.0)).collect();
    let g2: Vec<f64> = x.iter().map(|v| setup.single_m_s2(*v, d)).collect();
    let sum: Vec<f64> = x.iter().map(|v| setup.sum_m_s2(*v, d)).collect();
    let fit: Vec<f64> = x.iter().map(|v| r.eval(*v)).collect();
    let residual: Vec<f64> = sum.iter().zip(&fit).map(|(s, f)| s - f).collect();
    let parts = Chart::new(format!("d = {d} mm: each tactor and the sum (Figs 60/62)"))
        .x_label("position x [mm]")
        .y_label("acceleration amplitude [m/s^2]")
        .series(Series::line("tactor at 0 mm", x.clone(), g1).dashed())
        .series(Series::line(format!("tactor at {d} mm"), x.clone(), g2).dashed())
        .series(Series::line("sum", x.clone(), sum.clone()).width(2.5));
    let xs: Vec<f64> = x.iter().step_by(MARKER_STEP).copied().collect();
    let ys: Vec<f64> = sum.iter().step_by(MARKER_STEP).copied().collect();
    let fitted = Chart::new(format!(
        "d = {d} mm: fit A = {:.3}, mu = {:.2} mm, w = {:.2} mm, RMSE = {:.3e} (Figs 61/63)",
        r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse
    ))
    .x_label("position x [mm]")
    .y_label("acceleration amplitude [m/s^2]")
    .series(Series::scatter("sum of two tactors", xs, ys).marker(Marker::Circle))
    .series(Series::line("single-Gaussian fit", x.clone(), fit).width(2.0))
    .vline(r.center_mm, "mu");
    let resid = Chart::new(format!("d = {d} mm: residual of the fit"))
        .x_label("position x [mm]")
        .y_label("sum - fit [m/s^2]")
        .series(Series::line("residual", x, residual))
        .hline(0.0, "");
    [parts, fitted, resid]
}

/// The thesis's Figs 60–63 for each fit: three panels per distance. What `vestnav sim two-point --png` writes
/// and the console's two-point view exports.
pub fn fits_figure(setup: &TwoPointSetup, results: &[TwoPointResult]) -> Figure {
    let mut fig = Figure::new()
        .title(format!(
            "Two-point simulation (thesis Figs 60-63): two Gaussians of {} m/s^2, b = {} mm, and the single-Gaussian fit",
            setup.amplitude_m_s2, setup.width_mm
        ))
        .columns(3)
        .panel_size(560, 400);
    for r in results {
        for chart in fit_panels(setup, r) {
            fig = fig.push(chart);
        }
    }
    fig
}

/// RMSE against distance on linear and log-log axes, with the detection level, the threshold and the Sparrow
/// limit `sqrt(2) b` (where the sum becomes two-peaked). What `vestnav sim two-point --sweep --png` writes.
pub fn sweep_figure(sweep: &RmseSweep) -> Figure {
    let setup = &sweep.setup;
    let d: Vec<f64> = sweep.results.iter().map(|r| r.distance_mm).collect();
    let rmse: Vec<f64> = sweep.results.iter().map(|r| r.rmse).collect();
    let level = sweep.relative_rmse * setup.amplitude_m_s2;
    let sparrow = setup.sparrow_limit_mm();
    let mut linear = Chart::new(format!(
        "RMSE of the single-Gaussian fit (b = {} mm, 2 x {} m/s^2)",
        setup.width_mm, setup.amplitude_m_s2
    ))
    .x_label("distance between tactors d [mm]")
    .y_label("RMSE [m/s^2]")
    .series(Series::line("RMSE", d.clone(), rmse.clone()).width(2.0))
    .hline(level, format!("detection level {level:.2} m/s^2"))
    .vline(sparrow, format!("two peaks (sqrt(2) b = {sparrow:.1} mm)"));
    if let Some(t) = sweep.threshold_mm {
        linear = linear.vline(t, format!("threshold {t:.1} mm"));
    }
    let (d_log, r_log): (Vec<f64>, Vec<f64>) =
        d.iter().zip(&rmse).filter(|(x, y)| **x > 0.0 && **y > 0.0).map(|(x, y)| (*x, *y)).unzip();
    let c4 = r_log.first().zip(d_log.first()).map_or(0.0, |(r, d)| r / d.powi(4));
    let d4: Vec<f64> = d_log.iter().map(|x| c4 * x.powi(4)).collect();
    let mut log = Chart::new("The same on log-log axes: RMSE grows as d^4 for small d")
        .x_label("distance between tactors d [mm]")
        .y_label("RMSE [m/s^2]")
        .x_scale(Scale::Log10)
        .y_scale(Scale::Log10)
        .series(Series::line("RMSE", d_log.clone(), r_log).width(2.0))
        .series(Series::line("c d^4", d_log, d4).dashed())
        .hline(level, "detection level");
    if let Some(t) = sweep.threshold_mm {
        log = log.vline(t, "threshold");
    }
    Figure::new()
        .title("Two-point threshold from the RMSE sweep (thesis §4.2)")
        .columns(2)
        .panel_size(640, 420)
        .push(linear)
        .push(log)
}

/// The setup and each fit, one line each (the CSV header and the console's readout).
pub fn header(setup: &TwoPointSetup, results: &[TwoPointResult]) -> Vec<String> {
    let mut lines = vec![format!(
        "setup: a = {} m/s^2 each, b = {} mm, grid {}..{} mm step {} mm; Sparrow limit sqrt(2) b = {:.2} mm",
        setup.amplitude_m_s2,
        setup.width_mm,
        setup.grid_start_mm,
        setup.grid_end_mm,
        setup.grid_step_mm,
        setup.sparrow_limit_mm()
    )];
    for r in results {
        lines.push(format!(
            "d = {} mm: A = {:.4}, mu = {:.4} mm, w = {:.4} mm, RMSE = {:.6e} (sqrt(SSE/(n-3)), n = {})",
            r.distance_mm, r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse, r.points
        ));
    }
    lines
}

/// JSON of fits: one object for one distance, an array for several (`vestnav sim two-point --json`).
pub fn fits_json(results: &[TwoPointResult]) -> Result<String, serde_json::Error> {
    match results {
        [one] => crate::to_json(one),
        many => crate::to_json(many),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn one_fit_is_an_object_several_an_array() {
        let setup = TwoPointSetup::THESIS;
        let one = fits(&setup, &[11.0]).unwrap();
        let v: serde_json::Value = serde_json::from_str(&fits_json(&one).unwrap()).unwrap();
        // physics.md §3 at d = 11 mm: A = 19.546, mu = 5.5, w = 37.045, RMSE = 0.001727.
        assert_relative_eq!(v["amplitude"].as_f64().unwrap(), 19.546, max_relative = 1e-4);
        assert_relative_eq!(v["center_mm"].as_f64().unwrap(), 5.5, max_relative = 1e-4);
        let two = fits(&setup, &[11.0, 50.0]).unwrap();
        let v: serde_json::Value = serde_json::from_str(&fits_json(&two).unwrap()).unwrap();
        assert_eq!(v.as_array().map(Vec::len), Some(2));
        let back: Vec<TwoPointResult> = serde_json::from_value(v).unwrap();
        assert_relative_eq!(back[1].rmse, two[1].rmse, max_relative = 1e-12);
        assert_eq!(fits_figure(&setup, &two).panels.len(), 6);
    }

    #[test]
    fn sweep_starts_at_an_exact_gaussian_and_finds_the_threshold_below_sparrow() {
        let sweep =
            RmseSweep::compute(&TwoPointSetup::THESIS, 60.0, twopoint::DEFAULT_RELATIVE_RMSE).unwrap();
        assert_eq!(sweep.results.len(), 61);
        // d = 0: one Gaussian of 2 x 10 m/s^2 and width b, fitted exactly.
        assert!(sweep.results[0].rmse < 1e-8);
        assert_relative_eq!(sweep.results[0].amplitude_m_s2, 20.0, max_relative = 1e-9);
        let t = sweep.threshold_mm.unwrap();
        assert!(t > 11.0 && t < 2f64.sqrt() * 36.2, "{t}");
        assert_eq!(sweep_figure(&sweep).panels.len(), 2);
    }
}
