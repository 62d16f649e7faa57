//! The GPS panel's "Receiver" section: configure the receiver on a direct serial port (u-blox rate,
//! constellations, dynamic model, static hold, save; `SiRF` static navigation off) and show what became of
//! each command, with its time.
//!
//! The commands and their documents are `vestnav_device::gps::receiver_config`'s (docs/gps.md, "Receiver
//! configuration"); the serial source's worker writes them and decides each from the receiver's replies.

use std::time::Duration;

use egui::RichText;
use vestnav_device::gps::receiver_config::{
    ConfigEvent, ConfigTicket, Constellations, DynamicModel, Family, Outcome, ReceiverConfig,
};

use crate::config::GpsSourceConfig;
use vestnav_station::Station;

/// What the operator set up, and the last run.
#[derive(Debug)]
pub struct ReceiverUi {
    /// The configuration window is open.
    pub open: bool,
    /// The receiver family.
    pub family: Family,
    /// The operator picked the family (else it follows the family the stream shows).
    pub family_picked: bool,
    /// Navigation rate [Hz] (u-blox).
    pub rate_hz: u8,
    /// Constellations (u-blox).
    pub constellations: Constellations,
    /// Dynamic model (u-blox).
    pub dynamic_model: DynamicModel,
    /// Static hold threshold [m/s], 0 = off (u-blox).
    pub static_hold_m_s: f64,
    /// Also save to the receiver's flash.
    pub save: bool,
    /// The run under way.
    pub ticket: Option<ConfigTicket>,
    /// The last run's outcomes: local time, command, outcome.
    pub results: Vec<(String, String, Outcome)>,
    /// Why the last Send did not start, or how it ended.
    pub status: Option<String>,
}

impl Default for ReceiverUi {
    /// What the vest's wearer needs: 1 Hz, GPS + GLONASS + Galileo, pedestrian, static hold off.
    fn default() -> Self {
        Self {
            open: false,
            family: Family::Ublox,
            family_picked: false,
            rate_hz: 1,
            constellations: Constellations::default(),
            dynamic_model: DynamicModel::Pedestrian,
            static_hold_m_s: 0.0,
            save: false,
            ticket: None,
            results: Vec::new(),
            status: None,
        }
    }
}

impl ReceiverUi {
    /// The configuration "Send to receiver" sends (u-blox families: everything set here).
    pub fn request(&self) -> ReceiverConfig {
        match self.family {
            Family::Sirf => Self::sirf_static_nav_off(),
            f => ReceiverConfig {
                rate_hz: Some(self.rate_hz),
                constellations: Some(self.constellations),
                dynamic_model: Some(self.dynamic_model),
                static_hold_m_s: Some(self.static_hold_m_s),
                save: self.save,
                ..ReceiverConfig::new(f)
            },
        }
    }

    /// The `SiRF` button's configuration: static navigation off.
    pub fn sirf_static_nav_off() -> ReceiverConfig {
        ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Sirf) }
    }

    /// Takes the run's new events; true while it is still under way.
    pub fn poll(&mut self) -> bool {
        let Some(t) = &self.ticket else { return false };
        let mut finished = false;
        while let Some(ev) = t.try_recv() {
            match ev {
                ConfigEvent::Outcome(o) => {
                    let time = chrono::Local::now().format("%H:%M:%S").to_string();
                    self.results.push((time, o.name, o.outcome));
                }
                ConfigEvent::Failed(e) => {
                    self.status = Some(e);
                    finished = true;
                }
                ConfigEvent::Finished => {
                    let ok = self.results.iter().all(|r| matches!(r.2, Outcome::Accepted | Outcome::Sent));
                    self.status = Some(if ok { "done".into() } else { "done, not all accepted".into() });
                    finished = true;
                }
            }
        }
        if finished {
            self.ticket = None;
        }
        !finished
    }

    /// Starts a run of `cfg` through the station's running GPS source (a direct serial port only).
    pub fn send(&mut self, station: &Station, cfg: ReceiverConfig) {
        let ticket = station
            .gps_worker()
            .ok_or_else(|| "connect the GPS first".to_owned())
            .and_then(|w| w.configure(cfg));
        match ticket {
            Ok(t) => {
                self.ticket = Some(t);
                self.results.clear();
                self.status = Some("sending ...".into());
            }
            Err(e) => self.status = Some(e),
        }
    }
}

/// Whether the running source can configure its receiver: only a direct serial port can; otherwise why.
/// `source` is the configured source the station runs.
pub fn availability(station: &Station, source: &GpsSourceConfig) -> Result<(), String> {
    if !station.gps_connected() {
        return Err("connect the GPS on its serial port first".into());
    }
    match source {
        GpsSourceConfig::Serial { .. } => Ok(()),
        _ => Err(format!(
            "{} (the current source is not a serial port)",
            vestnav_device::gps::source::CONFIG_NEEDS_SERIAL
        )),
    }
}

/// Draws the configuration window when open (the GPS panel's **Receiver** toggle opens it). Drawn by the
/// frame, so it stays open when the GPS section is collapsed, and it takes no room above the vest grid.
/// A run under way is followed whether or not the window is open. `r` is the window's own state; `station`
/// runs the GPS source configured as `source`.
/// `rtk_open` is the RTK (NTRIP) window's switch, offered at the top (it is the receiver's input; the GPS
/// panel's row has no room for it without pushing the vest grid below the first screen).
pub fn window(
    station: &Station,
    source: &GpsSourceConfig,
    r: &mut ReceiverUi,
    rtk_open: &mut bool,
    ctx: &egui::Context,
) {
    if r.poll() {
        ctx.request_repaint_after(Duration::from_millis(100));
    }
    let mut open = r.open;
    egui::Window::new("GPS receiver configuration").open(&mut open).default_width(380.0).show(ctx, |ui| {
        ui.toggle_value(rtk_open, "RTK corrections (NTRIP)…")
            .on_hover_text("Corrections from an NTRIP caster to the receiver's serial port");
        ui.separator();
        body(station, source, r, ui);
    });
    r.open = open;
}

fn body(station: &Station, source: &GpsSourceConfig, r: &mut ReceiverUi, ui: &mut egui::Ui) {
    let available = availability(station, source);
    let detected = station.gps_family();
    if !r.family_picked
        && let Some(f) = detected
    {
        r.family = f;
    }
    let picked =
        egui::ComboBox::from_label("Receiver family").selected_text(r.family.label()).show_ui(ui, |ui| {
            Family::ALL.iter().any(|&f| ui.selectable_value(&mut r.family, f, f.label()).clicked())
        });
    if picked.inner == Some(true) {
        r.family_picked = true;
    }
    if let Some(f) = detected {
        ui.label(RichText::new(format!("the stream shows a {}", f.label())).small().weak());
    }
    let busy = r.ticket.is_some();
    if r.family == Family::Sirf {
        ui.label(
            "A SiRF III with static navigation on holds its position while the wearer walks slower than \
             about 1.2 m/s (speed reads 0), so guidance cannot see a slow walker move.",
        );
        let b = ui.add_enabled(available.is_ok() && !busy, egui::Button::new("SiRF static navigation off"));
        let b = match &available {
            Err(why) => b.on_disabled_hover_text(why),
            Ok(()) => b.on_hover_text("$PSRF100 to SiRF binary, MID 143 (disable), MID 129 back to NMEA"),
        };
        if b.clicked() {
            r.send(station, ReceiverUi::sirf_static_nav_off());
        }
    } else {
        ui.add(egui::Slider::new(&mut r.rate_hz, 1..=10).text("Hz navigation rate"));
        ui.horizontal_wrapped(|ui| {
            let k = &mut r.constellations;
            ui.checkbox(&mut k.gps, "GPS");
            ui.checkbox(&mut k.glonass, "GLONASS");
            ui.checkbox(&mut k.galileo, "Galileo");
            ui.checkbox(&mut k.beidou, "BeiDou");
            ui.checkbox(&mut k.qzss, "QZSS");
            ui.checkbox(&mut k.sbas, "SBAS");
        });
        egui::ComboBox::from_label("Dynamic model").selected_text(r.dynamic_model.name()).show_ui(ui, |ui| {
            for m in DynamicModel::ALL {
                ui.selectable_value(&mut r.dynamic_model, m, m.name());
            }
        });
        ui.add(
            egui::DragValue::new(&mut r.static_hold_m_s)
                .range(0.0..=2.55)
                .speed(0.01)
                .fixed_decimals(2)
                .prefix("static hold below ")
                .suffix(" m/s (0 = off)"),
        );
        ui.checkbox(&mut r.save, "Save to receiver flash (survives a power cycle)");
        let valid = r.request().validate().map_err(|e| e.to_string());
        let reason = available.clone().and(valid.clone());
        let b = ui.add_enabled(reason.is_ok() && !busy, egui::Button::new("Send to receiver"));
        let b = match &reason {
            Err(why) => b.on_disabled_hover_text(why),
            Ok(()) => b,
        };
        if b.clicked() {
            r.send(station, r.request());
        }
        if let Err(why) = valid {
            ui.label(RichText::new(why).color(ui.visuals().warn_fg_color));
        }
    }
    if let Err(why) = &available {
        ui.label(RichText::new(why).small().weak());
    }
    for (time, name, outcome) in &r.results {
        let color = match outcome {
            Outcome::Accepted | Outcome::Sent => ui.visuals().text_color(),
            _ => ui.visuals().warn_fg_color,
        };
        ui.label(RichText::new(format!("{time}  {name}: {}", outcome.label())).color(color));
    }
    if let Some(s) = &r.status {
        ui.label(RichText::new(s).small());
    }
}
