//! The console's own view of the devices: what the workers report and what the UI asks of them.
//!
//! The device crate's types are converted into these at the edge ([`crate::devices`]), so every panel, the
//! session log and the tests speak one small vocabulary.

use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{Pattern, TactorMask};

/// Fix mode, as NMEA GSA reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum FixMode {
    /// No position.
    #[default]
    NoFix,
    /// Latitude and longitude only.
    Fix2d,
    /// Latitude, longitude and altitude.
    Fix3d,
}

/// One satellite for the sky plot and the signal bars.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Satellite {
    /// PRN / satellite id.
    pub prn: u16,
    /// Elevation above the horizon [deg], if known.
    pub elevation_deg: Option<f64>,
    /// Azimuth from true north, clockwise [deg], if known.
    pub azimuth_deg: Option<f64>,
    /// Carrier-to-noise ratio [dB-Hz], if tracked.
    pub snr_db: Option<f64>,
    /// Whether it is used in the solution.
    pub used: bool,
}

/// One position epoch as the console shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct GpsFix {
    /// UTC time of the fix as ISO-8601 text, if the receiver sent one.
    pub time_utc: Option<String>,
    /// Latitude [deg], WGS-84.
    pub lat_deg: f64,
    /// Longitude [deg], WGS-84.
    pub lon_deg: f64,
    /// Altitude above mean sea level [m].
    pub alt_m: Option<f64>,
    /// Fix mode.
    pub mode: FixMode,
    /// Fix quality text (GPS, DGPS, RTK, estimated, simulated...).
    pub quality: String,
    /// Satellites used in the solution.
    pub sats_used: Option<u32>,
    /// Satellites in view.
    pub sats_visible: Option<u32>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Position dilution of precision.
    pub pdop: Option<f64>,
    /// Estimated horizontal error (about 1 sigma) [m].
    pub error_m: Option<f64>,
    /// Speed over ground [m/s].
    pub speed_m_s: Option<f64>,
    /// Course over ground, true [deg].
    pub course_deg: Option<f64>,
    /// The sky, when the receiver reported it.
    pub satellites: Vec<Satellite>,
}

impl GpsFix {
    /// Whether the fix carries a usable position.
    pub fn has_position(&self) -> bool {
        self.mode != FixMode::NoFix && self.lat_deg.is_finite() && self.lon_deg.is_finite()
    }
}

/// State of a device link, as shown in the top bar.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum LinkState {
    /// Not connected and not trying.
    #[default]
    Disconnected,
    /// Opening the port / handshaking; `attempt` counts reconnection attempts (1 = first).
    Connecting {
        /// Attempt number.
        attempt: u32,
    },
    /// Connected and data flowing.
    Live,
    /// Connected but nothing new for longer than expected.
    Stale,
    /// The link dropped; the worker retries after a backoff.
    Lost {
        /// Why, in words.
        reason: String,
    },
}

impl LinkState {
    /// Short label for the top bar.
    pub fn label(&self) -> String {
        match self {
            Self::Disconnected => "disconnected".to_owned(),
            Self::Connecting { attempt } if *attempt <= 1 => "connecting".to_owned(),
            Self::Connecting { attempt } => format!("reconnecting (attempt {attempt})"),
            Self::Live => "live".to_owned(),
            Self::Stale => "stale".to_owned(),
            Self::Lost { reason } => format!("lost: {reason}"),
        }
    }
}

/// What the GPS worker reports.
#[derive(Debug, Clone, PartialEq)]
pub enum GpsEvent {
    /// The link changed state.
    State(LinkState),
    /// A new epoch.
    Fix(GpsFix),
    /// Something the operator should read (bad checksums, file ended...).
    Notice(String),
}

/// A command for the vest worker.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum VestCommand {
    /// Fire these tactors for `on_ms`.
    Fire {
        /// Tactors to fire.
        mask: TactorMask,
        /// On-time [ms].
        on_ms: u16,
    },
    /// Play a timed pattern.
    Play(Pattern),
    /// Stop every tactor now.
    StopAll,
}

impl VestCommand {
    /// A short human description ("fire [0 3] 500 ms", "play 'turn left' (4 frames, x1)", "STOP ALL").
    pub fn describe(&self) -> String {
        match self {
            Self::Fire { mask, on_ms } => {
                let idx: Vec<String> = mask.indices().map(|i| i.to_string()).collect();
                format!("fire [{}] {on_ms} ms", idx.join(" "))
            }
            Self::Play(p) => format!("play '{}' ({} frames, x{})", p.name, p.frames.len(), p.repeats),
            Self::StopAll => "STOP ALL".to_owned(),
        }
    }
}

/// Who asked for a vest command (for the log and the override rule).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CommandOrigin {
    /// The operator, by hand.
    Manual,
    /// Automatic guidance.
    Guidance,
}

/// What the vest worker reports.
#[derive(Debug, Clone, PartialEq)]
pub enum VestEvent {
    /// The link changed state.
    State(LinkState),
    /// The tactors the unit says are on now (from its acks/status, not from what we sent).
    TactorsOn(TactorMask),
    /// A command was acknowledged by the unit.
    Ack {
        /// What was acknowledged, in words.
        what: String,
    },
    /// The unit refused or the link failed to deliver a command.
    Rejected {
        /// Why, in words.
        reason: String,
    },
    /// Something the operator should read (transport errors, identification).
    Notice(String),
    /// Battery / firmware status.
    Status {
        /// Battery charge [%], if reported.
        battery_pct: Option<u8>,
        /// Firmware version text.
        firmware: String,
    },
}

/// A bounded sender that never blocks: when the receiver lags, the newest message is dropped and counted.
#[derive(Debug)]
pub struct Outbox<T> {
    tx: SyncSender<T>,
    dropped: std::sync::Arc<std::sync::atomic::AtomicU64>,
    waker: Option<egui::Context>,
}

impl<T> Clone for Outbox<T> {
    fn clone(&self) -> Self {
        Self { tx: self.tx.clone(), dropped: self.dropped.clone(), waker: self.waker.clone() }
    }
}

impl<T> Outbox<T> {
    /// Wraps `tx`; `waker` (the UI's context) is asked to repaint after each message.
    pub fn new(tx: SyncSender<T>, waker: Option<egui::Context>) -> Self {
        Self { tx, dropped: std::sync::Arc::default(), waker }
    }

    /// Sends without blocking; returns `false` if the receiver is gone.
    pub fn send(&self, msg: T) -> bool {
        let alive = match self.tx.try_send(msg) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.dropped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        };
        if let Some(ctx) = &self.waker {
            ctx.request_repaint();
        }
        alive
    }

    /// Sends, waiting while the channel is full (back-pressure for producers that must not lose data and
    /// whose consumer is a worker thread, never the UI); returns `false` if the receiver is gone.
    pub fn send_wait(&self, msg: T) -> bool {
        let alive = self.tx.send(msg).is_ok();
        if let Some(ctx) = &self.waker {
            ctx.request_repaint();
        }
        alive
    }

    /// Messages dropped because the receiver lagged.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// Drains `rx` into `handle` until it is empty or `budget` has elapsed; returns how many were handled.
///
/// The budget keeps one frame short when a worker floods the channel: the rest waits for the next frame.
pub fn drain_within<T>(rx: &Receiver<T>, budget: Duration, mut handle: impl FnMut(T)) -> usize {
    let start = Instant::now();
    let mut n = 0;
    while let Ok(msg) = rx.try_recv() {
        handle(msg);
        n += 1;
        if n % 64 == 0 && start.elapsed() > budget {
            break;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outbox_drops_instead_of_blocking() {
        let (tx, rx) = std::sync::mpsc::sync_channel(2);
        let out = Outbox::new(tx, None);
        for i in 0..5 {
            assert!(out.send(i));
        }
        assert_eq!(out.dropped(), 3);
        let mut got = Vec::new();
        drain_within(&rx, Duration::from_millis(5), |m| got.push(m));
        assert_eq!(got, vec![0, 1]);
        drop(rx);
        assert!(!out.send(9));
    }
}
