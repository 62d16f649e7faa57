//! `vestnav doctor`: the set-up checks that fail in the field outside the program — serial-port permissions,
//! Bluetooth (`BlueZ` running, paired and bound SPP devices), the window system and OpenGL libraries the
//! console loads at run time, writable folders with free space, and optional parts (gpsd, liblsl, a
//! broker). Each check ends in a [`Finding`]: a plain verdict, what was seen, and the fix.
//!
//! Everything the checks look at comes through an [`Environment`]: a file-system root (`/` for the real
//! machine, a temporary folder holding `dev/`, `etc/group`, `proc/`, `sys/`, `usr/lib/`… in the tests), the
//! identity of the process (user, groups of this session) and its environment variables. Nothing here
//! opens a device, loads a library or starts a program; reads are bounded ([`MAX_SMALL_FILE`]), and the
//! only network access is the broker's TCP connect with a 1 s timeout.
//!
//! The console calls [`port_findings`] when a port fails to open, so the operator sees the same verdicts
//! `vestnav doctor` prints.
//!
//! ```
//! use vestnav_device::doctor::{self, Environment, Verdict};
//! let env = Environment::system();
//! let findings = doctor::port_findings(&env, "/dev/vestnav-no-such-port");
//! assert_eq!(findings[0].verdict, Verdict::Problem);
//! ```

use std::collections::BTreeMap;
use std::io::Read as _;
use std::net::{TcpStream, ToSocketAddrs as _};
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

use serde::Serialize;

/// The longest file a check reads (`/etc/group`, a `BlueZ` `info` file, `/proc/N/comm`) [bytes].
pub const MAX_SMALL_FILE: u64 = 1 << 20;
/// How long the broker check waits for a TCP connection.
pub const BROKER_TIMEOUT: Duration = Duration::from_secs(1);
/// The most directory entries one check lists (`/dev`, `/proc`): bounded time on any machine.
const MAX_DIR_ENTRIES: usize = 100_000;
/// The Serial Port Profile's service UUID, as `BlueZ` writes it in a device's `Services=` list.
const SPP_UUID: &str = "00001101-0000-1000-8000-00805f9b34fb";

/// How a check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Fine.
    Ok,
    /// Only matters for an optional part, or nothing to check (no port plugged in).
    Info,
    /// Works now but may fail (little free space, a library only one session type needs).
    Warning,
    /// Will fail: fix it before a session.
    Problem,
}

impl Verdict {
    /// The word printed in front of a finding.
    pub fn label(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Info => "info",
            Self::Warning => "warning",
            Self::Problem => "PROBLEM",
        }
    }
}

/// Which part of the set-up a finding is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Area {
    /// Serial ports (USB adapters, Bluetooth SPP bindings) and the user's permission to open them.
    SerialPorts,
    /// The `BlueZ` service, adapters, paired and bound SPP devices.
    Bluetooth,
    /// The display session and the OpenGL / window-system libraries of the console.
    Display,
    /// The config, data and tile-cache folders.
    Folders,
    /// gpsd, liblsl, a broker.
    Optional,
}

/// One check's outcome.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Finding {
    /// The part of the set-up.
    pub area: Area,
    /// What was checked, short ("/dev/ttyUSB0", "bluetoothd", "libEGL.so.1", "data folder").
    pub check: String,
    /// How it came out.
    pub verdict: Verdict,
    /// What was seen, in a sentence.
    pub detail: String,
    /// What to do about it, when there is something to do.
    pub fix: Option<String>,
}

impl Finding {
    fn new(area: Area, check: impl Into<String>, verdict: Verdict, detail: impl Into<String>) -> Self {
        Self { area, check: check.into(), verdict, detail: detail.into(), fix: None }
    }

    fn fix(mut self, fix: impl Into<String>) -> Self {
        self.fix = Some(fix.into());
        self
    }
}

/// Every finding of one run, in check order.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Report {
    /// The findings, area by area.
    pub findings: Vec<Finding>,
}

impl Report {
    /// The worst verdict (`Ok` for an empty report).
    pub fn worst(&self) -> Verdict {
        self.findings.iter().map(|f| f.verdict).max().unwrap_or(Verdict::Ok)
    }

    /// How many findings have `verdict`.
    pub fn count(&self, verdict: Verdict) -> usize {
        self.findings.iter().filter(|f| f.verdict == verdict).count()
    }
}

/// Who the checks run as: what decides whether a device node or a folder may be opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// The effective user id.
    pub uid: u32,
    /// The effective group id and the supplementary groups of this session (what the kernel checks; a
    /// group joined after login is in `/etc/group` but not here).
    pub gids: Vec<u32>,
    /// The login name, for the fix's `usermod` line.
    pub user: String,
}

/// Thresholds of the folder checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpaceLimits {
    /// Below this a folder is a problem: a session log or a tile cache will fill the disk [bytes].
    pub problem_below: u64,
    /// Below this a folder is a warning (the default tile cache alone may take 500 MB) [bytes].
    pub warning_below: u64,
}

impl Default for SpaceLimits {
    fn default() -> Self {
        Self { problem_below: 100 << 20, warning_below: 1 << 30 }
    }
}

/// Everything the checks look at (see the module doc).
#[derive(Debug, Clone)]
pub struct Environment {
    /// Where `/` is: `/` on the real machine, a prepared folder in tests.
    pub root: PathBuf,
    /// The process's user and groups.
    pub identity: Identity,
    /// The environment variables the checks read (`PATH`, `LD_LIBRARY_PATH`, `DISPLAY`,
    /// `WAYLAND_DISPLAY`, `HOME`, `VIRTUAL_ENV`).
    pub vars: BTreeMap<String, String>,
    /// Free-space thresholds of the folder checks.
    pub space: SpaceLimits,
}

/// The environment variables [`Environment::system`] keeps.
const VARS: [&str; 6] = ["PATH", "LD_LIBRARY_PATH", "DISPLAY", "WAYLAND_DISPLAY", "HOME", "VIRTUAL_ENV"];

impl Environment {
    /// The real machine: root `/`, this process's identity (from `/proc/self/status`) and environment.
    pub fn system() -> Self {
        let root = PathBuf::from("/");
        let vars = VARS.iter().filter_map(|k| std::env::var(k).ok().map(|v| ((*k).to_owned(), v))).collect();
        let mut env = Self {
            identity: Identity { uid: u32::MAX, gids: Vec::new(), user: String::new() },
            root,
            vars,
            space: SpaceLimits::default(),
        };
        let status = env.read_small("/proc/self/status").unwrap_or_default();
        env.identity = identity_from_status(&status);
        env.identity.user = env
            .user_name(env.identity.uid)
            .or_else(|| std::env::var("USER").ok())
            .unwrap_or_else(|| env.identity.uid.to_string());
        env
    }

    /// `path` (absolute, as on the machine being checked) under [`Environment::root`].
    pub fn at(&self, path: impl AsRef<Path>) -> PathBuf {
        let rel: PathBuf = path.as_ref().components().filter(|c| matches!(c, Component::Normal(_))).collect();
        self.root.join(rel)
    }

    fn var(&self, name: &str) -> Option<&str> {
        self.vars.get(name).map(String::as_str).filter(|v| !v.is_empty())
    }

    /// Reads at most [`MAX_SMALL_FILE`] bytes of a file (lossy UTF-8).
    fn read_small(&self, path: impl AsRef<Path>) -> std::io::Result<String> {
        let file = std::fs::File::open(self.at(path))?;
        let mut bytes = Vec::new();
        file.take(MAX_SMALL_FILE).read_to_end(&mut bytes)?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }

    /// The names in a folder, sorted (at most `MAX_DIR_ENTRIES`).
    fn list(&self, dir: impl AsRef<Path>) -> std::io::Result<Vec<String>> {
        let mut names: Vec<String> = std::fs::read_dir(self.at(dir))?
            .take(MAX_DIR_ENTRIES)
            .filter_map(Result::ok)
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        Ok(names)
    }

    fn user_name(&self, uid: u32) -> Option<String> {
        let passwd = self.read_small("/etc/passwd").ok()?;
        passwd.lines().find_map(|line| {
            let mut f = line.split(':');
            let name = f.next()?;
            (f.nth(1)?.parse::<u32>().ok()? == uid).then(|| name.to_owned())
        })
    }

    /// The first executable file called `program` in `PATH`.
    pub fn which(&self, program: &str) -> Option<PathBuf> {
        let path = self.var("PATH").unwrap_or("/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin");
        path.split(':')
            .filter(|d| d.starts_with('/'))
            .map(|d| Path::new(d).join(program))
            .find(|p| std::fs::metadata(self.at(p)).is_ok_and(|m| m.is_file() && mode_of(&m) & 0o111 != 0))
    }

    /// The folders the dynamic loader searches: `LD_LIBRARY_PATH`, `/etc/ld.so.conf` (with its
    /// `include`s), then the default and multiarch folders.
    pub fn library_dirs(&self) -> Vec<PathBuf> {
        let mut dirs: Vec<PathBuf> = Vec::new();
        if let Some(lp) = self.var("LD_LIBRARY_PATH") {
            dirs.extend(lp.split(':').filter(|d| d.starts_with('/')).map(PathBuf::from));
        }
        let mut conf_files = vec![PathBuf::from("/etc/ld.so.conf")];
        let mut seen = 0;
        while let Some(conf) = conf_files.pop() {
            seen += 1;
            if seen > 64 {
                break; // an include loop or a huge tree: the defaults below still apply
            }
            let Ok(text) = self.read_small(&conf) else { continue };
            for line in text.lines().map(|l| l.split('#').next().unwrap_or("").trim()) {
                if let Some(pattern) = line.strip_prefix("include ") {
                    conf_files.extend(self.glob_conf(pattern.trim()));
                } else if line.starts_with('/') {
                    dirs.push(PathBuf::from(line));
                }
            }
        }
        let triplet = format!("{}-linux-gnu", std::env::consts::ARCH);
        for d in ["/lib", "/usr/lib", "/lib64", "/usr/lib64", "/usr/local/lib"] {
            dirs.push(Path::new(d).join(&triplet));
            dirs.push(PathBuf::from(d));
        }
        let mut unique = Vec::new();
        for d in dirs {
            if !unique.contains(&d) {
                unique.push(d);
            }
        }
        unique
    }

    /// `include /etc/ld.so.conf.d/*.conf`: only a `*` in the last component is understood.
    fn glob_conf(&self, pattern: &str) -> Vec<PathBuf> {
        let pattern = Path::new(pattern);
        let (Some(dir), Some(name)) = (pattern.parent(), pattern.file_name().and_then(|n| n.to_str())) else {
            return Vec::new();
        };
        let (prefix, suffix) = name.split_once('*').unwrap_or((name, ""));
        let mut found: Vec<PathBuf> = self
            .list(dir)
            .unwrap_or_default()
            .into_iter()
            .filter(|n| {
                n.starts_with(prefix) && n.ends_with(suffix) && n.len() >= prefix.len() + suffix.len()
            })
            .map(|n| dir.join(n))
            .collect();
        found.reverse(); // popped from the end: read in name order
        found
    }

    /// The first file in the loader's folders whose name is `soname`.
    pub fn find_library(&self, soname: &str) -> Option<PathBuf> {
        self.library_dirs().into_iter().map(|d| d.join(soname)).find(|p| self.at(p).exists())
    }

    /// Whether a process called `name` runs (its `/proc/PID/comm`).
    pub fn process_running(&self, name: &str) -> bool {
        self.list("/proc").unwrap_or_default().iter().filter(|p| p.bytes().all(|b| b.is_ascii_digit())).any(
            |pid| self.read_small(Path::new("/proc").join(pid).join("comm")).is_ok_and(|c| c.trim() == name),
        )
    }
}

/// The effective uid and the groups from `/proc/self/status` (`Uid:`, `Gid:`, `Groups:` lines).
fn identity_from_status(status: &str) -> Identity {
    let field = |key: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .map(|rest| rest.split_whitespace().filter_map(|n| n.parse::<u32>().ok()).collect::<Vec<u32>>())
    };
    let uid = field("Uid:").and_then(|ids| ids.get(1).copied()).unwrap_or(u32::MAX);
    let mut gids = field("Gid:").and_then(|ids| ids.get(1).copied()).into_iter().collect::<Vec<_>>();
    for g in field("Groups:").unwrap_or_default() {
        if !gids.contains(&g) {
            gids.push(g);
        }
    }
    Identity { uid, gids, user: String::new() }
}

#[cfg(unix)]
fn mode_of(meta: &std::fs::Metadata) -> u32 {
    std::os::unix::fs::PermissionsExt::mode(&meta.permissions())
}

#[cfg(not(unix))]
fn mode_of(_meta: &std::fs::Metadata) -> u32 {
    0o777
}

/// Owner, group and mode of a file.
#[derive(Debug, Clone, Copy)]
struct Owner {
    uid: u32,
    gid: u32,
    mode: u32,
}

#[cfg(unix)]
fn owner_of(meta: &std::fs::Metadata) -> Owner {
    use std::os::unix::fs::MetadataExt as _;
    Owner { uid: meta.uid(), gid: meta.gid(), mode: meta.mode() }
}

#[cfg(not(unix))]
fn owner_of(_meta: &std::fs::Metadata) -> Owner {
    Owner { uid: 0, gid: 0, mode: 0o777 }
}

/// Whether `who` has all of `want` (`0o6` read+write, `0o3` write+search) on a file owned as `owner`:
/// the kernel's owner-then-group-then-other rule; root may do anything.
fn permits(who: &Identity, owner: Owner, want: u32) -> bool {
    if who.uid == 0 {
        return true;
    }
    let bits = if owner.uid == who.uid {
        owner.mode >> 6
    } else if who.gids.contains(&owner.gid) {
        owner.mode >> 3
    } else {
        owner.mode
    };
    bits & want == want
}

/// One `/etc/group` line: name, gid, members.
struct Group {
    name: String,
    gid: u32,
    members: Vec<String>,
}

fn parse_groups(text: &str) -> Vec<Group> {
    text.lines()
        .filter_map(|line| {
            let mut f = line.split(':');
            let name = f.next()?.to_owned();
            let gid = f.nth(1)?.parse().ok()?;
            let members =
                f.next().unwrap_or("").split(',').filter(|m| !m.is_empty()).map(str::to_owned).collect();
            Some(Group { name, gid, members })
        })
        .collect()
}

/// Everything `vestnav doctor` checks, in order.
#[derive(Debug, Clone, Default)]
pub struct Request {
    /// Ports to check besides those found under `/dev` (the ones in the console's settings, `--port`).
    pub ports: Vec<String>,
    /// The folders the program writes, with their role ("config folder", "data folder", "tile cache").
    pub folders: Vec<(String, PathBuf)>,
    /// A broker URL to reach, where one is configured.
    pub broker: Option<String>,
}

/// Runs every check.
pub fn run(env: &Environment, request: &Request) -> Report {
    let mut findings = serial_findings(env, &request.ports);
    findings.extend(bluetooth_findings(env));
    findings.extend(display_findings(env));
    for (role, path) in &request.folders {
        findings.push(folder_finding(env, role, path));
    }
    findings.extend(optional_findings(env, request.broker.as_deref()));
    Report { findings }
}

/// Whether a port name looks like one a GPS or a vest shows up as (`ttyS*` on-board UARTs always exist
/// and are left out unless named).
fn is_candidate_port(name: &str) -> bool {
    ["ttyUSB", "ttyACM", "rfcomm"].iter().any(|p| name.strip_prefix(p).is_some_and(|n| !n.is_empty()))
}

/// The serial ports: every USB and Bluetooth port under `/dev` and each of `named`, whether it exists and
/// whether this user may open it.
pub fn serial_findings(env: &Environment, named: &[String]) -> Vec<Finding> {
    let mut ports: Vec<String> = env
        .list("/dev")
        .unwrap_or_default()
        .into_iter()
        .filter(|n| is_candidate_port(n))
        .map(|n| format!("/dev/{n}"))
        .collect();
    for p in named {
        if !ports.contains(p) {
            ports.push(p.clone());
        }
    }
    if ports.is_empty() {
        return vec![
            Finding::new(
                Area::SerialPorts,
                "serial ports",
                Verdict::Info,
                "no USB serial adapter (/dev/ttyUSB*, /dev/ttyACM*) or Bluetooth binding (/dev/rfcomm*) present",
            )
            .fix("plug the GPS or vest in, or bind the Bluetooth device: sudo rfcomm bind 0 <MAC> 1 (docs/hardware.md)"),
        ];
    }
    let groups = parse_groups(&env.read_small("/etc/group").unwrap_or_default());
    ports.iter().map(|p| port_finding(env, &groups, p)).collect()
}

/// What the console shows when `port` fails to open: the port's own verdict and, for a Bluetooth binding,
/// the Bluetooth checks.
pub fn port_findings(env: &Environment, port: &str) -> Vec<Finding> {
    let groups = parse_groups(&env.read_small("/etc/group").unwrap_or_default());
    let mut findings = vec![port_finding(env, &groups, port)];
    if port.starts_with("/dev/rfcomm") {
        findings.extend(bluetooth_findings(env));
    }
    findings
}

fn port_finding(env: &Environment, groups: &[Group], port: &str) -> Finding {
    let finding = |verdict, detail: String| Finding::new(Area::SerialPorts, port, verdict, detail);
    let meta = match std::fs::metadata(env.at(port)) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let f = finding(Verdict::Problem, format!("{port} does not exist"));
            return if port.starts_with("/dev/rfcomm") {
                let n = port.trim_start_matches("/dev/rfcomm");
                f.fix(format!(
                    "bind the paired device: sudo rfcomm bind {n} <MAC> 1 (bluetoothctl devices Paired lists the MACs)"
                ))
            } else {
                f.fix("plug the device in; `vestnav doctor` lists the ports present")
            };
        }
        Err(e) => return finding(Verdict::Problem, format!("cannot inspect {port}: {e}")),
    };
    let owner = owner_of(&meta);
    let who = &env.identity;
    let group = groups.iter().find(|g| g.gid == owner.gid);
    let group_name = group.map_or_else(|| owner.gid.to_string(), |g| g.name.clone());
    if permits(who, owner, 0o6) {
        return finding(Verdict::Ok, format!("{} may open it (group {group_name})", who.user));
    }
    // The group could grant it: is the user in that group on paper (a new login would do) or not at all?
    if owner.mode & 0o060 == 0o060 {
        let on_paper = group.is_some_and(|g| g.members.contains(&who.user));
        return if on_paper {
            finding(
                Verdict::Problem,
                format!(
                    "{} is in group {group_name} in /etc/group, but not in this login session, so {port} cannot be opened",
                    who.user
                ),
            )
            .fix(format!("log out and back in (or run `newgrp {group_name}` in this shell)"))
        } else {
            finding(
                Verdict::Problem,
                format!(
                    "{} may not open it: it belongs to group {group_name}, and {} is not in it",
                    who.user, who.user
                ),
            )
            .fix(format!("sudo usermod -aG {group_name} {}, then log out and back in", who.user))
        };
    }
    finding(
        Verdict::Problem,
        format!(
            "{} may not open it: mode {:03o}, owner uid {}, group {group_name} gives no one else read and write",
            who.user,
            owner.mode & 0o777,
            owner.uid
        ),
    )
    .fix(format!(
        "give the dialout group access: sudo chgrp dialout {port} && sudo chmod 660 {port} (for good: a udev rule, docs/hardware.md)"
    ))
}

/// Bluetooth: an adapter, the `BlueZ` daemon, the `rfcomm` tool, paired SPP devices and bindings.
pub fn bluetooth_findings(env: &Environment) -> Vec<Finding> {
    let finding =
        |check: &str, verdict, detail: String| Finding::new(Area::Bluetooth, check, verdict, detail);
    let mut out = Vec::new();
    let adapters: Vec<String> = env
        .list("/sys/class/bluetooth")
        .unwrap_or_default()
        .into_iter()
        .filter(|n| n.starts_with("hci") && !n.contains(':'))
        .collect();
    out.push(if adapters.is_empty() {
        finding("adapter", Verdict::Warning, "no Bluetooth adapter found (/sys/class/bluetooth)".into())
            .fix("plug in a Bluetooth dongle or enable Bluetooth in the firmware settings; a USB GPS or vest needs none")
    } else {
        finding("adapter", Verdict::Ok, format!("adapter {}", adapters.join(", ")))
    });
    let running = env.process_running("bluetoothd");
    out.push(if running {
        finding("bluetoothd", Verdict::Ok, "the BlueZ service runs".into())
    } else {
        finding("bluetoothd", Verdict::Warning, "the BlueZ service (bluetoothd) is not running".into())
            .fix("sudo apt install bluez && sudo systemctl enable --now bluetooth")
    });
    out.push(match env.which("rfcomm") {
        Some(p) => finding("rfcomm", Verdict::Ok, format!("{} present", p.display())),
        None => finding(
            "rfcomm",
            Verdict::Warning,
            "the rfcomm tool is missing: Bluetooth serial ports cannot be bound".into(),
        )
        .fix("sudo apt install bluez (Debian ships rfcomm in it; some releases in bluez-deprecated)"),
    });
    out.push(paired_finding(env));
    let bound: Vec<String> =
        env.list("/dev").unwrap_or_default().into_iter().filter(|n| n.starts_with("rfcomm")).collect();
    out.push(if bound.is_empty() {
        finding("bound ports", Verdict::Info, "no Bluetooth serial port bound (/dev/rfcomm*)".into())
            .fix("sudo rfcomm bind 0 <MAC> 1 for each paired GPS or vest (docs/hardware.md)")
    } else {
        finding("bound ports", Verdict::Ok, format!("bound: /dev/{}", bound.join(", /dev/")))
    });
    out
}

/// Paired devices offering the Serial Port Profile, from `BlueZ`'s store (`/var/lib/bluetooth/ADAPTER/DEVICE/
/// info`, readable by root only).
fn paired_finding(env: &Environment) -> Finding {
    let finding =
        |verdict, detail: String| Finding::new(Area::Bluetooth, "paired SPP devices", verdict, detail);
    let store = Path::new("/var/lib/bluetooth");
    let adapters = match env.list(store) {
        Ok(a) => a,
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {
            return finding(Verdict::Info, "BlueZ's pairing store is readable by root only".into())
                .fix("list them with: bluetoothctl devices Paired");
        }
        Err(_) => {
            return finding(Verdict::Info, "no pairing store (/var/lib/bluetooth): nothing paired".into())
                .fix("pair the GPS and the vest: bluetoothctl, then `pair <MAC>` and `trust <MAC>` (docs/hardware.md)");
        }
    };
    let mut spp = Vec::new();
    let mut others = 0;
    for adapter in adapters.iter().filter(|a| a.contains(':')) {
        for device in env.list(store.join(adapter)).unwrap_or_default().iter().filter(|d| d.contains(':')) {
            let Ok(info) = env.read_small(store.join(adapter).join(device).join("info")) else { continue };
            let name = info.lines().find_map(|l| l.strip_prefix("Name=")).unwrap_or("").trim();
            let services = info.lines().find_map(|l| l.strip_prefix("Services=")).unwrap_or("");
            if services.to_ascii_lowercase().contains(SPP_UUID) {
                spp.push(if name.is_empty() { device.clone() } else { format!("{name} ({device})") });
            } else {
                others += 1;
            }
        }
    }
    if spp.is_empty() {
        finding(Verdict::Info, format!("no paired device offers a serial port ({others} other paired)")).fix(
            "pair the GPS and the vest: bluetoothctl, then `pair <MAC>` and `trust <MAC>` (docs/hardware.md)",
        )
    } else {
        finding(Verdict::Ok, spp.join(", "))
    }
}

/// A library the console loads at run time, and the Debian package that has it.
struct Lib {
    soname: &'static str,
    package: &'static str,
}

const GL_LIBS: [Lib; 2] =
    [Lib { soname: "libEGL.so.1", package: "libegl1" }, Lib { soname: "libGL.so.1", package: "libgl1" }];
const COMMON_LIBS: [Lib; 1] = [Lib { soname: "libxkbcommon.so.0", package: "libxkbcommon0" }];
const X11_LIBS: [Lib; 6] = [
    Lib { soname: "libX11.so.6", package: "libx11-6" },
    Lib { soname: "libX11-xcb.so.1", package: "libx11-xcb1" },
    Lib { soname: "libXcursor.so.1", package: "libxcursor1" },
    Lib { soname: "libXi.so.6", package: "libxi6" },
    Lib { soname: "libXrandr.so.2", package: "libxrandr2" },
    Lib { soname: "libxkbcommon-x11.so.0", package: "libxkbcommon-x11-0" },
];
const WAYLAND_LIBS: [Lib; 3] = [
    Lib { soname: "libwayland-client.so.0", package: "libwayland-client0" },
    Lib { soname: "libwayland-cursor.so.0", package: "libwayland-cursor0" },
    Lib { soname: "libwayland-egl.so.1", package: "libwayland-egl1" },
];

/// The Debian packages of every library the console's window opens at run time (the packaging script
/// makes them dependencies).
pub fn window_packages() -> Vec<&'static str> {
    GL_LIBS.iter().chain(&COMMON_LIBS).chain(&X11_LIBS).chain(&WAYLAND_LIBS).map(|l| l.package).collect()
}

/// The display session and the libraries the console's window needs (they are opened at run time, so a
/// missing one would only show when the window opens).
pub fn display_findings(env: &Environment) -> Vec<Finding> {
    let finding = |check: &str, verdict, detail: String| Finding::new(Area::Display, check, verdict, detail);
    let wayland = env.var("WAYLAND_DISPLAY").is_some();
    let x11 = env.var("DISPLAY").is_some();
    let mut out = vec![match (wayland, x11) {
        (true, _) => finding("session", Verdict::Ok, "a Wayland session (WAYLAND_DISPLAY)".into()),
        (false, true) => finding("session", Verdict::Ok, "an X11 session (DISPLAY)".into()),
        (false, false) => finding(
            "session",
            Verdict::Warning,
            "no display (neither DISPLAY nor WAYLAND_DISPLAY): the console window cannot open here; the subcommands work".into(),
        )
        .fix("run it from the desktop (its application menu), or over ssh -X"),
    }];
    let dirs = env.library_dirs();
    let find = |soname: &str| dirs.iter().map(|d| d.join(soname)).find(|p| env.at(p).exists());
    // Each library: a problem if the session in use needs it, a warning if only the other kind would.
    let mut check = |libs: &[Lib], needed: bool| {
        for lib in libs {
            out.push(match find(lib.soname) {
                Some(p) => finding(lib.soname, Verdict::Ok, format!("{}", p.display())),
                None => finding(
                    lib.soname,
                    if needed { Verdict::Problem } else { Verdict::Warning },
                    format!(
                        "{} is missing: the console window {}",
                        lib.soname,
                        if needed { "will not open" } else { "needs it in some sessions" }
                    ),
                )
                .fix(format!("sudo apt install {}", lib.package)),
            });
        }
    };
    check(&GL_LIBS, wayland || x11);
    check(&COMMON_LIBS, wayland || x11);
    check(&X11_LIBS, x11 && !wayland);
    check(&WAYLAND_LIBS, wayland);
    let driver = dirs
        .iter()
        .any(|d| env.list(d.join("dri")).is_ok_and(|names| names.iter().any(|n| n.ends_with("_dri.so"))));
    out.push(if driver {
        finding("OpenGL driver", Verdict::Ok, "Mesa's drivers are installed".into())
    } else {
        finding(
            "OpenGL driver",
            Verdict::Warning,
            "no Mesa driver (dri/*_dri.so): without a vendor driver OpenGL will not start".into(),
        )
        .fix("sudo apt install libgl1-mesa-dri")
    });
    out
}

/// Whether `role`'s folder `path` (absolute, as on the checked machine) is writable, or can be created,
/// with free space.
pub fn folder_finding(env: &Environment, role: &str, path: &Path) -> Finding {
    let finding = |verdict, detail: String| Finding::new(Area::Folders, role, verdict, detail);
    let shown = path.display();
    // The folder, or the nearest existing folder above it (it is created on first use).
    let mut existing = path.to_path_buf();
    let mut steps = 0;
    let meta = loop {
        match std::fs::metadata(env.at(&existing)) {
            Ok(m) => break m,
            Err(e)
                if matches!(e.kind(), std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory)
                    && steps < 64 =>
            {
                steps += 1;
                if !existing.pop() {
                    return finding(Verdict::Problem, format!("{shown}: no part of the path exists"));
                }
            }
            Err(e) => {
                return finding(Verdict::Problem, format!("cannot inspect {}: {e}", existing.display()));
            }
        }
    };
    let where_ = if existing == path {
        format!("{shown}")
    } else {
        format!("{} (to create {shown})", existing.display())
    };
    if !meta.is_dir() {
        return finding(Verdict::Problem, format!("{} is not a folder", existing.display()))
            .fix(format!("move the file {} aside", existing.display()));
    }
    if !permits(&env.identity, owner_of(&meta), 0o3) {
        return finding(Verdict::Problem, format!("{where_} is not writable by {}", env.identity.user))
            .fix(format!("sudo chown -R {} {}", env.identity.user, existing.display()));
    }
    if let Err(e) = probe_write(&env.at(&existing)) {
        return finding(Verdict::Problem, format!("{where_} cannot be written: {e}")).fix(
            if e.raw_os_error() == Some(READ_ONLY_FS) {
                "the file system is mounted read-only: remount it read-write, or choose another folder in the console's settings".to_owned()
            } else {
                format!("make {} writable for {}", existing.display(), env.identity.user)
            },
        );
    }
    match free_bytes(&env.at(&existing)) {
        Err(e) => finding(Verdict::Warning, format!("{where_} is writable; free space unknown: {e}")),
        Ok(free) if free < env.space.problem_below => {
            finding(Verdict::Problem, format!("{where_}: only {} free", human_bytes(free)))
                .fix("free disk space (the tile cache can be emptied in the console's Tiles window)")
        }
        Ok(free) if free < env.space.warning_below => finding(
            Verdict::Warning,
            format!("{where_}: {} free, little for a tile cache", human_bytes(free)),
        )
        .fix("free disk space, or lower the tile cache limit in the console's Tiles window"),
        Ok(free) => finding(Verdict::Ok, format!("{where_} is writable, {} free", human_bytes(free))),
    }
}

/// EROFS on Linux.
const READ_ONLY_FS: i32 = 30;

/// Creates and removes a file in `dir`: what a mode check cannot see (a read-only mount, an ACL).
fn probe_write(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".vestnav-doctor-{}", std::process::id()));
    std::fs::OpenOptions::new().write(true).create_new(true).open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(unix)]
fn free_bytes(dir: &Path) -> std::io::Result<u64> {
    let s = rustix::fs::statvfs(dir)?;
    Ok(s.f_bavail.saturating_mul(s.f_frsize))
}

#[cfg(not(unix))]
fn free_bytes(_dir: &Path) -> std::io::Result<u64> {
    Err(std::io::Error::other("not measured on this platform"))
}

/// `1.5 GB`, `320 MB`.
fn human_bytes(bytes: u64) -> String {
    let mb = bytes as f64 / 1e6;
    if mb >= 1000.0 { format!("{:.1} GB", mb / 1000.0) } else { format!("{mb:.0} MB") }
}

/// gpsd, liblsl and the broker: only needed for some set-ups, so never a problem unless configured.
pub fn optional_findings(env: &Environment, broker: Option<&str>) -> Vec<Finding> {
    let finding = |check: &str, verdict, detail: String| Finding::new(Area::Optional, check, verdict, detail);
    let mut out = vec![match env.which("gpsd") {
        Some(p) => finding("gpsd", Verdict::Ok, format!("{} present", p.display())),
        None => finding(
            "gpsd",
            Verdict::Info,
            "gpsd is not installed (needed only for a gpsd:// GPS source)".into(),
        )
        .fix("sudo apt install gpsd"),
    }];
    out.push(match find_liblsl(env) {
        Some(p) => finding("liblsl", Verdict::Ok, format!("{}", p.display())),
        None => {
            finding("liblsl", Verdict::Info, "liblsl not found (needed only for Lab Streaming Layer)".into())
                .fix("install liblsl from its releases, or `pip install pylsl` (its wheel carries liblsl)")
        }
    });
    out.push(match broker {
        None => finding("broker", Verdict::Info, "none configured".into()),
        Some(url) => match reach_broker(url, BROKER_TIMEOUT) {
            Ok(addr) => finding("broker", Verdict::Ok, format!("{url} answers ({addr})")),
            Err(e) => finding("broker", Verdict::Problem, format!("{url}: {e}"))
                .fix("start the broker, or check the host, port and firewall"),
        },
    });
    out
}

/// `liblsl.so*` in the loader's folders, else in a pylsl install (`pylsl/lib/` in the system's, the
/// user's or the active virtual environment's Python packages).
fn find_liblsl(env: &Environment) -> Option<PathBuf> {
    let is_lsl = |n: &str| n.starts_with("liblsl") && n.contains(".so");
    let mut dirs = env.library_dirs();
    let mut site_parents = vec![PathBuf::from("/usr/lib/python3/dist-packages")];
    let mut py_roots = vec![PathBuf::from("/usr/local/lib"), PathBuf::from("/usr/lib")];
    if let Some(home) = env.var("HOME") {
        py_roots.push(Path::new(home).join(".local/lib"));
    }
    if let Some(venv) = env.var("VIRTUAL_ENV") {
        py_roots.push(Path::new(venv).join("lib"));
    }
    for root in py_roots {
        for py in env.list(&root).unwrap_or_default().into_iter().filter(|n| n.starts_with("python3")) {
            site_parents.push(root.join(&py).join("site-packages"));
            site_parents.push(root.join(&py).join("dist-packages"));
        }
    }
    for site in site_parents {
        dirs.push(site.join("pylsl").join("lib"));
        dirs.push(site.join("pylsl"));
    }
    dirs.into_iter().find_map(|d| env.list(&d).ok()?.into_iter().find(|n| is_lsl(n)).map(|n| d.join(n)))
}

/// Connects to the broker's host and port (`mqtt://host:1883`, `tcp://host:port`, `host:port`; the MQTT
/// default ports when none is given) within `timeout` per address; the address that answered.
pub fn reach_broker(url: &str, timeout: Duration) -> Result<std::net::SocketAddr, String> {
    let (scheme, rest) = url.split_once("://").unwrap_or(("", url));
    let authority = rest.split(['/', '?', '#']).next().unwrap_or("");
    let authority = authority.rsplit_once('@').map_or(authority, |(_, host)| host);
    let default_port = match scheme {
        "mqtts" | "ssl" => 8883,
        _ => 1883,
    };
    let has_port = authority.rsplit_once(':').is_some_and(|(_, p)| p.bytes().all(|b| b.is_ascii_digit()))
        && !authority.ends_with(']');
    let target = if has_port { authority.to_owned() } else { format!("{authority}:{default_port}") };
    if authority.is_empty() {
        return Err("no host in the URL".into());
    }
    let addrs: Vec<_> =
        target.to_socket_addrs().map_err(|e| format!("cannot resolve {target}: {e}"))?.collect();
    let mut last = format!("{target} resolves to no address");
    for addr in addrs.into_iter().take(4) {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(_) => return Ok(addr),
            Err(e) => last = format!("cannot connect to {addr}: {e}"),
        }
    }
    Err(last)
}

/// The report as the terminal shows it: one line per finding, its fix indented below.
pub fn render_text(report: &Report) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let mut area = None;
    for f in &report.findings {
        if area != Some(f.area) {
            area = Some(f.area);
            let title = match f.area {
                Area::SerialPorts => "Serial ports",
                Area::Bluetooth => "Bluetooth",
                Area::Display => "Display and OpenGL",
                Area::Folders => "Folders",
                Area::Optional => "Optional parts",
            };
            let _ = writeln!(out, "{title}");
        }
        let _ = writeln!(out, "  {:<8} {}: {}", f.verdict.label(), f.check, f.detail);
        if let Some(fix) = f.fix.as_ref().filter(|_| f.verdict != Verdict::Ok) {
            let _ = writeln!(out, "           fix: {fix}");
        }
    }
    let _ = writeln!(
        out,
        "{} problem(s), {} warning(s)",
        report.count(Verdict::Problem),
        report.count(Verdict::Warning)
    );
    out
}

#[cfg(all(test, unix))]
// The fake machine's helpers unwrap too: a failure there is a failed test.
#[allow(clippy::unwrap_used)]
mod tests {
    use std::os::unix::fs::PermissionsExt as _;

    use super::*;

    /// A fake machine: a temporary folder standing in for `/`, removed on drop.
    struct FakeRoot {
        dir: PathBuf,
    }

    impl FakeRoot {
        fn new(name: &str) -> Self {
            let dir = std::env::temp_dir().join(format!("vestnav-doctor-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            Self { dir }
        }

        /// Writes `text` at `path` (absolute inside the fake machine), creating folders.
        fn file(&self, path: &str, text: &str) -> PathBuf {
            let p = self.dir.join(path.trim_start_matches('/'));
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, text).unwrap();
            p
        }

        fn mkdir(&self, path: &str) -> PathBuf {
            let p = self.dir.join(path.trim_start_matches('/'));
            std::fs::create_dir_all(&p).unwrap();
            p
        }

        /// An environment on this root, as user `alice` (uid 1000) in groups `gids`.
        fn env(&self, gids: &[u32], vars: &[(&str, &str)]) -> Environment {
            Environment {
                root: self.dir.clone(),
                identity: Identity { uid: 1000, gids: gids.to_vec(), user: "alice".into() },
                vars: vars.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect(),
                space: SpaceLimits { problem_below: 0, warning_below: 0 },
            }
        }
    }

    impl Drop for FakeRoot {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }

    /// Gives `path` owner, group and mode; false (the test then skips) when not allowed to (not root).
    fn own(path: &Path, uid: u32, gid: u32, mode: u32) -> bool {
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
        match std::os::unix::fs::chown(path, Some(uid), Some(gid)) {
            Ok(()) => true,
            Err(e) => {
                eprintln!("skipped: chown needs root ({e})");
                false
            }
        }
    }

    const GROUPS: &str = "root:x:0:\ndialout:x:20:\nalice:x:1000:\n";

    #[test]
    fn a_port_of_a_group_the_user_is_not_in_says_usermod() {
        let fake = FakeRoot::new("usermod");
        fake.file("/etc/group", GROUPS);
        let port = fake.file("/dev/ttyUSB0", "");
        if !own(&port, 0, 20, 0o660) {
            return;
        }
        let found = serial_findings(&fake.env(&[1000], &[]), &[]);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].check, "/dev/ttyUSB0");
        assert_eq!(found[0].verdict, Verdict::Problem);
        assert!(found[0].detail.contains("group dialout"), "{}", found[0].detail);
        assert_eq!(found[0].fix.as_deref(), Some("sudo usermod -aG dialout alice, then log out and back in"));
        // In the group in this session: fine.
        assert_eq!(serial_findings(&fake.env(&[1000, 20], &[]), &[])[0].verdict, Verdict::Ok);
    }

    #[test]
    fn a_group_joined_after_login_says_log_in_again() {
        let fake = FakeRoot::new("relogin");
        fake.file("/etc/group", "dialout:x:20:bob,alice\n");
        let port = fake.file("/dev/rfcomm0", "");
        if !own(&port, 0, 20, 0o660) {
            return;
        }
        let found =
            port_finding(&fake.env(&[1000], &[]), &parse_groups("dialout:x:20:bob,alice"), "/dev/rfcomm0");
        assert_eq!(found.verdict, Verdict::Problem);
        assert!(found.fix.as_deref().is_some_and(|f| f.contains("newgrp dialout")), "{found:?}");
    }

    #[test]
    fn a_port_only_its_owner_may_open_is_a_problem_for_everyone_else() {
        let fake = FakeRoot::new("owner");
        fake.file("/etc/group", GROUPS);
        // Mode 0600, owned by another user: no group membership helps.
        let port = fake.file("/dev/ttyACM0", "");
        if !own(&port, 4242, 20, 0o600) {
            return;
        }
        let env = fake.env(&[1000, 20], &[]);
        let f = &serial_findings(&env, &[])[0];
        assert_eq!(f.verdict, Verdict::Problem);
        assert!(f.detail.contains("mode 600"), "{}", f.detail);
        assert!(f.fix.as_deref().is_some_and(|x| x.contains("chmod 660 /dev/ttyACM0")));
        // Its owner may; so may root.
        let mut owner = env.clone();
        owner.identity.uid = 4242;
        assert_eq!(serial_findings(&owner, &[])[0].verdict, Verdict::Ok);
        owner.identity.uid = 0;
        assert_eq!(serial_findings(&owner, &[])[0].verdict, Verdict::Ok);
    }

    #[test]
    fn missing_ports_and_no_ports() {
        let fake = FakeRoot::new("missing");
        fake.mkdir("/dev");
        let env = fake.env(&[1000], &[]);
        let none = serial_findings(&env, &[]);
        assert_eq!(none.len(), 1);
        assert_eq!(none[0].verdict, Verdict::Info);
        // ttyS* always exist and are not listed unless named.
        fake.file("/dev/ttyS0", "");
        assert_eq!(serial_findings(&env, &[])[0].verdict, Verdict::Info);
        let named = port_findings(&env, "/dev/rfcomm3");
        assert_eq!(named[0].verdict, Verdict::Problem);
        assert!(named[0].fix.as_deref().is_some_and(|f| f.contains("rfcomm bind 3")));
        // A Bluetooth port brings the Bluetooth checks along.
        assert!(named.iter().any(|f| f.area == Area::Bluetooth));
        assert!(port_findings(&env, "/dev/ttyUSB9").iter().all(|f| f.area == Area::SerialPorts));
    }

    #[test]
    fn a_folder_the_user_cannot_write_is_a_problem() {
        let fake = FakeRoot::new("rofolder");
        let data = fake.mkdir("/home/alice/.local/share/vestnav");
        if !own(&data, 0, 0, 0o755) {
            return;
        }
        let env = fake.env(&[1000], &[]);
        let f = folder_finding(&env, "data folder", Path::new("/home/alice/.local/share/vestnav"));
        assert_eq!(f.verdict, Verdict::Problem, "{f:?}");
        assert!(f.detail.contains("not writable by alice"), "{}", f.detail);
        // A folder still to be created inside it cannot be created either.
        let below = folder_finding(&env, "tile cache", Path::new("/home/alice/.local/share/vestnav/tiles/x"));
        assert_eq!(below.verdict, Verdict::Problem);
        assert!(below.detail.contains("to create"), "{}", below.detail);
    }

    #[test]
    fn a_writable_folder_to_be_created_is_fine_and_free_space_counts() {
        let fake = FakeRoot::new("space");
        let home = fake.mkdir("/home/alice");
        if !own(&home, 1000, 1000, 0o755) {
            return;
        }
        let mut env = fake.env(&[1000], &[]);
        let f = folder_finding(&env, "config folder", Path::new("/home/alice/.config/vestnav"));
        assert_eq!(f.verdict, Verdict::Ok, "{f:?}");
        assert!(f.detail.contains("to create /home/alice/.config/vestnav"));
        // The same folder on a disk with less free space than the threshold.
        env.space.problem_below = u64::MAX;
        let full = folder_finding(&env, "config folder", Path::new("/home/alice/.config/vestnav"));
        assert_eq!(full.verdict, Verdict::Problem);
        assert!(full.detail.contains("free"));
        // A file where the folder should be.
        fake.file("/home/alice/.cache", "");
        let file =
            folder_finding(&fake.env(&[1000], &[]), "tile cache", Path::new("/home/alice/.cache/vestnav"));
        assert_eq!(file.verdict, Verdict::Problem);
        assert!(file.detail.contains("is not a folder"));
    }

    /// A real read-only file system (a tmpfs mounted read-only): even root cannot write it, and the write
    /// probe, not the mode bits, is what sees it. Skipped where mounting is not allowed.
    #[test]
    fn a_read_only_mount_is_a_problem_even_for_root() {
        let fake = FakeRoot::new("romount");
        let mnt = fake.mkdir("/data");
        let status = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", "ro,size=1m", "vestnav-doctor-test"])
            .arg(&mnt)
            .stderr(std::process::Stdio::null())
            .status();
        if !status.is_ok_and(|s| s.success()) {
            eprintln!("skipped: cannot mount a tmpfs here");
            return;
        }
        let mut env = fake.env(&[0], &[]);
        env.identity.uid = 0;
        let f = folder_finding(&env, "data folder", Path::new("/data"));
        let _ = std::process::Command::new("umount").arg(&mnt).status();
        assert_eq!(f.verdict, Verdict::Problem, "{f:?}");
        assert!(f.fix.as_deref().is_some_and(|x| x.contains("read-only")), "{f:?}");
    }

    #[test]
    fn window_libraries_by_session_kind() {
        let fake = FakeRoot::new("libs");
        let lib = format!("/usr/lib/{}-linux-gnu", std::env::consts::ARCH);
        for so in ["libEGL.so.1", "libGL.so.1", "libxkbcommon.so.0", "libwayland-client.so.0"] {
            fake.file(&format!("{lib}/{so}"), "");
        }
        fake.file(&format!("{lib}/dri/swrast_dri.so"), "");
        let verdict = |findings: &[Finding], check: &str| {
            findings.iter().find(|f| f.check == check).map(|f| (f.verdict, f.fix.clone()))
        };
        let x11 = display_findings(&fake.env(&[1000], &[("DISPLAY", ":0")]));
        assert_eq!(verdict(&x11, "libEGL.so.1").map(|v| v.0), Some(Verdict::Ok));
        assert_eq!(
            verdict(&x11, "libX11.so.6"),
            Some((Verdict::Problem, Some("sudo apt install libx11-6".to_owned())))
        );
        // Wayland needs its own libraries; the X11 ones only warn.
        let wl = display_findings(&fake.env(&[1000], &[("WAYLAND_DISPLAY", "wayland-0")]));
        assert_eq!(verdict(&wl, "libX11.so.6").map(|v| v.0), Some(Verdict::Warning));
        assert_eq!(verdict(&wl, "libwayland-egl.so.1").map(|v| v.0), Some(Verdict::Problem));
        assert_eq!(verdict(&wl, "OpenGL driver").map(|v| v.0), Some(Verdict::Ok));
        // No display at all: a warning, and nothing is a problem.
        let none = display_findings(&fake.env(&[1000], &[]));
        assert_eq!(none[0].verdict, Verdict::Warning);
        assert!(none.iter().all(|f| f.verdict != Verdict::Problem));
    }

    #[test]
    fn library_folders_follow_ld_so_conf_includes_and_ld_library_path() {
        let fake = FakeRoot::new("ldconf");
        fake.file("/etc/ld.so.conf", "# comment\ninclude /etc/ld.so.conf.d/*.conf\n");
        fake.file("/etc/ld.so.conf.d/lsl.conf", "/opt/lsl/lib  # the LSL release\n");
        fake.file("/etc/ld.so.conf.d/readme.txt", "/not/this\n");
        let env = fake.env(&[1000], &[("LD_LIBRARY_PATH", "/custom/lib:relative")]);
        let dirs = env.library_dirs();
        assert_eq!(dirs[0], Path::new("/custom/lib"));
        assert_eq!(dirs[1], Path::new("/opt/lsl/lib"));
        assert!(!dirs.iter().any(|d| d.starts_with("/not") || d.starts_with("relative")));
        assert_eq!(find_liblsl(&env), None);
        fake.file("/opt/lsl/lib/liblsl.so.1.16.2", "");
        assert_eq!(find_liblsl(&env), Some(PathBuf::from("/opt/lsl/lib/liblsl.so.1.16.2")));
    }

    #[test]
    fn liblsl_inside_a_pylsl_wheel_is_found() {
        let fake = FakeRoot::new("pylsl");
        fake.file("/home/alice/.local/lib/python3.12/site-packages/pylsl/lib/liblsl.so", "");
        let env = fake.env(&[1000], &[("HOME", "/home/alice")]);
        let found = optional_findings(&env, None);
        let lsl = found.iter().find(|f| f.check == "liblsl").unwrap();
        assert_eq!(lsl.verdict, Verdict::Ok);
        assert_eq!(lsl.detail, "/home/alice/.local/lib/python3.12/site-packages/pylsl/lib/liblsl.so");
        // gpsd absent is only information; no broker configured is not a problem either.
        assert!(found.iter().all(|f| f.verdict != Verdict::Problem));
        fake.file("/usr/sbin/gpsd", "");
        std::fs::set_permissions(fake.dir.join("usr/sbin/gpsd"), std::fs::Permissions::from_mode(0o755))
            .unwrap();
        let gpsd = optional_findings(&env, None).into_iter().find(|f| f.check == "gpsd").unwrap();
        assert_eq!(gpsd.verdict, Verdict::Ok);
    }

    #[test]
    fn bluetooth_paired_spp_devices_and_bindings() {
        let fake = FakeRoot::new("bt");
        let env = fake.env(&[1000], &[]);
        let before = bluetooth_findings(&env);
        assert!(
            before.iter().all(|f| f.verdict != Verdict::Ok && f.verdict != Verdict::Problem),
            "{before:?}"
        );
        fake.mkdir("/sys/class/bluetooth/hci0");
        fake.mkdir("/sys/class/bluetooth/hci0:256");
        fake.file("/proc/412/comm", "bluetoothd\n");
        fake.file("/proc/self/comm", "bluetoothd\n"); // not a pid: ignored
        fake.file("/usr/bin/rfcomm", "");
        std::fs::set_permissions(fake.dir.join("usr/bin/rfcomm"), std::fs::Permissions::from_mode(0o755))
            .unwrap();
        // BlueZ's store: the GPS offers SPP, the headphones do not.
        let store = "/var/lib/bluetooth/00:1A:7D:DA:71:13";
        fake.file(
            &format!("{store}/00:0B:0D:88:A4:1C/info"),
            "[General]\nName=BT-359\nServices=00001101-0000-1000-8000-00805F9B34FB;\nTrusted=true\n",
        );
        fake.file(
            &format!("{store}/00:0B:0D:88:A4:1D/info"),
            "[General]\nName=Headphones\nServices=0000110b-0000-1000-8000-00805f9b34fb;\n",
        );
        fake.file("/dev/rfcomm0", "");
        let after = bluetooth_findings(&env);
        assert!(after.iter().all(|f| f.verdict == Verdict::Ok), "{after:?}");
        let paired = after.iter().find(|f| f.check == "paired SPP devices").unwrap();
        assert_eq!(paired.detail, "BT-359 (00:0B:0D:88:A4:1C)");
        assert_eq!(after[0].detail, "adapter hci0");
    }

    #[test]
    fn broker_reachability_over_real_tcp() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        assert_eq!(
            reach_broker(&format!("mqtt://127.0.0.1:{port}/topic"), BROKER_TIMEOUT).unwrap().port(),
            port
        );
        assert!(reach_broker(&format!("user:pw@127.0.0.1:{port}"), BROKER_TIMEOUT).is_ok());
        drop(listener);
        let err = reach_broker(&format!("tcp://127.0.0.1:{port}"), BROKER_TIMEOUT).unwrap_err();
        assert!(err.contains(&format!("127.0.0.1:{port}")), "{err}");
        assert!(reach_broker("mqtt://", BROKER_TIMEOUT).is_err());
        let fake = FakeRoot::new("broker");
        let f = optional_findings(&fake.env(&[1000], &[]), Some(&format!("mqtt://127.0.0.1:{port}")));
        assert_eq!(f.last().unwrap().verdict, Verdict::Problem);
    }

    #[test]
    fn identity_from_proc_status() {
        // The layout proc(5) documents: real, effective, saved, file-system ids.
        let status =
            "Name:\tcat\nUid:\t1000\t1001\t1000\t1000\nGid:\t100\t20\t100\t100\nGroups:\t20 27 100 \n";
        let id = identity_from_status(status);
        assert_eq!(id.uid, 1001);
        assert_eq!(id.gids, vec![20, 27, 100]);
        // This process, against the kernel's own answer.
        let me = Environment::system();
        assert_eq!(me.identity.uid, rustix::process::geteuid().as_raw());
        assert!(me.identity.gids.contains(&rustix::process::getegid().as_raw()));
    }

    #[test]
    fn report_json_and_text() {
        let report = Report {
            findings: vec![
                Finding::new(Area::Folders, "data folder", Verdict::Ok, "fine").fix("never shown"),
                Finding::new(Area::SerialPorts, "/dev/ttyUSB0", Verdict::Problem, "no").fix("do this"),
            ],
        };
        assert_eq!(report.worst(), Verdict::Problem);
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["findings"][1]["area"], "serial_ports");
        assert_eq!(json["findings"][1]["verdict"], "problem");
        let text = render_text(&report);
        assert!(text.contains("fix: do this") && !text.contains("never shown"), "{text}");
        assert!(text.ends_with("1 problem(s), 0 warning(s)\n"));
    }
}
