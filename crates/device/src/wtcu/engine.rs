//! The unit side of the protocol as a sans-IO state machine: what the emulator runs, and what a firmware
//! would do. Bytes and the current time in; reply frames, tactor states and events out.
//!
//! The engine parses frames, enforces the [`Limits`] (NAK with a reason), runs fires and patterns against
//! the clock it is given, answers retransmitted requests without running them twice, and stops everything
//! when the console has been silent for the watchdog time. Garbage and truncated frames are dropped and
//! counted; no input makes it panic.
//!
//! Time is played exactly: however coarsely `handle_*` is called, every pattern step, fire end and watchdog
//! trip happens (and is booked for the limits) at its own instant. No tactor is ever on without a break for
//! longer than `max_on_ms`: besides each command's own limits, a FIRE or PLAY that keeps a tactor on which
//! is already on continues its run ([`RunTracker`]) and is refused (NAK 0x05) if the run would exceed it.
//! Outgoing frames wait in a queue of at most [`MAX_QUEUED_FRAMES`]; an unsent REPORT is superseded by the
//! next one, and when the queue is full the oldest frame (a REPORT first) is dropped and counted.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use vestnav_core::vest::{TACTOR_COUNT, TactorMask};

use super::codec::{DecodeError, FrameCodec, MIN_PROTOCOL_VERSION, PROTOCOL_VERSION, WireCodec};
use super::limits::{
    DutyLedger, LimitError, Limits, RunTracker, Schedule, Timeline, leading_pattern_ms, planned_fire_ms,
    planned_pattern_ms,
};
use vestnav_core::compass::{Calibration, tilt_compensated_heading};

use super::message::{
    Capabilities, CommandKind, DeviceInfo, Faults, FirmwareVersion, GPS_BAUDS, HeadingReport, NakReason,
    Packet, Reply, Request, UnitStatus,
};

/// The unit's magnetometer and accelerometer, sampled by the engine for its heading stream (protocol v2).
///
/// The engine knows the sensor only through this trait. The emulator fits [`crate::sim::SimulatedCompass`]
/// (a seeded sensor model, see [`super::emulator::UnitConfig`]); firmware reads real chips.
pub trait HeadingSensor: Send + std::fmt::Debug {
    /// The raw magnetometer reading \[µT\] and the accelerometer reading \[m/s²\] at `at`, body frame (x
    /// forward, y right, z down).
    fn sample(&mut self, at: Instant) -> ([f64; 3], [f64; 3]);
}

/// The unit's processing of one sensor sample, what firmware does too: `h = W (m - b)` with the loaded
/// calibration, tilt compensation with the accelerometer (`vestnav_core::compass`), the quality of `|h|`
/// against the calibrated field, and the raw reading for the console's calibration fit (saturating at the
/// wire's ±3276.7 µT, as a saturated sensor does). `None` when no heading is defined (free fall, no field).
pub fn heading_report(
    raw_ut: [f64; 3],
    accel_m_s2: [f64; 3],
    calibration: &Calibration,
) -> Option<HeadingReport> {
    let corrected = calibration.apply(raw_ut);
    let attitude = tilt_compensated_heading(corrected, accel_m_s2)?;
    let cdeg = |deg: f64, limit: f64| (deg * 100.0).round().clamp(-limit, limit) as i16;
    Some(HeadingReport {
        heading_cdeg: ((attitude.heading_deg * 100.0).round() as u32 % 36_000) as u16,
        pitch_cdeg: cdeg(attitude.pitch_deg, 9_000.0),
        roll_cdeg: cdeg(attitude.roll_deg, 18_000.0),
        quality_pct: calibration.quality_pct(corrected),
        raw_mag_dut: raw_ut
            .map(|v| (v * 10.0).round().clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16),
    })
}

/// What an outgoing frame is, for superseding and dropping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OutKind {
    /// An answer to a request: never superseded, dropped last.
    Answer,
    /// A REPORT (the whole tactor state): an unsent one is superseded by the next.
    Report,
    /// A HEADING reading: an unsent one is superseded by the next, dropped first.
    Heading,
    /// A `GPS_DATA` chunk of this many receiver bytes: never superseded, dropped after HEADINGs (its bytes
    /// counted as lost in the next chunk).
    Gps(u16),
}

impl OutKind {
    /// Whether an unsent frame of this kind says nothing a newer one of the same kind does not.
    fn superseded_by_newer(self) -> bool {
        matches!(self, Self::Report | Self::Heading)
    }
}

/// A `GPS_DATA` chunk is sent at a line feed, at this many bytes, or [`GPS_CHUNK_AGE`] after its first byte.
pub const GPS_CHUNK_BYTES: usize = 64;
/// The oldest a buffered receiver byte gets before its chunk is sent.
pub const GPS_CHUNK_AGE: Duration = Duration::from_millis(50);
/// Receiver bytes a unit buffers at most; bytes due beyond it (a unit that was not run for a while) are
/// dropped and counted as lost, as a real UART buffer overflows.
pub const GPS_BUFFER_BYTES: u64 = 1024;

/// Fastest heading stream a unit runs (reports per second).
pub const MAX_HEADING_RATE_HZ: u8 = 10;

/// Most frames waiting in the engine's outgoing queue: the engine never holds more, whoever (not) drains it.
pub const MAX_QUEUED_FRAMES: usize = 64;

/// Battery voltage below which [`Faults::LOW_BATTERY`] is raised (mV).
pub const LOW_BATTERY_MV: u16 = 3500;

/// How the emulated unit is built.
#[derive(Debug, Clone, PartialEq)]
pub struct EngineConfig {
    /// Firmware version reported.
    pub firmware: FirmwareVersion,
    /// Limits enforced and reported.
    pub limits: Limits,
    /// Silence after which everything stops (ms).
    pub watchdog_ms: u16,
    /// Whether the unit has per-tactor drive levels.
    pub intensity: bool,
    /// Battery voltage reported (mV).
    pub battery_mv: u16,
    /// Newest protocol version the unit speaks (1 or 2): a unit with `1` behaves exactly as v1 firmware,
    /// answering a v2 header with NAK 0x04.
    pub protocol_version: u8,
    /// What the GPS receiver on the unit's second UART sends, played in a loop at the requested baud (v2
    /// only, [`Capabilities::GPS`]), or none: the unit has no receiver.
    pub gps_nmea: Option<std::sync::Arc<[u8]>>,
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            firmware: FirmwareVersion { major: 1, minor: 0, patch: 0 },
            limits: Limits::default(),
            watchdog_ms: 1500,
            intensity: true,
            battery_mv: 3900,
            protocol_version: PROTOCOL_VERSION,
            gps_nmea: None,
        }
    }
}

/// Battery charge from voltage (%): a linear single-cell Li-ion model, 3300 mV = 0 %, 4200 mV = 100 %,
/// `pct = clamp((mv - 3300) / (4200 - 3300) * 100, 0, 100)` (a coarse stand-in for a discharge curve; the
/// WTCU's real gauge is unpublished).
pub fn battery_pct_from_mv(battery_mv: u16) -> u8 {
    let pct = (f64::from(battery_mv) - 3300.0) / 900.0 * 100.0;
    pct.round().clamp(0.0, 100.0) as u8
}

/// Something the engine did, for a live view or a log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EngineEvent {
    /// A console said HELLO.
    SessionStarted,
    /// The running tactors changed.
    TactorsChanged(TactorMask),
    /// A request was accepted.
    Accepted {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
    },
    /// A request or frame was refused with a NAK.
    Rejected {
        /// Sequence number, when the header could be trusted.
        seq: Option<u8>,
        /// Why.
        reason: NakReason,
        /// Details (the limit that was hit, the decode error).
        detail: String,
    },
    /// The console went silent and everything was stopped.
    WatchdogTripped,
    /// Bytes that were not a frame were dropped.
    Dropped(DecodeError),
}

/// Counters of what the engine received.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EngineStats {
    /// Valid frames.
    pub frames_ok: u64,
    /// Frames with a bad CRC or length.
    pub bad_crc: u64,
    /// Blocks that were not frames at all (bad COBS, too short, overlong).
    pub garbage: u64,
    /// Valid frames refused (unknown type, malformed, version, limits, before hello).
    pub naks_sent: u64,
    /// Retransmitted requests answered again without running them twice.
    pub duplicates: u64,
    /// Times the watchdog stopped everything.
    pub watchdog_trips: u64,
    /// Outgoing frames dropped because [`MAX_QUEUED_FRAMES`] were already waiting (nobody drained them).
    /// REPORTs superseded by a newer unsent REPORT are not counted: nothing is lost with them.
    pub frames_dropped: u64,
}

/// The device engine (see the module doc).
#[derive(Debug)]
pub struct Engine<C: WireCodec = FrameCodec> {
    config: EngineConfig,
    codec: C,
    identified: bool,
    timeline: Timeline,
    segment_start: Option<Instant>,
    ledger: DutyLedger,
    intensity: [u8; TACTOR_COUNT],
    faults: Faults,
    last_rx: Option<Instant>,
    watchdog_tripped: bool,
    last: Option<(u8, Request, Reply)>,
    report_seq: u8,
    /// Frames to send, each with what it is.
    out: VecDeque<(OutKind, Vec<u8>)>,
    events: VecDeque<EngineEvent>,
    stats: EngineStats,
    /// Protocol version of the current session (that of its HELLO).
    session_version: u8,
    heading: HeadingState,
    gps: GpsState,
}

/// The forwarded GPS receiver's state.
#[derive(Debug, Default)]
struct GpsState {
    /// What the receiver sends, looped; none: no receiver.
    source: Option<std::sync::Arc<[u8]>>,
    /// While forwarding: the baud and when it started.
    running: Option<(u32, Instant)>,
    /// Receiver bytes produced since forwarding started.
    emitted: u64,
    /// Where in `source` the next byte comes from.
    pos: usize,
    /// Bytes not yet sent, and when the first of them arrived.
    pending: Vec<u8>,
    pending_since: Option<Instant>,
    /// Bytes dropped since the last chunk.
    lost: u64,
}

impl GpsState {
    /// The instant the `n`-th receiver byte (1-based) since the start has fully arrived.
    fn byte_time(start: Instant, baud: u32, n: u64) -> Instant {
        start + Duration::from_micros(n * 10 * 1_000_000 / u64::from(baud))
    }

    /// Stops forwarding; bytes not yet sent are dropped.
    fn stop(&mut self) {
        self.running = None;
        self.pending.clear();
        self.pending_since = None;
        self.lost = 0;
    }
}

/// The heading stream's state.
#[derive(Debug, Default)]
struct HeadingState {
    sensor: Option<Box<dyn HeadingSensor>>,
    /// Reports per second while streaming.
    rate_hz: Option<u8>,
    /// When the next report is due.
    next_at: Option<Instant>,
    calibration: Calibration,
}

impl Engine<FrameCodec> {
    /// An engine speaking [`FrameCodec`] up to `config.protocol_version`, with no magnetometer (fit one
    /// with [`Self::with_heading_sensor`]).
    pub fn new(config: EngineConfig) -> Self {
        let codec = FrameCodec::with_max_version(config.protocol_version);
        let mut engine = Self::with_codec(config, codec);
        engine.gps.source = engine.config.gps_nmea.clone().filter(|b| !b.is_empty());
        engine
    }
}

impl<C: WireCodec> Engine<C> {
    /// An engine speaking `codec`.
    pub fn with_codec(config: EngineConfig, codec: C) -> Self {
        Self {
            config,
            codec,
            identified: false,
            timeline: Timeline::new(),
            segment_start: None,
            ledger: DutyLedger::new(),
            intensity: [255; TACTOR_COUNT],
            faults: Faults::default(),
            last_rx: None,
            watchdog_tripped: false,
            last: None,
            report_seq: 0,
            out: VecDeque::new(),
            events: VecDeque::new(),
            stats: EngineStats::default(),
            session_version: MIN_PROTOCOL_VERSION,
            heading: HeadingState::default(),
            gps: GpsState::default(),
        }
    }

    /// Gives the unit a magnetometer: it then reports [`Capabilities::HEADING`] in v2 sessions and streams
    /// [`Reply::Heading`] on request.
    #[must_use]
    pub fn with_heading_sensor(mut self, sensor: Box<dyn HeadingSensor>) -> Self {
        self.heading.sensor = Some(sensor);
        self
    }

    /// The heading stream's rate, while it runs.
    pub fn heading_rate_hz(&self) -> Option<u8> {
        self.heading.rate_hz
    }

    /// The GPS forwarding's baud, while it runs.
    pub fn gps_baud(&self) -> Option<u32> {
        self.gps.running.map(|(baud, _)| baud)
    }

    /// The calibration loaded by the console (the identity, with no reference field, until one is).
    pub fn calibration(&self) -> Calibration {
        self.heading.calibration
    }

    /// Protocol version of the current session.
    pub fn session_version(&self) -> u8 {
        self.session_version
    }

    /// What the unit says about itself.
    pub fn device_info(&self) -> DeviceInfo {
        let mut capabilities = Capabilities::PATTERNS;
        if self.config.intensity {
            capabilities = capabilities | Capabilities::INTENSITY;
        }
        if self.heading.sensor.is_some() && self.session_version >= 2 {
            capabilities = capabilities | Capabilities::HEADING;
        }
        if self.gps.source.is_some() && self.session_version >= 2 {
            capabilities = capabilities | Capabilities::GPS;
        }
        DeviceInfo {
            protocol_version: self.session_version,
            firmware: self.config.firmware,
            tactor_count: TACTOR_COUNT as u8,
            capabilities,
            limits: self.config.limits,
            watchdog_ms: self.config.watchdog_ms,
        }
    }

    /// The tactors running now (as of the last `handle_*` call).
    pub fn tactors_on(&self) -> TactorMask {
        self.timeline.on()
    }

    /// The continuous runs of the tactors so far (when each one's current run began).
    pub fn runs(&self) -> &RunTracker {
        self.timeline.runs()
    }

    /// Drive level of each tactor (255 = full).
    pub fn intensity(&self) -> [u8; TACTOR_COUNT] {
        self.intensity
    }

    /// Counters.
    pub fn stats(&self) -> EngineStats {
        self.stats
    }

    /// Current fault flags.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// Whether a console has said HELLO.
    pub fn identified(&self) -> bool {
        self.identified
    }

    /// When the last valid frame arrived.
    pub fn last_rx(&self) -> Option<Instant> {
        self.last_rx
    }

    /// Sets the battery voltage reported from now on (mV).
    pub fn set_battery_mv(&mut self, battery_mv: u16) {
        self.config.battery_mv = battery_mv;
    }

    /// The status the unit would report now.
    pub fn status(&self) -> UnitStatus {
        let mut faults = self.faults;
        if self.config.battery_mv < LOW_BATTERY_MV {
            faults = faults | Faults::LOW_BATTERY;
        }
        UnitStatus {
            battery_mv: self.config.battery_mv,
            battery_pct: battery_pct_from_mv(self.config.battery_mv),
            tactors_on: self.tactors_on(),
            faults,
            firmware: self.config.firmware,
        }
    }

    /// Next frame to send to the console.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        self.out.pop_front().map(|(_, frame)| frame)
    }

    /// Queues a frame for the console, keeping the queue bounded (see the module doc).
    fn push_out(&mut self, frame: Vec<u8>, kind: OutKind) {
        if kind.superseded_by_newer()
            && let Some(last) = self.out.iter_mut().rev().find(|(k, _)| *k == kind)
        {
            // A REPORT carries the whole state, a HEADING the latest reading: an unsent older one says
            // nothing the new one does not. (It keeps its place in the queue, so order is kept.)
            last.1 = frame;
            return;
        }
        if self.out.len() >= MAX_QUEUED_FRAMES {
            let rank = |k: &OutKind| match k {
                OutKind::Heading => 0,
                OutKind::Gps(_) => 1,
                OutKind::Report => 2,
                OutKind::Answer => 3,
            };
            let victim =
                (0..4).find_map(|want| self.out.iter().position(|(k, _)| rank(k) == want)).unwrap_or(0);
            if let Some((OutKind::Gps(bytes), _)) = self.out.remove(victim) {
                self.gps.lost += u64::from(bytes);
            }
            self.stats.frames_dropped += 1;
        }
        self.out.push_back((kind, frame));
    }

    /// Next event for a view or log.
    pub fn poll_event(&mut self) -> Option<EngineEvent> {
        self.events.pop_front()
    }

    /// When [`Self::handle_timeout`] must be called next (a pattern step, a fire's end, the watchdog).
    pub fn poll_timeout(&self) -> Option<Instant> {
        let gps_flush = self.gps.pending_since.map(|t| t + GPS_CHUNK_AGE);
        [self.timeline.next_change(), self.watchdog_deadline(), self.heading.next_at, gps_flush]
            .into_iter()
            .flatten()
            .min()
    }

    fn watchdog_deadline(&self) -> Option<Instant> {
        if !self.identified || self.watchdog_tripped {
            return None;
        }
        self.last_rx.map(|t| t + Duration::from_millis(u64::from(self.config.watchdog_ms)))
    }

    /// Advances the clock: trips the watchdog, steps patterns, ends fires, each at its own instant even when
    /// `now` is well past it; reports changes unsolicited.
    pub fn handle_timeout(&mut self, now: Instant) {
        loop {
            let change = self.timeline.next_change().filter(|&t| t <= now);
            let watchdog = self.watchdog_deadline().filter(|&t| t <= now);
            match (change, watchdog) {
                (change, Some(w)) if change.is_none_or(|c| w <= c) => {
                    self.watchdog_tripped = true;
                    self.stats.watchdog_trips += 1;
                    self.faults = self.faults | Faults::WATCHDOG;
                    self.events.push_back(EngineEvent::WatchdogTripped);
                    self.replace(Schedule::Idle, w, true);
                }
                (Some(c), _) => self.step(c, true),
                (None, _) => break,
            }
        }
        self.step(now, true);
        self.stream_heading(now);
        self.pump_gps(now);
    }

    /// Feeds bytes received from the console at `now`.
    pub fn handle_bytes(&mut self, bytes: &[u8], now: Instant) {
        self.handle_timeout(now);
        let mut decoded = Vec::new();
        self.codec.decode_requests(bytes, &mut decoded);
        for result in decoded {
            match result {
                Ok(packet) => {
                    self.stats.frames_ok += 1;
                    self.last_rx = Some(now);
                    self.watchdog_tripped = false;
                    self.handle_request(packet, now);
                }
                Err(err) => self.handle_decode_error(err),
            }
        }
    }

    fn handle_decode_error(&mut self, err: DecodeError) {
        if let Some(reason) = err.nak_reason() {
            if reason == NakReason::BadCrc {
                self.stats.bad_crc += 1;
                self.faults = self.faults | Faults::LINE_ERRORS;
            }
            let seq = err.seq();
            self.nak(seq.unwrap_or(0), reason, err.to_string(), seq);
        } else {
            self.stats.garbage += 1;
            self.faults = self.faults | Faults::LINE_ERRORS;
            self.events.push_back(EngineEvent::Dropped(err));
        }
    }

    fn nak(&mut self, seq: u8, reason: NakReason, detail: String, event_seq: Option<u8>) -> Reply {
        self.stats.naks_sent += 1;
        let reply = Reply::Nak { reason, tactors_on: self.tactors_on() };
        let frame = self.codec.encode_reply(seq, &reply);
        self.push_out(frame, OutKind::Answer);
        self.events.push_back(EngineEvent::Rejected { seq: event_seq, reason, detail });
        reply
    }

    fn handle_request(&mut self, Packet { version, seq, message }: Packet<Request>, now: Instant) {
        if message != Request::Hello
            && let Some((last_seq, last_req, last_reply)) = &self.last
            && *last_seq == seq
            && *last_req == message
        {
            // A retransmission (our reply was lost): answer again with fresh state, do not run it twice.
            self.stats.duplicates += 1;
            let on = self.tactors_on();
            let reply = match last_reply.clone() {
                Reply::Ack { .. } => Reply::Ack { tactors_on: on },
                Reply::Nak { reason, .. } => Reply::Nak { reason, tactors_on: on },
                Reply::Status(_) => Reply::Status(self.status()),
                other => other,
            };
            let frame = self.codec.encode_reply(seq, &reply);
            self.push_out(frame, OutKind::Answer);
            return;
        }
        if message == Request::Hello {
            self.last = None;
            // The session speaks the HELLO's version (the codec accepted it, so the unit speaks it too).
            self.session_version = version;
            self.codec.set_version(version);
        }
        let kind = message.kind();
        let reply = match self.execute(&message, now) {
            Ok(reply) => {
                let frame = self.codec.encode_reply(seq, &reply);
                self.push_out(frame, OutKind::Answer);
                self.events.push_back(EngineEvent::Accepted { seq, kind });
                reply
            }
            Err((reason, detail)) => {
                if matches!(
                    reason,
                    NakReason::DurationLimit
                        | NakReason::TooManyTactors
                        | NakReason::DutyCycle
                        | NakReason::PatternLimit
                ) {
                    self.faults = self.faults | Faults::LIMIT_REJECTED;
                }
                self.nak(seq, reason, format!("{}: {detail}", kind.name()), Some(seq))
            }
        };
        self.last = Some((seq, message, reply));
    }

    fn execute(&mut self, request: &Request, now: Instant) -> Result<Reply, (NakReason, String)> {
        let limit = |e: LimitError| (e.nak_reason(), e.to_string());
        if *request == Request::Hello {
            // A new session: whoever was driving the vest before is gone, so nothing keeps running.
            self.replace(Schedule::Idle, now, false);
            self.heading.rate_hz = None;
            self.heading.next_at = None;
            self.gps.stop();
            self.identified = true;
            self.events.push_back(EngineEvent::SessionStarted);
            return Ok(Reply::Identify(self.device_info()));
        }
        if !self.identified {
            return Err((NakReason::NotIdentified, "say hello first".to_owned()));
        }
        match request {
            Request::Hello | Request::Heartbeat => {}
            Request::Fire { mask, duration_ms } => {
                let planned = planned_fire_ms(*mask, *duration_ms);
                self.config.limits.check_fire(*mask, *duration_ms).map_err(limit)?;
                self.timeline.runs().check(&planned, now, &self.config.limits).map_err(limit)?;
                self.close_segment(self.tactors_on(), now);
                self.ledger.check(&planned, now, &self.config.limits).map_err(limit)?;
                self.replace(Schedule::fire(*mask, *duration_ms, now), now, false);
            }
            Request::Play { frames, repeats } => {
                self.config.limits.check_pattern(frames, *repeats).map_err(limit)?;
                let leading = leading_pattern_ms(frames, *repeats);
                self.timeline.runs().check(&leading, now, &self.config.limits).map_err(limit)?;
                self.close_segment(self.tactors_on(), now);
                self.ledger
                    .check(&planned_pattern_ms(frames, *repeats), now, &self.config.limits)
                    .map_err(limit)?;
                let schedule = Schedule::Pattern { frames: frames.clone(), repeats: *repeats, start: now };
                self.replace(schedule, now, false);
            }
            Request::SetIntensity { mask, level } => {
                if !self.config.intensity {
                    return Err((NakReason::NotSupported, "this unit has no intensity control".to_owned()));
                }
                for t in mask.indices() {
                    self.intensity[t] = *level;
                }
            }
            Request::StopAll => self.replace(Schedule::Idle, now, false),
            Request::HeadingStart { rate_hz } => {
                if self.heading.sensor.is_none() {
                    return Err((NakReason::NotSupported, "this unit has no magnetometer".to_owned()));
                }
                if !(1..=MAX_HEADING_RATE_HZ).contains(rate_hz) {
                    return Err((
                        NakReason::Malformed,
                        format!("rate {rate_hz} Hz is not 1..={MAX_HEADING_RATE_HZ}"),
                    ));
                }
                self.heading.rate_hz = Some(*rate_hz);
                self.heading.next_at = Some(now);
            }
            Request::HeadingStop => {
                self.heading.rate_hz = None;
                self.heading.next_at = None;
            }
            Request::GpsStart { baud } => {
                if self.gps.source.is_none() {
                    return Err((NakReason::NotSupported, "this unit has no GPS receiver".to_owned()));
                }
                if !GPS_BAUDS.contains(baud) {
                    return Err((NakReason::Malformed, format!("{baud} baud is not one of {GPS_BAUDS:?}")));
                }
                if self.gps.running.map(|(b, _)| b) != Some(*baud) {
                    self.gps.running = Some((*baud, now));
                    self.gps.emitted = 0;
                }
            }
            Request::GpsStop => self.gps.stop(),
            Request::SetCalibration(c) => {
                if self.heading.sensor.is_none() {
                    return Err((NakReason::NotSupported, "this unit has no magnetometer".to_owned()));
                }
                let calibration = Calibration::from_wire(c);
                calibration.check().map_err(|e| (NakReason::Malformed, e.to_string()))?;
                self.heading.calibration = calibration;
            }
            Request::GetStatus => {
                let status = self.status();
                self.faults = Faults::default();
                return Ok(Reply::Status(status));
            }
        }
        Ok(Reply::Ack { tactors_on: self.tactors_on() })
    }

    /// Books `mask`, on since the last booking, into the duty ledger up to `now`.
    /// Sends the heading report due at or before `now`, if any: one reading at the latest due instant (a
    /// unit that fell behind skips readings rather than bursting them), then schedules the next.
    fn stream_heading(&mut self, now: Instant) {
        let (Some(rate), Some(due)) = (self.heading.rate_hz, self.heading.next_at) else { return };
        if due > now {
            return;
        }
        let period = Duration::from_secs(1) / u32::from(rate);
        let behind = (now - due).as_nanos() / period.as_nanos().max(1);
        let at = due + period * u32::try_from(behind).unwrap_or(u32::MAX);
        self.heading.next_at = Some(at + period);
        let Some(sensor) = self.heading.sensor.as_mut() else { return };
        let (raw_ut, accel) = sensor.sample(at);
        // No reading while the accelerometer cannot tell down (free fall) or there is no field.
        let Some(report) = heading_report(raw_ut, accel, &self.heading.calibration) else { return };
        self.report_seq = self.report_seq.wrapping_add(1);
        let frame = self.codec.encode_reply(self.report_seq, &Reply::Heading(report));
        self.push_out(frame, OutKind::Heading);
    }

    /// Plays the receiver's bytes due by `now` into chunks: one at every line feed or
    /// [`GPS_CHUNK_BYTES`], and whatever is buffered once its first byte is [`GPS_CHUNK_AGE`] old.
    fn pump_gps(&mut self, now: Instant) {
        let (Some(source), Some((baud, start))) = (self.gps.source.clone(), self.gps.running) else {
            return;
        };
        let due = (now.saturating_duration_since(start).as_micros() as u64) * u64::from(baud) / 10_000_000;
        if due > self.gps.emitted + GPS_BUFFER_BYTES {
            // The unit was not run for a while: its UART buffer overflowed.
            let skipped = due - GPS_BUFFER_BYTES - self.gps.emitted;
            self.gps.lost += skipped;
            self.gps.pos = ((self.gps.pos as u64 + skipped) % source.len() as u64) as usize;
            self.gps.emitted += skipped;
        }
        while self.gps.emitted < due {
            let byte = source[self.gps.pos];
            self.gps.pos = (self.gps.pos + 1) % source.len();
            self.gps.emitted += 1;
            if self.gps.pending.is_empty() {
                self.gps.pending_since = Some(GpsState::byte_time(start, baud, self.gps.emitted));
            }
            self.gps.pending.push(byte);
            if byte == b'\n' || self.gps.pending.len() >= GPS_CHUNK_BYTES {
                self.flush_gps();
            }
        }
        if self.gps.pending_since.is_some_and(|t| t + GPS_CHUNK_AGE <= now) {
            self.flush_gps();
        }
    }

    fn flush_gps(&mut self) {
        self.gps.pending_since = None;
        if self.gps.pending.is_empty() {
            return;
        }
        let data = std::mem::take(&mut self.gps.pending);
        let lost = u16::try_from(self.gps.lost).unwrap_or(u16::MAX);
        self.gps.lost = 0;
        let bytes = data.len() as u16;
        self.report_seq = self.report_seq.wrapping_add(1);
        let frame = self.codec.encode_reply(self.report_seq, &Reply::GpsData { lost, data });
        self.push_out(frame, OutKind::Gps(bytes));
    }

    fn close_segment(&mut self, mask: TactorMask, now: Instant) {
        if let Some(start) = self.segment_start {
            self.ledger.record(mask, start, now);
        }
        self.segment_start = Some(now);
        let window = Duration::from_millis(u64::from(self.config.limits.duty_window_ms));
        self.ledger.prune(now, window);
    }

    /// Moves the timeline to `at`; a change is booked, announced and (if `report`) reported.
    fn step(&mut self, at: Instant, report: bool) {
        let before = self.tactors_on();
        if let Some(mask) = self.timeline.step(at) {
            self.changed(before, mask, at, report);
        }
    }

    /// Replaces the schedule at `at`; a change is booked, announced and (if `report`) reported.
    fn replace(&mut self, schedule: Schedule, at: Instant, report: bool) {
        let before = self.tactors_on();
        if let Some(mask) = self.timeline.replace(schedule, at) {
            self.changed(before, mask, at, report);
        }
    }

    fn changed(&mut self, before: TactorMask, mask: TactorMask, at: Instant, report: bool) {
        self.close_segment(before, at);
        self.events.push_back(EngineEvent::TactorsChanged(mask));
        if report {
            self.report_seq = self.report_seq.wrapping_add(1);
            let reply = Reply::Report { tactors_on: mask, faults: self.faults };
            let frame = self.codec.encode_reply(self.report_seq, &reply);
            self.push_out(frame, OutKind::Report);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_core::vest::Frame;

    /// A unit that said hello at `t0`, asked with requests encoded by an independent codec.
    struct Bench {
        unit: Engine,
        t0: Instant,
        seq: u8,
    }

    impl Bench {
        fn new() -> Self {
            let t0 = Instant::now();
            let mut unit = Engine::new(EngineConfig::default());
            unit.handle_bytes(
                &FrameCodec::with_max_version(1).encode_request(0, &Request::Hello).unwrap(),
                t0,
            );
            while unit.poll_transmit().is_some() {}
            Self { unit, t0, seq: 0 }
        }

        fn at(&self, ms: u64) -> Instant {
            self.t0 + Duration::from_millis(ms)
        }

        /// Sends `request` at `ms` after hello (stepping the clock through every deadline on the way) and
        /// returns the answer.
        fn ask(&mut self, ms: u64, request: &Request) -> Reply {
            let at = self.at(ms);
            while let Some(t) = self.unit.poll_timeout().filter(|&t| t <= at) {
                self.unit.handle_timeout(t);
            }
            while self.unit.poll_transmit().is_some() {}
            self.seq = self.seq.wrapping_add(1);
            self.unit.handle_bytes(
                &FrameCodec::with_max_version(1).encode_request(self.seq, request).unwrap(),
                at,
            );
            let mut out = Vec::new();
            FrameCodec::new().decode_replies(&self.unit.poll_transmit().unwrap(), &mut out);
            out.pop().unwrap().unwrap().message
        }
    }

    fn fire(mask: u16, duration_ms: u16) -> Request {
        Request::Fire { mask: TactorMask(mask), duration_ms }
    }

    fn play(frames: &[(u16, u16)], repeats: u8) -> Request {
        let frames = frames.iter().map(|&(m, d)| Frame { mask: TactorMask(m), duration_ms: d }).collect();
        Request::Play { frames, repeats }
    }

    fn is_nak(reply: &Reply, want: NakReason) -> bool {
        matches!(reply, Reply::Nak { reason, .. } if *reason == want)
    }

    #[test]
    fn a_repeated_pattern_cannot_hold_tactors_past_the_limit() {
        // The issue: 8 tactors, 1000 ms, 5 repeats = 5001 ms on before the fix.
        let mut b = Bench::new();
        let reply = b.ask(0, &play(&[(0x00FF, 1000)], 5));
        assert!(is_nak(&reply, NakReason::DurationLimit), "{reply:?}");
        assert_eq!(b.unit.tactors_on(), TactorMask::NONE);
        // Two repeats are exactly 2000 ms: fine.
        assert!(matches!(b.ask(1, &play(&[(0x00FF, 1000)], 2)), Reply::Ack { .. }));
    }

    #[test]
    fn a_fire_cannot_chain_onto_a_run() {
        let mut b = Bench::new();
        assert!(matches!(b.ask(0, &fire(1, 2000)), Reply::Ack { .. }));
        b.ask(1000, &Request::Heartbeat);
        // The first fire ends at 2000 ms; a fire at that very instant continues the run: 4000 ms.
        assert!(is_nak(&b.ask(2000, &fire(1, 2000)), NakReason::DurationLimit));
        assert!(is_nak(&b.ask(2000, &fire(1, 1)), NakReason::DurationLimit));
        // Another tactor, or the same after any break, starts afresh.
        assert!(matches!(b.ask(2000, &fire(2, 2000)), Reply::Ack { .. }));
        assert!(matches!(b.ask(3000, &fire(1, 2000)), Reply::Ack { .. }));
        // Replacing a running fire: the run goes on from 3000 ms; exactly 2000 ms in all is allowed.
        assert!(matches!(b.ask(4000, &fire(1, 1000)), Reply::Ack { .. }));
        assert!(is_nak(&b.ask(4500, &fire(1, 501)), NakReason::DurationLimit));
        assert!(matches!(b.ask(4500, &fire(1, 500)), Reply::Ack { .. }));
        assert!(b.unit.faults().contains(Faults::LIMIT_REJECTED));
    }

    #[test]
    fn a_pattern_continues_the_run_it_starts_in() {
        let mut b = Bench::new();
        assert!(matches!(b.ask(0, &fire(1, 1500)), Reply::Ack { .. }));
        // Tactor 0 on since 0; a pattern whose first 1100 ms keep it on would make 2100 ms.
        assert!(is_nak(&b.ask(1000, &play(&[(1, 1100), (2, 100)], 1)), NakReason::DurationLimit));
        // One that keeps it on 500 ms more (1500 ms in all), then switches it off and on, is fine.
        assert!(matches!(b.ask(1000, &play(&[(1, 500), (2, 100)], 2)), Reply::Ack { .. }));
        // A pattern that does not start with tactor 0 switches it off: a new run later.
        assert!(matches!(b.ask(1400, &play(&[(2, 100), (1, 2000)], 1)), Reply::Ack { .. }));
        assert_eq!(b.unit.tactors_on(), TactorMask(2));
    }

    #[test]
    fn a_late_clock_still_plays_every_step_at_its_own_instant() {
        let mut b = Bench::new();
        b.ask(0, &play(&[(1, 250), (2, 250), (4, 250), (8, 250)], 1));
        while b.unit.poll_event().is_some() {}
        // Nobody called for 1000 ms: every step happens anyway, and only the latest state is reported.
        b.unit.handle_timeout(b.at(1000));
        let changes: Vec<u16> = std::iter::from_fn(|| b.unit.poll_event())
            .filter_map(|e| if let EngineEvent::TactorsChanged(m) = e { Some(m.0) } else { None })
            .collect();
        assert_eq!(changes, vec![2, 4, 8, 0]);
        let frames: Vec<_> = std::iter::from_fn(|| b.unit.poll_transmit()).collect();
        assert_eq!(frames.len(), 1);
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(&frames[0], &mut out);
        assert!(matches!(
            out[0].as_ref().unwrap().message,
            Reply::Report { tactors_on: TactorMask::NONE, .. }
        ));
        // Each tactor was booked for its 250 ms, not for the whole late second.
        let runs = b.unit.runs();
        assert_eq!(runs.run_start(3, b.at(1000)), Some(b.at(750)));
        assert_eq!(runs.run_start(0, b.at(1000)), None);
    }

    #[test]
    fn the_outgoing_queue_is_bounded_and_keeps_the_newest() {
        let mut b = Bench::new();
        let codec = FrameCodec::with_max_version(1);
        for seq in 1..=200u8 {
            b.unit.handle_bytes(&codec.encode_request(seq, &Request::GetStatus).unwrap(), b.t0);
        }
        let frames: Vec<_> = std::iter::from_fn(|| b.unit.poll_transmit()).collect();
        assert_eq!(frames.len(), MAX_QUEUED_FRAMES);
        assert_eq!(b.unit.stats().frames_dropped, 200 - MAX_QUEUED_FRAMES as u64);
        let seq_of = |frame: &Vec<u8>| {
            let mut out = Vec::new();
            FrameCodec::new().decode_replies(frame, &mut out);
            out[0].as_ref().unwrap().seq
        };
        assert_eq!(seq_of(&frames[0]), 200 - MAX_QUEUED_FRAMES as u8 + 1);
        assert_eq!(seq_of(&frames[MAX_QUEUED_FRAMES - 1]), 200);
    }
}
