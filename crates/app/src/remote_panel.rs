//! The Stations window (`vestnav --broker …`): every station on the MQTT broker with its last contact
//! (stale shown as stale), GPS, vest, guidance, battery and stop, a Stop and a Resume per station, the
//! "continue the route if the link drops" switch, and STOP ALL for every station (the console's own STOP
//! ALL reaches them too, through [`RemotePanel::stop_all`]). It is a view over `vestnav_remote::Fleet`,
//! whose thread owns the connection; every row is derived from what the station last published and when.

use std::time::{Duration, Instant};

use egui::{Color32, RichText};
use vestnav_remote::wire::StateMsg;
use vestnav_remote::{BrokerConfig, Fleet, FleetError, FleetOptions, StationView};
use vestnav_station::command::StopSnapshot;

/// One station's row, as words (a pure view-model: tests read it without a window).
#[derive(Debug, Clone, PartialEq)]
pub struct StationRow {
    /// The station's name.
    pub name: String,
    /// Last contact ("0.4 s ago", "no contact 12 s", "offline").
    pub contact: String,
    /// Whether the row is stale (no live word within the fleet's stale bound, or offline).
    pub stale: bool,
    /// GPS state and fix age.
    pub gps: String,
    /// Vest link and tactors on.
    pub vest: String,
    /// Guidance: cue or hold; halted; the operator link as the station sees it.
    pub guidance: String,
    /// Battery charge, when the unit reported it.
    pub battery: String,
    /// STOP state: in force, confirmed or NOT CONFIRMED.
    pub stop: String,
}

/// The rows for `stations` at `now`.
pub fn rows(stations: &[StationView], now: Instant, stale_after: Duration) -> Vec<StationRow> {
    stations
        .iter()
        .map(|v| {
            let offline = v.hello.as_ref().is_some_and(|h| !h.online);
            let stale = offline || v.is_stale(now, stale_after);
            let mut contact = v.contact_label(now, stale_after);
            if offline {
                contact = format!("offline ({contact})");
            }
            let (gps, vest, guidance, battery, stop) =
                v.state.as_ref().map_or_else(Default::default, describe_state);
            StationRow { name: v.name.clone(), contact, stale, gps, vest, guidance, battery, stop }
        })
        .collect()
}

fn describe_state(m: &StateMsg) -> (String, String, String, String, String) {
    let s = &m.station;
    let gps = match (&s.gps_alarm, s.fix_age_s) {
        (Some(a), _) => format!("ALARM {a:?}"),
        (None, Some(age)) => format!("fix {age:.1} s old"),
        (None, None) => vestnav_station::source_state_label(s.gps_state.as_ref()),
    };
    let link = s.vest_link.as_ref().map_or_else(|| "no vest".to_owned(), ToString::to_string);
    let on = s.tactors_on.map_or_else(String::new, |m| {
        if m.is_empty() {
            ", all off".to_owned()
        } else {
            format!(", on {:?}", m.indices().collect::<Vec<_>>())
        }
    });
    let vest = format!("{link}{on}");
    let mut guidance = match (&s.halted, s.guidance.as_ref()) {
        (Some(h), _) => format!("halted: {h}"),
        (None, Some(g)) => match (&g.hold, g.cue) {
            (Some(h), _) => format!("hold: {h}"),
            (None, Some(c)) => format!("cue {}", c.name()),
            (None, None) => "guiding".to_owned(),
        },
        (None, None) => "no guidance yet".to_owned(),
    };
    if !m.link.operator_contact {
        guidance.push_str(" · operator link lost");
    }
    if m.link.continue_armed {
        guidance.push_str(" · continues if the link drops");
    }
    let battery = s.battery.as_ref().map_or_else(String::new, |b| format!("{} %", b.status.battery_pct));
    let stop = match (&s.stop, m.link.stop_in_force) {
        (Some(StopSnapshot::Unconfirmed { for_s, .. }), _) => format!("STOP NOT CONFIRMED ({for_s:.1} s)"),
        (_, true) => "STOPPED (until resumed)".to_owned(),
        (Some(StopSnapshot::Confirmed), false) => "stopped, confirmed".to_owned(),
        (Some(StopSnapshot::Pending), false) => "stop sent".to_owned(),
        (None, false) => String::new(),
    };
    (gps, vest, guidance, battery, stop)
}

/// The Stations window and its fleet client.
pub struct RemotePanel {
    fleet: Fleet,
    /// Whether the window is open.
    pub open: bool,
    /// The latest failure of a request, shown in the window until the next request.
    error: Option<String>,
    /// The station picked to drive, and what was sent to it.
    pub drive: crate::remote_drive::Drive,
}

impl RemotePanel {
    /// Connects to the broker as `operator` (in the background; the window shows the connection's state).
    pub fn connect(config: &BrokerConfig, operator: &str) -> Result<Self, FleetError> {
        Ok(Self {
            fleet: Fleet::connect(config, FleetOptions::operator(operator))?,
            open: true,
            error: None,
            drive: crate::remote_drive::Drive::default(),
        })
    }

    /// The fleet client (the stations as last heard).
    pub fn fleet(&self) -> &Fleet {
        &self.fleet
    }

    /// Sends `command` to the station being driven (nothing when none is): the Study tab drives a remote
    /// station's study through this, and the outcome shows in the drive's list.
    pub fn send_to_driven(&mut self, command: vestnav_station::command::Command) {
        self.drive.send(&self.fleet, command);
    }

    /// Every station's wearer as the map draws it (a fix older than `fix_stale_s` is drawn as stale).
    pub fn wearers(&self, fix_stale_s: f64) -> Vec<crate::map_panel::remote::RemoteWearer> {
        let now = Instant::now();
        let stale_after = self.fleet.options().stale_after;
        self.fleet
            .stations()
            .iter()
            .map(|v| crate::map_panel::remote::RemoteWearer::from_view(v, now, stale_after, fix_stale_s))
            .collect()
    }

    /// STOP ALL for every station on the broker (the console's STOP ALL calls it).
    pub fn stop_all(&mut self) {
        self.error = self.fleet.stop_all().err().map(|e| format!("STOP ALL: {e}"));
    }

    /// Draws the window. `local` is the console's own station: its route and settings are what the drive
    /// controls send to the station picked, with the operator's saved `patterns`.
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        local: &vestnav_station::Station,
        patterns: &[vestnav_core::vest::Pattern],
    ) {
        let now = Instant::now();
        let stale_after = self.fleet.options().stale_after;
        let stations = self.fleet.stations();
        let mut open = self.open;
        egui::Window::new("Stations").open(&mut open).default_width(760.0).show(ctx, |ui| {
            let (connected, err) = self.fleet.broker_status();
            let broker = if connected {
                RichText::new("broker connected").color(Color32::from_rgb(60, 160, 60))
            } else {
                RichText::new(format!("broker NOT connected: {}", err.unwrap_or_else(|| "connecting".into())))
                    .color(ui.visuals().error_fg_color)
            };
            ui.horizontal(|ui| {
                ui.label(broker);
                if ui.button(RichText::new("STOP ALL stations").strong().color(Color32::WHITE)).clicked() {
                    self.stop_all();
                }
            });
            if let Some(e) = &self.error {
                ui.label(RichText::new(e).color(ui.visuals().error_fg_color));
            }
            if stations.is_empty() {
                ui.label("No station has published on this broker yet.");
            }
            egui::Grid::new("stations-grid").striped(true).show(ui, |ui| {
                for h in ["station", "contact", "GPS", "vest", "guidance", "battery", "stop", "", "", "", ""] {
                    ui.label(RichText::new(h).strong());
                }
                ui.end_row();
                for (r, v) in rows(&stations, now, stale_after).into_iter().zip(&stations) {
                    ui.label(RichText::new(&r.name).strong());
                    let contact = RichText::new(&r.contact);
                    ui.label(if r.stale { contact.color(ui.visuals().error_fg_color) } else { contact });
                    for text in [&r.gps, &r.vest, &r.guidance, &r.battery] {
                        // A stale station's last word is shown weak: it may no longer be true.
                        ui.label(if r.stale { RichText::new(text).weak() } else { RichText::new(text) });
                    }
                    ui.label(RichText::new(&r.stop).color(if r.stop.contains("NOT") {
                        ui.visuals().error_fg_color
                    } else {
                        ui.visuals().text_color()
                    }));
                    if ui.button("Stop").clicked() {
                        self.error = self.fleet.stop(&r.name).err().map(|e| format!("Stop {}: {e}", r.name));
                    }
                    if ui.button("Resume").clicked() {
                        self.error = self.fleet.resume(&r.name).err().map(|e| format!("Resume {}: {e}", r.name));
                    }
                    let mut armed = v.state.as_ref().is_some_and(|s| s.link.continue_armed);
                    if ui
                        .checkbox(&mut armed, "continue if link drops")
                        .on_hover_text("Armed: if this console's link to the station drops, the station keeps guiding along its own copy of the route instead of stopping the vest.")
                        .changed()
                    {
                        self.fleet.set_continue_on_loss(&r.name, armed);
                    }
                    let driving = self.drive.selected.as_deref() == Some(r.name.as_str());
                    if ui
                        .selectable_label(driving, "Drive")
                        .on_hover_text("Send this station cues, a route, settings")
                        .clicked()
                    {
                        self.drive.selected = (!driving).then(|| r.name.clone());
                    }
                    ui.end_row();
                }
            });
            ui.separator();
            self.drive.ui(ui, &self.fleet, local, patterns, now);
        });
        self.open = open;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_silent_station_reads_as_stale_and_an_offline_one_as_offline() {
        let now = Instant::now();
        let heard = StationView {
            name: "alpha".into(),
            last_contact: Some(now.checked_sub(Duration::from_secs(12)).unwrap()),
            ..StationView::default()
        };
        let r = &rows(std::slice::from_ref(&heard), now, Duration::from_secs(2))[0];
        assert!(r.stale);
        assert_eq!(r.contact, "no contact 12 s");
        let fresh = StationView { last_contact: Some(now), ..heard.clone() };
        assert!(!rows(&[fresh], now, Duration::from_secs(2))[0].stale);
        let gone = StationView {
            last_contact: Some(now),
            hello: Some(vestnav_remote::wire::Hello {
                name: "alpha".into(),
                online: false,
                schema: "v1".into(),
                link_bound_s: 0.0,
            }),
            ..heard
        };
        let r = &rows(&[gone], now, Duration::from_secs(2))[0];
        assert!(r.stale && r.contact.starts_with("offline"), "{r:?}");
    }
}
