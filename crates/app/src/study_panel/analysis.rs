//! The Study tab's Analysis view: a results CSV read with `vestnav_core::study::read_csv`, analysed with
//! `vestnav_core::study::analyze`, its numbers shown and its figures drawn by
//! `vestnav_report::study::figures` — the same PNGs `vestnav study analyze --figures DIR` writes, shown as
//! textures. "Save figures…" writes them again into a folder the operator names (asking before it replaces
//! files there).
//!
//! Reading, analysing and drawing run on a `study-analysis` thread (a large results file never stalls a
//! frame); the figures go through a private temporary folder, removed once decoded. A figure larger than
//! [`MAX_FIGURE_PX`] on a side, or more than [`MAX_FIGURES`] of them, is not shown (bounded memory).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError};

use egui::RichText;
use vestnav_core::study::StudyAnalysis;

use crate::file_dialog::{self, Answer, Browse, DialogSpec, Mode, Picked, RecentFiles, RecentKind};

/// Most figures shown.
pub const MAX_FIGURES: usize = 24;
/// Largest figure side shown [px].
pub const MAX_FIGURE_PX: u32 = 4096;

/// What the worker hands back.
struct Loaded {
    source: PathBuf,
    rows: usize,
    analysis: Arc<StudyAnalysis>,
    /// (file name, pixels) per figure.
    figures: Vec<(String, egui::ColorImage)>,
}

/// A results file on screen.
struct Shown {
    source: PathBuf,
    rows: usize,
    analysis: Arc<StudyAnalysis>,
    figures: Vec<(String, egui::TextureHandle)>,
}

/// The Analysis view's state.
#[derive(Default)]
pub struct AnalysisView {
    /// The results file as typed or chosen.
    pub path: String,
    browse: Browse,
    running: Option<Receiver<Result<Loaded, String>>>,
    shown: Option<Shown>,
    /// Why the last file could not be analysed.
    pub error: Option<String>,
    /// The folder "Save figures…" writes to, as typed or chosen.
    pub save_dir: String,
    save_browse: Browse,
    /// A save waiting for the answer to "Replace …?".
    pending_save: Option<PathBuf>,
    saving: Option<Receiver<Result<String, String>>>,
    /// How the last save went.
    pub save_status: Option<Result<String, String>>,
}

/// A unique temporary folder for one run of the figures.
fn scratch_dir() -> PathBuf {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    std::env::temp_dir().join(format!("vestnav-study-figures-{}-{n}", std::process::id()))
}

/// Reads, analyses and draws `source` (on the worker thread).
fn load(source: PathBuf) -> Result<Loaded, String> {
    let rows = vestnav_core::study::record::read_csv_file(&source)?;
    let analysis = Arc::new(vestnav_core::study::analyze(&rows));
    let dir = scratch_dir();
    let drawn = std::fs::create_dir_all(&dir)
        .map_err(|e| format!("figures: cannot make {}: {e}", dir.display()))
        .and_then(|()| {
            vestnav_report::study::figures(&analysis, &dir)
                .map_err(|e| format!("figures of {}: {e}", source.display()))
        });
    let figures =
        drawn.map(|files| files.iter().take(MAX_FIGURES).filter_map(|f| decode(f).ok()).collect::<Vec<_>>());
    let _ = std::fs::remove_dir_all(&dir);
    Ok(Loaded { source, rows: rows.len(), analysis, figures: figures? })
}

/// One PNG as egui pixels, refused above [`MAX_FIGURE_PX`] a side.
fn decode(path: &Path) -> Result<(String, egui::ColorImage), String> {
    let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let reader = image::ImageReader::open(path).map_err(|e| e.to_string())?;
    let (w, h) = reader.into_dimensions().map_err(|e| e.to_string())?;
    if w > MAX_FIGURE_PX || h > MAX_FIGURE_PX {
        return Err(format!("{name}: {w}x{h} px is too large to show"));
    }
    let img = image::open(path).map_err(|e| e.to_string())?.to_rgba8();
    let size = [img.width() as usize, img.height() as usize];
    Ok((name, egui::ColorImage::from_rgba_unmultiplied(size, img.as_raw())))
}

impl AnalysisView {
    /// Starts analysing `path` (the view shows it when done).
    pub fn open(&mut self, path: PathBuf) {
        self.path = path.display().to_string();
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let spawned = std::thread::Builder::new().name("study-analysis".to_owned()).spawn(move || {
            let _ = tx.send(load(path));
        });
        match spawned {
            Ok(_) => {
                self.running = Some(rx);
                self.error = None;
            }
            Err(e) => self.error = Some(format!("cannot start the analysis: {e}")),
        }
    }

    /// The names of the figures shown (the PNG files `vestnav_report::study::figures` wrote).
    pub fn figure_names(&self) -> Vec<String> {
        self.shown.iter().flat_map(|s| s.figures.iter().map(|(n, _)| n.clone())).collect()
    }

    /// Whether a save is being written.
    pub fn is_saving(&self) -> bool {
        self.saving.is_some()
    }

    /// Whether an analysis is being made.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Collects a finished analysis or save (textures made in `ctx`).
    fn poll(&mut self, ctx: &egui::Context, recent: &mut RecentFiles) {
        if let Some(rx) = &self.running {
            let done = match rx.try_recv() {
                Ok(r) => Some(r),
                Err(TryRecvError::Empty) => {
                    ctx.request_repaint_after(std::time::Duration::from_millis(100));
                    None
                }
                Err(TryRecvError::Disconnected) => Some(Err("the analysis thread ended".to_owned())),
            };
            if let Some(r) = done {
                self.running = None;
                match r {
                    Ok(l) => {
                        recent.push(RecentKind::StudyResults, &l.source);
                        let figures = l
                            .figures
                            .into_iter()
                            .map(|(name, img)| {
                                let tex = ctx.load_texture(
                                    format!("study-figure-{name}"),
                                    img,
                                    egui::TextureOptions::LINEAR,
                                );
                                (name, tex)
                            })
                            .collect();
                        self.shown =
                            Some(Shown { source: l.source, rows: l.rows, analysis: l.analysis, figures });
                        self.error = None;
                    }
                    Err(e) => self.error = Some(e),
                }
            }
        }
        if let Some(rx) = &self.saving {
            match rx.try_recv() {
                Ok(r) => {
                    self.saving = None;
                    self.save_status = Some(r);
                }
                Err(TryRecvError::Empty) => ctx.request_repaint_after(std::time::Duration::from_millis(100)),
                Err(TryRecvError::Disconnected) => {
                    self.saving = None;
                    self.save_status = Some(Err("the save thread ended".to_owned()));
                }
            }
        }
    }

    /// Draws the view.
    pub fn ui(&mut self, ui: &mut egui::Ui, recent: &mut RecentFiles) {
        self.poll(ui.ctx(), recent);
        let base = recent.base();
        ui.heading("Results");
        let spec = DialogSpec { mode: Mode::Open, title: "Open study results", filter: ("CSV", &["csv"]) };
        let mut chosen =
            file_dialog::path_field(ui, &mut self.path, &mut self.browse, spec, &base, "results.csv");
        ui.horizontal(|ui| {
            if let Some(p) = file_dialog::recent_menu(ui, recent, RecentKind::StudyResults) {
                chosen = Some(p);
            }
            if ui.add_enabled(!self.is_running(), egui::Button::new("Analyse")).clicked() {
                chosen = file_dialog::resolve(&self.path, &base);
            }
            if self.is_running() {
                ui.spinner();
            }
        });
        if let Some(p) = chosen
            && !self.is_running()
        {
            self.open(p);
        }
        if let Some(e) = &self.error {
            ui.label(RichText::new(e).strong().color(ui.visuals().error_fg_color));
        }
        let Some(shown) = &self.shown else {
            return;
        };
        ui.separator();
        ui.label(RichText::new(format!("{} ({} trials)", shown.source.display(), shown.rows)).strong());
        numbers_ui(ui, &shown.analysis);
        ui.separator();
        self.save_ui(ui, &base);
        let Some(shown) = &self.shown else { return };
        egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| {
            let width = ui.available_width();
            for (name, tex) in &shown.figures {
                ui.label(RichText::new(name).small().weak());
                let size = tex.size_vec2();
                let scale = (width / size.x).min(1.0);
                ui.add(egui::Image::new((tex.id(), size * scale)));
                ui.add_space(8.0);
            }
        });
    }

    /// "Save figures…": the folder, the question before replacing, the outcome.
    fn save_ui(&mut self, ui: &mut egui::Ui, base: &Path) {
        if let Some(Picked::File(p)) = self.save_browse.poll() {
            self.save_dir = p.display().to_string();
        }
        let mut save = false;
        ui.horizontal(|ui| {
            ui.label("Figures to folder:");
            ui.add(egui::TextEdit::singleline(&mut self.save_dir).desired_width(240.0).hint_text("figures"));
            let spec = DialogSpec { mode: Mode::Folder, title: "Save the figures in", filter: ("", &[]) };
            file_dialog::browse_button(ui, &self.save_dir, &mut self.save_browse, spec, base);
            let idle = self.saving.is_none() && self.pending_save.is_none();
            save = ui.add_enabled(idle, egui::Button::new("Save figures…")).clicked();
            if self.saving.is_some() {
                ui.spinner();
            }
        });
        let dir = file_dialog::resolve(&self.save_dir, base);
        file_dialog::uses_label(ui, dir.as_deref());
        if save && let Some(dir) = dir {
            let names: Vec<&str> =
                self.shown.iter().flat_map(|s| s.figures.iter().map(|(n, _)| n.as_str())).collect();
            if names.iter().any(|n| dir.join(n).exists()) {
                self.pending_save = Some(dir);
            } else {
                self.start_save(dir);
            }
        }
        if let Some(dir) = self.pending_save.clone() {
            match file_dialog::confirm_replace(ui.ctx(), &dir.join("*.png")) {
                Some(Answer::Replace) => {
                    self.pending_save = None;
                    self.start_save(dir);
                }
                Some(Answer::Cancel) => self.pending_save = None,
                None => {}
            }
        }
        match &self.save_status {
            Some(Ok(t)) => {
                ui.label(RichText::new(t).small());
            }
            Some(Err(e)) => {
                ui.label(RichText::new(e).small().color(ui.visuals().error_fg_color));
            }
            None => {}
        }
    }

    /// Writes the figures into `dir` on a `vestnav-export` thread.
    fn start_save(&mut self, dir: PathBuf) {
        let Some(shown) = &self.shown else { return };
        let analysis = Arc::clone(&shown.analysis);
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let spawned = std::thread::Builder::new().name("vestnav-export".to_owned()).spawn(move || {
            let r = std::fs::create_dir_all(&dir)
                .map_err(|e| e.to_string())
                .and_then(|()| vestnav_report::study::figures(&analysis, &dir).map_err(|e| e.to_string()))
                .map(|files| format!("saved {} figures in {}", files.len(), dir.display()))
                .map_err(|e| format!("figures not saved in {}: {e}", dir.display()));
            let _ = tx.send(r);
        });
        match spawned {
            Ok(_) => {
                self.saving = Some(rx);
                self.save_status = None;
            }
            Err(e) => self.save_status = Some(Err(format!("cannot start the save: {e}"))),
        }
    }
}

/// The analysis's numbers: percent correct, information transfer with its bias note, response times; for
/// navigation trials the summary per condition.
fn numbers_ui(ui: &mut egui::Ui, a: &StudyAnalysis) {
    let task = a.task.map_or("mixed or unknown task", |t| t.name());
    ui.label(format!(
        "{} · {task} · participants: {}",
        a.protocols.join(", "),
        if a.participants.is_empty() { "none".to_owned() } else { a.participants.join(", ") }
    ));
    let outcomes: Vec<String> =
        a.outcomes.iter().filter(|(_, n)| *n > 0).map(|(name, n)| format!("{name} {n}")).collect();
    ui.label(format!("{} trials: {}", a.trials, outcomes.join(", ")));
    let big = |t: String| RichText::new(t).size(18.0).strong();
    if !a.navigation.is_empty() {
        navigation_ui(ui, a);
    }
    if a.task == Some(vestnav_core::study::Task::Navigation) {
        return;
    }
    match a.percent_correct {
        Some(p) => ui.label(big(format!(
            "Percent correct: {p:.1} % ({} of {} answered test trials)",
            a.correct, a.answered
        ))),
        None => ui.label(big("Percent correct: no answered test trial".to_owned())),
    };
    if let Some(it) = a.it_bits {
        let of = a.stimulus_bits.map_or_else(String::new, |m| format!(" of at most {m:.2}"));
        let bias = match (a.it_bias_bits, a.it_corrected_bits) {
            (Some(b), Some(c)) => format!("; small-sample bias about {b:.2} bits, corrected {c:.2} bits"),
            _ => String::new(),
        };
        ui.label(big(format!("Information transfer: {it:.2} bits{of}{bias}")));
        ui.label(RichText::new(&a.it_note).small());
    }
    if let Some(rt) = &a.rt {
        ui.label(format!(
            "Response time: median {:.0} ms (quartiles {:.0}–{:.0} ms), mean {:.0} ms, n = {}",
            rt.median_ms, rt.q1_ms, rt.q3_ms, rt.mean_ms, rt.n
        ));
    }
}

/// The navigation summary: one row per condition, as `vestnav study analyze` prints it.
fn navigation_ui(ui: &mut egui::Ui, a: &StudyAnalysis) {
    let f = |x: Option<f64>, digits: usize| x.map_or_else(|| "–".to_owned(), |x| format!("{x:.digits$}"));
    ui.label(RichText::new("Navigation by condition").size(18.0).strong());
    egui::Grid::new("study-navigation").striped(true).show(ui, |ui| {
        for h in [
            "condition",
            "walks",
            "completed",
            "completion [s]",
            "path / route",
            "cross-track RMS [m]",
            "cues",
            "stops",
            "missed waypoints",
        ] {
            ui.label(RichText::new(h).strong());
        }
        ui.end_row();
        for c in &a.navigation {
            ui.label(&c.condition);
            ui.label(c.trials.to_string());
            ui.label(c.completed.to_string());
            ui.label(f(c.completion_mean_s, 0));
            ui.label(f(c.path_ratio_mean, 2));
            ui.label(f(c.cross_track_rms_mean_m, 2));
            ui.label(f(c.cues_mean, 1));
            ui.label(c.stops_total.to_string());
            ui.label(c.missed_waypoints_total.to_string());
            ui.end_row();
        }
    });
    ui.label(RichText::new("means per walk; completion time over the completed walks only").small());
}
