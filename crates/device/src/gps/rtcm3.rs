//! RTCM 3 frames (`D3 len10 payload crc24`) as receivers interleave them with UBX and NMEA (a u-blox
//! F9R/F9T echoing its corrections, a base station's output): recognised by the framer and skipped whole.
//!
//! Layout (RTCM Standard 10403.x, "Transport Layer"): the preamble byte `0xD3`, 6 reserved bits (zero),
//! a 10-bit payload length (0..=1023), the payload (its first 12 bits are the message number), and a
//! 24-bit CRC over preamble, length and payload, sent most significant byte first. The CRC is Qualcomm's
//! CRC-24Q: polynomial 0x1864CFB, initial value 0, no reflection, no final XOR — the parameters the CRC
//! catalogue lists as CRC-24/LTE-A (check value of `"123456789"`: 0xCDE703).
//!
//! vestnav does not decode corrections; a verified frame is counted ([`DecodeStats::rtcm3_frames`]) and
//! its bytes can neither start a false sentence nor be mistaken for another protocol's frame.
//!
//! [`DecodeStats::rtcm3_frames`]: super::DecodeStats::rtcm3_frames

/// Preamble byte.
pub const PREAMBLE: u8 = 0xD3;
/// Longest payload the 10-bit length field can carry.
pub const MAX_PAYLOAD: usize = 1023;
/// Bytes of a frame around its payload: preamble, two length bytes, three CRC bytes.
pub const OVERHEAD: usize = 6;

/// The CRC-24Q engine (streaming use: `CRC24Q.digest()`).
pub(crate) const CRC24Q: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_24_LTE_A);

/// CRC-24Q over `bytes` (preamble, length and payload of a frame).
pub fn crc24q(bytes: &[u8]) -> u32 {
    CRC24Q.checksum(bytes)
}

/// The message number of a payload (its first 12 bits), if it has two bytes.
pub fn message_number(payload: &[u8]) -> Option<u16> {
    match payload {
        [a, b, ..] => Some((u16::from(*a) << 4) | (u16::from(*b) >> 4)),
        _ => None,
    }
}

/// One whole frame around `payload`.
///
/// # Panics
/// If the payload is longer than [`MAX_PAYLOAD`]; test frames are far shorter.
pub fn frame(payload: &[u8]) -> Vec<u8> {
    assert!(payload.len() <= MAX_PAYLOAD, "RTCM 3 payload longer than 1023 bytes");
    let len = u16::try_from(payload.len()).expect("checked above");
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.push(PREAMBLE);
    out.extend_from_slice(&len.to_be_bytes());
    out.extend_from_slice(payload);
    let crc = crc24q(&out).to_be_bytes();
    out.extend_from_slice(&crc[1..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc24q_check_value() {
        // The catalogue's check value for CRC-24/LTE-A (= CRC-24Q).
        assert_eq!(crc24q(b"123456789"), 0x00CD_E703);
    }

    #[test]
    fn message_number_is_the_first_twelve_bits() {
        // 1005 = 0x3ED: bytes 0x3E 0xD0.
        assert_eq!(message_number(&[0x3E, 0xD0, 0x00]), Some(1005));
        assert_eq!(message_number(&[0x3E]), None);
    }
}
