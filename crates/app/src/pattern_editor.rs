//! The pattern editor (Vest panel, **Pattern editor...**): builds a [`Pattern`] frame by frame, checks it
//! against the limits in force while it is edited, previews it on the vest, and saves it to a JSON file or
//! to the operator's patterns in the config.
//!
//! - **Timeline**: one button per frame, as wide as the frame is long; add, duplicate, delete, move earlier
//!   or later, and the selected frame's duration [ms].
//! - **Grid**: the 4x4 grid as worn (numbering of `vestnav_core::vest`); a click toggles a tactor in the
//!   selected frame, dragging paints every tactor the pointer passes with the state the first one got.
//! - **Intensity**: a drive level 0..=255 per tactor, sent as `SET_INTENSITY` (grouped by level, for the
//!   tactors the pattern uses) right before the PLAY of a preview. Only for a unit that reports the
//!   intensity capability; the levels stay on the unit until changed, hence **Reset unit to full**.
//! - **Validation**: [`Limits::check_pattern`] of `vestnav_device::wtcu::limits` (the one home of the
//!   rules) with the console's limits tightened by the unit's ([`limits_in_force`]); while the pattern is
//!   refused the reason is shown in red and Preview and Save are disabled.
//! - **Files**: the pattern as JSON (serde of core's [`Pattern`]; the intensity levels are not part of
//!   it). Paths are typed or chosen with **Browse…** (the desktop's dialog, `crate::file_dialog`); a
//!   relative one is taken in [`patterns_dir`], not the working directory, and the field shows the absolute
//!   path it uses. Files saved or loaded join the **Recent** menu. Saving never replaces a file without
//!   asking "Replace X?".

use std::path::{Path, PathBuf};

use crate::file_dialog::{self, RecentFiles, RecentKind};

use egui::{Color32, RichText, Sense, vec2};
use vestnav_core::vest::{DEFAULT_ON_MS, Frame, GRID, Pattern, TACTOR_COUNT, TactorMask};
use vestnav_device::wtcu::VestCommand;
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::message::{Capabilities, DeviceInfo};

use vestnav_station::Station;

use crate::config::Config;

/// Largest pattern file read [bytes]: a valid pattern (at most a few dozen frames) is far smaller, and a
/// file may be anything.
pub const MAX_FILE_BYTES: u64 = 256 * 1024;

/// Full drive level.
pub const FULL_LEVEL: u8 = 255;

/// The editor's state, kept by the console while the window is closed.
#[derive(Debug, Clone)]
pub struct PatternEditor {
    /// Whether the window is shown.
    pub open: bool,
    /// The pattern being edited.
    pub pattern: Pattern,
    /// Index of the selected frame (the one the grid paints).
    pub selected: usize,
    /// Drive level of each tactor, sent before a preview.
    pub levels: [u8; TACTOR_COUNT],
    /// The typed file path.
    pub path: String,
    /// The last outcome of a file or config action, and whether it is an error.
    pub message: Option<(String, bool)>,
    /// A save that waits for the operator to confirm replacing this existing file.
    pub confirm_overwrite: Option<PathBuf>,
    /// A save to my patterns that waits for the operator to confirm replacing the one of the same name.
    pub confirm_replace: bool,
    /// While dragging on the grid: the state painted onto every tactor passed.
    paint: Option<bool>,
    /// The "Browse…" dialog of the file field.
    pub browse: crate::file_dialog::Browse,
}

/// The pattern file field's dialog (the field serves Save and Load: the save dialog can pick either).
const PATTERN_FILE: crate::file_dialog::DialogSpec = crate::file_dialog::DialogSpec {
    mode: crate::file_dialog::Mode::Save,
    title: "Pattern file (JSON)",
    filter: ("Pattern (JSON)", &["json"]),
};

impl Default for PatternEditor {
    fn default() -> Self {
        Self {
            open: false,
            pattern: Pattern {
                name: String::new(),
                frames: vec![Frame { mask: TactorMask::NONE, duration_ms: DEFAULT_ON_MS }],
                repeats: 1,
            },
            selected: 0,
            levels: [FULL_LEVEL; TACTOR_COUNT],
            path: String::new(),
            message: None,
            confirm_overwrite: None,
            confirm_replace: false,
            paint: None,
            browse: crate::file_dialog::Browse::default(),
        }
    }
}

/// The limits a pattern is held to: the console's own, tightened field by field by those the unit
/// reported at the handshake (what the link enforces; `None`: the console's alone).
pub fn limits_in_force(device: Option<&DeviceInfo>) -> Limits {
    let console = Limits::default();
    device.map_or(console, |d| console.tighter(&d.limits))
}

/// Why `pattern` would be refused under `limits`, in words; `None` when it passes.
pub fn refusal(pattern: &Pattern, limits: &Limits) -> Option<String> {
    limits.check_pattern(&pattern.frames, pattern.repeats).err().map(|e| e.to_string())
}

/// The `SET_INTENSITY` commands that put the tactors `pattern` uses at `levels`: one per distinct level,
/// in order of each level's lowest tactor. Empty when the pattern drives no tactor.
pub fn intensity_commands(pattern: &Pattern, levels: &[u8; TACTOR_COUNT]) -> Vec<VestCommand> {
    let used = pattern.frames.iter().fold(TactorMask::NONE, |a, f| a | f.mask);
    let mut groups: Vec<(u8, TactorMask)> = Vec::new();
    for (t, &level) in levels.iter().enumerate().filter(|&(t, _)| used.contains(t)) {
        let bit = TactorMask::single(t).unwrap_or(TactorMask::NONE);
        match groups.iter_mut().find(|(l, _)| *l == level) {
            Some((_, mask)) => *mask = *mask | bit,
            None => groups.push((level, bit)),
        }
    }
    groups.into_iter().map(|(level, mask)| VestCommand::SetIntensity { mask, level }).collect()
}

/// Where relative pattern paths are taken: `patterns/` in the console's data directory.
pub fn patterns_dir() -> PathBuf {
    crate::config::data_dir().join("patterns")
}

/// The file a typed path names: trimmed, relative paths taken in `base`, `.json` added when there is no
/// extension. Refused: an empty path, one without a file name (`dir/`, `..`), another extension.
pub fn resolve_path(typed: &str, base: &Path) -> Result<PathBuf, String> {
    let typed = typed.trim();
    if typed.is_empty() {
        return Err("type a file name (e.g. sweep.json)".to_owned());
    }
    let mut path = PathBuf::from(typed);
    if path.is_relative() {
        path = base.join(path);
    }
    let ends_with_separator = typed.ends_with('/') || typed.ends_with(std::path::MAIN_SEPARATOR);
    let Some(name) = path.file_name().filter(|_| !ends_with_separator) else {
        return Err(format!("{typed}: not a file name (it names a directory)"));
    };
    if name.to_string_lossy().trim_start_matches('.').is_empty() {
        return Err(format!("{typed}: not a file name"));
    }
    match path.extension().map(|e| e.to_string_lossy().to_lowercase()) {
        None => {
            path.set_extension("json");
            Ok(path)
        }
        Some(e) if e == "json" => Ok(path),
        Some(e) => Err(format!("{}: a pattern file ends in .json, not .{e}", path.display())),
    }
}

/// Why a save did not happen.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SaveError {
    /// The file exists and replacing it was not asked for.
    Exists(PathBuf),
    /// Writing failed; the text names the file.
    Io(String),
}

impl std::fmt::Display for SaveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Exists(p) => write!(f, "{} already exists", p.display()),
            Self::Io(e) => f.write_str(e),
        }
    }
}

impl std::error::Error for SaveError {}

/// Writes `pattern` as JSON to `path`. Without `overwrite` an existing file is left alone
/// ([`SaveError::Exists`], decided by the file system at creation, not by an earlier look); with it the
/// file is replaced in one rename, so a crash leaves the old file or the new one.
pub fn save_pattern(pattern: &Pattern, path: &Path, overwrite: bool) -> Result<(), SaveError> {
    let fail =
        |p: &Path, e: &dyn std::fmt::Display| SaveError::Io(format!("cannot write {}: {e}", p.display()));
    let text = serde_json::to_string_pretty(pattern).map_err(|e| fail(path, &e))?;
    // The patterns folder is made when it is the first pattern saved there.
    vestnav_files::ensure_parent(path).map_err(|e| fail(path, &e))?;
    let written = if overwrite {
        vestnav_files::write_atomic(path, text.as_bytes())
    } else {
        vestnav_files::write_new(path, text.as_bytes())
    };
    written.map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            SaveError::Exists(path.to_path_buf())
        } else {
            fail(path, &e)
        }
    })
}

/// Reads a pattern file written by [`save_pattern`] (or by hand). Errors name the file.
pub fn load_pattern(path: &Path) -> Result<Pattern, String> {
    use std::io::Read as _;
    let fail = |e: &dyn std::fmt::Display| format!("cannot read {}: {e}", path.display());
    let file = std::fs::File::open(path).map_err(|e| fail(&e))?;
    let mut text = String::new();
    file.take(MAX_FILE_BYTES + 1).read_to_string(&mut text).map_err(|e| fail(&e))?;
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(fail(&format!("larger than {MAX_FILE_BYTES} bytes, not a pattern")));
    }
    serde_json::from_str(&text).map_err(|e| fail(&format!("not a pattern: {e}")))
}

impl PatternEditor {
    /// Draws the window when it is open: the preview goes to the vest `station` runs, saved patterns into
    /// `cfg`. Drawn by the frame, not inside the Vest section, so collapsing the section (or scrolling it
    /// away) does not hide an open editor.
    pub fn window(&mut self, station: &mut Station, cfg: &mut Config, ctx: &egui::Context) {
        if !self.open {
            return;
        }
        let mut open = self.open;
        egui::Window::new("Pattern editor")
            .open(&mut open)
            .default_pos([380.0, 90.0])
            .default_size([560.0, 720.0])
            .resizable(true)
            .vscroll(true)
            .show(ctx, |ui| self.ui(station, cfg, ui));
        self.open = open;
    }

    /// The editor's contents.
    pub fn ui(&mut self, station: &mut Station, cfg: &mut Config, ui: &mut egui::Ui) {
        self.selected = self.selected.min(self.pattern.frames.len().saturating_sub(1));
        ui.horizontal(|ui| {
            ui.label("Name");
            ui.add(egui::TextEdit::singleline(&mut self.pattern.name).hint_text("name").desired_width(160.0));
            ui.label("Repeats");
            ui.add(egui::DragValue::new(&mut self.pattern.repeats).range(1..=20));
        });
        ui.separator();
        self.timeline_ui(ui);
        ui.separator();
        self.grid_ui(ui);
        ui.separator();
        self.intensity_ui(station, ui);
        ui.separator();
        let limits = limits_in_force(station.vest.device.as_ref());
        let refused = refusal(&self.pattern, &limits);
        match &refused {
            Some(reason) => {
                ui.label(
                    RichText::new(format!("Refused: {reason}"))
                        .color(Color32::from_rgb(230, 60, 40))
                        .strong(),
                );
            }
            None => {
                ui.label(format!(
                    "Within the limits: {} ms in all, at most {} tactors at once, longest on-time {} ms",
                    self.pattern.total_ms(),
                    self.pattern.max_simultaneous(),
                    self.pattern.longest_on_ms()
                ));
            }
        }
        self.actions_ui(station, cfg, ui, refused.is_none());
        self.file_ui(ui, refused.is_none(), &mut cfg.recent);
        if let Some((text, error)) = &self.message {
            let text = RichText::new(text);
            ui.label(if *error { text.color(Color32::from_rgb(230, 60, 40)).strong() } else { text });
        }
    }

    fn timeline_ui(&mut self, ui: &mut egui::Ui) {
        ui.label("Timeline (frames, width by duration)");
        egui::ScrollArea::horizontal().id_salt("pattern-timeline").show(ui, |ui| {
            ui.horizontal(|ui| {
                for (k, f) in self.pattern.frames.iter().enumerate() {
                    let width = (f32::from(f.duration_ms) * 0.06).clamp(48.0, 180.0);
                    let text = format!("#{} · {} ms · {}", k + 1, f.duration_ms, f.mask.count());
                    let tip = format!("frame {}: tactors [{}]", k + 1, list(f.mask));
                    let b = egui::Button::selectable(k == self.selected, text).min_size(vec2(width, 32.0));
                    if ui.add(b).on_hover_text(tip).clicked() {
                        self.selected = k;
                    }
                }
            });
        });
        let n = self.pattern.frames.len();
        let has = n > 0;
        let room = n < usize::from(u8::MAX);
        ui.horizontal_wrapped(|ui| {
            if ui
                .add_enabled(room, egui::Button::new("Add frame"))
                .on_hover_text("An empty frame after this one")
                .clicked()
            {
                let duration_ms =
                    self.pattern.frames.get(self.selected).map_or(DEFAULT_ON_MS, |f| f.duration_ms);
                let at = if has { self.selected + 1 } else { 0 };
                self.pattern.frames.insert(at, Frame { mask: TactorMask::NONE, duration_ms });
                self.selected = at;
            }
            if ui.add_enabled(has && room, egui::Button::new("Duplicate frame")).clicked()
                && let Some(&f) = self.pattern.frames.get(self.selected)
            {
                self.pattern.frames.insert(self.selected + 1, f);
                self.selected += 1;
            }
            if ui.add_enabled(has, egui::Button::new("Delete frame")).clicked() && self.selected < n {
                self.pattern.frames.remove(self.selected);
                self.selected = self.selected.min(self.pattern.frames.len().saturating_sub(1));
            }
            if ui.add_enabled(has && self.selected > 0, egui::Button::new("Move earlier")).clicked() {
                self.pattern.frames.swap(self.selected, self.selected - 1);
                self.selected -= 1;
            }
            if ui.add_enabled(self.selected + 1 < n, egui::Button::new("Move later")).clicked() {
                self.pattern.frames.swap(self.selected, self.selected + 1);
                self.selected += 1;
            }
        });
        if let Some(f) = self.pattern.frames.get_mut(self.selected) {
            ui.horizontal(|ui| {
                let label = ui.label(format!("Frame {} duration", self.selected + 1));
                ui.add(egui::DragValue::new(&mut f.duration_ms).range(0..=10_000).speed(10.0).suffix(" ms"))
                    .labelled_by(label.id);
            });
        } else {
            ui.label("No frames: add one.");
        }
    }

    fn grid_ui(&mut self, ui: &mut egui::Ui) {
        let Some(frame) = self.pattern.frames.get_mut(self.selected) else { return };
        ui.label(
            RichText::new(format!(
                "Frame {}: click or drag to paint (back view, wearer's left on the left)",
                self.selected + 1
            ))
            .small(),
        );
        let (pressed, down) = ui.input(|i| (i.pointer.primary_pressed(), i.pointer.primary_down()));
        if pressed {
            self.paint = None;
        }
        let size = vec2(44.0, 34.0);
        egui::Grid::new("pattern-editor-grid").spacing(vec2(4.0, 4.0)).show(ui, |ui| {
            for row in 0..GRID {
                for col in 0..GRID {
                    let i = row * GRID + col;
                    let (rect, resp) = ui.allocate_exact_size(size, Sense::click_and_drag());
                    let on = frame.mask.contains(i);
                    resp.widget_info(|| {
                        egui::WidgetInfo::selected(
                            egui::Role::Button,
                            ui.is_enabled(),
                            on,
                            format!("Paint {}", vestnav_core::vest::tactor_label(i)),
                        )
                    });
                    let mut set = None;
                    if resp.drag_started() {
                        self.paint = Some(!on);
                        set = Some(!on);
                    } else if resp.clicked() {
                        set = Some(!on);
                    } else if let Some(v) = self.paint
                        && down
                        && ui.rect_contains_pointer(rect)
                    {
                        set = Some(v);
                    }
                    if let Some(v) = set {
                        let bit = TactorMask::single(i).unwrap_or(TactorMask::NONE);
                        frame.mask = if v { frame.mask | bit } else { TactorMask(frame.mask.0 & !bit.0) };
                    }
                    let on = frame.mask.contains(i);
                    let visuals = ui.style().interact(&resp);
                    let fill = if on { Color32::from_rgb(70, 110, 190) } else { visuals.bg_fill };
                    ui.painter().rect_filled(rect, 4.0, fill);
                    ui.painter().rect_stroke(rect, 4.0, visuals.bg_stroke, egui::StrokeKind::Inside);
                    let text_color = if on { Color32::WHITE } else { visuals.text_color() };
                    ui.painter().text(
                        rect.center(),
                        egui::Align2::CENTER_CENTER,
                        vestnav_core::vest::tactor_label(i),
                        egui::TextStyle::Button.resolve(ui.style()),
                        text_color,
                    );
                    resp.on_hover_text(format!("tactor {i}: row {row}, column {col}"));
                }
                ui.end_row();
            }
        });
        if !down {
            self.paint = None;
        }
    }

    fn intensity_ui(&mut self, station: &Station, ui: &mut egui::Ui) {
        let capable = station.vest.device.is_some_and(|d| d.capabilities.contains(Capabilities::INTENSITY));
        egui::CollapsingHeader::new("Intensity per tactor (sent before the preview)").show(ui, |ui| {
            if !capable {
                let why = if station.vest.device.is_none() {
                    "No unit has identified itself: connect the vest to set intensities."
                } else {
                    "This unit does not report the intensity capability (no SET_INTENSITY): tactors run at \
                     its fixed level."
                };
                ui.label(RichText::new(why).color(Color32::from_rgb(230, 60, 40)));
            }
            ui.add_enabled_ui(capable, |ui| {
                egui::Grid::new("pattern-editor-levels").spacing(vec2(4.0, 4.0)).show(ui, |ui| {
                    for row in 0..GRID {
                        for col in 0..GRID {
                            let i = row * GRID + col;
                            if let Some(level) = self.levels.get_mut(i) {
                                ui.label(vestnav_core::vest::tactor_label(i));
                                ui.add(egui::DragValue::new(level).range(0..=255));
                            }
                        }
                        ui.end_row();
                    }
                });
                ui.horizontal(|ui| {
                    if ui.button("All to full").clicked() {
                        self.levels = [FULL_LEVEL; TACTOR_COUNT];
                    }
                    if ui.button("All to half").clicked() {
                        self.levels = [FULL_LEVEL / 2 + 1; TACTOR_COUNT];
                    }
                });
            });
        });
    }

    fn actions_ui(&mut self, station: &mut Station, cfg: &mut Config, ui: &mut egui::Ui, valid: bool) {
        let live = station.vest.is_live();
        let capable = station.vest.device.is_some_and(|d| d.capabilities.contains(Capabilities::INTENSITY));
        ui.horizontal_wrapped(|ui| {
            let why = if valid { "The vest is not live" } else { "The pattern is outside the limits" };
            if ui
                .add_enabled(valid && live, egui::Button::new("Preview"))
                .on_hover_text("Play it on the vest (intensities first, when the unit has them)")
                .on_disabled_hover_text(why)
                .clicked()
            {
                if capable {
                    for command in intensity_commands(&self.pattern, &self.levels) {
                        let _ = station.send_manual(command, None);
                    }
                }
                let _ = station.send_manual(VestCommand::Play(self.pattern.clone()), None);
            }
            if ui
                .add_enabled(live && capable, egui::Button::new("Reset unit to full"))
                .on_hover_text("Every tactor of the unit back to level 255 (the levels stay on the unit)")
                .clicked()
            {
                let _ = station.send_manual(
                    VestCommand::SetIntensity { mask: TactorMask::ALL, level: FULL_LEVEL },
                    None,
                );
            }
            if !live {
                ui.label(RichText::new("Vest not live: no preview").color(Color32::from_rgb(230, 60, 40)));
            }
        });
        ui.horizontal_wrapped(|ui| {
            let name = self.pattern.name.trim().to_owned();
            let ok = valid && !name.is_empty();
            if ui
                .add_enabled(ok, egui::Button::new("Save to my patterns"))
                .on_disabled_hover_text("Needs a name and a pattern within the limits")
                .clicked()
            {
                if cfg.user_patterns.iter().any(|p| p.name == name) {
                    self.confirm_replace = true;
                } else {
                    self.save_to_config(cfg, &name);
                }
            }
            if self.confirm_replace {
                ui.label(RichText::new(format!("'{name}' exists in my patterns.")).strong());
                if ui.add_enabled(ok, egui::Button::new("Replace it")).clicked() {
                    self.save_to_config(cfg, &name);
                }
                if ui.button("Keep it").clicked() {
                    self.confirm_replace = false;
                }
            }
        });
    }

    fn save_to_config(&mut self, cfg: &mut Config, name: &str) {
        let mut p = self.pattern.clone();
        name.clone_into(&mut p.name);
        match cfg.user_patterns.iter_mut().find(|q| q.name == name) {
            Some(q) => *q = p,
            None => cfg.user_patterns.push(p),
        }
        self.confirm_replace = false;
        self.message = Some((format!("'{name}' saved to my patterns"), false));
    }

    fn file_ui(&mut self, ui: &mut egui::Ui, valid: bool, recent: &mut RecentFiles) {
        let base = patterns_dir();
        let before = self.path.clone();
        ui.horizontal(|ui| {
            ui.label("File");
            ui.vertical(|ui| {
                file_dialog::path_field(
                    ui,
                    &mut self.path,
                    &mut self.browse,
                    PATTERN_FILE,
                    &base,
                    "sweep.json",
                );
            });
            if let Some(p) = file_dialog::recent_menu(ui, recent, RecentKind::Patterns) {
                self.path = p.display().to_string();
            }
        });
        if self.path != before {
            self.confirm_overwrite = None;
        }
        ui.horizontal_wrapped(|ui| {
            if ui
                .add_enabled(valid, egui::Button::new("Save to file"))
                .on_disabled_hover_text("The pattern is outside the limits")
                .clicked()
            {
                self.save_file(&base, false, recent);
            }
            if ui.button("Load file").clicked() {
                self.confirm_overwrite = None;
                self.message = Some(
                    match resolve_path(&self.path, &base)
                        .and_then(|p| load_pattern(&p).map(|pattern| (p, pattern)))
                    {
                        Ok((p, pattern)) => {
                            self.pattern = pattern;
                            self.selected = 0;
                            recent.push(RecentKind::Patterns, &p);
                            (format!("loaded {}", p.display()), false)
                        }
                        Err(e) => (e, true),
                    },
                );
            }
            if let Some(p) = self.confirm_overwrite.clone() {
                ui.label(RichText::new(format!("Replace {}?", p.display())).strong());
                if ui.add_enabled(valid, egui::Button::new("Replace file")).clicked() {
                    self.save_file(&base, true, recent);
                }
                if ui.button("Cancel").clicked() {
                    self.confirm_overwrite = None;
                    self.message = Some((format!("{} left as it was", p.display()), false));
                }
            }
        });
    }

    fn save_file(&mut self, base: &Path, overwrite: bool, recent: &mut RecentFiles) {
        let path = match resolve_path(&self.path, base) {
            Ok(p) => p,
            Err(e) => {
                self.message = Some((e, true));
                return;
            }
        };
        // A confirmation is for the file it was asked about, not one typed since.
        let overwrite = overwrite && self.confirm_overwrite.as_deref() == Some(path.as_path());
        self.confirm_overwrite = None;
        self.message = Some(match save_pattern(&self.pattern, &path, overwrite) {
            Ok(()) => {
                recent.push(RecentKind::Patterns, &path);
                (format!("saved {}", path.display()), false)
            }
            Err(SaveError::Exists(p)) => {
                let text = format!("{} exists: Replace file, or Cancel", p.display());
                self.confirm_overwrite = Some(p);
                (text, true)
            }
            Err(SaveError::Io(e)) => (e, true),
        });
    }
}

fn list(mask: TactorMask) -> String {
    mask.indices().map(|i| i.to_string()).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(frames: &[(u16, u16)], repeats: u8) -> Pattern {
        Pattern {
            name: "p".into(),
            frames: frames.iter().map(|&(m, d)| Frame { mask: TactorMask(m), duration_ms: d }).collect(),
            repeats,
        }
    }

    #[test]
    fn refusals_come_from_the_device_limits() {
        let l = Limits::default();
        assert_eq!(refusal(&pattern(&[(0b11, 500), (0, 500)], 2), &l), None);
        let nine = refusal(&pattern(&[(0x01FF, 100)], 1), &l).unwrap();
        assert!(nine.contains("9 tactors at once"), "{nine}");
        let long = refusal(&pattern(&[(1, 2500)], 1), &l).unwrap();
        assert!(long.contains("2500 ms"), "{long}");
        let tighter = Limits { max_simultaneous: 2, ..l };
        assert!(refusal(&pattern(&[(0b111, 100)], 1), &tighter).is_some());
    }

    #[test]
    fn intensity_commands_group_the_used_tactors_by_level() {
        let mut levels = [FULL_LEVEL; TACTOR_COUNT];
        levels[1] = 100;
        levels[4] = 100;
        levels[9] = 7; // not used by the pattern
        let p = pattern(&[(0b11, 100), (0b1_0001, 100)], 1);
        assert_eq!(
            intensity_commands(&p, &levels),
            vec![
                VestCommand::SetIntensity { mask: TactorMask::from_indices([0]), level: 255 },
                VestCommand::SetIntensity { mask: TactorMask::from_indices([1, 4]), level: 100 },
            ]
        );
        assert!(intensity_commands(&pattern(&[(0, 100)], 1), &levels).is_empty());
    }

    #[test]
    fn typed_paths_are_checked_and_taken_in_the_patterns_dir() {
        let base = Path::new("/base");
        assert_eq!(resolve_path(" sweep ", base), Ok(PathBuf::from("/base/sweep.json")));
        assert_eq!(resolve_path("a/b.JSON", base), Ok(PathBuf::from("/base/a/b.JSON")));
        assert_eq!(resolve_path("/tmp/x.json", base), Ok(PathBuf::from("/tmp/x.json")));
        assert!(resolve_path("", base).is_err());
        assert!(resolve_path("dir/", base).is_err());
        assert!(resolve_path("..", base).is_err());
        assert!(resolve_path("x.gpx", base).unwrap_err().contains(".gpx"));
    }

    #[test]
    fn saving_never_replaces_a_file_unasked() {
        let dir = std::env::temp_dir().join(format!("vestnav-pattern-editor-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("p.json");
        let a = pattern(&[(1, 100)], 1);
        let b = pattern(&[(2, 200)], 3);
        save_pattern(&a, &path, false).unwrap();
        assert_eq!(save_pattern(&b, &path, false), Err(SaveError::Exists(path.clone())));
        assert_eq!(load_pattern(&path), Ok(a));
        save_pattern(&b, &path, true).unwrap();
        assert_eq!(load_pattern(&path), Ok(b));
        std::fs::write(&path, "{not json").unwrap();
        assert!(load_pattern(&path).unwrap_err().contains("p.json"));
        assert!(load_pattern(&dir.join("missing.json")).unwrap_err().contains("missing.json"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
