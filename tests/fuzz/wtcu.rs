//! Target 3: the WTCU protocol, both sides.
//!
//! - `wtcu-codec`: `FrameCodec::decode_requests` / `decode_replies` on streams of valid frames, frames with a
//!   valid CRC around hostile headers and payloads, mutated frames, garbage and overlong runs;
//! - `wtcu-engine`: the unit side (`Engine::handle_bytes`) driven by a fuzzed script of requests, garbage and
//!   clock steps (a simulated clock that honours `poll_timeout`), checking the safety limits on what the
//!   unit actually drives: never more than `max_simultaneous` tactors, no continuous run over `max_on_ms`,
//!   no tactor over `max_duty_on_ms` in any duty window, everything off once the watchdog expires;
//! - `wtcu-link`: the console side (`Link::handle_bytes`) connected to a real engine through a noisy,
//!   hostile channel (bytes flipped, dropped, duplicated, forged replies with the right sequence numbers,
//!   units lying about their limits), checking that every frame the console sends is well formed and
//!   within the console's own limits whatever the unit claims;
//! - a round trip of arbitrary messages (proptest).

use std::time::{Duration, Instant};

use proptest::prelude::*;
use vestnav_core::vest::{Frame, Pattern, TACTOR_COUNT, TactorMask};
use vestnav_device::wtcu::codec::{CRC16, FrameCodec, MAX_ENCODED, WireCodec, cobs_encode};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::engine::{Engine, EngineConfig};
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::link::{Link, LinkConfig, LinkState};
use vestnav_device::wtcu::message::{
    Capabilities, DeviceInfo, Faults, FirmwareVersion, NakReason, Packet, Reply, Request, UnitStatus,
};

use crate::harness::{self, Choices, Counts, Known, Rng, add, bump};
use crate::mutate::mutate;

// ---------------------------------------------------------------------------------------------------------
// Message generators, reading their choices from fuzz bytes.

fn mask(c: &mut Choices) -> TactorMask {
    match c.below(8) {
        0 => TactorMask::NONE,
        1 => TactorMask::ALL,
        2 => TactorMask::CORNERS,
        3 => TactorMask(1 << c.below(16)),
        4 => TactorMask(0x00FF),
        5 => TactorMask(0x01FF),
        _ => TactorMask(c.u16()),
    }
}

fn duration(c: &mut Choices) -> u16 {
    match c.below(12) {
        0 => 0,
        1 => 1,
        2 => 500,
        3 => 1999,
        4 => 2000,
        5 => 2001,
        6 => 5000,
        7 => u16::MAX,
        8 => 250,
        _ => c.u16() % 3000,
    }
}

fn frames(c: &mut Choices) -> Vec<Frame> {
    let n = match c.below(6) {
        0 => 0,
        1 => 33,
        2 => 49,
        _ => c.below(12),
    };
    (0..n).map(|_| Frame { mask: mask(c), duration_ms: duration(c) }).collect()
}

fn request(c: &mut Choices) -> Request {
    match c.below(10) {
        0 => Request::Hello,
        1 => Request::Heartbeat,
        2..=4 => Request::Fire { mask: mask(c), duration_ms: duration(c) },
        5 | 6 => Request::Play {
            frames: frames(c),
            repeats: if c.chance(200) { c.below(4) as u8 } else { c.u8() },
        },
        7 => Request::SetIntensity { mask: mask(c), level: c.u8() },
        8 => Request::StopAll,
        _ => Request::GetStatus,
    }
}

fn limits(c: &mut Choices) -> Limits {
    if c.chance(128) {
        return Limits::default();
    }
    let pick16 = |c: &mut Choices| match c.below(5) {
        0 => 0,
        1 => u16::MAX,
        2 => 1,
        _ => c.u16() % 12_000,
    };
    Limits {
        max_on_ms: pick16(c),
        max_simultaneous: if c.chance(64) { c.u8() } else { c.below(17) as u8 },
        duty_window_ms: pick16(c),
        max_duty_on_ms: pick16(c),
        max_pattern_frames: c.u8(),
        max_pattern_ms: pick16(c),
    }
}

fn firmware(c: &mut Choices) -> FirmwareVersion {
    FirmwareVersion { major: c.u8(), minor: c.u8(), patch: c.u8() }
}

fn reply(c: &mut Choices) -> Reply {
    match c.below(6) {
        0 => Reply::Identify(DeviceInfo {
            protocol_version: 1,
            firmware: firmware(c),
            tactor_count: if c.chance(200) { 16 } else { c.u8() },
            capabilities: Capabilities(c.u8()),
            limits: limits(c),
            watchdog_ms: match c.below(4) {
                0 => 0,
                1 => u16::MAX,
                _ => c.u16(),
            },
        }),
        1 | 2 => Reply::Ack { tactors_on: mask(c) },
        3 => Reply::Nak { reason: NakReason::from_code(c.u8()), tactors_on: mask(c) },
        4 => Reply::Status(UnitStatus {
            battery_mv: c.u16(),
            battery_pct: c.u8(),
            tactors_on: mask(c),
            faults: Faults(c.u8()),
            firmware: firmware(c),
        }),
        _ => Reply::Report { tactors_on: mask(c), faults: Faults(c.u8()) },
    }
}

/// A frame with a valid CRC around any header and payload: reaches the message parsers.
fn raw_frame(c: &mut Choices) -> Vec<u8> {
    let version = if c.chance(220) { 1 } else { c.u8() };
    let kind = if c.chance(200) {
        [0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x81, 0x82, 0x83, 0x84, 0x85][c.below(12)]
    } else {
        c.u8()
    };
    let n = c.below(211);
    let payload = c.take(n).to_vec();
    let declared = if c.chance(220) { payload.len() as u8 } else { c.u8() };
    let mut packet = vec![version, kind, c.u8(), declared];
    packet.extend_from_slice(&payload);
    let crc = if c.chance(240) { CRC16.checksum(&packet) } else { c.u16() };
    packet.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0];
    cobs_encode(&packet, &mut out);
    out.push(0);
    out
}

/// One piece of a byte stream to a decoder.
fn stream_item(c: &mut Choices, to_unit: bool) -> Vec<u8> {
    let codec = FrameCodec::with_max_version(1);
    match c.below(10) {
        0..=2 if to_unit => {
            let seq = c.u8();
            codec.encode_request(seq, &request(c)).unwrap_or_default()
        }
        0..=2 => {
            let seq = c.u8();
            codec.encode_reply(seq, &reply(c))
        }
        3 | 4 => raw_frame(c),
        5 | 6 => {
            // A valid frame with one to three bytes changed.
            let seq = c.u8();
            let mut f = if to_unit {
                codec.encode_request(seq, &request(c)).unwrap_or_default()
            } else {
                codec.encode_reply(seq, &reply(c))
            };
            for _ in 0..=c.below(3) {
                if !f.is_empty() {
                    let i = c.below(f.len());
                    f[i] ^= c.u8().max(1);
                }
            }
            f
        }
        7 => {
            let n = c.below(300);
            c.take(n).to_vec()
        }
        8 => vec![0xAA; MAX_ENCODED + c.below(600)],
        _ => vec![0; c.below(4)],
    }
}

// ---------------------------------------------------------------------------------------------------------
// Codec.

fn codec_check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let zeros = input.split(|&b| b == 0).count() - 1;
    let bound = zeros + input.len() / MAX_ENCODED + 1;
    let mut rng = Rng::new(input.len() as u64 ^ 0x55);
    let (mut req_codec, mut rep_codec) = (FrameCodec::new(), FrameCodec::new());
    let (mut requests, mut replies) = (Vec::new(), Vec::new());
    let mut rest = input;
    while !rest.is_empty() {
        let n = (1 + rng.size(700)).min(rest.len());
        req_codec.decode_requests(&rest[..n], &mut requests);
        rep_codec.decode_replies(&rest[..n], &mut replies);
        rest = &rest[n..];
    }
    if requests.len() > bound || replies.len() > bound {
        return Err(format!("decode results unbounded: {} / {} for {bound}", requests.len(), replies.len()));
    }
    // Re-encoded in the version each frame came in.
    let mut codec = FrameCodec::new();
    for p in requests.iter().flatten() {
        codec.set_version(p.version);
        let again =
            codec.encode_request(p.seq, &p.message).map_err(|e| format!("decoded request re-encode: {e}"))?;
        let mut out = Vec::new();
        FrameCodec::new().decode_requests(&again, &mut out);
        if out != vec![Ok(p.clone())] {
            return Err(format!("request does not round trip: {p:?} -> {out:?}"));
        }
    }
    for p in replies.iter().flatten() {
        codec.set_version(p.version);
        let again = codec.encode_reply(p.seq, &p.message);
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(&again, &mut out);
        if out != vec![Ok(p.clone())] {
            return Err(format!("reply does not round trip: {p:?} -> {out:?}"));
        }
    }
    bump(counts, "inputs");
    add(counts, "requests decoded", requests.iter().flatten().count() as u64);
    add(counts, "replies decoded", replies.iter().flatten().count() as u64);
    add(
        counts,
        "frames rejected",
        (requests.iter().filter(|r| r.is_err()).count() + replies.iter().filter(|r| r.is_err()).count())
            as u64,
    );
    Ok(())
}

fn codec_gen(rng: &mut Rng) -> Vec<u8> {
    let n = rng.size(4096);
    let script = rng.bytes(n);
    let mut c = Choices::new(&script);
    let mut out = Vec::new();
    let to_unit = rng.chance(0.5);
    while !c.is_empty() {
        out.extend(stream_item(&mut c, to_unit));
    }
    if rng.chance(0.3) {
        let rounds = 1 + rng.size(6);
        mutate(rng, &mut out, &[], rounds, 1 << 16);
    }
    out
}

// ---------------------------------------------------------------------------------------------------------
// The unit: an engine under a simulated clock, with its safety invariants.

struct Unit {
    engine: Engine,
    config: EngineConfig,
    /// What the unit drove, as (from, mask) steps.
    timeline: Vec<(Instant, TactorMask)>,
    tap: FrameCodec,
    to_console: Vec<u8>,
}

impl Unit {
    fn new(config: EngineConfig, t0: Instant) -> Self {
        Self {
            engine: UnitConfig::from(config.clone()).build(),
            config,
            timeline: vec![(t0, TactorMask::NONE)],
            tap: FrameCodec::new(),
            to_console: Vec::new(),
        }
    }

    /// Calls `handle_timeout` at every deadline up to `until`.
    fn run_until(&mut self, t: &mut Instant, until: Instant) -> Result<(), String> {
        let mut spins = 0;
        while let Some(d) = self.engine.poll_timeout().filter(|d| *d <= until) {
            *t = (*t).max(d);
            self.engine.handle_timeout(*t);
            self.after(*t)?;
            spins += 1;
            if spins > 10_000 {
                return Err(format!("engine timeouts do not advance: deadline {:?} at {:?}", d, *t));
            }
        }
        *t = (*t).max(until);
        Ok(())
    }

    fn feed(&mut self, bytes: &[u8], t: Instant) -> Result<(), String> {
        self.engine.handle_bytes(bytes, t);
        self.after(t)
    }

    /// Invariants after every call; drains what the engine sent and its events.
    fn after(&mut self, t: Instant) -> Result<(), String> {
        let on = self.engine.tactors_on();
        let lim = self.config.limits;
        if on.count() > u32::from(lim.max_simultaneous) {
            return Err(format!(
                "too many tactors: {} on ({on:?}), limit {}",
                on.count(),
                lim.max_simultaneous
            ));
        }
        if self.engine.identified()
            && let Some(rx) = self.engine.last_rx()
            && t >= rx + Duration::from_millis(u64::from(self.config.watchdog_ms))
            && !on.is_empty()
        {
            return Err(format!("watchdog expired {:?} ago but {on:?} still on", t - rx));
        }
        if self.timeline.last().is_some_and(|(_, m)| *m != on) {
            self.timeline.push((t, on));
        }
        let mut sent = 0;
        while let Some(frame) = self.engine.poll_transmit() {
            sent += 1;
            let mut out = Vec::new();
            self.tap.decode_replies(&frame, &mut out);
            if out.iter().any(Result::is_err) || out.is_empty() {
                return Err(format!("engine sent a frame its own codec rejects: {out:?}"));
            }
            self.to_console.extend_from_slice(&frame);
        }
        if sent > 600 {
            return Err(format!("engine sent {sent} frames in one call"));
        }
        while self.engine.poll_event().is_some() {}
        Ok(())
    }

    /// Continuous runs and duty windows over the whole timeline, from `timeline` up to `end`.
    fn check_timeline(&self, end: Instant) -> Result<(), String> {
        let lim = self.config.limits;
        let slack = Duration::from_millis(2);
        for tactor in 0..TACTOR_COUNT {
            // On-intervals of this tactor, with touching intervals merged (a zero-length break is no break).
            let mut runs: Vec<(Instant, Instant)> = Vec::new();
            for (i, (from, m)) in self.timeline.iter().enumerate() {
                if !m.contains(tactor) {
                    continue;
                }
                let to = self.timeline.get(i + 1).map_or(end, |x| x.0);
                match runs.last_mut() {
                    Some(last) if last.1 >= *from => last.1 = to,
                    _ => runs.push((*from, to)),
                }
            }
            let max_on = Duration::from_millis(u64::from(lim.max_on_ms));
            if let Some((s, e)) = runs.iter().find(|(s, e)| *e - *s > max_on + slack) {
                return Err(format!(
                    "continuous run too long: tactor {tactor} on for {} ms from t+{} ms, limit {} ms",
                    (*e - *s).as_millis(),
                    (*s - self.timeline[0].0).as_millis(),
                    lim.max_on_ms
                ));
            }
            let window = Duration::from_millis(u64::from(lim.duty_window_ms));
            let budget = Duration::from_millis(u64::from(lim.max_duty_on_ms));
            for (i, &(s, _)) in runs.iter().enumerate() {
                let w_end = s + window;
                let on: Duration =
                    runs[i..].iter().take_while(|r| r.0 < w_end).map(|r| r.1.min(w_end) - r.0).sum();
                if on > budget + slack {
                    return Err(format!(
                        "duty cycle exceeded: tactor {tactor} on {} ms in the {} ms window from t+{} ms, limit {} ms",
                        on.as_millis(),
                        lim.duty_window_ms,
                        (s - self.timeline[0].0).as_millis(),
                        lim.max_duty_on_ms
                    ));
                }
            }
        }
        Ok(())
    }
}

fn step(c: &mut Choices) -> Duration {
    Duration::from_millis(match c.below(14) {
        0 => 0,
        1 => 1,
        2 => 10,
        3 => 250,
        4 => 499,
        5 => 500,
        6 => 1499,
        7 => 1500,
        8 => 1501,
        9 => 2000,
        10 => 5000,
        11 => 10_000,
        _ => u64::from(c.u16() % 3000),
    })
}

fn engine_config(c: &mut Choices) -> EngineConfig {
    let mut config = EngineConfig::default();
    if c.chance(100) {
        config.limits = limits(c);
        config.watchdog_ms = [1, 100, 1500, u16::MAX][c.below(4)];
        config.intensity = c.chance(128);
    }
    config
}

fn engine_check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let mut c = Choices::new(input);
    let t0 = Instant::now();
    let mut t = t0;
    let mut unit = Unit::new(engine_config(&mut c), t0);
    let codec = FrameCodec::with_max_version(1);
    let mut steps = 0;
    while !c.is_empty() && steps < 400 {
        steps += 1;
        let dt = step(&mut c);
        let until = t + dt;
        unit.run_until(&mut t, until)?;
        let bytes = match c.below(8) {
            0 => codec.encode_request(c.u8(), &Request::Hello).unwrap_or_default(),
            1..=4 => {
                let seq = c.u8();
                codec.encode_request(seq, &request(&mut c)).unwrap_or_default()
            }
            _ => stream_item(&mut c, true),
        };
        // In one to three pieces, all at `t`.
        let cut = c.below(bytes.len() + 1);
        unit.feed(&bytes[..cut], t)?;
        unit.feed(&bytes[cut..], t)?;
    }
    // Every on-time, pattern and watchdog is at most u16::MAX ms: after that, silence means all off.
    let end = t + Duration::from_millis(u64::from(u16::MAX) + 1);
    unit.run_until(&mut t, end)?;
    if !unit.engine.tactors_on().is_empty() {
        return Err(format!("tactors {:?} still on 65.5 s after the last byte", unit.engine.tactors_on()));
    }
    unit.check_timeline(t)?;
    bump(counts, "inputs");
    add(counts, "steps", steps);
    add(counts, "tactor changes", unit.timeline.len() as u64);
    let st = unit.engine.stats();
    add(counts, "frames accepted", st.frames_ok);
    add(counts, "naks sent", st.naks_sent);
    add(counts, "watchdog trips", st.watchdog_trips);
    Ok(())
}

fn script_gen(rng: &mut Rng) -> Vec<u8> {
    let n = 16 + rng.size(6000);
    rng.bytes(n)
}

// ---------------------------------------------------------------------------------------------------------
// The console side, connected to a unit through a hostile channel.

/// Checks a request the console sent against the console's own limits.
fn console_request_ok(req: &Request, lim: &Limits) -> Result<(), String> {
    match req {
        Request::Fire { mask, duration_ms } => lim
            .check_fire(*mask, *duration_ms)
            .map_err(|e| format!("console sent a fire beyond its limits: {e}")),
        Request::Play { frames, repeats } => lim
            .check_pattern(frames, *repeats)
            .map_err(|e| format!("console sent a pattern beyond its limits: {e}")),
        _ => Ok(()),
    }
}

/// Changes bytes in transit: flips, drops, duplicates.
fn noisy(c: &mut Choices, bytes: &mut Vec<u8>) {
    match c.below(10) {
        0 if !bytes.is_empty() => {
            let i = c.below(bytes.len());
            bytes[i] ^= c.u8().max(1);
        }
        1 if !bytes.is_empty() => {
            let i = c.below(bytes.len());
            bytes.truncate(i);
        }
        2 => {
            let copy = bytes.clone();
            bytes.extend(copy);
        }
        3 => bytes.clear(),
        _ => {}
    }
}

#[allow(clippy::too_many_lines)]
fn link_check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let mut c = Choices::new(input);
    let t0 = Instant::now();
    let mut t = t0;
    let config = LinkConfig::default();
    let mut link = Link::new(config);
    let mut unit = Unit::new(engine_config(&mut c), t0);
    let codec = FrameCodec::with_max_version(1);
    let mut tap = FrameCodec::new();
    let mut to_unit: Vec<u8> = Vec::new();
    let mut last_seq = 0u8;
    let mut sent_frames = 0u64;
    let mut cues_sent = 0u64;
    link.connect(t);
    let mut steps = 0;
    while !c.is_empty() && steps < 400 {
        steps += 1;
        // Drain the console's output through the tap.
        let mut burst = 0;
        while let Some(frame) = link.poll_transmit() {
            burst += 1;
            sent_frames += 1;
            let mut out = Vec::new();
            tap.decode_requests(&frame, &mut out);
            for r in &out {
                match r {
                    Ok(Packet { seq, message, .. }) => {
                        last_seq = *seq;
                        if matches!(message, Request::Fire { mask, .. } if !mask.is_empty())
                            || matches!(message, Request::Play { .. })
                        {
                            cues_sent += 1;
                        }
                        console_request_ok(message, &config.limits)?;
                        console_request_ok(message, link.limits())?;
                    }
                    Err(e) => return Err(format!("console sent a malformed frame: {e}")),
                }
            }
            to_unit.extend_from_slice(&frame);
        }
        if burst > 64 {
            return Err(format!("console queued {burst} frames in one step"));
        }
        while link.poll_event().is_some() {}
        let l = link.limits();
        let cl = config.limits;
        if l.max_on_ms > cl.max_on_ms
            || l.max_simultaneous > cl.max_simultaneous
            || l.max_duty_on_ms > cl.max_duty_on_ms
            || l.duty_window_ms < cl.duty_window_ms
            || l.max_pattern_frames > cl.max_pattern_frames
            || l.max_pattern_ms > cl.max_pattern_ms
        {
            return Err(format!("console limits looser than its configuration: {l:?}"));
        }
        // Mostly short steps, so that handshakes and acks can happen within their timeouts.
        let dt = if c.chance(220) { Duration::from_millis(u64::from(c.u8())) } else { step(&mut c) };
        let until = t + dt;
        // Both sides' timers, in order.
        let mut spins = 0;
        loop {
            let next = [link.poll_timeout(), unit.engine.poll_timeout()]
                .into_iter()
                .flatten()
                .filter(|d| *d <= until)
                .min();
            let Some(d) = next else { break };
            t = t.max(d);
            link.handle_timeout(t);
            let now = t;
            unit.run_until(&mut t, now)?;
            spins += 1;
            if spins > 20_000 {
                return Err(format!("timeouts do not advance (would spin): link {:?}", link.poll_timeout()));
            }
        }
        t = until;
        if !matches!(link.state(), LinkState::Handshaking | LinkState::Ready) && c.chance(64) {
            // The worker reconnects after a loss.
            link.connect(t);
            tap.reset();
        }
        match c.below(12) {
            0 => {
                let (m, d) = (mask(&mut c), duration(&mut c));
                let _ = link.fire(m, d, t);
            }
            1 => {
                let frames = frames(&mut c);
                let repeats = c.below(4) as u8;
                let _ = link.play(&Pattern { name: "fuzz".into(), frames, repeats }, t);
            }
            2 => {
                let _ = link.stop_all(t);
            }
            3 => {
                let m = mask(&mut c);
                let _ = link.set_intensity(m, c.u8(), t);
            }
            4 => {
                let _ = link.request_status(t);
            }
            5 | 6 => {
                let mut bytes = std::mem::take(&mut to_unit);
                noisy(&mut c, &mut bytes);
                unit.feed(&bytes, t)?;
            }
            7 | 8 => {
                let mut bytes = std::mem::take(&mut unit.to_console);
                noisy(&mut c, &mut bytes);
                link.handle_bytes(&bytes, t);
            }
            9 => {
                // A forged reply to the request in flight.
                let seq = if c.chance(200) { last_seq } else { c.u8() };
                link.handle_bytes(&codec.encode_reply(seq, &reply(&mut c)), t);
            }
            10 => link.handle_bytes(&stream_item(&mut c, false), t),
            _ => match c.below(16) {
                0 | 1 => {
                    link.connect(t);
                    tap.reset();
                }
                2 | 3 => link.disconnect("fuzz"),
                _ => {}
            },
        }
    }
    bump(counts, "inputs");
    add(counts, "steps", steps);
    add(counts, "console frames sent", sent_frames);
    add(counts, "console ready at end", u64::from(link.is_ready()));
    add(counts, "console cues sent", cues_sent);
    let st = link.stats();
    add(counts, "console retransmits", st.retransmits);
    add(counts, "console bad frames", st.bad_frames);
    Ok(())
}

const KNOWN: &[Known] = &[];

#[test]
fn wtcu_codec_survives_hostile_streams() {
    harness::fuzz("wtcu-codec", 5000, KNOWN, codec_gen, codec_check);
}

#[test]
fn wtcu_engine_keeps_its_limits_under_fuzzed_scripts() {
    harness::fuzz("wtcu-engine", 2000, KNOWN, script_gen, engine_check);
}

#[test]
fn wtcu_link_stays_within_limits_on_a_hostile_channel() {
    harness::fuzz("wtcu-link", 2000, KNOWN, script_gen, link_check);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(harness::cases(512).min(50_000) as u32))]

    #[test]
    fn arbitrary_messages_round_trip(seq in any::<u8>(), choices in prop::collection::vec(any::<u8>(), 0..300)) {
        let mut c = Choices::new(&choices);
        let codec = FrameCodec::with_max_version(1);
        let req = request(&mut c);
        if let Ok(bytes) = codec.encode_request(seq, &req) {
            let mut out = Vec::new();
            FrameCodec::new().decode_requests(&bytes, &mut out);
            prop_assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: req })]);
        }
        let rep = reply(&mut c);
        let bytes = codec.encode_reply(seq, &rep);
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(&bytes, &mut out);
        prop_assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: rep })]);
    }
}
