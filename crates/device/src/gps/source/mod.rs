//! GPS sources on worker threads, all producing the same [`GpsEvent`] stream.
//!
//! [`GpsSource::spawn`] starts one named worker thread that owns one transport and one decoder; every event
//! goes to every consumer's [`Outbox`] (a bounded channel with its own overflow policy and waker: the GUI
//! drops what it cannot draw, a CLI or a file writer waits). A stop request always wins: a worker waiting
//! on a full lossless consumer gives up at once, every blocking read has a short timeout, and
//! [`GpsHandle::stop`] never waits more than [`STOP_WAIT`] for the thread (a thread stuck in DNS or in
//! `connect` is detached and ends by itself). Each source reports its [`SourceState`]; serial and gpsd
//! sources reconnect with exponential backoff (0.5 s doubling to 8 s) until stopped.
//!
//! Input is hostile until checked: the gpsd transport frames lines itself with a bounded buffer
//! ([`super::gpsd::LineFramer`], [`super::gpsd::MAX_LINE_LEN`]) so memory stays bounded whatever a server
//! sends, and every fix is checked by [`super::Fix::validate`] before it is sent.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::GnssErrorModel;

use super::receiver_config::{ConfigReporter, ConfigTicket, ReceiverConfig};
use super::{GpsEvent, NmeaDecoder};
use crate::outbox::{Outbox, Overflow, Waker};

#[cfg(test)]
mod control_tests;
mod corrections;
mod gpsd;
mod replay;
mod serial;
mod simulator;
mod spec;
#[cfg(test)]
mod tests;
mod through_vest;

pub use corrections::{CorrectionsWriter, PORT_NOT_OPEN};
pub use replay::{ReplayControl, ReplayProgress, replay_lines};
pub use serial::{detect_baud, score_baud};
pub use spec::{
    DEFAULT_VEST_GPS_BAUD, GPS_SPEC_FORMS, GpsSourceSpec, MAX_REPLAY_SPEED, ReplaySpeed, SERIAL_BAUDS,
    SpecError,
};

use gpsd::run_gpsd;
use replay::run_replay;
use serial::run_serial;
use simulator::{SimParams, run_sim};
use through_vest::run_through_vest;

/// Bauds tried by automatic detection, most likely first (`SiRF` III default 4800, u-blox 9600/38400).
pub const DETECT_BAUDS: [u32; 6] = [4800, 9600, 38400, 115_200, 19200, 57600];
/// No data (for gpsd: no complete line) for this long on a live link: the source is stale.
pub const STALE_AFTER: Duration = Duration::from_secs(3);
/// No data (for gpsd: no complete line) for this long: the link is treated as lost and reopened.
pub const LOST_AFTER: Duration = Duration::from_secs(10);
/// Read timeout of the gpsd socket: the stop flag and the stale/lost timers are checked at least this
/// often, even while a server trickles bytes without a line end.
pub const GPSD_READ_TIMEOUT: Duration = Duration::from_millis(50);
/// The longest [`GpsHandle::stop`] waits for the worker thread before detaching it.
pub const STOP_WAIT: Duration = Duration::from_millis(250);

/// Where fixes come from, as a running source needs it: [`GpsSourceSpec`] (what the operator names) plus
/// what exists only at run time (the loaded route, the simulator's settings, the vest's byte pipe).
#[derive(Debug, Clone, PartialEq)]
pub enum SourceConfig {
    /// A serial port (USB, Bluetooth SPP `/dev/rfcomm*`, a PTY); `baud: None` detects it.
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate, or `None` for automatic detection.
        baud: Option<u32>,
    },
    /// An NMEA log or recording replayed in time.
    Replay {
        /// The file.
        path: PathBuf,
        /// How fast.
        speed: ReplaySpeed,
    },
    /// A gpsd daemon's JSON stream.
    Gpsd {
        /// Host name or address (gpsd default 127.0.0.1).
        host: String,
        /// TCP port (gpsd default 2947).
        port: u16,
    },
    /// The built-in simulated receiver walking a route.
    Simulator {
        /// Waypoints (lat, lon) [deg].
        route: Vec<(f64, f64)>,
        /// Walking pace [m/s].
        pace_m_s: f64,
        /// Receiver error model.
        model: GnssErrorModel,
        /// Random seed.
        seed: u64,
        /// Time between epochs (1 s for a 1 Hz receiver); the simulator runs in real time.
        period: Duration,
        /// At the end of the route, start over (with seed `seed + lap`, so each lap has a different error
        /// realisation) and send a [`GpsEvent::Notice`] instead of [`SourceState::Finished`].
        looped: bool,
        /// Where to publish the walker's true position, course and pace every epoch (for an emulated vest's
        /// compass to measure the same wearer), if anywhere.
        truth: Option<crate::sim::SharedTruth>,
    },
    /// The receiver on the vest unit's second UART, forwarded inside the vest's link (protocol v2): its
    /// bytes come from the vest worker through this pipe.
    ThroughVest {
        /// The pipe from the vest worker.
        reader: super::through_vest::VestGpsReader,
        /// The receiver's baud rate on the unit's UART (one of `wtcu::message::GPS_BAUDS`).
        baud: u32,
    },
}

/// A source's connection state.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SourceState {
    /// Opening the port / connecting / detecting the baud rate.
    Connecting {
        /// What is being tried (e.g. "/dev/rfcomm0 at 4800 baud").
        detail: String,
    },
    /// Data is flowing.
    Live {
        /// E.g. the baud rate found.
        detail: String,
    },
    /// Connected but no data for [`STALE_AFTER`].
    Stale,
    /// The link failed.
    Lost {
        /// Why.
        reason: String,
    },
    /// Waiting before the next connection attempt.
    Reconnecting {
        /// Attempt number (1 = first retry).
        attempt: u32,
        /// Wait before it [ms].
        delay_ms: u64,
    },
    /// A replay reached the end of its file, or the simulator its route.
    Finished,
    /// Stopped on request.
    Stopped,
}

/// The controller of a running source (its events go to the consumers' channels, not through here).
#[derive(Debug)]
pub struct GpsHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    replay: Option<Arc<ReplayControl>>,
    config: Result<std::sync::mpsc::Sender<ConfigRequest>, &'static str>,
    /// The serial port's write handle while it is open (serial sources only).
    port: Option<Arc<corrections::PortSlot>>,
}

/// Why a source cannot take corrections (the operator sees this text).
pub const CORRECTIONS_NEED_SERIAL: &str = "RTK corrections need a direct serial connection to the receiver (gpsd, a replay, the simulator or the \
     receiver behind the vest cannot take them)";

/// A receiver configuration on its way to a serial source's worker, with where to report.
#[derive(Debug)]
pub(crate) struct ConfigRequest {
    pub(crate) config: ReceiverConfig,
    pub(crate) reporter: ConfigReporter,
}

/// Why a source cannot configure its receiver (the operator sees this text).
pub const CONFIG_NEEDS_SERIAL: &str = "configuration needs a direct serial connection to the receiver";

impl GpsHandle {
    /// The pause/seek/progress controls of a [`SourceConfig::Replay`] source (`None` for the others).
    pub fn replay_control(&self) -> Option<Arc<ReplayControl>> {
        self.replay.clone()
    }

    /// Sends `config` to the receiver (serial sources only: the worker writes the commands between reads
    /// and decides each from the receiver's replies). The ticket reports each command's outcome, then
    /// [`super::receiver_config::ConfigEvent::Finished`]; each outcome is also sent to the consumers as a [`GpsEvent::Notice`].
    /// Other sources say why they cannot (gpsd owns its device: use gpsctl/ubxtool there).
    pub fn configure(&self, config: ReceiverConfig) -> Result<ConfigTicket, String> {
        let tx = self.config.as_ref().map_err(|why| (*why).to_owned())?;
        config.validate().map_err(|e| e.to_string())?;
        let (reporter, ticket) = ConfigTicket::channel();
        tx.send(ConfigRequest { config, reporter }).map_err(|_| "the GPS source has stopped".to_owned())?;
        Ok(ticket)
    }

    /// A writer to the receiver's port for RTK corrections (serial sources only): it follows the port
    /// across reconnections, and says [`PORT_NOT_OPEN`] while the port is closed. Writing through it never
    /// waits for the source's reading (see the `corrections` module).
    pub fn corrections_writer(&self) -> Result<CorrectionsWriter, String> {
        self.port.clone().map(CorrectionsWriter).ok_or_else(|| CORRECTIONS_NEED_SERIAL.to_owned())
    }

    /// True while the worker runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Asks the worker to stop, without waiting.
    pub fn request_stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Stops the worker: sets the stop flag and waits for the thread at most [`STOP_WAIT`]. A worker stuck
    /// in a call that cannot be interrupted (DNS resolution, a TCP connect of up to 2 s) is detached and
    /// ends by itself; it sends nothing more once it sees the flag.
    pub fn stop(&mut self) {
        self.request_stop();
        let Some(t) = self.thread.take() else { return };
        let end = Instant::now() + STOP_WAIT;
        while !t.is_finished() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(2));
        }
        if t.is_finished() {
            let _ = t.join();
        }
    }
}

impl Drop for GpsHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Starts sources.
#[derive(Debug)]
pub struct GpsSource;

struct Worker {
    outputs: Vec<Outbox<GpsEvent>>,
    stop: Arc<AtomicBool>,
}

impl Worker {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Sends an event to every consumer (waiting for a lossless one until stopped); false when a stop was
    /// requested or every consumer is gone.
    fn send(&self, ev: GpsEvent) -> bool {
        if self.stopped() {
            return false;
        }
        let Some((last, rest)) = self.outputs.split_last() else { return false };
        let mut alive = false;
        for o in rest {
            alive |= o.send(ev.clone(), &self.stop);
        }
        alive |= last.send(ev, &self.stop);
        alive && !self.stopped()
    }

    fn state(&self, s: SourceState) -> bool {
        self.send(GpsEvent::State(s))
    }

    fn drain(&self, d: &mut NmeaDecoder) -> bool {
        while let Some(ev) = d.poll_event() {
            if !self.send(ev) {
                return false;
            }
        }
        true
    }

    /// Sleeps up to `d`, waking early on stop; false if stopped.
    fn sleep(&self, d: Duration) -> bool {
        let end = Instant::now() + d;
        while Instant::now() < end {
            if self.stopped() {
                return false;
            }
            std::thread::sleep((end - Instant::now()).min(Duration::from_millis(20)));
        }
        !self.stopped()
    }

    /// Before reconnect attempt `attempt` (0 = the first connection, no wait): reports `Reconnecting` and
    /// sleeps the backoff delay. False when the source was stopped meanwhile.
    fn back_off(&self, attempt: u32) -> bool {
        if attempt == 0 {
            return true;
        }
        let delay = backoff(attempt);
        self.state(SourceState::Reconnecting { attempt, delay_ms: delay.as_millis() as u64 })
            && self.sleep(delay)
    }
}

/// The sources' reconnect backoff: 0.5 s doubling, capped at 8 s (a GPS coming back into Bluetooth range,
/// a restarted gpsd).
pub const RECONNECT: crate::backoff::Backoff =
    crate::backoff::Backoff::new(Duration::from_millis(500), Duration::from_secs(8));

/// Reconnection delay for attempt `n` (1-based): [`RECONNECT`]'s delay before that retry.
pub fn backoff(attempt: u32) -> Duration {
    RECONNECT.delay_for_retry(attempt)
}

impl GpsSource {
    /// Starts a worker thread for `config`; every event goes to every one of `outputs` (each with its own
    /// overflow policy and waker). With no outputs the worker ends at once. The last event is
    /// [`SourceState::Stopped`], handed over only where there is room (it never waits).
    pub fn spawn(config: SourceConfig, outputs: Vec<Outbox<GpsEvent>>) -> std::io::Result<GpsHandle> {
        let stop = Arc::new(AtomicBool::new(false));
        let worker = Worker { outputs, stop: stop.clone() };
        let replay =
            matches!(config, SourceConfig::Replay { .. }).then(|| Arc::new(ReplayControl::default()));
        let ctl = replay.clone();
        let port =
            matches!(config, SourceConfig::Serial { .. }).then(|| Arc::new(corrections::PortSlot::default()));
        let slot = port.clone();
        let (config_tx, config_rx) = std::sync::mpsc::channel::<ConfigRequest>();
        let config_path = match &config {
            SourceConfig::Serial { .. } => Ok(config_tx),
            SourceConfig::Gpsd { .. } => Err("gpsd owns the receiver: configure it with gpsctl or ubxtool, \
                 or connect the console to the serial port directly (configuration needs a direct serial \
                 connection)"),
            SourceConfig::ThroughVest { .. } => Err(
                "the receiver behind the vest unit is read-only here (configuration needs a direct serial connection)",
            ),
            SourceConfig::Replay { .. } => Err("a replay has no receiver to configure"),
            SourceConfig::Simulator { .. } => Err(
                "the built-in simulator has no receiver to configure (use `vestnav emulate gps` on a PTY)",
            ),
        };
        let name = match &config {
            SourceConfig::Serial { .. } => "gps-serial",
            SourceConfig::Replay { .. } => "gps-replay",
            SourceConfig::Gpsd { .. } => "gps-gpsd",
            SourceConfig::Simulator { .. } => "gps-sim",
            SourceConfig::ThroughVest { .. } => "gps-vest",
        };
        let thread = std::thread::Builder::new().name(name.into()).spawn(move || {
            match config {
                SourceConfig::Serial { port, baud } => {
                    run_serial(
                        &worker,
                        &port,
                        baud,
                        &config_rx,
                        slot.as_deref().unwrap_or(&corrections::PortSlot::default()),
                    );
                }
                SourceConfig::Replay { path, speed } => {
                    run_replay(&worker, &path, speed, ctl.as_deref().unwrap_or(&ReplayControl::default()));
                }
                SourceConfig::Gpsd { host, port } => run_gpsd(&worker, &host, port),
                SourceConfig::Simulator { route, pace_m_s, model, seed, period, looped, truth } => {
                    let p = SimParams { route: &route, pace_m_s, model, seed, period, looped, truth };
                    run_sim(&worker, &p);
                }
                SourceConfig::ThroughVest { reader, baud } => run_through_vest(&worker, &reader, baud),
            }
            for o in &worker.outputs {
                o.try_send(GpsEvent::State(SourceState::Stopped));
            }
        })?;
        Ok(GpsHandle { stop, thread: Some(thread), replay, config: config_path, port })
    }

    /// Starts a source with one lossless consumer: a channel of `capacity` events with
    /// [`Overflow::Wait`] (the worker waits for the consumer, until stopped). For the CLI and tests.
    pub fn spawn_channel(
        config: SourceConfig,
        capacity: usize,
        waker: Option<Waker>,
    ) -> std::io::Result<(GpsHandle, Receiver<GpsEvent>)> {
        let (out, rx) = Outbox::channel(capacity, Overflow::Wait, waker);
        Ok((Self::spawn(config, vec![out])?, rx))
    }
}
