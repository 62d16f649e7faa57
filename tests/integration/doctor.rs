//! `vestnav doctor` as a user runs it: the real binary on this machine, once as an unprivileged user who
//! cannot open a real pseudo-terminal nor write their data folder (checked against the kernel's own refusal),
//! once with the data folder on a read-only file system; and the packaging script's dependencies against
//! the libraries the doctor checks.
#![cfg(unix)]

use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

/// A temporary folder removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("vestnav-it-doctor-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `vestnav doctor --json ARGS` with the XDG folders under `home`, optionally run through `prefix` (setpriv).
fn doctor(prefix: &[&str], home: &Path, args: &[&str]) -> (Output, Value) {
    let bin = env!("CARGO_BIN_EXE_vestnav");
    let mut cmd = if let Some((first, rest)) = prefix.split_first() {
        let mut c = Command::new(first);
        c.args(rest).arg(bin);
        c
    } else {
        Command::new(bin)
    };
    cmd.args(["doctor", "--json"]).args(args).env("HOME", home);
    for var in ["XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME"] {
        cmd.env_remove(var);
    }
    let out = cmd.output().expect("run vestnav doctor");
    let json = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)));
    (out, json)
}

fn finding<'a>(json: &'a Value, check: &str) -> &'a Value {
    json["findings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["check"] == check)
        .unwrap_or_else(|| panic!("no finding {check}: {json:#}"))
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .is_ok_and(|s| s.lines().any(|l| l.starts_with("Uid:") && l.split_whitespace().nth(2) == Some("0")))
}

#[test]
fn json_report_covers_every_area_and_the_exit_status_follows_problems() {
    let home = TempDir::new("areas");
    let (out, json) = doctor(&[], &home.0, &[]);
    let areas: Vec<&str> =
        json["findings"].as_array().unwrap().iter().filter_map(|f| f["area"].as_str()).collect();
    for area in ["serial_ports", "bluetooth", "display", "folders", "optional"] {
        assert!(areas.contains(&area), "{area} missing: {json:#}");
    }
    for f in json["findings"].as_array().unwrap() {
        assert!(["ok", "info", "warning", "problem"].contains(&f["verdict"].as_str().unwrap()), "{f}");
    }
    let problems = json["problems"].as_u64().unwrap();
    assert_eq!(out.status.code(), Some(i32::from(problems > 0)), "{json:#}");
    // The folders are the console's own, under this HOME.
    let data = finding(&json, "data folder")["detail"].as_str().unwrap();
    assert!(data.contains(&home.0.join(".local/share/vestnav").display().to_string()), "{data}");
}

/// An unprivileged user (nobody, no groups) meets a pseudo-terminal only root may open and a data folder
/// inside a home they cannot write. The doctor's verdict on the port is checked against the kernel: the
/// same user's `open` of it must fail.
#[test]
fn an_unprivileged_user_sees_the_port_and_the_folder_they_cannot_use() {
    if !is_root() || !Path::new("/usr/bin/setpriv").exists() {
        eprintln!("skipped: needs root and setpriv to run as another user");
        return;
    }
    let nobody = ["/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "--"];
    // A checkout under /root (mode 0700) is out of nobody's reach: nothing to run then.
    let reach = Command::new(nobody[0])
        .args(&nobody[1..])
        .args([env!("CARGO_BIN_EXE_vestnav"), "--version"])
        .output();
    if !reach.is_ok_and(|o| o.status.success()) {
        eprintln!("skipped: nobody cannot run {}", env!("CARGO_BIN_EXE_vestnav"));
        return;
    }
    let pty = vestnav_device::serial::Pty::open().unwrap();
    std::fs::set_permissions(pty.path(), std::fs::Permissions::from_mode(0o600)).unwrap();
    // The kernel's answer: nobody's open for reading and writing is refused.
    let open = Command::new(nobody[0])
        .args(&nobody[1..])
        .args(["/bin/sh", "-c", &format!("exec 3<>{}", pty.path())])
        .output()
        .unwrap();
    assert!(!open.status.success(), "nobody could open {}", pty.path());

    let home = TempDir::new("nobody"); // owned by root, 0755: nobody may read, not write
    std::fs::set_permissions(&home.0, std::fs::Permissions::from_mode(0o755)).unwrap();
    let (out, json) = doctor(&nobody, &home.0, &["--port", pty.path()]);
    let port = finding(&json, pty.path());
    assert_eq!(port["verdict"], "problem", "{port}");
    assert!(port["detail"].as_str().unwrap().contains("mode 600"), "{port}");
    let data = finding(&json, "data folder");
    assert_eq!(data["verdict"], "problem", "{data}");
    assert!(data["detail"].as_str().unwrap().contains("not writable by nobody"), "{data}");
    assert_eq!(out.status.code(), Some(1));
}

/// The data folder on a real read-only file system (a tmpfs mounted read-only; `XDG_DATA_HOME` points
/// there): even root cannot write it, and the doctor says so with the remount fix.
#[test]
fn a_data_folder_on_a_read_only_file_system() {
    let dir = TempDir::new("ro");
    let mnt = dir.0.join("ro");
    std::fs::create_dir_all(&mnt).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "ro,size=1m", "vestnav-doctor-it"])
        .arg(&mnt)
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped: cannot mount a tmpfs here");
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["doctor", "--json"])
        .env("HOME", &dir.0)
        .env("XDG_DATA_HOME", &mnt)
        .output();
    let _ = Command::new("umount").arg(&mnt).status();
    let out = out.unwrap();
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let data = finding(&json, "data folder");
    assert_eq!(data["verdict"], "problem", "{data}");
    assert!(data["fix"].as_str().unwrap().contains("read-only"), "{data}");
    assert_eq!(out.status.code(), Some(1));
}

/// A broker that answers, and one that does not, on 127.0.0.1.
#[test]
fn broker_option_checks_tcp_reachability() {
    let home = TempDir::new("broker");
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("mqtt://127.0.0.1:{}", listener.local_addr().unwrap().port());
    let (_, json) = doctor(&[], &home.0, &["--broker", &url]);
    assert_eq!(finding(&json, "broker")["verdict"], "ok");
    let refusing = vestnav_device::testkit::RefusingPort::bind().unwrap();
    let url = format!("mqtt://{}", refusing.addr());
    let (out, json) = doctor(&[], &home.0, &["--broker", &url]);
    assert_eq!(finding(&json, "broker")["verdict"], "problem");
    assert_eq!(out.status.code(), Some(1));
}

/// The package depends on every library the doctor checks for the window (both are lists of Debian
/// package names; the script's is what `apt` installs).
#[test]
fn the_package_depends_on_the_window_libraries_the_doctor_checks() {
    let script =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/deb.sh")).unwrap();
    let line = script.lines().find_map(|l| l.strip_prefix("window=\"")).expect("window= line in deb.sh");
    let mut in_script: Vec<&str> = line.trim_end_matches('"').split(", ").collect();
    let mut in_doctor = vestnav_device::doctor::window_packages();
    in_script.sort_unstable();
    in_doctor.sort_unstable();
    assert_eq!(in_script, in_doctor);
}
