//! Integration tests: the GPS path end to end — CLI decoding, the emulator on a real PTY read by the serial
//! source (baud detection, port vanishing, reconnect), and a real gpsd fed by our emulator.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use vestnav_device::gps::{GpsEvent, GpsHandle, GpsSource, SourceConfig, SourceState};

/// Starts a source with one lossless consumer.
fn spawn(config: SourceConfig) -> (GpsHandle, Receiver<GpsEvent>) {
    GpsSource::spawn_channel(config, 1024, None).expect("spawn the GPS worker")
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_vestnav")
}

fn logs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gpsd-logs")
}

/// Kills the child (by its own handle) when dropped.
pub(crate) struct Kill(pub(crate) Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `vestnav emulate gps ... --pty` and returns it with the PTY path it printed.
/// Starts `vestnav emulate gps --pty ARGS` and returns it (killed on drop) with the PTY path it printed.
pub(crate) fn emulator(args: &[&str]) -> (Kill, String) {
    let mut child = Command::new(bin())
        .args(["emulate", "gps", "--pty"])
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start vestnav emulate gps");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("piped stdout"))
        .read_line(&mut line)
        .expect("read the PTY path");
    let path = line.trim().to_owned();
    assert!(path.starts_with("/dev/"), "emulator printed {path:?}");
    (Kill(child), path)
}

fn wait_for(
    rx: &Receiver<GpsEvent>,
    timeout: Duration,
    mut pred: impl FnMut(&GpsEvent) -> bool,
) -> Vec<GpsEvent> {
    let end = Instant::now() + timeout;
    let mut seen = Vec::new();
    while Instant::now() < end {
        if let Ok(ev) = rx.recv_timeout(Duration::from_millis(50)) {
            let done = pred(&ev);
            seen.push(ev);
            if done {
                return seen;
            }
        }
    }
    panic!("timed out; events: {seen:?}");
}

#[test]
fn decode_json_matches_gpsd_positions() {
    let out = Command::new(bin())
        .args(["nmea", "decode", "--json"])
        .arg(logs().join("nd-1005.log"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 16);
    // gpsd's TPV for 11:05:18 (nd-1005.log.chk): lat 57.163445000, lon -2.121370000, mode 3, hdop 1.00.
    assert_eq!(lines[0]["time"], "2011-03-14T11:05:18.000Z");
    assert!((lines[0]["lat"].as_f64().unwrap() - 57.163_445).abs() <= 1e-7);
    assert!((lines[0]["lon"].as_f64().unwrap() + 2.121_37).abs() <= 1e-7);
    assert_eq!(lines[0]["mode"], "3d");
    assert_eq!(lines[0]["sats_used"], 8);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("rejected 0"), "{stderr}");
}

#[test]
fn decode_reports_rejections_on_stderr() {
    let out =
        Command::new(bin()).args(["nmea", "decode"]).arg(logs().join("firefly-II.log")).output().unwrap();
    assert!(out.status.success());
    // gpsd rejects all 23 GGA of this log for their bad checksums.
    assert!(String::from_utf8(out.stderr).unwrap().contains("bad checksum 23"));
}

#[test]
#[cfg(unix)]
fn pty_emulator_to_serial_source_with_baud_detection_loss_and_reconnect() {
    let dir = std::env::temp_dir().join(format!("vestnav-gps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("gps0");
    let log = logs().join("nd-1005.log");
    let log = log.to_str().unwrap();
    let (emu, path) = emulator(&["--replay", log, "--speed", "10", "--repeat"]);
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&path, &link).unwrap();
    let port = link.to_str().unwrap().to_owned();
    let (h, rx) = spawn(SourceConfig::Serial { port, baud: None });
    // Baud detection picks the first rate that yields valid sentences, then fixes flow.
    wait_for(
        &rx,
        Duration::from_secs(10),
        |e| matches!(e, GpsEvent::State(SourceState::Live { detail }) if detail.contains("baud")),
    );
    let mut fixes = 0;
    wait_for(&rx, Duration::from_secs(10), |e| {
        if let GpsEvent::Fix(f) = e {
            assert!((f.lat_deg.unwrap() - 57.163_445).abs() < 1e-7);
            fixes += 1;
        }
        fixes >= 3
    });
    // The port vanishes mid-stream: the source reports it lost and starts reconnecting.
    drop(emu);
    wait_for(&rx, Duration::from_secs(15), |e| matches!(e, GpsEvent::State(SourceState::Lost { .. })));
    wait_for(&rx, Duration::from_secs(5), |e| matches!(e, GpsEvent::State(SourceState::Reconnecting { .. })));
    // A new device appears behind the same name: the source reconnects and fixes flow again.
    let (_emu2, path2) = emulator(&["--replay", log, "--speed", "10", "--repeat"]);
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&path2, &link).unwrap();
    wait_for(&rx, Duration::from_secs(30), |e| matches!(e, GpsEvent::Fix(f) if f.has_position()));
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

pub(crate) fn which(prog: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|p| {
        std::env::split_paths(&p)
            .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/sbin")])
            .map(|d| d.join(prog))
            .find(|c| c.is_file())
    })
}

#[test]
#[cfg(unix)]
fn real_gpsd_fed_by_our_emulator() {
    let Some(gpsd) = which("gpsd") else {
        eprintln!("SKIPPED real_gpsd_fed_by_our_emulator: gpsd is not installed (apt-get install gpsd)");
        return;
    };
    let (_emu, path) = emulator(&["--replay", logs().join("nd-1005.log").to_str().unwrap(), "--repeat"]);
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let _gpsd = Kill(
        Command::new(gpsd)
            .args(["-N", "-n", "-b", "-S", &port.to_string(), &path])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let (_h, rx) = spawn(SourceConfig::Gpsd { host: "127.0.0.1".into(), port });
    let ev = wait_for(&rx, Duration::from_secs(30), |e| matches!(e, GpsEvent::Fix(f) if f.has_position()));
    let Some(GpsEvent::Fix(f)) = ev.last() else { unreachable!() };
    // The fix gpsd computed from our emulator's bytes is the log's position (gpsd's own .chk value).
    assert!((f.lat_deg.unwrap() - 57.163_445).abs() < 1e-7, "{f:?}");
    assert!((f.lon_deg.unwrap() + 2.121_37).abs() < 1e-7);
    assert!(ev.iter().any(|e| matches!(e, GpsEvent::State(SourceState::Live { .. }))));
}

/// A gpsd that trickles one byte per 50 ms and never ends its line (the "Safety first" issue): the source
/// counts time since the last complete line, so it goes stale after 3 s, is lost after 10 s, reconnects,
/// and gets fixes from the next (well-behaved) connection; the trickling connection never hangs it.
#[test]
fn gpsd_trickling_without_newline_goes_stale_then_lost_and_reconnects() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = std::thread::spawn(move || {
        // First connection: a byte every 50 ms, never a newline, for at most 15 s.
        let (mut s, _) = listener.accept().unwrap();
        s.set_write_timeout(Some(Duration::from_secs(1))).unwrap();
        let end = Instant::now() + Duration::from_secs(15);
        let _ = s.write_all(b"{\"class\":\"TPV\",");
        listener.set_nonblocking(true).unwrap();
        let mut second = None;
        while Instant::now() < end && second.is_none() {
            if s.write_all(b" ").is_err() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
            second = listener.accept().ok();
        }
        // Second connection: a proper TPV (gpsd's report for nd-1005.log at 11:05:18).
        let end = Instant::now() + Duration::from_secs(15);
        while second.is_none() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(20));
            second = listener.accept().ok();
        }
        if let Some((mut s2, _)) = second {
            s2.set_nonblocking(false).unwrap();
            let _ = s2.write_all(
                b"{\"class\":\"TPV\",\"mode\":3,\"time\":\"2011-03-14T11:05:18.000Z\",\"lat\":57.163445000,\
                  \"lon\":-2.121370000,\"altMSL\":59.300}\n",
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    });
    let (mut h, rx) = spawn(SourceConfig::Gpsd { host: "127.0.0.1".into(), port });
    let t0 = Instant::now();
    wait_for(&rx, Duration::from_secs(6), |e| matches!(e, GpsEvent::State(SourceState::Stale)));
    let stale_after = t0.elapsed();
    assert!(stale_after >= Duration::from_millis(2900), "{stale_after:?}");
    let ev =
        wait_for(&rx, Duration::from_secs(10), |e| matches!(e, GpsEvent::State(SourceState::Lost { .. })));
    assert!(!ev.iter().any(|e| matches!(e, GpsEvent::Fix(_))));
    wait_for(&rx, Duration::from_secs(3), |e| matches!(e, GpsEvent::State(SourceState::Reconnecting { .. })));
    let ev = wait_for(&rx, Duration::from_secs(5), |e| matches!(e, GpsEvent::Fix(f) if f.has_position()));
    let Some(GpsEvent::Fix(f)) = ev.last() else { unreachable!() };
    assert!((f.lat_deg.unwrap() - 57.163_445).abs() < 1e-9);
    let t1 = Instant::now();
    h.stop();
    assert!(t1.elapsed() < Duration::from_millis(300));
    server.join().unwrap();
}

/// `nmea record` on a real PTY fed by the GPS emulator, with cone marks typed on standard input: the
/// recording decodes to the emulator's fixes (positions of the replayed log) and carries the marks in order.
#[cfg(unix)]
#[test]
fn record_from_a_pty_with_operator_marks() {
    use std::io::Write as _;
    let dir = std::env::temp_dir().join(format!("vestnav-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("walk.nmea");
    let log = logs().join("nd-1005.log");
    let (_emu, path) = emulator(&["--replay", log.to_str().unwrap(), "--speed", "10", "--repeat"]);
    let mut rec = Command::new(bin())
        .args([
            "nmea",
            "record",
            &path,
            out.to_str().unwrap(),
            "--baud",
            "4800",
            "--duration-s",
            "4",
            "--marks",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start vestnav nmea record");
    let mut stdin = rec.stdin.take().unwrap();
    std::thread::sleep(Duration::from_millis(1200));
    stdin.write_all(b"\n").unwrap();
    std::thread::sleep(Duration::from_millis(800));
    stdin.write_all(b"cone B\n").unwrap();
    drop(stdin);
    let output = rec.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "record failed: {stderr}");
    assert!(stderr.contains("mark 1") && stderr.contains("mark 2"), "{stderr}");

    let bytes = std::fs::read(&out).unwrap();
    let (fixes, marks, stats) = vestnav_device::gps::decode_reader_with_marks(bytes.as_slice()).unwrap();
    assert!(fixes.len() >= 5, "only {} fixes recorded", fixes.len());
    // nd-1005 is a stationary log at 57.163445 N, 2.12137 W (gpsd's .chk says the same).
    for f in fixes.iter().filter(|f| f.has_position()) {
        assert!((f.lat_deg.unwrap() - 57.163_445).abs() < 1e-7);
        assert!((f.lon_deg.unwrap() + 2.121_37).abs() < 1e-7);
    }
    let labels: Vec<_> = marks.iter().map(|m| (m.number, m.label.as_str())).collect();
    assert_eq!(labels, vec![(1, "cone 1"), (2, "cone B")]);
    assert!(marks.iter().all(|m| m.recorded_unix_ms.is_some()));
    assert_eq!(stats.bad_checksum, 0, "{stats:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
