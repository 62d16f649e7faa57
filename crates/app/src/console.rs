//! The console's state and frame: top bar, side panels (GPS, Vest, Guidance), central tabs.
//!
//! [`Console`] holds everything the UI shows and can be built without a window (tests drive it with
//! `egui_kittest`). Devices come from an injected [`DeviceFactory`]. Worker threads report on bounded
//! channels that [`Console::ui`] drains at the start of each frame within a small time budget; the
//! guidance worker and the session-log writer are fed directly by routing threads, so they keep running
//! when the window is hidden.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::time::Duration;

use egui::{Color32, RichText};
use vestnav_core::guidance::StrategyKind;
use vestnav_core::vest::{Cue, TactorMask};

use crate::config::{Config, GpsSourceConfig, VestSourceConfig};
use crate::devices::{DeviceFactory, VestLink, Worker};
use crate::fieldtest_panel::{FieldTestAction, FieldTestPanel};
use crate::guidance::{GuidanceInput, GuidanceSettings, GuidanceStatus};
use crate::map_panel::MapView;
use crate::model::{
    CommandOrigin, GpsEvent, GpsFix, LinkState, Outbox, VestCommand, VestEvent, drain_within,
};
use crate::session_log::{LogEntry, LogSender, SessionLog};
use crate::sim_panel::SimPanel;

/// Time the UI may spend per frame draining worker events.
const DRAIN_BUDGET: Duration = Duration::from_millis(2);

/// The central area's tabs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tab {
    /// The map.
    Map,
    /// Physics simulation plots.
    Simulation,
    /// Drift and cone tests.
    FieldTests,
    /// Session log viewer and replay.
    SessionLog,
}

/// What the GPS side shows.
#[derive(Debug, Default)]
pub struct GpsView {
    /// Link state reported by the worker.
    pub link: LinkState,
    /// Latest fix.
    pub fix: Option<GpsFix>,
    /// UI time of the latest fix with a position [s].
    pub fix_at_s: Option<f64>,
    /// UI time of the latest epoch of any kind [s].
    pub epoch_at_s: Option<f64>,
    /// Fixes received this session.
    pub fixes: u64,
    /// Latest notice from the worker.
    pub notice: Option<String>,
    /// When the operator silenced the alarm (it re-arms on the next good fix).
    pub alarm_silenced: bool,
    /// Editor state of the source picker.
    pub picker: crate::gps_panel::SourcePicker,
}

/// Why the GPS alarm is on.
#[derive(Debug, Clone, PartialEq)]
pub enum GpsAlarm {
    /// The last position is older than the stale limit.
    Stale {
        /// Age [s].
        age_s: f64,
    },
    /// No position for longer than the lost limit, or the receiver reports no fix, or the link dropped.
    Lost {
        /// Why.
        reason: String,
    },
}

/// What the vest side shows.
#[derive(Debug, Default)]
pub struct VestView {
    /// Link state.
    pub link: LinkState,
    /// Tactors the unit reports on.
    pub tactors_on: TactorMask,
    /// Battery [%].
    pub battery_pct: Option<u8>,
    /// Firmware version.
    pub firmware: String,
    /// Latest ack or refusal, for the operator.
    pub last_reply: Option<String>,
    /// Tactors selected for a multi-fire.
    pub selected: TactorMask,
    /// Multi-select mode: clicks select instead of firing.
    pub select_mode: bool,
    /// Name typed for a new user pattern.
    pub new_pattern_name: String,
    /// Vest port typed or picked.
    pub port: String,
}

/// The console.
pub struct Console {
    /// Settings (persisted).
    pub cfg: Config,
    cfg_path: Option<PathBuf>,
    cfg_saved: Config,
    factory: Box<dyn DeviceFactory>,
    /// Active central tab.
    pub tab: Tab,
    /// GPS state.
    pub gps: GpsView,
    /// Vest state.
    pub vest: VestView,
    /// Map state (route, track, view).
    pub map: MapView,
    /// Latest guidance status.
    pub guidance: Option<GuidanceStatus>,
    /// Status line (errors shown once).
    pub status: String,
    gps_router_tx: SyncSender<GpsEvent>,
    gps_rx: Receiver<GpsEvent>,
    vest_router_tx: SyncSender<VestEvent>,
    vest_rx: Receiver<VestEvent>,
    guidance_rx: Receiver<GuidanceStatus>,
    guidance_tx: SyncSender<GuidanceInput>,
    gps_worker: Option<Box<dyn Worker>>,
    vest_link: Option<Arc<dyn VestLink>>,
    log: Option<SessionLog>,
    log_tx: Option<LogSender>,
    sim_panel: SimPanel,
    field_panel: FieldTestPanel,
    /// Session log viewer / replay.
    pub log_viewer: crate::log_viewer::LogViewer,
}

/// Options for [`Console::new`].
pub struct ConsoleOptions {
    /// Settings to start with.
    pub cfg: Config,
    /// Where to save settings (`None`: never saved, e.g. in tests).
    pub cfg_path: Option<PathBuf>,
    /// Directory for the session log (`None`: no log).
    pub log_dir: Option<PathBuf>,
    /// The UI context, to wake the UI from workers (`None` in headless tests that step frames anyway).
    pub waker: Option<egui::Context>,
}

impl Console {
    /// Builds the console, starts the guidance worker and the session log, and connects the configured
    /// devices when `cfg.auto_connect` is set.
    #[allow(clippy::too_many_lines)] // the wiring of every thread and channel, kept in one readable place
    pub fn new(factory: Box<dyn DeviceFactory>, opts: ConsoleOptions) -> Self {
        let ConsoleOptions { cfg, cfg_path, log_dir, waker } = opts;
        let mut status = String::new();
        let log = log_dir.and_then(|d| match SessionLog::create(&d) {
            Ok(l) => Some(l),
            Err(e) => {
                status = format!("session log disabled: cannot write in {}: {e}", d.display());
                None
            }
        });
        let log_tx = log.as_ref().and_then(SessionLog::sender);

        let (guidance_ui_tx, guidance_rx) = sync_channel(256);
        let (guidance_tx, guidance_in_rx) = sync_channel(1024);
        let settings = guidance_settings(&cfg);
        if let Err(e) = crate::guidance::spawn(
            guidance_in_rx,
            settings,
            Outbox::new(guidance_ui_tx, waker.clone()),
            log_tx.clone(),
        ) {
            status = format!("guidance worker failed to start: {e}");
        }

        let (gps_ui_tx, gps_rx) = sync_channel(1024);
        let (gps_router_tx, gps_router_rx) = sync_channel::<GpsEvent>(1024);
        {
            let ui = Outbox::new(gps_ui_tx, waker.clone());
            let guidance = Outbox::new(guidance_tx.clone(), None);
            let log = log_tx.clone();
            spawn_router("vestnav-gps-router", gps_router_rx, move |ev: GpsEvent| {
                if let GpsEvent::Fix(fix) = &ev {
                    if fix.has_position()
                        && let Some(log) = &log
                    {
                        log.log(LogEntry::Fix {
                            lat_deg: fix.lat_deg,
                            lon_deg: fix.lon_deg,
                            error_m: fix.error_m,
                            speed_m_s: fix.speed_m_s,
                            course_deg: fix.course_deg,
                            gps_utc: fix.time_utc.clone(),
                        });
                    }
                    guidance.send_wait(GuidanceInput::Fix(fix.clone()));
                } else if let (GpsEvent::State(s), Some(log)) = (&ev, &log) {
                    log.log(LogEntry::Note { text: format!("gps {}", s.label()) });
                }
                ui.send(ev)
            });
        }
        let (vest_ui_tx, vest_rx) = sync_channel(1024);
        let (vest_router_tx, vest_router_rx) = sync_channel::<VestEvent>(1024);
        {
            let ui = Outbox::new(vest_ui_tx, waker.clone());
            let log = log_tx.clone();
            spawn_router("vestnav-vest-router", vest_router_rx, move |ev: VestEvent| {
                if let Some(log) = &log {
                    match &ev {
                        VestEvent::Ack { what } => log.log(LogEntry::Ack { what: what.clone() }),
                        VestEvent::TactorsOn(mask) => log.log(LogEntry::TactorsOn { mask: *mask }),
                        VestEvent::Rejected { reason } => {
                            log.log(LogEntry::Note { text: format!("vest rejected: {reason}") });
                        }
                        VestEvent::State(s) => {
                            log.log(LogEntry::Note { text: format!("vest {}", s.label()) });
                        }
                        VestEvent::Notice(text) => log.log(LogEntry::Note { text: format!("vest: {text}") }),
                        VestEvent::Status { .. } => {}
                    }
                }
                ui.send(ev)
            });
        }

        let mut map = MapView::new(cfg.follow);
        match crate::route::parse_gpx(crate::route::DEMO_GPX) {
            Ok(c) => {
                map.route_name = c.name.unwrap_or_else(|| "demo".into());
                map.waypoints = c.waypoints;
            }
            Err(e) => status = format!("demo route unreadable: {e}"),
        }

        let mut console = Self {
            gps: GpsView {
                picker: crate::gps_panel::SourcePicker::from_config(&cfg.gps),
                ..GpsView::default()
            },
            vest: VestView {
                port: match &cfg.vest {
                    VestSourceConfig::Serial { port } => port.clone(),
                    VestSourceConfig::Emulated => String::new(),
                },
                ..VestView::default()
            },
            cfg_saved: cfg.clone(),
            cfg,
            cfg_path,
            factory,
            tab: Tab::Map,
            map,
            guidance: None,
            status,
            gps_router_tx,
            gps_rx,
            vest_router_tx,
            vest_rx,
            guidance_rx,
            guidance_tx,
            gps_worker: None,
            vest_link: None,
            log,
            log_tx,
            sim_panel: SimPanel::new(),
            field_panel: FieldTestPanel::new(),
            log_viewer: crate::log_viewer::LogViewer::default(),
        };
        console.push_route();
        if console.cfg.auto_connect {
            console.connect_vest();
            console.connect_gps();
        }
        console
    }

    /// Path of the session log being written, if any.
    pub fn log_path(&self) -> Option<&std::path::Path> {
        self.log.as_ref().map(SessionLog::path)
    }

    /// Whether a GPS worker is running.
    pub fn gps_connected(&self) -> bool {
        self.gps_worker.is_some()
    }

    /// Whether a vest link is open.
    pub fn vest_connected(&self) -> bool {
        self.vest_link.is_some()
    }

    /// (Re)connects the GPS to the configured source.
    pub fn connect_gps(&mut self) {
        self.disconnect_gps();
        let out = Outbox::new(self.gps_router_tx.clone(), None);
        self.gps.link = LinkState::Connecting { attempt: 1 };
        self.gps.notice = None;
        match self.factory.open_gps(&self.cfg.gps, &self.map.waypoints, out) {
            Ok(w) => self.gps_worker = Some(w),
            Err(e) => {
                self.gps.link = LinkState::Lost { reason: e.clone() };
                self.status = format!("GPS: {e}");
            }
        }
    }

    /// Stops the GPS worker.
    pub fn disconnect_gps(&mut self) {
        if let Some(mut w) = self.gps_worker.take() {
            w.stop();
        }
        self.gps.link = LinkState::Disconnected;
    }

    /// (Re)connects the vest.
    pub fn connect_vest(&mut self) {
        self.disconnect_vest();
        let out = Outbox::new(self.vest_router_tx.clone(), None);
        self.vest.link = LinkState::Connecting { attempt: 1 };
        match self.factory.open_vest(&self.cfg.vest, out) {
            Ok(link) => {
                self.guidance_tx.try_send(GuidanceInput::Vest(Some(link.clone()))).ok();
                self.vest_link = Some(link);
            }
            Err(e) => {
                self.vest.link = LinkState::Lost { reason: e.clone() };
                self.status = format!("vest: {e}");
            }
        }
    }

    /// Stops every tactor and closes the vest link.
    pub fn disconnect_vest(&mut self) {
        self.guidance_tx.try_send(GuidanceInput::Vest(None)).ok();
        if let Some(link) = self.vest_link.take() {
            link.close();
        }
        self.vest.link = LinkState::Disconnected;
        self.vest.tactors_on = TactorMask::NONE;
    }

    /// Sends a manual command to the vest (holding automatic guidance off) and logs it; `cue` names it when
    /// it is one of the vocabulary's cues.
    pub fn send_manual(&mut self, command: VestCommand, cue: Option<Cue>) {
        if command != VestCommand::StopAll {
            self.guidance_tx.try_send(GuidanceInput::ManualOverride(cue)).ok();
        }
        let Some(link) = &self.vest_link else {
            self.status = "vest not connected".into();
            return;
        };
        match link.send(command.clone()) {
            Ok(()) => {
                if let Some(log) = &self.log_tx {
                    log.log(LogEntry::Command {
                        origin: CommandOrigin::Manual,
                        command,
                        reason: "operator".into(),
                    });
                }
            }
            Err(e) => self.status = format!("vest: {e}"),
        }
    }

    /// STOP ALL: every tactor off now, automatic guidance off.
    pub fn stop_all(&mut self) {
        // The vest first: nothing else may delay it.
        self.send_manual(VestCommand::StopAll, Some(Cue::Stop));
        self.guidance_tx.try_send(GuidanceInput::StopAll).ok();
        if self.cfg.guidance_auto {
            self.cfg.guidance_auto = false;
            self.push_settings();
        }
        self.status = "STOP ALL sent; automatic guidance off".into();
    }

    /// Tells the guidance worker about the current route.
    pub fn push_route(&mut self) {
        let msg = GuidanceInput::Route { waypoints: self.map.waypoints.clone(), next: self.map.next };
        if self.guidance_tx.try_send(msg).is_err() {
            self.status = "guidance worker busy: route update dropped".into();
        }
    }

    fn push_settings(&mut self) {
        self.guidance_tx.try_send(GuidanceInput::Settings(guidance_settings(&self.cfg))).ok();
    }

    /// Logs an operator mark at the wearer's position.
    pub fn mark(&mut self, label: &str) {
        let pos = self.gps.fix.as_ref().filter(|f| f.has_position()).map(|f| (f.lat_deg, f.lon_deg));
        if let Some(log) = &self.log_tx {
            let label = label.to_owned();
            log.log(LogEntry::Mark { label, lat_deg: pos.map(|p| p.0), lon_deg: pos.map(|p| p.1) });
        }
        self.status = format!("marked '{label}'");
    }

    /// The GPS alarm at UI time `now_s`, if any.
    pub fn gps_alarm(&self, now_s: f64) -> Option<GpsAlarm> {
        if self.gps_worker.is_none() || self.gps.link == LinkState::Disconnected {
            return None;
        }
        if let LinkState::Lost { reason } = &self.gps.link {
            return Some(GpsAlarm::Lost { reason: reason.clone() });
        }
        if let Some(f) = &self.gps.fix
            && !f.has_position()
            && self.gps.epoch_at_s.is_some_and(|t| now_s - t < self.cfg.stale_after_s)
        {
            return Some(GpsAlarm::Lost { reason: "receiver reports no fix".into() });
        }
        let age = now_s - self.gps.fix_at_s?;
        if age > self.cfg.lost_after_s {
            Some(GpsAlarm::Lost { reason: format!("no position for {age:.0} s") })
        } else if age > self.cfg.stale_after_s {
            Some(GpsAlarm::Stale { age_s: age })
        } else {
            None
        }
    }

    /// Drains worker events into the state (within `DRAIN_BUDGET` per channel).
    pub fn pump(&mut self, now_s: f64) {
        let mut fixes = Vec::new();
        drain_within(&self.gps_rx, DRAIN_BUDGET, |ev| match ev {
            GpsEvent::State(s) => self.gps.link = s,
            GpsEvent::Fix(f) => fixes.push(f),
            GpsEvent::Notice(n) => self.gps.notice = Some(n),
        });
        for f in fixes {
            self.gps.epoch_at_s = Some(now_s);
            if f.has_position() {
                self.gps.fix_at_s = Some(now_s);
                self.gps.fixes += 1;
                self.gps.alarm_silenced = false;
                self.map.push_track(f.lat_deg, f.lon_deg);
                self.field_panel.push_position(now_s, f.lat_deg, f.lon_deg, f.speed_m_s);
            }
            self.gps.fix = Some(f);
        }
        drain_within(&self.vest_rx, DRAIN_BUDGET, |ev| match ev {
            VestEvent::State(s) => {
                if s != LinkState::Live {
                    self.vest.tactors_on = TactorMask::NONE;
                }
                self.vest.link = s;
            }
            VestEvent::TactorsOn(m) => self.vest.tactors_on = m,
            VestEvent::Ack { what } => self.vest.last_reply = Some(format!("ack: {what}")),
            VestEvent::Rejected { reason } => self.vest.last_reply = Some(format!("refused: {reason}")),
            VestEvent::Notice(text) => self.vest.last_reply = Some(text),
            VestEvent::Status { battery_pct, firmware } => {
                self.vest.battery_pct = battery_pct;
                self.vest.firmware = firmware;
            }
        });
        let mut latest = None;
        drain_within(&self.guidance_rx, DRAIN_BUDGET, |st| latest = Some(st));
        if let Some(st) = latest {
            if st.next != self.map.next {
                self.map.next = st.next;
            }
            self.guidance = Some(st);
        }
    }

    /// Draws one frame (also the entry point of the kittest tests).
    #[allow(clippy::too_many_lines)] // the frame's layout in one place: panels in the order they are drawn
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        let now_s = ui.input(|i| i.time);
        self.pump(now_s);
        self.handle_keys(ui);

        egui::Panel::top("vestnav-top").show(ui, |ui| self.top_bar(ui, now_s));
        egui::Panel::bottom("vestnav-status").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.label(RichText::new(&self.status).small());
                if let Some(p) = self.log_path() {
                    ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                        ui.label(RichText::new(format!("log: {}", p.display())).small().weak());
                    });
                }
            });
        });
        egui::Panel::left("vestnav-side").default_size(360.0).min_size(300.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                egui::CollapsingHeader::new("GPS").default_open(true).show(ui, |ui| {
                    crate::gps_panel::show(self, ui, now_s);
                });
                egui::CollapsingHeader::new("Vest").default_open(true).show(ui, |ui| {
                    crate::vest_panel::show(self, ui);
                });
                egui::CollapsingHeader::new("Guidance").default_open(true).show(ui, |ui| {
                    self.guidance_ui(ui);
                });
            });
        });
        egui::CentralPanel::default().show(ui, |ui| match self.tab {
            Tab::Map => {
                let fix = self.gps.fix.clone().filter(GpsFix::has_position);
                let speed = fix.as_ref().and_then(|f| f.speed_m_s);
                let walking = self.cfg.walking_speed_m_s;
                let changed = self.map.ui(ui, fix.as_ref(), speed, walking, &mut self.cfg, &mut self.status);
                if changed {
                    self.push_route();
                }
            }
            Tab::Simulation => self.sim_panel.ui(ui),
            Tab::FieldTests => {
                if let Some(FieldTestAction::Mark { label }) = self.field_panel.ui(ui) {
                    self.mark(&label);
                }
            }
            Tab::SessionLog => {
                let dir = self.log_dir();
                let current = self.log.as_ref().map(|l| l.path().to_path_buf());
                self.log_viewer.ui(ui, &dir, current.as_deref(), &mut self.map);
            }
        });

        if self.cfg != self.cfg_saved {
            self.push_settings();
            self.save_config();
        }
        // Fix ages and alarms change with time even when no event arrives.
        ui.ctx().request_repaint_after(Duration::from_millis(250));
    }

    fn log_dir(&self) -> PathBuf {
        self.cfg.log_dir.clone().unwrap_or_else(|| crate::config::data_dir().join("sessions"))
    }

    fn save_config(&mut self) {
        self.cfg_saved = self.cfg.clone();
        if let Some(p) = &self.cfg_path
            && let Err(e) = self.cfg.save(p)
        {
            self.status = format!("cannot save settings to {}: {e}", p.display());
        }
    }

    fn handle_keys(&mut self, ui: &egui::Ui) {
        let typing = ui.ctx().text_edit_focused();
        let (esc, space) = ui.input(|i| (i.key_pressed(egui::Key::Escape), i.key_pressed(egui::Key::Space)));
        if esc || (space && !typing) {
            self.stop_all();
        }
        let m = ui.input(|i| i.key_pressed(egui::Key::M));
        if m && !typing && self.tab != Tab::FieldTests {
            let n = self.map.marks + 1;
            self.map.marks = n;
            self.mark(&format!("mark {n}"));
        }
    }

    fn top_bar(&mut self, ui: &mut egui::Ui, now_s: f64) {
        ui.horizontal(|ui| {
            let stop = egui::Button::new(RichText::new("STOP ALL").strong().size(18.0).color(Color32::WHITE))
                .fill(Color32::from_rgb(200, 30, 30))
                .min_size(egui::vec2(120.0, 30.0));
            if ui
                .add(stop)
                .on_hover_text("Every tactor off, automatic guidance off (keys: Esc or Space)")
                .clicked()
            {
                self.stop_all();
            }
            ui.separator();
            let alarm = self.gps_alarm(now_s);
            let (gps_text, gps_color) = match &alarm {
                Some(GpsAlarm::Lost { .. }) => ("GPS: FIX LOST".to_owned(), Color32::from_rgb(230, 40, 40)),
                Some(GpsAlarm::Stale { .. }) => ("GPS: STALE".to_owned(), Color32::from_rgb(230, 150, 0)),
                None => (format!("GPS: {}", self.gps.link.label()), link_color(&self.gps.link)),
            };
            ui.label(RichText::new(gps_text).color(gps_color).strong());
            ui.separator();
            ui.label(
                RichText::new(format!("Vest: {}", self.vest.link.label()))
                    .color(link_color(&self.vest.link))
                    .strong(),
            );
            ui.separator();
            let g = if self.cfg.guidance_auto { "Guidance: AUTO" } else { "Guidance: manual" };
            ui.label(RichText::new(g).strong());
            ui.separator();
            ui.selectable_value(&mut self.tab, Tab::Map, "Map");
            ui.selectable_value(&mut self.tab, Tab::Simulation, "Simulation");
            ui.selectable_value(&mut self.tab, Tab::FieldTests, "Field tests");
            ui.selectable_value(&mut self.tab, Tab::SessionLog, "Session log");
        });
    }

    fn guidance_ui(&mut self, ui: &mut egui::Ui) {
        let mut changed = false;
        ui.horizontal(|ui| {
            changed |= ui.checkbox(&mut self.cfg.guidance_auto, "Automatic cues").changed();
            changed |= ui.checkbox(&mut self.cfg.loop_route, "Loop route").changed();
        });
        egui::ComboBox::from_label("Strategy").selected_text(self.cfg.strategy.clone()).show_ui(ui, |ui| {
            for k in StrategyKind::ALL {
                changed |=
                    ui.selectable_value(&mut self.cfg.strategy, k.name().to_owned(), k.name()).changed();
            }
        });
        changed |= ui
            .add(
                egui::Slider::new(&mut self.cfg.arrival_radius_m, 2.0..=50.0)
                    .suffix(" m")
                    .text("Arrival radius"),
            )
            .changed();
        changed |= ui
            .add(
                egui::Slider::new(&mut self.cfg.cue_interval_s, 1.0..=30.0).suffix(" s").text("Cue interval"),
            )
            .changed();
        changed |= ui
            .add(egui::Slider::new(&mut self.cfg.manual_hold_s, 0.0..=60.0).suffix(" s").text("Manual hold"))
            .changed();
        if changed {
            self.push_settings();
        }
        match &self.guidance {
            None => {
                ui.label("waiting for the first fix");
            }
            Some(st) => {
                let cue = st.cue.map_or("none", Cue::name);
                let sent = if st.sent { "sent" } else { "not sent now" };
                ui.label(RichText::new(format!("Cue: {cue} ({sent}) · {}", st.state)).strong());
                ui.label(&st.reason);
                let n = |v: Option<f64>, u: &str| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.0}{u}"));
                ui.label(format!(
                    "distance {} · bearing error {} · cross-track {} · heading from {}",
                    n(st.distance_m, " m"),
                    n(st.bearing_error_deg, "°"),
                    st.cross_track_m.map_or_else(|| "—".to_owned(), |x| format!("{x:+.1} m")),
                    st.heading_source
                ));
                if st.finished {
                    ui.label(RichText::new("Route finished").color(Color32::from_rgb(40, 160, 60)));
                }
            }
        }
        ui.horizontal(|ui| {
            if ui.button("< Previous waypoint").clicked() && self.map.next > 0 {
                self.map.next -= 1;
                self.push_route();
            }
            if ui.button("Next waypoint >").clicked() && self.map.next < self.map.waypoints.len() {
                self.map.next += 1;
                self.push_route();
            }
        });
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        self.disconnect_gps();
        self.disconnect_vest();
    }
}

fn link_color(s: &LinkState) -> Color32 {
    match s {
        LinkState::Live => Color32::from_rgb(40, 170, 60),
        LinkState::Connecting { .. } | LinkState::Stale => Color32::from_rgb(220, 150, 0),
        LinkState::Lost { .. } => Color32::from_rgb(230, 40, 40),
        LinkState::Disconnected => Color32::GRAY,
    }
}

fn guidance_settings(cfg: &Config) -> GuidanceSettings {
    GuidanceSettings {
        auto: cfg.guidance_auto,
        arrival_radius_m: cfg.arrival_radius_m,
        cue_interval_s: cfg.cue_interval_s,
        manual_hold_s: cfg.manual_hold_s,
        stale_after_s: cfg.stale_after_s,
        on_ms: cfg.on_ms,
        loop_route: cfg.loop_route,
        strategy: StrategyKind::from_name(&cfg.strategy).unwrap_or(StrategyKind::Pursuit),
    }
}

/// Forwards every message of `rx` through `forward` until the input closes or `forward` says the UI is gone.
fn spawn_router<T: Send + 'static>(
    name: &str,
    rx: Receiver<T>,
    forward: impl Fn(T) -> bool + Send + 'static,
) {
    let _ = std::thread::Builder::new().name(name.into()).spawn(move || {
        while let Ok(ev) = rx.recv() {
            if !forward(ev) {
                break;
            }
        }
    });
}

/// Kept for the config picker: which GPS source kind is chosen.
pub fn source_kind(s: &GpsSourceConfig) -> &'static str {
    match s {
        GpsSourceConfig::Simulator => "Simulator",
        GpsSourceConfig::Serial { .. } => "Serial port",
        GpsSourceConfig::Replay { .. } => "NMEA file replay",
        GpsSourceConfig::Gpsd { .. } => "gpsd",
    }
}
