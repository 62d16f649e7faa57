//! The operator's settings, remembered between runs as JSON in the platform config directory.
//!
//! Location: `directories::ProjectDirs::from("org", "vestnav", "vestnav")` → on Linux
//! `$XDG_CONFIG_HOME/vestnav/console.json` (usually `~/.config/vestnav/console.json`), on macOS
//! `~/Library/Application Support/org.vestnav.vestnav/console.json`, on Windows
//! `%APPDATA%\vestnav\vestnav\config\console.json`. A missing or unreadable file gives the defaults (and the
//! reason is shown once in the status line); the file is rewritten when a setting changes.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{DEFAULT_ON_MS, Pattern};

/// Where the GPS fixes come from: the device crate's one GPS source spec (its text form is `--gps`'s, its
/// serde form what this file has always stored), under the name the console uses.
pub use vestnav_device::gps::{GpsSourceSpec as GpsSourceConfig, ReplaySpeed};

/// Where the vest is.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum VestSourceConfig {
    /// The built-in emulated vest.
    Emulated,
    /// A WTCU on a serial port.
    Serial {
        /// Port path or name.
        port: String,
    },
}

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
    pub tiles: crate::tiles::TileSourceConfig,
    /// Size limit of the tile cache [MB]; the least recently used tiles are pruned above it.
    pub tile_cache_mb: u64,
    /// Tile cache folder; `None` = the platform cache folder (`crate::tiles::cache::default_root`).
    pub tile_cache_dir: Option<PathBuf>,
    /// Parallel downloads of the offline prefetch.
    pub prefetch_parallelism: usize,
    /// Keep the map centred on the wearer.
    pub follow: bool,
    /// Fix age after which the GPS is called stale [s].
    pub stale_after_s: f64,
    /// Fix age after which the fix is called lost [s].
    pub lost_after_s: f64,
    /// Patterns the operator saved.
    pub user_patterns: Vec<Pattern>,
    /// Directory of session logs; `None` = the platform data directory.
    pub log_dir: Option<PathBuf>,
    /// Which heading steers guidance: auto (a fresh, good compass, else COG), compass only, or COG only.
    pub heading_mode: vestnav_core::guidance::HeadingMode,
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
            tiles: crate::tiles::TileSourceConfig::Osm,
            tile_cache_mb: crate::tiles::cache::DEFAULT_LIMIT_MB,
            tile_cache_dir: None,
            prefetch_parallelism: crate::tiles::prefetch::DEFAULT_PARALLELISM,
            follow: true,
            stale_after_s: 3.0,
            lost_after_s: 10.0,
            user_patterns: Vec::new(),
            log_dir: None,
            heading_mode: vestnav_core::guidance::HeadingMode::Auto,
            compass_calibrations: std::collections::BTreeMap::new(),
            light_theme: false,
            large_text: false,
            audible_alarm: true,
            show_satellite_table: false,
            recent: crate::file_dialog::RecentFiles::default(),
        }
    }
}

/// The platform directories of vestnav, if the OS has a home directory.
fn project_dirs() -> Option<directories::ProjectDirs> {
    directories::ProjectDirs::from("org", "vestnav", "vestnav")
}

/// The config file's path (see the module doc), if the platform has a config directory.
pub fn default_path() -> Option<PathBuf> {
    project_dirs().map(|d| d.config_dir().join("console.json"))
}

/// Directory for session logs and the tile cache when the config names none.
pub fn data_dir() -> PathBuf {
    project_dirs().map_or_else(|| std::env::temp_dir().join("vestnav"), |d| d.data_dir().to_path_buf())
}

/// Where the console autosaves the route being edited and restores it from at start-up.
pub fn route_autosave_path() -> PathBuf {
    data_dir().join(crate::route::AUTOSAVE_FILE)
}

impl Config {
    /// Reads `path`; a missing file gives the defaults, a broken one gives the defaults and the reason.
    pub fn load(path: &Path) -> (Self, Option<String>) {
        match std::fs::read_to_string(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (Self::default(), None),
            Err(e) => (Self::default(), Some(format!("cannot read {}: {e}", path.display()))),
            Ok(text) => match serde_json::from_str(&text) {
                Ok(cfg) => (Self::sanitized(cfg), None),
                Err(e) => (Self::default(), Some(format!("ignoring broken {}: {e}", path.display()))),
            },
        }
    }

    /// Writes the config atomically (temp file + rename) so a crash never leaves half a file.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        let tmp = path.with_extension("json.tmp");
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(&tmp, text)?;
        std::fs::rename(&tmp, path)
    }

    /// Clamps values a hand-edited file could set out of range.
    fn sanitized(mut self) -> Self {
        let d = Self::default();
        self.on_ms = self.on_ms.clamp(20, 2000);
        let fix = |v: f64, lo: f64, hi: f64, def: f64| if v.is_finite() { v.clamp(lo, hi) } else { def };
        self.arrival_radius_m = fix(self.arrival_radius_m, 1.0, 100.0, d.arrival_radius_m);
        self.cue_interval_s = fix(self.cue_interval_s, 0.5, 60.0, d.cue_interval_s);
        self.manual_hold_s = fix(self.manual_hold_s, 0.0, 600.0, d.manual_hold_s);
        self.walking_speed_m_s = fix(self.walking_speed_m_s, 0.2, 5.0, d.walking_speed_m_s);
        self.stale_after_s = fix(self.stale_after_s, 1.0, 60.0, d.stale_after_s);
        self.lost_after_s = fix(self.lost_after_s, self.stale_after_s, 600.0, d.lost_after_s);
        self.tile_cache_mb = self.tile_cache_mb.clamp(10, 100_000);
        self.prefetch_parallelism =
            self.prefetch_parallelism.clamp(1, crate::tiles::prefetch::MAX_PARALLELISM);
        self.recent = std::mem::take(&mut self.recent).sanitized();
        self
    }
}

/// The forms `--vest` takes, for messages.
pub const VEST_SPEC_FORMS: &str = "emulated | serial:PATH";

/// Parses a `--vest` value: `emulated` or `serial:PATH`.
pub fn parse_vest_spec(spec: &str) -> Result<VestSourceConfig, String> {
    match spec {
        "emulated" => Ok(VestSourceConfig::Emulated),
        s => match s.strip_prefix("serial:") {
            Some(port) if !port.is_empty() => Ok(VestSourceConfig::Serial { port: port.to_owned() }),
            _ => Err(format!("--vest {spec:?}: expected {VEST_SPEC_FORMS}")),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_line_vest_specs() {
        assert_eq!(parse_vest_spec("emulated").unwrap(), VestSourceConfig::Emulated);
        assert_eq!(
            parse_vest_spec("serial:/dev/pts/3").unwrap(),
            VestSourceConfig::Serial { port: "/dev/pts/3".into() }
        );
        assert!(parse_vest_spec("serial:").is_err());
        assert!(parse_vest_spec("bluetooth").is_err());
    }

    #[test]
    fn round_trip_and_broken_file() {
        let dir = std::env::temp_dir().join(format!("vestnav-cfg-{}", std::process::id()));
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
        std::fs::write(&path, "{ not json").unwrap();
        let (back, err) = Config::load(&path);
        assert_eq!(back, Config::default());
        assert!(err.unwrap().contains("broken"));
        std::fs::write(&path, r#"{"on_ms": 60000, "arrival_radius_m": -4}"#).unwrap();
        let (back, _) = Config::load(&path);
        assert_eq!(back.on_ms, 2000);
        assert!((back.arrival_radius_m - 1.0).abs() < 1e-12);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
