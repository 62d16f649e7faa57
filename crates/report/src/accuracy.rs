//! GPS accuracy against a reference: the accuracy sheet, the receivers-side-by-side sheet, and the drift
//! and cone tests "against the reference", each with one JSON schema. Written by `vestnav fieldtest
//! accuracy | compare | drift --reference | cones --reference` and meant for the console's export alike
//! (the same inputs give the same PNG and JSON).

use serde::{Deserialize, Serialize};
use vestnav_core::accuracy::{AccuracyStats, Comparison, Reference, Sample};
use vestnav_core::geo::{Earth, LocalFrame};
use vestnav_plot::{Chart, Color, Figure, Marker, Series};

use crate::fieldtest::Source;

/// JSON of an accuracy test: the [`AccuracyStats`] flattened (keys `fixes`, `duration_s`, `bias_en_m`,
/// `bias_m`, `sigma_en_m`, `cep50_m`, `cep95_m`, `drms_m`, `twodrms_m`, `max_m`, `gaussian`, `within`,
/// `vertical`, `t_s`, `error_en_m`, `error_m`, `warnings`, ...), the reference, where the fixes came from and
/// the track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AccuracyReport {
    /// Always `accuracy`.
    pub test: String,
    /// Where the fixes came from.
    #[serde(flatten)]
    pub source: Source,
    /// Earth model of the distances.
    pub earth: Earth,
    /// The truth.
    #[serde(rename = "reference_point")]
    pub reference: Reference,
    /// The statistics, when there are any.
    #[serde(flatten)]
    pub stats: Option<AccuracyStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// The fixes analysed.
    pub track: Vec<Sample>,
}

impl AccuracyReport {
    /// The report of an accuracy test.
    pub fn new(
        source: Source,
        earth: Earth,
        reference: Reference,
        stats: Result<AccuracyStats, String>,
        track: &[Sample],
    ) -> Self {
        let (stats, error) = match stats {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e)),
        };
        Self { test: "accuracy".into(), source, earth, reference, stats, error, track: track.to_vec() }
    }

    /// The accuracy sheet of this report (a title only without statistics).
    pub fn figure(&self) -> Figure {
        match &self.stats {
            Some(s) => accuracy_figure(s, &self.reference),
            None => Figure::new().title("Accuracy against the reference: no statistics"),
        }
    }
}

/// Named accuracy statistics with units, for tables (the CLI's text and the console's).
pub fn accuracy_rows(s: &AccuracyStats) -> Vec<(&'static str, String)> {
    let mut rows = vec![
        ("fixes", format!("{} over {:.0} s", s.fixes, s.duration_s)),
        (
            "bias east / north",
            format!("{:+.3} / {:+.3} m (|bias| {:.3} m)", s.bias_en_m[0], s.bias_en_m[1], s.bias_m),
        ),
        ("sigma east / north", format!("{:.3} / {:.3} m", s.sigma_en_m[0], s.sigma_en_m[1])),
        ("CEP50 / CEP95 (measured)", format!("{:.3} / {:.3} m", s.cep50_m, s.cep95_m)),
        ("DRMS / 2DRMS (bias included)", format!("{:.3} / {:.3} m", s.drms_m, s.twodrms_m)),
        (
            "Gaussian CEP50 / R95 / 2DRMS",
            format!("{:.3} / {:.3} / {:.3} m", s.gaussian.cep50_m, s.gaussian.r95_m, s.gaussian.twodrms_m),
        ),
        ("max error", format!("{:.3} m", s.max_m)),
        (
            "within 0.1 / 0.5 / 1 / 2 / 5 m",
            s.within.iter().map(|w| format!("{:.1} %", 100.0 * w.share)).collect::<Vec<_>>().join(" / "),
        ),
    ];
    if let Some(v) = &s.vertical {
        rows.push((
            "vertical bias / RMS / P95",
            format!("{:+.3} / {:.3} / {:.3} m ({} fixes)", v.bias_m, v.rms_m, v.p95_abs_m, v.fixes),
        ));
    }
    rows
}

/// The panels of the accuracy statistics: horizontal (and vertical) error against time with the CEP
/// lines, the errors east/north about the reference with the CEP50, CEP95 and 2DRMS circles, the bias and
/// the reference's own uncertainty, and the share of fixes within each radius (the empirical distribution).
pub fn accuracy_panels(s: &AccuracyStats, label: &str) -> Vec<Chart> {
    let mut time = Chart::new(format!("{label}: error against time"))
        .x_label("time [s]")
        .y_label("error [m]")
        .series(Series::line("horizontal", s.t_s.clone(), s.error_m.clone()).width(2.0))
        .hline(s.cep50_m, format!("CEP50 {:.2} m", s.cep50_m))
        .hline(s.cep95_m, format!("CEP95 {:.2} m", s.cep95_m));
    if let Some(v) = &s.vertical {
        time = time.series(Series::line("vertical", v.t_s.clone(), v.error_m.clone()).dashed());
    }
    let mut scatter = Chart::new(format!("{label}: fixes about the reference ({} fixes)", s.fixes))
        .x_label("east [m]")
        .y_label("north [m]")
        .equal_aspect()
        .series(
            Series::scatter(
                "fix",
                s.error_en_m.iter().map(|p| p.x).collect(),
                s.error_en_m.iter().map(|p| p.y).collect(),
            )
            .marker(Marker::Circle)
            .color(Color::rgb(30, 90, 200)),
        )
        .series(
            Series::scatter("bias", vec![s.bias_en_m[0]], vec![s.bias_en_m[1]])
                .marker(Marker::Cross)
                .color(Color::rgb(200, 30, 30)),
        )
        .circle(0.0, 0.0, s.cep50_m, format!("CEP50 {:.2} m", s.cep50_m))
        .circle(0.0, 0.0, s.cep95_m, format!("CEP95 {:.2} m", s.cep95_m))
        .circle(0.0, 0.0, s.twodrms_m, format!("2DRMS {:.2} m", s.twodrms_m));
    if s.reference_uncertainty_m > 0.0 {
        scatter = scatter.circle(
            0.0,
            0.0,
            s.reference_uncertainty_m,
            format!("reference ±{:.2} m", s.reference_uncertainty_m),
        );
    }
    let mut sorted = s.error_m.clone();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len().max(1) as f64;
    let share: Vec<f64> = (1..=sorted.len()).map(|k| 100.0 * k as f64 / n).collect();
    let mut cdf = Chart::new(format!("{label}: share of fixes within a radius"))
        .x_label("horizontal error [m]")
        .y_label("fixes within [%]")
        .series(Series::line("measured", sorted, share).width(2.0))
        .hline(50.0, "50 %")
        .hline(95.0, "95 %");
    for w in &s.within {
        cdf =
            cdf.annotate(w.radius_m, 100.0 * w.share, format!("{} m: {:.0} %", w.radius_m, 100.0 * w.share));
    }
    vec![time, scatter, cdf]
}

/// The accuracy sheet: [`accuracy_panels`] under a title naming the reference.
pub fn accuracy_figure(s: &AccuracyStats, reference: &Reference) -> Figure {
    accuracy_panels(s, "Accuracy").into_iter().fold(
        Figure::new()
            .title(format!("Accuracy against the reference {}", reference.describe()))
            .columns(3)
            .panel_size(560, 480),
        Figure::push,
    )
}

/// The label of a drift test's panels against the reference (CLI and console alike).
pub const DRIFT_AGAINST_LABEL: &str = "Against the reference";
/// The label of a cone test's panels against the reference (CLI and console alike).
pub const CONES_AGAINST_LABEL: &str = "Marks against their cones";

/// A drift or cone test with its statistics against a reference: the test's own report flattened (its
/// keys unchanged), plus `reference_point` and `against_reference` (an [`AccuracyStats`]) or
/// `against_reference_error`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgainstReference<T> {
    /// The test's own report.
    #[serde(flatten)]
    pub test: T,
    /// The truth.
    pub reference_point: Reference,
    /// The fixes (drift) or the marks (cones, each against its own cone) against the truth.
    pub against_reference: Option<AccuracyStats>,
    /// Why there are no such statistics.
    pub against_reference_error: Option<String>,
}

impl<T> AgainstReference<T> {
    /// The test's report with its statistics against `reference`.
    pub fn new(test: T, reference: Reference, stats: Result<AccuracyStats, String>) -> Self {
        let (against_reference, against_reference_error) = match stats {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e)),
        };
        Self { test, reference_point: reference, against_reference, against_reference_error }
    }

    /// The test's own sheet (`figure`) followed by the accuracy panels.
    pub fn figure(&self, figure: impl FnOnce(&T) -> Figure, label: &str) -> Figure {
        let fig = figure(&self.test);
        match &self.against_reference {
            Some(s) => accuracy_panels(s, label).into_iter().fold(fig.columns(3), Figure::push),
            None => fig,
        }
    }
}

/// JSON of receivers side by side: the [`Comparison`] flattened (keys `names`, `tolerance_s`,
/// `matched_epochs`, `t_s`, `differences`, `against_reference`, `warnings`), each receiver's source and
/// track, and the reference if any.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompareReport {
    /// Always `compare`.
    pub test: String,
    /// Where each receiver's fixes came from.
    pub sources: Vec<Source>,
    /// Earth model of the distances.
    pub earth: Earth,
    /// The truth, if given.
    pub reference_point: Option<Reference>,
    /// The comparison.
    #[serde(flatten)]
    pub comparison: Comparison,
    /// Each receiver's fixes.
    pub tracks: Vec<Vec<Sample>>,
}

impl CompareReport {
    /// The sheet with every receiver: positions, the distance from the first receiver at each matched
    /// epoch and, with a reference, each one's horizontal error against time.
    pub fn figure(&self) -> Figure {
        let c = &self.comparison;
        let origin = self
            .reference_point
            .as_ref()
            .map(|r| r.pos)
            .or_else(|| self.tracks.first().and_then(|t| t.first()).map(|s| s.pos));
        let mut fig = Figure::new()
            .title(format!("{} receivers side by side ({} matched epochs)", c.names.len(), c.matched_epochs))
            .columns(3)
            .panel_size(560, 480);
        let Some(origin) = origin else { return fig };
        let frame = LocalFrame::new(origin, self.earth);
        let about =
            if self.reference_point.is_some() { "the reference" } else { "the first fix of the first" };
        let mut map = Chart::new(format!("Fixes about {about}"))
            .x_label("east [m]")
            .y_label("north [m]")
            .equal_aspect();
        for (k, (name, track)) in c.names.iter().zip(&self.tracks).enumerate() {
            let en: Vec<_> = track.iter().map(|s| frame.enu_from_wgs84(s.pos)).collect();
            map = map.series(
                Series::scatter(
                    name.clone(),
                    en.iter().map(|p| p.x).collect(),
                    en.iter().map(|p| p.y).collect(),
                )
                .marker(Marker::Circle)
                .color(Color::palette(k)),
            );
        }
        if self.reference_point.is_some() {
            map = map.series(
                Series::scatter("reference", vec![0.0], vec![0.0])
                    .marker(Marker::Cross)
                    .color(Color::rgb(0, 0, 0)),
            );
        }
        let first = c.names.first().cloned().unwrap_or_default();
        let mut diff = Chart::new(format!("Distance from {first} at matched epochs"))
            .x_label("time [s]")
            .y_label("distance [m]");
        for (k, d) in c.differences.iter().enumerate() {
            diff = diff.series(
                Series::line(
                    format!("{} (RMS {:.2} m)", d.name, d.rms_m),
                    c.t_s.clone(),
                    d.distance_m.clone(),
                )
                .color(Color::palette(k + 1)),
            );
        }
        fig = fig.push(map).push(diff);
        if c.against_reference.iter().any(Option::is_some) {
            let mut err =
                Chart::new("Each receiver against the reference").x_label("time [s]").y_label("error [m]");
            for (k, (name, s)) in c.names.iter().zip(&c.against_reference).enumerate() {
                if let Some(s) = s {
                    err = err.series(
                        Series::line(
                            format!("{name} (CEP50 {:.2} m)", s.cep50_m),
                            s.t_s.clone(),
                            s.error_m.clone(),
                        )
                        .color(Color::palette(k)),
                    );
                }
            }
            fig = fig.push(err);
        }
        fig
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_core::accuracy::{Receiver, accuracy, compare};
    use vestnav_core::geo::LatLon;

    #[test]
    fn accuracy_report_round_trips_and_draws() {
        let truth = LatLon::new(42.3575, -71.1010);
        let track: Vec<Sample> = (0..4)
            .map(|k| Sample {
                t_s: f64::from(k),
                pos: Earth::Wgs84.direct(truth, 90.0 * f64::from(k), 1.5),
                height_m: Some(20.0),
            })
            .collect();
        let reference = Reference { height_m: Some(19.0), ..Reference::typed(truth, 0.02) };
        let stats = accuracy(&track, &reference, Earth::Wgs84).unwrap();
        let report = AccuracyReport::new(Source::live(), Earth::Wgs84, reference.clone(), Ok(stats), &track);
        let text = crate::to_json(&report).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["test"], "accuracy");
        assert_relative_eq!(v["cep50_m"].as_f64().unwrap(), 1.5, max_relative = 1e-6);
        assert_relative_eq!(v["vertical"]["bias_m"].as_f64().unwrap(), 1.0, max_relative = 1e-9);
        let back: AccuracyReport = serde_json::from_str(&text).unwrap();
        assert_eq!(back.stats.as_ref().map(|s| s.fixes), Some(4));
        assert_eq!(report.figure().panels.len(), 3);
        let png = report.figure().render_png().unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let against = AgainstReference::new(1u8, reference, Err("none".into()));
        assert!(against.against_reference.is_none());

        let rx = |name: &str| Receiver { name: name.into(), samples: track.clone() };
        let cmp = compare(&[rx("a"), rx("b")], None, 0.1, Earth::Wgs84).unwrap();
        let report = CompareReport {
            test: "compare".into(),
            sources: vec![Source::live(), Source::live()],
            earth: Earth::Wgs84,
            reference_point: None,
            comparison: cmp,
            tracks: vec![track.clone(), track],
        };
        assert_eq!(report.figure().panels.len(), 2);
        let v: serde_json::Value = serde_json::from_str(&crate::to_json(&report).unwrap()).unwrap();
        assert_eq!(v["matched_epochs"], 4);
    }
}
