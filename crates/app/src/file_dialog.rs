//! Files the operator names: typed paths and where they resolve, native file dialogs, recent files, and the
//! one "Replace X?" confirmation before a save replaces a file.
//!
//! **Typed paths.** A console started from a desktop menu often runs in `/`, so a relative typed path never
//! resolves against the working directory: [`resolve`] takes it in the console's files folder
//! ([`files_dir`], `~/Documents/vestnav`: the default home of every export) — never the folder of the last
//! file used, so an export does not land next to a replayed log — and expands a leading `~`. Every path
//! field shows the absolute path it will use ("Uses: /home/me/Documents/vestnav/walk.gpx").
//!
//! **Native dialogs.** "Browse…" opens the platform's dialog through `rfd` (on Linux the XDG desktop portal
//! over D-Bus, `libdbus` opened at run time: no GTK, no C build; `rfd` falls back to `zenity` when no portal
//! answers). The dialog runs on its own `file-dialog` thread and hands its answer back on a channel, so the
//! UI never blocks. The typed path always works: when no dialog can open (no portal, no D-Bus session, no
//! zenity) the answer is "nothing chosen" and the field says to type the path instead.
//!
//! **Recent files.** [`RecentFiles`] (kept in the config) holds the last [`RECENT_MAX`] files per kind. The
//! "Recent" menus list them; a file that no longer exists is shown as missing and cannot be opened.
//!
//! **Overwrite.** A save that would hit an existing file first asks "Replace X?" ([`confirm_replace`]); the
//! file is written only after **Replace**.

use std::path::{Component, Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};

use egui::RichText;
use serde::{Deserialize, Serialize};

/// How many files each recent list keeps.
pub const RECENT_MAX: usize = 8;

/// What a recent file is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecentKind {
    /// Route files (GPX) imported or exported on the Map tab.
    Routes,
    /// Session logs opened in the log viewer.
    Logs,
    /// Pattern files saved or loaded in the pattern editor.
    Patterns,
    /// NMEA logs replayed as the GPS source.
    Nmea,
    /// Study protocols (TOML) loaded in the Study tab.
    Protocols,
    /// Study results (CSV) opened in the Study tab's analysis.
    StudyResults,
}

/// The last files used, per kind, newest first, plus the folder of the very last file used.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct RecentFiles {
    /// Route files.
    pub routes: Vec<PathBuf>,
    /// Session logs.
    pub logs: Vec<PathBuf>,
    /// Pattern files.
    pub patterns: Vec<PathBuf>,
    /// NMEA replays.
    pub nmea: Vec<PathBuf>,
    /// Study protocols.
    pub protocols: Vec<PathBuf>,
    /// Study results.
    pub study_results: Vec<PathBuf>,
    /// Folder of the last file opened, saved or exported (any kind).
    pub last_dir: Option<PathBuf>,
}

impl RecentFiles {
    /// The list of `kind`, newest first.
    pub fn list(&self, kind: RecentKind) -> &[PathBuf] {
        match kind {
            RecentKind::Routes => &self.routes,
            RecentKind::Logs => &self.logs,
            RecentKind::Patterns => &self.patterns,
            RecentKind::Nmea => &self.nmea,
            RecentKind::Protocols => &self.protocols,
            RecentKind::StudyResults => &self.study_results,
        }
    }

    fn list_mut(&mut self, kind: RecentKind) -> &mut Vec<PathBuf> {
        match kind {
            RecentKind::Routes => &mut self.routes,
            RecentKind::Logs => &mut self.logs,
            RecentKind::Patterns => &mut self.patterns,
            RecentKind::Nmea => &mut self.nmea,
            RecentKind::Protocols => &mut self.protocols,
            RecentKind::StudyResults => &mut self.study_results,
        }
    }

    /// Puts `path` first in the list of `kind` (once; the oldest beyond [`RECENT_MAX`] dropped) and
    /// remembers its folder. Relative paths are ignored: the list holds what was used.
    pub fn push(&mut self, kind: RecentKind, path: &Path) {
        if !path.is_absolute() {
            return;
        }
        self.used(path);
        let list = self.list_mut(kind);
        list.retain(|p| p != path);
        list.insert(0, path.to_path_buf());
        list.truncate(RECENT_MAX);
    }

    /// Notes that `path` was used (an export that is not in any list): its folder is remembered.
    pub fn used(&mut self, path: &Path) {
        if let Some(dir) = path.parent().filter(|d| d.is_absolute()) {
            self.last_dir = Some(dir.to_path_buf());
        }
    }

    /// The folder relative typed paths are taken in: always the console's files folder
    /// ([`files_dir`]), never the folder of whatever file was used last (a replayed log's folder is no
    /// place for an export).
    pub fn base(&self) -> PathBuf {
        files_dir()
    }

    /// Drops what a hand-edited config could hold beyond the limits (relative paths, long lists).
    #[must_use]
    pub fn sanitized(mut self) -> Self {
        for kind in [
            RecentKind::Routes,
            RecentKind::Logs,
            RecentKind::Patterns,
            RecentKind::Nmea,
            RecentKind::Protocols,
            RecentKind::StudyResults,
        ] {
            let list = self.list_mut(kind);
            list.retain(|p| p.is_absolute());
            list.truncate(RECENT_MAX);
        }
        self.last_dir = self.last_dir.filter(|d| d.is_absolute());
        self
    }
}

/// The console's files folder: where exports go and relative typed paths are taken —
/// `<documents>/vestnav` (on Linux `$XDG_DOCUMENTS_DIR/vestnav`, usually `~/Documents/vestnav`). The
/// program's own folder: made on first use (once per run; a failure shows when a file is written there).
pub fn files_dir() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let dir = documents_dir().join("vestnav");
        let _ = std::fs::create_dir_all(&dir);
        dir
    })
    .clone()
}

/// The user's documents folder (`directories::UserDirs`), else the home folder, else the console's data
/// folder.
pub fn documents_dir() -> PathBuf {
    directories::UserDirs::new().map_or_else(crate::dirs::data_dir, |u| {
        u.document_dir().unwrap_or_else(|| u.home_dir()).to_path_buf()
    })
}

/// The absolute file a typed path names: trimmed; `~` and `~/…` in the home folder; a relative path taken
/// in `base`; `.` and `..` resolved by name (not through links), so the path shown is the path used.
/// `None` for an empty field.
pub fn resolve(typed: &str, base: &Path) -> Option<PathBuf> {
    let typed = typed.trim();
    if typed.is_empty() {
        return None;
    }
    let home = || directories::UserDirs::new().map(|u| u.home_dir().to_path_buf());
    let path = match typed.strip_prefix('~') {
        Some("") => home().unwrap_or_else(|| PathBuf::from(typed)),
        Some(rest) if rest.starts_with('/') || rest.starts_with(std::path::MAIN_SEPARATOR) => {
            home().map_or_else(|| PathBuf::from(typed), |h| h.join(rest.trim_start_matches(['/', '\\'])))
        }
        _ => PathBuf::from(typed),
    };
    let path = if path.is_absolute() { path } else { base.join(path) };
    Some(normalize(&path))
}

/// `path` with `.` removed and `..` taking off the previous name (never above the root).
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !matches!(
                    out.components().next_back(),
                    None | Some(Component::RootDir | Component::Prefix(_))
                ) {
                    out.pop();
                }
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// The "Uses: /absolute/path" line under a path field (or what to type when it is empty).
pub fn uses_label(ui: &mut egui::Ui, resolved: Option<&Path>) {
    let text = resolved.map_or_else(
        || format!("Type a file name or Browse… (relative names are taken in {})", files_dir().display()),
        |p| format!("Uses: {}", p.display()),
    );
    ui.label(RichText::new(text).small().weak());
}

/// Whether a dialog opens an existing file or names one to save.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Pick an existing file.
    Open,
    /// Name a file to write (the dialog may ask about replacing; the console asks again in any case).
    Save,
    /// Pick an existing folder (the filter is not used).
    Folder,
}

/// What a dialog is for: its mode, title and file-type filter.
#[derive(Debug, Clone, Copy)]
pub struct DialogSpec {
    /// Open or save.
    pub mode: Mode,
    /// The window title.
    pub title: &'static str,
    /// The filter's name (e.g. "GPX") and extensions without the dot; empty = every file.
    pub filter: (&'static str, &'static [&'static str]),
}

/// What came back from a dialog.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Picked {
    /// The operator chose this file.
    File(PathBuf),
    /// Nothing: cancelled, or no dialog could open.
    Nothing,
}

/// Why a dialog gave nothing, for the field's note.
pub const NOTHING_CHOSEN: &str = "No file chosen: cancelled, or no file dialog could open (no XDG desktop \
                                  portal or zenity running). Type the path in the field instead.";

/// A native dialog running on its own thread; [`Browse::poll`] collects its answer.
#[derive(Debug, Default)]
pub struct Browse {
    running: Option<Receiver<Picked>>,
    /// What the last dialog gave, when it was not a file (shown under the field).
    pub note: Option<String>,
}

/// A copy has no dialog open: the open dialog's answer goes to the original.
impl Clone for Browse {
    fn clone(&self) -> Self {
        Self { running: None, note: self.note.clone() }
    }
}

impl Browse {
    /// Whether a dialog is open.
    pub fn is_open(&self) -> bool {
        self.running.is_some()
    }

    /// Opens a dialog as `spec` says, starting in `dir` (with `file_name` proposed when saving), on the
    /// `file-dialog` thread; `ctx` is woken when it answers.
    pub fn start(&mut self, ctx: &egui::Context, spec: DialogSpec, dir: &Path, file_name: Option<&str>) {
        if self.running.is_some() {
            return;
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let ctx = ctx.clone();
        let dir = dir.to_path_buf();
        let file_name = file_name.map(str::to_owned);
        let spawned = std::thread::Builder::new().name("file-dialog".to_owned()).spawn(move || {
            let mut dialog = rfd::AsyncFileDialog::new().set_title(spec.title);
            if dir.is_dir() {
                dialog = dialog.set_directory(&dir);
            }
            if !spec.filter.1.is_empty() {
                dialog = dialog.add_filter(spec.filter.0, spec.filter.1);
            }
            let handle = match spec.mode {
                Mode::Open => block_on(dialog.pick_file()),
                Mode::Folder => block_on(dialog.pick_folder()),
                Mode::Save => {
                    if let Some(name) = &file_name {
                        dialog = dialog.set_file_name(name);
                    }
                    block_on(dialog.save_file())
                }
            };
            let _ = tx.send(handle.map_or(Picked::Nothing, |h| Picked::File(h.path().to_path_buf())));
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => {
                self.running = Some(rx);
                self.note = None;
            }
            Err(e) => self.note = Some(format!("cannot open a file dialog ({e}): type the path instead")),
        }
    }

    /// The dialog's answer, once it has come.
    pub fn poll(&mut self) -> Option<Picked> {
        let rx = self.running.as_ref()?;
        let picked = match rx.try_recv() {
            Ok(p) => p,
            Err(TryRecvError::Empty) => return None,
            Err(TryRecvError::Disconnected) => Picked::Nothing,
        };
        self.running = None;
        self.note = (picked == Picked::Nothing).then(|| NOTHING_CHOSEN.to_owned());
        Some(picked)
    }
}

/// Runs `fut` to completion on this thread (the dialog thread has nothing else to do): parks until woken.
fn block_on<F: std::future::Future>(fut: F) -> F::Output {
    use std::sync::Arc;
    use std::task::{Context, Poll, Wake, Waker};
    struct Unpark(std::thread::Thread);
    impl Wake for Unpark {
        fn wake(self: Arc<Self>) {
            self.0.unpark();
        }
    }
    let waker = Waker::from(Arc::new(Unpark(std::thread::current())));
    let mut cx = Context::from_waker(&waker);
    let mut fut = std::pin::pin!(fut);
    loop {
        if let Poll::Ready(out) = fut.as_mut().poll(&mut cx) {
            return out;
        }
        std::thread::park();
    }
}

/// A typed path field with its "Browse…" button and the "Uses: …" line: `text` is what the operator typed
/// (a chosen file replaces it), `base` where a relative one is taken. Returns the file the dialog chose this
/// frame, if any.
pub fn path_field(
    ui: &mut egui::Ui,
    text: &mut String,
    browse: &mut Browse,
    spec: DialogSpec,
    base: &Path,
    hint: &str,
) -> Option<PathBuf> {
    let picked = match browse.poll() {
        Some(Picked::File(p)) => {
            *text = p.display().to_string();
            Some(p)
        }
        _ => None,
    };
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(text).hint_text(hint).desired_width(240.0))
            .on_hover_text(format!("Relative names are taken in {}", base.display()));
        browse_button(ui, text, browse, spec, base);
        if browse.is_open() {
            ui.spinner();
        }
    });
    uses_label(ui, resolve(text, base).as_deref());
    if let Some(note) = &browse.note {
        ui.label(RichText::new(note).small().color(ui.visuals().warn_fg_color));
    }
    picked
}

/// The **Browse…** button of a path field holding `text`: opens the dialog `spec` in the folder of the file
/// the field names (else `base`), proposing its name when saving. Disabled while a dialog is open.
pub fn browse_button(ui: &mut egui::Ui, text: &str, browse: &mut Browse, spec: DialogSpec, base: &Path) {
    let button = ui
        .add_enabled(!browse.is_open(), egui::Button::new("Browse…"))
        .on_hover_text("Choose the file in the desktop's file dialog");
    if button.clicked() {
        let current = resolve(text, base);
        let dir = current.as_deref().and_then(Path::parent).filter(|d| d.is_dir()).unwrap_or(base);
        let name = current.as_deref().and_then(Path::file_name).map(|n| n.to_string_lossy().into_owned());
        browse.start(ui.ctx(), spec, dir, name.as_deref());
    }
}

/// The "Recent" menu of `kind`: returns the file clicked. A file that no longer exists is listed as
/// "(missing)" and cannot be clicked.
pub fn recent_menu(ui: &mut egui::Ui, recent: &RecentFiles, kind: RecentKind) -> Option<PathBuf> {
    let list = recent.list(kind);
    let mut chosen = None;
    ui.add_enabled_ui(!list.is_empty(), |ui| {
        ui.menu_button("Recent", |ui| {
            for p in list {
                if p.exists() {
                    if ui.button(p.display().to_string()).clicked() {
                        chosen = Some(p.clone());
                        ui.close();
                    }
                } else {
                    ui.add_enabled(false, egui::Button::new(format!("{} (missing)", p.display())))
                        .on_disabled_hover_text("This file no longer exists");
                }
            }
        })
        .response
        .on_disabled_hover_text("No recent files yet");
    });
    chosen
}

/// The operator's answer to "Replace X?".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// Write over the file.
    Replace,
    /// Leave the file as it is.
    Cancel,
}

/// The modal "Replace X?" for an existing `path`: `Some(answer)` on the frame the operator answers.
pub fn confirm_replace(ctx: &egui::Context, path: &Path) -> Option<Answer> {
    let mut answer = None;
    let modal = egui::Modal::new(egui::Id::unique("vestnav-confirm-replace")).show(ctx, |ui| {
        ui.label(RichText::new(format!("Replace {}?", path.display())).strong());
        ui.label("The file exists. Replacing it loses what it holds now.");
        ui.horizontal(|ui| {
            if ui.button("Replace").clicked() {
                answer = Some(Answer::Replace);
            }
            if ui.button("Cancel").clicked() {
                answer = Some(Answer::Cancel);
            }
        });
    });
    if answer.is_none() && modal.should_close() {
        answer = Some(Answer::Cancel);
    }
    answer
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_resolve_against_the_base() {
        let base = Path::new("/home/op/Documents");
        assert_eq!(resolve("walk.gpx", base), Some(PathBuf::from("/home/op/Documents/walk.gpx")));
        assert_eq!(resolve("  routes/a.gpx ", base), Some(PathBuf::from("/home/op/Documents/routes/a.gpx")));
        assert_eq!(resolve("../x/./b.gpx", base), Some(PathBuf::from("/home/op/x/b.gpx")));
        assert_eq!(resolve("/tmp/c.gpx", base), Some(PathBuf::from("/tmp/c.gpx")));
        assert_eq!(resolve("/../../d", base), Some(PathBuf::from("/d")));
        assert_eq!(resolve("   ", base), None);
        if let Some(home) = directories::UserDirs::new().map(|u| u.home_dir().to_path_buf()) {
            assert_eq!(resolve("~/w.gpx", base), Some(home.join("w.gpx")));
            assert_eq!(resolve("~", base), Some(home));
        }
        // A name starting with ~ is a name.
        assert_eq!(resolve("~x", base), Some(PathBuf::from("/home/op/Documents/~x")));
    }

    #[test]
    fn recent_lists_are_newest_first_unique_and_bounded() {
        let mut r = RecentFiles::default();
        for k in 0..12 {
            r.push(RecentKind::Routes, Path::new(&format!("/r/{k}.gpx")));
        }
        r.push(RecentKind::Routes, Path::new("/r/5.gpx"));
        r.push(RecentKind::Routes, Path::new("relative.gpx"));
        let list = r.list(RecentKind::Routes);
        assert_eq!(list.len(), RECENT_MAX);
        assert_eq!(list[0], Path::new("/r/5.gpx"));
        assert_eq!(list[1], Path::new("/r/11.gpx"));
        assert_eq!(list.iter().filter(|p| *p == Path::new("/r/5.gpx")).count(), 1);
        assert!(r.list(RecentKind::Logs).is_empty());
        assert_eq!(r.last_dir.as_deref(), Some(Path::new("/r")));
        let hand_edited =
            RecentFiles { logs: vec!["rel.jsonl".into(), "/a.jsonl".into()], ..RecentFiles::default() };
        assert_eq!(hand_edited.sanitized().logs, vec![PathBuf::from("/a.jsonl")]);
    }

    #[test]
    fn the_base_is_the_files_folder_whatever_file_was_used_last() {
        let tmp = std::env::temp_dir();
        let mut r = RecentFiles::default();
        r.push(RecentKind::Nmea, &tmp.join("replayed.nmea"));
        assert_eq!(r.base(), documents_dir().join("vestnav"));
        assert!(r.base().is_dir(), "the console's own folder is made on first use");
    }
}
