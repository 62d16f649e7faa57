//! The operator's settings, remembered between runs as JSON in the platform config directory.
//!
//! Location: `directories::ProjectDirs::from("org", "vestnav", "vestnav")` → on Linux
//! `$XDG_CONFIG_HOME/vestnav/console.json` (usually `~/.config/vestnav/console.json`), on macOS
//! `~/Library/Application Support/org.vestnav.vestnav/console.json`, on Windows
//! `%APPDATA%\vestnav\vestnav\config\console.json`. A missing file gives the defaults. A broken one
//! (unreadable, truncated, too large, wrong types, binary) also gives the defaults, but is first moved
//! aside to `console.json.corrupt-<UTC time>` and reported as a [`ConfigProblem`] for a banner; when it
//! cannot be moved, saving is refused for the run so it is never overwritten. The file is rewritten
//! atomically when a setting changes.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{DEFAULT_ON_MS, Pattern};

/// Where the GPS fixes come from: the device crate's one GPS source spec (its text form is `--gps`'s, its
/// serde form what this file has always stored), under the name the console uses.
pub use vestnav_device::gps::{GpsSourceSpec as GpsSourceConfig, ReplaySpeed};

pub use vestnav_station::sources::{VEST_SPEC_FORMS, VestSourceConfig, parse_vest_spec};

/// Every remembered setting.
#[allow(clippy::struct_excessive_bools)] // independent on/off settings of the operator, not a state machine
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Config {
    /// GPS source chosen last.
    pub gps: GpsSourceConfig,
    /// Vest chosen last.
    pub vest: VestSourceConfig,
    /// Connect both devices at start-up.
    pub auto_connect: bool,
    /// On-time of a tactor fired by hand [ms].
    pub on_ms: u16,
    /// Automatic guidance on at start-up.
    pub guidance_auto: bool,
    /// Arrival radius around a waypoint [m].
    pub arrival_radius_m: f64,
    /// Minimum time between two automatic cues [s].
    pub cue_interval_s: f64,
    /// Start the route over after its last waypoint.
    pub loop_route: bool,
    /// Guidance strategy: `bearing` (straight at the waypoint) or `pursuit` (look-ahead on the leg).
    pub strategy: String,
    /// How long a manual command holds automatic guidance off [s].
    pub manual_hold_s: f64,
    /// Walking speed assumed for time-to-go when the GPS speed is too low [m/s].
    pub walking_speed_m_s: f64,
    /// Draw map tiles; off = local metric grid only.
    pub map_tiles: bool,
    /// Where the tiles come from (`vestnav --tiles SOURCE` overrides it for one run).
    pub tiles: vestnav_tiles::TileSourceConfig,
    /// The OpenStreetMap extract (`.osm.pbf`) drawn offline under the tiles and routed on
    /// (`vestnav --map FILE` sets it); `None` = none.
    pub osm_map: Option<PathBuf>,
    /// Size limit of the tile cache [MB]; the least recently used tiles are pruned above it.
    pub tile_cache_mb: u64,
    /// Tile cache folder; `None` = the platform cache folder (`vestnav_tiles::cache::default_root`).
    pub tile_cache_dir: Option<PathBuf>,
    /// Parallel downloads of the offline prefetch.
    pub prefetch_parallelism: usize,
    /// Keep the map centred on the wearer.
    pub follow: bool,
    /// Fix age after which the GPS is called stale [s].
    pub stale_after_s: f64,
    /// Fix age after which the fix is called lost [s].
    pub lost_after_s: f64,
    /// The GPS simulator's walker goes where the emulated vest's cues steer it, not along the route.
    pub sim_follows_vest: bool,
    /// Patterns the operator saved.
    pub user_patterns: Vec<Pattern>,
    /// Directory of session logs; `None` = the platform data directory.
    pub log_dir: Option<PathBuf>,
    /// Which heading steers guidance: auto (a fresh, good compass, else COG), compass only, or COG only.
    pub heading_mode: vestnav_core::guidance::HeadingMode,
    /// On a route planned along paths: farther than this from the path is off it [m].
    pub off_path_m: f64,
    /// Off the path this long re-plans the route from where the wearer is [s].
    pub reroute_after_s: f64,
    /// Compass calibrations by unit (its port, or "emulated"), sent to the unit when it connects.
    pub compass_calibrations: std::collections::BTreeMap<String, vestnav_core::compass::Calibration>,
    /// Light, high-contrast theme (for sunlight) instead of the dark one (View menu).
    pub light_theme: bool,
    /// Larger text everywhere (View menu): body text 18 pt instead of 13.
    pub large_text: bool,
    /// Ring the terminal bell once when the GPS fix or the vest link is lost (View menu).
    pub audible_alarm: bool,
    /// The GPS panel's satellite table is open (closed at first: open, it pushes the vest grid down).
    pub show_satellite_table: bool,
    /// The last files used, per kind, and the folder relative typed paths are taken in.
    pub recent: crate::file_dialog::RecentFiles,
    /// The MQTT broker of the Stations window (file names only: the password and key stay in their files);
    /// an empty URL: none. `vestnav --broker` overrides it for one run.
    pub broker: vestnav_remote::BrokerConfig,
    /// Connect to that broker when the console starts.
    pub broker_at_start: bool,
    /// The NTRIP caster of the RTK window (the credentials file's name only, never the password).
    pub ntrip: vestnav_station::ntrip::NtripSettings,
    /// The field tests' reference (the truth) set last, restored at start-up; `None`: none.
    pub field_reference: Option<vestnav_core::accuracy::Reference>,
    /// The Lab outputs window's choices, and whether they ran (started again at the next start).
    pub lab: LabSettings,
}

/// The Lab outputs (View menu) as last started or stopped.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct LabSettings {
    /// The outputs ran when the console closed: started again at start (LSL only when liblsl is found).
    pub on: bool,
    /// LSL streams.
    pub lsl: bool,
    /// OSC messages to `osc_target`.
    pub osc: bool,
    /// The OSC target as typed, `HOST:PORT` (at most [`LabSettings::MAX_TEXT`] characters).
    pub osc_target: String,
    /// The first part of every stream's name (at most 64 characters).
    pub stream_prefix: String,
}

impl Default for LabSettings {
    fn default() -> Self {
        Self {
            on: false,
            lsl: true,
            osc: false,
            osc_target: "127.0.0.1:9000".to_owned(),
            stream_prefix: "vestnav".to_owned(),
        }
    }
}

impl LabSettings {
    /// The longest OSC target kept (a host name's 253 characters and a port).
    pub const MAX_TEXT: usize = 260;

    /// Texts a hand-edited file made too long are cut (the target then fails to parse and says so when
    /// started); outputs with nothing chosen are off.
    fn sanitized(mut self) -> Self {
        let cut = |t: &str, n: usize| t.trim().chars().take(n).collect::<String>();
        self.osc_target = cut(&self.osc_target, Self::MAX_TEXT);
        self.stream_prefix = cut(&self.stream_prefix, 64);
        self.on &= self.lsl || self.osc;
        self
    }
}

impl Default for Config {
    fn default() -> Self {
        Self {
            gps: GpsSourceConfig::default(),
            vest: VestSourceConfig::Emulated,
            auto_connect: true,
            on_ms: DEFAULT_ON_MS,
            guidance_auto: true,
            arrival_radius_m: 8.0,
            cue_interval_s: 4.0,
            loop_route: true,
            strategy: "pursuit".to_owned(),
            manual_hold_s: 10.0,
            walking_speed_m_s: 1.3,
            map_tiles: true,
            tiles: vestnav_tiles::TileSourceConfig::Osm,
            osm_map: None,
            tile_cache_mb: vestnav_tiles::cache::DEFAULT_LIMIT_MB,
            tile_cache_dir: None,
            prefetch_parallelism: vestnav_tiles::prefetch::DEFAULT_PARALLELISM,
            follow: true,
            stale_after_s: 3.0,
            lost_after_s: 10.0,
            sim_follows_vest: false,
            user_patterns: Vec::new(),
            log_dir: None,
            heading_mode: vestnav_core::guidance::HeadingMode::Auto,
            off_path_m: vestnav_station::guidance::default_off_path_m(),
            reroute_after_s: vestnav_station::guidance::default_reroute_after_s(),
            compass_calibrations: std::collections::BTreeMap::new(),
            light_theme: false,
            large_text: false,
            audible_alarm: true,
            show_satellite_table: false,
            recent: crate::file_dialog::RecentFiles::default(),
            broker: vestnav_remote::BrokerConfig::default(),
            broker_at_start: false,
            field_reference: None,
            ntrip: vestnav_station::ntrip::NtripSettings::default(),
            lab: LabSettings::default(),
        }
    }
}

/// The config file's path (see the module doc), if the platform has a config directory.
pub fn default_path() -> Option<PathBuf> {
    crate::dirs::project_dirs().map(|d| d.config_dir().join("console.json"))
}

pub use crate::dirs::data_dir;

/// Where the console autosaves the route being edited and restores it from at start-up.
pub fn route_autosave_path() -> PathBuf {
    data_dir().join(vestnav_station::route::AUTOSAVE_FILE)
}

/// Settings files larger than this are refused as broken (a real one is a few KiB, with many patterns
/// and recent files some hundred).
pub const MAX_CONFIG_BYTES: u64 = 4 * 1024 * 1024;

/// A settings file that could not be used: the console started with the defaults and shows this in a
/// banner until the operator dismisses it ([`ConfigProblem::banner`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigProblem {
    /// The settings file.
    pub path: PathBuf,
    /// Where the broken file was moved (`console.json.corrupt-<UTC time>`), intact; `None` when it could
    /// not be moved, in which case saving is refused for this run ([`Config::save`]), so the file is
    /// never overwritten.
    pub kept_as: Option<PathBuf>,
    /// Why it could not be used (the read or parse error, or the size).
    pub reason: String,
    /// Why it could not be moved aside, when it could not.
    pub not_kept: Option<String>,
}

impl ConfigProblem {
    /// The words of the banner: what happened, where the file is, what the console does about it.
    pub fn banner(&self) -> String {
        match (&self.kept_as, &self.not_kept) {
            (Some(kept), _) => format!(
                "Settings file {} could not be used ({}); started with default settings. \
                 Your file was kept as {}.",
                self.path.display(),
                self.reason,
                kept.display()
            ),
            (None, why) => format!(
                "Settings file {} could not be used ({}); started with default settings. It could not be \
                 moved aside ({}), so setting changes are NOT saved in this run, to leave it untouched.",
                self.path.display(),
                self.reason,
                why.as_deref().unwrap_or("unknown reason")
            ),
        }
    }
}

/// Settings files that were broken and could not be moved aside: never written in this run.
static PROTECTED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn is_protected(path: &Path) -> bool {
    PROTECTED.lock().unwrap_or_else(std::sync::PoisonError::into_inner).iter().any(|p| p == path)
}

impl Config {
    /// Reads `path` (at most [`MAX_CONFIG_BYTES`], a regular file). A missing file gives the defaults and
    /// no problem. A file that cannot be read or parsed (truncated, too large, wrong types, binary, not
    /// UTF-8, a FIFO) gives the defaults and a [`ConfigProblem`], after the file was moved aside with
    /// [`vestnav_files::keep_aside`] so that no later save destroys it.
    pub fn load(path: &Path) -> (Self, Option<ConfigProblem>) {
        Self::load_with(path, vestnav_files::keep_aside)
    }

    /// Reads `path` as [`Config::load`] does but changes nothing on disk: a broken file stays where it is
    /// and the reason is returned (`vestnav doctor` looks; only the console keeps a broken file aside).
    pub fn inspect(path: &Path) -> (Self, Option<String>) {
        match vestnav_files::read_limited(path, MAX_CONFIG_BYTES) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (Self::default(), None),
            Err(e) => (Self::default(), Some(format!("{}: cannot read it: {e}", path.display()))),
            Ok(bytes) => match serde_json::from_slice::<Self>(&bytes) {
                Ok(cfg) => (Self::sanitized(cfg), None),
                Err(e) => (Self::default(), Some(format!("{}: not valid settings: {e}", path.display()))),
            },
        }
    }

    fn load_with(
        path: &Path,
        keep_aside: impl FnOnce(&Path) -> std::io::Result<PathBuf>,
    ) -> (Self, Option<ConfigProblem>) {
        let reason = match vestnav_files::read_limited(path, MAX_CONFIG_BYTES) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return (Self::default(), None),
            Err(e) => format!("cannot read it: {e}"),
            Ok(bytes) => match serde_json::from_slice::<Self>(&bytes) {
                Ok(cfg) => return (Self::sanitized(cfg), None),
                Err(e) => format!("not valid settings: {e}"),
            },
        };
        let (kept_as, not_kept) = match keep_aside(path) {
            Ok(kept) => (Some(kept), None),
            Err(e) => {
                PROTECTED.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push(path.to_path_buf());
                (None, Some(e.to_string()))
            }
        };
        let problem = ConfigProblem { path: path.to_path_buf(), kept_as, reason, not_kept };
        (Self::default(), Some(problem))
    }

    /// Writes the settings atomically ([`vestnav_files::write_atomic`]: a unique temporary file, synced,
    /// renamed), so a crash or a full disk never leaves half a file. Refused for a file that was broken
    /// at [`Config::load`] and could not be moved aside.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        if is_protected(path) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                "not saved: the broken settings file there could not be moved aside and is left untouched",
            ));
        }
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        vestnav_files::ensure_parent(path)?;
        vestnav_files::write_atomic(path, text.as_bytes())
    }

    /// Clamps values a hand-edited file could set out of range.
    fn sanitized(mut self) -> Self {
        use vestnav_station::command::ranges;
        let d = Self::default();
        self.on_ms = self.on_ms.clamp(*ranges::ON_MS.start(), *ranges::ON_MS.end());
        let fix = |v: f64, r: std::ops::RangeInclusive<f64>, def: f64| {
            if v.is_finite() { v.clamp(*r.start(), *r.end()) } else { def }
        };
        self.arrival_radius_m = fix(self.arrival_radius_m, ranges::ARRIVAL_RADIUS_M, d.arrival_radius_m);
        self.cue_interval_s = fix(self.cue_interval_s, ranges::CUE_INTERVAL_S, d.cue_interval_s);
        self.manual_hold_s = fix(self.manual_hold_s, ranges::MANUAL_HOLD_S, d.manual_hold_s);
        self.off_path_m = fix(self.off_path_m, ranges::OFF_PATH_M, d.off_path_m);
        self.reroute_after_s = fix(self.reroute_after_s, ranges::REROUTE_AFTER_S, d.reroute_after_s);
        self.walking_speed_m_s = fix(self.walking_speed_m_s, 0.2..=5.0, d.walking_speed_m_s);
        self.stale_after_s = fix(self.stale_after_s, ranges::STALE_AFTER_S, d.stale_after_s);
        self.lost_after_s =
            fix(self.lost_after_s, self.stale_after_s..=ranges::LOST_AFTER_MAX_S, d.lost_after_s);
        self.tile_cache_mb = self.tile_cache_mb.clamp(10, 100_000);
        self.prefetch_parallelism =
            self.prefetch_parallelism.clamp(1, vestnav_tiles::prefetch::MAX_PARALLELISM);
        self.recent = std::mem::take(&mut self.recent).sanitized();
        self.lab = std::mem::take(&mut self.lab).sanitized();
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vestnav-cfg-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn names_in(dir: &Path) -> Vec<String> {
        let mut v: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn round_trip_and_clamping() {
        let dir = temp_dir("rt");
        let path = dir.join("console.json");
        let cfg = Config {
            gps: GpsSourceConfig::Gpsd { host: "10.0.0.2".into(), port: 2947 },
            on_ms: 300,
            ..Config::default()
        };
        cfg.save(&path).unwrap();
        let (back, err) = Config::load(&path);
        assert!(err.is_none());
        assert_eq!(back, cfg);
        assert_eq!(names_in(&dir), ["console.json"], "no temporary left behind");
        // Out-of-range values are clamped, not a broken file.
        std::fs::write(&path, r#"{"on_ms": 60000, "arrival_radius_m": -4}"#).unwrap();
        let (back, err) = Config::load(&path);
        assert!(err.is_none());
        assert_eq!(back.on_ms, 2000);
        assert!((back.arrival_radius_m - 1.0).abs() < 1e-12);
        // The lab outputs' texts are cut to their limits, outputs with nothing chosen are off.
        let long = "x".repeat(10_000);
        std::fs::write(
            &path,
            format!(r#"{{"lab": {{"on": true, "lsl": false, "osc_target": "{long}", "stream_prefix": "{long}"}}}}"#),
        )
        .unwrap();
        let (back, err) = Config::load(&path);
        assert!(err.is_none());
        assert_eq!(back.lab.osc_target.chars().count(), LabSettings::MAX_TEXT);
        assert_eq!(back.lab.stream_prefix.chars().count(), 64);
        assert!(!back.lab.on, "neither LSL nor OSC chosen: off");
        // Missing: the defaults, nothing to report.
        std::fs::remove_file(&path).unwrap();
        assert_eq!(Config::load(&path), (Config::default(), None));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Each broken form: the defaults, a problem naming the file, the original bytes intact in
    /// `console.json.corrupt-*`, and a later save that writes a fresh file without touching that copy.
    #[test]
    fn broken_settings_are_kept_aside_and_never_overwritten() {
        let mut huge = b"{\"user_patterns\": [".to_vec();
        huge.resize(usize::try_from(MAX_CONFIG_BYTES).unwrap() + 1, b' ');
        let binary: Vec<u8> = (0..=255u8).cycle().take(4096).collect();
        let good = serde_json::to_vec_pretty(&Config { on_ms: 250, ..Config::default() }).unwrap();
        let forms: Vec<(&str, Vec<u8>, &str)> = vec![
            ("truncated", good[..good.len() / 2].to_vec(), "EOF"),
            ("huge", huge, "bytes"),
            ("wrong types", br#"{"on_ms": "loud", "large_text": 3}"#.to_vec(), "invalid type"),
            ("lab wrong types", br#"{"lab": {"on": "yes", "osc_target": 9000}}"#.to_vec(), "invalid type"),
            ("binary", binary, "not valid settings"),
            ("not UTF-8", b"{\"strategy\": \"\xff\xfe\"}".to_vec(), "not valid settings"),
            ("empty", Vec::new(), "EOF"),
        ];
        for (what, bytes, why) in forms {
            let dir = temp_dir("broken");
            let path = dir.join("console.json");
            std::fs::write(&path, &bytes).unwrap();
            let (cfg, problem) = Config::load(&path);
            assert_eq!(cfg, Config::default(), "{what}");
            let problem = problem.unwrap_or_else(|| panic!("{what}: no problem reported"));
            assert_eq!(problem.path, path);
            assert!(problem.reason.contains(why), "{what}: {}", problem.reason);
            let kept = problem.kept_as.clone().unwrap();
            assert!(
                kept.file_name().unwrap().to_string_lossy().starts_with("console.json.corrupt-"),
                "{kept:?}"
            );
            assert_eq!(std::fs::read(&kept).unwrap(), bytes, "{what}: the original bytes, intact");
            let banner = problem.banner();
            assert!(
                banner.contains(&path.display().to_string()) && banner.contains(&kept.display().to_string())
            );
            // A setting changes (View > Large text) and is saved: a fresh file, the copy untouched.
            Config { large_text: true, ..cfg }.save(&path).unwrap();
            assert!(Config::load(&path).0.large_text);
            assert_eq!(std::fs::read(&kept).unwrap(), bytes, "{what}: untouched by the save");
            assert_eq!(names_in(&dir).len(), 2, "{:?}", names_in(&dir));
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_in_place_of_the_settings_does_not_block() {
        let dir = temp_dir("fifo");
        let path = dir.join("console.json");
        assert!(std::process::Command::new("mkfifo").arg(&path).status().unwrap().success());
        let (cfg, problem) = Config::load(&path);
        assert_eq!(cfg, Config::default());
        let problem = problem.unwrap();
        assert!(problem.reason.contains("FIFO"), "{}", problem.reason);
        assert!(problem.kept_as.is_some());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_broken_file_that_cannot_be_moved_is_never_saved_over() {
        let dir = temp_dir("stuck");
        let path = dir.join("console.json");
        std::fs::write(&path, b"{ half").unwrap();
        let (cfg, problem) =
            Config::load_with(&path, |_| Err(std::io::Error::from(std::io::ErrorKind::ReadOnlyFilesystem)));
        let problem = problem.unwrap();
        assert_eq!(problem.kept_as, None);
        assert!(problem.banner().contains("NOT saved"), "{}", problem.banner());
        let err = Config { large_text: true, ..cfg }.save(&path).unwrap_err();
        assert!(err.to_string().contains("left untouched"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), b"{ half");
        // Another file is saved as usual.
        Config::default().save(&dir.join("other.json")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
