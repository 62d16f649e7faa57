//! The emulated WTCU: an [`Engine`] with a simulated compass ([`UnitConfig`]), served on a pseudo-terminal
//! or any `Read + Write`, with the wall clock.
//!
//! This module sits on top of the sans-IO [`Engine`]: the engine knows nothing of it, of ports or of
//! threads, and measures headings through the [`HeadingSensor`](super::engine::HeadingSensor) trait that [`crate::sim::SimulatedCompass`]
//! implements. [`serve`] is the loop (`vestnav emulate vest` runs it on the main thread with a terminal
//! view); [`PtyEmulator`] runs it on a named thread behind a PTY whose slave path a console can open, with
//! controls that tests use to make the unit go out of range or vanish mid-frame.
//!
//! A unit must not stop because nobody listens: when its replies go unread (the PTY buffer is full, a write
//! times out), [`serve`] drops them and counts them in [`EmulatorControl::replies_dropped`] instead of
//! blocking or ending. The leading delimiter of every frame makes a half-written one harmless.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::vest::{TACTOR_COUNT, TactorMask};

use super::codec::{FrameCodec, WireCodec};
use super::engine::{Engine, EngineConfig, EngineEvent, EngineStats};
use super::message::{CommandKind, Faults, Reply};
use crate::serial::is_timeout;
use crate::sim::{CompassSetup, SharedTruth, SimulatedCompass};

/// An emulated unit: the engine's settings and, for protocol v2, the simulated magnetometer it carries.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitConfig {
    /// The protocol side (firmware version, limits, watchdog, the receiver on the second UART).
    pub engine: EngineConfig,
    /// The unit's magnetometer, or none. Only a v2 unit (`engine.protocol_version >= 2`) has one.
    pub compass: Option<CompassSetup>,
    /// The simulated wearer who feels the tactors (the in-process unit tells it every change), if any.
    pub skin: Option<SharedTruth>,
}

impl Default for UnitConfig {
    /// A v2 unit with a typical uncalibrated magnetometer, the wearer standing facing north.
    fn default() -> Self {
        Self { engine: EngineConfig::default(), compass: Some(CompassSetup::default()), skin: None }
    }
}

impl From<EngineConfig> for UnitConfig {
    /// A unit with `engine`'s settings and the default magnetometer (none for a v1 unit).
    fn from(engine: EngineConfig) -> Self {
        Self { engine, ..Self::default() }
    }
}

impl UnitConfig {
    /// The unit's engine, its [`SimulatedCompass`] fitted when it has one.
    pub fn build(&self) -> Engine<FrameCodec> {
        let engine = Engine::new(self.engine.clone());
        match self.compass.as_ref().filter(|_| self.engine.protocol_version >= 2) {
            Some(setup) => engine.with_heading_sensor(Box::new(SimulatedCompass::new(setup))),
            None => engine,
        }
    }
}

/// Read timeout of the serving loop: the worst lateness of a pattern step or the watchdog.
pub const SERVE_POLL: Duration = Duration::from_millis(5);

/// Switches a running emulator reacts to (shared with the thread that serves it).
#[derive(Debug, Default)]
pub struct EmulatorControl {
    /// End the loop.
    pub stop: AtomicBool,
    /// Drop everything received and send nothing, as a unit out of Bluetooth range.
    pub out_of_range: AtomicBool,
    /// Write half a frame, then close the port (the port vanishing mid-frame).
    pub vanish: AtomicBool,
    /// Reply frames dropped (counted by [`serve`]) because the port would not take them in time: nobody is
    /// reading the other side.
    pub replies_dropped: AtomicU64,
}

/// Why [`serve`] returned.
#[derive(Debug)]
pub enum ServeEnd {
    /// [`EmulatorControl::stop`] was set.
    Stopped,
    /// The other side closed (read returned 0 bytes).
    Eof,
    /// [`EmulatorControl::vanish`] was set: half a frame was written and the port dropped.
    Vanished,
}

/// Serves `engine` on `port` (whose reads and writes must time out, e.g. after [`SERVE_POLL`]) until
/// stopped, EOF or a port error. `observe` sees the engine after every event it raises. A write that times
/// out (or would block) is not an error: that frame and the rest of this round's are dropped and counted in
/// [`EmulatorControl::replies_dropped`], so an unread port costs at most one write timeout per round.
pub fn serve<C: WireCodec>(
    engine: &mut Engine<C>,
    port: &mut (impl Read + Write + ?Sized),
    control: &EmulatorControl,
    mut observe: impl FnMut(&Engine<C>, &EngineEvent),
) -> io::Result<ServeEnd> {
    let mut buf = [0u8; 512];
    loop {
        if control.stop.load(Ordering::Relaxed) {
            return Ok(ServeEnd::Stopped);
        }
        if control.vanish.load(Ordering::Relaxed) {
            let frame = FrameCodec::with_max_version(1).encode_reply(
                0xEE,
                &Reply::Report { tactors_on: TactorMask::ALL, faults: Faults::default() },
            );
            let half = frame.get(..frame.len() / 2).unwrap_or(&[]);
            port.write_all(half)?;
            return Ok(ServeEnd::Vanished);
        }
        let muted = control.out_of_range.load(Ordering::Relaxed);
        match port.read(&mut buf) {
            Ok(0) => return Ok(ServeEnd::Eof),
            Ok(n) if !muted => engine.handle_bytes(buf.get(..n).unwrap_or(&[]), Instant::now()),
            Ok(_) => {}
            Err(e) if is_timeout(&e) => {}
            Err(e) => return Err(e),
        }
        engine.handle_timeout(Instant::now());
        // Observers first, so a view never lags behind what the console has already been told.
        while let Some(event) = engine.poll_event() {
            observe(engine, &event);
        }
        let mut dropped = 0u64;
        while let Some(frame) = engine.poll_transmit() {
            if muted {
                continue;
            }
            if dropped > 0 {
                dropped += 1;
                continue;
            }
            match port.write_all(&frame) {
                Ok(()) => {}
                Err(e) if is_timeout(&e) => dropped += 1,
                Err(e) => return Err(e),
            }
        }
        if dropped > 0 {
            control.replies_dropped.fetch_add(dropped, Ordering::Relaxed);
        }
    }
}

/// What a running emulator shows: the unit's state and a short history, for views and test assertions.
#[derive(Debug, Clone, Default)]
pub struct EmulatorView {
    /// Tactors on now.
    pub tactors_on: TactorMask,
    /// Drive level per tactor.
    pub intensity: [u8; TACTOR_COUNT],
    /// Counters.
    pub stats: EngineStats,
    /// Fault flags.
    pub faults: Faults,
    /// Whether a console said HELLO.
    pub identified: bool,
    /// When the last valid frame from the console arrived.
    pub last_rx: Option<Instant>,
    /// The last 256 changes of the running tactors, with their time.
    pub changes: VecDeque<(Instant, TactorMask)>,
    /// The last 64 events, in words.
    pub log: VecDeque<String>,
    /// How many commands of each kind the unit accepted since it started (sequence numbers wrap at 256:
    /// these do not).
    pub accepted: std::collections::HashMap<CommandKind, u64>,
}

impl EmulatorView {
    /// Updates the view from `engine` after `event`.
    pub fn observe<C: WireCodec>(&mut self, engine: &Engine<C>, event: &EngineEvent) {
        self.tactors_on = engine.tactors_on();
        self.intensity = engine.intensity();
        self.stats = engine.stats();
        self.faults = engine.faults();
        self.identified = engine.identified();
        self.last_rx = engine.last_rx();
        if let EngineEvent::TactorsChanged(mask) = event {
            if self.changes.len() >= 256 {
                self.changes.pop_front();
            }
            self.changes.push_back((Instant::now(), *mask));
        }
        if let EngineEvent::Accepted { kind, .. } = event {
            *self.accepted.entry(*kind).or_default() += 1;
        }
        if self.log.len() >= 64 {
            self.log.pop_front();
        }
        self.log.push_back(describe(event));
    }
}

/// One line describing an engine event.
pub fn describe(event: &EngineEvent) -> String {
    match event {
        EngineEvent::SessionStarted => "console said hello".to_owned(),
        EngineEvent::TactorsChanged(m) => format!("on: {:?}", m.indices().collect::<Vec<_>>()),
        EngineEvent::Accepted { seq, kind } => format!("#{seq} {} accepted", kind.name()),
        EngineEvent::Rejected { seq, reason, detail } => match seq {
            Some(s) => format!("#{s} NAK {reason}: {detail}"),
            None => format!("NAK {reason}: {detail}"),
        },
        EngineEvent::WatchdogTripped => "watchdog: console silent, everything stopped".to_owned(),
        EngineEvent::Dropped(e) => format!("dropped: {e}"),
    }
}

/// The one PTY wrapper (`crate::serial::Pty`); a unit is served on a master opened with
/// `Pty::open_with_timeout(SERVE_POLL)`.
#[cfg(unix)]
pub use crate::serial::Pty;

/// An emulated unit on its own thread behind a pseudo-terminal (Unix only).
#[derive(Debug)]
pub struct PtyEmulator {
    path: String,
    view: Arc<Mutex<EmulatorView>>,
    control: Arc<EmulatorControl>,
    thread: Option<JoinHandle<io::Result<ServeEnd>>>,
}

impl PtyEmulator {
    /// Opens a PTY pair and serves a unit built from `config` on the master side; consoles open
    /// [`Self::path`]. The emulator keeps its own handle on the slave so consoles may come and go.
    #[cfg(unix)]
    pub fn spawn(config: impl Into<UnitConfig>) -> io::Result<Self> {
        let config = config.into();
        let Pty { mut master, path, slave } = Pty::open_with_timeout(SERVE_POLL)?;
        let view = Arc::new(Mutex::new(EmulatorView::default()));
        let control = Arc::new(EmulatorControl::default());
        let (v, c) = (view.clone(), control.clone());
        let thread = std::thread::Builder::new().name("vest-emulator".to_owned()).spawn(move || {
            let _slave = slave;
            let mut engine = config.build();
            serve(&mut engine, &mut master, &c, |engine, event| {
                v.lock().unwrap_or_else(PoisonError::into_inner).observe(engine, event);
            })
        })?;
        Ok(Self { path, view, control, thread: Some(thread) })
    }

    /// The slave path a console opens (`/dev/pts/N`).
    pub fn path(&self) -> &str {
        &self.path
    }

    /// A snapshot of the unit.
    pub fn view(&self) -> EmulatorView {
        self.view.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }

    /// Reply frames dropped so far because nobody read them (see [`EmulatorControl::replies_dropped`]).
    pub fn replies_dropped(&self) -> u64 {
        self.control.replies_dropped.load(Ordering::Relaxed)
    }

    /// Whether the serving thread is still running.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Makes the unit deaf and mute (out of range) or brings it back.
    pub fn set_out_of_range(&self, out: bool) {
        self.control.out_of_range.store(out, Ordering::Relaxed);
    }

    /// Writes half a frame and closes the PTY; returns how the loop ended.
    pub fn vanish_mid_frame(mut self) -> io::Result<ServeEnd> {
        self.control.vanish.store(true, Ordering::Relaxed);
        self.join()
    }

    /// Stops the unit and closes the PTY.
    pub fn shutdown(mut self) -> io::Result<ServeEnd> {
        self.control.stop.store(true, Ordering::Relaxed);
        self.join()
    }

    fn join(&mut self) -> io::Result<ServeEnd> {
        match self.thread.take() {
            Some(t) => t.join().map_err(|_| io::Error::other("emulator thread panicked"))?,
            None => Ok(ServeEnd::Stopped),
        }
    }
}

impl Drop for PtyEmulator {
    fn drop(&mut self) {
        self.control.stop.store(true, Ordering::Relaxed);
        let _ = self.join();
    }
}
