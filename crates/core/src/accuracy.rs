//! GPS accuracy against the truth: a reference point and the error of every fix from it.
//!
//! The drift test of [`crate::fieldtest`] measures *precision* (scatter about the receiver's own first fix
//! or mean). Accuracy needs a truth: a [`Reference`] — a surveyed marker typed in (any form of
//! [`crate::coords::parse_position`]), a GPX waypoint, or the average of minutes of good fixes — with its own
//! stated uncertainty. Against it, [`accuracy`] gives the horizontal error over time, the bias east/north,
//! the radii below, the share of fixes within 0.1 / 0.5 / 1 / 2 / 5 m and the vertical error;
//! [`cones_against_reference`] gives each cone mark's error from where the cone really stands;
//! [`compare`] matches the epochs of several receivers by receiver time and gives their differences.
//!
//! **Definitions** (all horizontal errors are east/north vectors `e_i` of fix `i` in the
//! [`LocalFrame`] centred on the reference, so `|e_i|` is the geodesic distance from the reference):
//! - bias `b = (1/n) sum e_i`; `sigma_e`, `sigma_n`: population standard deviations about `b` (1/n);
//! - **measured** radii: `CEP50` and `CEP95` are the nearest-rank 50th and 95th percentiles of `|e_i|`
//!   (see [`percentile_nearest_rank`]): always a measured distance, bias included. `CEP95` is what some
//!   tools call the measured `R95`;
//! - `DRMS = sqrt((1/n) sum |e_i|^2) = sqrt(|b|^2 + sigma_e^2 + sigma_n^2)` (exact), `2DRMS = 2 DRMS`;
//! - **Gaussian approximations** from the scatter alone (bias not included, for comparison with datasheets
//!   and `RTKLIB`): `CEP50 ≈ 0.589 (sigma_e + sigma_n)` (within a few percent while
//!   `sigma_min / sigma_max > 0.3`); `R95 ≈ 2.0789 CEP50` (the circular case:
//!   `sqrt(2 ln 20) / sqrt(2 ln 2)`); `2DRMS = 2 sqrt(sigma_e^2 + sigma_n^2)` (95.4 % to 98.2 % depending on
//!   the ellipse). For a circular Gaussian with per-axis `sigma` the exact values are
//!   `CEP50 = sigma sqrt(2 ln 2) = 1.1774 sigma` and `R95 = sigma sqrt(2 ln 20) = 2.4477 sigma`.
//! - vertical error `h_i - h_ref` with `h` the height above mean sea level (the GGA altitude): its mean,
//!   RMS, and the nearest-rank P95 of `|h_i - h_ref|`.
//!
//! ```
//! use vestnav_core::accuracy::{accuracy, Reference, Sample};
//! use vestnav_core::geo::{Earth, LatLon};
//! let truth = LatLon::new(42.3575, -71.1010);
//! // Eight fixes on a 2 m circle around the marker: every error is 2 m, the bias is zero.
//! let fixes: Vec<_> = (0..8)
//!     .map(|i| Sample::new(f64::from(i), Earth::Wgs84.direct(truth, 45.0 * f64::from(i), 2.0)))
//!     .collect();
//! let s = accuracy(&fixes, &Reference::typed(truth, 0.01), Earth::Wgs84).unwrap();
//! assert!((s.cep50_m - 2.0).abs() < 1e-6 && (s.drms_m - 2.0).abs() < 1e-6 && s.bias_m < 1e-6);
//! ```

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::fieldtest::{FieldTestError, TimedFix, percentile_nearest_rank};
use crate::geo::{Earth, LatLon, LocalFrame};

/// The thresholds of [`AccuracyStats::within`] [m].
pub const WITHIN_M: [f64; 5] = [0.1, 0.5, 1.0, 2.0, 5.0];

/// `sqrt(2 ln 20) / sqrt(2 ln 2)`: R95 over CEP50 for a circular Gaussian.
pub const R95_PER_CEP50: f64 = 2.078_9;

/// Where a reference position came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ReferenceOrigin {
    /// Typed by the operator (a surveyed marker's published coordinates).
    Typed {
        /// The text as typed (`None` when given as numbers).
        text: Option<String>,
    },
    /// A waypoint of a GPX file.
    Waypoint {
        /// The file.
        file: String,
        /// The waypoint's name.
        name: String,
    },
    /// The mean of the good fixes of a window.
    Averaged {
        /// Fixes averaged.
        fixes: usize,
        /// Start of the window [s] on the fixes' time line.
        from_s: f64,
        /// Length of the window [s].
        duration_s: f64,
    },
}

/// The truth the fixes are measured against, with its own uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// The reference position.
    pub pos: LatLon,
    /// Its height above mean sea level [m], if known (vertical error needs it).
    pub height_m: Option<f64>,
    /// Its stated horizontal uncertainty (1 sigma, radial) [m]: the survey's figure, or for an averaged
    /// reference the DRMS of the averaged fixes about their mean.
    pub uncertainty_m: f64,
    /// Its stated vertical uncertainty (1 sigma) [m], if known.
    pub height_uncertainty_m: Option<f64>,
    /// Where it came from.
    pub origin: ReferenceOrigin,
}

impl Reference {
    /// A typed reference without height.
    pub fn typed(pos: LatLon, uncertainty_m: f64) -> Self {
        Self {
            pos,
            height_m: None,
            uncertainty_m,
            height_uncertainty_m: None,
            origin: ReferenceOrigin::Typed { text: None },
        }
    }

    /// The one-line description of the reference, for reports.
    pub fn describe(&self) -> String {
        let what = match &self.origin {
            ReferenceOrigin::Typed { text: Some(t) } => format!("typed \"{t}\""),
            ReferenceOrigin::Typed { text: None } => "typed".to_string(),
            ReferenceOrigin::Waypoint { file, name } => format!("waypoint \"{name}\" of {file}"),
            ReferenceOrigin::Averaged { fixes, from_s, duration_s } => {
                format!("mean of {fixes} fixes over {duration_s:.0} s from t = {from_s:.0} s")
            }
        };
        format!("{:.8}, {:.8} ± {:.3} m ({what})", self.pos.lat_deg, self.pos.lon_deg, self.uncertainty_m)
    }
}

/// One fix for the accuracy statistics: time, position and (optional) height above mean sea level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Time [s] (the receiver's time where known; any origin).
    pub t_s: f64,
    /// Position.
    pub pos: LatLon,
    /// Height above mean sea level [m] (GGA altitude).
    pub height_m: Option<f64>,
}

impl Sample {
    /// A sample without height.
    pub fn new(t_s: f64, pos: LatLon) -> Self {
        Self { t_s, pos, height_m: None }
    }

    fn is_valid(&self) -> bool {
        TimedFix { t_s: self.t_s, pos: self.pos }.is_valid() && self.height_m.is_none_or(f64::is_finite)
    }
}

/// Averages the fixes from `from_s` for `duration_s` seconds into a reference (the caller passes only
/// good fixes, e.g. those with a 3-D or corrected fix). Mean east/north in a frame on the first fix,
/// mapped back; height: the mean of the heights present. Its uncertainty is the DRMS of the averaged fixes
/// about their mean — deliberately not divided by `sqrt(n)`: GPS errors are correlated over minutes, so
/// averaging does not shrink them that fast. An averaged reference hides the receiver's own bias:
/// accuracy against it is precision.
pub fn average_reference(
    samples: &[Sample],
    from_s: f64,
    duration_s: f64,
    earth: Earth,
) -> Result<Reference, FieldTestError> {
    if !(duration_s.is_finite() && duration_s > 0.0 && from_s.is_finite()) {
        return Err(FieldTestError::BadSetting("the averaging window must be a positive number of seconds"));
    }
    let window: Vec<&Sample> =
        samples.iter().filter(|s| s.is_valid() && s.t_s >= from_s && s.t_s <= from_s + duration_s).collect();
    let [first, ..] = window.as_slice() else {
        return Err(FieldTestError::TooFew { what: "fixes in the averaging window", have: 0, need: 1 });
    };
    let n = window.len() as f64;
    let frame0 = LocalFrame::new(first.pos, earth);
    let mean = frame0.wgs84_from_enu(window.iter().map(|s| frame0.enu_from_wgs84(s.pos)).sum::<DVec2>() / n);
    let frame = LocalFrame::new(mean, earth);
    let drms = (window.iter().map(|s| frame.enu_from_wgs84(s.pos).length_squared()).sum::<f64>() / n).sqrt();
    let heights: Vec<f64> = window.iter().filter_map(|s| s.height_m).collect();
    let (height_m, height_uncertainty_m) = if heights.is_empty() {
        (None, None)
    } else {
        let m = heights.iter().sum::<f64>() / heights.len() as f64;
        let sd = (heights.iter().map(|h| (h - m).powi(2)).sum::<f64>() / heights.len() as f64).sqrt();
        (Some(m), Some(sd))
    };
    let span = window.last().map_or(0.0, |l| l.t_s - first.t_s);
    Ok(Reference {
        pos: mean,
        height_m,
        uncertainty_m: drms,
        height_uncertainty_m,
        origin: ReferenceOrigin::Averaged { fixes: window.len(), from_s: first.t_s, duration_s: span },
    })
}

/// The vertical error against the reference's height.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerticalStats {
    /// Fixes with a height.
    pub fixes: usize,
    /// Mean of `h_i - h_ref` [m].
    pub bias_m: f64,
    /// RMS of `h_i - h_ref` [m].
    pub rms_m: f64,
    /// Nearest-rank P95 of `|h_i - h_ref|` [m].
    pub p95_abs_m: f64,
    /// Largest `|h_i - h_ref|` [m].
    pub max_abs_m: f64,
    /// Time of each fix with a height, relative to the first fix [s].
    pub t_s: Vec<f64>,
    /// `h_i - h_ref` of each of those fixes [m].
    pub error_m: Vec<f64>,
}

/// The Gaussian approximations of the radii, from the scatter about the bias (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianRadii {
    /// `0.589 (sigma_e + sigma_n)` [m].
    pub cep50_m: f64,
    /// `2.0789 * cep50_m` [m].
    pub r95_m: f64,
    /// `sqrt(sigma_e^2 + sigma_n^2)` [m].
    pub drms_m: f64,
    /// `2 drms_m` [m].
    pub twodrms_m: f64,
}

impl GaussianRadii {
    /// The approximations from the per-axis standard deviations [m].
    pub fn from_sigmas(sigma_e_m: f64, sigma_n_m: f64) -> Self {
        let cep50 = 0.589 * (sigma_e_m + sigma_n_m);
        let drms = sigma_e_m.hypot(sigma_n_m);
        Self { cep50_m: cep50, r95_m: R95_PER_CEP50 * cep50, drms_m: drms, twodrms_m: 2.0 * drms }
    }
}

/// The share of fixes within one radius.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Within {
    /// The radius [m].
    pub radius_m: f64,
    /// Fixes with `|e_i| <= radius_m`, over all fixes (0..=1).
    pub share: f64,
}

/// Accuracy of a set of fixes against a reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AccuracyStats {
    /// Fixes used.
    pub fixes: usize,
    /// Fixes skipped as invalid (non-finite or out-of-range time, position or height).
    pub skipped_invalid: usize,
    /// Time from the first to the last fix [s].
    pub duration_s: f64,
    /// The reference position (origin of the east/north errors).
    pub reference: LatLon,
    /// The reference's stated horizontal uncertainty [m].
    pub reference_uncertainty_m: f64,
    /// Mean error east/north (the bias) [m].
    pub bias_en_m: [f64; 2],
    /// Length of the bias [m].
    pub bias_m: f64,
    /// Standard deviation east/north about the bias [m] (population, 1/n).
    pub sigma_en_m: [f64; 2],
    /// Measured CEP50: nearest-rank P50 of the horizontal error [m].
    pub cep50_m: f64,
    /// Measured CEP95 (= measured R95): nearest-rank P95 of the horizontal error [m].
    pub cep95_m: f64,
    /// `sqrt((1/n) sum |e_i|^2)` [m], bias included.
    pub drms_m: f64,
    /// `2 drms_m` [m].
    pub twodrms_m: f64,
    /// Largest horizontal error [m].
    pub max_m: f64,
    /// Gaussian approximations from the scatter (bias not included).
    pub gaussian: GaussianRadii,
    /// Share of fixes within each of [`WITHIN_M`].
    pub within: Vec<Within>,
    /// The vertical error, when the reference and some fixes have a height.
    pub vertical: Option<VerticalStats>,
    /// Time of each fix relative to the first [s].
    pub t_s: Vec<f64>,
    /// East/north error of each fix [m].
    pub error_en_m: Vec<DVec2>,
    /// Horizontal error of each fix [m].
    pub error_m: Vec<f64>,
    /// Warnings (reference uncertainty not small against the errors, invalid fixes skipped).
    pub warnings: Vec<String>,
}

impl AccuracyStats {
    /// The share of fixes within `radius_m` (one of [`WITHIN_M`]), if computed.
    pub fn share_within(&self, radius_m: f64) -> Option<f64> {
        self.within.iter().find(|w| (w.radius_m - radius_m).abs() < 1e-12).map(|w| w.share)
    }
}

/// Accuracy of `samples` against `reference` (see the module doc for every definition).
pub fn accuracy(
    samples: &[Sample],
    reference: &Reference,
    earth: Earth,
) -> Result<AccuracyStats, FieldTestError> {
    let truths = vec![reference.pos; samples.len()];
    let mut s = against_points(samples, &truths, reference.pos, earth)?;
    s.reference_uncertainty_m = reference.uncertainty_m;
    if let Some(h_ref) = reference.height_m.filter(|h| h.is_finite()) {
        let t0 = samples.iter().find(|x| x.is_valid()).map_or(0.0, |x| x.t_s);
        let (t, err): (Vec<f64>, Vec<f64>) = samples
            .iter()
            .filter(|x| x.is_valid())
            .filter_map(|x| Some((x.t_s - t0, x.height_m? - h_ref)))
            .unzip();
        if !err.is_empty() {
            let n = err.len() as f64;
            let abs: Vec<f64> = err.iter().map(|e| e.abs()).collect();
            s.vertical = Some(VerticalStats {
                fixes: err.len(),
                bias_m: err.iter().sum::<f64>() / n,
                rms_m: (err.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
                p95_abs_m: percentile_nearest_rank(&abs, 95.0).unwrap_or(0.0),
                max_abs_m: abs.iter().copied().fold(0.0, f64::max),
                t_s: t,
                error_m: err,
            });
        }
    }
    if reference.uncertainty_m.is_finite() && reference.uncertainty_m > s.cep50_m / 3.0 {
        s.warnings.push(format!(
            "the reference's own uncertainty ({:.3} m) is not small against the measured CEP50 ({:.3} m): \
             the errors below are partly the reference's",
            reference.uncertainty_m, s.cep50_m
        ));
    }
    if matches!(reference.origin, ReferenceOrigin::Averaged { .. }) {
        s.warnings.push(
            "the reference is the receiver's own average: the errors measure precision, not the receiver's bias"
                .to_string(),
        );
    }
    Ok(s)
}

/// The horizontal statistics of fixes each against its own truth (`truths[i]` for `samples[i]`), with the
/// errors expressed in the frame of `origin` (east/north of the truth-to-fix vector, each measured in a frame
/// on its truth: exact distances and bearings).
fn against_points(
    samples: &[Sample],
    truths: &[LatLon],
    origin: LatLon,
    earth: Earth,
) -> Result<AccuracyStats, FieldTestError> {
    let pairs: Vec<(&Sample, &LatLon)> = samples.iter().zip(truths).filter(|(s, _)| s.is_valid()).collect();
    let skipped_invalid = samples.len() - pairs.len();
    let [(first, _), ..] = pairs.as_slice() else {
        return Err(FieldTestError::TooFew { what: "valid fixes", have: 0, need: 1 });
    };
    let t0 = first.t_s;
    let errors: Vec<DVec2> =
        pairs.iter().map(|(s, truth)| LocalFrame::new(**truth, earth).enu_from_wgs84(s.pos)).collect();
    let n = errors.len() as f64;
    let radial: Vec<f64> = errors.iter().map(|e| e.length()).collect();
    let bias = errors.iter().sum::<DVec2>() / n;
    let var = errors.iter().map(|e| (*e - bias) * (*e - bias)).sum::<DVec2>() / n;
    let (sigma_e, sigma_n) = (var.x.sqrt(), var.y.sqrt());
    let drms = (radial.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let within = WITHIN_M
        .iter()
        .map(|&r| Within { radius_m: r, share: radial.iter().filter(|e| **e <= r).count() as f64 / n })
        .collect();
    let mut warnings = Vec::new();
    if skipped_invalid > 0 {
        warnings.push(format!("{skipped_invalid} invalid fixes skipped (non-finite or out-of-range)"));
    }
    Ok(AccuracyStats {
        fixes: pairs.len(),
        skipped_invalid,
        duration_s: pairs.last().map_or(0.0, |(l, _)| l.t_s - t0),
        reference: origin,
        reference_uncertainty_m: 0.0,
        bias_en_m: [bias.x, bias.y],
        bias_m: bias.length(),
        sigma_en_m: [sigma_e, sigma_n],
        cep50_m: percentile_nearest_rank(&radial, 50.0).unwrap_or(0.0),
        cep95_m: percentile_nearest_rank(&radial, 95.0).unwrap_or(0.0),
        drms_m: drms,
        twodrms_m: 2.0 * drms,
        max_m: radial.iter().copied().fold(0.0, f64::max),
        gaussian: GaussianRadii::from_sigmas(sigma_e, sigma_n),
        within,
        vertical: None,
        t_s: pairs.iter().map(|(s, _)| s.t_s - t0).collect(),
        error_en_m: errors,
        error_m: radial,
        warnings,
    })
}

/// Where the cones of a cone test really stand: cone `k` (0-based) at `k * spacing_m` along the geodesic
/// from `first_cone` at bearing `line_bearing_deg` (true).
pub fn cone_positions(
    first_cone: LatLon,
    line_bearing_deg: f64,
    spacing_m: f64,
    count: usize,
    earth: Earth,
) -> Vec<LatLon> {
    (0..count).map(|k| earth.direct(first_cone, line_bearing_deg, k as f64 * spacing_m)).collect()
}

/// Each cone mark against where its cone really stands: mark `k` against cone `k` of [`cone_positions`]
/// (the reference is the first cone, surveyed). The statistics' `t_s` are the marks' times from the first;
/// errors east/north are in frames on each cone.
pub fn cones_against_reference(
    marks: &[crate::fieldtest::ConeMark],
    reference: &Reference,
    line_bearing_deg: f64,
    spacing_m: f64,
    earth: Earth,
) -> Result<AccuracyStats, FieldTestError> {
    if !(spacing_m.is_finite() && spacing_m > 0.0 && line_bearing_deg.is_finite()) {
        return Err(FieldTestError::BadSetting("spacing and line bearing must be finite, spacing positive"));
    }
    let truths = cone_positions(reference.pos, line_bearing_deg, spacing_m, marks.len(), earth);
    let samples: Vec<Sample> = marks.iter().map(|m| Sample::new(m.t_s, m.pos)).collect();
    let mut s = against_points(&samples, &truths, reference.pos, earth)?;
    s.reference_uncertainty_m = reference.uncertainty_m;
    Ok(s)
}

/// One receiver's fixes for [`compare`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Receiver {
    /// Its name (e.g. the log file).
    pub name: String,
    /// Its fixes, times on the receiver's clock (UTC seconds; any common origin).
    pub samples: Vec<Sample>,
}

/// One receiver's difference from the first receiver over the matched epochs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Difference {
    /// The receiver's name.
    pub name: String,
    /// Mean of (this − first) east/north [m].
    pub mean_en_m: [f64; 2],
    /// RMS of the horizontal distance between the two [m].
    pub rms_m: f64,
    /// Nearest-rank P95 of that distance [m].
    pub p95_m: f64,
    /// Largest distance [m].
    pub max_m: f64,
    /// The distance at each matched epoch [m].
    pub distance_m: Vec<f64>,
}

/// Several receivers side by side.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// The receivers' names, in order.
    pub names: Vec<String>,
    /// Matching tolerance [s].
    pub tolerance_s: f64,
    /// Epochs at which every receiver has a fix.
    pub matched_epochs: usize,
    /// Time of each matched epoch (the first receiver's) from the first matched epoch [s].
    pub t_s: Vec<f64>,
    /// Every other receiver against the first, at the matched epochs.
    pub differences: Vec<Difference>,
    /// Each receiver against the reference, over all its fixes (`None` without reference or fixes).
    pub against_reference: Vec<Option<AccuracyStats>>,
    /// Warnings.
    pub warnings: Vec<String>,
}

impl Comparison {
    /// The same numbers without their per-epoch series (the matched times, each receiver's distance at each
    /// epoch, each fix's error against the reference): what a status line or a remote view shows, a few
    /// hundred bytes where the series of a day at 1 Hz are megabytes.
    #[must_use]
    pub fn without_series(&self) -> Self {
        let mut c = self.clone();
        c.t_s = Vec::new();
        for d in &mut c.differences {
            d.distance_m = Vec::new();
        }
        for s in c.against_reference.iter_mut().flatten() {
            s.t_s = Vec::new();
            s.error_en_m = Vec::new();
            s.error_m = Vec::new();
            if let Some(v) = &mut s.vertical {
                v.t_s = Vec::new();
                v.error_m = Vec::new();
            }
        }
        c
    }
}

/// Matches the receivers' epochs by receiver time (an epoch of the first receiver matches the nearest fix of
/// each other receiver within `tolerance_s`; each fix is used at most once since the fixes are 1 Hz or
/// faster and the tolerance is below half their period), gives each other receiver's horizontal distance
/// from the first at the matched epochs, and each receiver against `reference` over all its fixes.
pub fn compare(
    receivers: &[Receiver],
    reference: Option<&Reference>,
    tolerance_s: f64,
    earth: Earth,
) -> Result<Comparison, FieldTestError> {
    if receivers.len() < 2 {
        return Err(FieldTestError::TooFew { what: "receivers", have: receivers.len(), need: 2 });
    }
    if !(tolerance_s.is_finite() && tolerance_s >= 0.0) {
        return Err(FieldTestError::BadSetting(
            "the matching tolerance must be a non-negative number of seconds",
        ));
    }
    let sorted: Vec<Vec<Sample>> = receivers
        .iter()
        .map(|r| {
            let mut v: Vec<Sample> = r.samples.iter().copied().filter(Sample::is_valid).collect();
            v.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
            v
        })
        .collect();
    let [base, others @ ..] = sorted.as_slice() else {
        return Err(FieldTestError::TooFew { what: "receivers", have: 0, need: 2 });
    };
    // For each base epoch, the index of the matching fix in each other receiver.
    let mut matched: Vec<(f64, LatLon, Vec<LatLon>)> = Vec::new();
    for b in base {
        let mut row = Vec::with_capacity(others.len());
        for o in others {
            let i = o.partition_point(|x| x.t_s < b.t_s);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|k| o.get(k))
                .min_by(|x, y| (x.t_s - b.t_s).abs().total_cmp(&(y.t_s - b.t_s).abs()));
            match nearest {
                Some(x) if (x.t_s - b.t_s).abs() <= tolerance_s => row.push(x.pos),
                _ => break,
            }
        }
        if row.len() == others.len() {
            matched.push((b.t_s, b.pos, row));
        }
    }
    let t0 = matched.first().map_or(0.0, |m| m.0);
    let differences = others
        .iter()
        .enumerate()
        .map(|(k, _)| {
            let en: Vec<DVec2> = matched
                .iter()
                .filter_map(|(_, a, row)| row.get(k).map(|p| LocalFrame::new(*a, earth).enu_from_wgs84(*p)))
                .collect();
            let n = en.len().max(1) as f64;
            let d: Vec<f64> = en.iter().map(|v| v.length()).collect();
            let mean = en.iter().sum::<DVec2>() / n;
            Difference {
                name: receivers.get(k + 1).map_or_else(String::new, |r| r.name.clone()),
                mean_en_m: [mean.x, mean.y],
                rms_m: (d.iter().map(|x| x * x).sum::<f64>() / n).sqrt(),
                p95_m: percentile_nearest_rank(&d, 95.0).unwrap_or(0.0),
                max_m: d.iter().copied().fold(0.0, f64::max),
                distance_m: d,
            }
        })
        .collect();
    let against_reference =
        sorted.iter().map(|s| reference.and_then(|r| accuracy(s, r, earth).ok())).collect();
    let mut warnings = Vec::new();
    if matched.is_empty() {
        warnings.push(format!(
            "no epoch matched within {tolerance_s} s: are the logs from the same session, with receiver times?"
        ));
    }
    Ok(Comparison {
        names: receivers.iter().map(|r| r.name.clone()).collect(),
        tolerance_s,
        matched_epochs: matched.len(),
        t_s: matched.iter().map(|m| m.0 - t0).collect(),
        differences,
        against_reference,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::SeedableRng as _;
    use rand_distr::{Distribution as _, Normal};

    const TRUTH: LatLon = LatLon { lat_deg: 42.3575, lon_deg: -71.1010 };

    fn at(en: DVec2) -> LatLon {
        LocalFrame::new(TRUTH, Earth::Wgs84).wgs84_from_enu(en)
    }

    /// A ring of points at a known radius about the truth: every error is the radius; the bias is zero;
    /// `sigma_e = sigma_n = R / sqrt(2)` (the mean of `sin^2` over a full turn is 1/2).
    #[test]
    fn a_ring_at_known_radius() {
        let r = 3.0;
        let fixes: Vec<Sample> = (0..360)
            .map(|k| {
                let a = f64::from(k).to_radians();
                Sample::new(f64::from(k), at(DVec2::new(r * a.sin(), r * a.cos())))
            })
            .collect();
        let s = accuracy(&fixes, &Reference::typed(TRUTH, 0.0), Earth::Wgs84).unwrap();
        assert_relative_eq!(s.cep50_m, r, max_relative = 1e-9);
        assert_relative_eq!(s.cep95_m, r, max_relative = 1e-9);
        assert_relative_eq!(s.drms_m, r, max_relative = 1e-9);
        assert!(s.bias_m < 1e-9);
        assert_relative_eq!(s.sigma_en_m[0], r / 2f64.sqrt(), max_relative = 1e-9);
        assert_relative_eq!(s.sigma_en_m[1], r / 2f64.sqrt(), max_relative = 1e-9);
        assert_relative_eq!(s.gaussian.drms_m, r, max_relative = 1e-9);
        assert_relative_eq!(s.gaussian.cep50_m, 0.589 * 2.0 * r / 2f64.sqrt(), max_relative = 1e-9);
        assert_eq!(s.share_within(2.0), Some(0.0));
        assert_eq!(s.share_within(5.0), Some(1.0));
    }

    /// A circular Gaussian sample with per-axis sigma and a known bias: the measured radii about the mean
    /// match the Rayleigh closed forms (CEP50 = 1.1774 sigma, R95 = 2.4477 sigma), the Gaussian formulas
    /// give the same, the bias is recovered, and `DRMS^2 = |b|^2 + sigma_e^2 + sigma_n^2` exactly.
    #[test]
    fn a_circular_gaussian_with_known_sigma() {
        let sigma = 1.5;
        let bias = DVec2::new(0.8, -0.6);
        let mut rng = rand::rngs::StdRng::seed_from_u64(27);
        let normal = Normal::new(0.0, sigma).unwrap();
        let n = 40_000;
        let en: Vec<DVec2> =
            (0..n).map(|_| DVec2::new(normal.sample(&mut rng), normal.sample(&mut rng))).collect();
        // About the truth with a bias...
        let biased: Vec<Sample> =
            en.iter().enumerate().map(|(i, e)| Sample::new(i as f64, at(*e + bias))).collect();
        let s = accuracy(&biased, &Reference::typed(TRUTH, 0.0), Earth::Wgs84).unwrap();
        assert_relative_eq!(s.bias_en_m[0], 0.8, epsilon = 0.03);
        assert_relative_eq!(s.bias_en_m[1], -0.6, epsilon = 0.03);
        assert_relative_eq!(s.sigma_en_m[0], sigma, max_relative = 0.02);
        let exact = s.bias_m.powi(2) + s.sigma_en_m[0].powi(2) + s.sigma_en_m[1].powi(2);
        assert_relative_eq!(s.drms_m.powi(2), exact, max_relative = 1e-6);
        // ...and without: measured radii against the Rayleigh distribution's quantiles.
        let centred: Vec<Sample> =
            en.iter().enumerate().map(|(i, e)| Sample::new(i as f64, at(*e))).collect();
        let s = accuracy(&centred, &Reference::typed(TRUTH, 0.0), Earth::Wgs84).unwrap();
        let cep50 = sigma * (2.0 * 2f64.ln()).sqrt();
        let r95 = sigma * (2.0 * 20f64.ln()).sqrt();
        assert_relative_eq!(s.cep50_m, cep50, max_relative = 0.02);
        assert_relative_eq!(s.cep95_m, r95, max_relative = 0.02);
        assert_relative_eq!(s.gaussian.cep50_m, cep50, max_relative = 0.02);
        assert_relative_eq!(s.gaussian.r95_m, r95, max_relative = 0.02);
        assert_relative_eq!(s.gaussian.twodrms_m, 2.0 * 2f64.sqrt() * sigma, max_relative = 0.02);
        // Share within 1 m: 1 - exp(-1 / (2 sigma^2)).
        let within1 = 1.0 - (-1.0 / (2.0 * sigma * sigma)).exp();
        assert_relative_eq!(s.share_within(1.0).unwrap(), within1, epsilon = 0.01);
    }

    #[test]
    fn vertical_error_and_invalid_fixes() {
        let mut fixes: Vec<Sample> = [1.0, -1.0, 3.0, -3.0]
            .iter()
            .enumerate()
            .map(|(i, dh)| Sample { t_s: i as f64, pos: TRUTH, height_m: Some(10.0 + dh) })
            .collect();
        fixes.push(Sample { t_s: 9.0, pos: LatLon::new(f64::NAN, 0.0), height_m: None });
        let reference = Reference { height_m: Some(10.0), ..Reference::typed(TRUTH, 0.0) };
        let s = accuracy(&fixes, &reference, Earth::Wgs84).unwrap();
        assert_eq!((s.fixes, s.skipped_invalid), (4, 1));
        let v = s.vertical.unwrap();
        assert_relative_eq!(v.bias_m, 0.0, epsilon = 1e-12);
        assert_relative_eq!(v.rms_m, 5f64.sqrt(), max_relative = 1e-12);
        assert_relative_eq!(v.max_abs_m, 3.0);
        assert!(accuracy(&[], &reference, Earth::Wgs84).is_err());
    }

    #[test]
    fn an_averaged_reference_is_the_mean_with_its_scatter() {
        // Four fixes at +-1 m east and north of the truth in the window, one far outside it.
        let mut fixes: Vec<Sample> = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            .iter()
            .enumerate()
            .map(|(i, (e, n))| Sample {
                t_s: 10.0 + i as f64,
                pos: at(DVec2::new(*e, *n)),
                height_m: Some(5.0),
            })
            .collect();
        fixes.push(Sample::new(100.0, at(DVec2::new(50.0, 0.0))));
        let r = average_reference(&fixes, 10.0, 60.0, Earth::Wgs84).unwrap();
        assert!(Earth::Wgs84.distance_m(r.pos, TRUTH) < 1e-6);
        assert_relative_eq!(r.uncertainty_m, 1.0, max_relative = 1e-6);
        assert_eq!(r.height_m, Some(5.0));
        assert!(matches!(r.origin, ReferenceOrigin::Averaged { fixes: 4, .. }));
        assert!(average_reference(&fixes, 200.0, 60.0, Earth::Wgs84).is_err());
        assert!(average_reference(&fixes, 0.0, -1.0, Earth::Wgs84).is_err());
    }

    #[test]
    fn cone_marks_against_the_surveyed_line() {
        // Cones every 10 m at 30° true from the surveyed first cone; each mark 0.5 m east of its cone.
        let cones = cone_positions(TRUTH, 30.0, 10.0, 6, Earth::Wgs84);
        let marks: Vec<_> = cones
            .iter()
            .enumerate()
            .map(|(k, c)| crate::fieldtest::ConeMark {
                t_s: 10.0 * k as f64,
                label: format!("cone {k}"),
                pos: Earth::Wgs84.direct(*c, 90.0, 0.5),
            })
            .collect();
        let s = cones_against_reference(&marks, &Reference::typed(TRUTH, 0.02), 30.0, 10.0, Earth::Wgs84)
            .unwrap();
        assert_eq!(s.fixes, 6);
        assert_relative_eq!(s.bias_en_m[0], 0.5, max_relative = 1e-6);
        assert!(s.bias_en_m[1].abs() < 1e-6);
        assert_relative_eq!(s.cep95_m, 0.5, max_relative = 1e-6);
    }

    #[test]
    fn receivers_match_by_time_and_differ_by_their_offset() {
        let a: Vec<Sample> = (0..100).map(|k| Sample::new(f64::from(k), TRUTH)).collect();
        // B: 2 m north, its epochs 30 ms late, one epoch missing; C: 1 m east with an unrelated clock.
        let b: Vec<Sample> = (0..100)
            .filter(|k| *k != 50)
            .map(|k| Sample::new(f64::from(k) + 0.03, at(DVec2::new(0.0, 2.0))))
            .collect();
        let c: Vec<Sample> = (0..100).map(|k| Sample::new(f64::from(k), at(DVec2::new(1.0, 0.0)))).collect();
        let rx = |name: &str, samples: Vec<Sample>| Receiver { name: name.into(), samples };
        let reference = Reference::typed(TRUTH, 0.0);
        let cmp = compare(&[rx("a", a.clone()), rx("b", b), rx("c", c)], Some(&reference), 0.1, Earth::Wgs84)
            .unwrap();
        assert_eq!(cmp.matched_epochs, 99);
        assert_relative_eq!(cmp.differences[0].rms_m, 2.0, max_relative = 1e-6);
        assert_relative_eq!(cmp.differences[0].mean_en_m[1], 2.0, max_relative = 1e-6);
        assert_relative_eq!(cmp.differences[1].mean_en_m[0], 1.0, max_relative = 1e-6);
        let c_acc = cmp.against_reference[2].as_ref().unwrap();
        assert_relative_eq!(c_acc.cep50_m, 1.0, max_relative = 1e-6);
        // A far-off clock matches nothing, and says so.
        let late: Vec<Sample> = a.iter().map(|s| Sample { t_s: s.t_s + 3600.5, ..*s }).collect();
        let cmp = compare(&[rx("a", a), rx("late", late)], None, 0.1, Earth::Wgs84).unwrap();
        assert_eq!(cmp.matched_epochs, 0);
        assert_eq!(cmp.warnings.len(), 1);
    }
}
