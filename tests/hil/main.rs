//! The WTCU conformance suite: one set of checks, run against every implementation of the unit side of
//! `docs/wtcu-protocol.md` over a real pseudo-terminal, exactly as the console talks to `/dev/rfcomm0`:
//!
//! - `emulator`: the Rust emulator (`vestnav_device::wtcu::engine` behind `PtyEmulator`), with a GPS
//!   receiver sending a real receiver log;
//! - `firmware-mega`: the reference firmware (`firmware/build/wtcu-mega.elf`, the image one flashes) in
//!   simavr through `firmware/build/wtcu-sim`, with the same receiver log on its second UART and a
//!   simulated LSM303AGR;
//! - `firmware-nano`: the tactor-only `ATmega328P` build.
//!
//! The checks speak bytes through an independent client (the framing in `vestnav_device::wtcu::codec`,
//! itself checked against the document's vectors) and judge the unit by the document: replies, NAK
//! reasons, timing. For the firmware they also judge what the tactor **pins** did on the simulated clock
//! (the harness reports every change): on-times, the watchdog's all-off measured from the instant the
//! last frame reached the unit, the current budget (never more than 8 on), no run longer than
//! `max_on_ms`. The simulation is paced to wall-clock time, so the console-side timeouts hold as on a
//! board; pin durations are read on the simulated clock.
//!
//! `scripts/hil.sh` builds the firmware and the harness and runs this with `VESTNAV_HIL_REQUIRE_FIRMWARE=1`;
//! a plain `cargo test` without the AVR toolchain's outputs runs the emulator target only and says so.
//! Prints "N passed, M failed" and exits non-zero on a failure.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout, clippy::print_stderr)]

use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use vestnav_core::vest::{Frame, TactorMask};
use vestnav_device::sim::{CompassSetup, WearerMotion};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec, cobs_encode};
use vestnav_device::wtcu::emulator::{PtyEmulator, UnitConfig};
use vestnav_device::wtcu::engine::{EngineConfig, battery_pct_from_mv};
use vestnav_device::wtcu::firmware_sim::{FirmwareSim, FirmwareSimConfig, SimEvent, field_for_heading};
use vestnav_device::wtcu::message::{
    CalibrationWire, Capabilities, DeviceInfo, Faults, NakReason, Packet, Reply, Request,
};

mod client;
use client::{Client, ack, fire, nak, raw_frame};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// A real receiver's log (`GlobalSat` BU-353-S4, gpsd's regression suite): what the unit's GPS sends.
const GPS_LOG: &str = "tests/data/gpsd-logs/bu353s4.log";
const BATTERY_MV: u16 = 3900;
/// The field at the sensor: 20 µT horizontal, 45 µT down (|B| = 49.2 µT).
const FIELD_H: f64 = 20.0;
const FIELD_Z: f64 = 45.0;

type Check = Result<(), String>;

macro_rules! ensure {
    ($cond:expr, $($fmt:tt)+) => {
        let holds: bool = $cond;
        if !holds {
            return Err(format!($($fmt)+));
        }
    };
}

// ---------------------------------------------------------------------------------------------------------
// The unit under test.

struct Unit {
    name: &'static str,
    path: String,
    sim: Option<FirmwareSim>,
    _emulator: Option<PtyEmulator>,
    /// Every harness report so far (firmware only).
    pins: Vec<SimEvent>,
}

impl Unit {
    fn emulator() -> Self {
        let nmea = std::fs::read(Path::new(ROOT).join(GPS_LOG)).unwrap();
        let config = UnitConfig {
            engine: EngineConfig {
                battery_mv: BATTERY_MV,
                gps_nmea: Some(nmea.into()),
                ..EngineConfig::default()
            },
            compass: Some(CompassSetup {
                motion: WearerMotion::Still { heading_deg: 0.0 },
                ideal: true,
                ..CompassSetup::default()
            }),
            skin: None,
        };
        let emu = PtyEmulator::spawn(config).unwrap();
        Self {
            name: "emulator",
            path: emu.path().to_owned(),
            sim: None,
            _emulator: Some(emu),
            pins: Vec::new(),
        }
    }

    fn firmware(name: &'static str, elf: &Path) -> Result<Self, String> {
        let mut config = FirmwareSimConfig::new(elf);
        config.battery_mv = BATTERY_MV;
        config.gps_nmea = Some(Path::new(ROOT).join(GPS_LOG));
        config.mag_ut = Some(field_for_heading(0.0, FIELD_H, FIELD_Z));
        let sim = FirmwareSim::spawn(&config)?;
        Ok(Self { name, path: sim.path().to_owned(), sim: Some(sim), _emulator: None, pins: Vec::new() })
    }

    fn collect(&mut self) {
        if let Some(sim) = &self.sim {
            self.pins.extend(sim.drain_events());
        }
    }

    fn has_pins(&self) -> bool {
        self.sim.is_some()
    }
}

/// The pin log between two marks: (`sim_us`, mask) changes, and the delimiter arrivals.
fn pin_changes(events: &[SimEvent]) -> Vec<(u64, TactorMask)> {
    events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Pins { sim_us, mask } => Some((*sim_us, *mask)),
            _ => None,
        })
        .collect()
}

/// On-periods of `tactor` in a pin log: (start, end) in simulated µs; a period still open has no end.
fn on_periods(changes: &[(u64, TactorMask)], tactor: usize, before: TactorMask) -> Vec<(u64, Option<u64>)> {
    let mut out = Vec::new();
    let mut on = before.contains(tactor).then_some(0);
    for &(t, mask) in changes {
        match (on, mask.contains(tactor)) {
            (None, true) => on = Some(t),
            (Some(start), false) => {
                out.push((start, Some(t)));
                on = None;
            }
            _ => {}
        }
    }
    if let Some(start) = on {
        out.push((start, None));
    }
    out
}

// ---------------------------------------------------------------------------------------------------------
// The checks, in order (the first needs a unit nobody has said HELLO to).

struct Ctx<'a> {
    unit: &'a mut Unit,
    client: Client,
    info: Option<DeviceInfo>,
}

impl Ctx<'_> {
    fn caps(&self) -> Capabilities {
        self.info.map(|i| i.capabilities).unwrap_or_default()
    }

    /// Pin changes since `mark` (an index into the unit's log).
    fn pins_since(&mut self, mark: usize) -> Vec<SimEvent> {
        self.unit.collect();
        self.unit.pins[mark..].to_vec()
    }

    fn mark(&mut self) -> usize {
        self.unit.collect();
        self.unit.pins.len()
    }

    /// The unit's clock as far as the harness has reported it: the newest delimiter it saw go in or out
    /// (firmware only).
    fn sim_now(&mut self) -> Option<u64> {
        self.unit.collect();
        self.unit.pins.iter().rev().find_map(|e| match e {
            SimEvent::Rx(t) | SimEvent::Tx(t) => Some(*t),
            _ => None,
        })
    }

    /// Waits `d` on the unit's own clock, keeping its watchdog fed. The simulated firmware is paced to the
    /// wall clock but falls behind on a loaded machine; a wait on the wall clock would then be shorter on
    /// the unit's, and a check of its timing would judge the machine, not the firmware.
    fn wait_unit(&mut self, d: Duration) {
        let Some(t0) = self.sim_now() else {
            self.client.idle(d);
            return;
        };
        let target = t0 + u64::try_from(d.as_micros()).unwrap_or(u64::MAX);
        let give_up = Instant::now() + d * 4 + Duration::from_secs(2);
        self.client.idle(d);
        while self.sim_now().is_none_or(|t| t < target) && Instant::now() < give_up {
            self.client.idle(Duration::from_millis(20));
        }
    }
}

fn before_hello(c: &mut Ctx) -> Check {
    nak(&c.client.ask(&Request::Heartbeat)?, NakReason::NotIdentified)?;
    nak(&c.client.ask(&fire(1, 100))?, NakReason::NotIdentified)
}

fn handshake(c: &mut Ctx) -> Check {
    let reply = c.client.ask(&Request::Hello)?;
    ensure!(reply.version == 2, "IDENTIFY in a v{} header to a v2 HELLO", reply.version);
    let Reply::Identify(info) = reply.message else { return Err(format!("got {:?}", reply.message)) };
    ensure!(info.tactor_count == 16, "{} tactors", info.tactor_count);
    ensure!(info.watchdog_ms == 1500, "watchdog {} ms", info.watchdog_ms);
    let l = info.limits;
    ensure!(
        (
            l.max_on_ms,
            l.max_simultaneous,
            l.duty_window_ms,
            l.max_duty_on_ms,
            l.max_pattern_frames,
            l.max_pattern_ms
        ) == (2000, 8, 10_000, 5000, 32, 10_000),
        "limits {l:?} are not the document's defaults"
    );
    ensure!(info.capabilities.contains(Capabilities::PATTERNS), "no patterns capability");
    c.info = Some(info);
    Ok(())
}

fn v1_session(c: &mut Ctx) -> Check {
    let reply = c.client.ask_v(1, &Request::Hello)?;
    ensure!(reply.version == 1, "a v1 HELLO answered in a v{} header", reply.version);
    let Reply::Identify(info) = reply.message else { return Err(format!("got {:?}", reply.message)) };
    ensure!(
        !info.capabilities.contains(Capabilities::HEADING) && !info.capabilities.contains(Capabilities::GPS),
        "v2 capabilities in a v1 session: {:?}",
        info.capabilities
    );
    // A v2 message type in a v1 header is unknown, as on a v1 unit.
    let seq = c.client.next_seq();
    c.client.send_raw(&raw_frame(1, 0x08, seq, &[5], false));
    let r = c.client.read_for(Duration::from_millis(500), |p| p.seq == seq).ok_or("no answer")?;
    ensure!(r.version == 1, "answered in a v{} header inside a v1 session", r.version);
    nak(&r, NakReason::UnknownCommand)?;
    c.client.hello().map(drop)
}

fn heartbeat_and_status(c: &mut Ctx) -> Check {
    ack(&c.client.ask(&Request::Heartbeat)?)?;
    let Reply::Status(s) = c.client.ask(&Request::GetStatus)?.message else { return Err("no STATUS".into()) };
    ensure!(
        s.battery_mv.abs_diff(BATTERY_MV) <= 40,
        "battery {} mV, the ADC sees {BATTERY_MV} mV",
        s.battery_mv
    );
    ensure!(
        s.battery_pct == battery_pct_from_mv(s.battery_mv),
        "battery {} % for {} mV; the document's linear model gives {} %",
        s.battery_pct,
        s.battery_mv,
        battery_pct_from_mv(s.battery_mv)
    );
    let firmware = c.info.map(|i| i.firmware).unwrap_or_default();
    ensure!(s.firmware == firmware, "STATUS firmware {} but IDENTIFY {}", s.firmware, firmware);
    ensure!(s.tactors_on == TactorMask::NONE, "tactors {:?} on after HELLO", s.tactors_on);
    Ok(())
}

fn fire_runs_for_its_duration(c: &mut Ctx) -> Check {
    let mark = c.mark();
    let on = ack(&c.client.ask(&fire(0x9009, 500))?)?;
    ensure!(on == TactorMask(0x9009), "ACK says {on:?} on");
    c.wait_unit(Duration::from_millis(700));
    let report = c.client.unsolicited.iter().rev().find_map(|(_, p)| match p.message {
        Reply::Report { tactors_on, .. } => Some(tactors_on),
        _ => None,
    });
    ensure!(report == Some(TactorMask::NONE), "no REPORT of the fire's end (last: {report:?})");
    if c.unit.has_pins() {
        let changes = pin_changes(&c.pins_since(mark));
        let periods = on_periods(&changes, 0, TactorMask::NONE);
        // The tactors sit on up to three ports written microseconds apart (the 328P's D, B and C).
        let t0 = changes.first().map_or(0, |c| c.0);
        let settled = changes.iter().take_while(|c| c.0 <= t0 + 20).last().map(|c| c.1);
        ensure!(settled == Some(TactorMask(0x9009)), "pins {changes:?}");
        let [(start, Some(end))] = periods[..] else { return Err(format!("tactor 0 periods {periods:?}")) };
        let ms = (end - start) as f64 / 1000.0;
        ensure!((495.0..=500.0).contains(&ms), "corners on {ms:.2} ms on the pins for a 500 ms FIRE");
    }
    Ok(())
}

fn play_steps_on_the_units_clock(c: &mut Ctx) -> Check {
    let mark = c.mark();
    let frames = vec![
        Frame { mask: TactorMask(0x0002), duration_ms: 200 },
        Frame { mask: TactorMask(0x0004), duration_ms: 200 },
        Frame { mask: TactorMask::NONE, duration_ms: 100 },
    ];
    ack(&c.client.ask(&Request::Play { frames, repeats: 2 })?)?;
    c.wait_unit(Duration::from_millis(1200));
    let reports: Vec<TactorMask> = c
        .client
        .unsolicited
        .iter()
        .filter_map(|(_, p)| match p.message {
            Reply::Report { tactors_on, .. } => Some(tactors_on),
            _ => None,
        })
        .collect();
    ensure!(reports.ends_with(&[TactorMask::NONE]), "the pattern's end was not reported: {reports:?}");
    ensure!(reports.contains(&TactorMask(0x0004)), "the second frame was not reported: {reports:?}");
    if c.unit.has_pins() {
        let changes = pin_changes(&c.pins_since(mark));
        let masks: Vec<u16> = changes.iter().map(|c| c.1.0).collect();
        ensure!(masks == [2, 4, 0, 2, 4, 0], "pin sequence {masks:x?}, want 2 4 0 2 4 0");
        // Steps after the first land on the pattern's grid: 200, 400, 500, 700, 900 ms after its start.
        let t0 = changes[0].0;
        for (i, want_ms) in [(1, 200.0), (2, 400.0), (3, 500.0), (4, 700.0), (5, 900.0)] {
            let got = (changes[i].0 - t0) as f64 / 1000.0;
            ensure!((got - want_ms).abs() <= 2.0, "step {i} at {got:.2} ms, want {want_ms} ms");
        }
    }
    Ok(())
}

/// Frames arriving while a pattern steps: the pins follow the pattern exactly. A frame completed just
/// before a step's tick used to republish the older outputs for one millisecond (CI saw 2 0 2 in the PLAY
/// check); a HEARTBEAT every millisecond or so over 240 short steps puts frame ends next to step ticks.
fn play_under_a_frame_flood(c: &mut Ctx) -> Check {
    let mark = c.mark();
    let masks = [0x0001u16, 0x0010, 0x0100, 0x1000, 0x0002, 0x0020];
    let frames: Vec<Frame> =
        masks.iter().cycle().take(24).map(|&m| Frame { mask: TactorMask(m), duration_ms: 5 }).collect();
    ack(&c.client.ask(&Request::Play { frames, repeats: 10 })?)?;
    let end = Instant::now() + Duration::from_millis(1300);
    while Instant::now() < end {
        let seq = c.client.next_seq();
        let frame = c.client.codec.encode_request(seq, &Request::Heartbeat).unwrap();
        c.client.send_raw(&frame);
        c.client.read_for(Duration::from_millis(1), |_| false);
    }
    c.wait_unit(Duration::from_millis(200));
    if c.unit.has_pins() {
        // A step that moves tactors on two ports passes through an in-between state for a few µs (the
        // nano writes its ports one after another): such a state, held under 50 µs on the way from one
        // step to a different one, is left out. A return to the state before is a glitch, however short.
        let changes = pin_changes(&c.pins_since(mark));
        let mut got: Vec<u16> = Vec::new();
        for (i, &(t, TactorMask(m))) in changes.iter().enumerate() {
            let prev = if i == 0 { 0 } else { changes[i - 1].1.0 };
            let in_between = changes.get(i + 1).is_some_and(|&(t_next, TactorMask(next))| {
                t_next - t < 50 && next != prev && m & !(prev | next) == 0 && prev & next & !m == 0
            });
            if !in_between {
                got.push(m);
            }
        }
        let mut want: Vec<u16> = masks.iter().copied().cycle().take(240).collect();
        want.push(0);
        ensure!(got == want, "pin sequence {got:x?}, want the pattern 10 times then 0");
    }
    Ok(())
}

fn limits_are_refused_without_effect(c: &mut Ctx) -> Check {
    let mark = c.mark();
    nak(&c.client.ask(&fire(0x0001, 2001))?, NakReason::DurationLimit)?;
    nak(&c.client.ask(&fire(0x0001, 0))?, NakReason::DurationLimit)?;
    nak(&c.client.ask(&fire(0x01FF, 100))?, NakReason::TooManyTactors)?;
    let too_many = vec![Frame { mask: TactorMask(0x0001), duration_ms: 10 }; 33];
    nak(&c.client.ask(&Request::Play { frames: too_many, repeats: 1 })?, NakReason::PatternLimit)?;
    nak(&c.client.ask(&Request::Play { frames: vec![], repeats: 1 })?, NakReason::PatternLimit)?;
    let once = vec![Frame { mask: TactorMask(0x0001), duration_ms: 100 }];
    nak(&c.client.ask(&Request::Play { frames: once.clone(), repeats: 0 })?, NakReason::PatternLimit)?;
    // A pattern whose tactor runs through every repeat: 3 x 800 ms = 2400 ms without a break.
    let held = vec![Frame { mask: TactorMask(0x0001), duration_ms: 800 }];
    nak(&c.client.ask(&Request::Play { frames: held, repeats: 3 })?, NakReason::DurationLimit)?;
    // Nothing ran.
    let Reply::Status(s) = c.client.ask(&Request::GetStatus)?.message else { return Err("no STATUS".into()) };
    ensure!(s.faults.contains(Faults::LIMIT_REJECTED), "fault 0x04 not raised: {:?}", s.faults);
    ensure!(s.tactors_on == TactorMask::NONE, "{:?} on after refused commands", s.tactors_on);
    if c.unit.has_pins() {
        let changes = pin_changes(&c.pins_since(mark));
        ensure!(changes.is_empty(), "refused commands moved pins: {changes:?}");
    }
    Ok(())
}

fn a_run_cannot_be_chained_past_the_limit(c: &mut Ctx) -> Check {
    let mark = c.mark();
    ack(&c.client.ask(&fire(0x0020, 1500))?)?;
    c.wait_unit(Duration::from_millis(1100));
    // 1.1 s into the run, 1000 ms more would make 2.1 s without a break.
    nak(&c.client.ask(&fire(0x0020, 1000))?, NakReason::DurationLimit)?;
    // 300 ms more stays within 2 s.
    ack(&c.client.ask(&fire(0x0020, 300))?)?;
    c.wait_unit(Duration::from_millis(600));
    if c.unit.has_pins() {
        let changes = pin_changes(&c.pins_since(mark));
        let periods = on_periods(&changes, 5, TactorMask::NONE);
        let [(start, Some(end))] = periods[..] else { return Err(format!("tactor 5 periods {periods:?}")) };
        let ms = (end - start) as f64 / 1000.0;
        ensure!((1390.0..=2000.0).contains(&ms), "tactor 5 ran {ms:.1} ms without a break");
    }
    Ok(())
}

fn stop_all_stops_at_once(c: &mut Ctx) -> Check {
    ack(&c.client.ask(&fire(0x00C0, 2000))?)?;
    c.wait_unit(Duration::from_millis(300));
    let mark = c.mark();
    let on = ack(&c.client.ask(&Request::StopAll)?)?;
    ensure!(on == TactorMask::NONE, "STOP_ALL's ACK says {on:?} on");
    c.wait_unit(Duration::from_millis(50));
    if c.unit.has_pins() {
        let events = c.pins_since(mark);
        // The frame's second delimiter (its end): the first one opens it.
        let rx = events.iter().filter_map(|e| if let SimEvent::Rx(t) = e { Some(*t) } else { None }).nth(1);
        let off = pin_changes(&events).iter().find(|(_, m)| m.is_empty()).map(|(t, _)| *t);
        let (Some(rx), Some(off)) = (rx, off) else { return Err(format!("no rx/off in {events:?}")) };
        let us = off.saturating_sub(rx);
        println!("    {}: STOP_ALL frame end to pins off {us} µs (simulated)", c.unit.name);
        ensure!(us <= 2000, "pins off {us} µs after STOP_ALL arrived");
    }
    Ok(())
}

fn repeats_are_answered_not_rerun(c: &mut Ctx) -> Check {
    let mark = c.mark();
    let seq = c.client.next_seq();
    c.client.codec.set_version(2);
    let frame = c.client.codec.encode_request(seq, &fire(0x0400, 300)).unwrap();
    c.client.send_raw(&frame);
    let first = c.client.read_for(Duration::from_millis(500), |p| p.seq == seq).ok_or("no first answer")?;
    ack(&first)?;
    // The wall clock here: a heartbeat in between would make the repeat a new request.
    c.client.idle(Duration::from_millis(150));
    c.client.send_raw(&frame);
    let again = c.client.read_for(Duration::from_millis(500), |p| p.seq == seq).ok_or("no repeat answer")?;
    ack(&again)?;
    c.wait_unit(Duration::from_millis(400));
    if c.unit.has_pins() {
        let changes = pin_changes(&c.pins_since(mark));
        let periods = on_periods(&changes, 10, TactorMask::NONE);
        let [(start, Some(end))] = periods[..] else { return Err(format!("tactor 10 periods {periods:?}")) };
        let ms = (end - start) as f64 / 1000.0;
        ensure!(ms <= 301.0, "tactor 10 on {ms:.1} ms: the repeated FIRE was run again");
    }
    Ok(())
}

fn garbage_is_dropped_and_the_line_resyncs(c: &mut Ctx) -> Check {
    let answers = c.client.answers.len();
    // Junk without a delimiter, then one: no answer.
    let junk: Vec<u8> = (0..57u32).map(|i| (i * 37 % 255 + 1) as u8).collect();
    c.client.send_raw(&junk);
    c.client.send_raw(&[0]);
    // An overlong run (300 bytes, more than any frame) then a delimiter: no answer.
    c.client.send_raw(&[0x55; 300]);
    c.client.send_raw(&[0]);
    c.client.silent(Duration::from_millis(150));
    ensure!(
        c.client.answers.len() == answers,
        "the unit answered garbage: {:?}",
        &c.client.answers[answers..]
    );
    ack(&c.client.ask(&Request::Heartbeat)?)?;
    // A frame with a bad CRC: NAK 0x01. Unknown type: 0x02. Malformed payload: 0x03. Version: 0x04.
    let cases: [(Vec<u8>, NakReason); 4] = [
        (raw_frame(2, 0x02, 0x61, &[], true), NakReason::BadCrc),
        (raw_frame(2, 0x3F, 0x62, &[], false), NakReason::UnknownCommand),
        (raw_frame(2, 0x03, 0x63, &[1, 0, 100], false), NakReason::Malformed),
        (raw_frame(9, 0x02, 0x64, &[], false), NakReason::UnsupportedVersion),
    ];
    for (frame, want) in cases {
        c.client.send_raw(&frame);
        let r = c
            .client
            .read_for(Duration::from_millis(500), |p| matches!(p.message, Reply::Nak { .. }))
            .ok_or_else(|| format!("no NAK for {want}"))?;
        nak(&r, want)?;
    }
    let Reply::Status(s) = c.client.ask(&Request::GetStatus)?.message else { return Err("no STATUS".into()) };
    ensure!(s.faults.contains(Faults::LINE_ERRORS), "fault 0x08 not raised: {:?}", s.faults);
    let Reply::Status(s) = c.client.ask(&Request::GetStatus)?.message else { return Err("no STATUS".into()) };
    ensure!(!s.faults.contains(Faults::LINE_ERRORS), "STATUS did not clear its faults: {:?}", s.faults);
    Ok(())
}

fn intensity_is_pwm(c: &mut Ctx) -> Check {
    if !c.caps().contains(Capabilities::INTENSITY) {
        return nak(
            &c.client.ask(&Request::SetIntensity { mask: TactorMask(0x0800), level: 128 })?,
            NakReason::NotSupported,
        );
    }
    ack(&c.client.ask(&Request::SetIntensity { mask: TactorMask(0x0800), level: 128 })?)?;
    let mark = c.mark();
    ack(&c.client.ask(&fire(0x0800, 300))?)?;
    c.wait_unit(Duration::from_millis(400));
    let half = c.pins_since(mark);
    ack(&c.client.ask(&Request::SetIntensity { mask: TactorMask(0x0800), level: 255 })?)?;
    let mark = c.mark();
    ack(&c.client.ask(&fire(0x0800, 300))?)?;
    c.wait_unit(Duration::from_millis(400));
    if c.unit.has_pins() {
        let periods = on_periods(&pin_changes(&half), 11, TactorMask::NONE);
        let on_us: u64 = periods.iter().map(|(s, e)| e.unwrap_or(*s) - s).sum();
        let span =
            periods.last().and_then(|p| p.1).unwrap_or(0).saturating_sub(periods.first().map_or(0, |p| p.0));
        let duty = on_us as f64 / span.max(1) as f64;
        println!("    {}: level 128 -> {} pulses, duty {:.0} %", c.unit.name, periods.len(), duty * 100.0);
        ensure!(periods.len() >= 20, "level 128 is not PWM: {} on-periods in 300 ms", periods.len());
        ensure!((0.35..=0.65).contains(&duty), "level 128 gives {:.0} % duty", duty * 100.0);
        let full = on_periods(&pin_changes(&c.pins_since(mark)), 11, TactorMask::NONE);
        ensure!(full.len() == 1, "level 255 is not steadily on: {} on-periods", full.len());
    }
    Ok(())
}

fn heading_stream(c: &mut Ctx) -> Check {
    if !c.caps().contains(Capabilities::HEADING) {
        nak(&c.client.ask(&Request::HeadingStart { rate_hz: 5 })?, NakReason::NotSupported)?;
        return Ok(());
    }
    nak(&c.client.ask(&Request::HeadingStart { rate_hz: 0 })?, NakReason::Malformed)?;
    nak(&c.client.ask(&Request::HeadingStart { rate_hz: 11 })?, NakReason::Malformed)?;
    // Not positive definite (a negative diagonal): refused, the old calibration kept.
    let bad = CalibrationWire {
        hard_iron_dut: [0; 3],
        soft_iron_q12: [-4096, 0, 0, 0, 4096, 0, 0, 0, 4096],
        field_dut: 492,
    };
    nak(&c.client.ask(&Request::SetCalibration(bad))?, NakReason::Malformed)?;
    let zero_field =
        CalibrationWire { soft_iron_q12: [4096, 0, 0, 0, 4096, 0, 0, 0, 4096], field_dut: 0, ..bad };
    nak(&c.client.ask(&Request::SetCalibration(zero_field))?, NakReason::Malformed)?;
    let identity = CalibrationWire { field_dut: 492, ..zero_field };
    ack(&c.client.ask(&Request::SetCalibration(identity))?)?;
    let from = c.client.unsolicited.len();
    ack(&c.client.ask(&Request::HeadingStart { rate_hz: 5 })?)?;
    c.wait_unit(Duration::from_secs(2));
    let readings: Vec<_> = c.client.unsolicited[from..]
        .iter()
        .filter_map(|(_, p)| if let Reply::Heading(h) = p.message { Some(h) } else { None })
        .collect();
    ensure!((9..=11).contains(&readings.len()), "{} readings in 2 s at 5 Hz", readings.len());
    if c.unit.has_pins() {
        // Facing magnetic north, level: heading 0, pitch and roll 0, |h| = the calibrated field.
        let h = readings.last().unwrap();
        let deg = f64::from(h.heading_cdeg) / 100.0;
        ensure!(deg.min(360.0 - deg) <= 1.0, "heading {deg}° facing north");
        ensure!(h.pitch_cdeg.abs() <= 100 && h.roll_cdeg.abs() <= 100, "pitch/roll {h:?} for a level unit");
        ensure!(h.quality_pct >= 90, "quality {} with the field the calibration names", h.quality_pct);
        let raw = h.raw_mag_dut.map(|v| f64::from(v) / 10.0);
        ensure!(
            (raw[0] - FIELD_H).abs() <= 0.3 && raw[1].abs() <= 0.3 && (raw[2] - FIELD_Z).abs() <= 0.3,
            "raw {raw:?} µT"
        );
        // Turn the wearer to face east.
        let sim = c.unit.sim.as_mut().ok_or("no simulation")?;
        sim.set_field_ut(field_for_heading(90.0, FIELD_H, FIELD_Z)).map_err(|e| e.to_string())?;
        let from = c.client.unsolicited.len();
        c.wait_unit(Duration::from_millis(800));
        let east = c.client.unsolicited[from..]
            .iter()
            .rev()
            .find_map(|(_, p)| if let Reply::Heading(h) = p.message { Some(h) } else { None });
        let deg = east.map(|h| f64::from(h.heading_cdeg) / 100.0).ok_or("no reading after the turn")?;
        ensure!((deg - 90.0).abs() <= 1.0, "heading {deg}° facing east");
        let sim = c.unit.sim.as_mut().ok_or("no simulation")?;
        sim.set_field_ut(field_for_heading(0.0, FIELD_H, FIELD_Z)).map_err(|e| e.to_string())?;
    }
    ack(&c.client.ask(&Request::HeadingStop)?)?;
    c.wait_unit(Duration::from_millis(300));
    let from = c.client.unsolicited.len();
    c.wait_unit(Duration::from_millis(700));
    let late =
        c.client.unsolicited[from..].iter().filter(|(_, p)| matches!(p.message, Reply::Heading(_))).count();
    ensure!(late == 0, "{late} readings after HEADING_STOP");
    Ok(())
}

fn gps_forwarding(c: &mut Ctx) -> Check {
    if !c.caps().contains(Capabilities::GPS) {
        return nak(&c.client.ask(&Request::GpsStart { baud: 9600 })?, NakReason::NotSupported);
    }
    nak(&c.client.ask(&Request::GpsStart { baud: 1234 })?, NakReason::Malformed)?;
    let from = c.client.unsolicited.len();
    ack(&c.client.ask(&Request::GpsStart { baud: 9600 })?)?;
    c.wait_unit(Duration::from_secs(2));
    ack(&c.client.ask(&Request::GpsStop)?)?;
    c.wait_unit(Duration::from_millis(200));
    let chunks: Vec<(u16, Vec<u8>)> = c.client.unsolicited[from..]
        .iter()
        .filter_map(|(_, p)| match &p.message {
            Reply::GpsData { lost, data } => Some((*lost, data.clone())),
            _ => None,
        })
        .collect();
    let bytes: Vec<u8> = chunks.iter().flat_map(|(_, d)| d.clone()).collect();
    let lost: u32 = chunks.iter().map(|(l, _)| u32::from(*l)).sum();
    println!(
        "    {}: {} GPS bytes in {} chunks over ~2 s, {lost} lost",
        c.unit.name,
        bytes.len(),
        chunks.len()
    );
    ensure!(lost == 0, "{lost} receiver bytes lost");
    // 9600 baud, 10 bits a byte: 960 bytes a second.
    ensure!((1600..=2200).contains(&bytes.len()), "{} bytes in about 2 s at 9600 baud", bytes.len());
    // A chunk ends at a line feed, at 64 bytes, or 50 ms (48 bytes at 9600 baud) after its first byte.
    ensure!(chunks.iter().all(|(_, d)| d.len() <= 64), "a chunk longer than 64 bytes");
    let inner_lf = chunks.iter().filter(|(_, d)| d[..d.len() - 1].contains(&b'\n')).count();
    ensure!(inner_lf == 0, "{inner_lf} chunks run on past a line feed");
    // In order and complete: a contiguous stretch of the looped log.
    let log = std::fs::read(Path::new(ROOT).join(GPS_LOG)).unwrap();
    let looped = [log.as_slice(), log.as_slice()].concat();
    let probe = &bytes[..bytes.len().min(log.len())];
    if !looped.windows(probe.len()).any(|w| w == probe) {
        // Where the stream stops being the log: the longest prefix found in it.
        let good =
            (1..=probe.len()).rev().find(|&n| looped.windows(n).any(|w| w == &probe[..n])).unwrap_or(0);
        let around = String::from_utf8_lossy(&probe[good.saturating_sub(40)..(good + 40).min(probe.len())])
            .into_owned();
        return Err(format!(
            "the forwarded bytes leave the receiver's stream after {good} of {} bytes: {around:?}",
            probe.len()
        ));
    }
    let from = c.client.unsolicited.len();
    c.wait_unit(Duration::from_millis(500));
    let late = c.client.unsolicited[from..]
        .iter()
        .filter(|(_, p)| matches!(p.message, Reply::GpsData { .. }))
        .count();
    ensure!(late == 0, "{late} GPS chunks after GPS_STOP");
    Ok(())
}

fn watchdog_stops_everything(c: &mut Ctx) -> Check {
    // Tactors 8 and 9 alternate every 400 ms for 8 s; then the console goes quiet.
    let frames = vec![
        Frame { mask: TactorMask(0x0100), duration_ms: 400 },
        Frame { mask: TactorMask(0x0200), duration_ms: 400 },
    ];
    let mark = c.mark();
    ack(&c.client.ask(&Request::Play { frames, repeats: 10 })?)?;
    let quiet_from = Instant::now();
    // The watchdog acts on the unit's clock: allow for a simulation running behind a loaded machine.
    c.client.silent(Duration::from_millis(if c.unit.has_pins() { 3000 } else { 2000 }));
    let report = c.client.unsolicited.iter().find_map(|(t, p)| match p.message {
        Reply::Report { tactors_on, faults } if *t >= quiet_from && faults.contains(Faults::WATCHDOG) => {
            Some((*t - quiet_from, tactors_on))
        }
        _ => None,
    });
    let Some((after, on)) = report else { return Err("no REPORT with the watchdog fault".into()) };
    ensure!(on == TactorMask::NONE, "watchdog REPORT says {on:?} on");
    ensure!(
        after >= Duration::from_millis(1400) && (c.unit.has_pins() || after <= Duration::from_millis(1700)),
        "watchdog after {after:?}"
    );
    if c.unit.has_pins() {
        let events = c.pins_since(mark);
        let rx =
            events.iter().filter_map(|e| if let SimEvent::Rx(t) = e { Some(*t) } else { None }).next_back();
        let changes = pin_changes(&events);
        let off = changes.iter().rev().find(|(_, m)| m.is_empty()).map(|(t, _)| *t);
        let (Some(rx), Some(off)) = (rx, off) else { return Err(format!("no rx/off in {events:?}")) };
        let ms = (off - rx) as f64 / 1000.0;
        println!("    {}: last frame to all-off by the watchdog {ms:.2} ms (simulated)", c.unit.name);
        ensure!(
            (1499.0..=1502.0).contains(&ms),
            "the watchdog stopped the pins {ms:.2} ms after the last frame"
        );
    }
    let Reply::Status(s) = c.client.ask(&Request::GetStatus)?.message else { return Err("no STATUS".into()) };
    ensure!(s.faults.contains(Faults::WATCHDOG), "fault 0x01 not in STATUS: {:?}", s.faults);
    Ok(())
}

fn duty_cycle_is_enforced(c: &mut Ctx) -> Check {
    // 2 s on, a break, 2 s on, a break: 4 s of the 5 s per 10 s spent; another 2 s is too much.
    for _ in 0..2 {
        ack(&c.client.ask(&fire(0x2000, 2000))?)?;
        c.wait_unit(Duration::from_millis(2100));
    }
    nak(&c.client.ask(&fire(0x2000, 2000))?, NakReason::DutyCycle)?;
    // 900 ms still fits (4000 + 900 <= 5000).
    ack(&c.client.ask(&fire(0x2000, 900))?)?;
    c.wait_unit(Duration::from_secs(1));
    Ok(())
}

/// FIRE to ACK round trips at 115200 baud, as the console's link sees them (wall clock, PTY included).
fn fire_ack_latency(c: &mut Ctx) -> Check {
    let mut rtts = Vec::new();
    for i in 0..40u16 {
        // 20 ms on one of four tactors in turn: far inside every limit.
        let mask = 1u16 << (i % 4);
        let start = Instant::now();
        ack(&c.client.ask(&fire(mask, 20))?)?;
        rtts.push(start.elapsed().as_secs_f64() * 1000.0);
        c.client.idle(Duration::from_millis(30));
    }
    rtts.sort_by(f64::total_cmp);
    let (p50, p99) = (rtts[rtts.len() / 2], rtts[rtts.len() * 99 / 100]);
    println!(
        "    {}: FIRE -> ACK p50 {p50:.2} ms, p99 {p99:.2} ms, max {:.2} ms (40 round trips)",
        c.unit.name,
        rtts[rtts.len() - 1]
    );
    // A FIRE frame is 13 bytes and its ACK 10 at 86.8 µs a byte: 2 ms on the wire, plus the unit's turn.
    // A measurement, not a speed test: the bound only says the unit answers promptly at all (a loaded
    // machine slows the simulation; the figures above are what to read).
    ensure!(p99 < 250.0, "FIRE -> ACK p99 {p99:.2} ms");
    Ok(())
}

/// The console's own vest worker (`VestHandle`, the code behind the Vest panel) drives the unit: it
/// connects, fires, and on stop sends STOP ALL, which leaves every pin off.
fn console_worker_drives_the_unit(unit: &mut Unit) -> Check {
    use vestnav_device::wtcu::VestHandle;
    use vestnav_device::wtcu::link::LinkState;
    use vestnav_device::wtcu::worker::{
        CommandOrigin, Connector, Transport, VestCommand, VestEvent, WorkerSettings,
    };
    let path = unit.path.clone();
    let connector: Connector = Box::new(move || {
        let port = vestnav_device::serial::open(&path, 115_200, Duration::from_millis(2))
            .map_err(std::io::Error::other)?;
        Ok(Box::new(port) as Box<dyn Transport>)
    });
    unit.collect();
    let mark = unit.pins.len();
    let (handle, rx) =
        VestHandle::spawn_with_receiver(connector, WorkerSettings::default()).map_err(|e| e.to_string())?;
    let wait = |pred: &dyn Fn(&VestEvent) -> bool| -> Result<(), String> {
        let end = Instant::now() + Duration::from_secs(5);
        while Instant::now() < end {
            if let Ok(e) = rx.recv_timeout(Duration::from_millis(20))
                && pred(&e)
            {
                return Ok(());
            }
        }
        Err("timed out".to_owned())
    };
    wait(&|e| matches!(e, VestEvent::State(LinkState::Ready))).map_err(|e| format!("never ready: {e}"))?;
    handle
        .send(VestCommand::Fire { mask: TactorMask(0x0660), duration_ms: 1500 }, CommandOrigin::Manual)
        .map_err(|e| e.to_string())?;
    wait(&|e| matches!(e, VestEvent::TactorsOn(Some(m)) if *m == TactorMask(0x0660)))
        .map_err(|e| format!("the fire was not reported on: {e}"))?;
    std::thread::sleep(Duration::from_millis(200));
    let stop_at = Instant::now();
    ensure!(handle.stop(), "the worker's STOP ALL was not acknowledged");
    let stopped_in = stop_at.elapsed();
    std::thread::sleep(Duration::from_millis(50));
    if unit.has_pins() {
        let changes = {
            unit.collect();
            pin_changes(&unit.pins[mark..])
        };
        let on = changes.iter().find(|(_, m)| *m == TactorMask(0x0660)).map(|(t, _)| *t);
        let off = changes.iter().rev().find(|(_, m)| m.is_empty()).map(|(t, _)| *t);
        let (Some(on), Some(off)) = (on, off) else { return Err(format!("pins {changes:?}")) };
        let ms = (off - on) as f64 / 1000.0;
        ensure!(ms < 1000.0, "the pins stayed on {ms:.0} ms of a 1500 ms fire stopped after 200 ms");
        ensure!(changes.last().is_some_and(|(_, m)| m.is_empty()), "pins {changes:?} after stop");
    }
    println!(
        "    {}: console worker stop (STOP ALL acknowledged) in {:.1} ms",
        unit.name,
        stopped_in.as_secs_f64() * 1000.0
    );
    Ok(())
}

/// Over everything the pins did in the whole run: never more than 8 tactors on, and no tactor on without
/// a break for longer than `max_on_ms`.
fn pin_invariants(unit: &mut Unit) -> Check {
    unit.collect();
    let changes = pin_changes(&unit.pins);
    let most = changes.iter().map(|(_, m)| m.count()).max().unwrap_or(0);
    ensure!(most <= 8, "{most} tactors on at once");
    for t in 0..16 {
        for (start, end) in on_periods(&changes, t, TactorMask::NONE) {
            let ms = (end.unwrap_or(start) - start) as f64 / 1000.0;
            ensure!(ms <= 2000.0, "tactor {t} on for {ms:.1} ms without a break");
        }
    }
    let resets = unit.pins.iter().filter(|e| matches!(e, SimEvent::Reset(_))).count();
    ensure!(resets == 0, "{resets} watchdog resets of the MCU");
    println!("    {}: {} pin changes, at most {most} tactors on at once", unit.name, changes.len());
    Ok(())
}

type CheckFn = fn(&mut Ctx) -> Check;

const CHECKS: [(&str, CheckFn); 16] = [
    ("before hello: NAK 0x0A", before_hello),
    ("handshake: IDENTIFY v2, 16 tactors, default limits", handshake),
    ("v1 session: v1 headers, no v2 types", v1_session),
    ("heartbeat and status", heartbeat_and_status),
    ("FIRE runs for its duration", fire_runs_for_its_duration),
    ("PLAY steps on the unit's clock", play_steps_on_the_units_clock),
    ("PLAY under a frame flood: no step glitches", play_under_a_frame_flood),
    ("limits: NAK 0x05/0x06/0x08, no effect", limits_are_refused_without_effect),
    ("a run cannot be chained past 2 s", a_run_cannot_be_chained_past_the_limit),
    ("STOP_ALL stops at once", stop_all_stops_at_once),
    ("repeated requests are answered, not rerun", repeats_are_answered_not_rerun),
    ("garbage, resync, NAK 0x01..0x04", garbage_is_dropped_and_the_line_resyncs),
    ("intensity is PWM, 255 is steady", intensity_is_pwm),
    ("heading stream (or NAK 0x09)", heading_stream),
    ("GPS forwarding (or NAK 0x09)", gps_forwarding),
    ("watchdog stops everything", watchdog_stops_everything),
];

fn run_unit(mut unit: Unit, passed: &mut usize, failed: &mut Vec<String>) {
    println!("{} on {}", unit.name, unit.path);
    let client = Client::open(&unit.path);
    let name = unit.name;
    let mut ctx = Ctx { unit: &mut unit, client, info: None };
    let mut record = |check: &str, result: Check| match result {
        Ok(()) => {
            *passed += 1;
            println!("  ok    {check}");
        }
        Err(e) => {
            println!("  FAIL  {check}: {e}");
            failed.push(format!("{name}: {check}: {e}"));
        }
    };
    for (check, f) in CHECKS {
        if check.starts_with("handshake") || check.starts_with("before") {
            record(check, f(&mut ctx));
            continue;
        }
        // Every later check starts a fresh session (HELLO stops everything, ends the streams).
        let result = ctx.client.hello().and_then(|_| f(&mut ctx));
        record(check, result);
    }
    let result = ctx.client.hello().and_then(|_| duty_cycle_is_enforced(&mut ctx));
    record("duty cycle: NAK 0x07", result);
    let result = ctx.client.hello().and_then(|_| fire_ack_latency(&mut ctx));
    record("FIRE -> ACK latency", result);
    // The console's worker takes over the line (its HELLO starts a new session); ours is closed first
    // (a serial port is opened for exclusive use).
    let Ctx { unit, client, .. } = ctx;
    drop(client);
    record("the console's vest worker drives the unit", console_worker_drives_the_unit(unit));
    if unit.has_pins() {
        record("pins: <= 8 on, no run > 2 s, no MCU reset", pin_invariants(unit));
    }
}

/// `vestnav emulate vest --firmware`: the command a user runs prints the pseudo-terminal of the simulated
/// board, which answers a HELLO; when the command ends, the simulation ends with it.
fn cli_runs_the_firmware(elf: &Path) -> Check {
    use std::io::BufRead as _;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["emulate", "vest", "--firmware"])
        .arg(elf)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let stdout = child.stdout.take().ok_or("no stdout")?;
    let mut lines = std::io::BufReader::new(stdout).lines();
    let first = lines.next().and_then(Result::ok).unwrap_or_default();
    let path = first.rsplit(" on ").next().unwrap_or_default().trim().to_owned();
    let result = (|| {
        ensure!(first.starts_with("WTCU firmware") && path.starts_with("/dev/"), "first line {first:?}");
        let mut client = Client::open(&path);
        let info = client.hello()?;
        ensure!(info.tactor_count == 16, "IDENTIFY {info:?}");
        Ok(())
    })();
    let _ = child.kill();
    let _ = child.wait();
    result?;
    // The harness reads its stdin from the command: it ends, and its pseudo-terminal goes with it.
    let end = Instant::now() + Duration::from_secs(3);
    while Path::new(&path).exists() && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    ensure!(!Path::new(&path).exists(), "{path} still exists after the command ended");
    Ok(())
}

fn firmware_path(name: &str) -> PathBuf {
    Path::new(ROOT).join("firmware/build").join(name)
}

fn main() {
    if std::env::var_os("VESTNAV_HIL_SKIP").is_some() {
        println!("conformance suite skipped (VESTNAV_HIL_SKIP: scripts/hil.sh has run it)");
        return;
    }
    let filter: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let wanted = |name: &str| filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()));
    let require = std::env::var_os("VESTNAV_HIL_REQUIRE_FIRMWARE").is_some();
    let (mut passed, mut failed) = (0usize, Vec::new());
    if wanted("emulator") {
        run_unit(Unit::emulator(), &mut passed, &mut failed);
    }
    for (name, elf) in [("firmware-mega", "wtcu-mega.elf"), ("firmware-nano", "wtcu-nano.elf")] {
        if !wanted(name) {
            continue;
        }
        let elf = firmware_path(elf);
        if !elf.is_file() || !firmware_path("wtcu-sim").is_file() {
            let msg =
                format!("{name}: {} or the harness not built (scripts/hil.sh builds them)", elf.display());
            if require {
                failed.push(msg);
            } else {
                println!("skipped {msg}");
            }
            continue;
        }
        match Unit::firmware(name, &elf) {
            Ok(unit) => run_unit(unit, &mut passed, &mut failed),
            Err(e) => failed.push(format!("{name}: {e}")),
        }
        let check = "`vestnav emulate vest --firmware` serves it and ends with it";
        match cli_runs_the_firmware(&elf) {
            Ok(()) => {
                passed += 1;
                println!("  ok    {check}");
            }
            Err(e) => {
                println!("  FAIL  {check}: {e}");
                failed.push(format!("{name}: {check}: {e}"));
            }
        }
    }
    println!("{passed} passed, {} failed", failed.len());
    for f in &failed {
        println!("  failed: {f}");
    }
    if !failed.is_empty() {
        std::process::exit(1);
    }
}
