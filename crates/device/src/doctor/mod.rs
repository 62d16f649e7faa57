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
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

use serde::Serialize;

mod bluetooth;
mod folders;
mod libraries;
mod ports;

pub use bluetooth::bluetooth_findings;
pub use folders::folder_finding;
pub use libraries::{display_findings, optional_findings, reach_broker, window_packages};
pub use ports::{port_findings, serial_findings};

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

    use super::bluetooth::*;
    use super::folders::*;
    use super::libraries::*;
    use super::ports::*;
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
    }

    #[test]
    fn optional_parts_are_never_a_problem_when_absent() {
        let fake = FakeRoot::new("optional");
        let env = fake.env(&[1000], &[("HOME", "/home/alice")]);
        let found = optional_findings(&env, None);
        // liblsl is looked for by vestnav-lsl's own search (its tests cover the places); found or not, it is
        // never a problem. gpsd absent is only information; no broker configured is not a problem either.
        assert!(found.iter().any(|f| f.check == "liblsl"));
        assert!(found.iter().all(|f| f.verdict != Verdict::Problem), "{found:?}");
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
        // A port nobody listens on, and nobody can take while the test runs.
        let refusing = crate::testkit::RefusingPort::bind().unwrap();
        let port = refusing.port();
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
