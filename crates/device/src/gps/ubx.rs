//! u-blox UBX binary protocol: frames (`B5 62 class id len16le payload ck_a ck_b`) and the sans-IO
//! decoder of the navigation messages into [`Fix`](super::Fix)es (`UbxDecoder`).
//!
//! The frame layout and the 8-bit Fletcher checksum over class, id, length and payload are those of the
//! u-blox receiver description (e.g. "u-blox 8 / u-blox M8 Receiver Description, UBX-13003221", section
//! "UBX Frame Structure" and "UBX Checksum"). The framer ([`super::framing`]) verifies the checksum and
//! hands each frame's class, id and payload to `UbxDecoder::handle`; docs/gps.md ("u-blox UBX") says
//! which messages are used and how epochs are formed.

mod decoder;
#[cfg(test)]
mod tests;

pub(crate) use decoder::{UbxDecoder, UbxUnused, nmea_id, utc_from_calendar};

/// First sync byte.
pub const SYNC_1: u8 = 0xB5;
/// Second sync byte.
pub const SYNC_2: u8 = 0x62;
/// Bytes of a frame around its payload: two sync bytes, class, id, two length bytes, two checksum bytes.
pub const OVERHEAD: usize = 8;

/// The 8-bit Fletcher checksum `(ck_a, ck_b)` over `class id len_lo len_hi payload`.
pub fn checksum(class: u8, id: u8, payload: &[u8]) -> (u8, u8) {
    let len = u16::try_from(payload.len()).unwrap_or(u16::MAX).to_le_bytes();
    let (mut a, mut b) = (0u8, 0u8);
    for &byte in [class, id, len[0], len[1]].iter().chain(payload) {
        a = a.wrapping_add(byte);
        b = b.wrapping_add(a);
    }
    (a, b)
}

/// One whole frame for `class`/`id` around `payload`.
///
/// # Panics
/// If the payload is longer than the 16-bit length field can say (65,535 bytes); every message we build
/// is far shorter.
pub fn frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let len = u16::try_from(payload.len()).expect("UBX payload longer than 65,535 bytes");
    let (a, b) = checksum(class, id, payload);
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&[SYNC_1, SYNC_2, class, id]);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(payload);
    out.extend_from_slice(&[a, b]);
    out
}

/// UBX messages that carry no live position. A stream of only these gives no fix; the decode summary
/// says which and what to change ([`super::DecodeStats::ubx_without_fix`]). Identifiers from the u-blox 8 /
/// M8 receiver description (UBX-13003221).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum WithoutFix {
    /// RXM-SFRBX (0x02 0x13): the navigation message subframes as broadcast.
    RawSubframes,
    /// RXM-MEASX (0x02 0x14), RXM-RAWX (0x02 0x15): measurements for a post-processing engine.
    RawMeasurements,
    /// LOG-INFO (0x21 0x08), LOG-RETRIEVEPOS (0x0B), LOG-RETRIEVESTRING (0x0D), LOG-RETRIEVEPOSEXTRA (0x0F),
    /// LOG-BATCH (0x11), MON-BATCH (0x0A 0x32): records read back from the receiver's memory.
    StoredLog,
}

impl WithoutFix {
    /// The kind of a UBX message without a live position, or `None` for any other message.
    pub fn of(class: u8, id: u8) -> Option<Self> {
        match (class, id) {
            (0x02, 0x13) => Some(Self::RawSubframes),
            (0x02, 0x14 | 0x15) => Some(Self::RawMeasurements),
            (0x21, 0x08 | 0x0B | 0x0D | 0x0F | 0x11) | (0x0A, 0x32) => Some(Self::StoredLog),
            _ => None,
        }
    }

    /// Why a stream of such messages gives no fix, and what to change.
    pub fn advice(self) -> &'static str {
        match self {
            Self::RawSubframes => {
                "u-blox RXM-SFRBX only (broadcast navigation subframes, no position): enable NAV-PVT or NMEA \
                 output on the receiver"
            }
            Self::RawMeasurements => {
                "u-blox RXM-RAWX/MEASX only (raw measurements for post-processing, no position): enable \
                 NAV-PVT or NMEA output on the receiver"
            }
            Self::StoredLog => {
                "u-blox stored-log read-back only (LOG-BATCH/LOG-RETRIEVE: positions recorded earlier in the \
                 receiver's memory, not live fixes, not used): enable NAV-PVT or NMEA output on the receiver"
            }
        }
    }
}
