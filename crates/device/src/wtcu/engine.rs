//! The unit side of the protocol as a sans-IO state machine: what the emulator runs, and what a firmware
//! would do. Bytes and the current time in; reply frames, tactor states and events out.
//!
//! The engine parses frames, enforces the [`Limits`] (NAK with a reason), runs fires and patterns against
//! the clock it is given, answers retransmitted requests without running them twice, and stops everything
//! when the console has been silent for the watchdog time. Garbage and truncated frames are dropped and
//! counted; no input makes it panic.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use vestnav_core::vest::{Frame, TACTOR_COUNT, TactorMask};

use super::codec::{DecodeError, V1Codec, WireCodec};
use super::limits::{DutyLedger, LimitError, Limits, planned_fire_ms, planned_pattern_ms};
use super::message::{
    Capabilities, CommandKind, DeviceInfo, Faults, FirmwareVersion, NakReason, Packet, Reply, Request,
    UnitStatus,
};

/// Battery voltage below which [`Faults::LOW_BATTERY`] is raised (mV).
pub const LOW_BATTERY_MV: u16 = 3500;

/// How the emulated unit is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            firmware: FirmwareVersion { major: 1, minor: 0, patch: 0 },
            limits: Limits::default(),
            watchdog_ms: 1500,
            intensity: true,
            battery_mv: 3900,
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
}

#[derive(Debug, Clone)]
enum Activity {
    Idle,
    Fire { mask: TactorMask, until: Instant },
    Pattern { frames: Vec<Frame>, repeats: u8, start: Instant },
}

/// The device engine (see the module doc).
#[derive(Debug)]
pub struct Engine<C: WireCodec = V1Codec> {
    config: EngineConfig,
    codec: C,
    identified: bool,
    activity: Activity,
    on: TactorMask,
    segment_start: Option<Instant>,
    last_update: Option<Instant>,
    ledger: DutyLedger,
    intensity: [u8; TACTOR_COUNT],
    faults: Faults,
    last_rx: Option<Instant>,
    watchdog_tripped: bool,
    last: Option<(u8, Request, Reply)>,
    report_seq: u8,
    out: VecDeque<Vec<u8>>,
    events: VecDeque<EngineEvent>,
    stats: EngineStats,
}

impl Engine<V1Codec> {
    /// An engine speaking [`V1Codec`].
    pub fn new(config: EngineConfig) -> Self {
        Self::with_codec(config, V1Codec::new())
    }
}

impl<C: WireCodec> Engine<C> {
    /// An engine speaking `codec`.
    pub fn with_codec(config: EngineConfig, codec: C) -> Self {
        Self {
            config,
            codec,
            identified: false,
            activity: Activity::Idle,
            on: TactorMask::NONE,
            segment_start: None,
            last_update: None,
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
        }
    }

    /// What the unit says about itself.
    pub fn device_info(&self) -> DeviceInfo {
        let mut capabilities = Capabilities::PATTERNS;
        if self.config.intensity {
            capabilities = capabilities | Capabilities::INTENSITY;
        }
        DeviceInfo {
            protocol_version: super::codec::PROTOCOL_VERSION,
            firmware: self.config.firmware,
            tactor_count: TACTOR_COUNT as u8,
            capabilities,
            limits: self.config.limits,
            watchdog_ms: self.config.watchdog_ms,
        }
    }

    /// The tactors running now (as of the last `handle_*` call).
    pub fn tactors_on(&self) -> TactorMask {
        self.on
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
            tactors_on: self.on,
            faults,
            firmware: self.config.firmware,
        }
    }

    /// Next frame to send to the console.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        self.out.pop_front()
    }

    /// Next event for a view or log.
    pub fn poll_event(&mut self) -> Option<EngineEvent> {
        self.events.pop_front()
    }

    /// When [`Self::handle_timeout`] must be called next (a pattern step, a fire's end, the watchdog).
    pub fn poll_timeout(&self) -> Option<Instant> {
        let change = self.next_change();
        let watchdog = self.watchdog_deadline();
        match (change, watchdog) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn watchdog_deadline(&self) -> Option<Instant> {
        if !self.identified || self.watchdog_tripped {
            return None;
        }
        self.last_rx.map(|t| t + Duration::from_millis(u64::from(self.config.watchdog_ms)))
    }

    /// Advances the clock: trips the watchdog, steps patterns, ends fires; reports changes unsolicited.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.watchdog_deadline().is_some_and(|d| now >= d) {
            self.watchdog_tripped = true;
            self.stats.watchdog_trips += 1;
            self.faults = self.faults | Faults::WATCHDOG;
            self.activity = Activity::Idle;
            self.events.push_back(EngineEvent::WatchdogTripped);
        }
        self.update(now, true);
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
        let reply = Reply::Nak { reason, tactors_on: self.on };
        self.out.push_back(self.codec.encode_reply(seq, &reply));
        self.events.push_back(EngineEvent::Rejected { seq: event_seq, reason, detail });
        reply
    }

    fn handle_request(&mut self, Packet { seq, message }: Packet<Request>, now: Instant) {
        if message != Request::Hello
            && let Some((last_seq, last_req, last_reply)) = &self.last
            && *last_seq == seq
            && *last_req == message
        {
            // A retransmission (our reply was lost): answer again with fresh state, do not run it twice.
            self.stats.duplicates += 1;
            let reply = match last_reply.clone() {
                Reply::Ack { .. } => Reply::Ack { tactors_on: self.on },
                Reply::Nak { reason, .. } => Reply::Nak { reason, tactors_on: self.on },
                Reply::Status(_) => Reply::Status(self.status()),
                other => other,
            };
            self.out.push_back(self.codec.encode_reply(seq, &reply));
            return;
        }
        if message == Request::Hello {
            self.last = None;
        }
        let kind = message.kind();
        let reply = match self.execute(&message, now) {
            Ok(reply) => {
                self.out.push_back(self.codec.encode_reply(seq, &reply));
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
            self.activity = Activity::Idle;
            self.update(now, false);
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
                self.config.limits.check_fire(*mask, *duration_ms).map_err(limit)?;
                self.close_segment(now);
                self.ledger
                    .check(&planned_fire_ms(*mask, *duration_ms), now, &self.config.limits)
                    .map_err(limit)?;
                let until = now + Duration::from_millis(u64::from(*duration_ms));
                self.activity = Activity::Fire { mask: *mask, until };
                self.update(now, false);
            }
            Request::Play { frames, repeats } => {
                self.config.limits.check_pattern(frames, *repeats).map_err(limit)?;
                self.close_segment(now);
                self.ledger
                    .check(&planned_pattern_ms(frames, *repeats), now, &self.config.limits)
                    .map_err(limit)?;
                self.activity = Activity::Pattern { frames: frames.clone(), repeats: *repeats, start: now };
                self.update(now, false);
            }
            Request::SetIntensity { mask, level } => {
                if !self.config.intensity {
                    return Err((NakReason::NotSupported, "this unit has no intensity control".to_owned()));
                }
                for t in mask.indices() {
                    self.intensity[t] = *level;
                }
            }
            Request::StopAll => {
                self.activity = Activity::Idle;
                self.update(now, false);
            }
            Request::GetStatus => {
                let status = self.status();
                self.faults = Faults::default();
                return Ok(Reply::Status(status));
            }
        }
        Ok(Reply::Ack { tactors_on: self.on })
    }

    /// Books the on-time since the last change into the duty ledger.
    fn close_segment(&mut self, now: Instant) {
        if let Some(start) = self.segment_start {
            self.ledger.record(self.on, start, now);
        }
        self.segment_start = Some(now);
        let window = Duration::from_millis(u64::from(self.config.limits.duty_window_ms));
        self.ledger.prune(now, window);
    }

    /// The mask the current activity asks for at `now`, and when that changes next.
    fn activity_at(&self, now: Instant) -> (TactorMask, Option<Instant>) {
        match &self.activity {
            Activity::Idle => (TactorMask::NONE, None),
            Activity::Fire { mask, until } => {
                if now < *until {
                    (*mask, Some(*until))
                } else {
                    (TactorMask::NONE, None)
                }
            }
            Activity::Pattern { frames, repeats, start } => {
                let cycle_ms: u64 = frames.iter().map(|f| u64::from(f.duration_ms)).sum();
                let total_ms = cycle_ms * u64::from(*repeats);
                let elapsed_ms = now.saturating_duration_since(*start).as_millis() as u64;
                if cycle_ms == 0 || elapsed_ms >= total_ms {
                    return (TactorMask::NONE, None);
                }
                let cycle_start = elapsed_ms - elapsed_ms % cycle_ms;
                let mut end = cycle_start;
                for f in frames {
                    end += u64::from(f.duration_ms);
                    if elapsed_ms < end {
                        return (f.mask, Some(*start + Duration::from_millis(end)));
                    }
                }
                (TactorMask::NONE, None)
            }
        }
    }

    fn next_change(&self) -> Option<Instant> {
        match self.activity {
            Activity::Idle => None,
            _ => self.activity_at(self.last_update?).1,
        }
    }

    fn update(&mut self, now: Instant, report: bool) {
        self.last_update = Some(now);
        let (mask, next) = self.activity_at(now);
        if next.is_none() && mask.is_empty() {
            self.activity = Activity::Idle;
        }
        if mask != self.on {
            self.close_segment(now);
            self.on = mask;
            self.events.push_back(EngineEvent::TactorsChanged(mask));
            if report {
                self.report_seq = self.report_seq.wrapping_add(1);
                let reply = Reply::Report { tactors_on: mask, faults: self.faults };
                self.out.push_back(self.codec.encode_reply(self.report_seq, &reply));
            }
        } else if self.segment_start.is_none() {
            self.segment_start = Some(now);
        }
    }
}
