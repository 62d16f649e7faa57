//! Property tests: every message round-trips through the codec; no byte sequence panics the decoder, the
//! link or the engine; a valid frame after junk still decodes; truncated or corrupted frames are rejected;
//! and whatever sequence of commands the unit accepts, its tactors stay within the safety limits at every
//! instant (continuous on-time, current budget, duty window), checked on the trace of what it drove.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use vestnav_core::vest::{Frame, TactorMask};

use super::codec::{FrameCodec, WireCodec};
use super::engine::{Engine, EngineConfig, EngineEvent};
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
        let mut codec = FrameCodec::with_max_version(1);
        let bytes = codec.encode_request(seq, &request).unwrap();
        // Only the delimiters are zero.
        prop_assert!(bytes[1..bytes.len() - 1].iter().all(|&b| b != 0));
        let mut out = Vec::new();
        codec.decode_requests(&bytes, &mut out);
        prop_assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: request })]);
    }

    #[test]
    fn every_reply_round_trips(seq in any::<u8>(), reply in arb_reply()) {
        let mut codec = FrameCodec::with_max_version(1);
        let bytes = codec.encode_reply(seq, &reply);
        let mut out = Vec::new();
        codec.decode_replies(&bytes, &mut out);
        prop_assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: reply })]);
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

        let mut codec = FrameCodec::with_max_version(1);
        let mut out = Vec::new();
        codec.decode_requests(&junk, &mut out);
        let frame = codec.encode_request(seq, &request).unwrap();
        let mut after = Vec::new();
        codec.decode_requests(&frame, &mut after);
        // The leading delimiter ends whatever the junk left half done; the frame itself decodes.
        prop_assert_eq!(after.last().cloned(), Some(Ok(Packet { version: 1, seq, message: request })));
    }

    #[test]
    fn truncated_and_corrupted_frames_are_rejected_not_misread(
        request in arb_request(),
        cut in 1usize..40,
        flip_at in any::<prop::sample::Index>(),
        flip in 1u8..=255,
    ) {
        let codec = FrameCodec::with_max_version(1);
        let frame = codec.encode_request(9, &request).unwrap();
        let body = &frame[1..frame.len() - 1];
        // Truncated: the end of the frame never arrives, then the next frame's leading delimiter.
        let mut fresh = FrameCodec::with_max_version(1);
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
            FrameCodec::new().decode_requests(&bytes, &mut out);
            prop_assert!(out.iter().all(|r| r.as_ref().map_or(true, |p| p.message != request || p.seq != 9)));
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Safety invariants of the unit under arbitrary command sequences, on a simulated clock.

fn arb_on_mask() -> impl Strategy<Value = TactorMask> {
    prop_oneof![
        (1u16..16).prop_map(TactorMask),
        (0u16..=0xFF).prop_map(TactorMask),
        any::<u16>().prop_map(TactorMask),
        Just(TactorMask(1)),
    ]
}

fn arb_on_ms() -> impl Strategy<Value = u16> {
    prop_oneof![1u16..=800, 0u16..=2600, Just(2000), Just(1000), any::<u16>()]
}

fn arb_command() -> impl Strategy<Value = Request> {
    prop_oneof![
        4 => (arb_on_mask(), arb_on_ms()).prop_map(|(mask, duration_ms)| Request::Fire { mask, duration_ms }),
        4 => (prop::collection::vec((arb_on_mask(), arb_on_ms()), 0..6), 0u8..7).prop_map(|(f, repeats)| {
            Request::Play {
                frames: f.into_iter().map(|(mask, duration_ms)| Frame { mask, duration_ms }).collect(),
                repeats,
            }
        }),
        1 => (arb_mask(), any::<u8>()).prop_map(|(mask, level)| Request::SetIntensity { mask, level }),
        1 => Just(Request::StopAll),
        2 => Just(Request::Heartbeat),
        1 => Just(Request::GetStatus),
        1 => Just(Request::Hello),
    ]
}

fn arb_gap_ms() -> impl Strategy<Value = u64> {
    prop_oneof![Just(0u64), 0u64..30, 0u64..2500, 1900u64..2100]
}

/// Runs `ops` (gap before each, then the command) through a fresh engine on a simulated clock. The clock
/// stops at every deadline the engine asks for and at least every `step_ms` in between (only every
/// command when `step_ms` is `None`). Returns the driven set after each change with its time (exact when
/// the engine's deadlines are honoured) and the decoded ACK/NAK replies in order.
fn drive(
    config: EngineConfig,
    ops: &[(u64, Request)],
    step_ms: Option<u64>,
) -> (Vec<(Instant, TactorMask)>, Vec<Reply>) {
    let t0 = Instant::now();
    let budget = u32::from(config.limits.max_simultaneous);
    let mut engine = Engine::new(config);
    let codec = FrameCodec::with_max_version(1);
    let mut replies_codec = FrameCodec::with_max_version(1);
    let mut trace = vec![(t0, TactorMask::NONE)];
    let mut replies = Vec::new();
    let mut now = t0;
    let mut collect = |engine: &mut Engine, at: Instant, trace: &mut Vec<(Instant, TactorMask)>| {
        assert!(engine.tactors_on().count() <= budget, "{:?} on at once", engine.tactors_on());
        while let Some(event) = engine.poll_event() {
            if let EngineEvent::TactorsChanged(mask) = event {
                trace.push((at, mask));
            }
        }
        while let Some(frame) = engine.poll_transmit() {
            let mut out = Vec::new();
            replies_codec.decode_replies(&frame, &mut out);
            for packet in out.into_iter().flatten() {
                if matches!(packet.message, Reply::Ack { .. } | Reply::Nak { .. }) {
                    replies.push(packet.message);
                }
            }
        }
    };
    let mut advance = |engine: &mut Engine, now: &mut Instant, until: Instant, trace: &mut Vec<_>| {
        loop {
            let mut next = engine.poll_timeout();
            if let Some(step) = step_ms {
                let tick = *now + Duration::from_millis(step);
                next = Some(next.map_or(tick, |n| n.min(tick)));
            }
            match next {
                Some(t) if t <= until => {
                    *now = t.max(*now);
                    engine.handle_timeout(*now);
                    collect(engine, *now, trace);
                }
                _ => break,
            }
        }
        *now = until;
        engine.handle_timeout(*now);
        collect(engine, *now, trace);
    };
    let hello = codec.encode_request(0, &Request::Hello).unwrap();
    engine.handle_bytes(&hello, now);
    for (i, (gap_ms, request)) in ops.iter().enumerate() {
        let until = now + Duration::from_millis(*gap_ms);
        advance(&mut engine, &mut now, until, &mut trace);
        let bytes = codec.encode_request((i + 1) as u8, request).unwrap();
        engine.handle_bytes(&bytes, now);
        let until = now;
        advance(&mut engine, &mut now, until, &mut trace);
    }
    // Long enough for any pattern to end and the watchdog to trip.
    let until = now + Duration::from_secs(12);
    advance(&mut engine, &mut now, until, &mut trace);
    (trace, replies)
}

/// The on-intervals of each tactor from a trace of the driven set; intervals that touch (off for zero time)
/// are one run.
fn runs_of(trace: &[(Instant, TactorMask)]) -> Vec<Vec<(Instant, Instant)>> {
    let mut all = vec![Vec::<(Instant, Instant)>::new(); 16];
    for (tactor, runs) in all.iter_mut().enumerate() {
        let mut since: Option<Instant> = None;
        for &(at, mask) in trace {
            match (since, mask.contains(tactor)) {
                (None, true) => {
                    since = match runs.last() {
                        Some(&(start, end)) if end == at => {
                            runs.pop();
                            Some(start)
                        }
                        _ => Some(at),
                    };
                }
                (Some(start), false) => {
                    runs.push((start, at));
                    since = None;
                }
                _ => {}
            }
        }
        assert!(since.is_none(), "tactor {tactor} still on at the end");
    }
    all
}

/// On-time of `intervals` within `[from, to]`.
fn on_within(intervals: &[(Instant, Instant)], from: Instant, to: Instant) -> Duration {
    intervals.iter().map(|&(a, b)| b.min(to).saturating_duration_since(a.max(from))).sum()
}

fn assert_within_limits(trace: &[(Instant, TactorMask)], limits: &Limits) -> Result<(), TestCaseError> {
    let max_on = Duration::from_millis(u64::from(limits.max_on_ms));
    let window = Duration::from_millis(u64::from(limits.duty_window_ms));
    let max_duty = Duration::from_millis(u64::from(limits.max_duty_on_ms));
    for &(_, mask) in trace {
        prop_assert!(mask.count() <= u32::from(limits.max_simultaneous), "{mask:?} at once");
    }
    for (tactor, runs) in runs_of(trace).iter().enumerate() {
        for &(start, end) in runs {
            prop_assert!(end - start <= max_on, "tactor {tactor} on without a break for {:?}", end - start);
        }
        // The on-time in a sliding window is largest when the window starts as a run starts or ends as one
        // ends (it is piecewise linear in the window's position).
        for &(start, end) in runs {
            let from_start = on_within(runs, start, start + window);
            let to_end = on_within(runs, end.checked_sub(window).unwrap_or(end), end);
            prop_assert!(
                from_start <= max_duty && to_end <= max_duty,
                "tactor {tactor}: duty {from_start:?} / {to_end:?}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn no_accepted_command_sequence_breaks_the_limits(
        ops in prop::collection::vec((arb_gap_ms(), arb_command()), 1..40),
        step_ms in 1u64..=120,
        watchdog_ms in prop_oneof![Just(1500u16), Just(60_000u16)],
    ) {
        let config = EngineConfig { watchdog_ms, ..EngineConfig::default() };
        let (trace, replies) = drive(config.clone(), &ops, Some(step_ms));
        assert_within_limits(&trace, &config.limits)?;
        // Time is played exactly however coarsely the engine is driven: the same ACKs and NAKs.
        let (_, coarse_replies) = drive(config.clone(), &ops, None);
        prop_assert_eq!(replies, coarse_replies);
    }
}

#[test]
fn a_fine_clock_of_one_millisecond_sees_the_same_limits() {
    // The sequences on a 1 ms clock: chained fires, the repeated pattern, a fire continuing a pattern.
    let fire = |mask, duration_ms| Request::Fire { mask: TactorMask(mask), duration_ms };
    let play = |mask, duration_ms, repeats| Request::Play {
        frames: vec![Frame { mask: TactorMask(mask), duration_ms }],
        repeats,
    };
    let ops = vec![
        (0, fire(1, 2000)),
        (1000, Request::Heartbeat),
        (1000, fire(1, 2000)),
        (0, play(0x00FF, 1000, 5)),
        (100, play(0x00FF, 1000, 2)),
        (1000, Request::Heartbeat),
        (500, fire(0x0F, 600)),
        (0, Request::Heartbeat),
    ];
    let (trace, replies) = drive(EngineConfig::default(), &ops, Some(1));
    assert_within_limits(&trace, &Limits::default()).unwrap();
    let naks: Vec<bool> = replies.iter().map(|r| matches!(r, Reply::Nak { .. })).collect();
    // The second 2000 ms fire starts the instant the first ends: refused. So is the 5 x 1000 ms pattern.
    // The 2 x 1000 ms one is fine; a 600 ms fire 1500 ms into it would make tactors 0-3 run 2100 ms.
    assert_eq!(naks, vec![false, false, true, true, false, false, true, false]);
}
