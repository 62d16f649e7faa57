//! GPS field tests (thesis §5): the drift sheet (Fig 65), the cone sheet (Figs 67–70), and one JSON schema per
//! test, written by `vestnav fieldtest drift|cones --json` and by the console's field-test export alike.

use serde::{Deserialize, Serialize};
use vestnav_core::fieldtest::{ConeConfig, ConeMark, ConeStats, DriftStats, TimedFix};
use vestnav_core::geo::{Earth, LatLon, LocalFrame};
use vestnav_plot::{Chart, Color, Figure, Marker, Series};

/// Where the fixes of a field test came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// The log file read, or `None` for the console's live fixes.
    pub file: Option<String>,
    /// `nmea`, `session` (a console session log) or `live`.
    pub format: String,
    /// Rejected NMEA sentences or skipped session-log lines.
    pub rejected_sentences: u64,
}

impl Source {
    /// Live fixes in the console.
    pub fn live() -> Self {
        Self { file: None, format: "live".to_string(), rejected_sentences: 0 }
    }
}

/// JSON of a stationary drift test: the [`DriftStats`] flattened (keys `fixes`, `duration_s`, `first`,
/// `mean`, `max_from_first_m`, `max_from_mean_m`, `cep50_m`, `cep95_m`, `drms_m`, `twodrms_m`, `sigma_en_m`,
/// `t_s`, `from_first_m`, `from_mean_m`, `en_about_mean_m`, `pinning`, `warnings`), where the fixes came
/// from, the Earth model, the duration target (console) and the track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriftReport {
    /// Always `drift`.
    pub test: String,
    /// Where the fixes came from.
    #[serde(flatten)]
    pub source: Source,
    /// Earth model of the distances.
    pub earth: Earth,
    /// The console's duration target [s].
    pub target_s: Option<f64>,
    /// The statistics, when there are any.
    #[serde(flatten)]
    pub stats: Option<DriftStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// The positioned fixes analysed.
    pub track: Vec<TimedFix>,
    /// The clock of the times (`t_s`, `duration_s`): `receiver` (the fixes' UTC) or `arrival` (when the
    /// console received them; the receiver sent no time). Set by the console; absent for logs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock: Option<String>,
}

impl DriftReport {
    /// The report of a drift test.
    pub fn new(
        source: Source,
        earth: Earth,
        target_s: Option<f64>,
        stats: Result<DriftStats, String>,
        track: &[TimedFix],
    ) -> Self {
        let (stats, error) = match stats {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e)),
        };
        Self {
            test: "drift".to_string(),
            source,
            earth,
            target_s,
            stats,
            error,
            track: track.to_vec(),
            clock: None,
        }
    }
}

/// JSON of a cone test: the [`ConeStats`] flattened (keys `marks` (the count), `spacing_m`,
/// `expected_count`, `line_bearing_deg`, `distances_m`, `min_m`, `max_m`, `mean_m`, `rmse_m`, `along_m`,
/// `cross_m`, `along_rmse_m`, `cross_rms_m`, `origin`, `marks_t0_s`, `marks_en_m`, `marks_t_s`, `labels`,
/// `warnings`), the settings, the declination used for a magnetic bearing, the marks and the track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConesReport {
    /// Always `cones`.
    pub test: String,
    /// Where the fixes came from.
    #[serde(flatten)]
    pub source: Source,
    /// Earth model of the distances.
    pub earth: Earth,
    /// The settings.
    pub config: ConeConfig,
    /// Declination applied to a magnetic line bearing [deg, east positive].
    pub declination_deg: Option<f64>,
    /// The statistics (from the second mark on).
    #[serde(flatten)]
    pub stats: Option<ConeStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// The marks with their positions.
    pub cone_marks: Vec<ConeMark>,
    /// The positioned fixes of the walk.
    pub track: Vec<TimedFix>,
}

impl ConesReport {
    /// The report of a cone test; `stats` is `None` with no error before the second mark.
    pub fn new(
        source: Source,
        config: ConeConfig,
        declination_deg: Option<f64>,
        stats: Option<Result<ConeStats, String>>,
        marks: &[ConeMark],
        track: &[TimedFix],
    ) -> Self {
        let (stats, error) = match stats {
            Some(Ok(s)) => (Some(s), None),
            Some(Err(e)) => (None, Some(e)),
            None => (None, None),
        };
        Self {
            test: "cones".to_string(),
            source,
            earth: config.earth,
            config,
            declination_deg,
            stats,
            error,
            cone_marks: marks.to_vec(),
            track: track.to_vec(),
        }
    }

    /// The cone sheet of this report.
    pub fn figure(&self) -> Figure {
        cones_figure(self.stats.as_ref(), &self.cone_marks, &self.track, self.earth)
    }
}

impl DriftReport {
    /// The drift sheet of this report (empty without statistics).
    pub fn figure(&self) -> Figure {
        self.stats
            .as_ref()
            .map_or_else(|| Figure::new().title("Stationary drift: no statistics"), drift_figure)
    }
}

/// Named drift statistics with units, for tables.
pub fn drift_rows(s: &DriftStats) -> Vec<(&'static str, String)> {
    vec![
        ("fixes", format!("{} over {:.0} s", s.fixes, s.duration_s)),
        ("max distance from the first fix", format!("{:.3} m", s.max_from_first_m)),
        ("max distance from the mean", format!("{:.3} m", s.max_from_mean_m)),
        ("CEP50 (about the mean)", format!("{:.3} m", s.cep50_m)),
        ("CEP95 (about the mean)", format!("{:.3} m", s.cep95_m)),
        ("DRMS", format!("{:.3} m", s.drms_m)),
        ("2DRMS", format!("{:.3} m", s.twodrms_m)),
        ("sigma east / north", format!("{:.3} / {:.3} m", s.sigma_en_m[0], s.sigma_en_m[1])),
        ("mean position", format!("{:.7}°, {:.7}°", s.mean.lat_deg, s.mean.lon_deg)),
    ]
}

/// Drift sheet: the distance of each fix from the first against time (thesis Fig 65) and the scatter about
/// the mean with the CEP50, CEP95 and 2DRMS circles.
pub fn drift_figure(s: &DriftStats) -> Figure {
    let time = Chart::new("Distance of each fix from the first (thesis Fig 65)")
        .x_label("time [s]")
        .y_label("distance [m]")
        .series(Series::line("from the first fix", s.t_s.clone(), s.from_first_m.clone()).width(2.0))
        .series(Series::line("from the mean", s.t_s.clone(), s.from_mean_m.clone()).dashed())
        .hline(s.max_from_first_m, format!("max from first {:.2} m", s.max_from_first_m));
    let scatter = Chart::new(format!("Fixes about the mean position ({} fixes)", s.fixes))
        .x_label("east [m]")
        .y_label("north [m]")
        .equal_aspect()
        .series(
            Series::scatter(
                "fix",
                s.en_about_mean_m.iter().map(|p| p.x).collect(),
                s.en_about_mean_m.iter().map(|p| p.y).collect(),
            )
            .marker(Marker::Circle)
            .color(Color::rgb(30, 90, 200)),
        )
        .circle(0.0, 0.0, s.cep50_m, format!("CEP50 {:.2} m", s.cep50_m))
        .circle(0.0, 0.0, s.cep95_m, format!("CEP95 {:.2} m", s.cep95_m))
        .circle(0.0, 0.0, s.twodrms_m, format!("2DRMS {:.2} m", s.twodrms_m));
    Figure::new()
        .title("Stationary drift (thesis §5)")
        .columns(2)
        .panel_size(640, 480)
        .push(time)
        .push(scatter)
}

/// Cone sheet: the track with the marks circled (Figs 67/68), and with statistics the consecutive distances
/// against the spacing with the mean and the RMSE (Figs 69/70) and their along- and cross-line components.
///
/// The map is in east/north metres about the first mark (else the first fix); the track is drawn during the
/// walk (5 s either side of the marks) once there are statistics, all of it before.
pub fn cones_figure(
    stats: Option<&ConeStats>,
    marks: &[ConeMark],
    track: &[TimedFix],
    earth: Earth,
) -> Figure {
    let origin: Option<LatLon> = marks.first().map(|m| m.pos).or_else(|| track.first().map(|f| f.pos));
    let mut fig = Figure::new().title("Cone test (thesis §5)").columns(3).panel_size(560, 480);
    let Some(origin) = origin else { return fig };
    let frame = LocalFrame::new(origin, earth);
    let (t0, t1) = match stats {
        Some(s) => (s.marks_t0_s - 5.0, s.marks_t0_s + s.marks_t_s.last().copied().unwrap_or(0.0) + 5.0),
        None => (f64::NEG_INFINITY, f64::INFINITY),
    };
    let walk: Vec<_> =
        track.iter().filter(|f| f.t_s >= t0 && f.t_s <= t1).map(|f| frame.enu_from_wgs84(f.pos)).collect();
    let marks_en: Vec<_> = marks.iter().map(|m| frame.enu_from_wgs84(m.pos)).collect();
    let title = stats.map_or_else(
        || "Track and cone marks (Figs 67/68)".to_string(),
        |s| format!("Track and cone marks (Figs 67/68), line {:.0}° true", s.line_bearing_deg),
    );
    let mut map = Chart::new(title)
        .x_label("east [m]")
        .y_label("north [m]")
        .equal_aspect()
        .series(
            Series::line("track", walk.iter().map(|p| p.x).collect(), walk.iter().map(|p| p.y).collect())
                .color(Color::rgb(30, 90, 200)),
        )
        .series(
            Series::scatter(
                "marks",
                marks_en.iter().map(|p| p.x).collect(),
                marks_en.iter().map(|p| p.y).collect(),
            )
            .marker(Marker::Circle)
            .color(Color::rgb(200, 30, 30)),
        );
    for (p, m) in marks_en.iter().zip(marks) {
        map = map.circle(p.x, p.y, 1.5, "").annotate(p.x, p.y, m.label.clone());
    }
    fig = fig.push(map);
    if let Some(s) = stats {
        let idx: Vec<f64> = (1..=s.distances_m.len()).map(|k| k as f64).collect();
        let distances = Chart::new(format!(
            "Consecutive distances (Figs 69/70): mean {:.2} m, RMSE {:.2} m",
            s.mean_m, s.rmse_m
        ))
        .x_label("cone pair")
        .x_integer()
        .y_label("distance [m]")
        .series(
            Series::line("distance", idx.clone(), s.distances_m.clone()).marker(Marker::Circle).width(2.0),
        )
        .hline(s.spacing_m, format!("nominal {} m", s.spacing_m))
        .hline(s.mean_m, format!("mean {:.2} m", s.mean_m))
        .hline(s.rmse_m, format!("RMSE {:.2} m", s.rmse_m));
        let components = Chart::new("Along- and cross-line components")
            .x_label("cone pair")
            .x_integer()
            .y_label("component [m]")
            .series(Series::scatter("along-line", idx.clone(), s.along_m.clone()).marker(Marker::Square))
            .series(Series::scatter("cross-line (right +)", idx, s.cross_m.clone()).marker(Marker::Cross))
            .hline(s.spacing_m, "nominal")
            .hline(0.0, "");
        fig = fig.push(distances).push(components);
    }
    fig
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_core::fieldtest::drift;

    #[test]
    fn drift_report_round_trips_with_and_without_statistics() {
        // Four fixes on a 2 m circle about a point: DRMS = 2 m about the mean (the centre).
        let c = LatLon::new(42.3575, -71.1010);
        let track: Vec<TimedFix> = (0..4)
            .map(|k| TimedFix { t_s: f64::from(k), pos: Earth::Wgs84.direct(c, 90.0 * f64::from(k), 2.0) })
            .collect();
        let stats = drift(&track, Earth::Wgs84).unwrap();
        assert_relative_eq!(stats.drms_m, 2.0, max_relative = 1e-3);
        let report = DriftReport::new(Source::live(), Earth::Wgs84, Some(180.0), Ok(stats), &track);
        let text = crate::to_json(&report).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["fixes"], 4);
        assert_eq!(v["earth"], "Wgs84");
        let back: DriftReport = serde_json::from_str(&text).unwrap();
        // serde_json reads decimals back to within an ulp.
        for (a, b) in back.track.iter().zip(&report.track) {
            assert_relative_eq!(a.pos.lat_deg, b.pos.lat_deg, max_relative = 1e-15);
            assert_relative_eq!(a.pos.lon_deg, b.pos.lon_deg, max_relative = 1e-15);
        }
        assert_relative_eq!(back.stats.unwrap().drms_m, 2.0, max_relative = 1e-3);
        let empty = DriftReport::new(Source::live(), Earth::Wgs84, None, Err("no fixes".into()), &[]);
        let back: DriftReport = serde_json::from_str(&crate::to_json(&empty).unwrap()).unwrap();
        assert_eq!(back.stats, None);
        assert_eq!(back.error.as_deref(), Some("no fixes"));
        assert!(empty.figure().panels.is_empty());
    }
}
