//! Stations and an operator through a real Mosquitto (Debian's `mosquitto`, started here on a free
//! 127.0.0.1 port): TLS with a CA, server and client certificates made here with `openssl`, a password file
//! made with `mosquitto_passwd`, and the ACL shipped in `docs/remote/acl`. Each station is the real
//! `vestnav station` binary with its vest on a PTY, served by the WTCU engine (the unit's half of the real
//! protocol); every request frame that reaches a unit is logged with its arrival, so the tests measure what
//! reached the vests, not what was meant.
//!
//! Timings are printed, not asserted, except safety bounds (a STOP that does not reach a vest within a
//! second, a link loss not acted on within its bound plus a margin).

#![cfg(unix)]

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::vest::{Frame, Pattern, TactorMask};
use vestnav_device::wtcu::emulator::{Pty, SERVE_POLL, UnitConfig};
use vestnav_device::wtcu::{CommandKind, FrameCodec, VestCommand, WireCodec as _};
use vestnav_remote::wire::{Envelope, EventKind, Sender, StationTopic, now_ms};
use vestnav_remote::{BrokerConfig, Fleet, FleetOptions};
use vestnav_station::command::Command as StationCommand;

/// The operator-link bound the stations run with (the default).
const LINK_BOUND: Duration = Duration::from_secs(3);

fn run(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{cmd:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn private(path: &Path) {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).unwrap();
}

/// A test CA, the broker's certificate for 127.0.0.1, and one client certificate (every client presents
/// it, and its own user name and password).
fn make_pki(dir: &Path) {
    let ossl = |args: &[&str]| run(Command::new("openssl").args(args).current_dir(dir));
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"];
    ossl(
        &[
            &["req", "-x509"],
            &ec[..],
            &["-keyout", "ca.key", "-out", "ca.crt", "-days", "2", "-subj", "/CN=vestnav test CA"],
        ]
        .concat(),
    );
    for (who, ext) in [
        ("server", "subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth\nbasicConstraints=CA:FALSE\n"),
        ("client", "extendedKeyUsage=clientAuth\nbasicConstraints=CA:FALSE\n"),
    ] {
        std::fs::write(dir.join(format!("{who}.ext")), ext).unwrap();
        ossl(
            &[
                &["req"],
                &ec[..],
                &[
                    "-keyout",
                    &format!("{who}.key"),
                    "-out",
                    &format!("{who}.csr"),
                    "-subj",
                    &format!("/CN=vestnav {who}"),
                ],
            ]
            .concat(),
        );
        ossl(&[
            "x509",
            "-req",
            "-in",
            &format!("{who}.csr"),
            "-CA",
            "ca.crt",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            &format!("{who}.crt"),
            "-days",
            "2",
            "-extfile",
            &format!("{who}.ext"),
        ]);
        private(&dir.join(format!("{who}.key")));
    }
}

/// Users of the test broker (their roles are in the ACL) and their passwords.
const USERS: [&str; 5] = ["operator", "observer", "alpha", "bravo", "charlie"];

/// A Mosquitto on 127.0.0.1 with TLS, client certificates, passwords, the shipped ACL and persistence.
pub(crate) struct Broker {
    dir: PathBuf,
    port: u16,
    child: Option<Child>,
}

impl Broker {
    pub(crate) fn start(dir: &Path) -> Self {
        make_pki(dir);
        let pw = dir.join("passwd");
        for (i, u) in USERS.iter().enumerate() {
            let mut c = Command::new("mosquitto_passwd");
            if i == 0 {
                c.arg("-c");
            }
            run(c.arg("-b").arg(&pw).arg(u).arg(format!("{u}-secret")));
            let f = dir.join(format!("{u}.password"));
            std::fs::write(&f, format!("{u}-secret\n")).unwrap();
            private(&f);
        }
        std::fs::write(dir.join("wrong.password"), "not-the-password\n").unwrap();
        private(&dir.join("wrong.password"));
        let acl = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/remote/acl");
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let d = dir.display();
        let conf = format!(
            "user root\nper_listener_settings false\nallow_anonymous false\npassword_file {d}/passwd\nacl_file {}\n\
             persistence true\npersistence_location {d}/\nautosave_interval 1\nlog_dest file {d}/mosquitto.log\nlog_type all\n\
             listener {port} 127.0.0.1\ncafile {d}/ca.crt\ncertfile {d}/server.crt\nkeyfile {d}/server.key\n\
             require_certificate true\n",
            acl.display()
        );
        std::fs::write(dir.join("mosquitto.conf"), conf).unwrap();
        let mut b = Self { dir: dir.to_owned(), port, child: None };
        b.spawn();
        b
    }

    fn spawn(&mut self) {
        let child = Command::new("mosquitto")
            .arg("-c")
            .arg(self.dir.join("mosquitto.conf"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("mosquitto (Debian package mosquitto) must be installed");
        self.child = Some(child);
        let until = Instant::now() + Duration::from_secs(10);
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(Instant::now() < until, "mosquitto did not listen: {}", self.log());
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGKILL: the broker gone without a word.
    fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("mosquitto.log")).unwrap_or_default()
    }

    pub(crate) fn client(&self, user: &str) -> BrokerConfig {
        BrokerConfig {
            url: format!("mqtts://127.0.0.1:{}", self.port),
            ca: Some(self.dir.join("ca.crt")),
            user: Some(user.to_owned()),
            password_file: Some(self.dir.join(format!("{user}.password"))),
            cert: Some(self.dir.join("client.crt")),
            key: Some(self.dir.join("client.key")),
            insecure_plaintext_loopback: false,
        }
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.kill();
    }
}

/// A WTCU on the master of a PTY pair, logging every request frame that reached it, with its arrival.
pub(crate) struct Unit {
    pub(crate) path: String,
    received: Arc<Mutex<Vec<(Instant, CommandKind)>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Unit {
    pub(crate) fn spawn() -> Self {
        let Pty { mut master, path, slave } = Pty::open_with_timeout(SERVE_POLL).unwrap();
        let received = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (r, s) = (received.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let _slave = slave;
            let mut engine = UnitConfig::default().build();
            let mut requests = FrameCodec::new();
            let mut buf = [0u8; 1024];
            while !s.load(Ordering::Relaxed) {
                match master.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        let now = Instant::now();
                        let mut out = Vec::new();
                        requests.decode_requests(&buf[..n], &mut out);
                        r.lock().unwrap().extend(out.into_iter().flatten().map(|p| (now, p.message.kind())));
                        engine.handle_bytes(&buf[..n], now);
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                        ) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
                engine.handle_timeout(Instant::now());
                while let Some(frame) = engine.poll_transmit() {
                    let _ = master.write_all(&frame);
                }
                while engine.poll_event().is_some() {}
            }
        });
        Self { path, received, stop, thread: Some(thread) }
    }

    /// When frames of `kind` arrived after `since`.
    pub(crate) fn received_after(&self, kind: CommandKind, since: Instant) -> Vec<Instant> {
        let r = self.received.lock().unwrap();
        r.iter().filter(|(t, k)| *k == kind && *t >= since).map(|(t, _)| *t).collect()
    }
}

impl Drop for Unit {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A `vestnav station` process with its unit, its standard error kept line by line.
pub(crate) struct StationProc {
    name: &'static str,
    child: Child,
    lines: Arc<Mutex<Vec<(Instant, String)>>>,
    pub(crate) unit: Unit,
}

impl StationProc {
    pub(crate) fn spawn(broker: &Broker, name: &'static str) -> Self {
        let unit = Unit::spawn();
        let c = broker.client(name);
        let mut child = Command::new(env!("CARGO_BIN_EXE_vestnav"))
            .args(["station", "--name", name, "--gps", "sim", "--status-every", "0"])
            .arg("--vest")
            .arg(format!("serial:{}", unit.path))
            .arg("--broker")
            .arg(&c.url)
            .arg("--ca")
            .arg(c.ca.unwrap())
            .args(["--user", name])
            .arg("--password-file")
            .arg(c.password_file.unwrap())
            .arg("--cert")
            .arg(c.cert.unwrap())
            .arg("--key")
            .arg(c.key.unwrap())
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let lines = Arc::new(Mutex::new(Vec::new()));
        let (l, err) = (lines.clone(), child.stderr.take().unwrap());
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines() {
                let Ok(line) = line else { break };
                l.lock().unwrap().push((Instant::now(), line));
            }
        });
        Self { name, child, lines, unit }
    }

    /// The first line containing `text` said after `since`.
    fn said_after(&self, text: &str, since: Instant) -> Option<(Instant, String)> {
        self.lines.lock().unwrap().iter().find(|(t, l)| *t >= since && l.contains(text)).cloned()
    }

    pub(crate) fn quit(mut self) {
        if let Some(i) = self.child.stdin.as_mut() {
            let _ = i.write_all(b"quit\n");
        }
        let until = Instant::now() + Duration::from_secs(5);
        while self.child.try_wait().unwrap().is_none() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub(crate) fn wait_for(what: &str, timeout: Duration, mut ok: impl FnMut() -> bool) {
    let until = Instant::now() + timeout;
    while !ok() {
        assert!(Instant::now() < until, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Clicks the `nth` widget labelled `label` as a hand does: the pointer arrives (a frame), then presses.
/// A click in the same frame as the move lands on whatever covered the spot a frame before, such as the
/// tooltip of the button clicked last, which a real pointer closes by leaving that button.
pub(crate) fn click<S>(h: &mut egui_kittest::Harness<'_, S>, label: &str, nth: usize) {
    use egui_kittest::kittest::Queryable as _;
    h.get_all_by_label(label).nth(nth).unwrap().hover();
    h.run_steps(1);
    h.get_all_by_label(label).nth(nth).unwrap().click();
}

/// Turns a window until a label containing `text` shows, for at most 5 s (`what` names the failure).
pub(crate) fn run_until_shown<S>(h: &mut egui_kittest::Harness<'_, S>, text: &str, what: &str) {
    use egui_kittest::kittest::Queryable as _;
    let until = Instant::now() + Duration::from_secs(5);
    while h.query_by_label_contains(text).is_none() {
        assert!(Instant::now() < until, "{what}");
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

pub(crate) fn in_contact(fleet: &Fleet, name: &str) -> bool {
    fleet.station(name).is_some_and(|s| {
        s.state.as_ref().is_some_and(|st| {
            st.link.operator_contact
                && st.station.vest_link == Some(vestnav_device::wtcu::LinkState::Ready)
                && s.contact_age(Instant::now()).is_some_and(|a| a < Duration::from_secs(1))
        })
    })
}

pub(crate) fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-remote-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Three stations: STOP ALL to all three vests (p50/p99), fix-to-screen, the broker killed (each station
/// stops its vest within its bound and says so, the operator shows "no contact"), the broker back
/// (reconnection, the retained STOP honoured, no stale cue).
#[test]
#[allow(clippy::too_many_lines)]
fn three_stations_stop_all_link_loss_and_broker_restart() {
    let _t = crate::timing_exclusive();
    let dir = temp_dir("three");
    let mut broker = Broker::start(&dir);
    let names = ["alpha", "bravo", "charlie"];
    let stations: Vec<StationProc> = names.iter().map(|n| StationProc::spawn(&broker, n)).collect();
    let fleet = Fleet::connect(&broker.client("operator"), FleetOptions::operator("operator")).unwrap();
    for n in names {
        wait_for(&format!("{n} in contact with a ready vest"), Duration::from_secs(30), || {
            in_contact(&fleet, n)
        });
    }

    // The console's own STOP ALL (key, button) reaches every remote station too.
    let mut console = vestnav_app::console::Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_app::console::ConsoleOptions::default(),
    );
    console.remote = Some(
        vestnav_app::remote_panel::RemotePanel::connect(
            &broker.client("operator"),
            "operator",
            vestnav_station::stop::StopPath::default(),
        )
        .unwrap(),
    );
    wait_for("the console's broker connection", Duration::from_secs(10), || {
        console.remote.as_ref().is_some_and(|r| r.fleet().is_some_and(|f| f.broker_status().0))
    });
    let t0 = Instant::now();
    console.stop_all();
    for s in &stations {
        wait_for(&format!("the console's STOP ALL at {}'s vest", s.name), Duration::from_secs(1), || {
            !s.unit.received_after(CommandKind::StopAll, t0).is_empty()
        });
    }
    console.shutdown();
    drop(console);

    // STOP ALL from the operator to the three vests, many times.
    let mut lat_ms = Vec::new();
    for _ in 0..40 {
        let t0 = Instant::now();
        fleet.stop_all().unwrap();
        for s in &stations {
            wait_for(&format!("STOP ALL at {}'s vest within 1 s", s.name), Duration::from_secs(1), || {
                !s.unit.received_after(CommandKind::StopAll, t0).is_empty()
            });
            let t = s.unit.received_after(CommandKind::StopAll, t0)[0];
            lat_ms.push(t.duration_since(t0).as_secs_f64() * 1000.0);
        }
        std::thread::sleep(Duration::from_millis(30));
    }
    lat_ms.sort_by(f64::total_cmp);
    eprintln!(
        "STOP ALL operator -> broker (TLS) -> 3 stations -> vests: n={} p50={:.1} ms p99={:.1} ms max={:.1} ms",
        lat_ms.len(),
        percentile(&lat_ms, 0.5),
        percentile(&lat_ms, 0.99),
        lat_ms[lat_ms.len() - 1]
    );

    // Fix on the station to the operator's copy of its state (one clock: same machine).
    let mut screen_ms = Vec::new();
    let mut seen = std::collections::HashMap::new();
    let until = Instant::now() + Duration::from_secs(6);
    while Instant::now() < until {
        for n in names {
            let Some(v) = fleet.station(n) else { continue };
            let (Some(st), Some(arrived)) = (v.state, v.state_arrived_ms) else { continue };
            // Each new fix once: the first state that carries it.
            let fix_time = st.station.fix.as_ref().and_then(|f| f.time);
            if fix_time.is_some()
                && seen.insert(n, fix_time) != Some(fix_time)
                && let Some(age) = st.station.fix_age_s
            {
                screen_ms.push(arrived as f64 - (st.at_ms as f64 - age * 1000.0));
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    screen_ms.sort_by(f64::total_cmp);
    assert!(screen_ms.len() > 10, "states with fixes arrived: {}", screen_ms.len());
    eprintln!(
        "fix on station -> operator's state: n={} p50={:.0} ms p99={:.0} ms (a state waits up to 100 ms after the last)",
        screen_ms.len(),
        percentile(&screen_ms, 0.5),
        percentile(&screen_ms, 0.99)
    );

    // Alpha and bravo resumed (guidance on); charlie stays under the retained STOP ALL.
    fleet.resume("alpha").unwrap();
    fleet.resume("bravo").unwrap();
    for n in ["alpha", "bravo"] {
        wait_for(&format!("{n} resumed"), Duration::from_secs(5), || {
            fleet.station(n).and_then(|s| s.state).is_some_and(|s| s.station.auto && !s.link.stop_in_force)
        });
    }
    let charlie = fleet.station("charlie").and_then(|s| s.state).unwrap();
    assert!(charlie.link.stop_in_force && !charlie.station.auto, "charlie still stopped");
    // The broker writes its retained messages every second.
    std::thread::sleep(Duration::from_millis(2500));

    // The broker killed: every station stops its vest within its bound and says so.
    let t_kill = Instant::now();
    broker.kill();
    for s in &stations {
        let bound = LINK_BOUND + Duration::from_millis(1500);
        wait_for(&format!("{} to say its operator link is lost", s.name), bound, || {
            s.said_after("OPERATOR LINK LOST", t_kill).is_some()
        });
        let (said_at, line) = s.said_after("OPERATOR LINK LOST", t_kill).unwrap();
        assert!(line.contains("vest stopped"), "{line}");
        let stop = s.unit.received_after(CommandKind::StopAll, t_kill);
        assert!(!stop.is_empty(), "{}: no STOP ALL reached the vest after the broker died", s.name);
        let t = stop[0].duration_since(t_kill);
        assert!(t <= bound, "{}: STOP ALL {t:?} after the broker died", s.name);
        eprintln!(
            "{}: broker killed -> vest stopped after {:.2} s, said after {:.2} s: {line}",
            s.name,
            t.as_secs_f64(),
            said_at.duration_since(t_kill).as_secs_f64()
        );
    }
    wait_for("the operator to show no contact", Duration::from_secs(3), || {
        names.iter().all(|n| {
            fleet.station(n).is_some_and(|v| {
                v.contact_label(Instant::now(), fleet.options().stale_after).starts_with("no contact")
            })
        })
    });
    let label = fleet.station("alpha").unwrap().contact_label(Instant::now(), fleet.options().stale_after);
    eprintln!("operator shows alpha: {label}; broker: {:?}", fleet.broker_status());
    assert!(!fleet.broker_status().0);

    // The broker back: reconnection, the retained STOP ALL honoured by charlie, no cue played by anyone.
    let t_back = Instant::now();
    broker.spawn();
    for n in names {
        wait_for(&format!("{n} back in contact"), Duration::from_secs(20), || in_contact(&fleet, n));
    }
    eprintln!("all three back in contact {:.2} s after the broker restarted", t_back.elapsed().as_secs_f64());
    let c = &stations[2];
    wait_for("charlie to obey the retained STOP ALL again", Duration::from_secs(2), || {
        !c.unit.received_after(CommandKind::StopAll, t_back).is_empty()
    });
    std::thread::sleep(Duration::from_secs(2));
    for s in &stations {
        let st = fleet.station(s.name).and_then(|v| v.state).unwrap();
        assert!(!st.station.auto, "{}: automatic cues stay off after the link loss", s.name);
        assert!(st.link.on_loss.as_deref().is_some_and(|t| t.contains("vest stopped")), "{:?}", st.link);
        for kind in [CommandKind::Play, CommandKind::Fire] {
            let late = s.unit.received_after(kind, t_kill);
            assert!(late.is_empty(), "{}: {} cue(s) played after the link loss", s.name, late.len());
        }
    }
    assert!(fleet.station("charlie").and_then(|v| v.state).unwrap().link.stop_in_force);
    // An operator's resume brings alpha's automatic cues back.
    fleet.resume("alpha").unwrap();
    wait_for("alpha resumed after the restart", Duration::from_secs(5), || {
        fleet.station("alpha").and_then(|s| s.state).is_some_and(|s| s.station.auto)
    });
    for s in stations {
        s.quit();
    }
    drop(fleet);
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A raw MQTT client with `user`'s credentials (to send what the fleet client never would).
fn raw_client(broker: &Broker, user: &str) -> (rumqttc::Client, JoinHandle<()>, Arc<Mutex<Vec<String>>>) {
    let o = broker.client(user).mqtt_options(&format!("raw-{user}-{}", now_ms()), None).unwrap();
    let (client, mut conn) = rumqttc::Client::new(o, 64);
    let got = Arc::new(Mutex::new(Vec::new()));
    let g = got.clone();
    let t = std::thread::spawn(move || {
        for ev in conn.iter() {
            match ev {
                Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                    g.lock().unwrap().push(p.topic.clone());
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
    });
    (client, t, got)
}

fn envelope(to: &str, from: &Sender, seq: u64, sent_ms: i64) -> Vec<u8> {
    let command = StationCommand::Manual {
        command: VestCommand::Fire { mask: TactorMask::from_indices([3]), duration_ms: 100 },
        cue: None,
    };
    serde_json::to_vec(&Envelope { to: to.to_owned(), from: from.clone(), seq, sent_ms, command }).unwrap()
}

/// The TCP sockets process `pid` listens on (from /proc: its socket inodes, the kernel's tables).
fn tcp_listening(pid: u32) -> Vec<String> {
    let inodes: std::collections::HashSet<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter_map(|e| std::fs::read_link(e.ok()?.path()).ok())
        .filter_map(|l| Some(l.to_str()?.strip_prefix("socket:[")?.strip_suffix(']')?.to_owned()))
        .collect();
    assert!(!inodes.is_empty(), "the station has its broker connection open");
    let mut found = Vec::new();
    for table in ["tcp", "tcp6"] {
        let text = std::fs::read_to_string(format!("/proc/{pid}/net/{table}")).unwrap_or_default();
        for line in text.lines().skip(1) {
            let cols: Vec<&str> = line.split_whitespace().collect();
            // Column 4 is the state (0A: LISTEN), column 10 the socket's inode.
            if cols.len() > 9 && cols[3] == "0A" && inodes.contains(cols[9]) {
                found.push(format!("{table}: {line}"));
            }
        }
    }
    found
}

fn refused_with(fleet: &Fleet, name: &str, text: &str) -> bool {
    fleet
        .station(name)
        .is_some_and(|v| v.events.iter().any(|(_, e)| e.kind == EventKind::Refused && e.text.contains(text)))
}

/// A route with a path sent by an operator through a real Mosquitto: the `vestnav station` process guides
/// along the path and its route topic carries the path back; a path over the broker's limit is refused by
/// the operator's side before sending and, sent raw, by the station, which keeps its route.
///
/// The path is bent around the wearer `W` (as the station's own state reports it): from `A`, 1 km north of
/// `W`, 1 km east, 2 km south, 1 km west to `B`, 1 km south of `W`. The straight leg A→B passes through
/// `W` (cross-track about 0); the path is about 1 km away from `W` everywhere (A, the eastern side and B
/// are all 1 km off).
#[test]
fn a_route_with_a_path_reaches_a_remote_station_and_an_oversized_one_is_refused() {
    use vestnav_core::geo::{Earth, LatLon};
    use vestnav_core::guidance::RoutePath;
    use vestnav_remote::wire::MAX_WIRE_PATH_POINTS;
    use vestnav_station::route::Waypoint;

    let dir = temp_dir("path");
    let broker = Broker::start(&dir);
    let alpha = StationProc::spawn(&broker, "alpha");
    let fleet = Fleet::connect(&broker.client("operator"), FleetOptions::operator("operator")).unwrap();
    wait_for("alpha in contact", Duration::from_secs(30), || in_contact(&fleet, "alpha"));
    let fix = || {
        let st = fleet.station("alpha")?.state?;
        let f = st.station.fix?;
        Some(LatLon::new(f.lat_deg?, f.lon_deg?))
    };
    wait_for("alpha's position", Duration::from_secs(10), || fix().is_some());
    let w = fix().unwrap();
    let e = Earth::Wgs84;
    let (a, b) = (e.direct(w, 0.0, 1000.0), e.direct(w, 180.0, 1000.0));
    let pts = vec![a, e.direct(a, 90.0, 1000.0), e.direct(b, 90.0, 1000.0), b];
    let path = RoutePath::new(pts, vec![0, 3]).unwrap();
    let waypoints = vec![Waypoint::at("A", a), Waypoint::at("B", b)];
    let route = |path: RoutePath| StationCommand::SetRoute {
        name: "bent".into(),
        waypoints: waypoints.clone(),
        next: 1,
        path: Some(path),
    };
    fleet.send("alpha", route(path.clone())).unwrap();
    wait_for("the route with its path back on alpha's route topic", Duration::from_secs(5), || {
        fleet.station("alpha").and_then(|v| v.route).is_some_and(|r| r.path.as_ref() == Some(&path))
    });
    let revision = fleet.station("alpha").and_then(|v| v.route).unwrap().revision;
    assert_eq!(fleet.station("alpha").and_then(|v| v.route).unwrap().path_points, 4);
    // Guidance at the station measures the cross-track from the path, not from the straight leg.
    let mut cross_track_m = None;
    wait_for("guidance along the new route", Duration::from_secs(10), || {
        let g = fleet.station("alpha").and_then(|v| v.state).and_then(|s| s.station.guidance);
        cross_track_m =
            g.filter(|g| g.route_revision == revision && g.next == 1).and_then(|g| g.cross_track_m);
        cross_track_m.is_some()
    });
    let xt = cross_track_m.unwrap().abs();
    assert!((950.0..1050.0).contains(&xt), "cross-track {xt} m: not measured from the path");

    // One point over the limit: refused by the operator's side, nothing sent.
    let long: Vec<LatLon> = (0..=MAX_WIRE_PATH_POINTS)
        .map(|i| e.direct(a, 180.0, 2000.0 * i as f64 / MAX_WIRE_PATH_POINTS as f64))
        .collect();
    let too_long = RoutePath::new(long, vec![0, MAX_WIRE_PATH_POINTS]).unwrap();
    let err = fleet.send("alpha", route(too_long.clone())).unwrap_err().to_string();
    assert!(
        err.contains(&format!("its path has {} points, more than the 40000", MAX_WIRE_PATH_POINTS + 1)),
        "{err}"
    );
    // Sent raw (as another tool might): the station refuses it with the same words and keeps its route.
    let (raw, _rt, _) = raw_client(&broker, "operator");
    let me = Sender { operator: "operator".into(), session: 99 };
    let env = Envelope { to: "alpha".into(), from: me, seq: 1, sent_ms: now_ms(), command: route(too_long) };
    let bytes = serde_json::to_vec(&env).unwrap();
    assert!(bytes.len() < vestnav_remote::wire::MAX_PAYLOAD, "{} bytes", bytes.len());
    raw.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, bytes).unwrap();
    wait_for("the oversized path refused by the station", Duration::from_secs(5), || {
        refused_with(&fleet, "alpha", "more than the 40000 a route over the broker may carry")
    });
    let r = fleet.station("alpha").and_then(|v| v.route).unwrap();
    assert_eq!((r.revision, r.path.as_ref()), (revision, Some(&path)));
    alpha.quit();
    drop(fleet);
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}

/// What is refused: a wrong password, a plaintext client, an observer's command, a station commanding
/// another (by the ACL and by the station), a late FIRE; a repeated command plays once.
#[test]
#[allow(clippy::too_many_lines)]
fn refusals_through_a_real_mosquitto() {
    let dir = temp_dir("refusals");
    let broker = Broker::start(&dir);
    let alpha = StationProc::spawn(&broker, "alpha");
    let fleet = Fleet::connect(&broker.client("operator"), FleetOptions::operator("operator")).unwrap();
    wait_for("alpha in contact", Duration::from_secs(30), || in_contact(&fleet, "alpha"));

    // A wrong password and a plaintext client never connect.
    let mut wrong = broker.client("operator");
    wrong.password_file = Some(dir.join("wrong.password"));
    let w = Fleet::connect(&wrong, FleetOptions::operator("operator")).unwrap();
    let plain = BrokerConfig {
        url: format!("mqtt://127.0.0.1:{}", broker.port),
        user: Some("operator".into()),
        password_file: Some(dir.join("operator.password")),
        insecure_plaintext_loopback: true,
        ..BrokerConfig::default()
    };
    let p = Fleet::connect(&plain, FleetOptions::operator("operator")).unwrap();
    wait_for("both refused", Duration::from_secs(10), || {
        w.broker_status().1.is_some() && p.broker_status().1.is_some()
    });
    std::thread::sleep(Duration::from_millis(500));
    let (wc, we) = w.broker_status();
    let (pc, pe) = p.broker_status();
    assert!(!wc && we.as_deref().is_some_and(|e| e.contains("refused")), "wrong password: {we:?}");
    assert!(!pc, "plaintext client connected: {pe:?}");
    eprintln!("wrong password: {}; plaintext: {}", we.unwrap_or_default(), pe.unwrap_or_default());
    drop((w, p));

    // The operator's FIRE plays (the control for everything refused below).
    let t0 = Instant::now();
    fleet
        .send(
            "alpha",
            StationCommand::Manual {
                command: VestCommand::Fire { mask: TactorMask::from_indices([3]), duration_ms: 100 },
                cue: None,
            },
        )
        .unwrap();
    wait_for("the operator's FIRE at the vest", Duration::from_secs(2), || {
        alpha.unit.received_after(CommandKind::Fire, t0).len() == 1
    });

    // A repeated command (as QoS 1 may redeliver it) plays once; a late one never.
    let (raw, _rt, _) = raw_client(&broker, "operator");
    let me = Sender { operator: "operator".into(), session: 7 };
    let t1 = Instant::now();
    let once = envelope("alpha", &me, 1, now_ms());
    raw.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, once.clone()).unwrap();
    raw.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, once).unwrap();
    let late = envelope("alpha", &me, 2, now_ms() - 5000);
    raw.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, late).unwrap();
    // Addressed to bravo but on alpha's topic: refused by the station itself.
    let misrouted = envelope("bravo", &me, 3, now_ms());
    raw.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, misrouted).unwrap();
    wait_for("the late FIRE refused", Duration::from_secs(3), || {
        refused_with(&fleet, "alpha", "late, not played")
    });
    wait_for("the misrouted FIRE refused", Duration::from_secs(3), || {
        refused_with(&fleet, "alpha", "for station \"bravo\"")
    });
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(
        alpha.unit.received_after(CommandKind::Fire, t1).len(),
        1,
        "the repeat played once, the late and misrouted never"
    );

    // An observer's command and STOP ALL, and station bravo's command to alpha: dropped by the broker.
    let observer = Fleet::connect(
        &broker.client("observer"),
        FleetOptions { heartbeats: false, ..FleetOptions::operator("observer") },
    )
    .unwrap();
    wait_for("observer connected", Duration::from_secs(5), || observer.broker_status().0);
    let (bravo, _bt, _) = raw_client(&broker, "bravo");
    let (spy, _st, spied) = raw_client(&broker, "operator");
    spy.subscribe(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let t2 = Instant::now();
    observer
        .send(
            "alpha",
            StationCommand::Manual {
                command: VestCommand::Fire { mask: TactorMask::from_indices([5]), duration_ms: 100 },
                cue: None,
            },
        )
        .unwrap();
    let _ = observer.stop_all();
    let from_bravo = envelope("alpha", &Sender { operator: "bravo".into(), session: 1 }, 1, now_ms());
    bravo.publish(StationTopic::Cmd.of("alpha"), rumqttc::QoS::AtLeastOnce, false, from_bravo).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    assert!(
        alpha.unit.received_after(CommandKind::Fire, t2).is_empty(),
        "a command from an observer or a station played"
    );
    assert!(
        alpha.unit.received_after(CommandKind::StopAll, t2).is_empty(),
        "an observer's STOP ALL reached the vest"
    );
    assert!(spied.lock().unwrap().is_empty(), "the broker passed on a command from an observer or a station");
    assert!(broker.log().contains("Denied PUBLISH"), "the broker logged no denial:\n{}", broker.log());
    // The station connects out and listens on no port.
    let control = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    assert!(!tcp_listening(std::process::id()).is_empty(), "the check sees this test's own listener");
    drop(control);
    let listening = tcp_listening(alpha.child.id());
    assert!(listening.is_empty(), "the station listens: {listening:?}");
    alpha.quit();
    drop(fleet);
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The Stations window in a window harness against a real broker and two stations: the operator picks
/// alpha to drive and fires a tactor on its grid; the FIRE reaches alpha's vest on its PTY and not bravo's,
/// the window shows alpha's answer, and both wearers are handed to the map with their positions.
#[test]
fn driving_one_station_from_the_window_reaches_its_vest_only() {
    use egui_kittest::kittest::Queryable as _;
    let _t = crate::timing_exclusive();
    let dir = temp_dir("drive");
    let broker = Broker::start(&dir);
    let stations: Vec<StationProc> =
        ["alpha", "bravo"].iter().map(|n| StationProc::spawn(&broker, n)).collect();
    let panel = vestnav_app::remote_panel::RemotePanel::connect(
        &broker.client("operator"),
        "operator",
        vestnav_station::stop::StopPath::default(),
    )
    .unwrap();
    for n in ["alpha", "bravo"] {
        wait_for(&format!("{n} in contact with a ready vest"), Duration::from_secs(30), || {
            in_contact(panel.fleet().unwrap(), n)
        });
    }
    let local = vestnav_station::Station::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_station::StationOptions::default(),
    );
    // An operator's saved pattern (Vest panel), played on the driven station.
    let sweep = Pattern {
        name: "sweep".into(),
        frames: vec![
            Frame { mask: TactorMask::row(0), duration_ms: 100 },
            Frame { mask: TactorMask::row(3), duration_ms: 100 },
        ],
        repeats: 1,
    };
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(1400.0, 900.0)).build_ui_state(
        |ui,
         (p, local, patterns): &mut (
            vestnav_app::remote_panel::RemotePanel,
            vestnav_station::Station,
            Vec<Pattern>,
        )| {
            p.ui(ui.ctx(), local, patterns);
        },
        (panel, local, vec![sweep]),
    );
    h.run_steps(2);
    // Rows are in name order: the first Drive is alpha's.
    click(&mut h, "Drive", 0);
    h.run_steps(2);
    assert!(h.query_by_label_contains("Driving alpha").is_some());
    let t0 = Instant::now();
    click(&mut h, "T5", 0);
    h.run_steps(2);
    let (alpha, bravo) = (&stations[0].unit, &stations[1].unit);
    wait_for("the FIRE at alpha's vest", Duration::from_secs(2), || {
        !alpha.received_after(CommandKind::Fire, t0).is_empty()
    });
    run_until_shown(&mut h, "applied", "alpha's answer shown in the window");
    click(&mut h, "Play sweep", 0);
    h.run_steps(1);
    wait_for("the pattern at alpha's vest", Duration::from_secs(2), || {
        !alpha.received_after(CommandKind::Play, t0).is_empty()
    });
    std::thread::sleep(Duration::from_millis(300));
    assert!(bravo.received_after(CommandKind::Fire, t0).is_empty(), "bravo's vest got no FIRE");
    assert!(bravo.received_after(CommandKind::Play, t0).is_empty(), "bravo's vest got no pattern");
    // A refusal is shown with the station's reason: alpha stopped, then a resume of its cues.
    click(&mut h, "Stop", 0);
    h.run_steps(1);
    wait_for("alpha's STOP in force", Duration::from_secs(5), || {
        h.state()
            .0
            .fleet()
            .unwrap()
            .station("alpha")
            .and_then(|s| s.state)
            .is_some_and(|s| s.link.stop_in_force)
    });
    click(&mut h, "Resume automatic cues", 0);
    let until = Instant::now() + Duration::from_secs(5);
    while h.query_by_label_contains("resume refused: a STOP is in force").is_none() {
        assert!(Instant::now() < until, "alpha's refusal shown in the window");
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }

    // The wearers for the map: each station's simulated GPS position, in contact, with a track.
    wait_for("tracks of two fixes or more", Duration::from_secs(10), || {
        h.state().0.wearers(10.0).iter().all(|w| w.track.len() >= 2)
    });
    let wearers = h.state().0.wearers(10.0);
    assert_eq!(wearers.iter().map(|w| w.name.as_str()).collect::<Vec<_>>(), ["alpha", "bravo"]);
    for w in &wearers {
        let state = h.state().0.fleet().unwrap().station(&w.name).and_then(|s| s.state).unwrap();
        let fix = state.station.fix.unwrap();
        let (lat, lon) = w.position.unwrap();
        // The position drawn is the one the station last published (the next state may have moved on).
        assert!((lat - fix.lat_deg.unwrap()).abs() < 1e-3 && (lon - fix.lon_deg.unwrap()).abs() < 1e-3);
        assert!(!w.stale, "{} is live: {}", w.name, w.label);
    }
    drop(h);

    console_map_wearers(&broker, stations);
}

/// The console's map is handed the wearers of `stations` (alpha, bravo) each frame; bravo's, once its
/// station ends, turns stale.
fn console_map_wearers(broker: &Broker, stations: Vec<StationProc>) {
    let cfg = vestnav_app::config::Config { map_tiles: false, ..vestnav_app::config::Config::default() };
    let mut console = vestnav_app::console::Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_app::console::ConsoleOptions { cfg, ..vestnav_app::console::ConsoleOptions::default() },
    );
    console.tab = vestnav_app::console::Tab::Map;
    console.remote = Some(
        vestnav_app::remote_panel::RemotePanel::connect(
            &broker.client("operator"),
            "operator",
            vestnav_station::stop::StopPath::default(),
        )
        .unwrap(),
    );
    wait_for("the console's copy of both stations", Duration::from_secs(10), || {
        console
            .remote
            .as_ref()
            .is_some_and(|r| r.wearers(10.0).iter().filter(|w| w.position.is_some()).count() == 2)
    });
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 880.0))
        .build_ui_state(|ui, c: &mut vestnav_app::console::Console| c.ui(ui), console);
    h.run_steps(3);
    let names: Vec<String> = h.state().map.remote_wearers.iter().map(|w| w.name.clone()).collect();
    assert_eq!(names, ["alpha", "bravo"]);
    // A retained state replayed by the broker is not contact: both are live once each has spoken since.
    let until = Instant::now() + Duration::from_secs(5);
    while h.state().map.remote_wearers.iter().any(|w| w.stale) {
        assert!(Instant::now() < until, "both wearers live: {:?}", h.state().map.remote_wearers);
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    // Bravo's station ends: its wearer turns stale (hollow, grey, "last known") and alpha's stays live.
    let mut stations = stations;
    stations.pop().unwrap().quit();
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        h.run_steps(1);
        let w = &h.state().map.remote_wearers;
        if w.len() == 2 && w[1].stale {
            assert!(!w[0].stale, "alpha is live: {}", w[0].label);
            assert!(w[1].position.is_some(), "bravo's last position is still drawn");
            break;
        }
        assert!(Instant::now() < until, "bravo's wearer drawn as stale");
        std::thread::sleep(Duration::from_millis(50));
    }
    h.state_mut().shutdown();
    drop(h);
    for s in stations {
        s.quit();
    }
}
