//! Study figures (`docs/study.md`): the confusion matrix, the 4x4 localization map, the learning curve, the
//! response-time histogram and the navigation summary, drawn from a core [`StudyAnalysis`]. The same
//! figures from `vestnav study analyze --figures DIR` and from the console's Study tab.

use std::path::{Path, PathBuf};

use vestnav_core::study::StudyAnalysis;
use vestnav_core::vest::tactor_label;
use vestnav_plot::{Chart, Figure, Heatmap, Marker, PlotError, Series};

/// One study figure: its file name (without folder) and the figure.
pub struct StudyFigure {
    /// File name, e.g. `confusion.png`.
    pub file: &'static str,
    /// The figure.
    pub figure: Figure,
}

/// Every figure the analysis has data for, in the gallery's order: confusion matrix, localization map,
/// learning curve, response times, navigation.
pub fn figure_list(a: &StudyAnalysis) -> Vec<StudyFigure> {
    let mut out = Vec::new();
    if let Some(f) = confusion_figure(a) {
        out.push(StudyFigure { file: "confusion.png", figure: f });
    }
    if let Some(f) = localization_map_figure(a) {
        out.push(StudyFigure { file: "localization-map.png", figure: f });
    }
    if let Some(f) = learning_curve_figure(a) {
        out.push(StudyFigure { file: "learning-curve.png", figure: f });
    }
    if let Some(f) = rt_histogram_figure(a) {
        out.push(StudyFigure { file: "rt-histogram.png", figure: f });
    }
    if let Some(f) = navigation_figure(a) {
        out.push(StudyFigure { file: "navigation.png", figure: f });
    }
    out
}

/// Writes every figure of [`figure_list`] as PNG into `dir` (which must exist: a mistyped folder is an
/// error naming it, not a folder made silently) and returns the files written.
pub fn figures(a: &StudyAnalysis, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    if !dir.is_dir() {
        return Err(PlotError::Io {
            path: dir.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such folder"),
        });
    }
    let mut written = Vec::new();
    for f in figure_list(a) {
        let path = dir.join(f.file);
        f.figure.save_png(&path)?;
        written.push(path);
    }
    Ok(written)
}

/// The confusion matrix as row percentages (stimulus `i` up the y axis from the bottom, response `j` along
/// x, numbered as listed in the title), with IT and percent correct in the title.
pub fn confusion_figure(a: &StudyAnalysis) -> Option<Figure> {
    let m = a.confusion.as_ref()?;
    let (ny, nx) = (m.stimuli.len(), m.responses.len());
    if nx == 0 || ny == 0 {
        return None;
    }
    let fractions = m.row_fractions();
    let values: Vec<f64> = fractions.iter().flat_map(|r| r.iter().map(|f| 100.0 * f)).collect();
    let key = if m.responses.iter().all(|r| vestnav_core::study::protocol::parse_tactor_label(r).is_some()) {
        "numbers are tactors T0..T15".to_owned()
    } else {
        let names: Vec<String> =
            m.responses.iter().enumerate().map(|(i, r)| format!("{} {r}", i + 1)).collect();
        shorten(&names.join(", "), 140)
    };
    let title = format!(
        "Confusion matrix, row percent: {} % correct, IT {} bits (corrected {}), n = {}",
        fmt1(a.percent_correct),
        fmt2(a.it_bits),
        fmt2(a.it_corrected_bits),
        m.total()
    );
    let heat = Heatmap::new(title, (0.5, nx as f64 + 0.5), (0.5, ny as f64 + 0.5), nx, ny, values)
        .x_label(format!("response ({key})"))
        .y_label("stimulus")
        .colorbar_label("responses [% of the row]")
        .value_range(0.0, 100.0)
        .equal_aspect();
    Some(Figure::single(heat).panel_size(760, 680))
}

/// The 4x4 back view coloured by percent correct per tactor, each cell labelled with its tactor and value
/// (grey: never presented alone).
pub fn localization_map_figure(a: &StudyAnalysis) -> Option<Figure> {
    let map = a.localization_map.as_ref()?;
    // Heatmap row 0 is drawn at the bottom: grid row 3 (near the waist) goes first.
    let values: Vec<f64> =
        (0..4).rev().flat_map(|r| (0..4).map(move |c| map[r][c].unwrap_or(f64::NAN))).collect();
    let points = (0..16)
        .map(|i| {
            let (r, c) = (i / 4, i % 4);
            let text = map[r][c]
                .map_or_else(|| format!("{} -", tactor_label(i)), |p| format!("{} {p:.0}%", tactor_label(i)));
            (c as f64 + 0.2, 3.0 - r as f64 + 0.5, text)
        })
        .collect();
    let heat =
        Heatmap::new("Localization map, percent correct (back view)", (0.0, 4.0), (0.0, 4.0), 4, 4, values)
            .x_label("wearer's left  <-  column  ->  wearer's right")
            .y_label("waist  <-  row  ->  top")
            .colorbar_label("correct [%]")
            .value_range(0.0, 100.0)
            .equal_aspect()
            .points(points);
    Some(Figure::single(heat).panel_size(620, 560))
}

/// Percent correct and median response time per block (training blocks marked).
pub fn learning_curve_figure(a: &StudyAnalysis) -> Option<Figure> {
    if a.learning.is_empty() {
        return None;
    }
    let x: Vec<f64> = a.learning.iter().map(|b| b.block as f64 + 1.0).collect();
    let pc: Vec<f64> = a.learning.iter().map(|b| b.percent_correct.unwrap_or(f64::NAN)).collect();
    let rt: Vec<f64> = a.learning.iter().map(|b| b.rt_median_ms.unwrap_or(f64::NAN)).collect();
    let x_max = x.last().copied().unwrap_or(1.0) + 0.8;
    let mut percent = Chart::new("Percent correct per block")
        .x_label("block")
        .x_range(0.5, x_max)
        .y_label("correct [%]")
        .y_range(0.0, 100.0)
        .x_integer()
        .series(Series::line("", x.clone(), pc.clone()).marker(Marker::Circle));
    let mut times = Chart::new("Median response time per block")
        .x_label("block")
        .x_range(0.5, x_max)
        .y_label("median RT [ms]")
        .x_integer()
        .series(Series::line("", x.clone(), rt.clone()).marker(Marker::Circle));
    for (b, (xi, (p, t))) in a.learning.iter().zip(x.iter().zip(pc.iter().zip(&rt))) {
        let name = if b.training && !b.block_name.contains("training") {
            format!("{} (training)", b.block_name)
        } else {
            b.block_name.clone()
        };
        if p.is_finite() {
            percent = percent.annotate(*xi, *p, name.clone());
        }
        if t.is_finite() {
            times = times.annotate(*xi, *t, name);
        }
    }
    if let Some(bits) = a.stimulus_bits {
        percent = percent.hline(100.0 / bits.exp2(), "chance");
    }
    Some(Figure::new().title("Learning curve").columns(2).panel_size(560, 400).push(percent).push(times))
}

/// Histogram of the response times of the answered test trials, with the median and quartiles marked.
pub fn rt_histogram_figure(a: &StudyAnalysis) -> Option<Figure> {
    let rt = a.rt.as_ref()?;
    let values = &a.rt_values_ms;
    let (lo, hi) = (rt.min_ms, rt.max_ms);
    // Freedman–Diaconis bin width 2 IQR n^(-1/3), at least 1 ms, between 5 and 60 bins.
    let n = values.len() as f64;
    let fd = 2.0 * rt.iqr_ms / n.cbrt();
    let span = (hi - lo).max(1.0);
    let bins = if fd > 0.0 { (span / fd).ceil().clamp(5.0, 60.0) as usize } else { 10 };
    let width = span / bins as f64;
    let mut counts = vec![0usize; bins];
    for v in values {
        let k = (((v - lo) / width).floor().max(0.0) as usize).min(bins - 1);
        counts[k] += 1;
    }
    // Outline of the bars as one step line.
    let (mut xs, mut ys) = (vec![lo], vec![0.0]);
    for (k, c) in counts.iter().enumerate() {
        let (x0, x1) = (lo + k as f64 * width, lo + (k + 1) as f64 * width);
        xs.extend([x0, x1]);
        ys.extend([*c as f64, *c as f64]);
    }
    xs.push(lo + bins as f64 * width);
    ys.push(0.0);
    let chart = Chart::new(format!(
        "Response times: median {:.0} ms, IQR {:.0} ms, mean {:.0} ms, n = {}",
        rt.median_ms, rt.iqr_ms, rt.mean_ms, rt.n
    ))
    .x_label("response time [ms]")
    .y_label("trials")
    .series(Series::line("", xs, ys))
    .vline(rt.median_ms, "median")
    .vline(rt.q1_ms, "Q1")
    .vline(rt.q3_ms, "Q3");
    Some(Figure::single(chart).panel_size(760, 420))
}

/// Navigation trials by condition: completion time, path/route length, cross-track RMS and cues, one dot
/// per trial and the condition's mean.
pub fn navigation_figure(a: &StudyAnalysis) -> Option<Figure> {
    if a.navigation.is_empty() {
        return None;
    }
    let index = |c: &str| a.navigation.iter().position(|n| n.condition == c).map_or(0.0, |i| i as f64 + 1.0);
    let panel =
        |title: &str,
         y_label: &str,
         get: &dyn Fn(&vestnav_core::study::analysis::NavigationTrial) -> Option<f64>| {
            let (x, y): (Vec<f64>, Vec<f64>) =
                a.navigation_trials.iter().filter_map(|t| get(t).map(|v| (index(&t.condition), v))).unzip();
            let means: Vec<(f64, f64)> = a
                .navigation
                .iter()
                .enumerate()
                .filter_map(|(i, n)| {
                    let of: Vec<f64> = a
                        .navigation_trials
                        .iter()
                        .filter(|t| t.condition == n.condition)
                        .filter_map(get)
                        .collect();
                    (!of.is_empty()).then(|| (i as f64 + 1.0, of.iter().sum::<f64>() / of.len() as f64))
                })
                .collect();
            let (mx, my): (Vec<f64>, Vec<f64>) = means.into_iter().unzip();
            let mut chart = Chart::new(title)
                .x_label("condition")
                .y_label(y_label)
                .x_integer()
                .x_range(0.5, a.navigation.len() as f64 + 0.9)
                .series(Series::scatter("trials", x, y).marker(Marker::Circle))
                .series(Series::scatter("mean", mx.clone(), my.clone()).marker(Marker::Cross));
            for (i, n) in a.navigation.iter().enumerate() {
                if let Some(m) =
                    mx.iter().position(|v| (*v - (i as f64 + 1.0)).abs() < 1e-9).and_then(|k| my.get(k))
                {
                    chart = chart.annotate(i as f64 + 1.0, *m, n.condition.clone());
                }
            }
            chart
        };
    let fig = Figure::new()
        .title("Navigation by condition")
        .columns(2)
        .panel_size(560, 380)
        .push(panel("Completion time (completed walks)", "time [s]", &|t| {
            (t.outcome == vestnav_core::study::Outcome::Completed).then_some(t.completion_s).flatten()
        }))
        .push(panel("Path length / route length", "ratio", &|t| t.path_ratio))
        .push(panel("Cross-track RMS", "RMS [m]", &|t| t.cross_track_rms_m))
        .push(panel("Cues per walk", "cues", &|t| t.cues.map(f64::from)));
    Some(fig)
}

fn fmt1(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_owned(), |x| format!("{x:.1}"))
}

fn fmt2(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_owned(), |x| format!("{x:.2}"))
}

fn shorten(s: &str, max_chars: usize) -> String {
    if s.chars().count() <= max_chars {
        s.to_owned()
    } else {
        let mut t: String = s.chars().take(max_chars.saturating_sub(3)).collect();
        t.push_str("...");
        t
    }
}

#[cfg(test)]
#[path = "study_tests.rs"]
mod tests;
