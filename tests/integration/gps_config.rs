//! Receiver configuration end to end over real PTYs: the emulated receiver (`vestnav emulate gps
//! --simulate --pty --receiver ...`), the serial source writing the commands, and `vestnav gps configure`.
#![cfg(unix)]

use std::process::Command;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use vestnav_device::gps::receiver_config::{ConfigEvent, ConfigTicket, Family, Outcome, ReceiverConfig};
use vestnav_device::gps::{Fix, GpsEvent, GpsHandle, GpsSource, ReplaySpeed, SourceConfig};

use super::gps::Kill;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_vestnav")
}

/// The emulated receiver with a simulated walker (`vestnav emulate gps --pty --simulate ARGS`).
fn emulator(args: &[&str]) -> (Kill, String) {
    let args: Vec<&str> = std::iter::once("--simulate").chain(args.iter().copied()).collect();
    super::gps::emulator(&args)
}

fn serial(path: &str, baud: u32) -> (GpsHandle, Receiver<GpsEvent>) {
    GpsSource::spawn_channel(SourceConfig::Serial { port: path.into(), baud: Some(baud) }, 1024, None)
        .expect("spawn the serial source")
}

/// The next `n` fixes with a position (within `timeout`).
fn fixes(rx: &Receiver<GpsEvent>, n: usize, timeout: Duration) -> Vec<Fix> {
    let end = Instant::now() + timeout;
    let mut out = Vec::new();
    while out.len() < n {
        assert!(Instant::now() < end, "only {} of {n} fixes: {out:?}", out.len());
        if let Ok(GpsEvent::Fix(f)) = rx.recv_timeout(Duration::from_millis(50))
            && f.has_position()
        {
            out.push(*f);
        }
    }
    out
}

/// Every outcome of a configuration run, until it finishes.
fn outcomes(ticket: &ConfigTicket, rx: &Receiver<GpsEvent>) -> Vec<(String, Outcome)> {
    let end = Instant::now() + Duration::from_secs(10);
    let mut out = Vec::new();
    loop {
        assert!(Instant::now() < end, "configuration did not finish: {out:?}");
        // Keep the source's channel drained so its worker never waits on us.
        while rx.try_recv().is_ok() {}
        match ticket.recv_timeout(Duration::from_millis(50)) {
            Some(ConfigEvent::Outcome(o)) => out.push((o.name, o.outcome)),
            Some(ConfigEvent::Finished) => return out,
            Some(ConfigEvent::Failed(e)) => panic!("configuration failed: {e}"),
            None => {}
        }
    }
}

fn drain(rx: &Receiver<GpsEvent>) {
    while rx.try_recv().is_ok() {}
}

/// The thesis's problem and its fix: a `SiRF` III with static navigation on (the emulator's default) holds
/// a 0.8 m/s walker's position and reports speed 0; after `$PSRF100` + MID 143 (disable) + MID 129 from
/// the console's serial source, the positions follow the walker.
#[test]
fn sirf3_pins_a_slow_walker_until_static_navigation_is_switched_off() {
    let (_emu, path) = emulator(&["--pace-m-s", "0.8", "--seed", "3"]);
    let (h, rx) = serial(&path, 4800);
    let pinned = fixes(&rx, 4, Duration::from_secs(10));
    for f in &pinned[1..] {
        assert_eq!((f.lat_deg, f.lon_deg), (pinned[0].lat_deg, pinned[0].lon_deg), "held: {pinned:?}");
        assert!(f.speed_m_s.is_some_and(|v| v.abs() < 1e-9), "speed reads 0: {f:?}");
    }
    let cfg = ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Sirf) };
    let ticket = h.configure(cfg).expect("a serial source configures");
    let got = outcomes(&ticket, &rx);
    let got: Vec<Outcome> = got.into_iter().map(|(_, o)| o).collect();
    assert_eq!(got, [Outcome::Sent, Outcome::Accepted, Outcome::Sent]);
    drain(&rx);
    let moving = fixes(&rx, 4, Duration::from_secs(10));
    for w in moving[1..].windows(2) {
        assert_ne!((w[0].lat_deg, w[0].lon_deg), (w[1].lat_deg, w[1].lon_deg), "moving: {moving:?}");
    }
    for f in &moving[1..] {
        let v = f.speed_m_s.expect("RMC speed");
        assert!((v - 0.8).abs() < 0.02, "speed {v} m/s");
    }
}

/// u-blox 8: CFG-RATE 5 Hz is acknowledged with ACK-ACK and the epochs then come 200 ms apart on the
/// receiver's own time stamps.
#[test]
fn ublox8_acks_cfg_rate_and_sends_epochs_at_5_hz() {
    let (_emu, path) = emulator(&["--receiver", "ublox8"]);
    let (h, rx) = serial(&path, 9600);
    fixes(&rx, 1, Duration::from_secs(10));
    let cfg = ReceiverConfig { rate_hz: Some(5), ..ReceiverConfig::new(Family::Ublox) };
    let got = outcomes(&h.configure(cfg).expect("configure"), &rx);
    assert_eq!(got, [("CFG-RATE".to_owned(), Outcome::Accepted)]);
    drain(&rx);
    let fast = fixes(&rx, 8, Duration::from_secs(10));
    let times: Vec<_> = fast.iter().map(|f| f.time.expect("dated epochs")).collect();
    // The first gap may still be the old 1 s period (the epoch was already due).
    for w in times[1..].windows(2) {
        assert_eq!((w[1] - w[0]).num_milliseconds(), 200, "{times:?}");
    }
}

/// Sources that do not own a serial port say why instead of pretending.
#[test]
fn a_replay_cannot_configure_a_receiver() {
    let log = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gpsd-logs/nd-1005.log");
    let (h, _rx) = GpsSource::spawn_channel(
        SourceConfig::Replay { path: log, speed: ReplaySpeed::AsFastAsPossible },
        1024,
        None,
    )
    .unwrap();
    let cfg = ReceiverConfig { rate_hz: Some(5), ..ReceiverConfig::new(Family::Ublox) };
    assert!(h.configure(cfg).unwrap_err().contains("no receiver"));
}

/// `vestnav gps configure` against the emulated u-blox 8: each command's acknowledgement on stdout; a
/// `SiRF` III does not speak UBX, so the same command gets no reply and the exit status says so.
#[test]
fn cli_configures_the_emulated_receiver_and_reports_each_ack() {
    let (_emu, path) = emulator(&["--receiver", "ublox8"]);
    let out = Command::new(bin())
        .args(["gps", "configure", "--port", &path, "--baud", "9600", "--family", "ublox", "--rate", "2"])
        .args(["--dynamic-model", "pedestrian", "--static-hold", "0.3", "--save"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout} {}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(stdout, "CFG-RATE: accepted\nCFG-NAV5: accepted\nCFG-CFG (save): accepted\n");

    let (_sirf, path) = emulator(&[]);
    let out = Command::new(bin())
        .args(["gps", "configure", "--port", &path, "--baud", "4800", "--family", "ublox", "--rate", "2"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert_eq!(String::from_utf8_lossy(&out.stdout), "CFG-RATE: no reply\n");
}

/// `--dry-run` prints the frames as the documents publish them (CFG-RATE 1 Hz; MID 143 disable).
#[test]
fn cli_dry_run_prints_the_published_frames() {
    let run = |args: &[&str]| {
        let out = Command::new(bin()).args(["gps", "configure", "--dry-run"]).args(args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    assert_eq!(
        run(&["--family", "ublox", "--rate", "1"]),
        "CFG-RATE: B5 62 06 08 06 00 E8 03 01 00 01 00 01 39\n"
    );
    let sirf = run(&["--family", "sirf", "--sirf-static-nav", "off"]);
    assert!(sirf.contains("MID 143 Static Navigation: A0 A2 00 02 8F 00 00 8F B0 B3"), "{sirf}");
    let refused = Command::new(bin())
        .args([
            "gps",
            "configure",
            "--dry-run",
            "--family",
            "ublox",
            "--constellations",
            "gps,glonass,galileo,beidou",
        ])
        .output()
        .unwrap();
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("at most 3"));
}
