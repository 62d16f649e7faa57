//! The Stations window (`vestnav --broker …`, View > Stations…): every station on the MQTT broker and every
//! station on this machine's own ports (a second vest and GPS), with its last contact (stale shown as
//! stale), GPS, vest, guidance, battery and stop, a Stop and a Resume per station, the "continue the route
//! if the link drops" switch (broker stations), Add/Remove for local ones, and STOP ALL for every station
//! (the console's own STOP ALL reaches them too, through [`RemotePanel::stop_all`]). It is a view over
//! `vestnav_remote::Stations`, whose threads own the connection and the local stations; every row is
//! derived from what the station last published and when.

use std::time::{Duration, Instant};

use egui::{Color32, RichText};
use vestnav_remote::wire::StateMsg;
use vestnav_remote::{
    BrokerConfig, Fleet, FleetError, FleetOptions, LocalStationConfig, StationView, Stations,
};
use vestnav_station::command::StopSnapshot;
use vestnav_station::sources::{VEST_SPEC_FORMS, parse_gps_spec, parse_vest_spec};
use vestnav_station::stop::StopPath;

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

/// What the operator types to start a local station.
#[derive(Debug, Clone, Default)]
struct AddLocal {
    name: String,
    vest: String,
    gps: String,
}

/// The Stations window: every station, on the broker or on this machine's ports.
pub struct RemotePanel {
    stations: Stations,
    /// Whether the window is open.
    pub open: bool,
    /// The latest failure of a request, shown in the window until the next request.
    error: Option<String>,
    /// The station picked to drive, and what was sent to it.
    pub drive: crate::remote_drive::Drive,
    add: AddLocal,
    /// Where local stations' session logs go.
    log_dir: Option<std::path::PathBuf>,
}

impl RemotePanel {
    /// No broker and no local station yet. `stop` is the console's stop path (local stations join it, so
    /// the console's STOP ALL, a signal and every exit reach their vests).
    pub fn new(stop: StopPath, log_dir: Option<std::path::PathBuf>) -> Self {
        Self {
            stations: Stations::new("console", stop),
            open: true,
            error: None,
            drive: crate::remote_drive::Drive::default(),
            add: AddLocal::default(),
            log_dir,
        }
    }

    /// Connects to the broker as `operator` (in the background; the window shows the connection's state).
    pub fn connect(config: &BrokerConfig, operator: &str, stop: StopPath) -> Result<Self, FleetError> {
        let mut p = Self::new(stop, None);
        p.set_broker(config, operator)?;
        Ok(p)
    }

    /// Connects (again) to a broker, replacing the previous connection.
    pub fn set_broker(&mut self, config: &BrokerConfig, operator: &str) -> Result<(), FleetError> {
        self.stations.set_fleet(None);
        self.stations.set_fleet(Some(Fleet::connect(config, FleetOptions::operator(operator))?));
        Ok(())
    }

    /// Leaves the broker (local stations go on).
    pub fn leave_broker(&mut self) {
        self.stations.set_fleet(None);
    }

    /// Sets where local stations' session logs go.
    pub fn set_log_dir(&mut self, dir: Option<std::path::PathBuf>) {
        self.log_dir = dir;
    }

    /// The broker's client, when connected.
    pub fn fleet(&self) -> Option<&Fleet> {
        self.stations.fleet()
    }

    /// Every station, local and on the broker.
    pub fn stations(&self) -> &Stations {
        &self.stations
    }

    /// The same, to add or remove a local station.
    pub fn stations_mut(&mut self) -> &mut Stations {
        &mut self.stations
    }

    /// Sends `command` to the station being driven (nothing when none is): the Study tab drives a remote
    /// station's study through this, and the outcome shows in the drive's list.
    pub fn send_to_driven(&mut self, command: vestnav_station::command::Command) {
        self.drive.send(&self.stations, command);
    }

    /// Every station's wearer as the map draws it (a fix older than `fix_stale_s` is drawn as stale).
    pub fn wearers(&self, fix_stale_s: f64) -> Vec<crate::map_panel::remote::RemoteWearer> {
        let now = Instant::now();
        let stale_after = self.stations.stale_after();
        self.stations
            .stations()
            .into_iter()
            .map(|v| crate::map_panel::remote::RemoteWearer::from_view(v, now, stale_after, fix_stale_s))
            .collect()
    }

    /// STOP ALL for every station, local and on the broker (the console's STOP ALL calls it).
    pub fn stop_all(&mut self) {
        self.error = self.stations.stop_all().err().map(|e| format!("STOP ALL: {e}"));
    }

    /// Starts the local station the form describes.
    fn add_local(&mut self) {
        let a = &self.add;
        let config = parse_vest_spec(a.vest.trim()).and_then(|vest| {
            let gps = parse_gps_spec(a.gps.trim())?;
            let name = a.name.trim().to_owned();
            let log_dir = self.log_dir.as_ref().map(|d| d.join(&name));
            Ok(LocalStationConfig { name, vest, gps, log_dir })
        });
        let result = config.and_then(|c| {
            self.stations.add_local(c, Box::new(vestnav_station::hardware::Hardware::default()))
        });
        match result {
            Ok(()) => {
                self.error = None;
                self.add = AddLocal::default();
            }
            Err(e) => self.error = Some(format!("Add station: {e}")),
        }
    }

    /// The form that starts a local station.
    fn add_ui(&mut self, ui: &mut egui::Ui) {
        ui.collapsing("Add a station on this machine (a second vest and GPS)", |ui| {
            ui.horizontal(|ui| {
                ui.label("name");
                ui.add(egui::TextEdit::singleline(&mut self.add.name).hint_text("bravo").desired_width(90.0));
                ui.label("vest");
                ui.add(
                    egui::TextEdit::singleline(&mut self.add.vest)
                        .hint_text("serial:/dev/rfcomm1")
                        .desired_width(160.0),
                )
                .on_hover_text(format!("The vest: {VEST_SPEC_FORMS}"));
                ui.label("GPS");
                ui.add(
                    egui::TextEdit::singleline(&mut self.add.gps)
                        .hint_text("serial:/dev/rfcomm2")
                        .desired_width(160.0),
                )
                .on_hover_text(
                    "The GPS: serial:PATH[@BAUD], gpsd://HOST:PORT, replay:FILE, sim[:ROUTE.gpx], vest",
                );
                if ui.button("Add station").clicked() {
                    self.add_local();
                }
            });
        });
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
        let stale_after = self.stations.stale_after();
        let stations = self.stations.stations();
        let mut open = self.open;
        egui::Window::new("Stations").open(&mut open).default_width(760.0).show(ctx, |ui| {
            let broker = match self.stations.fleet().map(Fleet::broker_status) {
                Some((true, _)) => RichText::new("broker connected").color(Color32::from_rgb(60, 160, 60)),
                Some((false, err)) => RichText::new(format!(
                    "broker NOT connected: {}",
                    err.unwrap_or_else(|| "connecting".into())
                ))
                .color(ui.visuals().error_fg_color),
                None => RichText::new("no broker (View > Broker…); local stations only"),
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
                ui.label(if self.stations.fleet().is_some() {
                    "No station has published on this broker yet."
                } else {
                    "No station yet: add one on this machine's ports below."
                });
            }
            let mut remove = None;
            egui::Grid::new("stations-grid").striped(true).show(ui, |ui| {
                // The buttons come right after the name, whose width changes only with the list: the
                // status texts after them change width from frame to frame, and a button placed after
                // them would move under the pointer (a click meant for Stop could land on Resume).
                for h in ["station", "", "", "", "", "stop", "contact", "GPS", "vest", "guidance", "battery"] {
                    ui.label(RichText::new(h).strong());
                }
                ui.end_row();
                for (r, v) in rows(&stations, now, stale_after).into_iter().zip(&stations) {
                    let is_local = self.stations.is_local(&r.name);
                    let name = if is_local { format!("{} (this machine)", r.name) } else { r.name.clone() };
                    ui.label(RichText::new(name).strong());
                    if ui.button("Stop").clicked() {
                        self.error = self.stations.stop(&r.name).err().map(|e| format!("Stop {}: {e}", r.name));
                    }
                    if ui.button("Resume").clicked() {
                        self.error =
                            self.stations.resume(&r.name).err().map(|e| format!("Resume {}: {e}", r.name));
                    }
                    if is_local {
                        if ui
                            .button("Remove")
                            .on_hover_text("Stop this station's vest and close its ports")
                            .clicked()
                        {
                            remove = Some(r.name.clone());
                        }
                    } else if let Some(fleet) = self.stations.fleet() {
                        let mut armed = v.state.as_ref().is_some_and(|s| s.link.continue_armed);
                        if ui
                            .checkbox(&mut armed, "continue if link drops")
                            .on_hover_text("Armed: if this console's link to the station drops, the station keeps guiding along its own copy of the route instead of stopping the vest.")
                            .changed()
                        {
                            fleet.set_continue_on_loss(&r.name, armed);
                        }
                    } else {
                        ui.label("");
                    }
                    let driving = self.drive.selected.as_deref() == Some(r.name.as_str());
                    if ui
                        .selectable_label(driving, "Drive")
                        .on_hover_text("Send this station cues, a route, settings")
                        .clicked()
                    {
                        self.drive.selected = (!driving).then(|| r.name.clone());
                    }
                    ui.label(RichText::new(&r.stop).color(if r.stop.contains("NOT") {
                        ui.visuals().error_fg_color
                    } else {
                        ui.visuals().text_color()
                    }));
                    let contact = RichText::new(&r.contact);
                    ui.label(if r.stale { contact.color(ui.visuals().error_fg_color) } else { contact });
                    for text in [&r.gps, &r.vest, &r.guidance, &r.battery] {
                        // A stale station's last word is shown weak: it may no longer be true.
                        ui.label(if r.stale { RichText::new(text).weak() } else { RichText::new(text) });
                    }
                    ui.end_row();
                }
            });
            if let Some(name) = remove {
                self.stations.remove_local(&name);
                if self.drive.selected.as_deref() == Some(name.as_str()) {
                    self.drive.selected = None;
                }
            }
            self.add_ui(ui);
            ui.separator();
            self.drive.ui(ui, &self.stations, local, patterns, now);
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
