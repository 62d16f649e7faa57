//! Session log viewer and replay: pick a log, read its records, scrub through the session on the map.

use std::path::{Path, PathBuf};

use egui::RichText;

use crate::file_dialog::{self, RecentFiles, RecentKind};
use crate::map_panel::MapView;
use vestnav_device::heading::HeadingReference;
use vestnav_device::session_log::{LogEntry, LogRecord, ReadStats, list_logs, read_log, track};

/// Viewer state.
#[derive(Debug, Default)]
pub struct LogViewer {
    /// Path typed or picked.
    pub path: String,
    /// The log loaded: its records and what the reader skipped.
    pub loaded: Option<(PathBuf, Vec<LogRecord>, ReadStats)>,
    /// Replay position [s since session start].
    pub cursor_s: f64,
    /// Replay running.
    pub playing: bool,
    /// Replay speed factor.
    pub speed: f64,
    /// Error of the last load.
    pub error: Option<String>,
    /// The "Browse…" dialog of the path field.
    pub browse: crate::file_dialog::Browse,
}

/// The log viewer's open dialog.
const LOG_OPEN: crate::file_dialog::DialogSpec = crate::file_dialog::DialogSpec {
    mode: crate::file_dialog::Mode::Open,
    title: "Open a session log",
    filter: ("Session logs (JSON Lines)", &["jsonl", "json", "log"]),
};

impl LogViewer {
    /// Loads `path`.
    pub fn load(&mut self, path: &Path) {
        match read_log(path) {
            Ok((records, stats)) => {
                self.loaded = Some((path.to_path_buf(), records, stats));
                self.cursor_s = 0.0;
                self.error = None;
                if self.speed <= 0.0 {
                    self.speed = 10.0;
                }
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// Loads `path` and, once read, puts it first in the recent logs.
    fn open(&mut self, path: &Path, recent: &mut RecentFiles) {
        self.load(path);
        if self.error.is_none() {
            recent.push(RecentKind::Logs, path);
        }
    }

    /// The log file field (typed, Browse…, the absolute path it uses), Open and Recent.
    fn file_row(&mut self, ui: &mut egui::Ui, recent: &mut RecentFiles) {
        let base = recent.base();
        ui.horizontal(|ui| {
            ui.label("Log file");
            ui.vertical(|ui| {
                if let Some(p) = file_dialog::path_field(
                    ui,
                    &mut self.path,
                    &mut self.browse,
                    LOG_OPEN,
                    &base,
                    "session.jsonl",
                ) {
                    self.open(&p, recent);
                }
            });
            if ui.button("Open").clicked() {
                match file_dialog::resolve(&self.path, &base) {
                    Some(p) => self.open(&p, recent),
                    None => self.error = Some("type a log file path or Browse… first".to_owned()),
                }
            }
            if let Some(p) = file_dialog::recent_menu(ui, recent, RecentKind::Logs) {
                self.path = p.display().to_string();
                self.open(&p, recent);
            }
        });
    }

    /// Draws the tab; the replayed track goes to `map` (shown on the Map tab). A typed relative path is
    /// taken in `recent.base()`; the log opened joins `recent`.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        dir: &Path,
        current: Option<&Path>,
        map: &mut MapView,
        recent: &mut RecentFiles,
    ) {
        self.file_row(ui, recent);
        ui.collapsing(format!("Logs in {}", dir.display()), |ui| {
            for p in list_logs(dir).into_iter().take(50) {
                let cur = current.is_some_and(|c| c == p);
                let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                if ui
                    .selectable_label(false, if cur { format!("{name} (this session)") } else { name })
                    .clicked()
                {
                    self.path = p.display().to_string();
                    self.open(&p, recent);
                }
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::from_rgb(220, 40, 40), e);
        }
        let Some((path, records, stats)) = &self.loaded else {
            ui.label("Open a session log (JSON Lines, see docs/console.md) to view and replay it.");
            return;
        };
        let track = track(records);
        let (mut fixes, mut cmds, mut acks, mut marks, mut headings) = (0, 0, 0, 0, 0);
        for r in records {
            match r.entry {
                LogEntry::Fix { .. } => fixes += 1,
                LogEntry::Command { .. } => cmds += 1,
                LogEntry::Ack { .. } | LogEntry::TactorsOn { .. } => acks += 1,
                LogEntry::Mark { .. } => marks += 1,
                LogEntry::Heading { .. } => headings += 1,
                LogEntry::Note { .. } => {}
            }
        }
        let dur = records.last().map_or(0.0, |r| r.t_s);
        ui.label(format!(
            "{}: {dur:.0} s, {fixes} fixes, {headings} headings, {cmds} commands, {acks} acks, {marks} marks; skipped: {} unreadable \
             lines, {} over-long lines, {} records of unknown kinds, {} invalid fixes",
            path.display(),
            stats.bad_lines,
            stats.long_lines,
            stats.other_kinds,
            stats.invalid_fix_count()
        ));
        ui.horizontal(|ui| {
            if ui.button(if self.playing { "Pause" } else { "Replay" }).clicked() {
                self.playing = !self.playing;
                if self.cursor_s >= dur {
                    self.cursor_s = 0.0;
                }
            }
            ui.add(egui::Slider::new(&mut self.cursor_s, 0.0..=dur.max(0.001)).text("t [s]"));
            ui.add(egui::Slider::new(&mut self.speed, 1.0..=100.0).logarithmic(true).text("speed ×"));
        });
        if self.playing {
            self.cursor_s += f64::from(ui.input(|i| i.stable_dt).min(0.1)) * self.speed;
            if self.cursor_s >= dur {
                self.cursor_s = dur;
                self.playing = false;
            }
            ui.ctx().request_repaint();
        }
        let upto = track.partition_point(|p| p.0 <= self.cursor_s);
        map.replay = Some((
            track
                .iter()
                .map(|p| vestnav_device::route_file::TrackPoint {
                    lat_deg: p.1,
                    lon_deg: p.2,
                    ele_m: None,
                    time: None,
                })
                .collect(),
            upto,
        ));
        ui.label(RichText::new("The replayed track is drawn in purple on the Map tab.").weak());
        // The heading stream at the cursor: the newest heading record at or before it, with its age then.
        let heading_at = records[..records.partition_point(|r| r.t_s <= self.cursor_s)]
            .iter()
            .rev()
            .find(|r| matches!(r.entry, LogEntry::Heading { .. }));
        if let Some(r) = heading_at {
            let age = self.cursor_s - r.t_s;
            let text = format!("at {:.1} s: {} ({age:.1} s before)", self.cursor_s, summary(&r.entry));
            if age > 1.0 {
                ui.label(
                    RichText::new(format!("{text}: stale then")).color(egui::Color32::from_rgb(230, 150, 20)),
                );
            } else {
                ui.label(text);
            }
        }
        // The records around the cursor.
        let i0 = records.partition_point(|r| r.t_s < self.cursor_s);
        egui::ScrollArea::vertical().max_height(ui.available_height()).show(ui, |ui| {
            egui::Grid::new("log-records").striped(true).num_columns(2).show(ui, |ui| {
                for r in records.iter().skip(i0.saturating_sub(20)).take(60) {
                    ui.label(format!("{:9.2}", r.t_s));
                    ui.label(summary(&r.entry));
                    ui.end_row();
                }
            });
        });
    }
}

fn summary(e: &LogEntry) -> String {
    match e {
        LogEntry::Fix { lat_deg, lon_deg, error_m, .. } => {
            format!(
                "fix {lat_deg:.6}, {lon_deg:.6}{}",
                error_m.map_or(String::new(), |e| format!(" ±{e:.1} m"))
            )
        }
        LogEntry::Command { origin, command, reason } => {
            format!("{origin:?}: {} ({reason})", command.describe())
        }
        LogEntry::Ack { what } => format!("ack {what}"),
        LogEntry::TactorsOn { mask } => {
            format!("on: [{}]", mask.indices().map(|i| i.to_string()).collect::<Vec<_>>().join(" "))
        }
        LogEntry::Mark { label, .. } => format!("MARK {label}"),
        LogEntry::Note { text } => text.clone(),
        LogEntry::Heading { heading_deg, reference, origin, quality_pct, .. } => format!(
            "heading {heading_deg:.1}° {} ({origin:?}){}",
            match reference {
                HeadingReference::Magnetic => "magnetic",
                HeadingReference::True => "true",
            },
            quality_pct.map_or(String::new(), |q| format!(", quality {q} %"))
        ),
    }
}
