//! The console side of the WTCU protocol as a sans-IO state machine (quinn-proto's shape): feed it received
//! bytes and the time, drain bytes to send, events and the next deadline. No IO, no threads, no clock.
//!
//! - **Handshake**: [`Link::connect`] sends HELLO (retried); IDENTIFY makes the link [`LinkState::Ready`] and
//!   fixes the limits in force (the stricter of ours and the unit's).
//! - **Stop-and-wait delivery**: one request in flight; a missing ACK is retransmitted after
//!   [`LinkConfig::ack_timeout`] up to [`LinkConfig::max_retries`] times, then reported as not delivered.
//!   A NAK "bad CRC" triggers an immediate retransmission. The unit answers duplicates without running them
//!   twice, so a retransmitted FIRE cannot stack.
//! - **STOP ALL has priority**: it cancels queued and in-flight on-commands, goes out at once and is retried
//!   until acknowledged or the link is lost.
//! - **Heartbeat**: when idle, a HEARTBEAT every [`LinkConfig::heartbeat_interval`] (at most a quarter of the
//!   unit's watchdog) keeps the unit's watchdog fed and refreshes the tactors-on state.
//! - **Loss**: nothing valid from the unit for [`LinkConfig::loss_timeout`] -> [`LinkState::Lost`].
//! - **Tactors on** come only from the unit (ACK, NAK, STATUS, REPORT), never from what was sent.
//! - **Limits before sending**: every FIRE and PLAY is checked against the limits in force, including the
//!   continuous on-time across commands: the link replays the cues the unit acknowledged (each from the time
//!   it was first sent, the one in flight as if it will be acknowledged) and refuses a cue that would keep a
//!   tactor on past `max_on_ms` counted from the start of its current run ([`LimitError::RunTooLong`]). The
//!   unit checks the same on its own clock and has the last word (NAK 0x05).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use vestnav_core::vest::{Pattern, TACTOR_COUNT, TactorMask};

use super::codec::{EncodeError, FrameCodec, MIN_PROTOCOL_VERSION, WireCodec};
use super::limits::{
    DutyLedger, LimitError, Limits, Schedule, Timeline, leading_pattern_ms, planned_fire_ms,
    planned_pattern_ms,
};
use super::message::{
    CalibrationWire, Capabilities, CommandKind, DeviceInfo, HeadingReport, NakReason, Packet, Reply, Request,
    UnitStatus,
};

/// Timing and limits of the console side.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkConfig {
    /// Time to wait for a reply before retransmitting.
    pub ack_timeout: Duration,
    /// Retransmissions of a command before it is reported as not delivered.
    pub max_retries: u8,
    /// Retransmissions of HELLO before the handshake fails.
    pub hello_retries: u8,
    /// Idle time after which a heartbeat is sent (capped at a quarter of the unit's watchdog).
    pub heartbeat_interval: Duration,
    /// Silence from the unit after which the link is lost.
    pub loss_timeout: Duration,
    /// Console-side limits (the unit's are applied too, the stricter wins).
    pub limits: Limits,
    /// Most commands waiting behind the one in flight.
    pub max_queue: usize,
}

impl Default for LinkConfig {
    /// Bluetooth SPP round trips are tens of ms; 200 ms ack timeout with 3 retries gives up after 800 ms,
    /// before the 1000 ms loss timeout and well before the unit's 1500 ms watchdog.
    fn default() -> Self {
        Self {
            ack_timeout: Duration::from_millis(200),
            max_retries: 3,
            hello_retries: 4,
            heartbeat_interval: Duration::from_millis(250),
            loss_timeout: Duration::from_secs(1),
            limits: Limits::default(),
            max_queue: 16,
        }
    }
}

/// State of a vest link.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum LinkState {
    /// No transport.
    #[default]
    Disconnected,
    /// Opening the transport (set by the worker); `attempt` counts from 1.
    Connecting {
        /// Attempt number since the last good connection.
        attempt: u32,
    },
    /// HELLO sent, waiting for IDENTIFY.
    Handshaking,
    /// Identified; commands are accepted.
    Ready,
    /// The link failed; the worker reconnects after a backoff.
    Lost {
        /// Why, in words.
        reason: String,
    },
}

impl std::fmt::Display for LinkState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Disconnected => f.write_str("disconnected"),
            Self::Connecting { attempt } => write!(f, "connecting (attempt {attempt})"),
            Self::Handshaking => f.write_str("handshaking"),
            Self::Ready => f.write_str("ready"),
            Self::Lost { reason } => write!(f, "lost: {reason}"),
        }
    }
}

/// What the link reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkEvent {
    /// The state changed.
    State(LinkState),
    /// The unit identified itself.
    Identified(DeviceInfo),
    /// The unit reported a different set of running tactors.
    TactorsOn(TactorMask),
    /// A command was accepted by the unit.
    Acked {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
    },
    /// The unit refused a command (NAK).
    Rejected {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
        /// The unit's reason.
        reason: NakReason,
    },
    /// No reply after every retransmission, or the link was lost with the command pending.
    NotDelivered {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
    },
    /// Dropped before delivery: superseded by a newer cue or cancelled by STOP ALL.
    Cancelled {
        /// Its sequence number.
        seq: u8,
        /// Its kind.
        kind: CommandKind,
    },
    /// A status report.
    Status(UnitStatus),
    /// A reading of the unit's heading stream (protocol v2).
    Heading(HeadingReport),
    /// Bytes of the GPS receiver the unit forwards (protocol v2), in order.
    GpsData {
        /// Receiver bytes the unit dropped before these.
        lost: u16,
        /// The bytes.
        data: Vec<u8>,
    },
}

/// A command the link refused to send.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// The link is not ready.
    #[error("vest link not ready ({0})")]
    NotReady(LinkState),
    /// The command is outside the limits in force.
    #[error("refused before sending: {0}")]
    Limit(#[from] LimitError),
    /// The unit does not support the command.
    #[error("the unit does not support {0}")]
    NotSupported(&'static str),
    /// Too many commands waiting.
    #[error("command queue full")]
    QueueFull,
    /// The command does not fit one frame.
    #[error(transparent)]
    TooLarge(#[from] EncodeError),
}

/// Counters of the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Frames sent (first transmissions).
    pub sent: u64,
    /// Retransmissions.
    pub retransmits: u64,
    /// Valid frames received.
    pub received: u64,
    /// Received bytes that did not decode.
    pub bad_frames: u64,
    /// HELLOs re-offered at a lower protocol version after the unit refused the header's (NAK 0x04).
    pub version_fallbacks: u64,
}

#[derive(Debug, Clone)]
struct Outgoing {
    seq: u8,
    request: Request,
    bytes: Vec<u8>,
}

#[derive(Debug, Clone)]
struct InFlight {
    out: Outgoing,
    deadline: Instant,
    retries_left: u8,
    /// STOP ALL: retried until acknowledged or the link is lost.
    persistent: bool,
    /// When it was first transmitted: the earliest the unit can have started it.
    first_sent: Instant,
}

/// The console-side link (see the module doc).
#[derive(Debug)]
pub struct Link<C: WireCodec = FrameCodec> {
    config: LinkConfig,
    codec: C,
    state: LinkState,
    device: Option<DeviceInfo>,
    limits: Limits,
    heartbeat_interval: Duration,
    next_seq: u8,
    queue: VecDeque<Outgoing>,
    in_flight: Option<InFlight>,
    transmit: VecDeque<Vec<u8>>,
    events: VecDeque<LinkEvent>,
    last_rx: Option<Instant>,
    last_tx: Option<Instant>,
    tactors_on: Option<TactorMask>,
    ledger: DutyLedger,
    /// What the unit drives, replayed from the cues it acknowledged (from when each was first sent).
    unit_model: Timeline,
    stats: LinkStats,
}

impl Link<FrameCodec> {
    /// A link speaking [`FrameCodec`] (the newest version, falling back to what the unit speaks).
    pub fn new(config: LinkConfig) -> Self {
        Self::with_codec(config, FrameCodec::new())
    }
}

impl<C: WireCodec> Link<C> {
    /// A link speaking `codec`.
    pub fn with_codec(config: LinkConfig, codec: C) -> Self {
        Self {
            config,
            codec,
            state: LinkState::Disconnected,
            device: None,
            limits: config.limits,
            heartbeat_interval: config.heartbeat_interval,
            next_seq: 0,
            queue: VecDeque::new(),
            in_flight: None,
            transmit: VecDeque::new(),
            events: VecDeque::new(),
            last_rx: None,
            last_tx: None,
            tactors_on: None,
            ledger: DutyLedger::new(),
            unit_model: Timeline::new(),
            stats: LinkStats::default(),
        }
    }

    /// The current state.
    pub fn state(&self) -> &LinkState {
        &self.state
    }

    /// Whether commands are accepted.
    pub fn is_ready(&self) -> bool {
        self.state == LinkState::Ready
    }

    /// The unit, once identified.
    pub fn device(&self) -> Option<&DeviceInfo> {
        self.device.as_ref()
    }

    /// The limits in force (ours and the unit's, the stricter of each).
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// The tactors the unit last said are on; `None` when unknown (not connected, lost).
    pub fn tactors_on(&self) -> Option<TactorMask> {
        self.tactors_on
    }

    /// Counters.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Whether a command is waiting for its reply or queued.
    pub fn is_busy(&self) -> bool {
        self.in_flight.as_ref().is_some_and(|f| f.out.request != Request::Heartbeat) || !self.queue.is_empty()
    }

    /// Sets the state shown while the worker opens a transport.
    pub fn set_connecting(&mut self, attempt: u32) {
        self.set_state(LinkState::Connecting { attempt });
    }

    /// Starts a session on a fresh transport: sends HELLO.
    pub fn connect(&mut self, now: Instant) {
        self.codec.reset();
        // Offer the newest version again: the unit on this transport may not be the last one.
        self.codec.set_version(u8::MAX);
        self.abandon_all();
        self.transmit.clear();
        self.device = None;
        self.last_rx = None;
        self.tactors_on = None;
        // HELLO stops everything on the unit.
        self.unit_model.advance_to(now);
        self.unit_model.replace(Schedule::Idle, now);
        self.set_state(LinkState::Handshaking);
        let out = self.outgoing(Request::Hello).unwrap_or_else(|_| unreachable_hello());
        self.start(out, self.config.hello_retries, false, now);
    }

    /// The transport failed (write error, port gone): the link is lost.
    pub fn disconnect(&mut self, reason: &str) {
        if matches!(self.state, LinkState::Handshaking | LinkState::Ready) {
            self.lose(reason.to_owned());
        }
    }

    /// Next bytes to write to the transport.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        self.transmit.pop_front()
    }

    /// Next event.
    pub fn poll_event(&mut self) -> Option<LinkEvent> {
        self.events.pop_front()
    }

    /// When [`Self::handle_timeout`] must be called next.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let mut next: Option<Instant> = self.in_flight.as_ref().map(|f| f.deadline);
        let mut consider = |t: Instant| next = Some(next.map_or(t, |n| n.min(t)));
        if self.state == LinkState::Ready {
            if let Some(rx) = self.last_rx {
                consider(rx + self.config.loss_timeout);
            }
            if self.in_flight.is_none()
                && self.queue.is_empty()
                && let Some(tx) = self.last_tx
            {
                consider(tx + self.heartbeat_interval);
            }
        }
        next
    }

    /// Advances the clock: loss detection, retransmissions, heartbeats.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.state == LinkState::Ready
            && let Some(rx) = self.last_rx
            && now >= rx + self.config.loss_timeout
        {
            self.lose(format!("no reply for {} ms", self.config.loss_timeout.as_millis()));
            return;
        }
        if let Some(f) = &mut self.in_flight
            && now >= f.deadline
        {
            if f.persistent || f.retries_left > 0 {
                if !f.persistent {
                    f.retries_left -= 1;
                }
                f.deadline = now + self.config.ack_timeout;
                self.transmit.push_back(f.out.bytes.clone());
                self.stats.retransmits += 1;
                self.last_tx = Some(now);
            } else if let Some(f) = self.in_flight.take() {
                match f.out.request {
                    Request::Hello => {
                        self.lose("no answer to HELLO".to_owned());
                        return;
                    }
                    Request::Heartbeat => {}
                    ref r => {
                        self.events.push_back(LinkEvent::NotDelivered { seq: f.out.seq, kind: r.kind() });
                    }
                }
            }
        }
        self.pump(now);
    }

    /// Feeds bytes received from the unit at `now`.
    pub fn handle_bytes(&mut self, bytes: &[u8], now: Instant) {
        if !matches!(self.state, LinkState::Handshaking | LinkState::Ready) {
            return;
        }
        let mut decoded = Vec::new();
        self.codec.decode_replies(bytes, &mut decoded);
        for result in decoded {
            match result {
                Ok(packet) => {
                    self.stats.received += 1;
                    self.last_rx = Some(now);
                    self.handle_reply(packet, now);
                    if !matches!(self.state, LinkState::Handshaking | LinkState::Ready) {
                        return;
                    }
                }
                Err(_) => self.stats.bad_frames += 1,
            }
        }
        self.pump(now);
    }

    fn in_flight_matches(&self, seq: u8) -> Option<&Request> {
        self.in_flight.as_ref().filter(|f| f.out.seq == seq).map(|f| &f.out.request)
    }

    fn handle_reply(&mut self, Packet { version, seq, message }: Packet<Reply>, now: Instant) {
        match message {
            Reply::Identify(mut info) => {
                info.protocol_version = version;
                if self.in_flight_matches(seq) != Some(&Request::Hello) {
                    return;
                }
                self.in_flight = None;
                if usize::from(info.tactor_count) != TACTOR_COUNT {
                    self.lose(format!(
                        "unit drives {} tactors, the vest has {TACTOR_COUNT}",
                        info.tactor_count
                    ));
                    return;
                }
                self.limits = self.config.limits.tighter(&info.limits);
                let quarter = Duration::from_millis(u64::from(info.watchdog_ms) / 4);
                self.heartbeat_interval =
                    self.config.heartbeat_interval.min(quarter).max(Duration::from_millis(10));
                self.device = Some(info);
                self.events.push_back(LinkEvent::Identified(info));
                self.set_state(LinkState::Ready);
                // Battery and fault flags right away.
                if let Ok(out) = self.outgoing(Request::GetStatus) {
                    self.queue.push_back(out);
                }
            }
            Reply::Ack { tactors_on } => {
                self.set_tactors(tactors_on);
                if let Some(kind) = self.in_flight_matches(seq).map(Request::kind) {
                    if let Some(f) = self.in_flight.take()
                        && let Some(schedule) = schedule_of(&f.out.request, f.first_sent)
                    {
                        self.unit_model.advance_to(f.first_sent);
                        self.unit_model.replace(schedule, f.first_sent);
                    }
                    if kind != CommandKind::Heartbeat {
                        self.events.push_back(LinkEvent::Acked { seq, kind });
                    }
                }
            }
            Reply::Nak { reason, tactors_on } => {
                self.set_tactors(tactors_on);
                if reason == NakReason::BadCrc {
                    // The unit saw a corrupted frame, most likely ours: resend what is in flight now.
                    if let Some(f) = &mut self.in_flight {
                        f.deadline = now;
                    }
                    self.handle_timeout(now);
                    return;
                }
                if let Some(kind) = self.in_flight_matches(seq).map(Request::kind) {
                    self.in_flight = None;
                    if kind == CommandKind::Hello {
                        let offered = self.codec.version();
                        if reason == NakReason::UnsupportedVersion && offered > MIN_PROTOCOL_VERSION {
                            // Version negotiation: an older unit refuses our header; offer the one below.
                            self.codec.set_version(offered - 1);
                            self.stats.version_fallbacks += 1;
                            let out = self.outgoing(Request::Hello).unwrap_or_else(|_| unreachable_hello());
                            self.start(out, self.config.hello_retries, false, now);
                            return;
                        }
                        self.lose(format!("unit refused HELLO: {reason}"));
                        return;
                    }
                    self.events.push_back(LinkEvent::Rejected { seq, kind, reason });
                }
            }
            Reply::Status(status) => {
                self.set_tactors(status.tactors_on);
                if self.in_flight_matches(seq) == Some(&Request::GetStatus) {
                    self.in_flight = None;
                }
                self.events.push_back(LinkEvent::Status(status));
            }
            Reply::Report { tactors_on, .. } => self.set_tactors(tactors_on),
            Reply::Heading(report) => {
                if self.state == LinkState::Ready {
                    self.events.push_back(LinkEvent::Heading(report));
                }
            }
            Reply::GpsData { lost, data } => {
                if self.state == LinkState::Ready {
                    self.events.push_back(LinkEvent::GpsData { lost, data });
                }
            }
        }
    }

    /// Starts the unit's heading stream at `rate_hz` readings per second (protocol v2 units with
    /// [`Capabilities::HEADING`] only).
    pub fn heading_start(&mut self, rate_hz: u8, now: Instant) -> Result<u8, CommandError> {
        self.require_heading()?;
        let out = self.outgoing(Request::HeadingStart { rate_hz })?;
        self.enqueue(out, now)
    }

    /// Stops the unit's heading stream.
    pub fn heading_stop(&mut self, now: Instant) -> Result<u8, CommandError> {
        self.require_heading()?;
        let out = self.outgoing(Request::HeadingStop)?;
        self.enqueue(out, now)
    }

    /// Loads a magnetometer calibration into the unit.
    pub fn set_calibration(
        &mut self,
        calibration: CalibrationWire,
        now: Instant,
    ) -> Result<u8, CommandError> {
        self.require_heading()?;
        let out = self.outgoing(Request::SetCalibration(calibration))?;
        self.enqueue(out, now)
    }

    /// Asks the unit to forward its GPS receiver at `baud` (protocol v2 units with [`Capabilities::GPS`]).
    pub fn gps_start(&mut self, baud: u32, now: Instant) -> Result<u8, CommandError> {
        self.require_gps()?;
        let out = self.outgoing(Request::GpsStart { baud })?;
        self.enqueue(out, now)
    }

    /// Stops the unit's GPS forwarding.
    pub fn gps_stop(&mut self, now: Instant) -> Result<u8, CommandError> {
        self.require_gps()?;
        let out = self.outgoing(Request::GpsStop)?;
        self.enqueue(out, now)
    }

    /// The link is ready and the unit said it has `capability`; otherwise `NotSupported(what)`.
    fn require(&self, capability: Capabilities, what: &'static str) -> Result<(), CommandError> {
        self.require_ready()?;
        if self.device.is_some_and(|d| d.capabilities.contains(capability)) {
            Ok(())
        } else {
            Err(CommandError::NotSupported(what))
        }
    }

    fn require_gps(&self) -> Result<(), CommandError> {
        self.require(Capabilities::GPS, "GPS forwarding (needs a protocol v2 unit with a GPS receiver)")
    }

    fn require_heading(&self) -> Result<(), CommandError> {
        self.require(Capabilities::HEADING, "heading (needs a protocol v2 unit with a magnetometer)")
    }

    /// Fires `mask` for `duration_ms`; returns the sequence number. Checked against the limits first.
    pub fn fire(&mut self, mask: TactorMask, duration_ms: u16, now: Instant) -> Result<u8, CommandError> {
        self.require_ready()?;
        self.limits.check_fire(mask, duration_ms)?;
        let planned = planned_fire_ms(mask, duration_ms);
        self.check_runs(&planned, now)?;
        self.check_duty(&planned, now)?;
        let out = self.outgoing(Request::Fire { mask, duration_ms })?;
        let seq = self.enqueue_cue(out, now)?;
        self.ledger.truncate_after(now);
        self.ledger.record(mask, now, now + Duration::from_millis(u64::from(duration_ms)));
        self.pump(now);
        Ok(seq)
    }

    /// Plays `pattern` on the unit; returns the sequence number. Checked against the limits first.
    pub fn play(&mut self, pattern: &Pattern, now: Instant) -> Result<u8, CommandError> {
        self.require(Capabilities::PATTERNS, "patterns")?;
        self.limits.check_pattern(&pattern.frames, pattern.repeats)?;
        self.check_runs(&leading_pattern_ms(&pattern.frames, pattern.repeats), now)?;
        self.check_duty(&planned_pattern_ms(&pattern.frames, pattern.repeats), now)?;
        let out =
            self.outgoing(Request::Play { frames: pattern.frames.clone(), repeats: pattern.repeats })?;
        let seq = self.enqueue_cue(out, now)?;
        self.ledger.truncate_after(now);
        self.ledger.record_pattern(&pattern.frames, pattern.repeats, now);
        self.pump(now);
        Ok(seq)
    }

    /// Sets the drive level (0..=255) of `mask`; only on units with intensity support.
    pub fn set_intensity(&mut self, mask: TactorMask, level: u8, now: Instant) -> Result<u8, CommandError> {
        self.require(Capabilities::INTENSITY, "intensity")?;
        let out = self.outgoing(Request::SetIntensity { mask, level })?;
        self.enqueue(out, now)
    }

    /// Asks for a status report.
    pub fn request_status(&mut self, now: Instant) -> Result<u8, CommandError> {
        self.require_ready()?;
        let out = self.outgoing(Request::GetStatus)?;
        self.enqueue(out, now)
    }

    /// STOP ALL with a frame on the wire now: like [`Self::stop_all`], but when a STOP ALL is already in
    /// flight (its retry not yet due) its frame is sent again at once and its acknowledgement deadline
    /// restarts. The exit path uses it, so the last thing the unit hears is a fresh stop, whatever the
    /// retry timer says.
    pub fn stop_all_now(&mut self, now: Instant) -> Result<u8, CommandError> {
        if self.state == LinkState::Ready
            && let Some(f) = &mut self.in_flight
            && f.out.request == Request::StopAll
        {
            f.deadline = now + self.config.ack_timeout;
            let (bytes, seq) = (f.out.bytes.clone(), f.out.seq);
            self.transmit.push_back(bytes);
            self.stats.sent += 1;
            self.last_tx = Some(now);
            return Ok(seq);
        }
        self.stop_all(now)
    }

    /// Stops every tactor: cancels queued and in-flight on-commands and sends STOP ALL at once, retried
    /// until acknowledged or the link is lost. Returns the sequence number.
    pub fn stop_all(&mut self, now: Instant) -> Result<u8, CommandError> {
        if !matches!(self.state, LinkState::Handshaking | LinkState::Ready) {
            return Err(CommandError::NotReady(self.state.clone()));
        }
        if let Some(f) = &self.in_flight
            && f.out.request == Request::StopAll
        {
            return Ok(f.out.seq);
        }
        self.cancel_queued(Request::turns_on);
        self.ledger.truncate_after(now);
        let out = self.outgoing(Request::StopAll)?;
        let seq = out.seq;
        if self.state == LinkState::Handshaking {
            // Goes out first once the unit has identified itself.
            self.queue.push_front(out);
            return Ok(seq);
        }
        if let Some(f) = self.in_flight.take() {
            match f.out.request.kind() {
                CommandKind::Heartbeat => {}
                // Not a cue: keep it, it goes out after the stop.
                CommandKind::SetIntensity
                | CommandKind::GetStatus
                | CommandKind::HeadingStart
                | CommandKind::HeadingStop
                | CommandKind::SetCalibration => self.queue.push_front(f.out),
                kind => self.events.push_back(LinkEvent::Cancelled { seq: f.out.seq, kind }),
            }
        }
        self.start(out, 0, true, now);
        Ok(seq)
    }

    fn require_ready(&self) -> Result<(), CommandError> {
        if self.state == LinkState::Ready { Ok(()) } else { Err(CommandError::NotReady(self.state.clone())) }
    }

    /// What the unit drives at `now` as far as the console can know: the acknowledged cues replayed, plus the
    /// one in flight as if it will be acknowledged.
    fn unit_model_at(&self, now: Instant) -> Timeline {
        let mut model = self.unit_model.clone();
        if let Some(f) = &self.in_flight
            && let Some(schedule) = schedule_of(&f.out.request, f.first_sent)
        {
            model.advance_to(f.first_sent);
            model.replace(schedule, f.first_sent);
        }
        model.advance_to(now);
        model
    }

    /// The continuous on-time across commands: a cue sent now must not keep a tactor on past `max_on_ms`
    /// from the start of its current run.
    fn check_runs(&self, leading_ms: &[u32; TACTOR_COUNT], now: Instant) -> Result<(), CommandError> {
        self.unit_model_at(now).runs().check(leading_ms, now, &self.limits)?;
        Ok(())
    }

    fn check_duty(&mut self, planned: &[u32; TACTOR_COUNT], now: Instant) -> Result<(), CommandError> {
        let window = Duration::from_millis(u64::from(self.limits.duty_window_ms));
        self.ledger.prune(now, window);
        // What is still planned from the previous cue will be replaced: count only what already ran.
        let mut past = self.ledger.clone();
        past.truncate_after(now);
        past.check(planned, now, &self.limits)?;
        Ok(())
    }

    fn outgoing(&mut self, request: Request) -> Result<Outgoing, EncodeError> {
        let seq = self.next_seq;
        let bytes = self.codec.encode_request(seq, &request)?;
        self.next_seq = self.next_seq.wrapping_add(1);
        Ok(Outgoing { seq, request, bytes })
    }

    /// Queues a FIRE or PLAY; queued, unsent cues are superseded (the unit would replace them on arrival).
    fn enqueue_cue(&mut self, out: Outgoing, now: Instant) -> Result<u8, CommandError> {
        self.cancel_queued(|r| matches!(r, Request::Fire { .. } | Request::Play { .. }));
        self.enqueue(out, now)
    }

    fn enqueue(&mut self, out: Outgoing, now: Instant) -> Result<u8, CommandError> {
        if self.queue.len() >= self.config.max_queue {
            return Err(CommandError::QueueFull);
        }
        let seq = out.seq;
        self.queue.push_back(out);
        self.pump(now);
        Ok(seq)
    }

    fn cancel_queued(&mut self, which: impl Fn(&Request) -> bool) {
        let mut kept = VecDeque::with_capacity(self.queue.len());
        for out in self.queue.drain(..) {
            if which(&out.request) {
                self.events.push_back(LinkEvent::Cancelled { seq: out.seq, kind: out.request.kind() });
            } else {
                kept.push_back(out);
            }
        }
        self.queue = kept;
    }

    fn start(&mut self, out: Outgoing, retries: u8, persistent: bool, now: Instant) {
        self.transmit.push_back(out.bytes.clone());
        self.stats.sent += 1;
        self.last_tx = Some(now);
        self.in_flight = Some(InFlight {
            out,
            deadline: now + self.config.ack_timeout,
            retries_left: retries,
            persistent,
            first_sent: now,
        });
    }

    /// Sends the next queued command, or a heartbeat when idle.
    fn pump(&mut self, now: Instant) {
        if self.in_flight.is_some() {
            return;
        }
        match self.state {
            LinkState::Ready => {}
            _ => return,
        }
        if let Some(out) = self.queue.pop_front() {
            let persistent = out.request == Request::StopAll;
            self.start(out, self.config.max_retries, persistent, now);
        } else if self.last_tx.is_none_or(|t| now >= t + self.heartbeat_interval)
            && let Ok(out) = self.outgoing(Request::Heartbeat)
        {
            self.start(out, 0, false, now);
        }
    }

    fn set_tactors(&mut self, mask: TactorMask) {
        if self.tactors_on != Some(mask) {
            self.tactors_on = Some(mask);
            self.events.push_back(LinkEvent::TactorsOn(mask));
        }
    }

    fn set_state(&mut self, state: LinkState) {
        if self.state != state {
            self.state = state.clone();
            self.events.push_back(LinkEvent::State(state));
        }
    }

    /// Reports every pending command as not delivered and forgets it.
    fn abandon_all(&mut self) {
        if let Some(f) = self.in_flight.take()
            && !matches!(f.out.request, Request::Heartbeat | Request::Hello)
        {
            self.events.push_back(LinkEvent::NotDelivered { seq: f.out.seq, kind: f.out.request.kind() });
        }
        for out in self.queue.drain(..) {
            if out.request != Request::GetStatus {
                self.events.push_back(LinkEvent::NotDelivered { seq: out.seq, kind: out.request.kind() });
            }
        }
    }

    fn lose(&mut self, reason: String) {
        self.abandon_all();
        self.transmit.clear();
        self.codec.reset();
        self.tactors_on = None;
        self.set_state(LinkState::Lost { reason });
    }
}

/// What `request`, once run by the unit from `start`, makes it drive; `None` if it changes nothing.
fn schedule_of(request: &Request, start: Instant) -> Option<Schedule> {
    match request {
        Request::Fire { mask, duration_ms } => Some(Schedule::fire(*mask, *duration_ms, start)),
        Request::Play { frames, repeats } => {
            Some(Schedule::Pattern { frames: frames.clone(), repeats: *repeats, start })
        }
        Request::Hello | Request::StopAll => Some(Schedule::Idle),
        Request::Heartbeat
        | Request::SetIntensity { .. }
        | Request::GetStatus
        | Request::HeadingStart { .. }
        | Request::HeadingStop
        | Request::SetCalibration(_)
        | Request::GpsStart { .. }
        | Request::GpsStop => None,
    }
}

fn unreachable_hello() -> Outgoing {
    // HELLO has an empty payload and always encodes; keep the signature panic-free anyway.
    Outgoing { seq: 0, request: Request::Hello, bytes: Vec::new() }
}

pub use crate::backoff::Backoff;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_and_caps() {
        let mut b = Backoff::new(Duration::from_millis(100), Duration::from_secs(1));
        let got: Vec<u128> = (0..6).map(|_| b.next_delay().as_millis()).collect();
        assert_eq!(got, vec![100, 200, 400, 800, 1000, 1000]);
        b.reset();
        assert_eq!(b.next_delay(), Duration::from_millis(100));
        for _ in 0..100 {
            b.next_delay();
        }
        assert_eq!(b.next_delay(), Duration::from_secs(1));
    }

    #[test]
    fn commands_before_ready_are_refused() {
        let mut link = Link::new(LinkConfig::default());
        let now = Instant::now();
        assert!(matches!(link.fire(TactorMask(1), 100, now), Err(CommandError::NotReady(_))));
        assert!(link.stop_all(now).is_err());
    }

    /// The exit path's STOP ALL goes on the wire at once even while an earlier STOP ALL waits for its
    /// retry: a unit that never acknowledges still hears a fresh stop as the console goes.
    #[test]
    fn a_stop_in_flight_is_sent_again_at_once_on_exit() {
        use crate::wtcu::engine::{Engine, EngineConfig};
        let mut link = Link::new(LinkConfig::default());
        let mut unit = Engine::new(EngineConfig::default());
        let mut now = Instant::now();
        link.connect(now);
        for _ in 0..50 {
            while let Some(b) = link.poll_transmit() {
                unit.handle_bytes(&b, now);
            }
            unit.handle_timeout(now);
            while let Some(b) = unit.poll_transmit() {
                link.handle_bytes(&b, now);
            }
            if link.is_ready() {
                break;
            }
            now += Duration::from_millis(10);
            link.handle_timeout(now);
        }
        assert!(link.is_ready());
        while link.poll_transmit().is_some() {}
        let seq = link.stop_all(now).unwrap();
        let first = link.poll_transmit().expect("the first STOP ALL frame");
        // The unit never answers; a plain stop_all before the retry is due sends nothing new.
        assert_eq!(link.stop_all(now).unwrap(), seq);
        assert!(link.poll_transmit().is_none());
        // The exit path's does, the same frame (same sequence number).
        assert_eq!(link.stop_all_now(now).unwrap(), seq);
        assert_eq!(link.poll_transmit().as_deref(), Some(first.as_slice()));
    }
}
