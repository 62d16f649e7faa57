//! Integration tests of the WTCU protocol with a simulated clock: the console link against the device
//! engine (quinn's `Pair` idea), no IO, a lossy wire — acks, retransmits, link loss and the watchdog,
//! STOP ALL, and the safety limits checked on both sides.

// Helpers here are test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_core::vest::{Cue, DEFAULT_ON_MS, Frame, TactorMask};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::engine::{Engine, EngineConfig};
use vestnav_device::wtcu::limits::LimitError;
use vestnav_device::wtcu::link::{CommandError, Link, LinkConfig, LinkEvent, LinkState};
use vestnav_device::wtcu::message::{CommandKind, Faults, NakReason, Packet, Reply, Request};

// ---------------------------------------------------------------------------------------------------------
// Simulated-clock pair: the console link against the device engine, no IO, a lossy wire.

/// Decides, frame by frame, whether the simulated wire loses it.
type DropRule = Box<dyn FnMut(&[u8]) -> bool>;

struct Pair {
    now: Instant,
    console: Link,
    unit: Engine,
    /// Console-to-unit frames dropped while this returns true (called with the frame's bytes).
    drop_to_unit: DropRule,
    /// Unit-to-console frames dropped while this returns true.
    drop_to_console: DropRule,
    events: Vec<LinkEvent>,
    unit_changes: Vec<(Duration, TactorMask)>,
    t0: Instant,
}

impl Pair {
    fn new() -> Self {
        let t0 = Instant::now();
        Self {
            now: t0,
            console: Link::new(LinkConfig::default()),
            unit: UnitConfig::default().build(),
            drop_to_unit: Box::new(|_| false),
            drop_to_console: Box::new(|_| false),
            events: Vec::new(),
            unit_changes: Vec::new(),
            t0,
        }
    }

    /// Delivers every pending frame both ways (zero latency) until quiet.
    fn exchange(&mut self) {
        loop {
            let mut moved = false;
            while let Some(bytes) = self.console.poll_transmit() {
                moved = true;
                if !(self.drop_to_unit)(&bytes) {
                    self.unit.handle_bytes(&bytes, self.now);
                }
            }
            while let Some(bytes) = self.unit.poll_transmit() {
                moved = true;
                if !(self.drop_to_console)(&bytes) {
                    self.console.handle_bytes(&bytes, self.now);
                }
            }
            while let Some(e) = self.console.poll_event() {
                self.events.push(e);
            }
            while let Some(e) = self.unit.poll_event() {
                if let vestnav_device::wtcu::engine::EngineEvent::TactorsChanged(m) = e {
                    self.unit_changes.push((self.now - self.t0, m));
                }
            }
            if !moved {
                break;
            }
        }
    }

    /// Advances the clock to `until`, jumping from deadline to deadline.
    fn run_until(&mut self, until: Instant) {
        self.exchange();
        loop {
            let next = [self.console.poll_timeout(), self.unit.poll_timeout()].into_iter().flatten().min();
            match next {
                Some(t) if t <= until => {
                    self.now = self.now.max(t);
                    self.console.handle_timeout(self.now);
                    self.unit.handle_timeout(self.now);
                    self.exchange();
                }
                _ => break,
            }
        }
        self.now = until;
        self.console.handle_timeout(self.now);
        self.unit.handle_timeout(self.now);
        self.exchange();
    }

    fn advance_ms(&mut self, ms: u64) {
        let until = self.now + Duration::from_millis(ms);
        self.run_until(until);
    }

    fn connected() -> Self {
        let mut p = Self::new();
        p.console.connect(p.now);
        p.advance_ms(1);
        assert!(p.console.is_ready(), "{:?}", p.events);
        p.events.clear();
        p
    }
}

fn frame_kind(bytes: &[u8]) -> Option<u8> {
    let mut out = Vec::new();
    FrameCodec::new().decode_requests(bytes, &mut out);
    out.first().and_then(|r| r.as_ref().ok()).map(|p| match p.message {
        Request::HeadingStart { .. } => 8,
        Request::HeadingStop => 9,
        Request::SetCalibration(_) => 10,
        Request::Hello => 1,
        Request::Heartbeat => 2,
        Request::Fire { .. } => 3,
        Request::Play { .. } => 4,
        Request::SetIntensity { .. } => 5,
        Request::StopAll => 6,
        Request::GetStatus => 7,
        Request::GpsStart { .. } => 11,
        Request::GpsStop => 12,
    })
}

#[test]
fn pair_fire_is_acked_and_ends_by_itself() {
    let mut p = Pair::connected();
    let seq = p.console.fire(TactorMask::CORNERS, 500, p.now).unwrap();
    p.exchange();
    assert_eq!(p.unit.tactors_on(), TactorMask::CORNERS);
    assert_eq!(p.console.tactors_on(), Some(TactorMask::CORNERS));
    assert!(p.events.contains(&LinkEvent::Acked { seq, kind: CommandKind::Fire }));
    p.advance_ms(499);
    assert_eq!(p.unit.tactors_on(), TactorMask::CORNERS);
    p.advance_ms(1);
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    // The console learns it from the unit's REPORT, not from its own clock.
    assert_eq!(p.console.tactors_on(), Some(TactorMask::NONE));
    // Heartbeats kept the link alive meanwhile; over 10 s idle nothing is lost.
    p.advance_ms(10_000);
    assert!(p.console.is_ready());
    assert_eq!(p.unit.stats().watchdog_trips, 0);
}

#[test]
fn pair_pattern_steps_on_the_unit_clock() {
    let mut p = Pair::connected();
    let pattern = Cue::TurnRight.pattern(DEFAULT_ON_MS);
    p.console.play(&pattern, p.now).unwrap();
    p.advance_ms(2000);
    let seen: Vec<(u128, u16)> = p.unit_changes.iter().map(|(t, m)| (t.as_millis(), m.0)).collect();
    let start = seen[0].0;
    let col = |c| TactorMask::column(c).0;
    assert_eq!(
        seen.iter().map(|&(t, m)| (t - start, m)).collect::<Vec<_>>(),
        vec![(0, col(0)), (250, col(1)), (500, col(2)), (750, col(3)), (1000, 0)]
    );
}

#[test]
fn pair_dropped_command_is_retransmitted_once() {
    let mut p = Pair::connected();
    let mut dropped = false;
    p.drop_to_unit = Box::new(move |b| {
        if frame_kind(b) == Some(3) && !dropped {
            dropped = true;
            return true;
        }
        false
    });
    let sent_at = p.now;
    p.console.fire(TactorMask(0b11), 1000, p.now).unwrap();
    p.exchange();
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    p.advance_ms(200);
    assert_eq!(p.unit.tactors_on(), TactorMask(0b11));
    assert_eq!(p.console.stats().retransmits, 1);
    // The retransmitted fire runs its full 1000 ms from when it arrived.
    p.run_until(sent_at + Duration::from_millis(1199));
    assert_eq!(p.unit.tactors_on(), TactorMask(0b11));
    p.run_until(sent_at + Duration::from_millis(1200));
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
}

#[test]
fn pair_lost_ack_does_not_run_the_command_twice() {
    let mut p = Pair::connected();
    let mut dropped = false;
    p.drop_to_console = Box::new(move |b| {
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(b, &mut out);
        let is_fire_ack = matches!(out.first(), Some(Ok(Packet { message: Reply::Ack { tactors_on }, .. })) if *tactors_on == TactorMask(1));
        if is_fire_ack && !dropped {
            dropped = true;
            return true;
        }
        false
    });
    let start = p.now;
    let seq = p.console.fire(TactorMask(1), 600, p.now).unwrap();
    p.advance_ms(250);
    assert!(p.events.contains(&LinkEvent::Acked { seq, kind: CommandKind::Fire }));
    assert_eq!(p.unit.stats().duplicates, 1);
    // Not restarted by the duplicate: ends 600 ms after the first copy.
    p.run_until(start + Duration::from_millis(600));
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
}

#[test]
fn pair_silence_loses_the_link_and_trips_the_watchdog() {
    let mut p = Pair::connected();
    let pattern = vestnav_core::vest::Pattern {
        name: "long".into(),
        frames: vec![
            Frame { mask: TactorMask(0x000F), duration_ms: 500 },
            Frame { mask: TactorMask(0x00F0), duration_ms: 500 },
        ],
        repeats: 5,
    };
    p.console.play(&pattern, p.now).unwrap();
    p.exchange();
    let cut = p.now;
    let cut_flag = Arc::new(Mutex::new(true));
    let f = cut_flag.clone();
    p.drop_to_unit = Box::new(move |_| *f.lock().unwrap());
    let f = cut_flag.clone();
    p.drop_to_console = Box::new(move |_| *f.lock().unwrap());
    p.advance_ms(3000);
    // Console: lost after 1000 ms of silence.
    assert!(p.events.iter().any(|e| matches!(e, LinkEvent::State(LinkState::Lost { .. }))), "{:?}", p.events);
    assert_eq!(p.console.tactors_on(), None);
    // Unit: everything off exactly at the watchdog bound after the last frame it heard.
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    assert_eq!(p.unit.stats().watchdog_trips, 1);
    let last_rx = p.unit.last_rx().unwrap();
    let (off_at, off) = *p.unit_changes.last().unwrap();
    assert_eq!(off, TactorMask::NONE);
    assert_eq!(p.t0 + off_at - last_rx, Duration::from_millis(1500));
    assert!(last_rx >= cut);
    // Reconnect on the same wire.
    *cut_flag.lock().unwrap() = false;
    p.console.connect(p.now);
    p.advance_ms(1);
    assert!(p.console.is_ready());
}

#[test]
fn pair_stop_all_jumps_the_queue_and_cancels_cues() {
    let mut p = Pair::connected();
    // Hold the unit's replies so the fire stays in flight.
    let hold = Arc::new(Mutex::new(true));
    let h = hold.clone();
    p.drop_to_console = Box::new(move |_| *h.lock().unwrap());
    let fire = p.console.fire(TactorMask(1), 1000, p.now).unwrap();
    let play = p.console.play(&Cue::Stop.pattern(500), p.now).unwrap();
    p.exchange();
    let stop = p.console.stop_all(p.now).unwrap();
    *hold.lock().unwrap() = false;
    p.exchange();
    assert!(p.events.contains(&LinkEvent::Cancelled { seq: fire, kind: CommandKind::Fire }));
    assert!(p.events.contains(&LinkEvent::Cancelled { seq: play, kind: CommandKind::Play }));
    assert!(p.events.contains(&LinkEvent::Acked { seq: stop, kind: CommandKind::StopAll }));
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    assert_eq!(p.console.tactors_on(), Some(TactorMask::NONE));
}

#[test]
fn pair_stop_all_is_retried_until_acknowledged() {
    let mut p = Pair::connected();
    p.console.fire(TactorMask(1), 2000, p.now).unwrap();
    p.exchange();
    let mut lost = 0;
    p.drop_to_unit = Box::new(move |b| {
        if frame_kind(b) == Some(6) && lost < 4 {
            lost += 1;
            return true;
        }
        false
    });
    let stop = p.console.stop_all(p.now).unwrap();
    p.advance_ms(900);
    assert!(p.events.contains(&LinkEvent::Acked { seq: stop, kind: CommandKind::StopAll }));
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    assert_eq!(p.console.stats().retransmits, 4);
}

#[test]
fn console_refuses_out_of_bound_commands_before_sending() {
    let mut p = Pair::connected();
    let n = p.console.stats().sent;
    assert!(matches!(
        p.console.fire(TactorMask(0x01FF), 100, p.now),
        Err(CommandError::Limit(LimitError::TooManyTactors { requested: 9, max: 8 }))
    ));
    assert!(matches!(
        p.console.fire(TactorMask(1), 2001, p.now),
        Err(CommandError::Limit(LimitError::OnTooLong { .. }))
    ));
    // Duty cycle: 2 x 2000 ms + 1000 ms fits 5000 ms per 10 s; one more millisecond-heavy fire does not.
    // (The fires are 1 ms apart: back to back they would be one 4000 ms run, refused for the on-time.)
    for _ in 0..2 {
        p.console.fire(TactorMask(1), 2000, p.now).unwrap();
        p.advance_ms(2001);
    }
    p.console.fire(TactorMask(1), 1000, p.now).unwrap();
    p.advance_ms(1000);
    assert!(matches!(
        p.console.fire(TactorMask(1), 500, p.now),
        Err(CommandError::Limit(LimitError::DutyCycle { tactor: 0, .. }))
    ));
    // Another tactor is fine, and nothing refused was ever sent.
    p.console.fire(TactorMask(2), 500, p.now).unwrap();
    assert_eq!(p.unit.stats().naks_sent, 0);
    assert!(p.console.stats().sent > n);
}

#[test]
fn a_repeated_pattern_cannot_bypass_the_on_time_limit() {
    // The issue: PLAY repeats=5 of [(0x00FF, 1000 ms)] kept 8 tactors on for 5001 ms.
    let pattern = vestnav_core::vest::Pattern {
        name: "saved by a user".into(),
        frames: vec![Frame { mask: TactorMask(0x00FF), duration_ms: 1000 }],
        repeats: 5,
    };
    let mut p = Pair::connected();
    assert_eq!(
        p.console.play(&pattern, p.now),
        Err(CommandError::Limit(LimitError::OnTooLong { requested_ms: 5000, max_ms: 2000 }))
    );
    // The unit refuses it too when a console does not check.
    let mut unit = UnitConfig::default().build();
    let codec = FrameCodec::with_max_version(1);
    unit.handle_bytes(&codec.encode_request(0, &Request::Hello).unwrap(), p.now);
    let play = Request::Play { frames: pattern.frames.clone(), repeats: 5 };
    unit.handle_bytes(&codec.encode_request(1, &play).unwrap(), p.now);
    let mut replies = Vec::new();
    while let Some(frame) = unit.poll_transmit() {
        FrameCodec::new().decode_replies(&frame, &mut replies);
    }
    assert_eq!(
        replies.last().unwrap().as_ref().unwrap().message,
        Reply::Nak { reason: NakReason::DurationLimit, tactors_on: TactorMask::NONE }
    );
    p.advance_ms(6000);
    assert!(p.unit_changes.is_empty());
}

#[test]
fn chained_cues_cannot_keep_a_tactor_on_past_the_limit() {
    let mut p = Pair::connected();
    p.console.fire(TactorMask(1), 2000, p.now).unwrap();
    p.advance_ms(2000);
    // The fire has just ended; one more at this very instant would make one 4000 ms run.
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    assert_eq!(
        p.console.fire(TactorMask(1), 2000, p.now),
        Err(CommandError::Limit(LimitError::RunTooLong {
            tactor: 0,
            on_for_ms: 2000,
            requested_ms: 2000,
            max_ms: 2000
        }))
    );
    p.advance_ms(1);
    p.console.fire(TactorMask(1), 1500, p.now).unwrap();
    p.advance_ms(1000);
    // 1000 ms into the run: 1000 ms more is the limit exactly, 1001 is not; a pattern continuing it alike.
    let refused = p.console.fire(TactorMask(3), 1001, p.now);
    assert!(
        matches!(refused, Err(CommandError::Limit(LimitError::RunTooLong { tactor: 0, .. }))),
        "{refused:?}"
    );
    let pattern = vestnav_core::vest::Pattern {
        name: "continues".into(),
        frames: vec![
            Frame { mask: TactorMask(1), duration_ms: 1200 },
            Frame { mask: TactorMask(2), duration_ms: 100 },
        ],
        repeats: 1,
    };
    assert!(matches!(
        p.console.play(&pattern, p.now),
        Err(CommandError::Limit(LimitError::RunTooLong { .. }))
    ));
    p.console.fire(TactorMask(3), 1000, p.now).unwrap();
    p.advance_ms(1000);
    assert_eq!(p.unit.tactors_on(), TactorMask::NONE);
    // The unit saw only what the console let through and refused nothing.
    assert_eq!(p.unit.stats().naks_sent, 0);
    // The unit holds the same line on its own: a console that does not check gets a NAK 0x05.
    let mut unit = UnitConfig::default().build();
    let codec = FrameCodec::with_max_version(1);
    let t = p.now;
    let ms = |m| t + Duration::from_millis(m);
    unit.handle_bytes(&codec.encode_request(0, &Request::Hello).unwrap(), ms(0));
    unit.handle_bytes(
        &codec.encode_request(1, &Request::Fire { mask: TactorMask(1), duration_ms: 2000 }).unwrap(),
        ms(0),
    );
    unit.handle_bytes(&codec.encode_request(2, &Request::Heartbeat).unwrap(), ms(1000));
    unit.handle_timeout(ms(2000));
    unit.handle_bytes(
        &codec.encode_request(3, &Request::Fire { mask: TactorMask(1), duration_ms: 2000 }).unwrap(),
        ms(2000),
    );
    let mut replies = Vec::new();
    while let Some(frame) = unit.poll_transmit() {
        FrameCodec::new().decode_replies(&frame, &mut replies);
    }
    assert_eq!(
        replies.last().unwrap().as_ref().unwrap(),
        &Packet {
            version: 1,
            seq: 3,
            message: Reply::Nak { reason: NakReason::DurationLimit, tactors_on: TactorMask::NONE }
        }
    );
}

#[test]
fn unit_naks_out_of_bound_and_bad_requests() {
    let t = Instant::now();
    let codec = FrameCodec::with_max_version(1);
    let mut unit = UnitConfig::from(EngineConfig { intensity: false, ..EngineConfig::default() }).build();
    let mut replies = FrameCodec::new();
    let mut ask = |unit: &mut Engine, bytes: Vec<u8>| -> Reply {
        unit.handle_bytes(&bytes, t);
        let mut out = Vec::new();
        replies.decode_replies(&unit.poll_transmit().unwrap(), &mut out);
        out.pop().unwrap().unwrap().message
    };
    let nak = |reason| Reply::Nak { reason, tactors_on: TactorMask::NONE };
    let fire = |mask, ms| {
        codec.encode_request(1, &Request::Fire { mask: TactorMask(mask), duration_ms: ms }).unwrap()
    };
    assert_eq!(ask(&mut unit, fire(1, 100)), nak(NakReason::NotIdentified));
    assert!(matches!(ask(&mut unit, codec.encode_request(0, &Request::Hello).unwrap()), Reply::Identify(_)));
    assert_eq!(ask(&mut unit, fire(0x01FF, 100)), nak(NakReason::TooManyTactors));
    assert_eq!(ask(&mut unit, fire(1, 2001)), nak(NakReason::DurationLimit));
    assert_eq!(ask(&mut unit, fire(1, 0)), nak(NakReason::DurationLimit));
    let long = Request::Play { frames: vec![Frame { mask: TactorMask(1), duration_ms: 3000 }], repeats: 1 };
    assert_eq!(ask(&mut unit, codec.encode_request(2, &long).unwrap()), nak(NakReason::DurationLimit));
    let many = Request::Play { frames: vec![Frame { mask: TactorMask(0), duration_ms: 10 }; 33], repeats: 1 };
    assert_eq!(ask(&mut unit, codec.encode_request(3, &many).unwrap()), nak(NakReason::PatternLimit));
    let intensity = Request::SetIntensity { mask: TactorMask(1), level: 9 };
    assert_eq!(ask(&mut unit, codec.encode_request(4, &intensity).unwrap()), nak(NakReason::NotSupported));
    // Unknown type 0x42 with a valid CRC (built by hand: version 1, type 0x42, seq 5, no payload).
    let mut packet = vec![1, 0x42, 5, 0];
    let crc = vestnav_device::wtcu::codec::CRC16.checksum(&packet);
    packet.extend_from_slice(&crc.to_le_bytes());
    let mut raw = vec![0];
    vestnav_device::wtcu::codec::cobs_encode(&packet, &mut raw);
    raw.push(0);
    assert_eq!(ask(&mut unit, raw), nak(NakReason::UnknownCommand));
    // A flipped payload bit: bad CRC.
    let mut bad = fire(1, 100);
    bad[6] ^= 0x04;
    assert_eq!(ask(&mut unit, bad), nak(NakReason::BadCrc));
    assert_eq!(unit.stats().bad_crc, 1);
    assert!(unit.status().faults.contains(Faults::LIMIT_REJECTED));
    assert_eq!(unit.tactors_on(), TactorMask::NONE);
}
