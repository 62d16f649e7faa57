//! The protocol's messages, independent of how they are framed on the wire.
//!
//! [`Request`]s go from the console to the unit, [`Reply`]s from the unit to the console. A wire codec
//! ([`super::codec::WireCodec`]) turns them into bytes; the link and the device engine only see these types,
//! so another firmware's framing can be added without touching them.

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{Frame, TactorMask};

use super::limits::Limits;

/// A message from the console to the unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// Opens a session: the unit answers with [`Reply::Identify`].
    Hello,
    /// Keeps the unit's watchdog fed; answered with [`Reply::Ack`].
    Heartbeat,
    /// Turns `mask` on for `duration_ms`, replacing whatever was running.
    Fire {
        /// Tactors to turn on (an empty mask turns everything off).
        mask: TactorMask,
        /// How long they stay on (ms); bounded by [`Limits::max_on_ms`].
        duration_ms: u16,
    },
    /// Plays `frames` `repeats` times, replacing whatever was running.
    Play {
        /// The frames, in order.
        frames: Vec<Frame>,
        /// How many times the frames are played (at least 1).
        repeats: u8,
    },
    /// Sets the drive level of `mask` (units with [`Capabilities::INTENSITY`] only).
    SetIntensity {
        /// Tactors whose level is set.
        mask: TactorMask,
        /// Drive level, 0 (silent) ..= 255 (full).
        level: u8,
    },
    /// Turns every tactor off and ends any pattern.
    StopAll,
    /// Asks for a [`Reply::Status`].
    GetStatus,
    /// Protocol v2: starts the unit's [`Reply::Heading`] stream at `rate_hz` (1..=10) reports per second
    /// (units with [`Capabilities::HEADING`] only).
    HeadingStart {
        /// Reports per second, 1..=10.
        rate_hz: u8,
    },
    /// Protocol v2: stops the heading stream.
    HeadingStop,
    /// Protocol v2: loads a hard/soft-iron calibration into the unit's magnetometer processing (kept until
    /// the next one or a power cycle).
    SetCalibration(CalibrationWire),
    /// Protocol v2: opens the unit's GPS receiver UART at `baud` and starts forwarding its bytes as
    /// [`Reply::GpsData`] (units with [`Capabilities::GPS`] only).
    GpsStart {
        /// The receiver's baud rate, one of [`GPS_BAUDS`].
        baud: u32,
    },
    /// Protocol v2: stops the GPS forwarding.
    GpsStop,
}

/// The GPS receiver baud rates a unit accepts in [`Request::GpsStart`].
pub const GPS_BAUDS: [u32; 6] = [4800, 9600, 19_200, 38_400, 57_600, 115_200];

/// Most receiver bytes in one [`Reply::GpsData`] (the payload's 200 bytes minus the `lost` counter).
pub const MAX_GPS_CHUNK: usize = 198;

/// A magnetometer calibration in the protocol's fixed-point form (`h = W (m - b)`; see
/// `docs/wtcu-protocol.md`). Its one home is `vestnav_core::compass`, with the conversions.
pub use vestnav_core::compass::CalibrationWire;

/// One heading report of a unit's tilt-compensated magnetometer, as it travels on the wire (protocol v2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeadingReport {
    /// Magnetic heading of the vest's forward axis, 0..36000 centi-degrees.
    pub heading_cdeg: u16,
    /// Pitch, nose up positive, -9000..=9000 centi-degrees.
    pub pitch_cdeg: i16,
    /// Roll, right side down positive, -18000..=18000 centi-degrees.
    pub roll_cdeg: i16,
    /// Calibration/field quality 0..=100 (0 while uncalibrated).
    pub quality_pct: u8,
    /// The raw (uncalibrated) magnetometer reading, body frame x forward, y right, z down, in 0.1 µT: what
    /// the console's calibration fit works on.
    pub raw_mag_dut: [i16; 3],
}

impl HeadingReport {
    /// The reading as the one heading type of the console, received at `received_at`.
    pub fn to_attitude(&self, received_at: std::time::Instant) -> crate::heading::Attitude {
        crate::heading::Attitude {
            heading_deg: f64::from(self.heading_cdeg) / 100.0,
            reference: crate::heading::HeadingReference::Magnetic,
            pitch_deg: Some(f64::from(self.pitch_cdeg) / 100.0),
            roll_deg: Some(f64::from(self.roll_cdeg) / 100.0),
            quality_pct: Some(self.quality_pct),
            field_ut: None,
            raw_mag_ut: Some(self.raw_mag_dut.map(|v| f64::from(v) / 10.0)),
            origin: crate::heading::HeadingOrigin::Vest,
            received_at,
        }
    }

    /// Whether every field is in its range (the decoder refuses a report that is not).
    pub fn is_valid(&self) -> bool {
        self.heading_cdeg < 36_000
            && self.pitch_cdeg.unsigned_abs() <= 9_000
            && self.roll_cdeg.unsigned_abs() <= 18_000
            && self.quality_pct <= 100
    }
}

impl Request {
    /// What kind of request this is.
    pub fn kind(&self) -> CommandKind {
        match self {
            Self::Hello => CommandKind::Hello,
            Self::Heartbeat => CommandKind::Heartbeat,
            Self::Fire { .. } => CommandKind::Fire,
            Self::Play { .. } => CommandKind::Play,
            Self::SetIntensity { .. } => CommandKind::SetIntensity,
            Self::StopAll => CommandKind::StopAll,
            Self::GetStatus => CommandKind::GetStatus,
            Self::HeadingStart { .. } => CommandKind::HeadingStart,
            Self::HeadingStop => CommandKind::HeadingStop,
            Self::SetCalibration(_) => CommandKind::SetCalibration,
            Self::GpsStart { .. } => CommandKind::GpsStart,
            Self::GpsStop => CommandKind::GpsStop,
        }
    }

    /// Whether the request can turn a tactor on (and so is cancelled by STOP ALL).
    pub fn turns_on(&self) -> bool {
        matches!(self, Self::Fire { mask, .. } if !mask.is_empty()) || matches!(self, Self::Play { .. })
    }
}

/// The kinds of [`Request`], for events and logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CommandKind {
    /// [`Request::Hello`].
    Hello,
    /// [`Request::Heartbeat`].
    Heartbeat,
    /// [`Request::Fire`].
    Fire,
    /// [`Request::Play`].
    Play,
    /// [`Request::SetIntensity`].
    SetIntensity,
    /// [`Request::StopAll`].
    StopAll,
    /// [`Request::GetStatus`].
    GetStatus,
    /// [`Request::HeadingStart`].
    HeadingStart,
    /// [`Request::HeadingStop`].
    HeadingStop,
    /// [`Request::SetCalibration`].
    SetCalibration,
    /// [`Request::GpsStart`].
    GpsStart,
    /// [`Request::GpsStop`].
    GpsStop,
}

impl CommandKind {
    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Hello => "hello",
            Self::Heartbeat => "heartbeat",
            Self::Fire => "fire",
            Self::Play => "play",
            Self::SetIntensity => "set intensity",
            Self::StopAll => "stop all",
            Self::GetStatus => "status",
            Self::HeadingStart => "heading start",
            Self::HeadingStop => "heading stop",
            Self::SetCalibration => "set calibration",
            Self::GpsStart => "GPS start",
            Self::GpsStop => "GPS stop",
        }
    }
}

/// A message from the unit to the console.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// Answer to [`Request::Hello`]: who the unit is and what it allows.
    Identify(DeviceInfo),
    /// The request with the same sequence number was accepted; `tactors_on` is what runs now.
    Ack {
        /// Tactors on at the moment of the reply.
        tactors_on: TactorMask,
    },
    /// The request with the same sequence number was refused and had no effect.
    Nak {
        /// Why.
        reason: NakReason,
        /// Tactors on at the moment of the reply.
        tactors_on: TactorMask,
    },
    /// Answer to [`Request::GetStatus`].
    Status(UnitStatus),
    /// Unsolicited: the set of running tactors changed on its own (a fire ended, a pattern stepped, the
    /// watchdog stopped everything). Not an acknowledgement; never answered.
    Report {
        /// Tactors on now.
        tactors_on: TactorMask,
        /// Current fault flags.
        faults: Faults,
    },
    /// Protocol v2, unsolicited: one reading of the heading stream ([`Request::HeadingStart`]). Never
    /// answered; an unsent one is superseded by the next.
    Heading(HeadingReport),
    /// Protocol v2, unsolicited: bytes of the GPS receiver on the unit's second UART, in order
    /// ([`Request::GpsStart`]). Never answered, never superseded.
    GpsData {
        /// Receiver bytes the unit dropped since the previous chunk (saturating).
        lost: u16,
        /// The receiver's bytes, 1..=[`MAX_GPS_CHUNK`] of them.
        data: Vec<u8>,
    },
}

/// What a unit says about itself in [`Reply::Identify`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceInfo {
    /// Protocol version the unit speaks (from the frame header).
    pub protocol_version: u8,
    /// Firmware version.
    pub firmware: FirmwareVersion,
    /// Number of tactors the unit drives (16 on the vest).
    pub tactor_count: u8,
    /// Optional features.
    pub capabilities: Capabilities,
    /// The limits the unit enforces.
    pub limits: Limits,
    /// The unit stops everything when it has heard nothing for this long (ms).
    pub watchdog_ms: u16,
}

/// Firmware version `major.minor.patch`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct FirmwareVersion {
    /// Major version.
    pub major: u8,
    /// Minor version.
    pub minor: u8,
    /// Patch level.
    pub patch: u8,
}

impl std::fmt::Display for FirmwareVersion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// Optional unit features, a bit set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct Capabilities(pub u8);

impl Capabilities {
    /// The unit has per-tactor drive levels ([`Request::SetIntensity`]).
    pub const INTENSITY: Self = Self(0x01);
    /// The unit plays patterns itself ([`Request::Play`]).
    pub const PATTERNS: Self = Self(0x02);
    /// The unit has a tilt-compensated magnetometer and streams [`Reply::Heading`] (protocol v2).
    pub const HEADING: Self = Self(0x04);
    /// The unit forwards a GPS receiver on its second UART ([`Request::GpsStart`], protocol v2).
    pub const GPS: Self = Self(0x08);

    /// Whether every bit of `other` is set.
    pub fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
}

impl std::ops::BitOr for Capabilities {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

/// Fault flags of the unit, a bit set; a flag stays set until a [`Reply::Status`] has reported it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct Faults(pub u8);

impl Faults {
    /// The watchdog stopped everything because the console went silent.
    pub const WATCHDOG: Self = Self(0x01);
    /// The battery is below 3500 mV.
    pub const LOW_BATTERY: Self = Self(0x02);
    /// A command was refused for exceeding a limit.
    pub const LIMIT_REJECTED: Self = Self(0x04);
    /// A frame with a bad CRC or bad framing was received.
    pub const LINE_ERRORS: Self = Self(0x08);

    /// Whether every bit of `other` is set.
    pub fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// Human names of the set flags.
    pub fn names(self) -> Vec<&'static str> {
        let all = [
            (Self::WATCHDOG, "watchdog"),
            (Self::LOW_BATTERY, "low battery"),
            (Self::LIMIT_REJECTED, "limit rejected"),
            (Self::LINE_ERRORS, "line errors"),
        ];
        all.iter().filter(|(f, _)| self.contains(*f)).map(|(_, n)| *n).collect()
    }
}

impl std::ops::BitOr for Faults {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

/// The unit's answer to [`Request::GetStatus`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct UnitStatus {
    /// Battery voltage (mV).
    pub battery_mv: u16,
    /// Battery charge (%), 0..=100.
    pub battery_pct: u8,
    /// Tactors on now.
    pub tactors_on: TactorMask,
    /// Fault flags (cleared by this report).
    pub faults: Faults,
    /// Firmware version.
    pub firmware: FirmwareVersion,
}

/// Why a unit refused a request ([`Reply::Nak`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NakReason {
    /// 0x01: the frame's CRC did not match (the sequence number in the NAK may be garbage).
    BadCrc,
    /// 0x02: the message type is not known to this firmware.
    UnknownCommand,
    /// 0x03: the payload length or content is malformed for the message type.
    Malformed,
    /// 0x04: the protocol version in the header is not supported.
    UnsupportedVersion,
    /// 0x05: an on-time is zero or above the unit's maximum.
    DurationLimit,
    /// 0x06: more tactors at once than the current budget allows.
    TooManyTactors,
    /// 0x07: a tactor would exceed its on-time budget over the duty-cycle window.
    DutyCycle,
    /// 0x08: too many frames or too long a pattern.
    PatternLimit,
    /// 0x09: the feature is not supported by this unit (e.g. intensity).
    NotSupported,
    /// 0x0A: a command arrived before HELLO.
    NotIdentified,
    /// Any other code (a newer firmware).
    Other(u8),
}

impl NakReason {
    /// The code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Self::BadCrc => 0x01,
            Self::UnknownCommand => 0x02,
            Self::Malformed => 0x03,
            Self::UnsupportedVersion => 0x04,
            Self::DurationLimit => 0x05,
            Self::TooManyTactors => 0x06,
            Self::DutyCycle => 0x07,
            Self::PatternLimit => 0x08,
            Self::NotSupported => 0x09,
            Self::NotIdentified => 0x0A,
            Self::Other(c) => c,
        }
    }

    /// The reason for a code on the wire.
    pub fn from_code(code: u8) -> Self {
        match code {
            0x01 => Self::BadCrc,
            0x02 => Self::UnknownCommand,
            0x03 => Self::Malformed,
            0x04 => Self::UnsupportedVersion,
            0x05 => Self::DurationLimit,
            0x06 => Self::TooManyTactors,
            0x07 => Self::DutyCycle,
            0x08 => Self::PatternLimit,
            0x09 => Self::NotSupported,
            0x0A => Self::NotIdentified,
            c => Self::Other(c),
        }
    }
}

impl std::fmt::Display for NakReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadCrc => f.write_str("bad CRC"),
            Self::UnknownCommand => f.write_str("unknown command"),
            Self::Malformed => f.write_str("malformed payload"),
            Self::UnsupportedVersion => f.write_str("unsupported protocol version"),
            Self::DurationLimit => f.write_str("on-time limit exceeded"),
            Self::TooManyTactors => f.write_str("too many tactors at once (current budget)"),
            Self::DutyCycle => f.write_str("duty-cycle limit exceeded"),
            Self::PatternLimit => f.write_str("pattern too long"),
            Self::NotSupported => f.write_str("not supported by this unit"),
            Self::NotIdentified => f.write_str("command before hello"),
            Self::Other(c) => write!(f, "unknown reason 0x{c:02X}"),
        }
    }
}

/// A message with its sequence number and protocol version, as read from or written to the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet<M> {
    /// The header's protocol version.
    pub version: u8,
    /// Sequence number: chosen by the console for requests; a reply echoes the request's.
    pub seq: u8,
    /// The message.
    pub message: M,
}
