//! RTCM 3 framing: finds the frames of a correction stream and checks each one's CRC-24Q.
//!
//! A frame (RTCM 10403.x, §4) is the preamble `0xD3`, six reserved bits (zero), a 10-bit payload length
//! (0..=1023), the payload (its first 12 bits are the message number, e.g. 1005 station, 1077 GPS MSM7)
//! and a 24-bit CRC-24Q over everything before it: polynomial `0x864CFB`, initial value 0, no reflection,
//! no final xor (the `crc` crate's `CRC_24_LTE_A` is the same code; its check value over `"123456789"` is
//! `0xCDE703`). The framer is sans-IO and bounded: bytes in, verified frames out; junk and frames with a bad
//! CRC are skipped and counted, and it resynchronises on the next `0xD3` after a failed candidate.
//!
//! ```
//! use vestnav_device::rtcm3::{Framer, encode_frame};
//! let frame = encode_frame(&[0x3E, 0xD0, 0x00]).unwrap(); // message 1005's first bits
//! let mut framer = Framer::default();
//! let mut out = Vec::new();
//! framer.feed(&[b"junk".as_slice(), &frame].concat(), |f| out.push(f.message_type()));
//! assert_eq!(out, [Some(1005)]);
//! assert_eq!(framer.stats().junk_bytes, 4);
//! ```

/// The CRC-24Q of RTCM 3 (and Qualcomm): poly 0x864CFB, init 0, not reflected, no final xor.
pub const CRC24Q: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_24_LTE_A);

/// The frame preamble.
pub const PREAMBLE: u8 = 0xD3;

/// Largest payload a frame can carry (10 bits).
pub const MAX_PAYLOAD: usize = 1023;

/// Header (3) + CRC (3) bytes around the payload.
pub const OVERHEAD: usize = 6;

/// One verified frame, whole (preamble to CRC).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// The frame's bytes, exactly as received.
    pub bytes: &'a [u8],
}

impl Frame<'_> {
    /// The payload (between the header and the CRC).
    pub fn payload(&self) -> &[u8] {
        self.bytes.get(3..self.bytes.len().saturating_sub(3)).unwrap_or(&[])
    }

    /// The message number: the payload's first 12 bits (`None` for a payload shorter than 2 bytes).
    pub fn message_type(&self) -> Option<u16> {
        message_number(self.payload())
    }
}

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

/// Counts of what the framer saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FramerStats {
    /// Verified frames.
    pub frames: u64,
    /// Candidates whose CRC did not match.
    pub bad_crc: u64,
    /// Bytes outside any verified frame.
    pub junk_bytes: u64,
}

/// Errors building a frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The payload does not fit the 10-bit length.
    #[error("RTCM 3 payload of {0} bytes is longer than 1023")]
    TooLong(usize),
}

/// A whole frame around `payload`: preamble, length, payload, CRC-24Q.
pub fn encode_frame(payload: &[u8]) -> Result<Vec<u8>, FrameError> {
    let len = u16::try_from(payload.len()).ok().filter(|l| usize::from(*l) <= MAX_PAYLOAD);
    let Some(len) = len else { return Err(FrameError::TooLong(payload.len())) };
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&[PREAMBLE, (len >> 8) as u8 & 0x03, (len & 0xFF) as u8]);
    out.extend_from_slice(payload);
    let crc = CRC24Q.checksum(&out);
    out.extend_from_slice(&crc.to_be_bytes()[1..]);
    Ok(out)
}

/// The bounded RTCM 3 framer (holds at most one frame's worth of bytes).
#[derive(Debug, Default)]
pub struct Framer {
    buf: Vec<u8>,
    stats: FramerStats,
}

impl Framer {
    /// What the framer has seen so far.
    pub fn stats(&self) -> FramerStats {
        self.stats
    }

    /// Feeds bytes; calls `on_frame` with each verified frame, in order.
    pub fn feed(&mut self, data: &[u8], mut on_frame: impl FnMut(Frame<'_>)) {
        for chunk in data.chunks(4096) {
            self.buf.extend_from_slice(chunk);
            self.drain(&mut on_frame);
        }
    }

    fn drain(&mut self, on_frame: &mut impl FnMut(Frame<'_>)) {
        let mut start = 0;
        while let Some(rest) = self.buf.get(start..) {
            // Skip to the next preamble.
            let Some(skip) = rest.iter().position(|b| *b == PREAMBLE) else {
                self.stats.junk_bytes += rest.len() as u64;
                start = self.buf.len();
                break;
            };
            self.stats.junk_bytes += skip as u64;
            start += skip;
            let Some(&[_, hi, lo]) = self.buf.get(start..start + 3) else { break };
            if hi & 0xFC != 0 {
                // Reserved bits set: not a frame start.
                self.stats.junk_bytes += 1;
                start += 1;
                continue;
            }
            let total = ((usize::from(hi & 0x03) << 8) | usize::from(lo)) + OVERHEAD;
            let Some(candidate) = self.buf.get(start..start + total) else { break };
            let (body, crc) = candidate.split_at(total - 3);
            let expected = CRC24Q.checksum(body).to_be_bytes();
            if expected.get(1..) == Some(crc) {
                self.stats.frames += 1;
                on_frame(Frame { bytes: candidate });
                start += total;
            } else {
                self.stats.bad_crc += 1;
                self.stats.junk_bytes += 1;
                start += 1;
            }
        }
        self.buf.drain(..start.min(self.buf.len()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published check value of CRC-24Q over the ASCII digits "123456789": `0xCDE703` (the CRC `RevEng`
    /// catalogue, CRC-24/LTE-A, the same parameters as RTCM's CRC-24Q).
    #[test]
    fn crc24q_check_value() {
        assert_eq!(CRC24Q.checksum(b"123456789"), 0x00CD_E703);
    }

    /// A frame from RTCM 10403.3's example of message 1005 as quoted widely (e.g. in RTKLIB's and
    /// pygnssutils' tests): `D3 00 13 3E D7 D3 02 02 98 0E DE EF 34 B4 BD 62 AC 09 41 98 6F 33 36 0B 98`.
    #[test]
    fn a_published_1005_frame_checks() {
        let frame: [u8; 25] = [
            0xD3, 0x00, 0x13, 0x3E, 0xD7, 0xD3, 0x02, 0x02, 0x98, 0x0E, 0xDE, 0xEF, 0x34, 0xB4, 0xBD, 0x62,
            0xAC, 0x09, 0x41, 0x98, 0x6F, 0x33, 0x36, 0x0B, 0x98,
        ];
        let mut f = Framer::default();
        let mut got = Vec::new();
        f.feed(&frame, |fr| got.push((fr.message_type(), fr.bytes.to_vec())));
        assert_eq!(got, [(Some(1005), frame.to_vec())]);
        assert_eq!(encode_frame(&frame[3..22]).unwrap(), frame.to_vec());
    }

    #[test]
    fn resyncs_after_a_corrupt_frame_and_split_input() {
        let a = encode_frame(&[0x3E, 0xD0, 1, 2, 3]).unwrap();
        let mut bad = encode_frame(&[0x43, 0x50, 9, 9]).unwrap();
        bad[4] ^= 0xFF;
        let b = encode_frame(&[0x43, 0x50, 7]).unwrap();
        let stream = [a.clone(), bad, vec![0xD3, 0xFF, 0x00], b.clone()].concat();
        let mut f = Framer::default();
        let mut got = Vec::new();
        for byte in &stream {
            f.feed(std::slice::from_ref(byte), |fr| got.push(fr.bytes.to_vec()));
        }
        assert_eq!(got, [a, b]);
        assert_eq!(f.stats().frames, 2);
        assert_eq!(f.stats().bad_crc, 1);
        assert!(f.buf.len() < MAX_PAYLOAD + OVERHEAD);
        assert_eq!(encode_frame(&[0; 1024]), Err(FrameError::TooLong(1024)));
    }
}
