//! The study figures from a synthetic study: the docs' example protocols planned for their participants,
//! answered by a simulated wearer, written as results CSV and read back. With `VESTNAV_WRITE_GALLERY=1`
//! the CSVs and the PNGs are written to `docs/study/` (the gallery of `docs/study.md`).

use std::path::{Path, PathBuf};

use vestnav_core::study::plan::SplitMix64;
use vestnav_core::study::protocol::{label_cell, tactor_label};
use vestnav_core::study::{Outcome, Protocol, TrialRecord, analyze, plan, read_csv, write_csv};

use super::*;

fn docs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/study")
}

fn uniform(rng: &mut SplitMix64) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

/// A simulated localization study: each wearer reports the right tactor with a probability that grows
/// over the blocks and is higher in the corners (Jones and Ray 2008: the corners are localized best),
/// otherwise a grid neighbour; response times shorten with practice.
fn localization_results() -> Vec<TrialRecord> {
    let p = Protocol::load(&docs().join("localization.toml")).unwrap();
    let mut rng = SplitMix64::new(25);
    let mut rows = Vec::new();
    for who in &p.participants {
        let mut clock = 0.0;
        for t in plan(&p, who).unwrap() {
            let (r, c) = label_cell(&t.answer).unwrap();
            let corner = (r == 0 || r == 3) && (c == 0 || c == 3);
            let skill = 0.5 + 0.08 * t.block as f64 + if corner { 0.2 } else { 0.0 };
            let response = if uniform(&mut rng) < skill {
                t.answer.clone()
            } else {
                let nb = vestnav_core::vest::grid_neighbours(r * 4 + c);
                tactor_label(nb[rng.below(nb.len() as u64) as usize])
            };
            let rt =
                650.0 - 60.0 * t.block as f64 + 900.0 * uniform(&mut rng).powi(3) + 80.0 * uniform(&mut rng);
            let mut rec = TrialRecord::new(who, "S1", &p.name, p.task);
            rec.block = t.block;
            rec.block_name = t.block_name.clone();
            rec.trial = t.index;
            rec.training = t.training;
            rec.feedback = t.feedback;
            rec.stimulus = t.stimulus.label();
            rec.answer = t.answer.clone();
            clock += 3.0;
            rec.stimulus_on_s = Some(clock);
            rec.rt_ms = Some(rt.round());
            rec.response_s = Some(clock + rt.round() / 1000.0);
            rec.correct = Some(response == t.answer);
            rec.response = Some(response);
            rec.outcome = Outcome::Answered;
            rows.push(rec);
        }
    }
    // One trial stopped by STOP ALL, as a real session may hold.
    if let Some(r) = rows.get_mut(40) {
        r.response = None;
        r.correct = None;
        r.rt_ms = None;
        r.response_s = None;
        r.outcome = Outcome::Stopped;
        r.notes = "STOP ALL from the console".into();
    }
    rows
}

/// A simulated navigation study on the docs' navigation protocol.
fn navigation_results() -> Vec<TrialRecord> {
    let p = Protocol::load(&docs().join("navigation.toml")).unwrap();
    let mut rng = SplitMix64::new(7);
    let mut rows = Vec::new();
    for who in &p.participants {
        for t in plan(&p, who).unwrap() {
            let compass = t.answer.contains("compass");
            let pursuit = t.answer.contains("pursuit");
            let route_m = 412.0;
            let ratio = 1.05 + if pursuit { 0.0 } else { 0.06 } + 0.08 * uniform(&mut rng);
            let mut rec = TrialRecord::new(who, "S1", &p.name, p.task);
            rec.block = t.block;
            rec.block_name = t.block_name.clone();
            rec.trial = t.index;
            rec.training = t.training;
            rec.feedback = t.feedback;
            rec.stimulus = t.stimulus.label();
            rec.answer = t.answer.clone();
            rec.route_m = Some(route_m);
            rec.path_m = Some((route_m * ratio).round());
            rec.completion_s = Some(
                (route_m * ratio / 1.25 + if compass { 0.0 } else { 25.0 } + 30.0 * uniform(&mut rng))
                    .round(),
            );
            let rms = if compass { 2.5 } else { 4.0 } + 1.5 * uniform(&mut rng);
            rec.cross_track_rms_m = Some((rms * 100.0).round() / 100.0);
            rec.cues = Some(30 + rng.below(25) as u32);
            rec.stops = Some(u32::from(uniform(&mut rng) < 0.2));
            rec.missed_waypoints = Some(u32::from(uniform(&mut rng) < 0.1));
            rec.outcome = Outcome::Completed;
            rows.push(rec);
        }
    }
    rows
}

fn out_dir(name: &str) -> (PathBuf, bool) {
    if std::env::var_os("VESTNAV_WRITE_GALLERY").is_some() {
        (docs().join("gallery"), true)
    } else {
        let d = std::env::temp_dir().join(format!("vestnav-study-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        (d, false)
    }
}

fn is_png(path: &Path) -> bool {
    std::fs::read(path).is_ok_and(|b| b.len() > 1000 && &b[1..4] == b"PNG")
}

#[test]
fn localization_figures_from_a_synthetic_study() {
    let rows = localization_results();
    let csv = write_csv(&rows);
    let back = read_csv(&csv).unwrap();
    assert_eq!(back, rows);
    let a = analyze(&back);
    // 4 participants x 16 tactors x 6 test repetitions, one of them stopped.
    assert_eq!(a.answered, 4 * 16 * 6 - usize::from(!rows[40].training));
    assert_eq!(a.learning.len(), 4);
    let (dir, keep) = out_dir("loc");
    if keep {
        std::fs::write(docs().join("example-localization.csv"), &csv).unwrap();
    }
    let files = figures(&a, &dir).unwrap();
    let names: Vec<String> =
        files.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["confusion.png", "localization-map.png", "learning-curve.png", "rt-histogram.png"]);
    assert!(files.iter().all(|f| is_png(f)));
    if !keep {
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn navigation_figure_from_a_synthetic_study() {
    let rows = navigation_results();
    let csv = write_csv(&rows);
    let a = analyze(&read_csv(&csv).unwrap());
    assert_eq!(a.navigation.len(), 4);
    let (dir, keep) = out_dir("nav");
    if keep {
        std::fs::write(docs().join("example-navigation.csv"), &csv).unwrap();
    }
    let files = figures(&a, &dir).unwrap();
    assert_eq!(files.len(), 1);
    assert!(files[0].ends_with("navigation.png") && is_png(&files[0]));
    if !keep {
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn a_missing_folder_is_an_error_naming_it() {
    let a = analyze(&localization_results());
    let missing = std::env::temp_dir().join("vestnav-no-such-folder-for-study");
    let e = figures(&a, &missing).unwrap_err();
    assert!(e.to_string().contains("vestnav-no-such-folder-for-study"), "{e}");
}

#[test]
fn pattern_names_label_the_confusion_axis() {
    let mut rows = Vec::new();
    for (s, r) in [("left", "left"), ("right", "left"), ("stop", "stop"), ("right", "right")] {
        let mut rec = TrialRecord::new("P", "S", "pat", vestnav_core::study::Task::PatternId);
        rec.stimulus = s.into();
        rec.answer = s.into();
        rec.response = Some(r.into());
        rec.correct = Some(s == r);
        rec.outcome = Outcome::Answered;
        rows.push(rec);
    }
    let a = analyze(&rows);
    let f = confusion_figure(&a).unwrap();
    let vestnav_plot::Panel::Heatmap(h) = &f.panels[0] else { panic!("a heatmap") };
    assert!(h.x_label.contains("1 left, 2 right, 3 stop"), "{}", h.x_label);
    // Row 2 (right): one "left", one "right": 50 % each.
    assert!((h.values[3] - 50.0).abs() < 1e-9 && (h.values[4] - 50.0).abs() < 1e-9);
    assert!(localization_map_figure(&a).is_none());
}
