//! The console: a view over one in-process [`Station`] — the top bar, the side panels (GPS, Vest,
//! Guidance) and the central tabs.
//!
//! The station is the running system (devices, guidance, route, track, session log, alarms, the stop
//! path); the console holds only what is drawn: the settings it persists, each panel's own widget state,
//! and the view-only consumers of device events (the raw NMEA monitor, the compass wizard, the field
//! tests). Each frame [`Console::tick`] pumps the station (which beats the view's liveness heartbeat) and
//! the panels read its state and send it commands. Every state shown is derived from the devices' events
//! and their timestamps: the age of a fix is measured from the instant its bytes arrived.
//!
//! The stop path: STOP ALL goes from the key or the button to [`Station::stop_all`], which sets every vest
//! worker's atomic request (served within one 2 ms read timeout): no queue and no other thread is in the
//! way, and the worker stops every tactor by itself if the view stops turning. Every frame's work is
//! bounded (see `map_panel`'s drawing budgets and the route's [`vestnav_station::route::MAX_WAYPOINTS`]), so
//! the key is read within one cheap frame.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use vestnav_core::guidance::StrategyKind;
use vestnav_device::gps::{GpsEvent, SourceState};
use vestnav_device::outbox::Waker;
use vestnav_device::wtcu::VestEvent;
use vestnav_station::devices::DeviceFactory;
use vestnav_station::guidance::GuidanceSettings;
use vestnav_station::stop::StopPath;
use vestnav_station::{
    Notice, Severity as NoticeSeverity, Station, StationEvent, StationOptions, StationSettings, Subject,
};

use crate::config::{Config, GpsSourceConfig, VestSourceConfig};
use crate::fieldtest_panel::FieldTestPanel;
use crate::gps_panel::GpsUi;
use crate::map_panel::MapView;
use crate::sim_panel::SimPanel;
use crate::vest_panel::VestUi;

mod frame;
mod layout;

pub use frame::{Banner, BannerSubject, Severity};
pub use layout::{AGE_STEP, LIVENESS_TURN};
pub use vestnav_station::stop::EXIT_STOP_WAIT;
pub use vestnav_station::{GpsAlarm, Liveness, VestReply};

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
    /// Study protocols run on the station's trial runner, and their results.
    Study,
}

/// Devices named on the command line: they win over the saved settings for this run (and are not saved).
#[derive(Debug, Clone, Default)]
pub struct DeviceOverrides {
    /// `--gps`.
    pub gps: Option<GpsSourceConfig>,
    /// `--vest`.
    pub vest: Option<VestSourceConfig>,
    /// `--tiles`: the map's tile source for this run.
    pub tiles: Option<vestnav_tiles::TileSourceConfig>,
    /// `--map`: the OpenStreetMap extract drawn under the tiles (becomes the saved setting).
    pub map: Option<PathBuf>,
    /// `--study` (and `--study-wearer`): the Study tab opens with this protocol (not saved).
    pub study: Option<crate::study_panel::StudyLaunch>,
}

/// The console.
pub struct Console {
    /// Settings (persisted).
    pub cfg: Config,
    cfg_path: Option<PathBuf>,
    cfg_saved: Config,
    /// Device settings as read from the config file, written back instead of command-line overrides.
    file_devices: (GpsSourceConfig, VestSourceConfig),
    /// The tile source as read from the config file, written back instead of a `--tiles` override.
    file_tiles: vestnav_tiles::TileSourceConfig,
    overrides: DeviceOverrides,
    /// The running system.
    pub station: Station,
    /// The stations on an MQTT broker (`vestnav --broker`), if any: the console's STOP ALL reaches them too.
    pub remote: Option<crate::remote_panel::RemotePanel>,
    /// The Broker window (the broker in the saved settings; connect, disconnect).
    pub broker_window: crate::broker_settings::BrokerWindow,
    /// The Lab outputs window (LSL, OSC of the local station).
    pub lab_window: crate::lab_window::LabWindow,
    /// Active central tab.
    pub tab: Tab,
    /// The GPS panel's widget state.
    pub gps_ui: GpsUi,
    /// The Vest panel's widget state.
    pub vest_ui: VestUi,
    /// The map's view state (centre, zoom, tiles, editor, tools).
    pub map: MapView,
    /// The extract's path network handed to the station for re-routing (graph and profile).
    network_shared: Option<(usize, vestnav_osm::Profile)>,
    /// The compass calibration wizard.
    pub compass_wizard: crate::compass_panel::Wizard,
    /// The pattern editor (Vest panel), kept while its window is closed.
    pub pattern_editor: crate::pattern_editor::PatternEditor,
    sim_panel: SimPanel,
    /// The Field tests tab (its reference form, the exports).
    pub field_panel: FieldTestPanel,
    /// Session log viewer / replay.
    pub log_viewer: crate::log_viewer::LogViewer,
    /// The Study tab's widget state (the study's own state is the station's).
    pub study: crate::study_panel::StudyPanel,
    /// The audible alarm on fix loss, vest loss and an unconfirmed stop (`console/frame.rs`).
    alarm: frame::AudibleAlarm,
    /// The window's logic step already pumped the station this frame (the frame then does not again).
    ticked: bool,
    /// The station's automatic-cues switch as last synced into the settings (a change of the station's
    /// own — STOP ALL, a stalled thread — is taken into the settings, an edit of the operator's is not
    /// overwritten).
    synced_auto: bool,
    /// The side panel is shown (collapsed to a strip otherwise).
    pub side_open: bool,
}

/// Options for [`Console::new`].
#[derive(Default)]
pub struct ConsoleOptions {
    /// Settings to start with.
    pub cfg: Config,
    /// Where to save settings (`None`: never saved, e.g. in tests).
    pub cfg_path: Option<PathBuf>,
    /// Directory for the session log (`None`: no log).
    pub log_dir: Option<PathBuf>,
    /// The UI context, to wake the UI from workers (`None` in headless tests that step frames anyway).
    pub waker: Option<egui::Context>,
    /// Devices given on the command line.
    pub devices: DeviceOverrides,
    /// Liveness bounds; `None` turns the check off (headless tests that step frames at their own pace).
    pub liveness: Option<Liveness>,
    /// Where STOP ALL and the exit paths find the vests (the signal handler holds a clone).
    pub stop: StopPath,
    /// Where the route is autosaved and restored from at start-up (`None`: neither, e.g. in tests; the
    /// console's own is [`crate::config::route_autosave_path`]).
    pub route_autosave: Option<PathBuf>,
}

/// The station's settings for the console's.
pub fn station_settings(cfg: &Config) -> StationSettings {
    StationSettings {
        guidance: GuidanceSettings {
            auto: cfg.guidance_auto,
            arrival_radius_m: cfg.arrival_radius_m,
            cue_interval_s: cfg.cue_interval_s,
            manual_hold_s: cfg.manual_hold_s,
            stale_after_s: cfg.stale_after_s,
            on_ms: cfg.on_ms,
            loop_route: cfg.loop_route,
            strategy: StrategyKind::from_name(&cfg.strategy).unwrap_or(StrategyKind::Pursuit),
            heading_mode: cfg.heading_mode,
            off_path_m: cfg.off_path_m,
            reroute_after_s: cfg.reroute_after_s,
            turn_in_place: vestnav_station::guidance::default_turn_in_place(),
            end_at_finish: false,
        },
        lost_after_s: cfg.lost_after_s,
        sim_follows_vest: cfg.sim_follows_vest,
    }
}

impl Console {
    /// Builds the console and its station, and connects the configured devices when `cfg.auto_connect`
    /// is set or devices were given on the command line.
    pub fn new(factory: Box<dyn DeviceFactory>, opts: ConsoleOptions) -> Self {
        let ConsoleOptions { mut cfg, cfg_path, log_dir, waker, devices, liveness, stop, route_autosave } =
            opts;
        let file_devices = (cfg.gps.clone(), cfg.vest.clone());
        let connect_now = cfg.auto_connect || devices.gps.is_some() || devices.vest.is_some();
        if let Some(g) = &devices.gps {
            cfg.gps = g.clone();
        }
        if let Some(v) = &devices.vest {
            cfg.vest = v.clone();
        }
        if let Some(m) = &devices.map {
            cfg.osm_map = Some(m.clone());
        }
        let file_tiles = cfg.tiles.clone();
        if let Some(t) = &devices.tiles {
            cfg.tiles = t.clone();
            cfg.map_tiles = true;
        }
        let waker: Option<Waker> =
            waker.map(|ctx| std::sync::Arc::new(move || ctx.request_repaint()) as Waker);
        let station = Station::new(
            factory,
            StationOptions {
                settings: station_settings(&cfg),
                gps: Some(cfg.gps.clone()),
                vest: Some(cfg.vest.clone()),
                log_dir,
                waker,
                liveness,
                stop,
                route: vestnav_station::RouteStart {
                    file: devices
                        .gps
                        .as_ref()
                        .and_then(GpsSourceConfig::sim_route)
                        .map(std::path::Path::to_path_buf),
                    autosave: route_autosave,
                },
            },
        );
        let lab_window = crate::lab_window::LabWindow::from_settings(&cfg.lab);
        let mut console = Self {
            gps_ui: GpsUi::from_config(&cfg.gps),
            vest_ui: VestUi::from_config(&cfg.vest),
            map: MapView::new(cfg.follow),
            network_shared: None,
            cfg_saved: cfg.clone(),
            cfg,
            cfg_path,
            file_devices,
            file_tiles,
            overrides: devices,
            station,
            remote: None,
            broker_window: crate::broker_settings::BrokerWindow::default(),
            lab_window,
            tab: Tab::Map,
            compass_wizard: crate::compass_panel::Wizard::default(),
            pattern_editor: crate::pattern_editor::PatternEditor::default(),
            sim_panel: SimPanel::new(),
            field_panel: FieldTestPanel::new(),
            log_viewer: crate::log_viewer::LogViewer::default(),
            study: crate::study_panel::StudyPanel::default(),
            alarm: frame::AudibleAlarm::default(),
            ticked: false,
            synced_auto: false,
            side_open: true,
        };
        console.synced_auto = console.station.settings().guidance.auto;
        if let Some(r) = console.cfg.field_reference.clone()
            && let Err(e) = console.station.field_tests.set_reference(Some(r))
        {
            // A saved reference that is out of range is dropped (and the file rewritten without it).
            console.cfg.field_reference = None;
            console.say(NoticeSeverity::Warning, Subject::Settings, format!("saved {e}: not restored"));
        }
        if connect_now {
            console.connect_vest();
            console.connect_gps();
        }
        // Lab outputs that ran when the console last closed start again (the frame says how it went).
        console.lab_window.restore(&mut console.station);
        if let Some(launch) = console.overrides.study.clone() {
            console.tab = Tab::Study;
            let base = console.cfg.recent.base();
            console.study.launch(&launch, &mut console.station, &base);
        }
        console
    }

    /// Raises a notice for the operator (shown once, where its subject belongs).
    pub fn say(&mut self, severity: NoticeSeverity, subject: Subject, text: impl Into<String>) {
        self.station.notices.raise(severity, subject, text);
    }

    /// The newest notice (what the status line shows).
    pub fn latest_notice(&self) -> Option<&Notice> {
        self.station.notices.all().last()
    }

    /// Path of the session log being written, if any.
    pub fn log_path(&self) -> Option<&std::path::Path> {
        self.station.log_path()
    }

    /// Whether a GPS source is running.
    pub fn gps_connected(&self) -> bool {
        self.station.gps_connected()
    }

    /// Whether a vest worker is running.
    pub fn vest_connected(&self) -> bool {
        self.station.vest_connected()
    }

    /// (Re)connects the GPS to the configured source.
    pub fn connect_gps(&mut self) {
        crate::gps_panel::connect(&mut self.station, &mut self.cfg, &mut self.gps_ui);
    }

    /// The pause/seek/progress controls of the running GPS source when it is a replay.
    pub fn gps_replay(&self) -> Option<std::sync::Arc<vestnav_device::gps::ReplayControl>> {
        self.station.gps_worker()?.replay_control()
    }

    /// Stops the GPS source (never waits long on its IO).
    pub fn disconnect_gps(&mut self) {
        self.station.disconnect_gps();
    }

    /// (Re)connects the vest.
    pub fn connect_vest(&mut self) {
        crate::vest_panel::connect(&mut self.station, &self.cfg);
    }

    /// Stops every tactor and closes the vest link (waiting a bounded time for the acknowledgement).
    pub fn disconnect_vest(&mut self) {
        self.station.disconnect_vest();
    }

    /// Stops the vest first (STOP ALL, acknowledged or timed out), then the GPS: the console's exit.
    pub fn shutdown(&mut self) {
        self.station.shutdown();
        // The Stations window's local stations (their vests stopped), and the broker left.
        if let Some(r) = &mut self.remote {
            r.stations_mut().shutdown();
        }
    }

    /// STOP ALL: every tactor off now, automatic guidance latched off until the operator resumes it.
    pub fn stop_all(&mut self) {
        // Every vest of the process first (this station's and each local station's of the Stations
        // window), with no thread in the way; then each station's own state.
        self.station.stop_path().stop_all();
        self.station.stop_all();
        if let Some(r) = &mut self.remote {
            r.stop_all();
        }
        self.sync_settings_from_station();
    }

    /// The operator's deliberate resume of automatic cues.
    pub fn resume_guidance(&mut self) {
        self.station.resume_guidance();
        self.sync_settings_from_station();
        // The status line shows the newest notice: it must not still speak of the stop.
        self.say(
            NoticeSeverity::Info,
            Subject::Guidance,
            "automatic cues resumed: guidance steers the wearer again",
        );
    }

    /// Automatic cues latched off by the station (STOP ALL, a stalled thread) show as off in the settings
    /// too, without a second push to guidance.
    fn sync_settings_from_station(&mut self) {
        let auto = self.station.settings().guidance.auto;
        if auto != self.synced_auto {
            self.synced_auto = auto;
            self.cfg.guidance_auto = auto;
            self.cfg_saved.guidance_auto = auto;
        }
    }

    /// Logs an operator mark at the wearer's position.
    pub fn mark(&mut self, label: &str) {
        self.station.mark(label);
        self.say(NoticeSeverity::Info, Subject::Route, format!("marked '{label}'"));
    }

    /// Age of the latest position at `now`, from the instant its bytes arrived.
    pub fn position_age(&self, now: Instant) -> Option<Duration> {
        self.station.position_age(now)
    }

    /// The GPS alarm at `now`, if any.
    pub fn gps_alarm(&self, now: Instant) -> Option<GpsAlarm> {
        self.station.gps_alarm(now)
    }

    /// Pumps the station (its events into its state, within its budget) and hands the view-only consumers
    /// what they need: the raw monitor and the compass wizard (the station feeds the field tests itself).
    pub fn pump(&mut self) {
        let (monitor, wizard) = (&mut self.gps_ui.monitor, &mut self.compass_wizard);
        let mut identified = false;
        self.station.pump(|ev| match ev {
            StationEvent::Gps(GpsEvent::Raw(line)) => monitor.push(line.clone(), Instant::now()),
            StationEvent::Vest(VestEvent::Heading(a)) => wizard.push(a),
            StationEvent::Vest(VestEvent::Identified(_)) => identified = true,
            _ => {}
        });
        if identified {
            crate::compass_panel::on_identified(&mut self.station, &self.cfg);
        }
        crate::map_panel::walk::share_network(&self.map, &mut self.station, &mut self.network_shared);
        self.sync_settings_from_station();
    }

    /// The UI thread's turn without drawing (also while the window is hidden): beat the liveness
    /// heartbeat and drain the workers' events. A frame drawn after it in the same turn does not pump again.
    pub fn tick(&mut self) {
        self.pump();
        self.ticked = true;
    }

    /// The frame's pump: skipped when the window's logic step already pumped this turn.
    fn frame_pump(&mut self) {
        if !std::mem::take(&mut self.ticked) {
            self.pump();
        }
    }

    /// Where session logs go (the settings' folder, else the data folder's `sessions`).
    pub(crate) fn log_dir(&self) -> PathBuf {
        self.cfg.log_dir.clone().unwrap_or_else(|| crate::config::data_dir().join("sessions"))
    }

    /// Hands every settings change of the frame to the station (once) and saves the file.
    fn settings_changed(&mut self) {
        // The field tests' reference is kept with the settings (restored at start-up).
        let reference = self.station.field_tests.reference();
        if self.cfg.field_reference.as_ref() != reference {
            self.cfg.field_reference = reference.cloned();
        }
        if self.cfg == self.cfg_saved {
            return;
        }
        self.station.set_settings(station_settings(&self.cfg));
        self.synced_auto = self.station.settings().guidance.auto;
        self.save_config();
    }

    fn save_config(&mut self) {
        self.cfg_saved = self.cfg.clone();
        let Some(p) = &self.cfg_path else { return };
        // Devices given on the command line are for this run only: the file keeps its own unless the
        // operator changed them in the console.
        let mut on_disk = self.cfg.clone();
        if self.overrides.gps.as_ref().is_some_and(|g| *g == on_disk.gps) {
            on_disk.gps = self.file_devices.0.clone();
        }
        if self.overrides.vest.as_ref().is_some_and(|v| *v == on_disk.vest) {
            on_disk.vest = self.file_devices.1.clone();
        }
        if self.overrides.tiles.as_ref().is_some_and(|t| *t == on_disk.tiles) {
            on_disk.tiles = self.file_tiles.clone();
        }
        if let Err(e) = on_disk.save(p) {
            let text = format!("SETTINGS NOT SAVED: cannot write {}: {e}", p.display());
            self.say(NoticeSeverity::Alarm, Subject::Settings, text);
        }
    }

    /// The Lab outputs window: outputs that finished starting put in force (a restored start's outcome told
    /// to the operator), the window drawn, its choices taken into the settings.
    fn lab_ui(&mut self, ctx: &egui::Context) {
        match self.lab_window.poll(&mut self.station) {
            Some(Ok(running)) => self.say(
                NoticeSeverity::Info,
                Subject::Settings,
                format!("lab outputs started again as they were saved: {running}"),
            ),
            Some(Err(why)) => self.say(
                NoticeSeverity::Warning,
                Subject::Settings,
                format!("lab outputs saved as on were NOT started: {why} (View > Lab outputs)"),
            ),
            None => {}
        }
        self.lab_window.ui(ctx, &mut self.station);
        if self.lab_window.settings() != &self.cfg.lab {
            self.cfg.lab = self.lab_window.settings().clone();
        }
        if self.lab_window.busy() {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
    }

    /// Whether the GPS source is one that ends (a replay that reached its end, a stopped source).
    pub fn gps_ended(&self) -> bool {
        matches!(self.station.gps.state, Some(SourceState::Finished | SourceState::Stopped))
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        self.shutdown();
    }
}
