//! The vestnav station: the running system with no window. It owns the devices (a GPS source and a vest
//! worker), the guidance worker, the route (the one owner of the waypoints, the next waypoint, the edit
//! history and the autosave), the wearer's track, the session log, the alarms and the stop path. A view —
//! the console's window, a headless `vestnav station`, a test — sends it commands and reads its state;
//! nothing a view does (or fails to do) is on the way between a fix and a cue, or between STOP ALL and
//! the vest.
//!
//! ```no_run
//! use vestnav_station::{Station, StationOptions, hardware::Hardware};
//! let mut station = Station::new(Box::new(Hardware::default()), StationOptions::default());
//! station.connect_vest();
//! station.connect_gps(Vec::new());
//! station.pump(|_| {});
//! station.stop_all(); // every tactor off, automatic cues halted until resumed
//! ```
//!
//! Threads: the GPS source's worker, the vest worker, the guidance worker and the session-log writer.
//! Each hands its events to its consumers through its own bounded [`Outbox`]es (one of them is the
//! station's, drained by [`Station::pump`] within [`DRAIN_BUDGET`] per channel).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::time::{Duration, Instant};

use vestnav_core::fieldtest_live::FieldTests;
use vestnav_core::pinned::PinDetector;
use vestnav_core::vest::Cue;
use vestnav_device::gps::{GpsEvent, SourceState};
use vestnav_device::outbox::{Outbox, Waker, drain_within};
use vestnav_device::session_log::{LogEntry, LogSender, SessionLog};
use vestnav_device::wtcu::worker::{Heartbeat, Watched};
use vestnav_device::wtcu::{CommandKind, CommandOrigin, LinkState, VestCommand, VestEvent, VestHandle};

pub mod command;
pub mod devices;
pub mod fieldtests;
pub mod guidance;
pub mod hardware;
pub mod lab;
pub mod ntrip;
pub mod pinned;
pub mod receivers;
mod reroute;
pub mod route;
pub mod sources;
pub mod state;
pub mod stop;
pub mod study;
pub mod view_wake;
mod words;

use devices::{DeviceFactory, GpsWorker};
use guidance::{GuidanceInput, GuidanceSettings, GuidanceStatus};
use route::{RouteModel, Track};
use sources::{GpsSourceConfig, VestSourceConfig};
pub use state::{GpsAlarm, GpsState, Notice, Notices, Severity, StopAlarm, Subject, VestReply, VestState};
use stop::{EXIT_STOP_WAIT, StopPath};
use words::{gps_log_entry, vest_log_entry};
pub use words::{source_state_label, stop_alarm_text};

/// Time a pump may spend per channel draining worker events.
pub const DRAIN_BUDGET: Duration = Duration::from_millis(2);
/// Capacity of each of the station's event channels.
const EVENT_CHANNEL: usize = 1024;
/// Capacity of the guidance worker's input channel (fixes beyond it are dropped: it needs the newest).
const GUIDANCE_CHANNEL: usize = 256;

/// Liveness bounds of the threads the vest worker watches (see `vestnav_device::wtcu::worker`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Liveness {
    /// The view must turn at least this often (the console's window turns at least every 750 ms while a
    /// vest is connected); `None` for a headless station, whose operator path is its signals and its
    /// network, not a frame.
    pub view: Option<Duration>,
    /// The guidance worker must turn at least this often (it ticks every 250 ms).
    pub guidance: Duration,
}

impl Default for Liveness {
    fn default() -> Self {
        Self { view: Some(Duration::from_millis(1500)), guidance: Duration::from_secs(1) }
    }
}

/// The station's settings: guidance's and the GPS alarm's limits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StationSettings {
    /// Guidance (automatic cues, radius, interval, strategy, heading source; the fix age after which the
    /// GPS is stale).
    pub guidance: GuidanceSettings,
    /// Fix age after which the fix is lost [s].
    pub lost_after_s: f64,
    /// The built-in GPS simulator's walker goes where the emulated vest's cues steer it (core's wearer
    /// model feeling the unit's tactors) instead of along the route; taken when the simulator starts.
    #[serde(default)]
    pub sim_follows_vest: bool,
}

impl Default for StationSettings {
    fn default() -> Self {
        Self {
            guidance: GuidanceSettings {
                auto: true,
                arrival_radius_m: 8.0,
                cue_interval_s: 4.0,
                manual_hold_s: 10.0,
                stale_after_s: 3.0,
                on_ms: vestnav_core::vest::DEFAULT_ON_MS,
                loop_route: true,
                strategy: vestnav_core::guidance::StrategyKind::Pursuit,
                heading_mode: vestnav_core::guidance::HeadingMode::Auto,
                off_path_m: guidance::default_off_path_m(),
                reroute_after_s: guidance::default_reroute_after_s(),
                turn_in_place: guidance::default_turn_in_place(),
                end_at_finish: false,
            },
            lost_after_s: 10.0,
            sim_follows_vest: false,
        }
    }
}

/// Where the station's route comes from at start.
#[derive(Debug, Clone, Default)]
pub struct RouteStart {
    /// A GPX file named on the command line (wins over the autosave).
    pub file: Option<PathBuf>,
    /// Where the route is autosaved and restored from (`None`: neither).
    pub autosave: Option<PathBuf>,
}

/// Options for [`Station::new`].
#[derive(Default)]
pub struct StationOptions {
    /// Settings to start with.
    pub settings: StationSettings,
    /// The GPS source to use.
    pub gps: Option<GpsSourceConfig>,
    /// The vest to use.
    pub vest: Option<VestSourceConfig>,
    /// Directory for the session log (`None`: no log).
    pub log_dir: Option<PathBuf>,
    /// Wakes the view when an event changes what it shows at once (see [`view_wake`]; `None`: the view
    /// polls).
    pub waker: Option<Waker>,
    /// Liveness bounds; `None` turns the checks off (tests that step at their own pace).
    pub liveness: Option<Liveness>,
    /// Where STOP ALL and the exit paths find the vests (a signal handler holds a clone).
    pub stop: StopPath,
    /// The route at start.
    pub route: RouteStart,
}

/// An event a view may want beyond the station's state (the raw sentence monitor, a calibration wizard,
/// a field test's fixes): what [`Station::pump`] hands to its callback, after the station took it in.
#[derive(Debug)]
pub enum StationEvent<'a> {
    /// An event of the GPS source.
    Gps(&'a GpsEvent),
    /// An event of the vest worker.
    Vest(&'a VestEvent),
}

/// The set-up findings of one failed port, for the notices of `subject`.
type PortFindings = (Subject, Vec<vestnav_device::doctor::Finding>);

/// The next station's id on a shared stop path (each station of a process has its own).
static NEXT_STOP_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The running system (see the crate doc).
pub struct Station {
    settings: StationSettings,
    gps_source: GpsSourceConfig,
    vest_source: VestSourceConfig,
    factory: Box<dyn DeviceFactory>,
    liveness: Option<Liveness>,
    gps_rx: Receiver<GpsEvent>,
    gps_out: Outbox<GpsEvent>,
    vest_rx: Receiver<VestEvent>,
    vest_out: Outbox<VestEvent>,
    guidance_rx: Receiver<GuidanceStatus>,
    guidance_tx: SyncSender<GuidanceInput>,
    /// The route revision guidance has; `None` until it took one.
    route_sent: Option<u64>,
    /// Settings guidance has not taken yet (a full channel never loses a change: retried every pump).
    settings_pending: bool,
    gps_worker: Option<Box<dyn GpsWorker>>,
    /// The taps of the last [`Self::connect_gps`] (a study's navigation trial restarts the simulator).
    gps_taps: Vec<Outbox<GpsEvent>>,
    vest_link: Option<Arc<VestHandle>>,
    view_beat: Option<Heartbeat>,
    stop: StopPath,
    /// This station's vest on the stop path (stations sharing one path each have their own).
    stop_id: u64,
    log: Option<SessionLog>,
    log_tx: Option<LogSender>,
    route: RouteModel,
    autosave: Option<route::Autosave>,
    track: Track,
    /// What the GPS side shows.
    pub gps: GpsState,
    /// What the vest side shows.
    pub vest: VestState,
    /// Latest guidance status.
    pub guidance: Option<GuidanceStatus>,
    /// The latest cues guidance handed to the vest, newest last.
    pub cues: state::SentCues,
    /// Notices for the operator.
    pub notices: Notices,
    /// Whether the stop alarm was on at the last pump (its rising edge is logged once).
    stop_alarm_was: bool,
    /// The session log's health as last shown.
    log_health: vestnav_device::session_log::LogHealth,
    /// Ports whose set-up findings were shown since they were connected (each said once).
    diagnosed: Vec<String>,
    /// Set-up findings of a failed port, from the thread that looked (it reads files and runs programs,
    /// which the view's thread never waits for).
    port_findings: (std::sync::mpsc::Sender<PortFindings>, std::sync::mpsc::Receiver<PortFindings>),
    rerouter: reroute::Rerouter,
    /// The drift and cone tests, fed with every fix of whatever source runs.
    pub field_tests: FieldTests,
    /// The origin of the field tests' and the pin detector's times.
    epoch: Instant,
    /// Watches for a receiver holding its position (see [`pinned`]).
    pin: PinDetector,
    /// The pinned-receiver cause guidance was last told (`None`: not frozen).
    frozen_sent: Option<String>,
    /// The study session loaded, if any (see [`study`]).
    study: study::StudySlot,
    /// The lab outputs (LSL, OSC) every feeding thread sees (see [`lab`]).
    lab: lab::LabTap,
    /// RTK corrections to the receiver, once started (see [`ntrip`]).
    ntrip: Option<ntrip::Corrections>,
    /// More receivers beside the primary, compared with it (see [`receivers`]).
    receivers: receivers::Receivers,
}

impl Station {
    /// Builds the station, starts the guidance worker and the session log, and loads the route (the file
    /// named, else the autosave, else the demo route). Devices are connected with [`Self::connect_gps`]
    /// and [`Self::connect_vest`].
    pub fn new(factory: Box<dyn DeviceFactory>, opts: StationOptions) -> Self {
        let StationOptions { settings, gps, vest, log_dir, waker, liveness, stop, route: route_start } = opts;
        let mut notices = Notices::default();
        // A log whose folder cannot be written now starts failing (shown, retried) instead of being off.
        let log = log_dir.and_then(|d| match SessionLog::create_resilient(&d) {
            Ok(l) => Some(l),
            Err(e) => {
                notices.raise(
                    Severity::Alarm,
                    Subject::Storage,
                    format!(
                        "SESSION LOG OFF: cannot write in {}: {e}. Nothing of this session is recorded.",
                        d.display()
                    ),
                );
                None
            }
        });
        let log_tx = log.as_ref().and_then(SessionLog::sender);
        let (guidance_ui, guidance_rx) = view_wake::guidance_outbox(EVENT_CHANNEL, waker.clone());
        let (guidance_tx, guidance_in_rx) = sync_channel(GUIDANCE_CHANNEL);
        if let Err(e) = guidance::spawn(guidance_in_rx, settings.guidance, guidance_ui, log_tx.clone()) {
            notices.raise(
                Severity::Alarm,
                Subject::Guidance,
                format!(
                    "GUIDANCE WORKER FAILED TO START: {e}. No automatic cues this session; restart vestnav."
                ),
            );
        }
        let lab = lab::LabTap::default();
        // The channel is new and empty: this first message always fits.
        let _ = guidance_tx.try_send(GuidanceInput::Lab(lab.clone()));
        let (gps_out, gps_rx) = view_wake::outbox(EVENT_CHANNEL, waker.clone(), view_wake::gps_wakes);
        let (vest_out, vest_rx) = view_wake::outbox(EVENT_CHANNEL, waker, view_wake::vest_wakes);
        let (route, autosave) = route::load_start(&route_start, &mut notices);
        Self {
            settings,
            gps_source: gps.unwrap_or_default(),
            vest_source: vest.unwrap_or(VestSourceConfig::Emulated),
            factory,
            liveness,
            gps_rx,
            gps_out,
            vest_rx,
            vest_out,
            guidance_rx,
            guidance_tx,
            route_sent: None,
            settings_pending: false,
            gps_worker: None,
            gps_taps: Vec::new(),
            vest_link: None,
            view_beat: None,
            stop,
            stop_id: NEXT_STOP_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            log,
            log_tx,
            route,
            autosave,
            track: Track::default(),
            gps: GpsState::default(),
            vest: VestState::default(),
            guidance: None,
            cues: state::SentCues::default(),
            notices,
            stop_alarm_was: false,
            log_health: vestnav_device::session_log::LogHealth::Ok,
            diagnosed: Vec::new(),
            port_findings: std::sync::mpsc::channel(),
            rerouter: reroute::Rerouter::default(),
            field_tests: FieldTests::new(),
            epoch: Instant::now(),
            pin: PinDetector::default(),
            frozen_sent: None,
            study: study::StudySlot::default(),
            lab,
            ntrip: None,
            receivers: receivers::Receivers::default(),
        }
    }

    /// The settings in force.
    pub fn settings(&self) -> &StationSettings {
        &self.settings
    }

    /// Changes the settings; guidance takes them on this pump or a later one (never lost). Turning
    /// automatic cues back on is the operator's deliberate resume.
    pub fn set_settings(&mut self, settings: StationSettings) {
        if settings == self.settings {
            return;
        }
        let resume = settings.guidance.auto && !self.settings.guidance.auto;
        self.settings = settings;
        if resume {
            self.resume_guidance();
        } else {
            self.push_settings();
        }
    }

    fn push_settings(&mut self) {
        self.settings_pending =
            self.guidance_tx.try_send(GuidanceInput::Settings(self.settings.guidance)).is_err();
    }

    /// The GPS source the station uses.
    pub fn gps_source(&self) -> &GpsSourceConfig {
        &self.gps_source
    }

    /// Sets the GPS source (takes effect at the next [`Self::connect_gps`]).
    pub fn set_gps_source(&mut self, source: GpsSourceConfig) {
        self.gps_source = source;
    }

    /// The vest the station uses.
    pub fn vest_source(&self) -> &VestSourceConfig {
        &self.vest_source
    }

    /// Sets the vest (takes effect at the next [`Self::connect_vest`]).
    pub fn set_vest_source(&mut self, source: VestSourceConfig) {
        self.vest_source = source;
    }

    /// The stop path (for a signal handler or a window's close).
    pub fn stop_path(&self) -> &StopPath {
        &self.stop
    }

    /// The session log being written, if any.
    pub fn log_path(&self) -> Option<&Path> {
        self.log.as_ref().map(SessionLog::path)
    }

    /// Whether the session log is failing to write now (its notice says why and what was lost).
    pub fn log_failing(&self) -> bool {
        self.log.as_ref().is_some_and(|l| l.health().is_failing())
    }

    /// A sender into the session log (for a view's own records), if there is a log.
    pub fn log_sender(&self) -> Option<&LogSender> {
        self.log_tx.as_ref()
    }

    /// Whether a GPS source is running.
    pub fn gps_connected(&self) -> bool {
        self.gps_worker.is_some()
    }

    /// Whether a vest worker is running.
    pub fn vest_connected(&self) -> bool {
        self.vest_link.is_some()
    }

    /// The running vest worker, if any.
    pub fn vest_handle(&self) -> Option<&Arc<VestHandle>> {
        self.vest_link.as_ref()
    }

    /// The running GPS source, if any.
    pub fn gps_worker(&self) -> Option<&dyn GpsWorker> {
        self.gps_worker.as_deref()
    }

    /// The route (read only; edits go through [`Self::route_mut`]).
    pub fn route(&self) -> &RouteModel {
        &self.route
    }

    /// The route, to edit: every change reaches guidance and the autosave at the next pump.
    pub fn route_mut(&mut self) -> &mut RouteModel {
        &mut self.route
    }

    /// The wearer's track.
    pub fn track(&self) -> &Track {
        &self.track
    }

    /// The route to edit, the track to draw beside it and the notices to report to, at once (a map view
    /// needs all three in one frame).
    pub fn route_view(&mut self) -> (&mut RouteModel, &Track, &mut Notices) {
        (&mut self.route, &self.track, &mut self.notices)
    }

    /// (Re)connects the GPS to the configured source; `taps` receive every event too (a recorder).
    pub fn connect_gps(&mut self, taps: Vec<Outbox<GpsEvent>>) {
        self.disconnect_gps();
        let mut outputs = vec![self.gps_out.clone()];
        outputs.push(Outbox::mapped(
            self.guidance_tx.clone(),
            |ev: GpsEvent| {
                matches!(ev, GpsEvent::Fix(_) | GpsEvent::Attitude(_)).then_some(GuidanceInput::Gps(ev))
            },
            None,
        ));
        if let Some(log) = self.log_tx.clone() {
            outputs.push(Outbox::sink(move |ev: GpsEvent| {
                if let Some(entry) = gps_log_entry(&ev) {
                    log.log(entry);
                }
                true
            }));
        }
        outputs.push(self.lab.gps_sink());
        outputs.push(self.receivers.primary_outbox());
        self.gps_taps.clone_from(&taps);
        outputs.extend(taps);
        self.gps = GpsState::default();
        self.diagnosed.clear();
        // A new source: its clock and arrival times start afresh for the field tests too.
        self.field_tests.source_changed();
        self.pin.clear();
        // A new source: its first position must not be joined to the old source's last one.
        self.track.break_segment();
        if let Some(wearer) = self.factory.simulated_wearer() {
            wearer.set_follow_vest(self.settings.sim_follows_vest);
        }
        match self.factory.open_gps(&self.gps_source, &self.route.walked(), outputs) {
            Ok(w) => self.gps_worker = Some(w),
            Err(e) => {
                self.gps.state = Some(SourceState::Lost { reason: e.clone() });
                self.notices.raise(Severity::Alarm, Subject::Gps, format!("GPS: {e}"));
            }
        }
    }

    /// Stops the GPS source (never waits long on its IO).
    pub fn disconnect_gps(&mut self) {
        self.end_ntrip("the GPS source was disconnected or changed");
        if let Some(mut w) = self.gps_worker.take() {
            w.stop();
        }
        self.gps.state = None;
    }

    /// (Re)connects the vest.
    pub fn connect_vest(&mut self) {
        self.disconnect_vest();
        let mut outputs = vec![self.vest_out.clone()];
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
        outputs.push(self.lab.vest_sink());
        self.vest = VestState::default();
        self.diagnosed.clear();
        match self.factory.open_vest(&self.vest_source, outputs) {
            Ok(handle) => {
                let handle = Arc::new(handle);
                self.stop.register(self.stop_id, handle.stopper());
                self.view_beat = self.liveness.and_then(|l| l.view).map(|b| handle.heartbeat(Watched::Ui, b));
                let g_bound = self.liveness.map_or(Duration::ZERO, |l| l.guidance);
                if self.guidance_tx.try_send(GuidanceInput::VestLink(Some(handle.clone()), g_bound)).is_err()
                {
                    self.notices.raise(
                        Severity::Alarm,
                        Subject::Guidance,
                        "guidance worker busy: it does not know the vest yet; reconnect the vest",
                    );
                }
                self.vest.state = Some(LinkState::Connecting { attempt: 1 });
                self.vest_link = Some(handle);
            }
            Err(e) => {
                self.vest.state = Some(LinkState::Lost { reason: e.clone() });
                self.notices.raise(Severity::Alarm, Subject::Vest, format!("vest: {e}"));
            }
        }
    }

    /// Stops every tactor and closes the vest link (waiting a bounded time for the acknowledgement).
    pub fn disconnect_vest(&mut self) {
        let _ = self.guidance_tx.try_send(GuidanceInput::VestLink(None, Duration::ZERO));
        self.view_beat = None;
        if let Some(link) = self.vest_link.take() {
            link.stopper().stop_and_close(EXIT_STOP_WAIT);
        }
        self.stop.unregister(self.stop_id);
        self.vest = VestState::default();
    }

    /// Stops the vest first (STOP ALL, acknowledged or timed out), then the GPS, and writes the route: the
    /// station's end.
    pub fn shutdown(&mut self) {
        self.disconnect_vest();
        self.study_exit();
        self.disconnect_gps();
        self.stop_receivers();
        self.autosave_route(true);
    }

    /// This station's vest's id on the stop path.
    pub fn stop_id(&self) -> u64 {
        self.stop_id
    }

    /// STOP ALL: every tactor of this station's vest off now, automatic guidance latched off until the
    /// operator resumes it. (Every vest of the process at once: [`StopPath::stop_all`] on
    /// [`Self::stop_path`], which a console with several local stations calls first.)
    pub fn stop_all(&mut self) {
        // The vest first: an atomic request the worker serves before anything else.
        self.stop.stop(self.stop_id);
        let now = Instant::now();
        if self.vest_link.is_some() {
            self.vest.stop_requested(now);
        }
        let _ = self.guidance_tx.try_send(GuidanceInput::StopAll);
        self.lab.command(CommandOrigin::Manual, &VestCommand::StopAll);
        self.log(LogEntry::Command {
            origin: CommandOrigin::Manual,
            command: VestCommand::StopAll,
            reason: "operator".into(),
        });
        if self.settings.guidance.auto {
            self.settings.guidance.auto = false;
            self.push_settings();
        }
    }

    /// The operator's deliberate resume of automatic cues.
    pub fn resume_guidance(&mut self) {
        self.settings.guidance.auto = true;
        if let Some(link) = &self.vest_link {
            link.resume_guidance();
        }
        self.vest.commanded();
        let _ = self.guidance_tx.try_send(GuidanceInput::Resume);
        self.push_settings();
    }

    /// Sends a manual command to the vest (holding automatic guidance off) and logs it; `cue` names it when
    /// it is one of the vocabulary's cues. Returns what to tell the operator when it was not sent.
    pub fn send_manual(&mut self, command: VestCommand, cue: Option<Cue>) -> Result<(), String> {
        if command == VestCommand::StopAll {
            self.stop_all();
            return Ok(());
        }
        let _ = self.guidance_tx.try_send(GuidanceInput::ManualOverride(cue));
        self.send_device(command)
    }

    /// Sends a command as the operator's and logs it, without holding automatic guidance off (the heading
    /// stream and calibration commands go this way).
    pub fn send_device(&mut self, command: VestCommand) -> Result<(), String> {
        let result = match &self.vest_link {
            None => Err(format!("{} not sent: no vest connected", command.describe())),
            Some(link) => link
                .send(command.clone(), CommandOrigin::Manual)
                .map_err(|e| format!("{} not sent: {e}", command.describe())),
        };
        match &result {
            Ok(()) => {
                self.vest.commanded();
                self.lab.command(CommandOrigin::Manual, &command);
                self.log(LogEntry::Command {
                    origin: CommandOrigin::Manual,
                    command,
                    reason: "operator".into(),
                });
            }
            Err(text) => {
                self.vest.last_reply =
                    Some(VestReply { text: text.clone(), refused: true, at: Instant::now() });
            }
        }
        result
    }

    /// Marks the next cone of the running cone test at the latest fix and logs the mark; returns its label
    /// (`None`: no cone test runs or no fix yet).
    pub fn mark_cone(&mut self) -> Option<String> {
        let label = self.field_tests.mark_cone()?;
        self.mark(&label);
        Some(label)
    }

    /// Logs an operator mark at the wearer's position.
    pub fn mark(&mut self, label: &str) {
        let pos = self.gps.last_position.as_ref().and_then(|f| f.lat_deg.zip(f.lon_deg));
        self.log(LogEntry::Mark {
            label: label.to_owned(),
            lat_deg: pos.map(|p| p.0),
            lon_deg: pos.map(|p| p.1),
        });
    }

    fn log(&self, entry: LogEntry) {
        if let Some(log) = &self.log_tx {
            log.log(entry);
        }
    }

    /// Age of the latest position at `now`, from the instant its bytes arrived.
    pub fn position_age(&self, now: Instant) -> Option<Duration> {
        self.gps.last_position.as_ref().and_then(|f| f.age(now))
    }

    /// The GPS alarm at `now`, if any.
    pub fn gps_alarm(&self, now: Instant) -> Option<GpsAlarm> {
        state::gps_alarm(
            &self.gps,
            self.gps_worker.is_some(),
            now,
            self.settings.guidance.stale_after_s,
            self.settings.lost_after_s,
        )
    }

    /// Asks the simulated wearer to turn on the spot at `rate_deg_s` (`None`: walk on), as an operator
    /// asks a real wearer during a compass calibration; the emulated vest's compass measures the turn and
    /// the built-in simulator holds its walker meanwhile. False when the vest is not the emulated one (a
    /// real wearer is asked in words).
    pub fn turn_simulated_wearer(&self, rate_deg_s: Option<f64>) -> bool {
        if self.vest_source != VestSourceConfig::Emulated {
            return false;
        }
        let Some(truth) = self.factory.simulated_wearer() else { return false };
        match rate_deg_s {
            Some(rate) => truth.start_turn(rate),
            None => truth.end_turn(),
        }
        true
    }

    /// The receiver family the GPS stream shows, if it shows one.
    pub fn gps_family(&self) -> Option<vestnav_device::gps::receiver_config::Family> {
        self.gps.stats.as_ref().and_then(vestnav_device::gps::receiver_config::Family::detect)
    }

    /// The pinned-receiver diagnosis at `now`: the receiver holds one position (see [`pinned`]).
    pub fn pinned(&self, now: Instant) -> Option<pinned::Pinned> {
        let now_s = now.saturating_duration_since(self.epoch).as_secs_f64();
        pinned::Pinned::diagnose(&self.pin, now_s, self.gps_family())
    }

    /// The stop alarm at `now`: the latest STOP ALL not confirmed by the unit.
    pub fn stop_alarm(&self, now: Instant) -> Option<StopAlarm> {
        self.vest.stop_alarm(now)
    }

    /// The view's turn: beats the view's liveness heartbeat, drains the workers' events into the state
    /// (within [`DRAIN_BUDGET`] per channel), hands each to `view`, and keeps guidance and the autosave up
    /// to date with the route and the settings.
    pub fn pump(&mut self, mut view: impl FnMut(StationEvent<'_>)) {
        if let Some(b) = &self.view_beat {
            b.beat();
        }
        let mut gps_events = Vec::new();
        drain_within(&self.gps_rx, DRAIN_BUDGET, |ev| gps_events.push(ev));
        for ev in &gps_events {
            self.gps_event(ev);
            self.receivers.primary_event(ev);
            view(StationEvent::Gps(ev));
        }
        self.pump_receivers(Instant::now());
        let mut vest_events = Vec::new();
        drain_within(&self.vest_rx, DRAIN_BUDGET, |ev| vest_events.push(ev));
        for ev in &vest_events {
            self.vest_event(ev);
            view(StationEvent::Vest(ev));
        }
        self.take_port_findings();
        self.pump_ntrip();
        let mut statuses = Vec::new();
        drain_within(&self.guidance_rx, DRAIN_BUDGET, |st: GuidanceStatus| statuses.push(st));
        for st in &statuses {
            if st.sent
                && let Some(cue) = st.cue
            {
                self.cues.push(cue, Instant::now());
            }
        }
        self.study_pump(&vest_events, &gps_events, &statuses);
        if let Some(st) = statuses.pop() {
            if st.route_revision == self.route.revision() && st.next != self.route.next() {
                // Guidance moved on (an arrival) on the route it has: the route's next follows, and
                // guidance need not hear it back.
                self.route.set_next(st.next);
                if self.route_sent == Some(st.route_revision) {
                    self.route_sent = Some(self.route.revision());
                }
            }
            self.guidance = Some(st);
        }
        self.reroute_turn();
        if self.route_sent != Some(self.route.revision()) {
            self.push_route();
        }
        if self.settings_pending {
            self.push_settings();
        }
        self.push_frozen();
        let alarm = self.vest.stop_alarm(Instant::now());
        if let Some(a) = &alarm
            && !self.stop_alarm_was
        {
            self.log(LogEntry::Note { text: format!("STOP NOT CONFIRMED: {}", stop_alarm_text(a)) });
        }
        self.stop_alarm_was = alarm.is_some();
        self.watch_log();
        self.autosave_route(false);
    }

    /// Shows the session log's storage failures (full disk, read-only medium, I/O errors) where the
    /// operator looks, one notice replaced as the episode changes, gone when all is well again.
    fn watch_log(&mut self) {
        let Some(log) = &self.log else { return };
        let health = log.health();
        if health == self.log_health {
            return;
        }
        self.notices.dismiss_subject(Subject::Storage);
        if let Some(text) = health.banner(log.path()) {
            let severity = if health.is_failing() { Severity::Alarm } else { Severity::Warning };
            self.notices.raise(severity, Subject::Storage, text);
        }
        self.log_health = health;
    }

    /// Tells guidance when the pinned-receiver diagnosis begins or ends (retried every pump until taken):
    /// a frozen position is not a wearer standing still, and guidance holds on it.
    fn push_frozen(&mut self) {
        let frozen = self.pinned(Instant::now()).map(|p| p.cause().to_owned());
        if frozen != self.frozen_sent
            && self.guidance_tx.try_send(GuidanceInput::PositionFrozen(frozen.clone())).is_ok()
        {
            self.frozen_sent = frozen;
        }
    }

    /// Tells guidance the current route (retried every pump until it is taken).
    fn push_route(&mut self) {
        let msg = GuidanceInput::Route {
            waypoints: self.route.waypoints().to_vec(),
            path: self.route.path().cloned(),
            next: self.route.next(),
            revision: self.route.revision(),
        };
        if self.guidance_tx.try_send(msg).is_ok() {
            self.route_sent = Some(self.route.revision());
        }
    }

    /// Writes the route to the autosave when it changed (rate-limited, unless `now_or_never`); a failure
    /// is raised once.
    pub fn autosave_route(&mut self, now_or_never: bool) {
        let Some(a) = &mut self.autosave else { return };
        let r = &self.route;
        if let Some(e) = a.poll(r, Instant::now(), now_or_never) {
            self.notices.raise(Severity::Alarm, Subject::Route, e);
        }
    }

    /// When a serial port fails, says once what on this machine is in the way and how to fix it (the
    /// same findings as `vestnav doctor`: group membership, Bluetooth binding, the device node).
    fn diagnose_port(&mut self, subject: Subject, port: &str) {
        if self.diagnosed.iter().any(|p| p == port) {
            return;
        }
        self.diagnosed.push(port.to_owned());
        let (tx, port) = (self.port_findings.0.clone(), port.to_owned());
        let looked = std::thread::Builder::new().name("vestnav-port-doctor".into()).spawn(move || {
            let env = vestnav_device::doctor::Environment::system();
            let _ = tx.send((subject, vestnav_device::doctor::port_findings(&env, &port)));
        });
        if let Err(e) = looked {
            tracing::warn!("port check not started: {e}");
        }
    }

    /// Shows the findings of port checks that have finished.
    fn take_port_findings(&mut self) {
        use vestnav_device::doctor::Verdict;
        while let Ok((subject, findings)) = self.port_findings.1.try_recv() {
            for f in findings {
                let severity = match f.verdict {
                    Verdict::Problem => Severity::Alarm,
                    Verdict::Warning => Severity::Warning,
                    Verdict::Ok | Verdict::Info => continue,
                };
                let fix = f.fix.map_or_else(String::new, |x| format!(" Fix: {x}"));
                self.notices.raise(
                    severity,
                    subject,
                    format!("{}: {}.{fix}", f.check, f.detail.trim_end_matches('.')),
                );
            }
        }
    }

    fn gps_event(&mut self, ev: &GpsEvent) {
        match ev {
            GpsEvent::State(s) => {
                if let (
                    SourceState::Lost { .. } | SourceState::Reconnecting { .. },
                    GpsSourceConfig::Serial { port, .. },
                ) = (s, &self.gps_source)
                    && self.gps.last_position.is_none()
                {
                    let port = port.clone();
                    self.diagnose_port(Subject::Gps, &port);
                }
                if *s == SourceState::Finished {
                    self.field_tests.source_ended();
                }
                // A worker's last word is Stopped; after "finished" or "lost" that says less than what it
                // follows (a replay at its end stays finished, not an alarm about an ageing fix).
                let says_less = *s == SourceState::Stopped
                    && matches!(self.gps.state, Some(SourceState::Finished | SourceState::Lost { .. }));
                if !says_less {
                    self.gps.state = Some(s.clone());
                }
            }
            GpsEvent::Fix(f) => {
                if f.has_position() {
                    fieldtests::feed(&mut self.field_tests, self.epoch, f);
                    if let (Some(lat), Some(lon), Some(at)) = (f.lat_deg, f.lon_deg, f.received_at) {
                        let t_s = at.saturating_duration_since(self.epoch).as_secs_f64();
                        self.pin.push_fix(t_s, vestnav_core::geo::LatLon::new(lat, lon), f.speed_m_s);
                        // The built-in simulator knows whether its walker moves.
                        if matches!(self.gps_source, GpsSourceConfig::Simulator { .. })
                            && let Some(body) = self.factory.simulated_wearer().and_then(|w| w.get())
                            && body.pace_m_s > vestnav_core::pinned::MOVING_SPEED_M_S
                        {
                            self.pin.simulator_moving(t_s);
                        }
                    }
                    self.gps.fixes += 1;
                    self.gps.alarm_silenced = false;
                    self.track.push(f);
                    self.gps.last_position = Some((**f).clone());
                }
                self.gps.fix = Some((**f).clone());
            }
            GpsEvent::Stats(s) => self.gps.stats = Some(*s),
            GpsEvent::Mark(m) => {
                self.gps.notice = Some(format!("mark {} {} in the input", m.number, m.label));
            }
            GpsEvent::Notice(n) => self.gps.notice = Some(n.clone()),
            GpsEvent::Attitude(a) => self.gps.attitude = Some(*a),
            GpsEvent::Raw(line) => self.ntrip_gga(line),
            GpsEvent::Discontinuity(n) => {
                // A replay seek or loop: the next position must not be joined to the last one, and the
                // receiver's clock jumps with it.
                self.track.break_segment();
                self.field_tests.source_jumped();
                self.gps.notice = Some(n.clone());
            }
        }
    }

    fn vest_event(&mut self, ev: &VestEvent) {
        let now = Instant::now();
        match ev {
            VestEvent::State(s) => {
                if *s != LinkState::Ready {
                    self.vest.tactors_on = None;
                    self.vest.status = None;
                }
                if matches!(s, LinkState::Lost { .. } | LinkState::Disconnected) {
                    self.vest.device = None;
                    self.vest.heading = None;
                }
                match s {
                    LinkState::Lost { reason } => self.vest.lost = Some(reason.clone()),
                    LinkState::Ready => self.vest.lost = None,
                    _ => {}
                }
                self.vest.state = Some(s.clone());
            }
            VestEvent::Identified(info) => {
                self.vest.device = Some(*info);
                self.vest.heading = None;
            }
            VestEvent::TactorsOn(m) => self.vest.tactors_on = *m,
            VestEvent::Acked { seq, kind } => {
                self.vest.acked(*kind, now);
                self.vest.last_reply =
                    Some(VestReply { text: format!("ack: {} #{seq}", kind.name()), refused: false, at: now });
            }
            VestEvent::Rejected { kind, origin, reason } => {
                let who = match origin {
                    Some(CommandOrigin::Guidance) => "automatic ",
                    Some(CommandOrigin::Manual) | None => "",
                };
                let text = format!("refused {who}{}: {reason}", kind.name());
                if *kind == CommandKind::StopAll {
                    self.notices.raise(Severity::Alarm, Subject::Vest, text.clone());
                }
                self.vest.last_reply = Some(VestReply { text, refused: true, at: now });
            }
            VestEvent::Status(st) => {
                self.vest.tactors_on = Some(st.tactors_on);
                self.vest.status = Some((*st, now));
            }
            VestEvent::Transport(e) => {
                if let VestSourceConfig::Serial { port } = &self.vest_source
                    && self.vest.device.is_none()
                {
                    let port = port.clone();
                    self.diagnose_port(Subject::Vest, &port);
                }
                self.vest.last_reply =
                    Some(VestReply { text: format!("transport: {e}"), refused: true, at: now });
            }
            VestEvent::Halted { reason } => {
                // The worker latched automatic cues off; the settings say so too (no push: guidance knows).
                self.settings.guidance.auto = false;
                // The worker stopped the tactors (the operator's STOP ALL, or a stalled thread): track it.
                if self.vest.stop.is_none_or(|s| s.acked_at.is_some()) {
                    self.vest.stop_requested(now);
                }
                self.vest.halted = Some(reason.clone());
            }
            VestEvent::Resumed => self.vest.halted = None,
            VestEvent::Heading(a) => {
                if let Some(p) = a.pitch_deg {
                    self.pin.push_pitch(a.received_at.saturating_duration_since(self.epoch).as_secs_f64(), p);
                }
                self.vest.heading = Some(*a);
            }
        }
    }
}

impl Drop for Station {
    fn drop(&mut self) {
        self.shutdown();
    }
}
