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
