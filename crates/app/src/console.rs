//! The console's state and frame: top bar, side panels (GPS, Vest, Guidance), central tabs.
//!
//! [`Console`] holds everything the UI shows and can be built without a window (tests drive it with
//! `egui_kittest`). Devices come from an injected [`DeviceFactory`]; the device crate's workers deliver
//! their own events ([`GpsEvent`], [`VestEvent`]) straight to the UI, to the guidance worker and to the
//! session log, each through its own bounded [`Outbox`]. [`Console::ui`] drains the UI's channels at the
//! start of each frame within a small time budget. Every state shown is derived from those events and
//! their timestamps: the age of a fix is measured from the instant its bytes arrived.
//!
//! Threads the console starts: the GPS source's worker, the vest worker, the guidance worker and the
//! session-log writer — nothing else.
//!
//! The stop path: STOP ALL goes from the key or button straight to the vest worker's atomic request (it
//! never waits in a queue behind anything). The UI thread beats the vest worker's [`Watched::Ui`]
//! heartbeat every frame: if the UI stalls past its bound, the vest worker stops every tactor by itself.
//! [`Console::shutdown`] (window close, drop, and the signal handler through [`ExitGuard`]) stops the vest
//! first, with a bounded wait for the unit's acknowledgement.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_core::guidance::StrategyKind;
use vestnav_core::vest::{Cue, TactorMask};
use vestnav_device::gps::{DecodeStats, Fix, GpsEvent, SourceState};
use vestnav_device::heading::Attitude;
use vestnav_device::outbox::{Outbox, Overflow, Waker, drain_within};
use vestnav_device::wtcu::worker::{Heartbeat, VestStopper, Watched};
use vestnav_device::wtcu::{
    CommandKind, CommandOrigin, DeviceInfo, LinkState, UnitStatus, VestCommand, VestEvent, VestHandle,
};

use crate::config::{Config, GpsSourceConfig, VestSourceConfig};
use crate::devices::{DeviceFactory, GpsWorker};
use crate::fieldtest_panel::FieldTestPanel;
use crate::guidance::{GuidanceInput, GuidanceSettings, GuidanceStatus};
use crate::map_panel::MapView;
use crate::sim_panel::SimPanel;
use vestnav_device::session_log::{LogEntry, LogSender, SessionLog};

mod frame;

pub use frame::{Banner, BannerSubject, Severity};

/// Time the UI may spend per frame draining worker events.
const DRAIN_BUDGET: Duration = Duration::from_millis(2);
/// Capacity of each of the UI's event channels.
const UI_CHANNEL: usize = 1024;
/// Capacity of the guidance worker's input channel (fixes beyond it are dropped: it needs the newest).
const GUIDANCE_CHANNEL: usize = 256;
/// How long exit waits for the unit to acknowledge STOP ALL.
pub const EXIT_STOP_WAIT: Duration = Duration::from_millis(180);

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

/// What the GPS side shows, all of it from the source's events.
#[derive(Debug, Default)]
pub struct GpsView {
    /// The source's state (`None`: no source running).
    pub state: Option<SourceState>,
    /// Latest epoch, with or without a position.
    pub fix: Option<Fix>,
    /// Latest epoch with a position.
    pub last_position: Option<Fix>,
    /// Fixes with a position this session.
    pub fixes: u64,
    /// Latest notice from the source.
    pub notice: Option<String>,
    /// The decoder's latest counts of accepted and rejected input.
    pub stats: Option<DecodeStats>,
    /// Latest heading reading from the GPS input (an NMEA compass's HDG, gpsd's ATT).
    pub attitude: Option<Attitude>,
    /// When the operator silenced the alarm (it re-arms on the next good fix).
    pub alarm_silenced: bool,
    /// Editor state of the source picker.
    pub picker: crate::gps_panel::SourcePicker,
    /// The raw sentence monitor (the last sentences received).
    pub monitor: crate::gps_panel::RawMonitor,
    /// The Record toggle: the source's sentences to a file (kept across reconnections).
    pub recording: crate::gps_panel::RecordUi,
    /// The Receiver section: the configuration to send and the last run's outcomes (kept across
    /// reconnections).
    pub receiver: crate::gps_receiver::ReceiverUi,
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

/// The latest reply of the vest, for the operator.
#[derive(Debug, Clone, PartialEq)]
pub struct VestReply {
    /// What happened, in words.
    pub text: String,
    /// A refusal (shown as an error) rather than an acknowledgement.
    pub refused: bool,
    /// When it arrived.
    pub at: Instant,
}

/// What the vest side shows, all of it from the worker's events.
#[derive(Debug, Default)]
pub struct VestView {
    /// Link state (`None`: no worker).
    pub state: Option<LinkState>,
    /// Tactors the unit reports on (`None`: unknown, e.g. no link).
    pub tactors_on: Option<TactorMask>,
    /// What the unit said about itself at the handshake.
    pub device: Option<DeviceInfo>,
    /// The unit's last status report and when it came.
    pub status: Option<(UnitStatus, Instant)>,
    /// Latest ack or refusal.
    pub last_reply: Option<VestReply>,
    /// Why automatic cues are latched off, when they are (STOP ALL, a stalled thread).
    pub halted: Option<String>,
    /// Why the link was last lost, kept until the unit is ready again: reconnection attempts in between
    /// are still a lost vest (the banner says so).
    pub lost: Option<String>,
    /// Latest reading of the unit's heading stream (protocol v2), timed by its arrival.
    pub heading: Option<Attitude>,
    /// Tactors selected for a multi-fire.
    pub selected: TactorMask,
    /// Multi-select mode: clicks select instead of firing.
    pub select_mode: bool,
    /// Name typed for a new user pattern.
    pub new_pattern_name: String,
    /// Vest port typed or picked.
    pub port: String,
}

impl VestView {
    /// Whether the unit is connected and has identified itself (commands can be delivered).
    pub fn is_live(&self) -> bool {
        self.state == Some(LinkState::Ready)
    }

    /// The state as words for the top bar.
    pub fn label(&self) -> String {
        self.state.as_ref().map_or_else(|| "disconnected".to_owned(), ToString::to_string)
    }
}

/// Liveness bounds of the threads the vest worker watches (see `vestnav_device::wtcu::worker`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Liveness {
    /// The UI must draw a frame at least this often (it requests one every 250 ms).
    pub ui: Duration,
    /// The guidance worker must turn at least this often (it ticks every 250 ms).
    pub guidance: Duration,
}

impl Default for Liveness {
    fn default() -> Self {
        Self { ui: Duration::from_millis(1500), guidance: Duration::from_secs(1) }
    }
}

/// Where the exit paths (signal handler, window close) find the vest to stop and the window to close. The
/// console keeps the stopper of its current vest here; the locks are only ever held to swap or clone.
#[derive(Debug, Clone, Default)]
pub struct ExitGuard(Arc<ExitInner>);

#[derive(Debug, Default)]
struct ExitInner {
    stopper: Mutex<Option<VestStopper>>,
    ui: Mutex<Option<egui::Context>>,
    signal: std::sync::atomic::AtomicI32,
}

impl ExitGuard {
    fn set(&self, stopper: Option<VestStopper>) {
        if let Ok(mut g) = self.0.stopper.lock() {
            *g = stopper;
        }
    }

    /// The window's context, so an exit path can ask it to close.
    pub fn set_ui(&self, ctx: egui::Context) {
        if let Ok(mut g) = self.0.ui.lock() {
            *g = Some(ctx);
        }
    }

    /// STOP ALL to the current vest and end its worker, waiting at most `wait` for the acknowledgement;
    /// returns whether the unit acknowledged (`false` too when no vest is connected).
    pub fn stop_vest(&self, wait: Duration) -> bool {
        let stopper = self.0.stopper.lock().ok().and_then(|g| g.clone());
        stopper.is_some_and(|s| s.stop_and_close(wait))
    }

    /// Records that the process ends because of signal `sig` and asks the window to close; returns whether
    /// there was a window to ask.
    pub fn close_for_signal(&self, sig: i32) -> bool {
        self.0.signal.store(sig, std::sync::atomic::Ordering::SeqCst);
        let ctx = self.0.ui.lock().ok().and_then(|g| g.clone());
        ctx.is_some_and(|ctx| {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            ctx.request_repaint();
            true
        })
    }

    /// The signal the process is ending for, if any.
    pub fn signal(&self) -> Option<i32> {
        Some(self.0.signal.load(std::sync::atomic::Ordering::SeqCst)).filter(|s| *s != 0)
    }
}

/// Devices named on the command line: they win over the saved settings for this run (and are not saved).
#[derive(Debug, Clone, Default)]
pub struct DeviceOverrides {
    /// `--gps`.
    pub gps: Option<GpsSourceConfig>,
    /// `--vest`.
    pub vest: Option<VestSourceConfig>,
    /// `--tiles`: the map's tile source for this run.
    pub tiles: Option<crate::tiles::TileSourceConfig>,
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
    file_tiles: crate::tiles::TileSourceConfig,
    overrides: DeviceOverrides,
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
    epoch: Instant,
    liveness: Option<Liveness>,
    gps_rx: Receiver<GpsEvent>,
    gps_ui: Outbox<GpsEvent>,
    vest_rx: Receiver<VestEvent>,
    vest_ui: Outbox<VestEvent>,
    guidance_rx: Receiver<GuidanceStatus>,
    guidance_tx: SyncSender<GuidanceInput>,
    route_pending: bool,
    gps_worker: Option<Box<dyn GpsWorker>>,
    vest_link: Option<Arc<VestHandle>>,
    /// The compass calibration wizard.
    pub compass_wizard: crate::compass_panel::Wizard,
    /// The pattern editor (Vest panel), kept while its window is closed.
    pub pattern_editor: crate::pattern_editor::PatternEditor,
    ui_beat: Option<Heartbeat>,
    exit: ExitGuard,
    log: Option<SessionLog>,
    log_tx: Option<LogSender>,
    sim_panel: SimPanel,
    field_panel: FieldTestPanel,
    /// Session log viewer / replay.
    pub log_viewer: crate::log_viewer::LogViewer,
    /// The route autosave (`None`: the route is not autosaved).
    route_autosave: Option<crate::route::Autosave>,
    /// The audible alarm on fix loss and vest loss (`console/frame.rs`).
    alarm: frame::AudibleAlarm,
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
    /// Where exit paths find the vest (the signal handler holds a clone).
    pub exit: ExitGuard,
    /// Where the route is autosaved and restored from at start-up (`None`: neither, e.g. in tests; the
    /// console's own is [`crate::config::route_autosave_path`]).
    pub route_autosave: Option<PathBuf>,
}

impl Console {
    /// Builds the console, starts the guidance worker and the session log, and connects the configured
    /// devices when `cfg.auto_connect` is set or devices were given on the command line.
    pub fn new(factory: Box<dyn DeviceFactory>, opts: ConsoleOptions) -> Self {
        let ConsoleOptions { mut cfg, cfg_path, log_dir, waker, devices, liveness, exit, route_autosave } =
            opts;
        let waker: Option<Waker> = waker.map(|ctx| Arc::new(move || ctx.request_repaint()) as Waker);
        let mut status = String::new();
        let log = log_dir.and_then(|d| match SessionLog::create(&d) {
            Ok(l) => Some(l),
            Err(e) => {
                status = format!("session log disabled: cannot write in {}: {e}", d.display());
                None
            }
        });
        let log_tx = log.as_ref().and_then(SessionLog::sender);

        let (guidance_ui, guidance_rx) = Outbox::channel(UI_CHANNEL, Overflow::DropNewest, waker.clone());
        let (guidance_tx, guidance_in_rx) = sync_channel(GUIDANCE_CHANNEL);
        if let Err(e) =
            crate::guidance::spawn(guidance_in_rx, guidance_settings(&cfg), guidance_ui, log_tx.clone())
        {
            status = format!("guidance worker failed to start: {e}");
        }
        let (gps_ui, gps_rx) = Outbox::channel(UI_CHANNEL, Overflow::DropNewest, waker.clone());
        let (vest_ui, vest_rx) = Outbox::channel(UI_CHANNEL, Overflow::DropNewest, waker.clone());

        let file_devices = (cfg.gps.clone(), cfg.vest.clone());
        let connect_now = cfg.auto_connect || devices.gps.is_some() || devices.vest.is_some();
        if let Some(g) = &devices.gps {
            cfg.gps = g.clone();
        }
        if let Some(v) = &devices.vest {
            cfg.vest = v.clone();
        }
        let file_tiles = cfg.tiles.clone();
        if let Some(t) = &devices.tiles {
            cfg.tiles = t.clone();
            cfg.map_tiles = true;
        }

        let mut map = MapView::new(cfg.follow);
        let cli_route = devices.gps.as_ref().and_then(|g| g.sim_route()).map(std::path::Path::to_path_buf);
        if let Some(e) = load_route(&mut map, cli_route, route_autosave.as_deref()) {
            status = e;
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
            file_devices,
            file_tiles,
            overrides: devices,
            factory,
            tab: Tab::Map,
            map,
            guidance: None,
            status,
            epoch: Instant::now(),
            liveness,
            gps_rx,
            gps_ui,
            vest_rx,
            vest_ui,
            guidance_rx,
            guidance_tx,
            route_pending: true,
            gps_worker: None,
            vest_link: None,
            compass_wizard: crate::compass_panel::Wizard::default(),
            pattern_editor: crate::pattern_editor::PatternEditor::default(),
            ui_beat: None,
            exit,
            log,
            log_tx,
            sim_panel: SimPanel::new(),
            field_panel: FieldTestPanel::new(),
            log_viewer: crate::log_viewer::LogViewer::default(),
            alarm: frame::AudibleAlarm::default(),
            route_autosave: None,
        };
        console.route_autosave =
            route_autosave.map(|p| crate::route::Autosave::new(p, console.map.route_state()));
        console.push_route();
        if connect_now {
            console.connect_vest();
            console.connect_gps();
        }
        console
    }

    /// Path of the session log being written, if any.
    pub fn log_path(&self) -> Option<&std::path::Path> {
        self.log.as_ref().map(SessionLog::path)
    }

    /// Whether a GPS source is running.
    pub fn gps_connected(&self) -> bool {
        self.gps_worker.is_some()
    }

    /// Whether a vest worker is running.
    pub fn vest_connected(&self) -> bool {
        self.vest_link.is_some()
    }

    /// (Re)connects the GPS to the configured source.
    pub fn connect_gps(&mut self) {
        self.disconnect_gps();
        let mut outputs = vec![self.gps_ui.clone()];
        let guidance = Outbox::mapped(
            self.guidance_tx.clone(),
            |ev: GpsEvent| {
                matches!(ev, GpsEvent::Fix(_) | GpsEvent::Attitude(_)).then_some(GuidanceInput::Gps(ev))
            },
            None,
        );
        outputs.push(guidance);
        if let Some(log) = self.log_tx.clone() {
            outputs.push(Outbox::sink(move |ev: GpsEvent| {
                if let Some(entry) = gps_log_entry(&ev) {
                    log.log(entry);
                }
                true
            }));
        }
        // The recording tap records whatever source runs; it outlives the connection like the picker.
        outputs.push(self.gps.recording.tap.outbox());
        self.gps = GpsView {
            picker: std::mem::take(&mut self.gps.picker),
            recording: std::mem::take(&mut self.gps.recording),
            receiver: std::mem::take(&mut self.gps.receiver),
            monitor: self.gps.monitor.emptied(),
            ..GpsView::default()
        };
        // A new source: its first position must not be joined to the old source's last one.
        self.map.break_track();
        match self.factory.open_gps(&self.cfg.gps, &self.map.waypoints, outputs) {
            Ok(w) => {
                if let GpsSourceConfig::Replay { path, .. } = &self.cfg.gps {
                    // Relative replay paths are ignored by the list (it holds absolute paths only).
                    self.cfg.recent.push(crate::file_dialog::RecentKind::Nmea, path);
                }
                self.gps_worker = Some(w);
            }
            Err(e) => {
                self.gps.state = Some(SourceState::Lost { reason: e.clone() });
                self.status = format!("GPS: {e}");
            }
        }
    }

    /// The pause/seek/progress controls of the running GPS source when it is a replay.
    pub fn gps_replay(&self) -> Option<std::sync::Arc<vestnav_device::gps::ReplayControl>> {
        self.gps_worker.as_ref()?.replay_control()
    }

    /// Sends a receiver configuration through the running GPS source (a direct serial port only).
    pub fn gps_configure(
        &self,
        config: vestnav_device::gps::receiver_config::ReceiverConfig,
    ) -> Result<vestnav_device::gps::receiver_config::ConfigTicket, String> {
        self.gps_worker.as_ref().ok_or_else(|| "connect the GPS first".to_owned())?.configure(config)
    }

    /// Stops the GPS source (never waits long on its IO).
    pub fn disconnect_gps(&mut self) {
        if let Some(mut w) = self.gps_worker.take() {
            w.stop();
        }
        self.gps.state = None;
    }

    /// (Re)connects the vest.
    pub fn connect_vest(&mut self) {
        self.disconnect_vest();
        let mut outputs = vec![self.vest_ui.clone()];
        outputs.push(Outbox::mapped(
            self.guidance_tx.clone(),
            |ev: VestEvent| {
                matches!(
                    ev,
                    VestEvent::State(_)
                        | VestEvent::Halted { .. }
                        | VestEvent::Resumed
                        | VestEvent::Heading(_)
                )
                .then_some(GuidanceInput::Vest(ev))
            },
            None,
        ));
        if let Some(log) = self.log_tx.clone() {
            outputs.push(Outbox::sink(move |ev: VestEvent| {
                if let Some(entry) = vest_log_entry(&ev) {
                    log.log(entry);
                }
                true
            }));
        }
        self.vest = VestView { port: std::mem::take(&mut self.vest.port), ..VestView::default() };
        match self.factory.open_vest(&self.cfg.vest, outputs) {
            Ok(handle) => {
                let handle = Arc::new(handle);
                self.exit.set(Some(handle.stopper()));
                let bound = self.liveness.map(|l| (l.ui, l.guidance));
                self.ui_beat = bound.map(|(ui, _)| handle.heartbeat(Watched::Ui, ui));
                let g_bound = bound.map_or(Duration::ZERO, |(_, g)| g);
                if self.guidance_tx.try_send(GuidanceInput::VestLink(Some(handle.clone()), g_bound)).is_err()
                {
                    self.status = "guidance worker busy: it does not know the vest yet".into();
                }
                self.vest.state = Some(LinkState::Connecting { attempt: 1 });
                self.vest_link = Some(handle);
            }
            Err(e) => {
                self.vest.state = Some(LinkState::Lost { reason: e.clone() });
                self.status = format!("vest: {e}");
            }
        }
    }

    /// Stops every tactor and closes the vest link (waiting a bounded time for the acknowledgement).
    pub fn disconnect_vest(&mut self) {
        let _ = self.guidance_tx.try_send(GuidanceInput::VestLink(None, Duration::ZERO));
        self.ui_beat = None;
        if let Some(link) = self.vest_link.take() {
            link.stopper().stop_and_close(EXIT_STOP_WAIT);
        }
        self.exit.set(None);
        self.vest.state = None;
        self.vest.tactors_on = None;
        self.vest.device = None;
        self.vest.status = None;
    }

    /// Stops the vest first (STOP ALL, acknowledged or timed out), then the GPS: the console's exit.
    pub fn shutdown(&mut self) {
        self.disconnect_vest();
        self.disconnect_gps();
        self.autosave_route(true);
    }

    /// Writes the route to the autosave when it changed (rate-limited, unless `now_or_never`); a failure
    /// is shown once in the status line.
    pub fn autosave_route(&mut self, now_or_never: bool) {
        let Some(a) = &mut self.route_autosave else { return };
        let m = &self.map;
        if let Some(e) = a.poll(&m.route_name, &m.waypoints, m.next, Instant::now(), now_or_never) {
            self.status = e;
        }
    }

    /// Sends a manual command to the vest (holding automatic guidance off) and logs it; `cue` names it when
    /// it is one of the vocabulary's cues.
    pub fn send_manual(&mut self, command: VestCommand, cue: Option<Cue>) {
        if command == VestCommand::StopAll {
            self.stop_all();
            return;
        }
        let _ = self.guidance_tx.try_send(GuidanceInput::ManualOverride(cue));
        self.send_device(command);
    }

    /// Sends a command as the operator's and logs it, without holding automatic guidance off (what
    /// [`Self::send_manual`] adds): the heading stream and calibration commands go this way.
    pub fn send_device(&mut self, command: VestCommand) {
        let Some(link) = &self.vest_link else {
            self.refused(format!("{} not sent: no vest connected", command.describe()));
            return;
        };
        match link.send(command.clone(), CommandOrigin::Manual) {
            Ok(()) => {
                if let Some(log) = &self.log_tx {
                    log.log(LogEntry::Command {
                        origin: CommandOrigin::Manual,
                        command,
                        reason: "operator".into(),
                    });
                }
            }
            Err(e) => self.refused(format!("{} not sent: {e}", command.describe())),
        }
    }

    fn refused(&mut self, text: String) {
        self.status.clone_from(&text);
        self.vest.last_reply = Some(VestReply { text, refused: true, at: Instant::now() });
    }

    /// STOP ALL: every tactor off now, automatic guidance latched off until the operator resumes it.
    pub fn stop_all(&mut self) {
        // The vest first: an atomic request the worker serves before anything else.
        if let Some(link) = &self.vest_link {
            link.stop_all();
        }
        let _ = self.guidance_tx.try_send(GuidanceInput::StopAll);
        if let Some(log) = &self.log_tx {
            log.log(LogEntry::Command {
                origin: CommandOrigin::Manual,
                command: VestCommand::StopAll,
                reason: "operator".into(),
            });
        }
        if self.cfg.guidance_auto {
            self.cfg.guidance_auto = false;
            self.cfg_saved.guidance_auto = false;
            self.push_settings();
        }
        self.status = if self.vest_link.is_some() {
            "STOP ALL sent; automatic guidance halted until resumed".into()
        } else {
            "STOP ALL: no vest connected".into()
        };
    }

    /// The operator's deliberate resume of automatic cues.
    pub fn resume_guidance(&mut self) {
        self.cfg.guidance_auto = true;
        self.cfg_saved.guidance_auto = true;
        if let Some(link) = &self.vest_link {
            link.resume_guidance();
        }
        let _ = self.guidance_tx.try_send(GuidanceInput::Resume);
        self.push_settings();
    }

    /// Tells the guidance worker about the current route (retried every frame until it is taken).
    pub fn push_route(&mut self) {
        let msg = GuidanceInput::Route { waypoints: self.map.waypoints.clone(), next: self.map.next };
        self.route_pending = self.guidance_tx.try_send(msg).is_err();
    }

    fn push_settings(&mut self) {
        let _ = self.guidance_tx.try_send(GuidanceInput::Settings(guidance_settings(&self.cfg)));
    }

    /// Logs an operator mark at the wearer's position.
    pub fn mark(&mut self, label: &str) {
        let pos = self.gps.last_position.as_ref().and_then(|f| f.lat_deg.zip(f.lon_deg));
        if let Some(log) = &self.log_tx {
            let label = label.to_owned();
            log.log(LogEntry::Mark { label, lat_deg: pos.map(|p| p.0), lon_deg: pos.map(|p| p.1) });
        }
        self.status = format!("marked '{label}'");
    }

    /// Age of the latest position at `now`, from the instant its bytes arrived.
    pub fn position_age(&self, now: Instant) -> Option<Duration> {
        self.gps.last_position.as_ref().and_then(|f| f.age(now))
    }

    /// The GPS alarm at `now`, if any.
    pub fn gps_alarm(&self, now: Instant) -> Option<GpsAlarm> {
        let state = self.gps.state.as_ref()?;
        self.gps_worker.as_ref()?;
        if let SourceState::Lost { reason } = state {
            return Some(GpsAlarm::Lost { reason: reason.clone() });
        }
        if let Some(f) = &self.gps.fix
            && !f.has_position()
            && f.age(now).is_some_and(|a| a.as_secs_f64() < self.cfg.stale_after_s)
        {
            return Some(GpsAlarm::Lost { reason: "receiver reports no fix".into() });
        }
        let age = self.position_age(now)?.as_secs_f64();
        if age > self.cfg.lost_after_s {
            Some(GpsAlarm::Lost { reason: format!("no position for {age:.0} s") })
        } else if age > self.cfg.stale_after_s {
            Some(GpsAlarm::Stale { age_s: age })
        } else {
            None
        }
    }

    /// Drains worker events into the state (within `DRAIN_BUDGET` per channel).
    pub fn pump(&mut self) {
        let mut fixes = Vec::new();
        drain_within(&self.gps_rx, DRAIN_BUDGET, |ev| match ev {
            GpsEvent::State(s) => self.gps.state = Some(s),
            GpsEvent::Fix(f) => fixes.push(Some(*f)),
            GpsEvent::Stats(s) => self.gps.stats = Some(s),
            GpsEvent::Mark(m) => {
                self.gps.notice = Some(format!("mark {} {} in the input", m.number, m.label));
            }
            GpsEvent::Notice(n) => self.gps.notice = Some(n),
            GpsEvent::Attitude(a) => self.gps.attitude = Some(a),
            GpsEvent::Raw(line) => self.gps.monitor.push(line, Instant::now()),
            GpsEvent::Discontinuity(n) => {
                // A replay seek: the next position must not be joined to the last one (`None` below).
                fixes.push(None);
                self.gps.notice = Some(n);
            }
        });
        for f in fixes {
            let Some(f) = f else {
                self.map.break_track();
                continue;
            };
            if f.has_position() {
                self.gps.fixes += 1;
                self.gps.alarm_silenced = false;
                self.map.push_track(&f);
                let t_s =
                    f.received_at.map_or(0.0, |t| t.saturating_duration_since(self.epoch).as_secs_f64());
                self.field_panel.push_fix(t_s, &f);
                self.gps.last_position = Some(f.clone());
            }
            self.gps.fix = Some(f);
        }
        let mut vest_events = Vec::new();
        drain_within(&self.vest_rx, DRAIN_BUDGET, |ev| vest_events.push(ev));
        for ev in vest_events {
            self.vest_event(ev);
        }
        let mut latest = None;
        drain_within(&self.guidance_rx, DRAIN_BUDGET, |st| latest = Some(st));
        if let Some(st) = latest {
            if st.next != self.map.next {
                self.map.next = st.next;
            }
            self.guidance = Some(st);
        }
        if self.route_pending {
            self.push_route();
        }
    }

    fn vest_event(&mut self, ev: VestEvent) {
        let now = Instant::now();
        match ev {
            VestEvent::State(s) => {
                if s != LinkState::Ready {
                    self.vest.tactors_on = None;
                    self.vest.status = None;
                }
                if matches!(s, LinkState::Lost { .. } | LinkState::Disconnected) {
                    self.vest.device = None;
                    self.vest.heading = None;
                }
                match &s {
                    LinkState::Lost { reason } => self.vest.lost = Some(reason.clone()),
                    LinkState::Ready => self.vest.lost = None,
                    _ => {}
                }
                self.vest.state = Some(s);
            }
            VestEvent::Identified(info) => {
                self.vest.device = Some(info);
                self.vest.heading = None;
                crate::compass_panel::on_identified(self);
            }
            VestEvent::TactorsOn(m) => self.vest.tactors_on = m,
            VestEvent::Acked { seq, kind } => {
                self.vest.last_reply =
                    Some(VestReply { text: format!("ack: {} #{seq}", kind.name()), refused: false, at: now });
            }
            VestEvent::Rejected { kind, origin, reason } => {
                let who = match origin {
                    Some(CommandOrigin::Guidance) => "automatic ",
                    Some(CommandOrigin::Manual) | None => "",
                };
                let text = format!("refused {who}{}: {reason}", kind.name());
                if kind == CommandKind::StopAll {
                    self.status.clone_from(&text);
                }
                self.vest.last_reply = Some(VestReply { text, refused: true, at: now });
            }
            VestEvent::Status(st) => {
                self.vest.tactors_on = Some(st.tactors_on);
                self.vest.status = Some((st, now));
            }
            VestEvent::Transport(e) => {
                self.vest.last_reply =
                    Some(VestReply { text: format!("transport: {e}"), refused: true, at: now });
            }
            VestEvent::Halted { reason } => {
                self.cfg.guidance_auto = false;
                self.cfg_saved.guidance_auto = false;
                self.vest.halted = Some(reason);
            }
            VestEvent::Resumed => self.vest.halted = None,
            VestEvent::Heading(a) => {
                self.compass_wizard.push(&a);
                self.vest.heading = Some(a);
            }
        }
    }

    /// The UI thread's turn without drawing (also while the window is hidden): beat the liveness
    /// heartbeat and drain the workers' events.
    pub fn tick(&mut self) {
        if let Some(b) = &self.ui_beat {
            b.beat();
        }
        self.pump();
        self.autosave_route(false);
    }

    fn log_dir(&self) -> PathBuf {
        self.cfg.log_dir.clone().unwrap_or_else(|| crate::config::data_dir().join("sessions"))
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
            self.status = format!("cannot save settings to {}: {e}", p.display());
        }
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Loads the route the console starts with into `map`: the route named on the command line, else the
/// autosaved one, else the demo route. Returns a problem for the status line.
fn load_route(
    map: &mut MapView,
    cli_route: Option<PathBuf>,
    autosave: Option<&std::path::Path>,
) -> Option<String> {
    if cli_route.is_none()
        && let Some(path) = autosave
        && restore_route(path, map)
    {
        return None;
    }
    let route = match cli_route {
        Some(path) => std::fs::read_to_string(&path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))
            .and_then(|t| crate::route::parse_gpx(&t).map_err(|e| format!("{}: {e}", path.display()))),
        None => crate::route::parse_gpx(crate::route::DEMO_GPX).map_err(|e| format!("demo route: {e}")),
    };
    match route {
        Ok(c) => {
            map.route_name = c.name.unwrap_or_else(|| "route".into());
            map.waypoints = c.waypoints;
            map.notice.clone()
        }
        Err(e) => Some(format!("route unreadable: {e}")),
    }
}

/// Restores the autosaved route at `path` into `map`; returns whether it did. An unreadable autosave is
/// moved aside (`….corrupt`, so that the next autosave does not overwrite what may be worth rescuing)
/// and the reason, naming the file, is left in `map.notice`.
fn restore_route(path: &std::path::Path, map: &mut MapView) -> bool {
    match crate::route::read_autosave(path) {
        Ok(Some(state)) => {
            map.route_name = state.name;
            map.waypoints = state.waypoints;
            map.next = state.next;
            true
        }
        Ok(None) => false,
        Err(e) => {
            let mut aside = path.as_os_str().to_owned();
            aside.push(".corrupt");
            let aside = PathBuf::from(aside);
            let kept = match std::fs::rename(path, &aside) {
                Ok(()) => format!("it was kept as {}", aside.display()),
                Err(_) => "it will be overwritten by the next autosave".to_owned(),
            };
            map.notice = Some(format!(
                "Route autosave {} is unreadable ({e}); started with the default route, {kept}.",
                path.display()
            ));
            false
        }
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
        heading_mode: cfg.heading_mode,
    }
}

/// What the session log records of a GPS event.
fn gps_log_entry(ev: &GpsEvent) -> Option<LogEntry> {
    match ev {
        GpsEvent::Fix(f) if f.has_position() => Some(LogEntry::Fix {
            lat_deg: f.lat_deg?,
            lon_deg: f.lon_deg?,
            error_m: f.error.map(|e| e.horizontal_m),
            speed_m_s: f.speed_m_s,
            course_deg: f.course_deg,
            gps_utc: f.time.map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true)),
        }),
        GpsEvent::State(s) => {
            Some(LogEntry::Note { text: format!("gps {}", crate::gps_panel::state_label(Some(s))) })
        }
        GpsEvent::Notice(n) | GpsEvent::Discontinuity(n) => {
            Some(LogEntry::Note { text: format!("gps: {n}") })
        }
        GpsEvent::Attitude(a) => Some(LogEntry::heading(a)),
        _ => None,
    }
}

/// What the session log records of a vest event.
fn vest_log_entry(ev: &VestEvent) -> Option<LogEntry> {
    Some(match ev {
        VestEvent::Acked { seq, kind } => LogEntry::Ack { what: format!("{} #{seq}", kind.name()) },
        VestEvent::TactorsOn(Some(mask)) => LogEntry::TactorsOn { mask: *mask },
        VestEvent::Rejected { kind, reason, .. } => {
            LogEntry::Note { text: format!("vest refused {}: {reason}", kind.name()) }
        }
        VestEvent::State(s) => LogEntry::Note { text: format!("vest {s}") },
        VestEvent::Transport(t) => LogEntry::Note { text: format!("vest transport: {t}") },
        VestEvent::Halted { reason } => LogEntry::Note { text: format!("guidance halted: {reason}") },
        VestEvent::Resumed => LogEntry::Note { text: "guidance resumed".to_owned() },
        VestEvent::Identified(info) => LogEntry::Note {
            text: format!(
                "vest identified: protocol v{}, firmware {}, {} tactors, watchdog {} ms",
                info.protocol_version, info.firmware, info.tactor_count, info.watchdog_ms
            ),
        },
        VestEvent::Heading(a) => LogEntry::heading(a),
        VestEvent::TactorsOn(None) | VestEvent::Status(_) => return None,
    })
}
