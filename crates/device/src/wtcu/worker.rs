//! The vest worker: a named thread that owns one transport, one [`Link`] and one [`Backoff`], and talks to
//! the rest of the program through bounded channels ([`VestHandle`]).
//!
//! The worker connects, handshakes, relays commands, reports events (waking the UI after each batch), and
//! on loss reconnects with exponential backoff. STOP ALL bypasses the command queue (a flag the worker checks
//! every turn). When the handle is stopped or dropped, the worker sends STOP ALL and waits briefly for its
//! acknowledgement before closing the port; if the link is already gone, the unit's watchdog stops
//! everything.

use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::vest::{Pattern, TactorMask};

use super::emulator::is_timeout;
use super::engine::{Engine, EngineConfig};
use super::link::{Backoff, CommandError, Link, LinkConfig, LinkEvent, LinkState};
use super::message::{CommandKind, DeviceInfo, UnitStatus};

/// A byte transport the worker can own: a serial port, a PTY, an in-memory pipe. Reads must time out
/// (`TimedOut`/`WouldBlock`) after a few ms so the worker can serve its timers and commands.
pub trait Transport: Read + Write + Send {}
impl<T: Read + Write + Send + ?Sized> Transport for T {}

/// Opens a fresh transport for each connection attempt.
pub type Connector = Box<dyn FnMut() -> io::Result<Box<dyn Transport>> + Send>;

/// Where the vest is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum VestConfig {
    /// A serial port (a Bluetooth SPP port such as `/dev/rfcomm0` or `COM5`, or an emulator's PTY).
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate (SPP ignores it; real UARTs need it).
        baud: u32,
    },
    /// The emulated unit, in process (no port needed).
    Emulated(EngineConfig),
}

/// A command for the vest.
#[derive(Debug, Clone, PartialEq, Eq)]
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
}

impl VestCommand {
    /// Its kind.
    pub fn kind(&self) -> CommandKind {
        match self {
            Self::Fire { .. } => CommandKind::Fire,
            Self::Play(_) => CommandKind::Play,
            Self::SetIntensity { .. } => CommandKind::SetIntensity,
            Self::StopAll => CommandKind::StopAll,
            Self::RequestStatus => CommandKind::GetStatus,
        }
    }
}

/// What the worker reports.
#[derive(Debug, Clone, PartialEq, Eq)]
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
    /// A command was refused (by our limits or the unit), not delivered, or cancelled.
    Rejected {
        /// Its kind.
        kind: CommandKind,
        /// Why, in words.
        reason: String,
    },
    /// Battery, firmware and fault flags.
    Status(UnitStatus),
    /// The transport could not be opened or failed.
    Transport(String),
}

/// Tuning of the worker.
#[derive(Debug, Clone)]
pub struct WorkerSettings {
    /// The link's timing and limits.
    pub link: LinkConfig,
    /// Reconnect backoff.
    pub backoff: Backoff,
    /// Read timeout of the transport: bounds how late a command or timer is served.
    pub io_poll: Duration,
    /// Capacity of the command channel.
    pub command_capacity: usize,
    /// Capacity of the event channel (events beyond it are dropped and counted).
    pub event_capacity: usize,
    /// How long the worker waits for the STOP ALL acknowledgement when shutting down.
    pub shutdown_grace: Duration,
}

impl Default for WorkerSettings {
    fn default() -> Self {
        Self {
            link: LinkConfig::default(),
            backoff: Backoff::default(),
            io_poll: Duration::from_millis(2),
            command_capacity: 32,
            event_capacity: 256,
            shutdown_grace: Duration::from_millis(300),
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
}

struct Shared {
    stop_all: AtomicBool,
    shutdown: AtomicBool,
    dropped_events: AtomicU64,
}

/// The handle the application holds (see the module doc).
pub struct VestHandle {
    commands: SyncSender<VestCommand>,
    events: Receiver<VestEvent>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for VestHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VestHandle").field("running", &self.thread.is_some()).finish_non_exhaustive()
    }
}

impl VestHandle {
    /// Starts the worker for `config`; `waker` is called after each batch of events (e.g. egui's
    /// `request_repaint`).
    pub fn spawn(config: VestConfig, waker: impl Fn() + Send + Sync + 'static) -> io::Result<Self> {
        let settings = WorkerSettings::default();
        let connector: Connector = match config {
            VestConfig::Serial { port, baud } => {
                let poll = settings.io_poll;
                Box::new(move || {
                    let p = crate::serial::open(&port, baud, poll).map_err(io::Error::other)?;
                    Ok(Box::new(p) as Box<dyn Transport>)
                })
            }
            VestConfig::Emulated(engine) => {
                let poll = settings.io_poll;
                Box::new(move || Ok(Box::new(EmulatedPort::new(engine, poll)) as Box<dyn Transport>))
            }
        };
        Self::spawn_with(connector, settings, waker)
    }

    /// Starts the worker on transports from `connector` (tests, other transports).
    pub fn spawn_with(
        connector: Connector,
        settings: WorkerSettings,
        waker: impl Fn() + Send + Sync + 'static,
    ) -> io::Result<Self> {
        let (cmd_tx, cmd_rx) = std::sync::mpsc::sync_channel(settings.command_capacity.max(1));
        let (ev_tx, ev_rx) = std::sync::mpsc::sync_channel(settings.event_capacity.max(1));
        let shared = Arc::new(Shared {
            stop_all: AtomicBool::new(false),
            shutdown: AtomicBool::new(false),
            dropped_events: AtomicU64::new(0),
        });
        let mut worker = Worker {
            link: Link::new(settings.link),
            backoff: settings.backoff,
            settings,
            connector,
            commands: cmd_rx,
            events: ev_tx,
            shared: shared.clone(),
            waker: Box::new(waker),
        };
        let thread =
            std::thread::Builder::new().name("vest-worker".to_owned()).spawn(move || worker.run())?;
        Ok(Self { commands: cmd_tx, events: ev_rx, shared, thread: Some(thread) })
    }

    /// Queues a command without blocking. STOP ALL never fails while the worker runs: it bypasses the queue.
    pub fn send(&self, command: VestCommand) -> Result<(), VestSendError> {
        if self.thread.as_ref().is_none_or(JoinHandle::is_finished) {
            return Err(VestSendError::Stopped);
        }
        if command == VestCommand::StopAll {
            self.shared.stop_all.store(true, Ordering::SeqCst);
            return Ok(());
        }
        self.commands.try_send(command).map_err(|e| match e {
            TrySendError::Full(_) => VestSendError::Full,
            TrySendError::Disconnected(_) => VestSendError::Stopped,
        })
    }

    /// The next event, if any.
    pub fn try_recv(&self) -> Option<VestEvent> {
        self.events.try_recv().ok()
    }

    /// Waits up to `timeout` for the next event.
    pub fn recv_timeout(&self, timeout: Duration) -> Option<VestEvent> {
        self.events.recv_timeout(timeout).ok()
    }

    /// Events dropped because the receiver lagged.
    pub fn dropped_events(&self) -> u64 {
        self.shared.dropped_events.load(Ordering::Relaxed)
    }

    /// Sends STOP ALL, waits briefly for its acknowledgement, closes the port and ends the worker.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.shared.stop_all.store(true, Ordering::SeqCst);
        self.shared.shutdown.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
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
    commands: Receiver<VestCommand>,
    events: SyncSender<VestEvent>,
    shared: Arc<Shared>,
    waker: Box<dyn Fn() + Send + Sync>,
}

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
                    reason: "vest not connected; its watchdog stops every tactor when the link is lost"
                        .to_owned(),
                });
                refused = true;
            }
            while let Ok(cmd) = self.commands.try_recv() {
                self.emit(VestEvent::Rejected { kind: cmd.kind(), reason: "vest not connected".to_owned() });
                refused = true;
            }
            if refused {
                self.wake();
            }
            std::thread::sleep(self.settings.io_poll.min(until.saturating_duration_since(Instant::now())));
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
            if self.shared.stop_all.swap(false, Ordering::SeqCst) {
                self.apply(&VestCommand::StopAll, now);
            }
            loop {
                match self.commands.try_recv() {
                    Ok(cmd) => self.apply(&cmd, Instant::now()),
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
                return SessionEnd::Lost { was_ready };
            }
        }
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
        if self.link.stop_all(start).is_err() {
            return;
        }
        let mut buf = [0u8; 512];
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

    fn apply(&mut self, cmd: &VestCommand, now: Instant) {
        let kind = cmd.kind();
        let result = match cmd {
            VestCommand::Fire { mask, duration_ms } => self.link.fire(*mask, *duration_ms, now),
            VestCommand::Play(p) => self.link.play(p, now),
            VestCommand::SetIntensity { mask, level } => self.link.set_intensity(*mask, *level, now),
            VestCommand::StopAll => self.link.stop_all(now),
            VestCommand::RequestStatus => self.link.request_status(now),
        };
        if let Err(e) = result {
            let reason = match e {
                CommandError::NotReady(_) => format!("vest not ready: {}", self.link.state()),
                e => e.to_string(),
            };
            self.emit(VestEvent::Rejected { kind, reason });
        }
    }

    /// Forwards the link's events; returns whether there were any.
    fn forward_link_events(&mut self) -> bool {
        let mut any = false;
        while let Some(ev) = self.link.poll_event() {
            any = true;
            let event = match ev {
                LinkEvent::State(s) => {
                    let lost = matches!(s, LinkState::Lost { .. });
                    self.emit(VestEvent::State(s));
                    if lost {
                        self.emit(VestEvent::TactorsOn(None));
                    }
                    continue;
                }
                LinkEvent::Identified(info) => VestEvent::Identified(info),
                LinkEvent::TactorsOn(m) => VestEvent::TactorsOn(Some(m)),
                LinkEvent::Acked { seq, kind } => VestEvent::Acked { seq, kind },
                LinkEvent::Rejected { kind, reason, .. } => VestEvent::Rejected {
                    kind,
                    reason: format!("the unit refused {}: {reason}", kind.name()),
                },
                LinkEvent::NotDelivered { kind, .. } => VestEvent::Rejected {
                    kind,
                    reason: format!("{} not acknowledged by the unit", kind.name()),
                },
                LinkEvent::Cancelled { kind, .. } => VestEvent::Rejected {
                    kind,
                    reason: format!("{} cancelled (superseded or stopped)", kind.name()),
                },
                LinkEvent::Status(s) => VestEvent::Status(s),
            };
            self.emit(event);
        }
        any
    }

    fn emit(&self, event: VestEvent) {
        if let Err(TrySendError::Full(_)) = self.events.try_send(event) {
            self.shared.dropped_events.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn wake(&self) {
        (self.waker)();
    }
}

/// The emulated unit as an in-process transport: writes feed the [`Engine`] at the wall-clock time, reads
/// return its replies, waiting at most the read timeout (the engine's timers run inside reads).
#[derive(Debug)]
pub struct EmulatedPort {
    engine: Engine,
    pending: std::collections::VecDeque<u8>,
    read_timeout: Duration,
}

impl EmulatedPort {
    /// A fresh unit built from `config`; reads wait at most `read_timeout`.
    pub fn new(config: EngineConfig, read_timeout: Duration) -> Self {
        Self { engine: Engine::new(config), pending: std::collections::VecDeque::new(), read_timeout }
    }

    /// The unit behind the port.
    pub fn engine(&self) -> &Engine {
        &self.engine
    }
}

impl Read for EmulatedPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let deadline = Instant::now() + self.read_timeout;
        loop {
            let now = Instant::now();
            self.engine.handle_timeout(now);
            while let Some(frame) = self.engine.poll_transmit() {
                self.pending.extend(frame);
            }
            while self.engine.poll_event().is_some() {}
            if !self.pending.is_empty() {
                let n = buf.len().min(self.pending.len());
                for (dst, src) in buf.iter_mut().zip(self.pending.drain(..n)) {
                    *dst = src;
                }
                return Ok(n);
            }
            if now >= deadline {
                return Err(io::Error::new(io::ErrorKind::TimedOut, "no data from the emulated unit"));
            }
            let wake = self.engine.poll_timeout().map_or(deadline, |t| t.min(deadline));
            std::thread::sleep(wake.saturating_duration_since(now).max(Duration::from_micros(100)));
        }
    }
}

impl Write for EmulatedPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.engine.handle_bytes(buf, Instant::now());
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
