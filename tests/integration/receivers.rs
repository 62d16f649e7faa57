//! Receivers side by side in one station session (issue 27): two replayed real gpsd logs, the primary and a
//! comparison source, each on its own reader thread. The station's live comparison must say what
//! `vestnav fieldtest compare` prints for the same logs — the recordings the station wrote beside its session
//! log, and the original files — and two identical logs differ by nothing.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use vestnav_core::accuracy::Comparison;
use vestnav_device::gps::{ReplaySpeed, SourceState};
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::GpsSourceConfig;
use vestnav_station::{Station, StationOptions};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_vestnav")
}

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-receivers-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The log with every latitude `4404.1…` made `4404.2…` (0.1 arc-minute, about 185 m further north) and
/// each changed sentence's checksum recomputed: a second receiver with a known offset and the same clock.
fn shifted_copy(src: &Path, dst: &Path) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        match line.strip_prefix('$').and_then(|l| l.split_once('*')) {
            Some((body, _)) if body.contains(",4404.1") => {
                let body = body.replace(",4404.1", ",4404.2");
                let sum = body.bytes().fold(0u8, |a, b| a ^ b);
                write!(out, "${body}*{sum:02X}\r\n").unwrap();
            }
            _ => {
                out.push_str(line);
                out.push_str("\r\n");
            }
        }
    }
    std::fs::write(dst, out).unwrap();
}

fn replay(path: &Path) -> GpsSourceConfig {
    GpsSourceConfig::Replay { path: path.to_owned(), speed: ReplaySpeed::Times(40.0) }
}

/// Runs a station with `primary` and one comparison source `other` until both replays end; returns the
/// station's comparison and the two recordings it wrote.
fn run_side_by_side(dir: &Path, primary: &Path, other: &Path) -> (Comparison, PathBuf, PathBuf) {
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            gps: Some(replay(primary)),
            log_dir: Some(dir.to_owned()),
            liveness: None,
            ..StationOptions::default()
        },
    );
    station.add_receiver(replay(other)).unwrap();
    station.connect_gps(Vec::new());
    let until = Instant::now() + Duration::from_secs(30);
    let done = |s: &Station| {
        matches!(s.gps.state, Some(SourceState::Finished))
            && matches!(s.receivers().sources()[0].state, Some(SourceState::Finished))
    };
    while !done(&station) && Instant::now() < until {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(done(&station), "both replays must end: {:?}", station.receiver_status(0, Instant::now()));
    // The last events after the end, then the comparison of everything.
    for _ in 0..20 {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(5));
    }
    station.recompute_receivers(Instant::now());
    assert!(station.await_comparison(Duration::from_secs(30)), "the comparison must come");
    let cmp = station.receivers().comparison().cloned().expect("a comparison").expect("compared");
    let rx1 = station.receivers().primary_recording().expect("primary recorded").path;
    let rx2 = station.receivers().sources()[0].recording().expect("recorded").path;
    station.remove_receiver(0);
    station.shutdown();
    (cmp, rx1, rx2)
}

fn cli_compare(a: &Path, b: &Path) -> serde_json::Value {
    let out = Command::new(bin()).args(["fieldtest", "compare"]).args([a, b]).arg("--json").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn assert_same(live: &Comparison, cli: &serde_json::Value, what: &str) {
    assert_eq!(
        cli["matched_epochs"].as_u64().unwrap() as usize,
        live.matched_epochs,
        "{what}: matched epochs"
    );
    let d = &live.differences[0];
    let c = &cli["differences"][0];
    for (name, value) in [("rms_m", d.rms_m), ("p95_m", d.p95_m), ("max_m", d.max_m)] {
        let v = c[name].as_f64().unwrap();
        assert!((v - value).abs() <= 1e-9 * v.abs().max(1.0), "{what}: {name} CLI {v} live {value}");
    }
    for k in 0..2 {
        let v = c["mean_en_m"][k].as_f64().unwrap();
        assert!((v - d.mean_en_m[k]).abs() <= 1e-9 * v.abs().max(1.0), "{what}: mean_en_m[{k}]");
    }
}

/// A real log (gpsd's `SkyTraq` DGPS, 96 fixes) as the primary and its copy moved 0.1' north as the second
/// receiver: the station's live numbers equal what `fieldtest compare` prints on the recordings the station
/// wrote and on the original files; every epoch matches; the difference is due north, about 185 m.
#[test]
fn side_by_side_equals_fieldtest_compare_on_the_same_logs() {
    let dir = tempdir("shifted");
    let a = data("gpsd-logs/skytraq-dgps.log");
    let b = dir.join("skytraq-north.log");
    shifted_copy(&a, &b);
    let (live, rx1, rx2) = run_side_by_side(&dir, &a, &b);
    assert_eq!(live.matched_epochs, 96, "{:?}", live.warnings);
    assert_same(&live, &cli_compare(&rx1, &rx2), "the station's recordings");
    assert_same(&live, &cli_compare(&a, &b), "the original logs");
    // 0.1 arc-minute of latitude at 44° N: the meridian's radius of curvature M = a(1-e²)/(1-e² sin²φ)^1.5.
    let (a_m, e2, phi) = (6_378_137.0_f64, 0.006_694_379_990_14_f64, 44.068_8_f64.to_radians());
    let m = a_m * (1.0 - e2) / (1.0 - e2 * phi.sin().powi(2)).powf(1.5);
    let expect = m * (0.1_f64 / 60.0).to_radians();
    let d = &live.differences[0];
    assert!((d.mean_en_m[1] - expect).abs() < 0.01, "north {} vs {expect}", d.mean_en_m[1]);
    assert!(d.mean_en_m[0].abs() < 0.01, "east {}", d.mean_en_m[0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Two identical logs: every epoch matched, zero difference (closed form), and the CLI agrees.
#[test]
fn identical_receivers_differ_by_nothing() {
    let dir = tempdir("same");
    let a = data("gpsd-logs/skytraq-dgps.log");
    let (live, rx1, rx2) = run_side_by_side(&dir, &a, &a);
    assert_eq!(live.matched_epochs, 96);
    let d = &live.differences[0];
    assert!(d.rms_m < 1e-9 && d.max_m < 1e-9, "{d:?}");
    assert_same(&live, &cli_compare(&rx1, &rx2), "the station's recordings");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The console: the operator opens Field tests → Compare receivers, types the second receiver in `--gps`'s
/// form and adds it, then the primary starts. The table's numbers are those `vestnav fieldtest compare`
/// prints for the recordings the console wrote beside its session log, and each receiver's status is said
/// once, in its row.
#[test]
fn console_compare_receivers_table_shows_what_fieldtest_compare_prints() {
    use egui::accesskit::Role;
    use egui_kittest::kittest::Queryable as _;
    use vestnav_app::config::Config;
    use vestnav_app::console::{Console, ConsoleOptions};

    let dir = tempdir("console");
    let a = data("gpsd-logs/skytraq-dgps.log");
    let b = dir.join("skytraq-north.log");
    shifted_copy(&a, &b);
    let cfg = Config {
        gps: replay(&a),
        auto_connect: false,
        map_tiles: false,
        guidance_auto: false,
        ..Config::default()
    };
    let console = Console::new(
        Box::new(Hardware::default()),
        ConsoleOptions { cfg, log_dir: Some(dir.clone()), ..ConsoleOptions::default() },
    );
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(2);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("Compare receivers").click();
    h.run_steps(2);
    assert!(h.query_by_label("No receiver beside the primary: add one above.").is_some());
    h.get_by_role_and_label(Role::TextInput, "source")
        .set_text_value_accesskit(&format!("replay:{}@40", b.display()));
    h.run_steps(1);
    h.get_by_label("Add receiver").click();
    h.run_steps(2);
    assert_eq!(
        h.state().station.receivers().sources().len(),
        1,
        "{:?}",
        h.state().field_panel.receivers.error
    );
    h.state_mut().connect_gps();
    let until = Instant::now() + Duration::from_secs(30);
    let done = |c: &Console| {
        matches!(c.station.gps.state, Some(SourceState::Finished))
            && matches!(c.station.receivers().sources()[0].state, Some(SourceState::Finished))
    };
    while !done(h.state()) && Instant::now() < until {
        h.step();
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(done(h.state()), "both replays must end");
    for _ in 0..10 {
        h.step();
        std::thread::sleep(Duration::from_millis(5));
    }
    h.state_mut().station.recompute_receivers(Instant::now());
    assert!(h.state_mut().station.await_comparison(Duration::from_secs(30)), "the comparison must come");
    h.run_steps(2);
    let rx1 = h.state().station.receivers().primary_recording().unwrap().path;
    let rx2 = h.state().station.receivers().sources()[0].recording().unwrap().path;
    assert_eq!(rx1.parent(), h.state().log_path().and_then(Path::parent), "recorded beside the session log");
    let cli = cli_compare(&rx1, &rx2);
    let d = &cli["differences"][0];
    let f = |k: &str| d[k].as_f64().unwrap();
    let mean = format!(
        "{:+.3} / {:+.3} m",
        d["mean_en_m"][0].as_f64().unwrap(),
        d["mean_en_m"][1].as_f64().unwrap()
    );
    let spread = format!("{:.3} / {:.3} / {:.3} m", f("rms_m"), f("p95_m"), f("max_m"));
    let matched = format!("{} epochs matched within 0.1 s", cli["matched_epochs"]);
    let live = h.state().station.receivers().comparison().cloned().unwrap().unwrap();
    eprintln!(
        "live matched {} primary fixes {} other {}",
        live.matched_epochs,
        h.state().station.receivers().primary_fixes(),
        h.state().station.receivers().sources()[0].fixes()
    );
    for text in [&mean, &spread, &matched] {
        assert!(h.query_by_label(text).is_some(), "the table shows {text}");
    }
    // The sheet `vestnav fieldtest compare --png` draws, drawn on a thread of its own, arrives in the tab.
    let until = Instant::now() + Duration::from_secs(10);
    while h.query_by_label_contains("Fixes about the first fix").is_none() {
        assert!(Instant::now() < until, "the receivers sheet never arrived");
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    // Each source's state once: the primary's in the GPS panel, the second receiver's in its row.
    // Each source's state once where it belongs: the primary's in the GPS panel (and the top bar's line),
    // the second receiver's in its row only: no notice repeats it.
    assert_eq!(h.query_all_by_label("end of input").count(), 2, "the GPS panel's and the row's");
    let name = format!("2: replay:{}@40", b.display());
    assert!(
        !h.state().station.notices.all().iter().any(|n| n.text.contains(&name)),
        "no notice repeats the receiver's state"
    );
    // Removing it ends the comparison and both recordings.
    h.get_by_label("Remove receiver 2").click();
    h.run_steps(2);
    assert!(h.state().station.receivers().sources().is_empty());
    assert!(!h.state().station.receivers().active());
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The closed form of [`shifted_copy`]'s offset: 0.1 arc-minute of latitude at the log's 44.0688° N, along
/// the meridian (radius of curvature M = a(1-e²)/(1-e² sin²φ)^1.5 on WGS 84) [m].
fn shift_north_m() -> f64 {
    let (a_m, e2, phi) = (6_378_137.0_f64, 0.006_694_379_990_14_f64, 44.068_8_f64.to_radians());
    let m = a_m * (1.0 - e2) / (1.0 - e2 * phi.sin().powi(2)).powf(1.5);
    m * (0.1_f64 / 60.0).to_radians()
}

/// `vestnav station --compare-gps`: the headless station replays the log as its GPS and the shifted copy as
/// a receiver beside it, ends when both are read, and its last status line (JSON) carries the comparison:
/// every epoch matched, the second receiver due north by the closed-form offset. Its recording of the second
/// receiver, read back by `vestnav fieldtest compare`, says the same.
#[test]
fn the_headless_station_compares_receivers_given_on_its_command_line() {
    let dir = tempdir("cli");
    let a = data("gpsd-logs/skytraq-dgps.log");
    let b = dir.join("skytraq-north.log");
    shifted_copy(&a, &b);
    let out = Command::new(bin())
        .args(["station", "--json", "--status-every", "0", "--exit-when-done", "--for", "60"])
        .arg("--gps")
        .arg(format!("replay:{}@40", a.display()))
        .arg("--compare-gps")
        .arg(format!("replay:{}@40", b.display()))
        .arg("--log-dir")
        .arg(&dir)
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    let last: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    let r = &last["receivers"];
    let cmp = &r["comparison"]["Ok"];
    assert_eq!(cmp["matched_epochs"], 96, "{r}\n{stderr}");
    let d = &cmp["differences"][0];
    let north = d["mean_en_m"][1].as_f64().unwrap();
    assert!((north - shift_north_m()).abs() < 0.01, "north {north} m vs {} m", shift_north_m());
    assert!(d["mean_en_m"][0].as_f64().unwrap().abs() < 0.01, "{d}");
    assert!(d["distance_m"].as_array().unwrap().is_empty(), "a status line carries no per-epoch series");
    assert_eq!(r["sources"][0]["name"], format!("2: replay:{}@40", b.display()));
    assert_eq!(r["sources"][0]["fixes"], 96);
    // The recordings beside the session log read back as the same comparison.
    let rx = |v: &serde_json::Value| PathBuf::from(v["path"].as_str().unwrap());
    let (rx1, rx2) = (rx(&r["primary_recording"]), rx(&r["sources"][0]["recording"]));
    let cli = cli_compare(&rx1, &rx2);
    assert_eq!(cli["matched_epochs"], 96);
    let cli_north = cli["differences"][0]["mean_en_m"][1].as_f64().unwrap();
    assert!((cli_north - north).abs() < 1e-9, "CLI {cli_north} live {north}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A receiver read from a real gpsd (fed on a PTY by our emulator with the shifted log) is recorded as the
/// NMEA sentences gpsd passes on, so `vestnav fieldtest compare` reads the session afterwards: the primary's
/// recording against the gpsd receiver's gives the closed-form offset due north.
#[test]
#[cfg(unix)]
fn a_gpsd_receiver_is_recorded_for_fieldtest_compare() {
    use vestnav_station::command::Command as StationCommand;
    let Some(gpsd) = crate::gps::which("gpsd") else {
        eprintln!("SKIPPED a_gpsd_receiver_is_recorded_for_fieldtest_compare: gpsd is not installed");
        return;
    };
    let dir = tempdir("gpsd");
    let a = data("gpsd-logs/skytraq-dgps.log");
    let b = dir.join("skytraq-north.log");
    shifted_copy(&a, &b);
    let (_emu, pty) = crate::gps::emulator(&["--replay", b.to_str().unwrap(), "--speed", "10"]);
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let _gpsd = crate::gps::Kill(
        Command::new(gpsd)
            .args(["-N", "-n", "-b", "-S", &port.to_string(), &pty])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            gps: Some(replay(&a)),
            log_dir: Some(dir.clone()),
            liveness: None,
            ..StationOptions::default()
        },
    );
    station.apply(StationCommand::AddReceiver { spec: format!("gpsd://127.0.0.1:{port}") }).unwrap();
    station.connect_gps(Vec::new());
    // Until the emulator's replay (9.6 s at ten times its pace) has gone through gpsd: no new fix for 2 s.
    let until = Instant::now() + Duration::from_secs(40);
    let (mut fixes, mut since) = (0, Instant::now());
    while Instant::now() < until {
        station.pump(|_| {});
        let n = station.receivers().sources()[0].fixes();
        if n != fixes {
            (fixes, since) = (n, Instant::now());
        } else if fixes > 0 && since.elapsed() > Duration::from_secs(2) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(fixes >= 60, "fixes through gpsd: {fixes} ({:?})", station.receiver_status(0, Instant::now()));
    let rx1 = station.receivers().primary_recording().unwrap().path;
    let rec = station.receivers().sources()[0].recording().unwrap();
    station.apply(StationCommand::RemoveReceiver { number: 2 }).unwrap();
    station.shutdown();
    assert!(rec.error.is_none() && rec.sentences > 0, "{rec:?}");
    let cli = cli_compare(&rx1, &rec.path);
    let matched = cli["matched_epochs"].as_u64().unwrap();
    assert!(matched as usize >= fixes - 2, "matched {matched} of {fixes} fixes read through gpsd");
    let north = cli["differences"][0]["mean_en_m"][1].as_f64().unwrap();
    assert!((north - shift_north_m()).abs() < 0.01, "north {north} m vs {} m", shift_north_m());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Over a real Mosquitto with the shipped ACL: an observer's `add_receiver` never reaches the station (the
/// broker drops it), an operator's opens the receiver and the station's state shows it; a file spec is
/// refused over the broker, a fifth receiver is refused with the limit named, a removal by number applies.
#[test]
#[cfg(unix)]
fn only_an_operator_adds_a_receiver_over_the_broker() {
    use vestnav_remote::wire::{EventKind, Sender};
    use vestnav_remote::{Fleet, FleetOptions};
    use vestnav_station::command::Command as StationCommand;

    use crate::remote::{Broker, StationProc, in_contact, temp_dir, wait_for};

    let dir = temp_dir("receivers");
    let broker = Broker::start(&dir);
    let alpha = StationProc::spawn(&broker, "alpha");
    let fleet = Fleet::connect(&broker.client("operator"), FleetOptions::operator("operator")).unwrap();
    wait_for("alpha in contact", Duration::from_secs(30), || in_contact(&fleet, "alpha"));
    let receivers = || fleet.station("alpha").and_then(|v| v.state).and_then(|s| s.station.receivers);
    let event = |kind: EventKind, from: &Sender, text: &str| {
        fleet.station("alpha").is_some_and(|v| {
            v.events.iter().any(|(_, e)| {
                e.kind == kind && e.answers.as_ref().is_some_and(|(s, _)| s == from) && e.text.contains(text)
            })
        })
    };
    let add = |spec: &str| StationCommand::AddReceiver { spec: spec.into() };

    let observer = Fleet::connect(
        &broker.client("observer"),
        FleetOptions { heartbeats: false, ..FleetOptions::operator("observer") },
    )
    .unwrap();
    wait_for("observer connected", Duration::from_secs(5), || observer.broker_status().0);
    observer.send("alpha", add("sim")).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    assert!(receivers().is_none(), "an observer's receiver was opened: {:?}", receivers());
    assert!(
        !fleet
            .station("alpha")
            .unwrap()
            .events
            .iter()
            .any(|(_, e)| e.answers.as_ref().is_some_and(|(s, _)| s == observer.sender())),
        "the station answered an observer's command"
    );

    let me = fleet.sender().clone();
    fleet.send("alpha", add("sim")).unwrap();
    wait_for("the operator's receiver in alpha's state", Duration::from_secs(5), || {
        receivers().is_some_and(|r| r.sources.len() == 1 && r.sources[0].name == "2: sim")
    });
    let e = fleet.send("alpha", add("replay:/etc/passwd@1")).unwrap_err().to_string();
    assert!(e.contains("refused over the broker"), "{e}");
    // A gpsd elsewhere in the station's network: refused by the station (started without
    // --remote-gpsd-host), which names the flag; nothing is opened.
    fleet.send("alpha", add("gpsd://10.255.0.7:2947")).unwrap();
    wait_for("gpsd on another host refused", Duration::from_secs(5), || {
        event(EventKind::Refused, &me, "gpsd://10.255.0.7:2947 refused over the broker")
            && event(EventKind::Refused, &me, "--remote-gpsd-host 10.255.0.7")
    });
    assert_eq!(receivers().map(|r| r.sources.len()), Some(1), "only the simulator beside the primary");
    for _ in 0..3 {
        fleet.send("alpha", add("sim")).unwrap();
    }
    wait_for("four receivers beside the primary", Duration::from_secs(5), || {
        receivers().is_some_and(|r| r.sources.len() == 4)
    });
    fleet.send("alpha", add("sim")).unwrap();
    wait_for("the fifth refused, the limit named", Duration::from_secs(5), || {
        event(EventKind::Refused, &me, "at most 4 receivers beside the primary")
    });
    fleet.send("alpha", StationCommand::RemoveReceiver { number: 2 }).unwrap();
    wait_for("receiver 2 removed", Duration::from_secs(5), || {
        receivers().is_some_and(|r| r.sources.iter().map(|s| s.number).eq([3, 4, 5]))
    });
    alpha.quit();
    drop(observer);
    drop(fleet);
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A comparison receiver that stops giving fixes but stays connected (a PTY nobody writes to after three
/// GGAs) is stale: the station says so with the age of its last fix, measured against the test's own clock,
/// and the age is a number beside the words, so two snapshots a second apart compare equal once ages are
/// set aside (a remote publisher sends on change, not every second).
#[test]
fn a_stale_receivers_age_is_a_number_not_part_of_its_words() {
    use std::io::Write as _;
    use vestnav_station::receivers::ReceiverStatus;
    let nmea = |body: &str| format!("${body}*{:02X}\r\n", body.bytes().fold(0u8, |a, b| a ^ b));
    let mut pty = vestnav_device::serial::Pty::open().unwrap();
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            gps: Some(replay(&data("gpsd-logs/skytraq-dgps.log"))),
            liveness: None,
            ..StationOptions::default()
        },
    );
    let mut settings = *station.settings();
    settings.guidance.stale_after_s = 1.0;
    station.set_settings(settings);
    station.add_receiver(GpsSourceConfig::Serial { port: pty.path().to_owned(), baud: Some(9600) }).unwrap();
    station.connect_gps(Vec::new());
    let pump_for = |station: &mut Station, d: Duration| {
        let until = Instant::now() + d;
        while Instant::now() < until {
            station.pump(|_| {});
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    let mut last_write = Instant::now();
    for s in 0..3 {
        let gga = nmea(&format!("GPGGA,1200{s:02}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"));
        last_write = Instant::now();
        pty.write_all(gga.as_bytes()).unwrap();
        pump_for(&mut station, Duration::from_millis(150));
    }
    let fixes = |s: &Station| s.receivers().sources()[0].fixes();
    let until = Instant::now() + Duration::from_secs(10);
    while fixes(&station) < 3 && Instant::now() < until {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(fixes(&station) >= 3, "{:?}", station.receiver_status(0, Instant::now()));
    pump_for(&mut station, Duration::from_millis(1500));
    let now = Instant::now();
    let status = station.receiver_status(0, now).unwrap();
    let ReceiverStatus::Stale { age_s } = status else { panic!("not stale: {status}") };
    let since_write = now.duration_since(last_write).as_secs_f64();
    assert!(
        (since_write - 0.5..=since_write + 0.1).contains(&age_s),
        "age {age_s} s, written {since_write} s ago"
    );
    let first = station.snapshot(now).receivers.unwrap();
    pump_for(&mut station, Duration::from_millis(1100));
    let second = station.snapshot(Instant::now()).receivers.unwrap();
    let (a, b) = (&first.sources[0], &second.sources[0]);
    assert_eq!(a.status, "stale: no fix");
    assert!(b.stale_for_s.unwrap() >= a.stale_for_s.unwrap() + 1.0, "{a:?} {b:?}");
    assert_eq!(a.status_text(), format!("stale: no fix for {:.0} s", a.stale_for_s.unwrap()));
    assert!(second.summary().contains("stale: no fix for"), "{}", second.summary());
    let mut snaps = [station.snapshot(now), station.snapshot(Instant::now() + Duration::from_secs(2))];
    for s in &mut snaps {
        *s = s.without_ages();
    }
    assert_eq!(snaps[0].receivers, snaps[1].receivers, "only the age changed");
    station.shutdown();
}
