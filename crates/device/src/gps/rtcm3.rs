//! RTCM 3 frames (`D3 len10 payload crc24`) as receivers interleave them with UBX and NMEA (a u-blox
//! F9R/F9T echoing its corrections, a base station's output): recognised by the framer and skipped whole.
//!
//! Layout (RTCM Standard 10403.x, "Transport Layer"): the preamble byte `0xD3`, 6 reserved bits (zero),
//! a 10-bit payload length (0..=1023), the payload (its first 12 bits are the message number), and a
//! 24-bit CRC over preamble, length and payload, sent most significant byte first. The CRC is Qualcomm's
//! CRC-24Q: polynomial 0x1864CFB, initial value 0, no reflection, no final XOR — the parameters the CRC
//! catalogue lists as CRC-24/LTE-A (check value of `"123456789"`: 0xCDE703).
//!
//! The format's one home is [`crate::rtcm3`] (also the NTRIP client's framer); this module is how the GPS
//! framer treats such frames. vestnav does not decode corrections; a verified frame is counted ([`DecodeStats::rtcm3_frames`]) and
//! its bytes can neither start a false sentence nor be mistaken for another protocol's frame.
//!
//! [`DecodeStats::rtcm3_frames`]: super::DecodeStats::rtcm3_frames

pub use crate::rtcm3::{CRC24Q, MAX_PAYLOAD, OVERHEAD, PREAMBLE, crc24q, message_number};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_number_is_the_first_twelve_bits() {
        // 1005 = 0x3ED: bytes 0x3E 0xD0.
        assert_eq!(message_number(&[0x3E, 0xD0, 0x00]), Some(1005));
        assert_eq!(message_number(&[0x3E]), None);
        assert_eq!(crc24q(b"123456789"), 0x00CD_E703);
    }

    /// gpsd's two RTCM 3 logs: every frame gpsd decoded (its `.chk` has one JSON object per message, with
    /// its type and length) is recognised by our framer, in the same order, and nothing else comes out:
    /// no sentence, no fix, no binary family detected.
    #[test]
    fn gpsd_rtcm3_logs_frame_exactly_as_gpsd() {
        use crate::gps::framing::{Frame, Framer};
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-rtcm");
        for name in ["rtcm3.2.log", "rtcm3.bndm.log"] {
            let bytes = std::fs::read(dir.join(name)).unwrap();
            let chk = std::fs::read_to_string(dir.join(format!("{name}.chk"))).unwrap();
            let gpsd: Vec<(u64, u64)> = chk
                .lines()
                .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
                .filter(|v| v["class"] == "RTCM3")
                .map(|v| (v["type"].as_u64().unwrap(), v["length"].as_u64().unwrap()))
                .collect();
            let mut f = Framer::new();
            let mut ours = Vec::new();
            let mut other = 0;
            let mut push = |fr: Frame<'_>, _: &mut _| match fr {
                Frame::Rtcm3 { payload } => {
                    ours.push((u64::from(message_number(payload).unwrap()), payload.len() as u64));
                }
                _ => other += 1,
            };
            f.feed(&bytes, &mut push);
            f.finish(&mut push);
            assert_eq!(ours, gpsd, "{name}");
            assert_eq!(other, 0, "{name}");
            assert_eq!(f.stats().undecoded_protocol, None, "{name}");
            let (fixes, stats) = crate::gps::decode_file(&dir.join(name)).unwrap();
            assert!(fixes.is_empty(), "{name}");
            assert_eq!(stats.sentences, 0, "{name}");
            assert_eq!(stats.rtcm3_frames, gpsd.len() as u64, "{name}");
        }
    }

    /// A u-blox stream with RTCM 3 frames between its messages (an F9 echoing corrections) gives the same
    /// fixes as without them; a corrupted RTCM 3 frame is counted and hides nothing.
    #[test]
    fn rtcm3_between_ubx_and_nmea_loses_nothing() {
        let log = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/data/gpsd-logs-more/ublox-neo-m8n.log");
        let bytes = std::fs::read(&log).unwrap();
        // The log's UBX frames, written again back to back: once plain, once with RTCM 3 between them.
        let mut frames = Vec::new();
        let mut f = crate::gps::framing::Framer::new();
        f.feed(&bytes, |fr, _| {
            if let crate::gps::framing::Frame::Ubx { class, id, payload } = fr {
                frames.push(crate::gps::ubx::frame(class, id, payload));
            }
        });
        let plain_bytes = frames.concat();
        let (plain, _) = crate::gps::decode_reader(plain_bytes.as_slice()).unwrap();
        assert!(plain.len() > 10);
        let rtcm =
            crate::rtcm3::encode_frame(&[0x3E, 0xD0, 0x24, 0x42, 0xB5, 0x62, b'$', 0xBA, 0xCE]).unwrap();
        let mut broken = rtcm.clone();
        broken[5] ^= 0x40;
        let gga = b"$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n";
        let mut mixed = Vec::new();
        let mut k = 0u64;
        for fr in &frames {
            mixed.extend(fr);
            mixed.extend(if k.is_multiple_of(2) { &rtcm } else { &broken });
            k += 1;
        }
        mixed.extend(gga);
        let (fixes, stats) = crate::gps::decode_reader(mixed.as_slice()).unwrap();
        assert_eq!(stats.rtcm3_frames, k.div_ceil(2));
        assert!(stats.binary_bad_checksum >= k / 2, "{stats}");
        assert_eq!(stats.sentences, 1, "the sentence after the last broken frame is not hidden");
        assert_eq!(fixes.len(), plain.len());
        for (a, b) in fixes.iter().zip(&plain) {
            assert_eq!((a.time, a.lat_deg, a.lon_deg, a.mode), (b.time, b.lat_deg, b.lon_deg, b.mode));
        }
    }
}
