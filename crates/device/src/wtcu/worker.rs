//! The vest worker: a named thread that owns one transport, one [`Link`] and one [`Backoff`], and talks to
//! the rest of the program through bounded channels ([`VestHandle`]).
//!
//! The worker connects, handshakes, relays commands, reports events to its consumers ([`Outbox`]es that
//! never block it), and on loss reconnects with exponential backoff.
//!
//! **The stop path does not depend on any other thread.** STOP ALL bypasses the command queue: the
//! caller sets an atomic request that the worker reads on every turn (at most one read timeout, 2 ms, later)
//! and bumps a stop generation, so every command queued before the stop is refused instead of played.
//! A STOP ALL also latches automatic commands off ([`CommandOrigin::Guidance`] is refused) until the
//! operator resumes them ([`VestHandle::resume_guidance`]). The worker never waits on another thread: its
//! events go out through non-blocking outboxes, commands come in through `try_recv`.
//!
//! **Liveness.** The threads that can be the operator's only way to stop the vest (the UI) or that send
//! automatic cues (guidance) beat a [`Heartbeat`]. If an armed heartbeat is older than its bound, the worker
//! stops every tactor by itself and latches automatic commands off, exactly as if the operator had pressed
//! STOP ALL.
//!
//! When the handle is stopped or dropped — or a [`VestStopper`] is used from a signal handler thread — the
//! worker sends STOP ALL and waits briefly for its acknowledgement before closing the port; if the link is
//! already gone, the unit's watchdog stops everything.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread::JoinHandle;
use std::thread::Thread;
use std::time::{Duration, Instant};

use vestnav_core::vest::{Pattern, TactorMask};

use super::emulator::UnitConfig;
use super::link::{Backoff, CommandError, Link, LinkConfig, LinkEvent, LinkState};
use super::message::{CalibrationWire, Capabilities, CommandKind, DeviceInfo, UnitStatus};
use crate::gps::through_vest::{ForwardingState, VestGpsWriter};
use crate::heading::Attitude;
use crate::outbox::Outbox;
use crate::serial::is_timeout;

mod emulated_port;
#[cfg(test)]
mod tests;

pub use emulated_port::EmulatedPort;

/// A byte transport the worker can own: a serial port, a PTY, an in-memory pipe. Reads must time out
/// (`TimedOut`/`WouldBlock`) after a few ms so the worker can serve its timers and commands.
pub trait Transport: Read + Write + Send {}
impl<T: Read + Write + Send + ?Sized> Transport for T {}

/// Opens a fresh transport for each connection attempt.
pub type Connector = Box<dyn FnMut() -> io::Result<Box<dyn Transport>> + Send>;

/// Where the vest is.
#[derive(Debug, Clone, PartialEq)]
pub enum VestConfig {
    /// A serial port (a Bluetooth SPP port such as `/dev/rfcomm0` or `COM5`, or an emulator's PTY).
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate (SPP ignores it; real UARTs need it).
        baud: u32,
    },
    /// The emulated unit, in process (no port needed).
    Emulated(UnitConfig),
}

/// A command for the vest.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VestCommand {
    /// Fire `mask` for `duration_ms`.
    Fire {
        /// Tactors.
        mask: TactorMask,
        /// On-time (ms).
        duration_ms: u16,
    },
    /// Play a pattern.
    Play(Pattern),
    /// Set the drive level (0..=255) of `mask`.
    SetIntensity {
        /// Tactors.
        mask: TactorMask,
        /// Level.
        level: u8,
    },
    /// Stop every tactor (jumps every queue).
    StopAll,
    /// Ask for battery, firmware and fault flags.
    RequestStatus,
    /// Start the unit's heading stream at `rate_hz` (1..=10) readings per second (protocol v2).
    HeadingStart {
        /// Readings per second.
        rate_hz: u8,
    },
    /// Stop the unit's heading stream.
    HeadingStop,
    /// Load a magnetometer calibration into the unit.
    SetCalibration(CalibrationWire),
}

/// Who asked for a vest command: the worker refuses automatic commands after a STOP ALL until the
/// operator resumes them, and the session log records it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum CommandOrigin {
    /// The operator, by hand.
    Manual,
    /// Automatic guidance.
    Guidance,
}

impl VestCommand {
    /// A short human description ("fire [0 3] 500 ms", "play 'turn left' (4 frames, x1)", "STOP ALL").
    pub fn describe(&self) -> String {
        let list = |m: TactorMask| m.indices().map(|i| i.to_string()).collect::<Vec<_>>().join(" ");
        match self {
            Self::Fire { mask, duration_ms } => format!("fire [{}] {duration_ms} ms", list(*mask)),
            Self::Play(p) => format!("play '{}' ({} frames, x{})", p.name, p.frames.len(), p.repeats),
            Self::SetIntensity { mask, level } => format!("intensity {level} on [{}]", list(*mask)),
            Self::StopAll => "STOP ALL".to_owned(),
            Self::RequestStatus => "status request".to_owned(),
            Self::HeadingStart { rate_hz } => format!("heading stream at {rate_hz} Hz"),
            Self::HeadingStop => "heading stream off".to_owned(),
            Self::SetCalibration(c) => format!(
                "compass calibration (hard iron {:.1} {:.1} {:.1} µT)",
                f64::from(c.hard_iron_dut[0]) / 10.0,
                f64::from(c.hard_iron_dut[1]) / 10.0,
                f64::from(c.hard_iron_dut[2]) / 10.0
            ),
        }
    }

    /// Its kind.
    pub fn kind(&self) -> CommandKind {
        match self {
            Self::Fire { .. } => CommandKind::Fire,
            Self::Play(_) => CommandKind::Play,
            Self::SetIntensity { .. } => CommandKind::SetIntensity,
            Self::StopAll => CommandKind::StopAll,
            Self::RequestStatus => CommandKind::GetStatus,
            Self::HeadingStart { .. } => CommandKind::HeadingStart,
            Self::HeadingStop => CommandKind::HeadingStop,
            Self::SetCalibration(_) => CommandKind::SetCalibration,
        }
    }
}

/// What the worker reports. Every event carries what the device (or our own refusal) said; the time it
/// happened is when the consumer receives it, a few milliseconds later at most (a heading reading carries
/// the instant its bytes arrived).
#[derive(Debug, Clone, PartialEq)]
pub enum VestEvent {
    /// The link changed state.
    State(LinkState),
    /// The unit identified itself.
    Identified(DeviceInfo),
    /// The tactors the unit says are on; `None` when unknown (link lost).
    TactorsOn(Option<TactorMask>),
    /// A command was accepted by the unit.
    Acked {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
    },
    /// A command was refused (by our limits, the STOP ALL latch, or the unit), not delivered, or cancelled.
    Rejected {
        /// Its kind.
        kind: CommandKind,
        /// Who sent it, when known.
        origin: Option<CommandOrigin>,
        /// Why, in words.
        reason: String,
    },
    /// Battery, firmware and fault flags.
    Status(UnitStatus),
    /// The transport could not be opened or failed.
    Transport(String),
    /// Automatic commands are latched off: by the operator's STOP ALL, or by the worker itself because a
    /// watched thread stalled.
    Halted {
        /// Why, in words.
        reason: String,
    },
    /// The operator resumed automatic commands.
    Resumed,
    /// A reading of the unit's heading stream (protocol v2), timed by when its bytes arrived.
    Heading(Attitude),
}

/// Tuning of the worker.
#[derive(Debug, Clone)]
pub struct WorkerSettings {
    /// The link's timing and limits.
    pub link: LinkConfig,
    /// Reconnect backoff.
    pub backoff: Backoff,
    /// Read timeout of the transport: bounds how late a command, a STOP ALL or a timer is served.
    pub io_poll: Duration,
    /// Capacity of the command channel.
    pub command_capacity: usize,
    /// How long the worker waits for the STOP ALL acknowledgement when shutting down.
    pub shutdown_grace: Duration,
    /// Where a GPS receiver forwarded by the unit goes (protocol v2), if anywhere: while a GPS source reads
    /// the other end of this pipe ([`crate::gps::through_vest`]), the worker asks a unit with
    /// [`Capabilities::GPS`] to forward its receiver at the baud the source wants and writes every chunk
    /// into the pipe.
    pub gps: Option<VestGpsWriter>,
}

impl Default for WorkerSettings {
    fn default() -> Self {
        Self {
            link: LinkConfig::default(),
            backoff: Backoff::default(),
            io_poll: Duration::from_millis(2),
            command_capacity: 32,
            // Exit must stop the vest within 200 ms of a signal: STOP ALL's round trip at 115200 baud is
            // a few ms; this leaves room for a retransmission.
            shutdown_grace: Duration::from_millis(150),
            gps: None,
        }
    }
}

/// Why [`VestHandle::send`] failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum VestSendError {
    /// The command channel is full (the worker is behind); the command was not queued.
    #[error("vest command queue full")]
    Full,
    /// The worker has stopped.
    #[error("vest worker stopped")]
    Stopped,
    /// Automatic commands are latched off since a STOP ALL (or a stalled thread) until the operator
    /// resumes them.
    #[error("automatic cues halted: {0}")]
    Halted(String),
}

/// A thread whose liveness the worker watches (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Watched {
    /// The UI thread: while it stalls, the operator cannot press STOP ALL.
    Ui,
    /// The guidance thread: a stalled one may have left a cue running with nobody deciding.
    Guidance,
}

impl Watched {
    fn index(self) -> usize {
        match self {
            Self::Ui => 0,
            Self::Guidance => 1,
        }
    }

    /// Its name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ui => "console UI",
            Self::Guidance => "guidance",
        }
    }
}

const WATCHED: [Watched; 2] = [Watched::Ui, Watched::Guidance];

/// One watched thread's last beat, in microseconds since the worker's epoch (0 = not armed).
#[derive(Debug, Default)]
struct WatchSlot {
    last_us: AtomicU64,
    bound_us: AtomicU64,
    tripped: AtomicBool,
}

/// A command waiting in the queue, with the stop generation it was queued in.
struct Queued {
    cmd: VestCommand,
    origin: CommandOrigin,
    generation: u64,
}

struct Shared {
    epoch: Instant,
    /// A STOP ALL is waiting for the worker.
    stop_all: AtomicBool,
    /// Bumped by every STOP ALL: commands queued before it are refused.
    generation: AtomicU64,
    /// Automatic commands are refused while set.
    halted: AtomicBool,
    /// The operator resumed automatic commands; the worker reports it.
    resumed: AtomicBool,
    shutdown: AtomicBool,
    /// The worker has ended.
    finished: AtomicBool,
    /// The last STOP ALL sent was acknowledged by the unit (cleared when a new one is requested).
    stop_acked: AtomicBool,
    watches: [WatchSlot; 2],
    thread: std::sync::OnceLock<Thread>,
}

impl Shared {
    fn now_us(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_micros()).unwrap_or(u64::MAX).max(1)
    }

    fn request_stop_all(&self) {
        self.generation.fetch_add(1, Ordering::SeqCst);
        self.halted.store(true, Ordering::SeqCst);
        self.stop_acked.store(false, Ordering::SeqCst);
        self.stop_all.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.get() {
            t.unpark();
        }
    }
}

/// The handle the application holds (see the module doc). Sending takes `&self`: the UI and the guidance
/// thread can share it behind an `Arc`.
pub struct VestHandle {
    commands: SyncSender<Queued>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for VestHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VestHandle").field("running", &self.thread.is_some()).finish_non_exhaustive()
    }
}

/// A clonable STOP ALL button for the worker, for threads that must be able to stop the vest whatever
/// else happens (the signal handler thread, the exit path).
#[derive(Clone)]
pub struct VestStopper {
    shared: Arc<Shared>,
}

impl std::fmt::Debug for VestStopper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VestStopper").finish_non_exhaustive()
    }
}

impl VestStopper {
    /// STOP ALL now (the worker sends it within one read timeout) and latch automatic commands off.
    pub fn stop_all(&self) {
        self.shared.request_stop_all();
    }

    /// STOP ALL, then end the worker, waiting at most `timeout` for it to finish; returns whether the
    /// unit acknowledged the STOP ALL before the worker ended.
    pub fn stop_and_close(&self, timeout: Duration) -> bool {
        self.shared.request_stop_all();
        self.shared.shutdown.store(true, Ordering::SeqCst);
        let end = Instant::now() + timeout;
        while !self.shared.finished.load(Ordering::SeqCst) && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(1));
        }
        self.shared.stop_acked.load(Ordering::SeqCst)
    }
}

/// The beat of one watched thread (see [`Watched`]). The second beat arms the check — the first only says
/// the thread is there, so one-time start-up work between the two (the UI's first frame builds its font
/// atlas and compiles its shaders) is not taken for a stall; dropping or [`Heartbeat::release`] disarms it
/// (a thread that ends cleanly is not a stalled one).
pub struct Heartbeat {
    shared: Arc<Shared>,
    who: Watched,
    started: AtomicBool,
}

impl std::fmt::Debug for Heartbeat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Heartbeat").field("who", &self.who).finish_non_exhaustive()
    }
}

impl Heartbeat {
    /// "Still alive"; from the second beat on, the check is armed.
    pub fn beat(&self) {
        if self.started.swap(true, Ordering::SeqCst) {
            let slot = &self.shared.watches[self.who.index()];
            slot.last_us.store(self.shared.now_us(), Ordering::SeqCst);
        }
    }

    /// Disarms the check.
    pub fn release(&self) {
        self.shared.watches[self.who.index()].last_us.store(0, Ordering::SeqCst);
    }
}

impl Drop for Heartbeat {
    fn drop(&mut self) {
        self.release();
    }
}

impl VestHandle {
    /// Starts the worker for `config`; every event goes to every outbox of `events`.
    pub fn spawn(config: VestConfig, events: Vec<Outbox<VestEvent>>) -> io::Result<Self> {
        Self::spawn_configured(config, WorkerSettings::default(), events)
    }

    /// [`Self::spawn`] with `settings` (e.g. a GPS receiver forwarded by the unit,
    /// [`WorkerSettings::gps`]).
    pub fn spawn_configured(
        config: VestConfig,
        settings: WorkerSettings,
        events: Vec<Outbox<VestEvent>>,
    ) -> io::Result<Self> {
        let connector: Connector = match config {
            VestConfig::Serial { port, baud } => {
                let poll = settings.io_poll;
                Box::new(move || {
                    let p = crate::serial::open(&port, baud, poll).map_err(|e| {
                        tracing::warn!(port, baud, "vest serial port {port}: cannot open: {e}");
                        io::Error::other(e)
                    })?;
                    tracing::info!(port, baud, "vest serial port {port} open at {baud} baud");
                    Ok(Box::new(p) as Box<dyn Transport>)
                })
            }
            VestConfig::Emulated(engine) => {
                let poll = settings.io_poll;
                Box::new(move || Ok(Box::new(EmulatedPort::new(&engine, poll)) as Box<dyn Transport>))
            }
        };
        Self::spawn_with(connector, settings, events)
    }

    /// Starts the worker on transports from `connector` with one lossless-enough receiver of its events
    /// (a 1024-event channel; a consumer that lags further loses the newest events): for tools and tests.
    pub fn spawn_with_receiver(
        connector: Connector,
        settings: WorkerSettings,
    ) -> io::Result<(Self, Receiver<VestEvent>)> {
        let (out, rx) = Outbox::channel(1024, crate::outbox::Overflow::DropNewest, None);
        Ok((Self::spawn_with(connector, settings, vec![out])?, rx))
    }

    /// Starts the worker on transports from `connector` (tests, other transports).
    pub fn spawn_with(
        connector: Connector,
        settings: WorkerSettings,
        events: Vec<Outbox<VestEvent>>,
    ) -> io::Result<Self> {
        let (cmd_tx, cmd_rx) = std::sync::mpsc::sync_channel(settings.command_capacity.max(1));
        let shared = Arc::new(Shared {
            epoch: Instant::now(),
            stop_all: AtomicBool::new(false),
            generation: AtomicU64::new(0),
            halted: AtomicBool::new(false),
            resumed: AtomicBool::new(false),
            shutdown: AtomicBool::new(false),
            finished: AtomicBool::new(false),
            stop_acked: AtomicBool::new(false),
            watches: [WatchSlot::default(), WatchSlot::default()],
            thread: std::sync::OnceLock::new(),
        });
        let mut worker = Worker {
            link: Link::new(settings.link),
            backoff: settings.backoff,
            settings,
            connector,
            commands: cmd_rx,
            events,
            shared: shared.clone(),
            gps_requested: None,
            gps_unsupported_said: false,
            origins: VecDeque::new(),
        };
        let thread = std::thread::Builder::new().name("vest-worker".to_owned()).spawn(move || {
            worker.shared.thread.get_or_init(std::thread::current);
            worker.run();
            worker.shared.finished.store(true, Ordering::SeqCst);
        })?;
        Ok(Self { commands: cmd_tx, shared, thread: Some(thread) })
    }

    /// Queues a command without blocking. STOP ALL never fails while the worker runs: it bypasses the
    /// queue (see [`VestHandle::stop_all`]). Automatic commands are refused while halted.
    pub fn send(&self, command: VestCommand, origin: CommandOrigin) -> Result<(), VestSendError> {
        if self.shared.finished.load(Ordering::SeqCst) || self.shared.shutdown.load(Ordering::SeqCst) {
            return Err(VestSendError::Stopped);
        }
        if command == VestCommand::StopAll {
            self.stop_all();
            return Ok(());
        }
        if origin == CommandOrigin::Guidance && self.shared.halted.load(Ordering::SeqCst) {
            return Err(VestSendError::Halted("since STOP ALL, until the operator resumes".to_owned()));
        }
        let generation = self.shared.generation.load(Ordering::SeqCst);
        self.commands.try_send(Queued { cmd: command, origin, generation }).map_err(|e| match e {
            TrySendError::Full(_) => VestSendError::Full,
            TrySendError::Disconnected(_) => VestSendError::Stopped,
        })
    }

    /// STOP ALL: every tactor off (the worker sends it within one read timeout, whatever the queue holds),
    /// every command queued before it refused, automatic commands latched off until
    /// [`VestHandle::resume_guidance`].
    pub fn stop_all(&self) {
        self.shared.request_stop_all();
    }

    /// The operator's deliberate resume of automatic commands after a STOP ALL or a liveness stop.
    pub fn resume_guidance(&self) {
        if self.shared.halted.swap(false, Ordering::SeqCst) {
            for slot in &self.shared.watches {
                slot.tripped.store(false, Ordering::SeqCst);
            }
            self.shared.resumed.store(true, Ordering::SeqCst);
            if let Some(t) = self.shared.thread.get() {
                t.unpark();
            }
        }
    }

    /// Whether automatic commands are latched off.
    pub fn is_halted(&self) -> bool {
        self.shared.halted.load(Ordering::SeqCst)
    }

    /// A STOP ALL button for other threads (signal handlers, exit paths).
    pub fn stopper(&self) -> VestStopper {
        VestStopper { shared: self.shared.clone() }
    }

    /// The heartbeat of `who`, to be beaten at least every `bound` (see the module doc).
    pub fn heartbeat(&self, who: Watched, bound: Duration) -> Heartbeat {
        let slot = &self.shared.watches[who.index()];
        slot.bound_us.store(u64::try_from(bound.as_micros()).unwrap_or(u64::MAX), Ordering::SeqCst);
        Heartbeat { shared: self.shared.clone(), who, started: AtomicBool::new(false) }
    }

    /// Whether the worker still runs.
    pub fn is_running(&self) -> bool {
        !self.shared.finished.load(Ordering::SeqCst)
    }

    /// Sends STOP ALL, waits briefly for its acknowledgement, closes the port and ends the worker; returns
    /// whether the STOP ALL was acknowledged.
    pub fn stop(mut self) -> bool {
        self.shutdown()
    }

    fn shutdown(&mut self) -> bool {
        self.shared.request_stop_all();
        self.shared.shutdown.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.shared.stop_acked.load(Ordering::SeqCst)
    }
}

impl Drop for VestHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

enum SessionEnd {
    Shutdown,
    Lost { was_ready: bool },
}

struct Worker {
    link: Link,
    backoff: Backoff,
    settings: WorkerSettings,
    connector: Connector,
    commands: Receiver<Queued>,
    events: Vec<Outbox<VestEvent>>,
    shared: Arc<Shared>,
    /// The baud GPS forwarding was requested at in this session, if it was.
    gps_requested: Option<u32>,
    /// This session's unit cannot forward a receiver, and the GPS source has been told so.
    gps_unsupported_said: bool,
    /// Who sent the commands handed to the link whose outcome is not known yet, by sequence number and
    /// kind: a command the unit refuses, never receives, or the link cancels is reported with its sender.
    /// Bounded ([`ORIGINS_KEPT`], oldest dropped).
    origins: VecDeque<(u8, CommandKind, CommandOrigin)>,
}

/// How many pending commands' senders the worker remembers: far more than can be queued or in flight at
/// once.
const ORIGINS_KEPT: usize = 64;

impl Worker {
    fn run(&mut self) {
        let mut attempt = 0u32;
        while !self.shared.shutdown.load(Ordering::SeqCst) {
            attempt += 1;
            self.link.set_connecting(attempt);
            self.forward_link_events();
            match (self.connector)() {
                Ok(mut port) => {
                    self.link.connect(Instant::now());
                    match self.session(port.as_mut()) {
                        SessionEnd::Shutdown => break,
                        SessionEnd::Lost { was_ready } => {
                            if was_ready {
                                self.backoff.reset();
                                attempt = 0;
                            }
                        }
                    }
                }
                Err(e) => {
                    // The serial connector names its port in its own warning; other transports are named here.
                    tracing::debug!("vest transport: cannot open the vest port: {e}");
                    self.emit(VestEvent::Transport(format!("cannot open the vest port: {e}")));
                    self.wake();
                }
            }
            let delay = self.backoff.next_delay();
            self.wait_disconnected(delay);
        }
        self.emit(VestEvent::State(LinkState::Disconnected));
        self.wake();
    }

    /// Sleeps `delay` in small steps, refusing commands (nothing can be delivered) and watching for shutdown.
    fn wait_disconnected(&mut self, delay: Duration) {
        let until = Instant::now() + delay;
        while Instant::now() < until && !self.shared.shutdown.load(Ordering::SeqCst) {
            let mut refused = false;
            if self.shared.stop_all.swap(false, Ordering::SeqCst) {
                self.emit(VestEvent::Rejected {
                    kind: CommandKind::StopAll,
                    origin: Some(CommandOrigin::Manual),
                    reason: "vest not connected; its watchdog stops every tactor when the link is lost"
                        .to_owned(),
                });
                self.emit_halted("STOP ALL");
                refused = true;
            }
            self.check_liveness(None, Instant::now());
            self.report_resume();
            while let Ok(q) = self.commands.try_recv() {
                self.emit(VestEvent::Rejected {
                    kind: q.cmd.kind(),
                    origin: Some(q.origin),
                    reason: "vest not connected".to_owned(),
                });
                refused = true;
            }
            if refused {
                self.wake();
            }
            std::thread::park_timeout(
                self.settings.io_poll.min(until.saturating_duration_since(Instant::now())),
            );
        }
    }

    fn session(&mut self, port: &mut dyn Transport) -> SessionEnd {
        let mut buf = [0u8; 512];
        let mut was_ready = false;
        loop {
            let now = Instant::now();
            if self.shared.shutdown.load(Ordering::SeqCst) {
                self.graceful_stop(port);
                return SessionEnd::Shutdown;
            }
            self.serve_stop_all(now);
            self.check_liveness(Some(&mut *port), now);
            loop {
                match self.commands.try_recv() {
                    Ok(q) => self.apply_queued(&q, Instant::now()),
                    Err(TryRecvError::Empty) => break,
                    // The handle is gone without a shutdown (cannot happen through Drop, but be safe).
                    Err(TryRecvError::Disconnected) => {
                        self.shared.shutdown.store(true, Ordering::SeqCst);
                        break;
                    }
                }
            }
            self.flush_transmit(port);
            match port.read(&mut buf) {
                Ok(0) => self.link.disconnect("the port closed"),
                Ok(n) => self.link.handle_bytes(buf.get(..n).unwrap_or(&[]), Instant::now()),
                Err(e) if is_timeout(&e) => {}
                Err(e) => self.link.disconnect(&format!("read failed: {e}")),
            }
            let now = Instant::now();
            if self.link.poll_timeout().is_some_and(|t| now >= t) {
                self.link.handle_timeout(now);
            }
            self.flush_transmit(port);
            was_ready |= self.link.is_ready();
            if self.forward_link_events() {
                self.wake();
            }
            if matches!(self.link.state(), LinkState::Lost { .. }) {
                self.gps_requested = None;
                self.gps_unsupported_said = false;
                if let Some(g) = &self.settings.gps {
                    g.set_state(ForwardingState::NoLink);
                }
                return SessionEnd::Lost { was_ready };
            }
            self.sync_gps(Instant::now());
        }
    }

    /// Starts or stops the unit's GPS forwarding as the GPS source wants it (never before the link is ready).
    fn sync_gps(&mut self, now: Instant) {
        let Some(g) = self.settings.gps.clone() else { return };
        let Some(info) = self.link.device().copied().filter(|_| self.link.is_ready()) else { return };
        if !info.capabilities.contains(Capabilities::GPS) {
            if self.gps_unsupported_said || g.wanted().is_none() {
                return;
            }
            // Said once per session: every later turn costs a load and a compare.
            self.gps_unsupported_said = true;
            g.set_state(ForwardingState::Unsupported(format!(
                "this unit (firmware {}, protocol v{}) has no GPS receiver to forward",
                info.firmware, info.protocol_version
            )));
            return;
        }
        match (g.wanted(), self.gps_requested) {
            (Some(baud), requested) if requested != Some(baud) && self.link.gps_start(baud, now).is_ok() => {
                self.gps_requested = Some(baud);
                g.set_state(ForwardingState::Requested { baud });
            }
            (None, Some(_)) if self.link.gps_stop(now).is_ok() => {
                self.gps_requested = None;
                g.set_state(ForwardingState::NoLink);
            }
            _ => {}
        }
    }

    /// Serves a pending STOP ALL request: first thing on every turn.
    fn serve_stop_all(&mut self, now: Instant) {
        if self.shared.stop_all.swap(false, Ordering::SeqCst) {
            self.apply(&VestCommand::StopAll, CommandOrigin::Manual, now);
            self.emit_halted("STOP ALL");
        }
        self.report_resume();
    }

    fn report_resume(&self) {
        if self.shared.resumed.swap(false, Ordering::SeqCst) && !self.shared.halted.load(Ordering::SeqCst) {
            self.emit(VestEvent::Resumed);
            self.wake();
        }
    }

    /// Stops every tactor when an armed watched thread has not beaten within its bound.
    fn check_liveness(&mut self, port: Option<&mut dyn Transport>, now: Instant) {
        let now_us = self.shared.now_us();
        let mut stalled = None;
        for who in WATCHED {
            let slot = &self.shared.watches[who.index()];
            let last = slot.last_us.load(Ordering::SeqCst);
            let bound = slot.bound_us.load(Ordering::SeqCst);
            if last == 0 || bound == 0 {
                continue;
            }
            let late_us = now_us.saturating_sub(last);
            if late_us > bound {
                if !slot.tripped.swap(true, Ordering::SeqCst) {
                    stalled = Some((who, late_us));
                }
            } else if !self.shared.halted.load(Ordering::SeqCst) {
                slot.tripped.store(false, Ordering::SeqCst);
            }
        }
        if let Some((who, late_us)) = stalled {
            self.shared.generation.fetch_add(1, Ordering::SeqCst);
            self.shared.halted.store(true, Ordering::SeqCst);
            if self.link.is_ready() {
                self.apply(&VestCommand::StopAll, CommandOrigin::Manual, now);
                if let Some(port) = port {
                    self.flush_transmit(port);
                }
            }
            self.emit(VestEvent::Halted {
                reason: format!(
                    "the {} did not respond for {:.1} s: every tactor stopped, automatic cues halted",
                    who.name(),
                    late_us as f64 / 1e6
                ),
            });
            self.wake();
        }
    }

    fn emit_halted(&self, why: &str) {
        self.emit(VestEvent::Halted { reason: format!("{why}: automatic cues halted until resumed") });
    }

    fn flush_transmit(&mut self, port: &mut dyn Transport) {
        while let Some(bytes) = self.link.poll_transmit() {
            if let Err(e) = port.write_all(&bytes).and_then(|()| port.flush()) {
                self.link.disconnect(&format!("write failed: {e}"));
                break;
            }
        }
    }

    /// STOP ALL and a short wait for its acknowledgement, so no tactor is left running when we go.
    fn graceful_stop(&mut self, port: &mut dyn Transport) {
        let start = Instant::now();
        self.shared.stop_all.store(false, Ordering::SeqCst);
        // A fresh frame even when a STOP ALL is already in flight: the unit hears a stop as we go.
        if self.link.stop_all_now(start).is_err() {
            return;
        }
        let mut buf = [0u8; 512];
        self.flush_transmit(port);
        while start.elapsed() < self.settings.shutdown_grace && self.link.is_busy() && self.link.is_ready() {
            self.flush_transmit(port);
            match port.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => self.link.handle_bytes(buf.get(..n).unwrap_or(&[]), Instant::now()),
                Err(e) if is_timeout(&e) => {}
                Err(_) => break,
            }
            let now = Instant::now();
            if self.link.poll_timeout().is_some_and(|t| now >= t) {
                self.link.handle_timeout(now);
            }
        }
        self.forward_link_events();
    }

    fn apply_queued(&mut self, q: &Queued, now: Instant) {
        let kind = q.cmd.kind();
        if q.generation != self.shared.generation.load(Ordering::SeqCst) {
            self.emit(VestEvent::Rejected {
                kind,
                origin: Some(q.origin),
                reason: "cancelled by STOP ALL".to_owned(),
            });
        } else if q.origin == CommandOrigin::Guidance && self.shared.halted.load(Ordering::SeqCst) {
            self.emit(VestEvent::Rejected {
                kind,
                origin: Some(q.origin),
                reason: "automatic cues halted until the operator resumes them".to_owned(),
            });
        } else {
            self.apply(&q.cmd, q.origin, now);
        }
    }

    fn apply(&mut self, cmd: &VestCommand, origin: CommandOrigin, now: Instant) {
        let kind = cmd.kind();
        let result = match cmd {
            VestCommand::Fire { mask, duration_ms } => self.link.fire(*mask, *duration_ms, now),
            VestCommand::Play(p) => self.link.play(p, now),
            VestCommand::SetIntensity { mask, level } => self.link.set_intensity(*mask, *level, now),
            VestCommand::StopAll => self.link.stop_all(now),
            VestCommand::RequestStatus => self.link.request_status(now),
            VestCommand::HeadingStart { rate_hz } => self.link.heading_start(*rate_hz, now),
            VestCommand::HeadingStop => self.link.heading_stop(now),
            VestCommand::SetCalibration(c) => self.link.set_calibration(*c, now),
        };
        let result = result.map(|seq| {
            if self.origins.len() >= ORIGINS_KEPT {
                self.origins.pop_front();
            }
            self.origins.push_back((seq, kind, origin));
        });
        if let Err(e) = result {
            let reason = match e {
                CommandError::NotReady(_) => format!("vest not ready: {}", self.link.state()),
                e => e.to_string(),
            };
            self.emit(VestEvent::Rejected { kind, origin: Some(origin), reason });
        }
    }

    /// Who sent the command the link numbered `seq`, if it was handed over by [`Worker::apply`] recently
    /// (heartbeats, GPS forwarding and the signal path's STOP ALL have no sender).
    /// The entry is removed: the link reports one outcome per command.
    fn origin_of(&mut self, seq: u8, kind: CommandKind) -> Option<CommandOrigin> {
        let i = self.origins.iter().rposition(|(s, k, _)| *s == seq && *k == kind)?;
        self.origins.remove(i).map(|(_, _, o)| o)
    }

    /// Forwards the link's events; returns whether there were any.
    fn forward_link_events(&mut self) -> bool {
        let mut any = false;
        while let Some(ev) = self.link.poll_event() {
            any = true;
            let event = match ev {
                LinkEvent::State(s) => {
                    let lost = matches!(s, LinkState::Lost { .. });
                    if let LinkState::Lost { reason } = &s {
                        tracing::warn!("vest link lost: {reason}");
                    }
                    self.emit(VestEvent::State(s));
                    if lost {
                        self.emit(VestEvent::TactorsOn(None));
                    }
                    continue;
                }
                LinkEvent::Identified(info) => VestEvent::Identified(info),
                LinkEvent::TactorsOn(m) => VestEvent::TactorsOn(Some(m)),
                LinkEvent::Acked { seq, kind } => {
                    let _ = self.origin_of(seq, kind);
                    if kind == CommandKind::StopAll {
                        self.shared.stop_acked.store(true, Ordering::SeqCst);
                    }
                    if kind == CommandKind::GpsStart
                        && let (Some(g), Some(baud)) = (&self.settings.gps, self.gps_requested)
                    {
                        g.set_state(ForwardingState::Forwarding { baud });
                    }
                    VestEvent::Acked { seq, kind }
                }
                LinkEvent::Rejected { kind, reason, .. } if kind == CommandKind::GpsStart => {
                    if let Some(g) = &self.settings.gps {
                        g.set_state(ForwardingState::Unsupported(format!(
                            "the unit refused to forward its receiver: {reason}"
                        )));
                    }
                    VestEvent::Rejected {
                        kind,
                        origin: None,
                        reason: format!("the unit refused {}: {reason}", kind.name()),
                    }
                }
                LinkEvent::Rejected { seq, kind, reason } => VestEvent::Rejected {
                    kind,
                    origin: self.origin_of(seq, kind),
                    reason: format!("the unit refused {}: {reason}", kind.name()),
                },
                LinkEvent::NotDelivered { seq, kind } => VestEvent::Rejected {
                    kind,
                    origin: self.origin_of(seq, kind),
                    reason: format!("{} not acknowledged by the unit", kind.name()),
                },
                LinkEvent::Cancelled { seq, kind } => VestEvent::Rejected {
                    kind,
                    origin: self.origin_of(seq, kind),
                    reason: format!("{} cancelled (superseded or stopped)", kind.name()),
                },
                LinkEvent::Status(s) => VestEvent::Status(s),
                // The link reports events right after the bytes that carried them were fed in.
                LinkEvent::Heading(report) => VestEvent::Heading(report.to_attitude(Instant::now())),
                // Receiver bytes go to the GPS source's pipe, not to the event consumers.
                LinkEvent::GpsData { lost, data } => {
                    if let Some(g) = &self.settings.gps {
                        g.write(lost, &data);
                    }
                    continue;
                }
            };
            self.emit(event);
        }
        any
    }

    fn emit(&self, event: VestEvent) {
        // Never waits: a lagging consumer loses events (counted by its outbox), the stop path never does.
        if let Some((last, rest)) = self.events.split_last() {
            for out in rest {
                out.try_send(event.clone());
            }
            last.try_send(event);
        }
    }

    fn wake(&self) {
        for out in &self.events {
            out.wake();
        }
    }
}
