//! The vest panel: connection, the 4x4 grid as worn (back view), patterns, live tactor state.
//!
//! Grid buttons are labelled `T0`..`T15` with the numbering of `vestnav_core::vest` (seen from behind the
//! wearer, row-major from the top-left). A click fires that tactor for the configured on-time; with
//! "Multi-select" on (or Ctrl held), clicks toggle a selection that "Fire selected" sends at once.
//! "Pattern editor..." opens [`crate::pattern_editor`] in its own window.

use egui::{Color32, RichText, vec2};
use vestnav_core::vest::{Cue, Frame, GRID, Pattern, TactorMask};

use vestnav_device::wtcu::VestCommand;
use vestnav_station::Station;

use crate::compass_panel::Wizard;
use crate::config::{Config, VestSourceConfig};

/// The Vest panel's own widget state.
#[derive(Debug, Default)]
pub struct VestUi {
    /// Tactors selected for a multi-fire.
    pub selected: TactorMask,
    /// Multi-select mode: clicks select instead of firing.
    pub select_mode: bool,
    /// Name typed for a new user pattern.
    pub new_pattern_name: String,
    /// Vest port typed or picked.
    pub port: String,
}

impl VestUi {
    /// The state for the configured vest `source` (its port typed in).
    pub fn from_config(source: &VestSourceConfig) -> Self {
        Self {
            port: match source {
                VestSourceConfig::Serial { port } => port.clone(),
                VestSourceConfig::Emulated => String::new(),
            },
            ..Self::default()
        }
    }
}

/// (Re)connects the vest `station` runs to the source configured in `cfg`.
pub fn connect(station: &mut Station, cfg: &Config) {
    station.set_vest_source(cfg.vest.clone());
    station.connect_vest();
}

/// Sends a manual command (holding automatic guidance off; the station logs it). A refusal shows in the
/// panel's last reply, so the result is not shown twice.
fn send_manual(station: &mut Station, command: VestCommand, cue: Option<Cue>) {
    let _ = station.send_manual(command, cue);
}

/// Draws the Vest section: what `station` reports of the vest and the commands to it, the settings in `cfg`
/// it edits (on-time, port, patterns), its own state `vest_ui`, the compass `wizard` and whether the
/// pattern editor is open (`editor_open`).
pub fn show(
    station: &mut Station,
    cfg: &mut Config,
    vest_ui: &mut VestUi,
    wizard: &mut Wizard,
    editor_open: &mut bool,
    ui: &mut egui::Ui,
) {
    connection_ui(station, cfg, vest_ui, ui);
    if !station.vest.is_live() {
        ui.label(
            RichText::new(format!("Vest not live ({}): tactors cannot be fired", station.vest.label()))
                .color(Color32::from_rgb(230, 60, 40))
                .strong(),
        );
    }
    // The grid first, high in the panel: in view without scrolling.
    grid_ui(station, cfg, vest_ui, ui);
    ui.add(egui::Slider::new(&mut cfg.on_ms, 50..=2000).suffix(" ms").text("On-time"));
    ui.horizontal(|ui| {
        ui.checkbox(&mut vest_ui.select_mode, "Multi-select");
        let n = vest_ui.selected.count();
        if ui
            .add_enabled(n > 0 && station.vest.is_live(), egui::Button::new(format!("Fire selected ({n})")))
            .clicked()
        {
            send_manual(station, VestCommand::Fire { mask: vest_ui.selected, duration_ms: cfg.on_ms }, None);
        }
        if ui.add_enabled(n > 0, egui::Button::new("Clear")).clicked() {
            vest_ui.selected = TactorMask::NONE;
        }
    });
    ui.label(format!(
        "on now (as the unit reports): {}",
        match station.vest.tactors_on {
            None => "unknown".to_owned(),
            Some(m) if m.is_empty() => "none".to_owned(),
            Some(m) => m.indices().map(|i| i.to_string()).collect::<Vec<_>>().join(", "),
        }
    ));
    if let Some(r) = &station.vest.last_reply {
        let age = r.at.elapsed().as_secs_f64();
        let text = format!("{} ({age:.0} s ago)", r.text);
        if r.refused {
            ui.label(RichText::new(text).color(Color32::from_rgb(230, 60, 40)).strong());
        } else {
            ui.label(text);
        }
    }
    ui.separator();
    patterns_ui(station, cfg, vest_ui, editor_open, ui);
    ui.separator();
    crate::compass_panel::show(station, cfg, wizard, ui);
}

fn connection_ui(station: &mut Station, cfg: &mut Config, vest_ui: &mut VestUi, ui: &mut egui::Ui) {
    let emulated = matches!(cfg.vest, VestSourceConfig::Emulated);
    ui.horizontal(|ui| {
        let mut choice = emulated;
        ui.radio_value(&mut choice, true, "Emulated vest");
        ui.radio_value(&mut choice, false, "WTCU port");
        if choice != emulated {
            cfg.vest = if choice {
                VestSourceConfig::Emulated
            } else {
                VestSourceConfig::Serial { port: vest_ui.port.clone() }
            };
        }
    });
    if let VestSourceConfig::Serial { port } = &mut cfg.vest {
        ui.horizontal(|ui| {
            ui.label("Port");
            egui::ComboBox::from_id_salt("vest-port")
                .selected_text(if port.is_empty() { "pick" } else { port.as_str() })
                .show_ui(ui, |ui| {
                    for p in vestnav_device::serial::list_ports() {
                        let bt =
                            if p.kind == vestnav_device::serial::PortKind::Bluetooth { "[BT] " } else { "" };
                        ui.selectable_value(
                            port,
                            p.name.clone(),
                            format!("{bt}{} {}", p.name, p.description),
                        );
                    }
                });
            ui.text_edit_singleline(port);
        });
        vest_ui.port.clone_from(port);
    }
    ui.horizontal(|ui| {
        let connected = station.vest_connected();
        if ui.add_enabled(!connected, egui::Button::new("Connect vest")).clicked() {
            connect(station, cfg);
        }
        if ui.add_enabled(connected, egui::Button::new("Disconnect vest")).clicked() {
            station.disconnect_vest();
        }
        ui.label(RichText::new(station.vest.label()).strong());
    });
    // Shown only while the unit is live: what it said on a link that is gone is not its state now.
    if station.vest.is_live() {
        let battery = station.vest.status.as_ref().map_or_else(
            || "—".to_owned(),
            |(s, at)| format!("{} % ({:.0} s ago)", s.battery_pct, at.elapsed().as_secs_f64()),
        );
        let fw = station.vest.device.as_ref().map_or_else(|| "—".to_owned(), |d| d.firmware.to_string());
        ui.label(format!("battery {battery} · firmware {fw}"));
    }
}

fn grid_ui(station: &mut Station, cfg: &Config, vest_ui: &mut VestUi, ui: &mut egui::Ui) {
    let ctrl = ui.input(|i| i.modifiers.command);
    // Firing needs a live unit; selecting does not.
    let live = station.vest.is_live() || vest_ui.select_mode || ctrl;
    let on = station.vest.tactors_on;
    let selected = vest_ui.selected;
    let clicked = back_view_grid(ui, "vest-grid", vec2(52.0, 40.0), live, |i| {
        let lit = on.is_some_and(|m| m.contains(i));
        GridCell {
            text: vestnav_core::vest::tactor_label(i),
            fill: if lit {
                Some(Color32::from_rgb(250, 170, 20))
            } else if selected.contains(i) {
                Some(Color32::from_rgb(70, 110, 190))
            } else {
                None
            },
            hover: format!("tactor {i}: row {}, column {}", i / GRID, i % GRID),
        }
    });
    if let Some(i) = clicked {
        if vest_ui.select_mode || ctrl {
            vest_ui.selected = TactorMask(vest_ui.selected.0 ^ (1 << i));
        } else if let Some(mask) = TactorMask::single(i) {
            send_manual(station, VestCommand::Fire { mask, duration_ms: cfg.on_ms }, None);
        }
    }
    // The live state comes from the unit's reports: each change wakes the window (the station's waker).
}

/// One cell of [`back_view_grid`]: its text, its fill (`None`: the theme's button fill, normal text; a
/// fill is drawn with black text) and its hover text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GridCell {
    /// The cell's label.
    pub text: String,
    /// A highlight colour, if any.
    pub fill: Option<Color32>,
    /// What hovering says.
    pub hover: String,
}

/// The 4x4 tactor grid as worn, seen from behind the wearer (row-major from the wearer's upper left, the
/// numbering of `vestnav_core::vest`), with its "wearer's left · back view · right" line above: one drawing
/// for every view that shows or picks tactors on the back (the Vest panel, the Study tab). Cells are buttons
/// of `size`, enabled when `enabled`, each drawn as `cell(index)` says. Returns the index clicked.
pub fn back_view_grid(
    ui: &mut egui::Ui,
    id_salt: &str,
    size: egui::Vec2,
    enabled: bool,
    cell: impl Fn(usize) -> GridCell,
) -> Option<usize> {
    ui.horizontal(|ui| {
        ui.label(RichText::new("wearer's left").small());
        ui.label(RichText::new("· back view, as seen behind the wearer ·").small().weak());
        ui.label(RichText::new("right").small());
    });
    let mut clicked = None;
    let gap = (size.y * 0.15).clamp(4.0, 10.0);
    egui::Grid::new(id_salt).spacing(vec2(gap, gap)).show(ui, |ui| {
        for row in 0..GRID {
            for col in 0..GRID {
                let i = row * GRID + col;
                let c = cell(i);
                let text = RichText::new(c.text).strong();
                // Big cells (the Study tab's answer grid) get big labels; small ones the theme's size.
                let text = if size.y > 48.0 { text.size(size.y * 0.3) } else { text };
                let b = match c.fill {
                    Some(fill) => egui::Button::new(text.color(Color32::BLACK)).fill(fill),
                    None => egui::Button::new(text.color(ui.visuals().text_color()))
                        .fill(ui.visuals().widgets.inactive.bg_fill),
                };
                if ui.add_enabled(enabled, b.min_size(size)).on_hover_text(c.hover).clicked() {
                    clicked = Some(i);
                }
            }
            ui.end_row();
        }
    });
    clicked
}

fn patterns_ui(
    station: &mut Station,
    cfg: &mut Config,
    vest_ui: &mut VestUi,
    editor_open: &mut bool,
    ui: &mut egui::Ui,
) {
    ui.label("Patterns");
    ui.horizontal_wrapped(|ui| {
        for cue in Cue::ALL {
            if ui
                .add_enabled(station.vest.is_live(), egui::Button::new(cue.name()))
                .on_hover_text(describe(&cue.pattern(cfg.on_ms)))
                .clicked()
            {
                send_manual(station, VestCommand::Play(cue.pattern(cfg.on_ms)), Some(cue));
            }
        }
    });
    let mut remove = None;
    let mut play = None;
    for (k, p) in cfg.user_patterns.iter().enumerate() {
        ui.horizontal(|ui| {
            if ui
                .add_enabled(station.vest.is_live(), egui::Button::new(format!("Play {}", p.name)))
                .on_hover_text(describe(p))
                .clicked()
            {
                play = Some(p.clone());
            }
            if ui.small_button("Del").on_hover_text("Delete this pattern").clicked() {
                remove = Some(k);
            }
        });
    }
    if let Some(p) = play {
        send_manual(station, VestCommand::Play(p), None);
    }
    if let Some(k) = remove {
        cfg.user_patterns.remove(k);
    }
    ui.horizontal(|ui| {
        ui.add(
            egui::TextEdit::singleline(&mut vest_ui.new_pattern_name).hint_text("name").desired_width(90.0),
        );
        let ok = !vest_ui.selected.is_empty() && !vest_ui.new_pattern_name.trim().is_empty();
        if ui
            .add_enabled(ok, egui::Button::new("Save selection as pattern"))
            .on_hover_text("The selected tactors, on for the on-time, then off for as long, three times")
            .clicked()
        {
            cfg.user_patterns.push(Pattern {
                name: vest_ui.new_pattern_name.trim().to_owned(),
                frames: vec![
                    Frame { mask: vest_ui.selected, duration_ms: cfg.on_ms },
                    Frame { mask: TactorMask::NONE, duration_ms: cfg.on_ms },
                ],
                repeats: 3,
            });
            vest_ui.new_pattern_name.clear();
        }
    });
    let label = if *editor_open { "Close pattern editor" } else { "Pattern editor..." };
    if ui
        .button(label)
        .on_hover_text("Frames on a timeline, painted on the grid, intensities, preview, files")
        .clicked()
    {
        *editor_open = !*editor_open;
    }
}

fn describe(p: &Pattern) -> String {
    let frames: Vec<String> = p
        .frames
        .iter()
        .map(|f| {
            let idx: Vec<String> = f.mask.indices().map(|i| i.to_string()).collect();
            format!("[{}] {} ms", idx.join(" "), f.duration_ms)
        })
        .collect();
    format!("{} × {}: {}", p.repeats, p.name, frames.join(" -> "))
}

/// A small 4x4 back view of the tactors `on` (as worn, seen from behind), sized for a banner line of
/// `pt` points: where the operator looks when a stop is not confirmed, without scrolling to the grid.
/// `None`: the unit reports nothing.
pub fn mini_grid(ui: &mut egui::Ui, on: Option<TactorMask>, pt: f32) {
    let cell = (pt * 0.45).max(6.0);
    let gap = 2.0;
    let side = GRID as f32 * cell + (GRID as f32 - 1.0) * gap;
    let (rect, resp) = ui.allocate_exact_size(vec2(side, side), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    for row in 0..GRID {
        for col in 0..GRID {
            let i = row * GRID + col;
            let min = rect.min + vec2(col as f32 * (cell + gap), row as f32 * (cell + gap));
            let r = egui::Rect::from_min_size(min, vec2(cell, cell));
            let fill = match on {
                Some(m) if m.contains(i) => Color32::from_rgb(250, 170, 20),
                Some(_) => Color32::from_gray(60),
                None => Color32::from_gray(120),
            };
            painter.rect_filled(r, 1.0, fill);
        }
    }
    let text = match on {
        Some(m) if !m.is_empty() => {
            format!(
                "unit reports on: {}",
                m.indices().map(vestnav_core::vest::tactor_label).collect::<Vec<_>>().join(" ")
            )
        }
        Some(_) => "unit reports every tactor off".to_owned(),
        None => "the unit reports no tactor state".to_owned(),
    };
    resp.on_hover_text(text);
}
