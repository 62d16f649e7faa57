//! The station's lab outputs: Lab Streaming Layer (LSL) streams and Open Sound Control (OSC) messages, so a
//! lab records the vest, the wearer's position and a study's events on one clock with its other
//! instruments (EEG, eye tracking, motion capture).
//!
//! - LSL (through `vestnav-lsl`: liblsl found at run time): a marker stream (`<prefix>-markers`, type
//!   `Markers`, one string channel, irregular rate) and data streams `<prefix>-position` (lat, lon, `h_acc`;
//!   double64), `<prefix>-heading` (deg; double64) and `<prefix>-vest` (string: the commands sent to the vest
//!   and the unit's acknowledgements and refusals). Every sample carries the timestamp its caller gave, on
//!   liblsl's clock ([`LabOutputs::now`]).
//! - OSC over UDP (`osc`): `/vestnav/marker s`, `/vestnav/position ddd`, `/vestnav/heading f`,
//!   `/vestnav/vest s`.
//!
//! Callers never wait: each call stamps nothing itself (the caller's `at` is the time), puts one item in a
//! bounded queue (full: dropped and counted) and returns; the `vestnav-lab` thread owns the outlets and the
//! socket and does the pushing. The station feeds the data streams itself (`wiring`); a study runner emits
//! the markers (vocabulary in `docs/study.md`).

mod osc;
mod wiring;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
pub use vestnav_lsl::{INSTALL_HINT, Lsl, LslError, LslMissing};
pub use wiring::LabTap;

/// Items the lab thread may hold before callers' items are dropped (counted in [`LabStatus::dropped`]).
pub const QUEUE: usize = 4096;
/// How long [`LabOutputs::start`] waits for the lab thread to open its outlets.
const START_TIMEOUT: Duration = Duration::from_secs(10);

/// Which lab outputs to run.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LabConfig {
    /// LSL streams on.
    pub lsl: bool,
    /// Where OSC messages go (`None`: no OSC).
    pub osc: Option<SocketAddr>,
    /// The first part of every stream's name and source id, e.g. the station's name.
    pub stream_prefix: String,
}

impl Default for LabConfig {
    fn default() -> Self {
        Self { lsl: false, osc: None, stream_prefix: "vestnav".to_owned() }
    }
}

impl LabConfig {
    /// Whether any output is asked for.
    pub fn any(&self) -> bool {
        self.lsl || self.osc.is_some()
    }

    /// The prefix as used: letters, digits, '-', '_' and '.' kept (others become '_'), at most 64
    /// characters, "vestnav" when empty.
    pub fn prefix(&self) -> String {
        let p: String = self
            .stream_prefix
            .trim()
            .chars()
            .take(64)
            .map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '_' })
            .collect();
        if p.is_empty() { "vestnav".to_owned() } else { p }
    }
}

/// An OSC target from the command line: `HOST:PORT` (a name is resolved once, the first address used).
pub fn parse_osc_target(text: &str) -> Result<SocketAddr, String> {
    use std::net::ToSocketAddrs as _;
    let mut addrs = text.trim().to_socket_addrs().map_err(|e| format!("{text:?}: not HOST:PORT ({e})"))?;
    let addr = addrs.next().ok_or_else(|| format!("{text:?}: no address"))?;
    if addr.port() == 0 {
        return Err(format!("{text:?}: port 0"));
    }
    Ok(addr)
}

/// Why the lab outputs could not start.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    /// LSL was asked for and liblsl is not installed (the message lists what was tried and how to install).
    #[error("{0}")]
    LslMissing(LslMissing),
    /// liblsl was found but an outlet could not be opened.
    #[error("LSL: {0}")]
    Lsl(LslError),
    /// The OSC socket could not be opened.
    #[error("OSC to {addr}: {source}")]
    Osc {
        /// The target.
        addr: SocketAddr,
        /// The socket's error.
        source: std::io::Error,
    },
    /// The lab thread could not start or did not answer.
    #[error("lab outputs: {0}")]
    Thread(String),
}

/// The LSL side as a screen shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum LslState {
    /// Not asked for.
    Off,
    /// Streams open.
    On {
        /// liblsl's version ("1.16").
        version: String,
        /// Where it was loaded from.
        library: String,
        /// The streams' names.
        streams: Vec<String>,
    },
    /// Asked for, liblsl not installed: what was tried and how to install it.
    Missing {
        /// The whole message.
        why: String,
    },
    /// Asked for, liblsl found, but the streams could not be opened.
    Failed {
        /// What went wrong.
        why: String,
    },
}

/// The OSC side as a screen shows it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct OscStatus {
    /// Where messages go.
    pub target: String,
    /// Messages sent.
    pub sent: u64,
    /// Messages the socket refused (e.g. nobody listening: the port was unreachable).
    pub errors: u64,
}

/// The lab outputs as a screen shows them (in `Snapshot::lab`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LabStatus {
    /// The LSL side.
    pub lsl: LslState,
    /// The OSC side (`None`: off).
    pub osc: Option<OscStatus>,
    /// Markers handed to the outputs.
    pub markers: u64,
    /// Position samples.
    pub positions: u64,
    /// Heading samples.
    pub headings: u64,
    /// Vest commands, acknowledgements and refusals.
    pub vest: u64,
    /// Items dropped because the lab thread was behind (its queue holds [`QUEUE`]).
    pub dropped: u64,
    /// The latest marker.
    pub last_marker: Option<String>,
    /// The latest push or send error.
    pub error: Option<String>,
}

impl LabStatus {
    /// The status of outputs that could not start with `cfg` because of `err`.
    pub fn failed(cfg: &LabConfig, err: &LabError) -> Self {
        let lsl = match err {
            LabError::LslMissing(m) => LslState::Missing { why: m.to_string() },
            LabError::Lsl(e) => LslState::Failed { why: e.to_string() },
            _ if cfg.lsl => LslState::Failed { why: err.to_string() },
            _ => LslState::Off,
        };
        Self {
            lsl,
            osc: None,
            markers: 0,
            positions: 0,
            headings: 0,
            vest: 0,
            dropped: 0,
            last_marker: None,
            error: Some(err.to_string()),
        }
    }

    /// One line for a terminal or a status bar.
    pub fn summary(&self) -> String {
        let lsl = match &self.lsl {
            LslState::Off => "LSL off".to_owned(),
            LslState::On { version, streams, .. } => format!("LSL {version}: {} streams", streams.len()),
            LslState::Missing { .. } => "LSL missing (liblsl not installed)".to_owned(),
            LslState::Failed { why } => format!("LSL failed: {why}"),
        };
        let osc = self.osc.as_ref().map_or_else(
            || "OSC off".to_owned(),
            |o| format!("OSC to {}: {} sent, {} errors", o.target, o.sent, o.errors),
        );
        format!(
            "{lsl}; {osc}; {} markers, {} positions, {} headings, {} vest, {} dropped",
            self.markers, self.positions, self.headings, self.vest, self.dropped
        )
    }
}

/// One item for the lab thread.
enum Item {
    Marker(String, f64),
    Position([f64; 3], f64),
    Heading(f64, f64),
    Vest(String, f64),
}

#[derive(Default)]
struct Counts {
    markers: AtomicU64,
    positions: AtomicU64,
    headings: AtomicU64,
    vest: AtomicU64,
    dropped: AtomicU64,
    osc_sent: AtomicU64,
    osc_errors: AtomicU64,
}

/// The clock samples are stamped on.
enum Clock {
    Lsl(Lsl),
    Session(Instant),
}

/// What the callers and the lab thread both update.
#[derive(Default)]
struct Shared {
    counts: Counts,
    last_marker: Mutex<Option<String>>,
    error: Mutex<Option<String>>,
}

impl Shared {
    fn note(&self, e: String) {
        if let Ok(mut slot) = self.error.lock() {
            *slot = Some(e);
        }
    }
}

/// The callers' side. The lab thread holds only `Shared`, so it ends when the last sender (here) is gone.
struct Inner {
    clock: Clock,
    tx: Option<SyncSender<Item>>,
    lsl: LslState,
    osc: Option<SocketAddr>,
    shared: Arc<Shared>,
}

/// Every lab output of one station (see the module doc). Cheap to clone and to call from any thread.
#[derive(Clone)]
pub struct LabOutputs {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for LabOutputs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LabOutputs").field("lsl", &self.inner.lsl).field("osc", &self.inner.osc).finish()
    }
}

impl LabOutputs {
    /// Opens what `cfg` asks for: liblsl and its four outlets, the OSC socket, and the `vestnav-lab` thread.
    /// With nothing asked for it is [`Self::disabled`].
    pub fn start(cfg: &LabConfig) -> Result<LabOutputs, LabError> {
        if !cfg.any() {
            return Ok(Self::disabled());
        }
        let lsl = if cfg.lsl { Some(Lsl::load().map_err(LabError::LslMissing)?) } else { None };
        let socket = match cfg.osc {
            Some(addr) => Some(osc::Sender::open(addr).map_err(|source| LabError::Osc { addr, source })?),
            None => None,
        };
        let (tx, rx) = sync_channel(QUEUE);
        let (ready_tx, ready_rx) = sync_channel(1);
        let shared = Arc::new(Shared::default());
        let thread_lsl = lsl.clone();
        let thread_shared = shared.clone();
        let prefix = cfg.prefix();
        std::thread::Builder::new()
            .name("vestnav-lab".into())
            .spawn(move || {
                // liblsl's outlets are made, used and dropped on this thread only.
                let outlets = match thread_lsl.as_ref().map(|l| Outlets::open(l, &prefix)).transpose() {
                    Ok(o) => o,
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return;
                    }
                };
                let names = outlets.as_ref().map(Outlets::names).unwrap_or_default();
                if ready_tx.send(Ok(names)).is_ok() {
                    run(&rx, outlets.as_ref(), socket.as_ref(), &thread_shared);
                }
            })
            .map_err(|e| LabError::Thread(e.to_string()))?;
        let streams = match ready_rx.recv_timeout(START_TIMEOUT) {
            Ok(Ok(names)) => names,
            Ok(Err(e)) => return Err(LabError::Lsl(e)),
            Err(_) => return Err(LabError::Thread("the lab thread did not open its outputs".into())),
        };
        let lsl_state = match &lsl {
            Some(l) => LslState::On { version: l.version_text(), library: l.path().to_owned(), streams },
            None => LslState::Off,
        };
        Ok(LabOutputs {
            inner: Arc::new(Inner {
                clock: lsl.map_or_else(|| Clock::Session(Instant::now()), Clock::Lsl),
                tx: Some(tx),
                lsl: lsl_state,
                osc: cfg.osc,
                shared,
            }),
        })
    }

    /// No outputs: every call only counts; [`Self::now`] is a monotonic session clock (seconds since this
    /// call).
    pub fn disabled() -> LabOutputs {
        LabOutputs {
            inner: Arc::new(Inner {
                clock: Clock::Session(Instant::now()),
                tx: None,
                lsl: LslState::Off,
                osc: None,
                shared: Arc::default(),
            }),
        }
    }

    /// Whether any output runs.
    pub fn is_on(&self) -> bool {
        self.inner.tx.is_some()
    }

    /// Whether the LSL streams are open (then [`Self::now`] is liblsl's clock).
    pub fn lsl_on(&self) -> bool {
        matches!(self.inner.clock, Clock::Lsl(_))
    }

    /// The time to stamp an event with [s]: `lsl_local_clock()` when LSL is on, else seconds since the
    /// outputs started.
    pub fn now(&self) -> f64 {
        match &self.inner.clock {
            Clock::Lsl(l) => l.local_clock(),
            Clock::Session(t0) => t0.elapsed().as_secs_f64(),
        }
    }

    /// The time on [`Self::now`]'s clock at which `t` was (a device event's arrival).
    pub fn at(&self, t: Instant) -> f64 {
        self.now() - t.elapsed().as_secs_f64()
    }

    fn put(&self, item: Item, count: &AtomicU64) {
        count.fetch_add(1, Ordering::Relaxed);
        if let Some(tx) = &self.inner.tx {
            match tx.try_send(item) {
                Ok(()) | Err(TrySendError::Disconnected(_)) => {}
                Err(TrySendError::Full(_)) => {
                    self.inner.shared.counts.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    /// One marker (the vocabulary is in `docs/study.md`), timestamped `at` (from [`Self::now`]).
    pub fn marker(&self, text: &str, at: f64) {
        if let Ok(mut m) = self.inner.shared.last_marker.lock() {
            *m = Some(shortened(text).to_owned());
        }
        self.put(Item::Marker(text.to_owned(), at), &self.inner.shared.counts.markers);
    }

    /// One position sample: latitude and longitude [deg], horizontal accuracy [m] (NaN: unknown).
    pub fn position(&self, lat: f64, lon: f64, h_acc_m: f64, at: f64) {
        self.put(Item::Position([lat, lon, h_acc_m], at), &self.inner.shared.counts.positions);
    }

    /// One heading sample [deg].
    pub fn heading(&self, deg: f64, at: f64) {
        self.put(Item::Heading(deg, at), &self.inner.shared.counts.headings);
    }

    /// A command sent to the vest, or the unit's acknowledgement or refusal, in words.
    pub fn vest(&self, text: &str, at: f64) {
        self.put(Item::Vest(text.to_owned(), at), &self.inner.shared.counts.vest);
    }

    /// What a screen shows.
    pub fn status(&self) -> LabStatus {
        let c = &self.inner.shared.counts;
        let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
        LabStatus {
            lsl: self.inner.lsl.clone(),
            osc: self.inner.osc.map(|a| OscStatus {
                target: a.to_string(),
                sent: n(&c.osc_sent),
                errors: n(&c.osc_errors),
            }),
            markers: n(&c.markers),
            positions: n(&c.positions),
            headings: n(&c.headings),
            vest: n(&c.vest),
            dropped: n(&c.dropped),
            last_marker: self.inner.shared.last_marker.lock().ok().and_then(|m| m.clone()),
            error: self.inner.shared.error.lock().ok().and_then(|e| e.clone()),
        }
    }
}

/// `text` cut to 200 bytes at a character boundary (the latest marker as a screen shows it).
fn shortened(text: &str) -> &str {
    let mut end = text.len().min(200);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

/// The four LSL outlets (on the lab thread only).
struct Outlets {
    markers: vestnav_lsl::Outlet,
    position: vestnav_lsl::Outlet,
    heading: vestnav_lsl::Outlet,
    vest: vestnav_lsl::Outlet,
}

impl Outlets {
    fn open(lsl: &Lsl, prefix: &str) -> Result<Outlets, LslError> {
        use vestnav_lsl::{ChannelFormat as F, StreamSpec};
        let spec = |what: &str, kind: &str, n: usize, f: F| {
            let name = format!("{prefix}-{what}");
            StreamSpec::new(&name, kind, n, f, &name)
        };
        Ok(Outlets {
            markers: lsl.outlet(&spec("markers", "Markers", 1, F::String).with_channels(&["marker"]))?,
            position: lsl.outlet(&spec("position", "Position", 3, F::Double64).with_units(&[
                ("lat", "degrees"),
                ("lon", "degrees"),
                ("h_acc", "m"),
            ]))?,
            heading: lsl
                .outlet(&spec("heading", "Heading", 1, F::Double64).with_units(&[("heading", "degrees")]))?,
            vest: lsl.outlet(&spec("vest", "VestEvents", 1, F::String).with_channels(&["event"]))?,
        })
    }

    fn names(&self) -> Vec<String> {
        [&self.markers, &self.position, &self.heading, &self.vest]
            .iter()
            .map(|o| o.name().to_owned())
            .collect()
    }
}

/// The lab thread's loop: every item to LSL and OSC, until every `LabOutputs` is gone.
fn run(rx: &Receiver<Item>, outlets: Option<&Outlets>, osc: Option<&osc::Sender>, shared: &Shared) {
    while let Ok(item) = rx.recv() {
        let pushed = match (&item, outlets) {
            (_, None) => Ok(()),
            (Item::Marker(t, at), Some(o)) => o.markers.push_str(t, *at),
            (Item::Position(v, at), Some(o)) => o.position.push_f64(v, *at),
            (Item::Heading(d, at), Some(o)) => o.heading.push_f64(&[*d], *at),
            (Item::Vest(t, at), Some(o)) => o.vest.push_str(t, *at),
        };
        if let Err(e) = pushed {
            shared.note(format!("LSL: {e}"));
        }
        if let Some(s) = osc {
            let msg = match &item {
                Item::Marker(t, _) => osc::message("/vestnav/marker", &[osc::Arg::Str(t)]),
                Item::Position([lat, lon, acc], _) => osc::message(
                    "/vestnav/position",
                    &[osc::Arg::Double(*lat), osc::Arg::Double(*lon), osc::Arg::Double(*acc)],
                ),
                Item::Heading(d, _) => osc::message("/vestnav/heading", &[osc::Arg::Float(*d as f32)]),
                Item::Vest(t, _) => osc::message("/vestnav/vest", &[osc::Arg::Str(t)]),
            };
            match s.send(&msg) {
                Ok(()) => shared.counts.osc_sent.fetch_add(1, Ordering::Relaxed),
                Err(e) => {
                    shared.note(format!("OSC: {e}"));
                    shared.counts.osc_errors.fetch_add(1, Ordering::Relaxed)
                }
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn osc_targets_are_host_and_port() {
        assert_eq!(parse_osc_target("127.0.0.1:9000").unwrap(), "127.0.0.1:9000".parse().unwrap());
        assert_eq!(parse_osc_target(" localhost:57120 ").unwrap().port(), 57120);
        assert!(parse_osc_target("127.0.0.1").is_err());
        assert!(parse_osc_target("127.0.0.1:0").unwrap_err().contains("port 0"));
        assert!(parse_osc_target("127.0.0.1:99999").is_err());
    }

    #[test]
    fn stream_prefixes_are_tidied() {
        let p = |s: &str| LabConfig { stream_prefix: s.into(), ..LabConfig::default() }.prefix();
        assert_eq!(p("lab-3_a.b"), "lab-3_a.b");
        assert_eq!(p("  "), "vestnav");
        assert_eq!(p("a b/c\0"), "a_b_c_");
        assert_eq!(p(&"x".repeat(100)).len(), 64);
    }

    #[test]
    fn disabled_outputs_count_and_keep_a_session_clock() {
        let lab = LabOutputs::disabled();
        assert!(!lab.is_on() && !lab.lsl_on());
        let t0 = lab.now();
        std::thread::sleep(Duration::from_millis(5));
        assert!(lab.now() - t0 >= 0.004);
        let earlier = Instant::now().checked_sub(Duration::from_secs(1)).unwrap();
        // One second before, plus however long this thread waited between the two clock reads.
        let ago = lab.now() - lab.at(earlier);
        assert!((0.99..1.5).contains(&ago), "{ago}");
        lab.marker("pause", lab.now());
        let s = lab.status();
        assert_eq!((s.markers, s.lsl, s.osc), (1, LslState::Off, None));
        assert_eq!(s.last_marker.as_deref(), Some("pause"));
    }

    #[test]
    fn a_failed_start_shows_why() {
        let cfg = LabConfig { lsl: true, ..LabConfig::default() };
        let missing = LslMissing { tried: vec![("liblsl.so (system library)".into(), "not found".into())] };
        let s = LabStatus::failed(&cfg, &LabError::LslMissing(missing));
        let LslState::Missing { why } = &s.lsl else { panic!("{s:?}") };
        assert!(why.contains("liblsl.so (system library): not found") && why.contains("pip install pylsl"));
        assert!(s.summary().starts_with("LSL missing"));
    }
}
