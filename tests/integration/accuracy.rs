//! GPS accuracy against the truth (issue 27): the statistics of `vestnav fieldtest accuracy` against an
//! independent computation (Python geographiclib, `scripts/accuracy_check.py`) on a real log, `fieldtest
//! compare` on real logs, and the NTRIP client against casters that these tests run on 127.0.0.1, serving
//! the RTCM 3 streams of gpsd's regression logs (`tests/data/gpsd-rtcm`, BSD-2, see `COPYING.gpsd`): every
//! frame reaches the receiver's PTY byte for byte, GGA reaches the caster, wrong credentials and mountpoints
//! are clear errors, and a stalled caster is detected.
#![cfg(unix)]

use std::io::{BufRead as _, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_device::ntrip::{
    Credentials, NtripConfig, NtripState, NtripVersion, fetch_sourcetable, read_credentials, spawn,
};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_vestnav")
}

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
}

// ---------------------------------------------------------------------------------------------------------
// Statistics against an independent computation.

/// The u-blox ZED-F9P log of gpsd's suite (655 autonomous 1 Hz fixes), against a reference point: our JSON
/// against Python's geographiclib and its own GGA parser. Skipped (with a note) when python3 or geographiclib
/// is missing: `pip install geographiclib`.
#[test]
fn accuracy_matches_python_geographiclib_on_a_real_log() {
    let log = data("gpsd-logs/ublox-zed-f9p_hpg1.11.log");
    let (lat, lon, h) = ("-45.8775925", "170.5001265", "16.5");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/accuracy_check.py");
    let py = Command::new("python3").arg(&script).arg(&log).args([lat, lon, h]).output();
    let py = match py {
        Ok(o) if o.status.success() => o,
        _ => {
            eprintln!("skipped: python3 with geographiclib is not available (pip install geographiclib)");
            return;
        }
    };
    let truth: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
    let out = Command::new(bin())
        .args(["fieldtest", "accuracy"])
        .arg(&log)
        .args(["--reference", &format!("{lat}, {lon}"), "--reference-height-m", h, "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ours: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(ours["fixes"], truth["fixes"]);
    let close = |a: &serde_json::Value, b: &serde_json::Value, what: &str| {
        let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
        assert!((a - b).abs() <= 1e-6 + 1e-9 * b.abs(), "{what}: ours {a}, geographiclib {b}");
    };
    for k in ["drms_m", "cep50_m", "cep95_m", "max_m"] {
        close(&ours[k], &truth[k], k);
    }
    for i in 0..2 {
        close(&ours["bias_en_m"][i], &truth["bias_en_m"][i], "bias");
        close(&ours["sigma_en_m"][i], &truth["sigma_en_m"][i], "sigma");
    }
    for i in 0..5 {
        close(&ours["within"][i]["share"], &truth["within"][i], "share within");
    }
    close(&ours["gaussian"]["cep50_m"], &truth["gaussian_cep50_m"], "gaussian CEP50");
    close(&ours["vertical"]["bias_m"], &truth["vertical_bias_m"], "vertical bias");
    close(&ours["vertical"]["rms_m"], &truth["vertical_rms_m"], "vertical RMS");
}

/// The same log typed as DMS and as UTM gives the same statistics (one parser, core's `coords`), and a
/// drift test against the reference keeps its own keys and adds `against_reference`; the figure is drawn.
#[test]
fn reference_forms_agree_and_drift_gains_against_reference() {
    let log = data("gpsd-logs/ublox-zed-f9p_hpg1.11.log");
    let run = |reference: &str, sub: &str| -> serde_json::Value {
        let out = Command::new(bin())
            .args(["fieldtest", sub])
            .arg(&log)
            .args(["--reference", reference, "--json"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let decimal = run("-45.8775925, 170.5001265", "accuracy");
    // 45°52'39.333"S 170°30'00.4554"E is the same point to 0.1 mm.
    let dms = run("45 52 39.333 S 170 30 0.4554 E", "accuracy");
    let a = decimal["cep50_m"].as_f64().unwrap();
    let b = dms["cep50_m"].as_f64().unwrap();
    assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    let drift = run("-45.8775925, 170.5001265", "drift");
    assert_eq!(drift["test"], "drift");
    assert!(drift["cep50_m"].as_f64().is_some(), "the drift keys stay");
    let against = drift["against_reference"]["cep50_m"].as_f64().unwrap();
    assert!((against - a).abs() < 1e-9);
    let dir = tempdir("accuracy-png");
    let png = dir.join("drift.png");
    let out = Command::new(bin())
        .args(["fieldtest", "drift"])
        .arg(&log)
        .args(["--reference", "-45.8775925, 170.5001265", "--png"])
        .arg(&png)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("against the reference"));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
}

/// Two receivers: a log against itself matches every epoch with zero difference; against another day's log
/// nothing matches and the report says so.
#[test]
fn compare_matches_epochs_by_receiver_time() {
    let a = data("gpsd-logs/ublox-zed-f9p_hpg1.11.log");
    let out = Command::new(bin())
        .args(["fieldtest", "compare"])
        .args([&a, &a])
        .args(["--reference-average-s", "60", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["matched_epochs"], 655);
    assert!(v["differences"][0]["rms_m"].as_f64().unwrap() < 1e-9);
    assert_eq!(v["reference_point"]["origin"]["kind"], "averaged");
    assert!(v["against_reference"][1]["cep50_m"].as_f64().is_some());
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

// ---------------------------------------------------------------------------------------------------------
// The test caster.

/// The RTCM 3 stream of a gpsd log: the bytes after its `#` comment lines.
fn rtcm_stream(name: &str) -> Vec<u8> {
    let raw = std::fs::read(data(&format!("gpsd-rtcm/{name}"))).unwrap();
    let mut i = 0;
    while raw.get(i) == Some(&b'#') {
        i += raw[i..].iter().position(|b| *b == b'\n').unwrap() + 1;
    }
    raw[i..].to_vec()
}

/// CRC-24Q bit by bit (RTCM 10403 §4.2: generator 0x1864CFB, no reflection), written apart from the crate's
/// table-driven `crc` so the two check each other.
fn crc24q_bitwise(data: &[u8]) -> u32 {
    let mut crc: u32 = 0;
    for b in data {
        crc ^= u32::from(*b) << 16;
        for _ in 0..8 {
            crc <<= 1;
            if crc & 0x0100_0000 != 0 {
                crc ^= 0x0186_4CFB;
            }
        }
    }
    crc & 0x00FF_FFFF
}

/// The frames of a stream found by the test's own scan (preamble, length, bitwise CRC-24Q).
fn frames_of(stream: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 6 <= stream.len() {
        if stream[i] == 0xD3 && stream[i + 1] & 0xFC == 0 {
            let len = ((usize::from(stream[i + 1]) & 3) << 8 | usize::from(stream[i + 2])) + 6;
            if let Some(f) = stream.get(i..i + len) {
                let crc = u32::from_be_bytes([0, f[len - 3], f[len - 2], f[len - 1]]);
                if crc24q_bitwise(&f[..len - 3]) == crc {
                    out.push(f.to_vec());
                    i += len;
                    continue;
                }
            }
        }
        i += 1;
    }
    out
}

/// The message types gpsd decoded from a log (its `.chk`), in order.
fn gpsd_types(name: &str) -> Vec<u64> {
    let text = std::fs::read_to_string(data(&format!("gpsd-rtcm/{name}.chk"))).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["type"].as_u64().unwrap())
        .collect()
}

const USER: &str = "rover";
const PASSWORD: &str = "s3cret:with colon";

/// A caster on 127.0.0.1: mountpoints `RTCM32` and `BNDM` serve gpsd's streams, `STALL` sends three frames
/// and then nothing; `/` is the source table. Speaks v1 or v2 by the request. Every line a client sends
/// after its request (GGA) is kept.
struct Caster {
    addr: String,
    upstream: Arc<Mutex<Vec<String>>>,
    connections: Arc<Mutex<usize>>,
}

const TABLE: &str = "STR;RTCM32;Wettzell;RTCM 3.2;1077(1),1087(1);2;GPS+GLO;IGS;DEU;49.14;12.88;0;0;x;none;B;N;5000;\r\n\
STR;BNDM;Bend;RTCM 3;1004(1),1006(10),1012(1);2;GPS+GLO;ORGN;USA;44.06;-121.31;1;0;x;none;B;N;3000;\r\n\
ENDSOURCETABLE\r\n";

impl Caster {
    fn start() -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let upstream = Arc::new(Mutex::new(Vec::new()));
        let connections = Arc::new(Mutex::new(0));
        let (up, conns) = (Arc::clone(&upstream), Arc::clone(&connections));
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(stream) = stream else { return };
                *conns.lock().unwrap() += 1;
                let up = Arc::clone(&up);
                std::thread::spawn(move || serve(stream, &up));
            }
        });
        Self { addr, upstream, connections }
    }

    fn upstream(&self) -> Vec<String> {
        self.upstream.lock().unwrap().clone()
    }
}

fn serve(mut stream: TcpStream, upstream: &Arc<Mutex<Vec<String>>>) {
    stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut head = Vec::new();
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        if line == "\r\n" {
            break;
        }
        head.push(line.trim_end().to_string());
    }
    let request = head.first().cloned().unwrap_or_default();
    let path = request.split_whitespace().nth(1).unwrap_or("/").to_string();
    let v2 = head.iter().any(|h| h.eq_ignore_ascii_case("Ntrip-Version: Ntrip/2.0"));
    let expected = format!(
        "Authorization: Basic {}",
        vestnav_device::ntrip::base64(format!("{USER}:{PASSWORD}").as_bytes())
    );
    let authorised = head.contains(&expected);
    if path == "/" {
        let answer = if v2 {
            format!(
                "HTTP/1.1 200 OK\r\nContent-Type: gnss/sourcetable\r\nContent-Length: {}\r\n\r\n{TABLE}",
                TABLE.len()
            )
        } else {
            format!("SOURCETABLE 200 OK\r\nContent-Type: text/plain\r\n\r\n{TABLE}")
        };
        let _ = stream.write_all(answer.as_bytes());
        return;
    }
    let body = match path.as_str() {
        "/RTCM32" => rtcm_stream("rtcm3.2.log"),
        "/BNDM" => rtcm_stream("rtcm3.bndm.log"),
        "/STALL" => frames_of(&rtcm_stream("rtcm3.2.log")).into_iter().take(3).flatten().collect(),
        _ => {
            let answer = if v2 {
                "HTTP/1.1 404 Not Found\r\nConnection: close\r\n\r\n".to_string()
            } else {
                format!("SOURCETABLE 200 OK\r\n\r\n{TABLE}")
            };
            let _ = stream.write_all(answer.as_bytes());
            return;
        }
    };
    if !authorised {
        let version = if v2 { "1.1" } else { "1.0" };
        let _ = stream.write_all(
            format!("HTTP/{version} 401 Unauthorized\r\nWWW-Authenticate: Basic realm=\"/RTCM32\"\r\n\r\n")
                .as_bytes(),
        );
        return;
    }
    let head = if v2 {
        "HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0\r\nContent-Type: gnss/data\r\nTransfer-Encoding: chunked\r\n\r\n"
    } else {
        "ICY 200 OK\r\n"
    };
    stream.write_all(head.as_bytes()).unwrap();
    // What the client sends from now on (GGA lines) is recorded.
    let up = Arc::clone(upstream);
    std::thread::spawn(move || {
        let mut line = String::new();
        while reader.read_line(&mut line).unwrap_or(0) > 0 {
            up.lock().unwrap().push(line.trim_end().to_string());
            line.clear();
        }
    });
    // Pieces of varying sizes, so frames straddle reads and chunks.
    let mut k = 0usize;
    let mut i = 0;
    while i < body.len() {
        let n = (1 + (k * 379) % 700).min(body.len() - i);
        let piece = &body[i..i + n];
        let ok = if v2 {
            stream
                .write_all(format!("{n:x}\r\n").as_bytes())
                .and_then(|()| stream.write_all(piece))
                .and_then(|()| stream.write_all(b"\r\n"))
        } else {
            stream.write_all(piece)
        };
        if ok.is_err() {
            return;
        }
        i += n;
        k += 1;
        std::thread::sleep(Duration::from_millis(2));
    }
    // Hold the connection open (a caster keeps streaming; here nothing more comes) until the client leaves.
    std::thread::sleep(Duration::from_secs(if path == "/STALL" { 30 } else { 4 }));
}

fn config(caster: &Caster, mountpoint: &str, version: NtripVersion) -> NtripConfig {
    let mut c = NtripConfig::new(caster.addr.clone(), mountpoint);
    c.version = version;
    c.credentials = Some(Credentials { user: USER.into(), password: PASSWORD.into() });
    c.gga_every = Some(Duration::from_millis(300));
    c.connect_timeout = Duration::from_secs(3);
    c
}

const GGA: &str = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47";

/// Reads the PTY master until `want` bytes came or `timeout` passed.
fn read_pty(master: &mut impl Read, want: usize, timeout: Duration) -> Vec<u8> {
    let deadline = Instant::now() + timeout;
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while got.len() < want && Instant::now() < deadline {
        match master.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e)
                if e.kind() == std::io::ErrorKind::TimedOut || e.kind() == std::io::ErrorKind::WouldBlock => {
            }
            Err(e) => panic!("reading the PTY: {e}"),
        }
    }
    got
}

fn wait_until(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    cond()
}

/// NTRIP 2.0 (chunked) and 1.0 (ICY): every CRC-checked frame of gpsd's two streams reaches the receiver's
/// PTY byte for byte and in order (junk between frames does not), the message types are gpsd's, and GGA
/// reaches the caster.
#[test]
fn ntrip_forwards_every_frame_byte_for_byte_to_a_pty() {
    let caster = Caster::start();
    for (mount, log, version) in
        [("RTCM32", "rtcm3.2.log", NtripVersion::V2), ("BNDM", "rtcm3.bndm.log", NtripVersion::V1)]
    {
        let frames = frames_of(&rtcm_stream(log));
        let expected: Vec<u8> = frames.concat();
        let types = gpsd_types(log);
        assert_eq!(frames.len(), types.len(), "{log}: our scan and gpsd agree on the frame count");
        let vestnav_device::serial::Pty { mut master, slave, .. } =
            vestnav_device::serial::Pty::open_with_timeout(Duration::from_millis(100)).unwrap();
        let handle = spawn(config(&caster, mount, version), Box::new(slave)).unwrap();
        assert!(handle.set_gga(GGA));
        assert!(!handle.set_gga("$GPGGA,\u{7}bell*00"), "a control character never goes upstream");
        let got = read_pty(&mut master, expected.len(), Duration::from_secs(20));
        assert_eq!(got.len(), expected.len(), "{log}: bytes at the receiver");
        assert!(got == expected, "{log}: the receiver got the frames byte for byte");
        assert!(
            wait_until(Duration::from_secs(3), || caster.upstream().iter().any(|l| l == GGA)),
            "GGA upstream"
        );
        let status = handle.stop();
        assert_eq!(status.frames as usize, frames.len());
        assert_eq!(status.bad_crc, 0);
        let mut counts = std::collections::BTreeMap::new();
        for t in types {
            *counts.entry(u16::try_from(t).unwrap()).or_insert(0u64) += 1;
        }
        assert_eq!(status.message_types, counts, "{log}: message types as gpsd decoded them");
        assert!(status.gga_sent >= 1);
        assert_eq!(status.connects, 1);
    }
}

/// A wrong password and a wrong mountpoint end the client with an error that says which, in both versions.
#[test]
fn ntrip_wrong_password_or_mountpoint_is_a_clear_error() {
    let caster = Caster::start();
    let failed = |c: NtripConfig| -> String {
        let handle = spawn(c, Box::new(std::io::sink())).unwrap();
        assert!(wait_until(Duration::from_secs(10), || handle.is_finished()), "the client gives up");
        match handle.stop().state {
            NtripState::Failed { reason } => reason,
            other => panic!("not failed: {other:?}"),
        }
    };
    for version in [NtripVersion::V1, NtripVersion::V2] {
        let mut c = config(&caster, "RTCM32", version);
        c.credentials = Some(Credentials { user: USER.into(), password: "wrong".into() });
        let reason = failed(c);
        assert!(reason.contains("wrong user name or password"), "{version:?}: {reason}");
        assert!(reason.contains(&caster.addr), "names the caster: {reason}");
        let reason = failed(config(&caster, "NOSUCH", version));
        assert!(reason.contains("no mountpoint NOSUCH"), "{version:?}: {reason}");
    }
}

/// A caster that goes silent is detected within the stall time, shown, and reconnected to.
#[test]
fn ntrip_stalled_caster_is_detected_and_reconnected() {
    let caster = Caster::start();
    let mut c = config(&caster, "STALL", NtripVersion::V2);
    c.stall_after = Duration::from_millis(600);
    let handle = spawn(c, Box::new(std::io::sink())).unwrap();
    assert!(wait_until(Duration::from_secs(5), || handle.status().frames == 3));
    assert!(wait_until(Duration::from_secs(5), || handle.status().stalls >= 1), "stall detected");
    let s = handle.status();
    assert!(s.last_error.as_deref().is_some_and(|e| e.contains("stalled")), "{s:?}");
    assert!(s.correction_age(Instant::now()).unwrap() >= Duration::from_millis(600));
    // The backoff's first delay is 1 s: then it connects again.
    assert!(wait_until(Duration::from_secs(5), || *caster.connections.lock().unwrap() >= 2), "reconnected");
    let t = Instant::now();
    let last = handle.stop();
    assert!(t.elapsed() < Duration::from_millis(500), "stop is prompt even mid-stall");
    assert_eq!(last.state, NtripState::Stopped);
}

#[test]
fn ntrip_source_table_both_versions() {
    let caster = Caster::start();
    for version in [NtripVersion::V1, NtripVersion::V2] {
        let table = fetch_sourcetable(&config(&caster, "", version)).unwrap();
        let names: Vec<&str> = table.streams.iter().map(|s| s.mountpoint.as_str()).collect();
        assert_eq!(names, ["RTCM32", "BNDM"], "{version:?}");
        assert!(table.streams[1].nmea);
    }
}

/// The credentials file: refused while others may read it (like ssh), read once it is private; the
/// password may hold a colon.
#[test]
fn ntrip_credentials_file_must_be_private() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempdir("ntrip-cred");
    let path = dir.join("caster.cred");
    std::fs::write(&path, format!("{USER}:{PASSWORD}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    let err = read_credentials(&path).unwrap_err().to_string();
    assert!(err.contains("chmod 600") && err.contains("caster.cred"), "{err}");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    let c = read_credentials(&path).unwrap();
    assert_eq!((c.user.as_str(), c.password.as_str()), (USER, PASSWORD));
    assert!(read_credentials(&dir).is_err(), "a folder is refused");
}

/// The command line end to end over a PTY: `vestnav ntrip` reads the receiver's GGA from the port and sends
/// it upstream, writes the frames into the port, prints its status; with a wrong password it exits with the
/// error.
#[test]
fn ntrip_cli_end_to_end() {
    use std::os::unix::fs::PermissionsExt as _;
    let caster = Caster::start();
    let dir = tempdir("ntrip-cli");
    let cred = dir.join("cred");
    std::fs::write(&cred, format!("{USER}:{PASSWORD}\n")).unwrap();
    std::fs::set_permissions(&cred, std::fs::Permissions::from_mode(0o600)).unwrap();
    let mut pty = vestnav_device::serial::Pty::open().unwrap();
    let expected: Vec<u8> = frames_of(&rtcm_stream("rtcm3.bndm.log")).concat();
    let child = Command::new(bin())
        .args(["ntrip", "--caster", &caster.addr, "--mountpoint", "BNDM", "--ntrip-version", "1"])
        .arg("--credentials")
        .arg(&cred)
        .args(["--port", pty.path(), "--gga-every", "0.5", "--duration-s", "4"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The receiver talks: one GGA a few times a second while the corrections come in.
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(6);
    let mut buf = [0u8; 4096];
    while Instant::now() < deadline && got.len() < expected.len() {
        pty.write_all(format!("{GGA}\r\n").as_bytes()).unwrap();
        if let Ok(n) = pty.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(got == expected, "frames through the CLI: {} of {} bytes", got.len(), expected.len());
    assert!(caster.upstream().iter().any(|l| l == GGA), "the receiver's GGA reached the caster");
    assert!(stdout.contains("connected: age"), "{stdout}");
    assert!(stdout.contains("1006("), "{stdout}");

    std::fs::write(&cred, format!("{USER}:nope\n")).unwrap();
    let out = Command::new(bin())
        .args(["ntrip", "--caster", &caster.addr, "--mountpoint", "BNDM", "--credentials"])
        .arg(&cred)
        .args(["--port", pty.path(), "--duration-s", "10"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("wrong user name or password"), "{err}");
}

/// `$BODY*hh` with its checksum.
fn nmea(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}")
}

/// The receiver's GGA at second `k` with fix quality `q` (4: RTK fixed).
fn gga(k: u32, q: u8) -> String {
    let (m, s) = (35 + k / 60, k % 60);
    nmea(&format!("GPGGA,12{m:02}{s:02}.00,4807.038,N,01131.000,E,{q},12,0.6,545.4,M,46.9,M,1.0,0000"))
}

/// The console's path (issue 27): the station's serial GPS source gives the NTRIP client a write handle on
/// its port, so every verified frame reaches the receiver's PTY byte for byte while the station reads the
/// receiver's NMEA from the same port; the receiver's GGA goes upstream and its quality 4 shows as "RTK
/// fixed" on the status line. Without a serial source the station says why it cannot.
#[test]
fn ntrip_through_the_station_reaches_the_receivers_pty() {
    use std::os::unix::fs::PermissionsExt as _;
    use vestnav_device::gps::SourceState;
    use vestnav_station::hardware::Hardware;
    use vestnav_station::ntrip::NtripSettings;
    use vestnav_station::sources::GpsSourceConfig;
    use vestnav_station::{Station, StationOptions};

    let caster = Caster::start();
    let dir = tempdir("ntrip-station");
    let cred = dir.join("cred");
    std::fs::write(&cred, format!("{USER}:{PASSWORD}\n")).unwrap();
    std::fs::set_permissions(&cred, std::fs::Permissions::from_mode(0o600)).unwrap();
    let mut pty = vestnav_device::serial::Pty::open().unwrap();
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            gps: Some(GpsSourceConfig::Serial { port: pty.path().to_owned(), baud: Some(115_200) }),
            ..StationOptions::default()
        },
    );
    let settings = NtripSettings {
        caster: caster.addr.clone(),
        mountpoint: "RTCM32".into(),
        credentials_file: Some(cred.clone()),
        gga_every_s: 0.3,
        ..NtripSettings::default()
    };
    let refused = station.start_ntrip(settings.clone()).unwrap_err();
    assert!(refused.contains("serial port"), "{refused}");
    station.connect_gps(Vec::new());
    assert!(
        wait_until(Duration::from_secs(5), || {
            station.pump(|_| {});
            matches!(station.gps.state, Some(SourceState::Live { .. }))
        }),
        "GPS source live"
    );
    station.start_ntrip(settings).unwrap();
    let expected: Vec<u8> = frames_of(&rtcm_stream("rtcm3.2.log")).concat();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut k = 0;
    while Instant::now() < deadline
        && (got.len() < expected.len() || !caster.upstream().iter().any(|l| l.contains(",4,12,")))
    {
        pty.write_all(format!("{}\r\n", gga(k, 4)).as_bytes()).unwrap();
        k += 1;
        if let Ok(n) = pty.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
        station.pump(|_| {});
    }
    assert_eq!(got.len(), expected.len(), "bytes at the receiver");
    assert!(got == expected, "the receiver got the frames byte for byte through the station");
    assert!(caster.upstream().iter().any(|l| l.contains(",4,12,")), "the receiver's GGA reached the caster");
    station.pump(|_| {});
    let line = station.ntrip_line(Instant::now()).unwrap();
    assert!(line.starts_with("connected"), "{line}");
    assert!(line.contains("receiver RTK fixed"), "{line}");
    assert!(line.contains("1077("), "{line}");
    station.stop_ntrip();
    assert!(!station.ntrip().unwrap().running());
    // Changing the source ends the corrections, and says why.
    station
        .start_ntrip(NtripSettings {
            credentials_file: Some(cred),
            ..station.ntrip().unwrap().settings.clone()
        })
        .unwrap();
    station.disconnect_gps();
    let c = station.ntrip().unwrap();
    assert!(!c.running() && c.ended.as_deref().is_some_and(|w| w.contains("GPS source")));
}
