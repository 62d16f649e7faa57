//! RTK corrections in the console: the **RTK (NTRIP)** window over the station's NTRIP client
//! (`vestnav_station::ntrip`), and its one status line in the GPS panel. The window takes the caster,
//! mountpoint, credentials file (a file name only: the password stays in the file), version, GGA interval
//! and stall time, saved in the settings; **Start** asks the station to send the corrections to the running
//! serial receiver. What it shows comes from the client's status at the last pump: the state (a lost or
//! stalled caster as "reconnecting" with the reason, a refusal as "failed"), the correction age (amber
//! once older than `OLD_CORRECTION`), bytes per second, frames and their RTCM message types, and the
//! receiver's fix quality from its GGA (RTK fixed / float). Nothing here waits on the network.

use std::time::Instant;

use egui::RichText;
use vestnav_device::ntrip::{NtripState, NtripVersion};
use vestnav_station::Station;
use vestnav_station::ntrip::{NtripSettings, OLD_CORRECTION};

use crate::file_dialog::{Browse, DialogSpec, Mode, path_field, resolve};

/// The window's own state (the settings themselves live in the console's settings).
#[derive(Debug, Default)]
pub struct NtripUi {
    /// The window is open.
    pub open: bool,
    browse: Browse,
    /// The credentials file as typed.
    pub credentials_text: Option<String>,
    /// Why the last Start was refused.
    pub error: Option<String>,
}

const CREDENTIALS: DialogSpec =
    DialogSpec { mode: Mode::Open, title: "NTRIP credentials (user:password, private)", filter: ("", &[]) };

/// The corrections' status line with its colour (`None` before they were started): red when failed, amber
/// while reconnecting or when the last correction is old.
pub fn status(station: &Station, now: Instant) -> Option<(String, Status)> {
    let c = station.ntrip()?;
    let line = station.ntrip_line(now)?;
    let old = c.status.correction_age(now).is_some_and(|a| a > OLD_CORRECTION);
    let kind = match &c.status.state {
        NtripState::Failed { .. } => Status::Bad,
        NtripState::Reconnecting { .. } => Status::Warn,
        NtripState::Connected if old => Status::Warn,
        _ => Status::Normal,
    };
    let line = match &c.ended {
        Some(why) => format!("RTK corrections stopped: {why}. Last: {line}"),
        None => format!("RTK corrections {line}"),
    };
    Some((line, kind))
}

/// How a status line is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// As normal text.
    Normal,
    /// Amber: reconnecting, or old corrections.
    Warn,
    /// Red: failed.
    Bad,
}

/// The status line in the GPS panel (nothing before the corrections were started).
pub fn status_ui(station: &Station, ui: &mut egui::Ui, now: Instant) {
    let Some((line, kind)) = status(station, now) else { return };
    let color = match kind {
        Status::Normal => ui.visuals().text_color(),
        Status::Warn => ui.visuals().warn_fg_color,
        Status::Bad => ui.visuals().error_fg_color,
    };
    ui.label(RichText::new(line).small().color(color));
}

/// The **RTK (NTRIP)** window.
pub fn window(
    station: &mut Station,
    settings: &mut NtripSettings,
    state: &mut NtripUi,
    base: &std::path::Path,
    ctx: &egui::Context,
) {
    let mut open = state.open;
    egui::Window::new("RTK corrections (NTRIP)").open(&mut open).resizable(true).show(ctx, |ui| {
        body(station, settings, state, base, ui);
    });
    state.open = open;
}

fn body(
    station: &mut Station,
    settings: &mut NtripSettings,
    state: &mut NtripUi,
    base: &std::path::Path,
    ui: &mut egui::Ui,
) {
    let running = station.ntrip().is_some_and(vestnav_station::ntrip::Corrections::running);
    ui.add_enabled_ui(!running, |ui| {
        egui::Grid::new("ntrip-settings").num_columns(2).show(ui, |ui| {
            let name = ui.label("caster");
            ui.add(egui::TextEdit::singleline(&mut settings.caster).hint_text("HOST:2101"))
                .labelled_by(name.id);
            ui.end_row();
            let name = ui.label("mountpoint");
            ui.add(egui::TextEdit::singleline(&mut settings.mountpoint)).labelled_by(name.id);
            ui.end_row();
            ui.label("version");
            ui.horizontal(|ui| {
                ui.radio_value(&mut settings.version, NtripVersion::V2, "NTRIP 2.0");
                ui.radio_value(&mut settings.version, NtripVersion::V1, "NTRIP 1.0");
            });
            ui.end_row();
            let name = ui.label("send GGA every");
            ui.add(egui::DragValue::new(&mut settings.gga_every_s).range(0.0..=600.0).suffix(" s"))
                .labelled_by(name.id)
                .on_hover_text("0: never (casters of virtual reference stations need it)");
            ui.end_row();
            let name = ui.label("stalled after");
            ui.add(egui::DragValue::new(&mut settings.stall_s).range(1.0..=600.0).suffix(" s"))
                .labelled_by(name.id);
            ui.end_row();
        });
        ui.label("credentials file (user:password on its first line, readable by you only; blank: none)");
        let text = state.credentials_text.get_or_insert_with(|| {
            settings.credentials_file.as_ref().map(|p| p.display().to_string()).unwrap_or_default()
        });
        path_field(ui, text, &mut state.browse, CREDENTIALS, base, "ntrip-credentials");
        settings.credentials_file = resolve(text, base).filter(|_| !text.trim().is_empty());
    });
    ui.horizontal(|ui| {
        if running {
            if ui.button("Stop corrections").clicked() {
                station.stop_ntrip();
            }
        } else if ui.button("Start corrections").clicked() {
            state.error = station.start_ntrip(settings.clone()).err();
        }
    });
    if let Some(e) = &state.error {
        ui.colored_label(ui.visuals().error_fg_color, e);
    }
    let now = Instant::now();
    if let Some((line, kind)) = status(station, now) {
        let color = match kind {
            Status::Normal => ui.visuals().text_color(),
            Status::Warn => ui.visuals().warn_fg_color,
            Status::Bad => ui.visuals().error_fg_color,
        };
        ui.label(RichText::new(line).color(color));
    }
    if let Some(c) = station.ntrip() {
        let s = &c.status;
        ui.label(format!(
            "{} bytes, {} frames ({} bad CRC dropped), {} stalls, {} connections, {} refused by the receiver's port",
            s.bytes, s.frames, s.bad_crc, s.stalls, s.connects, s.write_errors
        ));
        if let Some(e) = &s.last_error {
            ui.label(RichText::new(format!("last error: {e}")).small().weak());
        }
    }
}
