//! One export row for every view that writes a file (simulation figures, field-test reports): a path field
//! with **Browse…** (the desktop's save dialog), one "Save …" button per format, the absolute path the export
//! will use, a "Replace X?" question when that file exists, and the outcome of the last export.
//!
//! A typed relative path is taken in the folder the console passes as `base` (the last file's folder, else
//! the documents folder: [`crate::file_dialog::RecentFiles::base`]), never in the working directory, which
//! is `/` when the console starts from a desktop menu. The path's extension follows the button pressed, so
//! one path serves every format. Writing runs on a worker thread; a file that appears at the target between
//! the question and the write is not replaced unless the operator said so.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, TryRecvError};
#[cfg(test)]
use std::time::Duration;

use crate::file_dialog::{self, Answer, Browse, DialogSpec, Mode, Picked};

/// What an export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ExportFormat {
    /// A PNG sheet of the panels.
    Png,
    /// The panels' data as CSV.
    Csv,
    /// A JSON report.
    Json,
}

impl ExportFormat {
    fn extension(self) -> &'static str {
        match self {
            ExportFormat::Png => "png",
            ExportFormat::Csv => "csv",
            ExportFormat::Json => "json",
        }
    }

    fn button_text(self) -> &'static str {
        match self {
            ExportFormat::Png => "Save PNG",
            ExportFormat::Csv => "Save CSV",
            ExportFormat::Json => "Save JSON",
        }
    }
}

/// An export the operator asked for: the format, the absolute file, and whether replacing it was confirmed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct ExportRequest {
    /// The format of the button pressed.
    pub format: ExportFormat,
    /// The absolute file to write.
    pub path: PathBuf,
    /// The operator confirmed replacing an existing file.
    pub replace: bool,
}

/// Where a view's export goes and how the last export went (see the module documentation).
pub(crate) struct Exporter {
    /// The path as typed or chosen (relative paths are taken in the `base` given to [`Exporter::ui`]).
    pub path: String,
    /// The save dialog's title.
    title: &'static str,
    browse: Browse,
    /// A request waiting for the answer to "Replace X?".
    pending: Option<ExportRequest>,
    status: Option<Result<String, String>>,
    running: Option<Receiver<Result<String, String>>>,
}

impl Exporter {
    /// An exporter proposing `default_path`; `title` names the save dialog ("Export the tactor figure to").
    pub fn new(default_path: &str, title: &'static str) -> Self {
        Self {
            path: default_path.to_string(),
            title,
            browse: Browse::default(),
            pending: None,
            status: None,
            running: None,
        }
    }

    /// The absolute file an export in `format` writes: the typed path resolved in `base`, its extension
    /// replaced by the format's. `None` while the field is empty.
    pub fn target(&self, format: ExportFormat, base: &Path) -> Option<PathBuf> {
        file_dialog::resolve(&self.path, base).map(|p| p.with_extension(format.extension()))
    }

    /// Draws the export row and, when the operator asks for a file that exists, the "Replace X?" question.
    /// Returns the export to start on the frame it is decided: at once for a new file, after "Replace" for
    /// an existing one, never after "Cancel".
    pub fn ui(&mut self, ui: &mut egui::Ui, formats: &[ExportFormat], base: &Path) -> Option<ExportRequest> {
        self.poll();
        if let Some(Picked::File(p)) = self.browse.poll() {
            self.path = p.display().to_string();
        }
        let mut pressed = None;
        ui.horizontal_wrapped(|ui| {
            ui.label("Export to:");
            ui.add(egui::TextEdit::singleline(&mut self.path).desired_width(260.0).hint_text("path/figure"))
                .on_hover_text(format!("Relative names are taken in {}", base.display()));
            let spec = DialogSpec { mode: Mode::Save, title: self.title, filter: ("", &[]) };
            file_dialog::browse_button(ui, &self.path, &mut self.browse, spec, base);
            ui.add_enabled_ui(!self.is_running() && self.pending.is_none(), |ui| {
                for &format in formats {
                    if ui.button(format.button_text()).clicked() {
                        pressed = Some(format);
                    }
                }
            });
            if self.is_running() || self.browse.is_open() {
                ui.spinner();
            }
        });
        file_dialog::uses_label(ui, file_dialog::resolve(&self.path, base).as_deref());
        if let Some(note) = &self.browse.note {
            ui.label(egui::RichText::new(note).small().color(ui.visuals().warn_fg_color));
        }
        match &self.status {
            Some(Ok(msg)) => {
                ui.label(msg);
            }
            Some(Err(e)) => {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
            None => {}
        }
        let mut decided = None;
        if let Some(format) = pressed {
            match self.target(format, base) {
                None => self.status = Some(Err("type a file path or Browse… first".to_string())),
                Some(path) => {
                    // The field shows the absolute path the export uses from now on.
                    if let Some(abs) = file_dialog::resolve(&self.path, base) {
                        self.path = abs.display().to_string();
                    }
                    let request = ExportRequest { format, path, replace: false };
                    if request.path.exists() {
                        self.pending = Some(request);
                    } else {
                        decided = Some(request);
                    }
                }
            }
        }
        if let Some(pending) = &self.pending {
            match file_dialog::confirm_replace(ui.ctx(), &pending.path) {
                Some(Answer::Replace) => {
                    decided = self.pending.take().map(|r| ExportRequest { replace: true, ..r });
                }
                Some(Answer::Cancel) => {
                    self.pending = None;
                    self.status = Some(Ok("not exported: the file was kept".to_string()));
                }
                None => {}
            }
        }
        decided
    }

    /// Writes `bytes()` to the request's file on a worker thread. Unless the request says `replace`, a file
    /// that exists by then is left alone and the export fails naming it.
    pub fn start(
        &mut self,
        ctx: &egui::Context,
        request: ExportRequest,
        bytes: impl FnOnce() -> Result<Vec<u8>, String> + Send + 'static,
    ) {
        let (tx, rx) = mpsc::sync_channel(1);
        let ctx = ctx.clone();
        let ExportRequest { path, replace, .. } = request;
        let spawned = std::thread::Builder::new().name("vestnav-export".to_string()).spawn(move || {
            let result = if !replace && path.exists() {
                Err(format!("{} already exists: not replaced", path.display()))
            } else {
                bytes().and_then(|data| {
                    // Replacing: atomically (never half a file); new: never over a file that appeared
                    // since the check.
                    let written = if replace {
                        vestnav_files::write_atomic(&path, &data)
                    } else {
                        vestnav_files::write_new(&path, &data)
                    };
                    written.map(|()| format!("wrote {} ({} bytes)", path.display(), data.len())).map_err(
                        |e| {
                            if e.kind() == std::io::ErrorKind::AlreadyExists {
                                format!("{} already exists: not replaced", path.display())
                            } else {
                                format!("cannot write {}: {e}", path.display())
                            }
                        },
                    )
                })
            };
            let _ = tx.send(result);
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => {
                self.running = Some(rx);
                self.status = None;
            }
            Err(e) => self.status = Some(Err(format!("cannot start the export thread: {e}"))),
        }
    }

    /// Collects a finished export.
    fn poll(&mut self) {
        let Some(rx) = &self.running else { return };
        match rx.try_recv() {
            Ok(result) => {
                self.status = Some(result);
                self.running = None;
            }
            Err(TryRecvError::Empty) => {}
            Err(TryRecvError::Disconnected) => {
                self.status = Some(Err("the export thread stopped without a result".to_string()));
                self.running = None;
            }
        }
    }

    /// Result of the last export: `Ok(message)` or `Err(reason)`.
    #[cfg(test)]
    pub fn status(&self) -> Option<&Result<String, String>> {
        self.status.as_ref()
    }

    /// Whether an export is being written.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Blocks until the running export (if any) has finished; for tests.
    #[cfg(test)]
    pub fn wait(&mut self) {
        while self.running.is_some() {
            std::thread::sleep(Duration::from_millis(2));
            self.poll();
        }
    }
}

#[cfg(test)]
mod tests {
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable as _;

    use super::*;

    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vestnav-export-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    struct Row {
        exporter: Exporter,
        base: PathBuf,
        written: Vec<ExportRequest>,
    }

    fn harness(base: PathBuf, path: &str) -> Harness<'static, Row> {
        let row = Row { exporter: Exporter::new(path, "Export to"), base, written: Vec::new() };
        let mut h = Harness::new_ui_state(
            |ui, row: &mut Row| {
                let base = row.base.clone();
                if let Some(r) = row.exporter.ui(ui, &[ExportFormat::Png, ExportFormat::Json], &base) {
                    row.written.push(r.clone());
                    row.exporter.start(ui.ctx(), r, || Ok(b"new".to_vec()));
                }
            },
            row,
        );
        h.set_size(egui::vec2(900.0, 400.0));
        h
    }

    #[test]
    fn a_relative_path_is_taken_in_the_base_folder_and_the_extension_follows_the_button() {
        let base = tmp_dir("relative");
        let mut h = harness(base.clone(), "figures/../fig.png");
        h.run_steps(1);
        h.get_by_label("Save JSON").click();
        h.run_steps(2);
        h.state_mut().exporter.wait();
        h.run_steps(1);
        let want = base.join("fig.json");
        assert_eq!(h.state().written[0].path, want);
        assert_eq!(std::fs::read(&want).unwrap(), b"new");
        assert_eq!(h.state().exporter.path, base.join("fig.png").display().to_string());
        let cwd_copy = std::env::current_dir().unwrap().join("fig.json");
        assert!(!cwd_copy.exists() || cwd_copy == want, "nothing is written in the working directory");
    }

    #[test]
    fn an_existing_file_is_replaced_only_after_the_operator_says_so() {
        let base = tmp_dir("replace");
        let file = base.join("kept.png");
        std::fs::write(&file, b"old").unwrap();
        let mut h = harness(base, &file.display().to_string());
        h.run_steps(1);
        h.get_by_label("Save PNG").click();
        h.run_steps(2);
        assert!(h.state().written.is_empty(), "nothing is written before the answer");
        h.get_by_label("Cancel").click();
        h.run_steps(2);
        assert!(h.state().written.is_empty());
        assert_eq!(std::fs::read(&file).unwrap(), b"old");
        h.get_by_label("Save PNG").click();
        h.run_steps(2);
        h.get_by_label("Replace").click();
        h.run_steps(2);
        h.state_mut().exporter.wait();
        assert_eq!(std::fs::read(&file).unwrap(), b"new");
        assert!(h.state().written[0].replace);
    }

    #[test]
    fn a_file_that_appears_before_the_write_is_not_replaced_and_errors_name_the_file() {
        let base = tmp_dir("race");
        let mut ex = Exporter::new("x", "Export to");
        let ctx = egui::Context::default();
        let path = base.join("late.json");
        std::fs::write(&path, b"someone else's").unwrap();
        ex.start(
            &ctx,
            ExportRequest { format: ExportFormat::Json, path: path.clone(), replace: false },
            || Ok(b"ours".to_vec()),
        );
        ex.wait();
        assert!(matches!(ex.status(), Some(Err(e)) if e.contains("late.json") && e.contains("not replaced")));
        assert_eq!(std::fs::read(&path).unwrap(), b"someone else's");
        let bad = PathBuf::from("/nonexistent-dir-vestnav/x.csv");
        ex.start(&ctx, ExportRequest { format: ExportFormat::Csv, path: bad, replace: false }, || {
            Ok(vec![1])
        });
        ex.wait();
        assert!(
            matches!(ex.status(), Some(Err(e)) if e.contains("cannot write /nonexistent-dir-vestnav/x.csv"))
        );
        assert_eq!(ex.target(ExportFormat::Png, &base), Some(base.join("x.png")));
        ex.path = "  ".to_string();
        assert_eq!(ex.target(ExportFormat::Png, &base), None);
    }
}
