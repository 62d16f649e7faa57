//! Integration tests: the command line as a user meets it (`--help`, shell completions, the man page) and the
//! distribution files beside it (licences, the third-party licence notice).

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the binary and returns its standard output, failing the test on a non-zero exit.
fn vestnav(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().expect("run vestnav");
    assert!(
        out.status.success(),
        "vestnav {args:?} failed ({}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// The subcommands a user types; each must be in the help, the completions and the man page.
const SUBCOMMANDS: [&str; 9] =
    ["sim", "analyze", "nmea", "gps", "emulate", "nav", "fieldtest", "tiles", "doctor"];

#[test]
fn help_says_that_no_subcommand_opens_the_console() {
    let help = vestnav(&["--help"]);
    assert!(help.contains("Run with no subcommand to open the console"), "{help}");
    assert!(help.contains("--gps <SPEC>") && help.contains("--vest <SPEC>"), "console options: {help}");
    for sub in SUBCOMMANDS {
        assert!(help.contains(&format!("\n  {sub} ")), "{sub} listed: {help}");
    }
    // The generators are named in the footer, not in the list of commands.
    assert!(!help.contains("\n  completions ") && !help.contains("\n  man "), "{help}");
    assert!(help.contains("vestnav completions <bash|zsh|fish|powershell|elvish>"), "{help}");
    assert!(help.contains("vestnav man"), "{help}");

    let short = vestnav(&["-h"]);
    assert!(short.contains("vestnav [OPTIONS]     opens the console"), "{short}");
}

#[test]
fn bash_completions_name_every_subcommand() {
    let bash = vestnav(&["completions", "bash"]);
    assert!(bash.contains("_vestnav()"), "{bash}");
    for sub in SUBCOMMANDS {
        assert!(bash.contains(&format!("vestnav,{sub})")), "{sub} completed: {bash}");
    }
    assert!(bash.contains("--gps") && bash.contains("--vest"), "{bash}");
    // Nested subcommands are completed too.
    assert!(bash.contains("two-point") && bash.contains("drift") && bash.contains("cones"), "{bash}");
}

#[test]
fn completions_for_every_shell_are_generated() {
    for shell in ["bash", "zsh", "fish", "powershell", "elvish"] {
        let script = vestnav(&["completions", shell]);
        assert!(script.contains("vestnav") && script.contains("fieldtest"), "{shell}: {script}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(["completions", "tcsh"]).output().unwrap();
    assert!(!out.status.success(), "an unknown shell is an error");
}

#[test]
fn man_page_is_roff_and_names_the_program() {
    let man = vestnav(&["man"]);
    assert!(man.starts_with(".ie") || man.starts_with(".TH"), "roff: {man}");
    assert!(man.contains(".TH vestnav 1"), "title line: {man}");
    assert!(man.contains(".SH NAME\nvestnav \\- "), "NAME section: {man}");
    assert!(man.contains("Run with no subcommand to open the console"), "{man}");
    for sub in SUBCOMMANDS {
        assert!(man.contains(&format!("vestnav\\-{sub}(1)")), "{sub} in SUBCOMMANDS: {man}");
    }
}

#[test]
fn licence_files_name_the_vestnav_developers() {
    let mit = std::fs::read_to_string(root().join("LICENSE-MIT")).unwrap();
    assert!(mit.starts_with("MIT License") && mit.contains("The vestnav developers"), "{mit}");
    let apache = std::fs::read_to_string(root().join("LICENSE-APACHE")).unwrap();
    assert!(apache.contains("Apache License") && apache.contains("Version 2.0, January 2004"));
    assert!(apache.contains("The vestnav developers"));
}

/// The `(name, version)` of every third-party package in a Cargo.lock: those with a `source` (registry or git);
/// path packages, our own crates, have none.
fn locked_registry_packages(lock: &str) -> BTreeSet<(String, String)> {
    let value = |line: &str, key: &str| {
        line.strip_prefix(key)
            .and_then(|rest| rest.strip_prefix(" = \""))
            .and_then(|rest| rest.strip_suffix('"'))
            .map(str::to_owned)
    };
    let mut found = BTreeSet::new();
    for block in lock.split("[[package]]").skip(1) {
        let (mut name, mut version, mut sourced) = (None, None, false);
        for line in block.lines() {
            name = name.or_else(|| value(line, "name"));
            version = version.or_else(|| value(line, "version"));
            sourced |= line.starts_with("source = ");
        }
        if let (Some(name), Some(version), true) = (name, version, sourced) {
            found.insert((name, version));
        }
    }
    found
}

#[test]
fn third_party_notice_names_every_locked_crate() {
    let lock = std::fs::read_to_string(root().join("Cargo.lock")).unwrap();
    let notice = std::fs::read_to_string(root().join("THIRD-PARTY-LICENSES.md")).unwrap();
    let locked = locked_registry_packages(&lock);
    assert!(locked.len() > 100 && locked.iter().any(|(name, _)| name == "clap_mangen"), "{locked:?}");
    let missing: Vec<String> = locked
        .iter()
        .filter(|(name, version)| !notice.contains(&format!("\n| {name} | {version} | ")))
        .map(|(name, version)| format!("{name} {version}"))
        .collect();
    assert!(
        missing.is_empty(),
        "THIRD-PARTY-LICENSES.md is stale: run scripts/third-party-licenses.sh. Missing: {}",
        missing.join(", ")
    );
}

#[test]
fn lock_parser_skips_our_own_crates() {
    let lock = "version = 4\n\n[[package]]\nname = \"a\"\nversion = \"1.2.3\"\nsource = \
                \"registry+https://github.com/rust-lang/crates.io-index\"\nchecksum = \"00\"\n\n[[package]]\n\
                name = \"vestnav-core\"\nversion = \"0.1.0\"\ndependencies = [\n \"a\",\n]\n";
    let found = locked_registry_packages(lock);
    assert_eq!(found.into_iter().collect::<Vec<_>>(), [("a".to_owned(), "1.2.3".to_owned())]);
}

/// Runs the console with `args` and no display, for at most 20 s; returns (success, stderr).
fn console_refusal(args: &[&str]) -> (bool, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run vestnav");
    let end = std::time::Instant::now() + std::time::Duration::from_secs(20);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut err = String::new();
            std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
            return (status.success(), err);
        }
        assert!(std::time::Instant::now() < end, "vestnav {args:?} did not end");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Issue 23 item 6: `--gps replay:MISSING`, a `--tiles` file that is not a tile store and a `--map` file
/// that is no OSM extract are refused before the window opens, naming the file, with a non-zero exit.
#[test]
fn console_files_are_checked_before_the_window_opens() {
    let (ok, err) = console_refusal(&["--gps", "replay:/nonexistent/walk.nmea"]);
    assert!(!ok);
    assert!(err.contains("--gps") && err.contains("/nonexistent/walk.nmea"), "{err}");
    let dir = std::env::temp_dir().join(format!("vestnav-cli-tiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("area.pmtiles");
    std::fs::write(&bad, b"this is not a PMTiles archive, only some text that is long enough").unwrap();
    let (ok, err) = console_refusal(&["--tiles", bad.to_str().unwrap()]);
    assert!(!ok);
    assert!(err.contains("--tiles") && err.contains("area.pmtiles"), "{err}");
    let not_an_extract = dir.join("area.osm.pbf");
    std::fs::write(&not_an_extract, b"<osm version='0.6'/> is XML, not the PBF format").unwrap();
    let (ok, err) = console_refusal(&["--map", not_an_extract.to_str().unwrap()]);
    assert!(!ok);
    assert!(err.contains("--map") && err.contains("area.osm.pbf"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs the binary expecting failure; returns its standard error.
fn vestnav_fails(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().expect("run vestnav");
    assert!(!out.status.success(), "vestnav {args:?} should fail: {}", String::from_utf8_lossy(&out.stdout));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Errors are said once (issue 23, item 11): the file named once, the OS error once.
#[test]
fn errors_name_the_file_and_the_cause_once() {
    let readme = root().join("README.md");
    let readme = readme.to_str().unwrap();
    let err = vestnav_fails(&["nav", "simulate", "--route", readme, "--runs", "1"]);
    assert_eq!(err.matches("README.md").count(), 1, "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");

    let png = format!("/no/such/dir-{}/x.png", std::process::id());
    let err = vestnav_fails(&["sim", "tactor", "--png", &png]);
    // The OS's own words, as `std::io::Error` prints them for ENOENT.
    let os = std::io::Error::from_raw_os_error(2).to_string();
    assert_eq!(err.matches(&os).count(), 1, "{err}");
    assert_eq!(err.matches(&png).count(), 1, "{err}");
}

/// A file that is no GPS log is reported as such, with a non-zero exit (issue 23, item 11).
#[test]
fn decoding_a_non_nmea_file_fails_and_says_why() {
    let readme = root().join("README.md");
    let err = vestnav_fails(&["nmea", "decode", readme.to_str().unwrap()]);
    assert!(err.contains("README.md: not an NMEA log"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    // A real log still decodes with exit 0.
    let log = root().join("tests/data/gpsd-logs/firefly-II.log");
    let out =
        Command::new(env!("CARGO_BIN_EXE_vestnav")).args(["nmea", "decode"]).arg(&log).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// A negative number is parsed as a value and then validated, not refused as an unknown option.
#[test]
fn negative_values_are_parsed_then_validated() {
    let err = vestnav_fails(&["sim", "two-point", "--distance-mm", "-5000"]);
    assert!(err.contains("--distance-mm must be finite and within ±1000 mm"), "{err}");
    assert!(!err.contains("unexpected argument"), "{err}");
    let out = vestnav(&["sim", "two-point", "--distance-mm", "-5", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(v.to_string().contains("-5"), "{out}");
}
