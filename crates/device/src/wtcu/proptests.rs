//! Property tests: every message round-trips through the codec; no byte sequence panics the decoder, the
//! link or the engine; a valid frame after junk still decodes; truncated or corrupted frames are rejected.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use vestnav_core::vest::{Frame, TactorMask};

use super::codec::{V1Codec, WireCodec};
use super::engine::{Engine, EngineConfig};
use super::limits::Limits;
use super::link::{Link, LinkConfig};
use super::message::{
    Capabilities, DeviceInfo, Faults, FirmwareVersion, NakReason, Packet, Reply, Request, UnitStatus,
};

fn arb_mask() -> impl Strategy<Value = TactorMask> {
    any::<u16>().prop_map(TactorMask)
}

fn arb_request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::Hello),
        Just(Request::Heartbeat),
        (arb_mask(), any::<u16>()).prop_map(|(mask, duration_ms)| Request::Fire { mask, duration_ms }),
        (prop::collection::vec((arb_mask(), any::<u16>()), 0..48), any::<u8>()).prop_map(|(f, repeats)| {
            Request::Play {
                frames: f.into_iter().map(|(mask, duration_ms)| Frame { mask, duration_ms }).collect(),
                repeats,
            }
        }),
        (arb_mask(), any::<u8>()).prop_map(|(mask, level)| Request::SetIntensity { mask, level }),
        Just(Request::StopAll),
        Just(Request::GetStatus),
    ]
}

fn arb_reply() -> impl Strategy<Value = Reply> {
    let fw = (any::<u8>(), any::<u8>(), any::<u8>()).prop_map(|(major, minor, patch)| FirmwareVersion {
        major,
        minor,
        patch,
    });
    let limits = (any::<u16>(), any::<u8>(), any::<u16>(), any::<u16>(), any::<u8>(), any::<u16>()).prop_map(
        |(a, b, c, d, e, f)| Limits {
            max_on_ms: a,
            max_simultaneous: b,
            duty_window_ms: c,
            max_duty_on_ms: d,
            max_pattern_frames: e,
            max_pattern_ms: f,
        },
    );
    prop_oneof![
        (fw.clone(), any::<u8>(), any::<u8>(), limits, any::<u16>()).prop_map(
            |(firmware, n, caps, limits, wd)| {
                Reply::Identify(DeviceInfo {
                    protocol_version: 1,
                    firmware,
                    tactor_count: n,
                    capabilities: Capabilities(caps),
                    limits,
                    watchdog_ms: wd,
                })
            }
        ),
        arb_mask().prop_map(|tactors_on| Reply::Ack { tactors_on }),
        (any::<u8>(), arb_mask())
            .prop_map(|(code, tactors_on)| Reply::Nak { reason: NakReason::from_code(code), tactors_on }),
        (any::<u16>(), any::<u8>(), arb_mask(), any::<u8>(), fw).prop_map(
            |(mv, pct, on, faults, firmware)| {
                Reply::Status(UnitStatus {
                    battery_mv: mv,
                    battery_pct: pct,
                    tactors_on: on,
                    faults: Faults(faults),
                    firmware,
                })
            }
        ),
        (arb_mask(), any::<u8>()).prop_map(|(tactors_on, f)| Reply::Report { tactors_on, faults: Faults(f) }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn every_request_round_trips(seq in any::<u8>(), request in arb_request()) {
        let mut codec = V1Codec::new();
        let bytes = codec.encode_request(seq, &request).unwrap();
        // Only the delimiters are zero.
        prop_assert!(bytes[1..bytes.len() - 1].iter().all(|&b| b != 0));
        let mut out = Vec::new();
        codec.decode_requests(&bytes, &mut out);
        prop_assert_eq!(out, vec![Ok(Packet { seq, message: request })]);
    }

    #[test]
    fn every_reply_round_trips(seq in any::<u8>(), reply in arb_reply()) {
        let mut codec = V1Codec::new();
        let bytes = codec.encode_reply(seq, &reply);
        let mut out = Vec::new();
        codec.decode_replies(&bytes, &mut out);
        prop_assert_eq!(out, vec![Ok(Packet { seq, message: reply })]);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_a_frame_after_them_survives(
        junk in prop::collection::vec(any::<u8>(), 0..600),
        seq in any::<u8>(),
        request in arb_request(),
    ) {
        let t0 = Instant::now();
        let mut engine = Engine::new(EngineConfig::default());
        engine.handle_bytes(&junk, t0);
        engine.handle_timeout(t0 + Duration::from_secs(3));
        while engine.poll_transmit().is_some() {}
        let mut link = Link::new(LinkConfig::default());
        link.connect(t0);
        link.handle_bytes(&junk, t0);
        link.handle_timeout(t0 + Duration::from_secs(3));

        let mut codec = V1Codec::new();
        let mut out = Vec::new();
        codec.decode_requests(&junk, &mut out);
        let frame = codec.encode_request(seq, &request).unwrap();
        let mut after = Vec::new();
        codec.decode_requests(&frame, &mut after);
        // The leading delimiter ends whatever the junk left half done; the frame itself decodes.
        prop_assert_eq!(after.last().cloned(), Some(Ok(Packet { seq, message: request })));
    }

    #[test]
    fn truncated_and_corrupted_frames_are_rejected_not_misread(
        request in arb_request(),
        cut in 1usize..40,
        flip_at in any::<prop::sample::Index>(),
        flip in 1u8..=255,
    ) {
        let codec = V1Codec::new();
        let frame = codec.encode_request(9, &request).unwrap();
        let body = &frame[1..frame.len() - 1];
        // Truncated: the end of the frame never arrives, then the next frame's leading delimiter.
        let mut fresh = V1Codec::new();
        let mut out = Vec::new();
        let keep = body.len().saturating_sub(cut).max(1);
        let mut bytes = vec![0];
        bytes.extend_from_slice(&body[..keep]);
        bytes.push(0);
        fresh.decode_requests(&bytes, &mut out);
        prop_assert!(out.iter().all(Result::is_err));
        // One corrupted byte (never a zero, which would be a delimiter): CRC or framing catches it.
        let mut bad = body.to_vec();
        let i = flip_at.index(bad.len());
        bad[i] ^= flip;
        if !bad.contains(&0) {
            let mut bytes = vec![0];
            bytes.extend_from_slice(&bad);
            bytes.push(0);
            let mut out = Vec::new();
            V1Codec::new().decode_requests(&bytes, &mut out);
            prop_assert!(out.iter().all(|r| r.as_ref().map_or(true, |p| p.message != request || p.seq != 9)));
        }
    }
}
