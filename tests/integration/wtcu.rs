//! Integration tests of the WTCU protocol: test vectors of `docs/wtcu-protocol.md` and end-to-end tests
//! over real pseudo-terminals (worker <-> emulator). The simulated-clock pair tests of the console link
//! against the device engine are in `wtcu_pair.rs`; the property tests (proptest) live next to the codec,
//! in `crates/device/src/wtcu/proptests.rs`.

// Helpers here are test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_core::vest::{Cue, DEFAULT_ON_MS, Frame, TactorMask};
use vestnav_device::outbox::{Outbox, Overflow};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec, hex};
use vestnav_device::wtcu::emulator::PtyEmulator;
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::engine::EngineConfig;
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::link::LinkState;
use vestnav_device::wtcu::message::{
    Capabilities, CommandKind, DeviceInfo, Faults, FirmwareVersion, NakReason, Packet, Reply, Request,
    UnitStatus,
};
use vestnav_device::wtcu::worker::{
    CommandOrigin, Connector, Transport, VestCommand, VestConfig, VestEvent, VestHandle, VestSendError,
    WorkerSettings,
};

// ---------------------------------------------------------------------------------------------------------
// Test vectors. The hex strings were produced by an independent Python implementation of the framing
// (bitwise CRC-16/CCITT-FALSE, hand-written COBS) and are the ones printed in docs/wtcu-protocol.md.

const DOC: &str = include_str!("../../docs/wtcu-protocol.md");

fn unhex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

fn request_vectors() -> Vec<(u8, Request, &'static str)> {
    let col = TactorMask::column;
    vec![
        (0, Request::Hello, "00 03 01 01 01 03 44 c5 00"),
        (1, Request::Heartbeat, "00 04 01 02 01 03 25 af 00"),
        (
            2,
            Request::Fire { mask: TactorMask::CORNERS, duration_ms: 500 },
            "00 0b 01 03 02 04 09 90 f4 01 43 e8 00",
        ),
        (
            3,
            Request::Play {
                frames: [3, 2, 1, 0].iter().map(|&c| Frame { mask: col(c), duration_ms: 250 }).collect(),
                repeats: 1,
            },
            "00 0a 01 04 03 12 01 04 88 88 fa 04 44 44 fa 04 22 22 fa 04 11 11 fa 03 57 d6 00",
        ),
        (
            4,
            Request::SetIntensity { mask: TactorMask::ALL, level: 128 },
            "00 0a 01 05 04 03 ff ff 80 60 45 00",
        ),
        (5, Request::StopAll, "00 04 01 06 05 03 21 bf 00"),
        (6, Request::GetStatus, "00 04 01 07 06 03 42 dd 00"),
    ]
}

fn reply_vectors() -> Vec<(u8, Reply, &'static str)> {
    let fw = FirmwareVersion { major: 1, minor: 0, patch: 0 };
    let info = DeviceInfo {
        protocol_version: 1,
        firmware: fw,
        tactor_count: 16,
        capabilities: Capabilities::INTENSITY | Capabilities::PATTERNS,
        limits: Limits::default(),
        watchdog_ms: 1500,
    };
    vec![
        (
            0,
            Reply::Identify(info),
            "00 03 01 81 03 11 01 01 11 10 03 d0 07 08 10 27 88 13 20 10 27 dc 05 4a 96 00",
        ),
        (2, Reply::Ack { tactors_on: TactorMask::CORNERS }, "00 09 01 82 02 02 09 90 ca 97 00"),
        (
            7,
            Reply::Nak { reason: NakReason::TooManyTactors, tactors_on: TactorMask::NONE },
            "00 06 01 83 07 03 06 01 03 c7 1d 00",
        ),
        (
            6,
            Reply::Status(UnitStatus {
                battery_mv: 3900,
                battery_pct: 67,
                tactors_on: TactorMask::NONE,
                faults: Faults::default(),
                firmware: fw,
            }),
            "00 08 01 84 06 09 3c 0f 43 01 01 02 01 01 03 6e b4 00",
        ),
        (
            1,
            Reply::Report { tactors_on: TactorMask::NONE, faults: Faults::WATCHDOG },
            "00 05 01 85 01 03 01 04 01 22 ff 00",
        ),
    ]
}

#[test]
fn request_vectors_match_the_document_both_ways() {
    let mut codec = FrameCodec::with_max_version(1);
    for (seq, request, want) in request_vectors() {
        assert!(DOC.contains(want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_request(seq, &request).unwrap()), want, "{request:?}");
        let mut out = Vec::new();
        codec.decode_requests(&unhex(want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: request })]);
    }
}

#[test]
fn reply_vectors_match_the_document_both_ways() {
    let mut codec = FrameCodec::with_max_version(1);
    for (seq, reply, want) in reply_vectors() {
        assert!(DOC.contains(want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_reply(seq, &reply)), want, "{reply:?}");
        let mut out = Vec::new();
        codec.decode_replies(&unhex(want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 1, seq, message: reply })]);
    }
}

#[test]
fn the_emulator_identifies_itself_as_the_vector_says() {
    let now = Instant::now();
    let mut engine = UnitConfig::default().build();
    engine.handle_bytes(&unhex("00 03 01 01 01 03 44 c5 00"), now);
    let identify = reply_vectors()[0].2;
    assert_eq!(hex(&engine.poll_transmit().unwrap()), identify);
    engine.handle_bytes(&unhex("00 04 01 07 06 03 42 dd 00"), now);
    assert_eq!(hex(&engine.poll_transmit().unwrap()), reply_vectors()[3].2);
}

// ---------------------------------------------------------------------------------------------------------
// Over real pseudo-terminals.

fn fast_settings() -> WorkerSettings {
    WorkerSettings {
        backoff: vestnav_device::wtcu::link::Backoff::new(
            Duration::from_millis(50),
            Duration::from_millis(400),
        ),
        ..WorkerSettings::default()
    }
}

pub(super) fn pty_connector(path: Arc<Mutex<String>>) -> Connector {
    Box::new(move || {
        let p = path.lock().unwrap().clone();
        // The worker's poll interval bounds how late it picks up a command.
        let poll = WorkerSettings::default().io_poll;
        let port = vestnav_device::serial::open(&p, 115_200, poll).map_err(std::io::Error::other)?;
        Ok(Box::new(port) as Box<dyn Transport>)
    })
}

/// A worker with one receiver of its events, sending as the operator.
pub(super) struct Vest {
    handle: VestHandle,
    rx: std::sync::mpsc::Receiver<VestEvent>,
}

impl Vest {
    pub(super) fn spawn(connector: Connector, settings: WorkerSettings) -> Self {
        let (handle, rx) = VestHandle::spawn_with_receiver(connector, settings).unwrap();
        Self { handle, rx }
    }

    pub(super) fn send(&self, command: VestCommand) -> Result<(), VestSendError> {
        self.handle.send(command, CommandOrigin::Manual)
    }

    fn recv_timeout(&self, timeout: Duration) -> Option<VestEvent> {
        self.rx.recv_timeout(timeout).ok()
    }

    pub(super) fn stop(self) -> bool {
        self.handle.stop()
    }
}

/// Collects events until `pred` holds for one of them (returns it) or `timeout` passes (panics).
pub(super) fn wait_for(
    vest: &Vest,
    seen: &mut Vec<VestEvent>,
    timeout: Duration,
    pred: impl Fn(&VestEvent) -> bool,
) -> VestEvent {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if let Some(e) = vest.recv_timeout(Duration::from_millis(20)) {
            seen.push(e.clone());
            if pred(&e) {
                return e;
            }
        }
    }
    panic!("timed out; events: {seen:#?}");
}

fn wait_until(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    cond()
}

#[test]
fn pty_fire_pattern_stop_round_trips() {
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let path = Arc::new(Mutex::new(emu.path().to_owned()));
    let wakes = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let w = wakes.clone();
    let waker: vestnav_device::outbox::Waker = Arc::new(move || {
        w.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    });
    let (out, rx) = Outbox::channel(1024, Overflow::DropNewest, Some(waker));
    let handle = VestHandle::spawn_with(pty_connector(path), fast_settings(), vec![out]).unwrap();
    let vest = Vest { handle, rx };
    let mut seen = Vec::new();
    let s = Duration::from_secs(3);
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    assert!(seen.iter().any(|e| matches!(e, VestEvent::Identified(d) if d.tactor_count == 16)));

    vest.send(VestCommand::Fire { mask: TactorMask::CORNERS, duration_ms: 300 }).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { kind: CommandKind::Fire, .. }));
    assert!(wait_until(s, || emu.view().changes.iter().any(|(_, m)| *m == TactorMask::CORNERS)));
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::NONE)));

    // 500 ms a column: the STOP ALL below has that long to cut the pattern before column 0.
    vest.send(VestCommand::Play(Cue::TurnLeft.pattern(2 * DEFAULT_ON_MS))).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { kind: CommandKind::Play, .. }));
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::column(1))));
    vest.send(VestCommand::StopAll).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { kind: CommandKind::StopAll, .. }));
    assert!(wait_until(s, || emu.view().tactors_on.is_empty()));
    // The pattern was cut short: column 0 never came on.
    assert!(!emu.view().changes.iter().any(|(_, m)| *m == TactorMask::column(0)));

    vest.send(VestCommand::Fire { mask: TactorMask(0x01FF), duration_ms: 100 }).unwrap();
    let e = wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Rejected { .. }));
    assert!(
        matches!(e, VestEvent::Rejected { kind: CommandKind::Fire, reason, .. } if reason.contains("current budget"))
    );
    vest.send(VestCommand::RequestStatus).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Status(st) if st.battery_mv == 3900));
    assert!(wakes.load(std::sync::atomic::Ordering::Relaxed) > 0);

    // Dropping the handle sends STOP ALL first.
    vest.send(VestCommand::Fire { mask: TactorMask(1), duration_ms: 2000 }).unwrap();
    assert!(wait_until(s, || emu.view().tactors_on == TactorMask(1)));
    let before = emu.view().stats.frames_ok;
    drop(vest);
    assert!(emu.view().tactors_on.is_empty());
    assert!(emu.view().stats.frames_ok > before);
    assert_eq!(emu.view().stats.watchdog_trips, 0);
}

#[test]
fn pty_port_vanishing_mid_frame_then_returning() {
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let path = Arc::new(Mutex::new(emu.path().to_owned()));
    let vest = Vest::spawn(pty_connector(path.clone()), fast_settings());
    let mut seen = Vec::new();
    let s = Duration::from_secs(3);
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    emu.vanish_mid_frame().unwrap();
    // The kernel may hand the freed /dev/pts number to another test's PTY at once; a vanished Bluetooth
    // port has no node at all, so the connector is pointed at one that cannot exist.
    *path.lock().unwrap() = "/dev/pts/vestnav-port-gone".to_owned();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Lost { .. })));
    // Reconnect attempts are visible while the port is gone.
    wait_for(
        &vest,
        &mut seen,
        s,
        |e| matches!(e, VestEvent::State(LinkState::Connecting { attempt }) if *attempt >= 2),
    );
    assert!(seen.iter().any(|e| matches!(e, VestEvent::Transport(_))));
    // The unit comes back (on a new PTY path, as a re-paired Bluetooth port may).
    let emu2 = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    *path.lock().unwrap() = emu2.path().to_owned();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    vest.send(VestCommand::Fire { mask: TactorMask(0b1010), duration_ms: 200 }).unwrap();
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask(0b1010))));
    assert_eq!(emu2.view().stats.garbage, 0);
}

#[test]
fn pty_link_loss_leaves_every_tactor_off_within_the_watchdog_bound() {
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let path = Arc::new(Mutex::new(emu.path().to_owned()));
    let vest = Vest::spawn(pty_connector(path), fast_settings());
    let mut seen = Vec::new();
    let s = Duration::from_secs(3);
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    let long = vestnav_core::vest::Pattern {
        name: "long".into(),
        frames: vec![
            Frame { mask: TactorMask(0x0003), duration_ms: 400 },
            Frame { mask: TactorMask(0x0300), duration_ms: 400 },
        ],
        repeats: 10,
    };
    vest.send(VestCommand::Play(long)).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { kind: CommandKind::Play, .. }));
    // Out of Bluetooth range: nothing gets through either way.
    emu.set_out_of_range(true);
    let cut = Instant::now();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Lost { .. })));
    assert!(wait_until(Duration::from_secs(3), || emu.view().stats.watchdog_trips == 1));
    let view = emu.view();
    assert!(view.tactors_on.is_empty());
    let last_rx = view.last_rx.unwrap();
    let (off_at, off) = *view.changes.back().unwrap();
    assert!(off.is_empty());
    let bound = Duration::from_millis(1500);
    let after = off_at.duration_since(last_rx);
    println!("watchdog: everything off {} ms after the last frame (bound 1500 ms)", after.as_millis());
    // The unit polls every 5 ms; the slack only absorbs thread scheduling on a loaded 2-core CI machine.
    let slack = Duration::from_millis(300);
    assert!(after >= bound && after < bound + slack, "{after:?}");
    assert!(off_at.duration_since(cut) < bound + slack);
    assert!(off_at.duration_since(cut) < Duration::from_secs(8), "the 8 s pattern was cut short");
    drop(vest);
}

#[test]
fn pty_emulator_drops_garbage_and_naks_out_of_bound_commands() {
    use std::io::{Read, Write};
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let mut port = vestnav_device::serial::open(emu.path(), 115_200, Duration::from_millis(50)).unwrap();
    let codec = FrameCodec::with_max_version(1);
    let mut replies = FrameCodec::new();
    let mut read_replies = |port: &mut dyn Read, want: usize| {
        let mut got = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(2);
        let mut buf = [0u8; 256];
        while got.len() < want && Instant::now() < deadline {
            if let Ok(n) = port.read(&mut buf) {
                replies.decode_replies(&buf[..n], &mut got);
            }
        }
        got
    };
    // Line noise, a truncated frame, an overlong run, then HELLO.
    let fire = codec.encode_request(1, &Request::Fire { mask: TactorMask(1), duration_ms: 100 }).unwrap();
    let mut junk = b"\x1b[2J$GPGGA,garbage*00\r\n".to_vec();
    junk.extend_from_slice(&fire[..fire.len() / 2]);
    junk.extend(std::iter::repeat_n(0x55u8, 400));
    port.write_all(&junk).unwrap();
    port.write_all(&codec.encode_request(0, &Request::Hello).unwrap()).unwrap();
    let got = read_replies(&mut *port, 1);
    assert!(matches!(got.last(), Some(Ok(Packet { seq: 0, message: Reply::Identify(_), .. }))), "{got:?}");
    assert!(wait_until(Duration::from_secs(1), || emu.view().stats.garbage >= 2), "{:?}", emu.view().stats);
    // Out of bounds: 9 tactors, 2.5 s.
    let nine =
        codec.encode_request(2, &Request::Fire { mask: TactorMask(0x01FF), duration_ms: 100 }).unwrap();
    let long = codec.encode_request(3, &Request::Fire { mask: TactorMask(1), duration_ms: 2500 }).unwrap();
    port.write_all(&nine).unwrap();
    port.write_all(&long).unwrap();
    let got = read_replies(&mut *port, 2);
    let naks: Vec<_> = got
        .into_iter()
        .filter_map(|r| match r {
            Ok(Packet { seq, message: Reply::Nak { reason, .. }, .. }) => Some((seq, reason)),
            _ => None,
        })
        .collect();
    assert_eq!(naks, vec![(2, NakReason::TooManyTactors), (3, NakReason::DurationLimit)]);
    assert!(emu.view().tactors_on.is_empty());
}

/// Writes `n` `GET_STATUS` requests (after a HELLO) to `port` and never reads: the replies pile up unread.
fn flood_without_reading(port: &mut dyn serialport::SerialPort, n: usize) {
    let codec = FrameCodec::with_max_version(1);
    let mut bytes = codec.encode_request(0, &Request::Hello).unwrap();
    for i in 0..n {
        bytes.extend(codec.encode_request((i % 200) as u8 + 1, &Request::GetStatus).unwrap());
    }
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut rest = &bytes[..];
    while !rest.is_empty() {
        assert!(Instant::now() < deadline, "the emulator stopped reading");
        // A full line only times out: the emulator reads on, so retry.
        if let Ok(n) = std::io::Write::write(port, rest) {
            rest = &rest[n..];
        }
    }
}

/// Reads and throws away everything waiting, then sends a HEARTBEAT with seq 0xAB and waits for its ACK.
fn drain_then_heartbeat_is_answered(port: &mut dyn serialport::SerialPort) -> usize {
    let mut stale = 0;
    let mut buf = [0u8; 4096];
    let mut quiet_since = Instant::now();
    while quiet_since.elapsed() < Duration::from_millis(200) {
        match std::io::Read::read(port, &mut buf) {
            Ok(n) if n > 0 => {
                stale += n;
                quiet_since = Instant::now();
            }
            _ => {}
        }
    }
    std::io::Write::write_all(
        port,
        &FrameCodec::with_max_version(1).encode_request(0xAB, &Request::Heartbeat).unwrap(),
    )
    .unwrap();
    let mut replies = FrameCodec::new();
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(2);
    while Instant::now() < deadline {
        if let Ok(n) = std::io::Read::read(port, &mut buf) {
            replies.decode_replies(&buf[..n], &mut got);
        }
        if got.iter().any(|r| matches!(r, Ok(Packet { seq: 0xAB, message: Reply::Ack { .. }, .. }))) {
            return stale;
        }
    }
    panic!("no answer to the heartbeat after the flood: {got:?}");
}

#[test]
fn pty_emulator_drops_replies_nobody_reads_and_answers_afterwards() {
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let mut port = vestnav_device::serial::open(emu.path(), 115_200, Duration::from_millis(50)).unwrap();
    // About 110 KB of STATUS replies, more than a PTY holds (the issue: the emulator died at ~20 KB).
    let t = Instant::now();
    flood_without_reading(&mut *port, 6000);
    assert!(
        wait_until(Duration::from_secs(5), || emu.view().stats.frames_ok >= 6001),
        "{:?}",
        emu.view().stats
    );
    // Nobody reads for a while longer.
    std::thread::sleep(Duration::from_millis(300));
    assert!(emu.is_running());
    let dropped = emu.replies_dropped();
    assert!(dropped > 0);
    let stale = drain_then_heartbeat_is_answered(&mut *port);
    println!(
        "flood of 6000 requests unread for {} ms: {dropped} replies dropped, {stale} bytes were waiting; answered afterwards",
        t.elapsed().as_millis()
    );
    assert!(emu.is_running());
}

#[test]
fn the_emulator_program_drops_replies_nobody_reads_and_says_so() {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["emulate", "vest", "--pty"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let path = first.strip_prefix("WTCU emulator on ").unwrap().to_owned();
    let drain = std::thread::spawn(move || lines.map_while(Result::ok).count());
    let errors = Arc::new(Mutex::new(Vec::new()));
    let e = errors.clone();
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let drain_err = std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            e.lock().unwrap().push(line);
        }
    });
    let mut port = vestnav_device::serial::open(&path, 115_200, Duration::from_millis(50)).unwrap();
    flood_without_reading(&mut *port, 6000);
    // The report comes at most once a second.
    let said = wait_until(Duration::from_secs(4), || {
        errors.lock().unwrap().iter().any(|l| l.contains("replies dropped"))
    });
    assert!(said, "{:?}", errors.lock().unwrap());
    assert!(child.try_wait().unwrap().is_none(), "the emulator exited");
    drain_then_heartbeat_is_answered(&mut *port);
    let lines_about_drops = errors.lock().unwrap().iter().filter(|l| l.contains("replies dropped")).count();
    assert!(lines_about_drops <= 6, "{:?}", errors.lock().unwrap());
    child.kill().unwrap();
    child.wait().unwrap();
    drain.join().unwrap();
    drain_err.join().unwrap();
}

// ---------------------------------------------------------------------------------------------------------
// Measurements (printed, no timing assertion).

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

#[test]
fn measure_codec_cost_and_pty_round_trip() {
    use std::io::{Read, Write};
    let mut codec = FrameCodec::with_max_version(1);
    let fire = Request::Fire { mask: TactorMask::CORNERS, duration_ms: 500 };
    let play = Request::Play { frames: Cue::TurnAround.pattern(DEFAULT_ON_MS).frames, repeats: 2 };
    let n = 20_000u32;
    for (name, req) in [("fire", &fire), ("play (5 frames)", &play)] {
        let t = Instant::now();
        let mut bytes = Vec::new();
        for i in 0..n {
            bytes = codec.encode_request(i as u8, req).unwrap();
        }
        let enc = t.elapsed() / n;
        let t = Instant::now();
        let mut out = Vec::with_capacity(1);
        for _ in 0..n {
            out.clear();
            codec.decode_requests(&bytes, &mut out);
        }
        let dec = t.elapsed() / n;
        assert_eq!(out.len(), 1);
        println!(
            "codec {name}: {} bytes, encode {} ns, decode {} ns",
            bytes.len(),
            enc.as_nanos(),
            dec.as_nanos()
        );
    }

    // Worker <-> emulator over a PTY: from `send(Fire)` to the `Acked` event.
    let emu = PtyEmulator::spawn(EngineConfig::default()).unwrap();
    let path = Arc::new(Mutex::new(emu.path().to_owned()));
    let vest = Vest::spawn(pty_connector(path), fast_settings());
    let mut seen = Vec::new();
    wait_for(&vest, &mut seen, Duration::from_secs(3), |e| matches!(e, VestEvent::State(LinkState::Ready)));
    let mut rtts = Vec::new();
    for i in 0..200u32 {
        let mask = TactorMask(1 << (i % 16));
        let t = Instant::now();
        vest.send(VestCommand::Fire { mask, duration_ms: 20 }).unwrap();
        wait_for(&vest, &mut seen, Duration::from_secs(2), |e| {
            matches!(e, VestEvent::Acked { kind: CommandKind::Fire, .. })
        });
        rtts.push(t.elapsed());
        seen.clear();
    }
    rtts.sort();
    println!(
        "PTY fire -> ack through the worker (200 commands): p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        percentile(&rtts, 0.5).as_secs_f64() * 1e3,
        percentile(&rtts, 0.99).as_secs_f64() * 1e3,
        rtts.last().unwrap().as_secs_f64() * 1e3
    );
    drop(vest);

    // The bare link on the PTY (no worker polling): write FIRE, read until its ACK.
    let mut port = vestnav_device::serial::open(emu.path(), 115_200, Duration::from_millis(50)).unwrap();
    let mut replies = FrameCodec::new();
    let mut buf = [0u8; 256];
    let mut bare = Vec::new();
    for i in 0..201u32 {
        let req = if i == 0 {
            Request::Hello
        } else {
            Request::Fire { mask: TactorMask(1 << (i % 16)), duration_ms: 20 }
        };
        let bytes = codec.encode_request(i as u8, &req).unwrap();
        let t = Instant::now();
        port.write_all(&bytes).unwrap();
        'wait: loop {
            let n = port.read(&mut buf).unwrap();
            let mut got = Vec::new();
            replies.decode_replies(&buf[..n], &mut got);
            for r in got {
                if matches!(r, Ok(Packet { seq, message: Reply::Ack { .. } | Reply::Identify(_), .. }) if seq == i as u8)
                {
                    break 'wait;
                }
            }
        }
        if i > 0 {
            bare.push(t.elapsed());
        }
    }
    bare.sort();
    println!(
        "PTY fire -> ack, bare link (200 commands): p50 {:.3} ms, p99 {:.3} ms",
        percentile(&bare, 0.5).as_secs_f64() * 1e3,
        percentile(&bare, 0.99).as_secs_f64() * 1e3
    );
}

#[test]
fn emulated_vest_in_process_connects_out_of_the_box() {
    let (out, rx) = Outbox::channel(1024, Overflow::DropNewest, None);
    let handle = VestHandle::spawn(VestConfig::Emulated(UnitConfig::default()), vec![out]).unwrap();
    let vest = Vest { handle, rx };
    let mut seen = Vec::new();
    let s = Duration::from_secs(3);
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    vest.send(VestCommand::Play(Cue::Stop.pattern(200))).unwrap();
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::CORNERS)));
    // The end of the cue comes from the unit's REPORT.
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::NONE)));
    vest.send(VestCommand::SetIntensity { mask: TactorMask::ALL, level: 100 }).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { kind: CommandKind::SetIntensity, .. }));
    vest.stop();
}

#[test]
fn the_emulator_program_serves_a_console_on_its_pty() {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["emulate", "vest", "--pty", "--battery-mv", "3400"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let path = first.strip_prefix("WTCU emulator on ").unwrap().to_owned();
    // Keep draining the plain-text view so the program never blocks on a full pipe.
    let log = Arc::new(Mutex::new(Vec::new()));
    let l = log.clone();
    let drain = std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            l.lock().unwrap().push(line);
        }
    });
    let vest = Vest::spawn(pty_connector(Arc::new(Mutex::new(path))), fast_settings());
    let mut seen = Vec::new();
    let s = Duration::from_secs(5);
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    // The first status after the handshake carries the battery and its low-battery flag.
    wait_for(
        &vest,
        &mut seen,
        s,
        |e| matches!(e, VestEvent::Status(st) if st.battery_mv == 3400 && st.faults.contains(Faults::LOW_BATTERY)),
    );
    vest.send(VestCommand::Fire { mask: TactorMask::CORNERS, duration_ms: 200 }).unwrap();
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::CORNERS)));
    wait_for(&vest, &mut seen, s, |e| *e == VestEvent::TactorsOn(Some(TactorMask::NONE)));
    vest.stop();
    child.kill().unwrap();
    child.wait().unwrap();
    drain.join().unwrap();
    let log = log.lock().unwrap();
    assert!(log.iter().any(|l| l.ends_with("on: [0, 3, 12, 15]")), "{log:?}");
}
