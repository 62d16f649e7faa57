//! `SiRF` binary protocol: frames (`A0 A2 len16be payload ck16be B0 B3`).
//!
//! The layout and checksum are those of the "`SiRF` Binary Protocol Reference Manual" (`SiRF` Technology,
//! rev. 2.4, 2008), chapter 1 "Protocol Layers": the payload length has 15 bits, the checksum is the sum of
//! the payload bytes modulo 2^15, both big-endian; the payload starts with the message id (MID).

/// Start sequence.
pub const START: [u8; 2] = [0xA0, 0xA2];
/// End sequence.
pub const END: [u8; 2] = [0xB0, 0xB3];
/// Bytes of a frame around its payload: start (2), length (2), checksum (2), end (2).
pub const OVERHEAD: usize = 8;
/// Longest payload the 15-bit length field can carry.
pub const MAX_PAYLOAD: usize = 0x7FFF;

/// The 15-bit checksum of a payload.
pub fn checksum(payload: &[u8]) -> u16 {
    payload.iter().fold(0u16, |sum, &b| sum.wrapping_add(u16::from(b)) & 0x7FFF)
}

/// One whole frame around `payload` (MID first).
///
/// # Panics
/// If the payload is longer than [`MAX_PAYLOAD`]; every message we build is far shorter.
pub fn frame(payload: &[u8]) -> Vec<u8> {
    assert!(payload.len() <= MAX_PAYLOAD, "SiRF payload longer than 32,767 bytes");
    let len = u16::try_from(payload.len()).expect("checked above");
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&START);
    out.extend_from_slice(&len.to_be_bytes());
    out.extend_from_slice(payload);
    out.extend_from_slice(&checksum(payload).to_be_bytes());
    out.extend_from_slice(&END);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_of_a_real_sirf_ii_receiver_round_trips() {
        // The first frame of gpsd's `sirf2.log` (MID 41, Geodetic Navigation Data, 91 bytes): the receiver
        // computed its checksum (0x079A), so building the frame from its payload must give its bytes back.
        let hex = "a0a2005b290001100004f4000003e807d40418173bbb8000000000000000000000000000000000000000001500000000\
                   00000000000000000000000000000000000000000000000000000000001bdff000000000000000000000000000fa0007\
                   9ab0b3";
        let bytes: Vec<u8> = (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
            .collect();
        let payload = &bytes[4..bytes.len() - 4];
        assert_eq!(payload.len(), 91);
        assert_eq!(checksum(payload), 0x079A);
        assert_eq!(frame(payload), bytes);
    }
}
