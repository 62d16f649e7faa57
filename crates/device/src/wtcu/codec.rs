//! Wire codecs: messages to bytes and back. The link and the engine use a codec only through
//! [`WireCodec`], so another firmware's framing can be added as another implementation.
//!
//! [`FrameCodec`] is vestnav's own framing (protocol versions 1 and 2; the header carries the version) (see `docs/wtcu-protocol.md`):
//!
//! ```text
//! wire:    0x00 | COBS(packet) | 0x00
//! packet:  version(1) | type(1) | seq(1) | len(1) | payload(len) | crc16(2, little-endian)
//! ```
//!
//! The CRC is CRC-16/IBM-3740 (also known as CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, not reflected,
//! no final xor; check value of "123456789" = 0x29B1) over `version..payload`. Integers are little-endian.
//! COBS (Cheshire & Baker, 1999) removes every 0x00 from the packet so 0x00 only ever delimits frames; the
//! leading delimiter terminates any half frame left on the line (a link that dropped mid-frame).

use vestnav_core::vest::{Frame, TactorMask};

use super::limits::Limits;
use super::message::{
    CalibrationWire, Capabilities, DeviceInfo, Faults, FirmwareVersion, HeadingReport, MAX_GPS_CHUNK,
    NakReason, Packet, Reply, Request, UnitStatus,
};

/// The newest protocol version this build speaks (written in every header unless a peer negotiated lower).
pub const PROTOCOL_VERSION: u8 = 2;
/// The oldest protocol version this build still speaks.
pub const MIN_PROTOCOL_VERSION: u8 = 1;
/// Largest payload of one packet (bytes).
pub const MAX_PAYLOAD: usize = 200;
/// Largest packet: header (4) + payload + CRC (2).
pub const MAX_PACKET: usize = 4 + MAX_PAYLOAD + 2;
/// Largest COBS-encoded packet (one overhead byte per 254 bytes, rounded up).
pub const MAX_ENCODED: usize = MAX_PACKET + MAX_PACKET / 254 + 1;

/// The CRC used by [`FrameCodec`]: CRC-16/IBM-3740 (CCITT-FALSE).
pub const CRC16: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Message type codes of [`FrameCodec`].
pub mod msg_type {
    /// Console: open a session.
    pub const HELLO: u8 = 0x01;
    /// Console: keep the watchdog fed.
    pub const HEARTBEAT: u8 = 0x02;
    /// Console: fire a mask for a duration.
    pub const FIRE: u8 = 0x03;
    /// Console: play a pattern.
    pub const PLAY: u8 = 0x04;
    /// Console: set the drive level of a mask.
    pub const SET_INTENSITY: u8 = 0x05;
    /// Console: stop everything.
    pub const STOP_ALL: u8 = 0x06;
    /// Console: ask for the status.
    pub const GET_STATUS: u8 = 0x07;
    /// Unit: answer to HELLO.
    pub const IDENTIFY: u8 = 0x81;
    /// Unit: accepted.
    pub const ACK: u8 = 0x82;
    /// Unit: refused.
    pub const NAK: u8 = 0x83;
    /// Unit: answer to `GET_STATUS`.
    pub const STATUS: u8 = 0x84;
    /// Console (v2): start the heading stream.
    pub const HEADING_START: u8 = 0x08;
    /// Console (v2): stop the heading stream.
    pub const HEADING_STOP: u8 = 0x09;
    /// Console (v2): load a magnetometer calibration.
    pub const SET_CALIBRATION: u8 = 0x0A;
    /// Unit (v2): one heading reading.
    pub const HEADING: u8 = 0x86;
    /// Console (v2): start forwarding the unit's GPS receiver.
    pub const GPS_START: u8 = 0x0B;
    /// Console (v2): stop forwarding the GPS receiver.
    pub const GPS_STOP: u8 = 0x0C;
    /// Unit (v2): a chunk of the GPS receiver's bytes.
    pub const GPS_DATA: u8 = 0x87;
    /// Unit: unsolicited change of the running tactors.
    pub const REPORT: u8 = 0x85;
}

/// Why a frame could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The bytes between two delimiters are not valid COBS.
    #[error("invalid COBS encoding")]
    Cobs,
    /// The frame is shorter than a header and a CRC.
    #[error("frame too short ({len} bytes)")]
    TooShort {
        /// Decoded length (bytes).
        len: usize,
    },
    /// More bytes than the largest frame arrived without a delimiter; they were discarded.
    #[error("frame too long (no delimiter within {MAX_ENCODED} bytes)")]
    Overlong,
    /// The CRC does not match.
    #[error("bad CRC: computed 0x{computed:04X}, found 0x{found:04X}")]
    BadCrc {
        /// CRC of the received bytes.
        computed: u16,
        /// CRC in the frame.
        found: u16,
    },
    /// The header's length does not match the frame.
    #[error("length field {declared} does not match the {actual} payload bytes")]
    LengthMismatch {
        /// Length in the header.
        declared: usize,
        /// Payload bytes present.
        actual: usize,
    },
    /// The header's protocol version is not ours.
    #[error("unsupported protocol version {version}")]
    Version {
        /// Version in the header.
        version: u8,
        /// Sequence number in the header (the CRC was valid).
        seq: u8,
    },
    /// The message type is unknown.
    #[error("unknown message type 0x{kind:02X}")]
    UnknownType {
        /// Type code.
        kind: u8,
        /// Sequence number in the header (the CRC was valid).
        seq: u8,
    },
    /// The payload does not fit the message type.
    #[error("malformed payload for message type 0x{kind:02X}")]
    Malformed {
        /// Type code.
        kind: u8,
        /// Sequence number in the header (the CRC was valid).
        seq: u8,
    },
}

impl DecodeError {
    /// The sequence number of the frame, when its CRC was valid (so the header can be trusted).
    pub fn seq(&self) -> Option<u8> {
        match self {
            Self::Version { seq, .. } | Self::UnknownType { seq, .. } | Self::Malformed { seq, .. } => {
                Some(*seq)
            }
            _ => None,
        }
    }

    /// The NAK a unit answers this error with, if any: structural garbage (bad COBS, too short, overlong)
    /// gets none, because nothing in it can be trusted to be a frame at all.
    pub fn nak_reason(&self) -> Option<NakReason> {
        match self {
            Self::BadCrc { .. } | Self::LengthMismatch { .. } => Some(NakReason::BadCrc),
            Self::Version { .. } => Some(NakReason::UnsupportedVersion),
            Self::UnknownType { .. } => Some(NakReason::UnknownCommand),
            Self::Malformed { .. } => Some(NakReason::Malformed),
            Self::Cobs | Self::TooShort { .. } | Self::Overlong => None,
        }
    }
}

/// A request too large for one frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("message payload of {len} bytes exceeds the frame limit of {MAX_PAYLOAD}")]
pub struct EncodeError {
    /// Payload length (bytes).
    pub len: usize,
}

/// A wire protocol: encodes messages into complete frames and decodes a byte stream into messages.
///
/// One instance serves one side of one connection: it keeps the partial frame between calls.
pub trait WireCodec: Send {
    /// Encodes a request as one complete frame.
    fn encode_request(&self, seq: u8, request: &Request) -> Result<Vec<u8>, EncodeError>;
    /// Encodes a reply as one complete frame.
    fn encode_reply(&self, seq: u8, reply: &Reply) -> Vec<u8>;
    /// Feeds received bytes and appends every request they complete (console-to-unit direction).
    fn decode_requests(&mut self, bytes: &[u8], out: &mut Vec<Result<Packet<Request>, DecodeError>>);
    /// Feeds received bytes and appends every reply they complete (unit-to-console direction).
    fn decode_replies(&mut self, bytes: &[u8], out: &mut Vec<Result<Packet<Reply>, DecodeError>>);
    /// Drops any partial frame (a new connection).
    fn reset(&mut self);
    /// Writes `version` in the headers from now on (clamped to the versions the codec speaks): the version
    /// a session negotiated.
    fn set_version(&mut self, version: u8);
    /// The version written in headers now.
    fn version(&self) -> u8;
}

/// COBS-encodes `data` into `out` (no delimiters).
///
/// Consistent Overhead Byte Stuffing (Cheshire & Baker, IEEE/ACM Transactions on Networking, 1999): each run of up to 254 non-zero
/// bytes is preceded by a code byte = run length + 1; a code below 0xFF implies a zero after the run.
pub fn cobs_encode(data: &[u8], out: &mut Vec<u8>) {
    let mut code_at = out.len();
    out.push(0);
    let mut code: u8 = 1;
    for &b in data {
        if b == 0 {
            out[code_at] = code;
            code_at = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_at] = code;
}

/// Decodes one COBS block (no delimiters); `None` if it is not valid COBS.
pub fn cobs_decode(data: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(data.len());
    let mut i = 0;
    while i < data.len() {
        let code = usize::from(data[i]);
        // A zero code is impossible; a run reaching past the end is a truncated frame.
        if code == 0 || i + code > data.len() {
            return None;
        }
        out.extend_from_slice(data.get(i + 1..i + code)?);
        i += code;
        if code < 0xFF && i < data.len() {
            out.push(0);
        }
    }
    Some(out)
}

/// Splits a byte stream at 0x00 delimiters, bounding the size of a partial frame.
#[derive(Debug, Clone, Default)]
pub struct Framer {
    buf: Vec<u8>,
    discarding: bool,
}

impl Framer {
    /// Feeds bytes; `on_block` gets each complete non-empty block, or `Err(Overlong)` once per discarded run.
    pub fn feed(&mut self, bytes: &[u8], mut on_block: impl FnMut(Result<&[u8], DecodeError>)) {
        for &b in bytes {
            if b == 0 {
                if !self.discarding && !self.buf.is_empty() {
                    on_block(Ok(&self.buf));
                }
                self.buf.clear();
                self.discarding = false;
            } else if !self.discarding {
                if self.buf.len() >= MAX_ENCODED {
                    self.buf.clear();
                    self.discarding = true;
                    on_block(Err(DecodeError::Overlong));
                } else {
                    self.buf.push(b);
                }
            }
        }
    }

    /// Drops the partial frame.
    pub fn reset(&mut self) {
        self.buf.clear();
        self.discarding = false;
    }
}

/// vestnav's WTCU framing, protocol versions 1 and 2 (see the module doc and `docs/wtcu-protocol.md`).
///
/// It writes its current [`FrameCodec::version`] in every header and accepts frames of any version from
/// [`MIN_PROTOCOL_VERSION`] up to its `max_version`; the v2 message types are known only in v2 frames, so a
/// codec limited to v1 decodes exactly as a v1 unit does.
#[derive(Debug, Clone)]
pub struct FrameCodec {
    framer: Framer,
    version: u8,
    max_version: u8,
}

impl Default for FrameCodec {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameCodec {
    /// A codec speaking the newest version, [`PROTOCOL_VERSION`].
    pub fn new() -> Self {
        Self::with_max_version(PROTOCOL_VERSION)
    }

    /// A codec that speaks at most `max_version` (clamped to the versions this build knows): what a unit
    /// with older firmware is.
    pub fn with_max_version(max_version: u8) -> Self {
        let max_version = max_version.clamp(MIN_PROTOCOL_VERSION, PROTOCOL_VERSION);
        Self { framer: Framer::default(), version: max_version, max_version }
    }

    /// The newest version accepted.
    pub fn max_version(&self) -> u8 {
        self.max_version
    }
}

/// Builds a complete frame from a version, type, sequence number and payload (payload <= [`MAX_PAYLOAD`]).
fn frame(version: u8, kind: u8, seq: u8, payload: &[u8]) -> Vec<u8> {
    let mut packet = Vec::with_capacity(payload.len() + 6);
    packet.extend_from_slice(&[version, kind, seq, payload.len() as u8]);
    packet.extend_from_slice(payload);
    let crc = CRC16.checksum(&packet);
    packet.extend_from_slice(&crc.to_le_bytes());
    let mut out = Vec::with_capacity(packet.len() + 4);
    out.push(0);
    cobs_encode(&packet, &mut out);
    out.push(0);
    out
}

/// Checks a decoded block and splits it into (version, type, seq, payload).
fn unpack(block: &[u8], max_version: u8) -> Result<(u8, u8, u8, Vec<u8>), DecodeError> {
    let packet = cobs_decode(block).ok_or(DecodeError::Cobs)?;
    if packet.len() < 6 {
        return Err(DecodeError::TooShort { len: packet.len() });
    }
    let (body, crc_bytes) = packet.split_at(packet.len() - 2);
    let found = u16::from_le_bytes([crc_bytes[0], crc_bytes[1]]);
    let computed = CRC16.checksum(body);
    if computed != found {
        return Err(DecodeError::BadCrc { computed, found });
    }
    let (version, kind, seq, declared) = (body[0], body[1], body[2], usize::from(body[3]));
    let payload = &body[4..];
    if declared != payload.len() {
        return Err(DecodeError::LengthMismatch { declared, actual: payload.len() });
    }
    if !(MIN_PROTOCOL_VERSION..=max_version).contains(&version) {
        return Err(DecodeError::Version { version, seq });
    }
    Ok((version, kind, seq, payload.to_vec()))
}

/// Little-endian reader over a payload; every read is checked.
struct Reader<'a> {
    data: &'a [u8],
}

impl Reader<'_> {
    fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.data.split_first()?;
        self.data = rest;
        Some(b)
    }

    fn u16(&mut self) -> Option<u16> {
        let lo = self.u8()?;
        let hi = self.u8()?;
        Some(u16::from_le_bytes([lo, hi]))
    }

    fn i16(&mut self) -> Option<i16> {
        self.u16().map(u16::cast_signed)
    }

    fn u32(&mut self) -> Option<u32> {
        let lo = self.u16()?;
        let hi = self.u16()?;
        Some(u32::from(lo) | (u32::from(hi) << 16))
    }

    fn rest(&mut self) -> &[u8] {
        std::mem::take(&mut self.data)
    }

    fn done(&self) -> Option<()> {
        self.data.is_empty().then_some(())
    }
}

// Outer `None`: malformed payload; inner `None`: unknown type (the `?` on each field keeps it short).
#[allow(clippy::option_option)]
fn parse_request(version: u8, kind: u8, payload: &[u8]) -> Option<Option<Request>> {
    use msg_type::{
        FIRE, GET_STATUS, GPS_START, GPS_STOP, HEADING_START, HEADING_STOP, HEARTBEAT, HELLO, PLAY,
        SET_CALIBRATION, SET_INTENSITY, STOP_ALL,
    };
    let mut r = Reader { data: payload };
    let v2 = version >= 2;
    let req = match kind {
        HELLO => Request::Hello,
        HEARTBEAT => Request::Heartbeat,
        FIRE => Request::Fire { mask: TactorMask(r.u16()?), duration_ms: r.u16()? },
        PLAY => {
            let repeats = r.u8()?;
            let count = r.u8()?;
            let mut frames = Vec::with_capacity(usize::from(count));
            for _ in 0..count {
                frames.push(Frame { mask: TactorMask(r.u16()?), duration_ms: r.u16()? });
            }
            Request::Play { frames, repeats }
        }
        SET_INTENSITY => Request::SetIntensity { mask: TactorMask(r.u16()?), level: r.u8()? },
        STOP_ALL => Request::StopAll,
        GET_STATUS => Request::GetStatus,
        HEADING_START if v2 => Request::HeadingStart { rate_hz: r.u8()? },
        HEADING_STOP if v2 => Request::HeadingStop,
        SET_CALIBRATION if v2 => {
            let mut c = CalibrationWire::default();
            for v in c.hard_iron_dut.iter_mut().chain(c.soft_iron_q12.iter_mut()) {
                *v = r.i16()?;
            }
            c.field_dut = r.u16()?;
            Request::SetCalibration(c)
        }
        GPS_START if v2 => Request::GpsStart { baud: r.u32()? },
        GPS_STOP if v2 => Request::GpsStop,
        _ => return Some(None),
    };
    r.done()?;
    Some(Some(req))
}

#[allow(clippy::option_option)]
fn parse_reply(version: u8, kind: u8, payload: &[u8]) -> Option<Option<Reply>> {
    use msg_type::{ACK, GPS_DATA, HEADING, IDENTIFY, NAK, REPORT, STATUS};
    let mut r = Reader { data: payload };
    let reply = match kind {
        IDENTIFY => {
            let firmware = FirmwareVersion { major: r.u8()?, minor: r.u8()?, patch: r.u8()? };
            let tactor_count = r.u8()?;
            let capabilities = Capabilities(r.u8()?);
            let limits = Limits {
                max_on_ms: r.u16()?,
                max_simultaneous: r.u8()?,
                duty_window_ms: r.u16()?,
                max_duty_on_ms: r.u16()?,
                max_pattern_frames: r.u8()?,
                max_pattern_ms: r.u16()?,
            };
            let watchdog_ms = r.u16()?;
            Reply::Identify(DeviceInfo {
                protocol_version: version,
                firmware,
                tactor_count,
                capabilities,
                limits,
                watchdog_ms,
            })
        }
        ACK => Reply::Ack { tactors_on: TactorMask(r.u16()?) },
        NAK => Reply::Nak { reason: NakReason::from_code(r.u8()?), tactors_on: TactorMask(r.u16()?) },
        STATUS => Reply::Status(UnitStatus {
            battery_mv: r.u16()?,
            battery_pct: r.u8()?,
            tactors_on: TactorMask(r.u16()?),
            faults: Faults(r.u8()?),
            firmware: FirmwareVersion { major: r.u8()?, minor: r.u8()?, patch: r.u8()? },
        }),
        REPORT => Reply::Report { tactors_on: TactorMask(r.u16()?), faults: Faults(r.u8()?) },
        HEADING if version >= 2 => {
            let report = HeadingReport {
                heading_cdeg: r.u16()?,
                pitch_cdeg: r.i16()?,
                roll_cdeg: r.i16()?,
                quality_pct: r.u8()?,
                raw_mag_dut: [r.i16()?, r.i16()?, r.i16()?],
            };
            // Out-of-range numbers are a malformed payload: refused here, never shown as a heading.
            if !report.is_valid() {
                return None;
            }
            Reply::Heading(report)
        }
        GPS_DATA if version >= 2 => {
            let lost = r.u16()?;
            let data = r.rest().to_vec();
            // An empty chunk says nothing; a longer one cannot come from a conforming unit.
            if data.is_empty() || data.len() > MAX_GPS_CHUNK {
                return None;
            }
            Reply::GpsData { lost, data }
        }
        _ => return Some(None),
    };
    r.done()?;
    Some(Some(reply))
}

/// Parses a block with `parse` (given the header's version, type and payload), which returns `None` for a
/// malformed payload and `Some(None)` for an unknown type.
#[allow(clippy::option_option)]
fn decode_block<M>(
    block: Result<&[u8], DecodeError>,
    max_version: u8,
    parse: fn(u8, u8, &[u8]) -> Option<Option<M>>,
) -> Result<Packet<M>, DecodeError> {
    let (version, kind, seq, payload) = unpack(block?, max_version)?;
    match parse(version, kind, &payload) {
        Some(Some(message)) => Ok(Packet { version, seq, message }),
        Some(None) => Err(DecodeError::UnknownType { kind, seq }),
        None => Err(DecodeError::Malformed { kind, seq }),
    }
}

impl WireCodec for FrameCodec {
    fn encode_request(&self, seq: u8, request: &Request) -> Result<Vec<u8>, EncodeError> {
        use msg_type::{
            FIRE, GET_STATUS, GPS_START, GPS_STOP, HEADING_START, HEADING_STOP, HEARTBEAT, HELLO, PLAY,
            SET_CALIBRATION, SET_INTENSITY, STOP_ALL,
        };
        let mut p = Vec::new();
        let kind = match request {
            Request::Hello => HELLO,
            Request::Heartbeat => HEARTBEAT,
            Request::Fire { mask, duration_ms } => {
                p.extend_from_slice(&mask.0.to_le_bytes());
                p.extend_from_slice(&duration_ms.to_le_bytes());
                FIRE
            }
            Request::Play { frames, repeats } => {
                let count =
                    u8::try_from(frames.len()).map_err(|_| EncodeError { len: 2 + 4 * frames.len() })?;
                p.extend_from_slice(&[*repeats, count]);
                for f in frames {
                    p.extend_from_slice(&f.mask.0.to_le_bytes());
                    p.extend_from_slice(&f.duration_ms.to_le_bytes());
                }
                PLAY
            }
            Request::SetIntensity { mask, level } => {
                p.extend_from_slice(&mask.0.to_le_bytes());
                p.push(*level);
                SET_INTENSITY
            }
            Request::StopAll => STOP_ALL,
            Request::GetStatus => GET_STATUS,
            Request::HeadingStart { rate_hz } => {
                p.push(*rate_hz);
                HEADING_START
            }
            Request::HeadingStop => HEADING_STOP,
            Request::SetCalibration(c) => {
                for v in c.hard_iron_dut.iter().chain(&c.soft_iron_q12) {
                    p.extend_from_slice(&v.to_le_bytes());
                }
                p.extend_from_slice(&c.field_dut.to_le_bytes());
                SET_CALIBRATION
            }
            Request::GpsStart { baud } => {
                p.extend_from_slice(&baud.to_le_bytes());
                GPS_START
            }
            Request::GpsStop => GPS_STOP,
        };
        if p.len() > MAX_PAYLOAD {
            return Err(EncodeError { len: p.len() });
        }
        Ok(frame(self.version, kind, seq, &p))
    }

    fn encode_reply(&self, seq: u8, reply: &Reply) -> Vec<u8> {
        use msg_type::{ACK, GPS_DATA, HEADING, IDENTIFY, NAK, REPORT, STATUS};
        let mut p = Vec::new();
        let kind = match reply {
            Reply::Identify(info) => {
                let l = &info.limits;
                p.extend_from_slice(&[info.firmware.major, info.firmware.minor, info.firmware.patch]);
                p.extend_from_slice(&[info.tactor_count, info.capabilities.0]);
                p.extend_from_slice(&l.max_on_ms.to_le_bytes());
                p.push(l.max_simultaneous);
                p.extend_from_slice(&l.duty_window_ms.to_le_bytes());
                p.extend_from_slice(&l.max_duty_on_ms.to_le_bytes());
                p.push(l.max_pattern_frames);
                p.extend_from_slice(&l.max_pattern_ms.to_le_bytes());
                p.extend_from_slice(&info.watchdog_ms.to_le_bytes());
                IDENTIFY
            }
            Reply::Ack { tactors_on } => {
                p.extend_from_slice(&tactors_on.0.to_le_bytes());
                ACK
            }
            Reply::Nak { reason, tactors_on } => {
                p.push(reason.code());
                p.extend_from_slice(&tactors_on.0.to_le_bytes());
                NAK
            }
            Reply::Status(s) => {
                p.extend_from_slice(&s.battery_mv.to_le_bytes());
                p.push(s.battery_pct);
                p.extend_from_slice(&s.tactors_on.0.to_le_bytes());
                p.push(s.faults.0);
                p.extend_from_slice(&[s.firmware.major, s.firmware.minor, s.firmware.patch]);
                STATUS
            }
            Reply::Report { tactors_on, faults } => {
                p.extend_from_slice(&tactors_on.0.to_le_bytes());
                p.push(faults.0);
                REPORT
            }
            Reply::Heading(h) => {
                p.extend_from_slice(&h.heading_cdeg.to_le_bytes());
                p.extend_from_slice(&h.pitch_cdeg.to_le_bytes());
                p.extend_from_slice(&h.roll_cdeg.to_le_bytes());
                p.push(h.quality_pct);
                for v in h.raw_mag_dut {
                    p.extend_from_slice(&v.to_le_bytes());
                }
                HEADING
            }
            Reply::GpsData { lost, data } => {
                p.extend_from_slice(&lost.to_le_bytes());
                // A unit never builds a longer chunk; cut rather than exceed the frame limit.
                p.extend_from_slice(&data[..data.len().min(MAX_GPS_CHUNK)]);
                GPS_DATA
            }
        };
        frame(self.version, kind, seq, &p)
    }

    fn decode_requests(&mut self, bytes: &[u8], out: &mut Vec<Result<Packet<Request>, DecodeError>>) {
        let max = self.max_version;
        self.framer.feed(bytes, |block| out.push(decode_block(block, max, parse_request)));
    }

    fn decode_replies(&mut self, bytes: &[u8], out: &mut Vec<Result<Packet<Reply>, DecodeError>>) {
        let max = self.max_version;
        self.framer.feed(bytes, |block| out.push(decode_block(block, max, parse_reply)));
    }

    fn reset(&mut self) {
        self.framer.reset();
    }

    fn set_version(&mut self, version: u8) {
        self.version = version.clamp(MIN_PROTOCOL_VERSION, self.max_version);
    }

    fn version(&self) -> u8 {
        self.version
    }
}

/// Lower-case hex of `bytes` separated by spaces (for logs and the protocol document).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_ibm_3740_by_its_check_value() {
        // The catalogue's check value for CRC-16/IBM-3740 (reveng.sourceforge.io/crc-catalogue).
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
    }

    #[test]
    fn cobs_matches_the_paper_examples() {
        // Examples from the COBS paper / Wikipedia's table.
        let cases: [(&[u8], &[u8]); 5] = [
            (&[0x00], &[0x01, 0x01]),
            (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
            (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
            (&[0x11, 0x22, 0x33, 0x44], &[0x05, 0x11, 0x22, 0x33, 0x44]),
            (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
        ];
        for (raw, enc) in cases {
            let mut out = Vec::new();
            cobs_encode(raw, &mut out);
            assert_eq!(out, enc);
            assert_eq!(cobs_decode(enc).unwrap(), raw);
        }
        let long: Vec<u8> = (1..=254).collect();
        let mut out = Vec::new();
        cobs_encode(&long, &mut out);
        assert_eq!(out.len(), 256);
        assert_eq!(out[0], 0xFF);
        assert_eq!(cobs_decode(&out).unwrap(), long);
    }

    #[test]
    fn cobs_rejects_truncated_runs() {
        assert_eq!(cobs_decode(&[0x05, 0x11, 0x22]), None);
        assert_eq!(cobs_decode(&[0x00]), None);
    }
}
