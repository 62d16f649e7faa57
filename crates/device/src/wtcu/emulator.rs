//! The emulated WTCU: the [`Engine`] served on a pseudo-terminal or any `Read + Write`, with the wall clock.
//!
//! [`serve`] is the loop (`vestnav emulate vest` runs it on the main thread with a terminal view);
//! [`PtyEmulator`] runs it on a named thread behind a PTY whose slave path a console can open, with controls
//! that tests use to make the unit go out of range or vanish mid-frame.
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

use chrono::Datelike as _;
use vestnav_core::compass::{MagnetometerModel, MagnetometerSim, SensorPose, SteelObject};
use vestnav_core::geo::LatLon;

use crate::heading::SharedTruth;

use super::codec::WireCodec;
use super::engine::{Engine, EngineConfig, EngineEvent, EngineStats, HeadingSensor};
use super::message::{Faults, Reply};

/// How the emulated wearer's body moves: the truth the emulated magnetometer measures.
#[derive(Debug, Clone, PartialEq)]
pub enum WearerMotion {
    /// Standing, facing `heading_deg` (true).
    Still {
        /// True heading \[deg\].
        heading_deg: f64,
    },
    /// Turning in place at `rate_deg_s` from `start_deg` (true): a calibration rotation.
    Turning {
        /// True heading at the start \[deg\].
        start_deg: f64,
        /// Turn rate, clockwise positive \[deg/s\].
        rate_deg_s: f64,
    },
    /// Where the GPS simulator's walker is and faces (the console's simulated wearer): one wearer for both
    /// simulated devices. Standing facing north until the simulator's first epoch.
    Follow(SharedTruth),
}

impl WearerMotion {
    /// The wearer's pose after `t_s` seconds on the unit's clock.
    pub fn pose(&self, t_s: f64) -> SensorPose {
        let standing =
            |heading_true_deg| SensorPose { t_s, heading_true_deg, east_m: 0.0, north_m: 0.0, pace_m_s: 0.0 };
        match self {
            Self::Still { heading_deg } => standing(*heading_deg),
            Self::Turning { start_deg, rate_deg_s } => {
                standing((start_deg + rate_deg_s * t_s).rem_euclid(360.0))
            }
            Self::Follow(cell) => cell.get().map_or_else(
                || standing(0.0),
                |b| SensorPose {
                    t_s,
                    heading_true_deg: b.heading_true_deg,
                    east_m: b.east_m,
                    north_m: b.north_m,
                    pace_m_s: b.pace_m_s,
                },
            ),
        }
    }
}

/// The emulated unit's magnetometer (protocol v2): which sensor, where, and how the wearer moves.
#[derive(Debug, Clone, PartialEq)]
pub struct CompassSetup {
    /// How the wearer moves.
    pub motion: WearerMotion,
    /// A parked car (a steel dipole of 30 µT m³) this far east of the wearer \[m\], if any: within 1–2 m
    /// it turns the heading by tens of degrees and lowers the quality figure.
    pub steel_east_m: Option<f64>,
    /// An ideal sensor (no iron, no noise) instead of a typical uncalibrated vest unit.
    pub ideal: bool,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Default for CompassSetup {
    fn default() -> Self {
        Self { motion: WearerMotion::Still { heading_deg: 0.0 }, steel_east_m: None, ideal: false, seed: 1 }
    }
}

/// Where the emulated wearer stands: the demo route's start by the MIT campus (42.3562° N, 71.1000° W).
/// The World Magnetic Model field there is what the emulated sensor measures.
pub const EMULATED_PLACE: (f64, f64) = (42.3562, -71.1000);

/// The emulated unit's magnetometer and accelerometer: `vestnav_core::compass`'s sensor model (hard and
/// soft iron, noise, the WMM field at [`EMULATED_PLACE`] on today's date, steel) seeing a wearer who moves
/// as [`CompassSetup::motion`] says, on the unit's clock.
#[derive(Debug)]
pub struct SimulatedCompass {
    sim: MagnetometerSim,
    motion: WearerMotion,
    start: Option<Instant>,
}

impl SimulatedCompass {
    /// The sensor for `setup`. The WMM has no model for dates it does not cover; then the field of the
    /// model's epoch at the place is used.
    pub fn new(setup: &CompassSetup) -> Self {
        let mut model =
            if setup.ideal { MagnetometerModel::ideal() } else { MagnetometerModel::typical_vest() };
        if let Some(east_m) = setup.steel_east_m {
            model.steel.push(SteelObject { east_m, north_m: 0.0, moment_ut_m3: 30.0 });
        }
        let place = LatLon::new(EMULATED_PLACE.0, EMULATED_PLACE.1);
        let today = chrono::Utc::now().date_naive();
        let date = (today.year(), today.month() as u8, today.day() as u8);
        let sim = MagnetometerSim::new(model.clone(), place, 0.0, date, setup.seed)
            .or_else(|_| MagnetometerSim::new(model.clone(), place, 0.0, (2025, 1, 1), setup.seed))
            // Boston's field (WMM2025): 14.3 µT north, -4.2 µT east, 47.9 µT down.
            .unwrap_or_else(|_| MagnetometerSim::with_field(model, [18.9, -5.1, 47.0], setup.seed));
        Self { sim, motion: setup.motion.clone(), start: None }
    }

    /// Declination of the emulated place's field, east positive \[deg\].
    pub fn declination_deg(&self) -> f64 {
        self.sim.declination_deg()
    }
}

impl HeadingSensor for SimulatedCompass {
    fn sample(&mut self, at: Instant) -> ([f64; 3], [f64; 3]) {
        let start = *self.start.get_or_insert(at);
        let t_s = at.saturating_duration_since(start).as_secs_f64();
        let s = self.sim.sample(&self.motion.pose(t_s));
        (s.raw_mag_body_ut, s.accel_body_m_s2)
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
            let frame = super::codec::FrameCodec::with_max_version(1).encode_reply(
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

/// Whether a read error only means "nothing yet".
pub fn is_timeout(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted)
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
    pub fn spawn(config: EngineConfig) -> io::Result<Self> {
        let Pty { mut master, path, slave } = Pty::open_with_timeout(SERVE_POLL)?;
        let view = Arc::new(Mutex::new(EmulatorView::default()));
        let control = Arc::new(EmulatorControl::default());
        let (v, c) = (view.clone(), control.clone());
        let thread = std::thread::Builder::new().name("vest-emulator".to_owned()).spawn(move || {
            let _slave = slave;
            let mut engine = Engine::new(config);
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
