//! [`GpsSourceSpec`]: the one way to name a GPS source, for the command line (`--gps`), the console's
//! settings file and the GPS panel; and [`ReplaySpeed`], the one meaning of a replay's pace.
//!
//! The text form ([`std::str::FromStr`] and [`std::fmt::Display`], which round-trip) is
//! [`GPS_SPEC_FORMS`]; the serde form is what `console.json` has always stored (`"Simulator"`,
//! `{"Serial":{"port":"/dev/rfcomm0","baud":null}}`, `{"Replay":{"path":"walk.nmea","speed":1.0}}` with
//! speed 0 for as fast as possible, `{"Gpsd":{"host":"127.0.0.1","port":2947}}`,
//! `{"ThroughVest":{"baud":9600}}`), plus `{"Simulator":{"route":"r.gpx"}}` for a simulator given a route.
//! A running source is started from a [`super::SourceConfig`], which adds what only exists at run time (the
//! loaded route, the vest's byte pipe).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::wtcu::message::GPS_BAUDS;

/// The forms a GPS source spec takes (for messages and help).
pub const GPS_SPEC_FORMS: &str =
    "gpsd://HOST:PORT | serial:PATH[@BAUD] | replay:FILE[@SPEED] | sim[:ROUTE.gpx] | vest[@BAUD]";

/// The fastest replay factor accepted.
pub const MAX_REPLAY_SPEED: f64 = 1000.0;
/// The baud rate of the vest unit's receiver when none is named (`vest`).
pub const DEFAULT_VEST_GPS_BAUD: u32 = 9600;
/// Baud rates a serial port spec may name.
pub const SERIAL_BAUDS: std::ops::RangeInclusive<u32> = 300..=4_000_000;

/// How fast a replay plays its log.
///
/// Text and serde write it as one number: the factor, or `0` for [`Self::AsFastAsPossible`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    /// No waiting between lines.
    AsFastAsPossible,
    /// This many times the recorded pace (1 = as recorded): a finite factor in (0, [`MAX_REPLAY_SPEED`]].
    Times(f64),
}

impl Default for ReplaySpeed {
    /// As recorded.
    fn default() -> Self {
        Self::Times(1.0)
    }
}

impl ReplaySpeed {
    /// The speed a factor means: `0` = as fast as possible, else that factor, which must be finite and at
    /// most [`MAX_REPLAY_SPEED`].
    pub fn from_factor(factor: f64) -> Result<Self, SpecError> {
        if factor == 0.0 {
            Ok(Self::AsFastAsPossible)
        } else if factor.is_finite() && factor > 0.0 && factor <= MAX_REPLAY_SPEED {
            Ok(Self::Times(factor))
        } else {
            Err(SpecError(format!("speed {factor} is not 0 (as fast as possible) to {MAX_REPLAY_SPEED}")))
        }
    }

    /// The factor, `0` for as fast as possible (the number the text and serde forms hold).
    pub fn factor(self) -> f64 {
        match self {
            Self::AsFastAsPossible => 0.0,
            Self::Times(f) => f,
        }
    }

    /// The factor to pace by, `None` for no pacing (also for a factor that is not positive and finite,
    /// which [`Self::from_factor`] never makes).
    pub fn pace(self) -> Option<f64> {
        match self {
            Self::AsFastAsPossible => None,
            Self::Times(f) => (f.is_finite() && f > 0.0).then_some(f),
        }
    }
}

impl fmt::Display for ReplaySpeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.factor())
    }
}

impl FromStr for ReplaySpeed {
    type Err = SpecError;

    /// A factor as [`Self::from_factor`] takes it (`0` = as fast as possible).
    fn from_str(s: &str) -> Result<Self, SpecError> {
        let v = s.trim().parse::<f64>().map_err(|_| SpecError(format!("speed {s:?} is not a number")))?;
        Self::from_factor(v)
    }
}

impl Serialize for ReplaySpeed {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(self.factor())
    }
}

impl<'de> Deserialize<'de> for ReplaySpeed {
    /// A hand-edited settings file is forgiven: a factor out of range is clamped into [0, 1000] (0 and
    /// below: as fast as possible), as the console always did, rather than losing every other setting.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = f64::deserialize(d)?;
        if v.is_nan() {
            return Ok(Self::default());
        }
        Ok(if v <= 0.0 { Self::AsFastAsPossible } else { Self::Times(v.min(MAX_REPLAY_SPEED)) })
    }
}

/// Where GPS fixes come from, as the operator names it.
#[derive(Debug, Clone, PartialEq)]
pub enum GpsSourceSpec {
    /// The built-in simulator, walking `route` (a GPX file) when given, else the route loaded in the
    /// console (the demo route by default).
    Simulator {
        /// A GPX route to load and walk.
        route: Option<PathBuf>,
    },
    /// A serial port (USB, Bluetooth SPP `/dev/rfcomm*`, a PTY); `baud: None` detects it.
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate, or `None` for automatic detection.
        baud: Option<u32>,
    },
    /// An NMEA log or recording replayed in time.
    Replay {
        /// The log file.
        path: PathBuf,
        /// How fast.
        speed: ReplaySpeed,
    },
    /// A gpsd daemon's JSON stream.
    Gpsd {
        /// Host name or address (an IPv6 address without brackets).
        host: String,
        /// TCP port (gpsd's default is 2947).
        port: u16,
    },
    /// The receiver on the vest unit's second UART, forwarded inside the vest's link (protocol v2 units
    /// with a GPS receiver, e.g. the reference firmware's Mega build).
    ThroughVest {
        /// The receiver's baud rate on the unit's UART (one of `wtcu::message::GPS_BAUDS`).
        baud: u32,
    },
}

impl Default for GpsSourceSpec {
    /// The simulator on the console's route.
    fn default() -> Self {
        Self::Simulator { route: None }
    }
}

impl GpsSourceSpec {
    /// The route file a simulator spec names (`sim:ROUTE.gpx`).
    pub fn sim_route(&self) -> Option<&Path> {
        match self {
            Self::Simulator { route } => route.as_deref(),
            _ => None,
        }
    }

    /// Checks the files the spec names before anything starts (the console checks `--gps` before its window
    /// opens): a replay's log must be a regular file that can be opened, a simulator's route a GPX the one
    /// reader accepts. The error names the file and why.
    pub fn check_files(&self) -> Result<(), String> {
        match self {
            Self::Replay { path, .. } => vestnav_files::open_regular(path)
                .map(drop)
                .map_err(|e| format!("cannot replay {}: {e}", path.display())),
            Self::Simulator { route: Some(path) } => {
                crate::gps::sim::load_route_gpx(path).map(drop).map_err(|e| e.to_string())
            }
            _ => Ok(()),
        }
    }
}

/// Why a GPS source spec was refused; the text names the spec and the forms expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct SpecError(String);

impl FromStr for GpsSourceSpec {
    type Err = SpecError;

    /// Parses [`GPS_SPEC_FORMS`]. A `@` suffix is taken as a baud or speed only when it parses as a
    /// number, so paths with `@` in them still work (but a serial port path ending in `@NUMBER` needs an
    /// explicit `@BAUD`); a serial port without `@BAUD` detects the baud rate, a replay without `@SPEED`
    /// plays at the recorded pace (`@0`: as fast as possible), `vest` without `@BAUD` is 9600 baud.
    fn from_str(spec: &str) -> Result<Self, SpecError> {
        let bad = |why: &str| SpecError(format!("{spec:?}: {why} (expected {GPS_SPEC_FORMS})"));
        if let Some(rest) = spec.strip_prefix("gpsd://") {
            let (host, port) = rest.rsplit_once(':').ok_or_else(|| bad("missing :PORT"))?;
            let host = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')).unwrap_or(host);
            if host.is_empty() {
                return Err(bad("missing host"));
            }
            if host.chars().any(|c| c.is_whitespace() || matches!(c, '[' | ']' | '/' | '@')) {
                return Err(bad("the host has characters no host name has"));
            }
            let port =
                port.parse::<u16>().ok().filter(|p| *p > 0).ok_or_else(|| bad("port must be 1-65535"))?;
            return Ok(Self::Gpsd { host: host.to_owned(), port });
        }
        if let Some(rest) = spec.strip_prefix("serial:") {
            let (port, baud) = match rest.rsplit_once('@') {
                Some((p, b)) if !p.is_empty() => match b.parse::<u32>() {
                    Ok(b) if SERIAL_BAUDS.contains(&b) => (p, Some(b)),
                    Ok(_) => return Err(bad("baud must be 300-4000000")),
                    Err(_) => (rest, None),
                },
                _ => (rest, None),
            };
            if port.is_empty() {
                return Err(bad("missing port path"));
            }
            return Ok(Self::Serial { port: port.to_owned(), baud });
        }
        if let Some(rest) = spec.strip_prefix("replay:") {
            let (file, speed) = match rest.rsplit_once('@') {
                Some((f, s)) if !f.is_empty() => match s.parse::<f64>() {
                    Ok(v) => (f, ReplaySpeed::from_factor(v).map_err(|e| bad(&e.0))?),
                    Err(_) => (rest, ReplaySpeed::default()),
                },
                _ => (rest, ReplaySpeed::default()),
            };
            if file.is_empty() {
                return Err(bad("missing file"));
            }
            return Ok(Self::Replay { path: PathBuf::from(file), speed });
        }
        if spec == "sim" {
            return Ok(Self::Simulator { route: None });
        }
        if let Some(route) = spec.strip_prefix("sim:") {
            if route.is_empty() {
                return Err(bad("missing route file after sim:"));
            }
            return Ok(Self::Simulator { route: Some(PathBuf::from(route)) });
        }
        if spec == "vest" {
            return Ok(Self::ThroughVest { baud: DEFAULT_VEST_GPS_BAUD });
        }
        if let Some(b) = spec.strip_prefix("vest@") {
            let baud = b.parse::<u32>().ok().filter(|b| GPS_BAUDS.contains(b)).ok_or_else(|| {
                bad("the vest unit's receiver baud must be 4800, 9600, 19200, 38400, 57600 or 115200")
            })?;
            return Ok(Self::ThroughVest { baud });
        }
        Err(bad("unknown source"))
    }
}

impl fmt::Display for GpsSourceSpec {
    /// The text form [`FromStr`] reads back (a replay always with its `@SPEED`, a gpsd IPv6 host in
    /// brackets, the vest's receiver always with its `@BAUD`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Simulator { route: None } => write!(f, "sim"),
            Self::Simulator { route: Some(r) } => write!(f, "sim:{}", r.display()),
            Self::Serial { port, baud: None } => write!(f, "serial:{port}"),
            Self::Serial { port, baud: Some(b) } => write!(f, "serial:{port}@{b}"),
            Self::Replay { path, speed } => write!(f, "replay:{}@{speed}", path.display()),
            Self::Gpsd { host, port } if host.contains(':') => write!(f, "gpsd://[{host}]:{port}"),
            Self::Gpsd { host, port } => write!(f, "gpsd://{host}:{port}"),
            Self::ThroughVest { baud } => write!(f, "vest@{baud}"),
        }
    }
}

/// The serde form: the variants as `console.json` stores them (see the module doc).
#[derive(Serialize, Deserialize)]
#[serde(rename = "GpsSourceSpec")]
enum Stored {
    Simulator { route: Option<PathBuf> },
    Serial { port: String, baud: Option<u32> },
    Replay { path: PathBuf, speed: ReplaySpeed },
    Gpsd { host: String, port: u16 },
    ThroughVest { baud: u32 },
}

/// The simulator without a route, stored as the bare string `"Simulator"`.
#[derive(Serialize, Deserialize)]
#[serde(rename = "GpsSourceSpec")]
enum StoredUnit {
    Simulator,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum StoredAny {
    Unit(StoredUnit),
    Full(Stored),
}

impl Serialize for GpsSourceSpec {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let stored = match self.clone() {
            Self::Simulator { route: None } => return StoredUnit::Simulator.serialize(s),
            Self::Simulator { route } => Stored::Simulator { route },
            Self::Serial { port, baud } => Stored::Serial { port, baud },
            Self::Replay { path, speed } => Stored::Replay { path, speed },
            Self::Gpsd { host, port } => Stored::Gpsd { host, port },
            Self::ThroughVest { baud } => Stored::ThroughVest { baud },
        };
        stored.serialize(s)
    }
}

impl<'de> Deserialize<'de> for GpsSourceSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(match StoredAny::deserialize(d)? {
            StoredAny::Unit(StoredUnit::Simulator) => Self::Simulator { route: None },
            StoredAny::Full(Stored::Simulator { route }) => Self::Simulator { route },
            StoredAny::Full(Stored::Serial { port, baud }) => Self::Serial { port, baud },
            StoredAny::Full(Stored::Replay { path, speed }) => Self::Replay { path, speed },
            StoredAny::Full(Stored::Gpsd { host, port }) => Self::Gpsd { host, port },
            StoredAny::Full(Stored::ThroughVest { baud }) => Self::ThroughVest { baud },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(s: &str) -> Result<GpsSourceSpec, SpecError> {
        s.parse()
    }

    /// Issue 23 item 6: a missing replay file is found before anything starts, and named.
    #[test]
    fn check_files_names_a_missing_replay() {
        let spec: GpsSourceSpec = "replay:/nonexistent/walk.nmea".parse().unwrap();
        let e = spec.check_files().unwrap_err();
        assert!(e.contains("/nonexistent/walk.nmea"), "{e}");
        let here: GpsSourceSpec =
            format!("replay:{}/Cargo.toml", env!("CARGO_MANIFEST_DIR")).parse().unwrap();
        assert_eq!(here.check_files(), Ok(()));
        let dir: GpsSourceSpec = format!("replay:{}", env!("CARGO_MANIFEST_DIR")).parse().unwrap();
        assert!(dir.check_files().is_err(), "a folder is not a log");
        assert_eq!("sim".parse::<GpsSourceSpec>().unwrap().check_files(), Ok(()));
    }

    #[test]
    fn the_documented_forms_parse() {
        use GpsSourceSpec as G;
        assert_eq!(p("gpsd://127.0.0.1:2947").unwrap(), G::Gpsd { host: "127.0.0.1".into(), port: 2947 });
        assert_eq!(p("gpsd://[::1]:3000").unwrap(), G::Gpsd { host: "::1".into(), port: 3000 });
        assert_eq!(
            p("serial:/dev/rfcomm0@4800").unwrap(),
            G::Serial { port: "/dev/rfcomm0".into(), baud: Some(4800) }
        );
        assert_eq!(p("serial:/dev/ttyUSB0").unwrap(), G::Serial { port: "/dev/ttyUSB0".into(), baud: None });
        assert_eq!(
            p("replay:walk.nmea@10").unwrap(),
            G::Replay { path: "walk.nmea".into(), speed: ReplaySpeed::Times(10.0) }
        );
        assert_eq!(
            p("replay:walk.nmea@0").unwrap(),
            G::Replay { path: "walk.nmea".into(), speed: ReplaySpeed::AsFastAsPossible }
        );
        assert_eq!(
            p("replay:a@b.nmea").unwrap(),
            G::Replay { path: "a@b.nmea".into(), speed: ReplaySpeed::Times(1.0) }
        );
        assert_eq!(p("sim").unwrap(), G::Simulator { route: None });
        assert_eq!(p("sim:r.gpx").unwrap(), G::Simulator { route: Some("r.gpx".into()) });
        assert_eq!(p("sim:r.gpx").unwrap().sim_route(), Some(Path::new("r.gpx")));
        assert_eq!(p("vest").unwrap(), G::ThroughVest { baud: 9600 });
        assert_eq!(p("vest@38400").unwrap(), G::ThroughVest { baud: 38_400 });
        assert!(p("vest@1234").unwrap_err().to_string().contains("4800"));
        for bad in [
            "gpsd://host",
            "gpsd://:1",
            "gpsd://h:0",
            "gpsd://h:65536",
            "gpsd://a b:1",
            "serial:",
            "serial:/dev/x@7",
            "replay:",
            "replay:x@-1",
            "replay:x@1001",
            "replay:x@inf",
            "replay:x@NaN",
            "sim:",
            "tcp:x",
            "",
        ] {
            let e = p(bad).unwrap_err().to_string();
            assert!(e.contains(GPS_SPEC_FORMS), "{bad}: {e}");
        }
    }

    #[test]
    fn todays_console_json_forms_still_read() {
        // What console.json holds today (serde's externally tagged form of the app's old enum).
        use GpsSourceSpec as G;
        let cases = [
            (r#""Simulator""#, G::Simulator { route: None }),
            (
                r#"{"Serial":{"port":"/dev/rfcomm0","baud":null}}"#,
                G::Serial { port: "/dev/rfcomm0".into(), baud: None },
            ),
            (
                r#"{"Serial":{"port":"COM5","baud":4800}}"#,
                G::Serial { port: "COM5".into(), baud: Some(4800) },
            ),
            (
                r#"{"Replay":{"path":"/home/op/walk.nmea","speed":1.0}}"#,
                G::Replay { path: "/home/op/walk.nmea".into(), speed: ReplaySpeed::Times(1.0) },
            ),
            (
                r#"{"Replay":{"path":"w.nmea","speed":0.0}}"#,
                G::Replay { path: "w.nmea".into(), speed: ReplaySpeed::AsFastAsPossible },
            ),
            (r#"{"Gpsd":{"host":"10.0.0.2","port":2947}}"#, G::Gpsd { host: "10.0.0.2".into(), port: 2947 }),
            (r#"{"ThroughVest":{"baud":9600}}"#, G::ThroughVest { baud: 9600 }),
        ];
        for (json, want) in cases {
            let got: GpsSourceSpec = serde_json::from_str(json).unwrap();
            assert_eq!(got, want, "{json}");
            // Written back in the same form.
            let v: serde_json::Value = serde_json::from_str(json).unwrap();
            assert_eq!(serde_json::to_value(&got).unwrap(), v, "{json}");
        }
        // A hand-edited speed out of range is clamped, as the console always did.
        let g: GpsSourceSpec = serde_json::from_str(r#"{"Replay":{"path":"w","speed":5000}}"#).unwrap();
        assert_eq!(g, G::Replay { path: "w".into(), speed: ReplaySpeed::Times(1000.0) });
        let g: GpsSourceSpec = serde_json::from_str(r#"{"Replay":{"path":"w","speed":-3}}"#).unwrap();
        assert_eq!(g, G::Replay { path: "w".into(), speed: ReplaySpeed::AsFastAsPossible });
        // A simulator with a route.
        let g = G::Simulator { route: Some("r.gpx".into()) };
        let json = serde_json::to_string(&g).unwrap();
        assert_eq!(json, r#"{"Simulator":{"route":"r.gpx"}}"#);
        assert_eq!(serde_json::from_str::<GpsSourceSpec>(&json).unwrap(), g);
        assert!(serde_json::from_str::<GpsSourceSpec>(r#""Bluetooth""#).is_err());
    }

    /// Specs the text form can hold: paths and hosts without the characters the grammar gives meaning to
    /// in their position (a serial path ending in `@NUMBER` needs its baud, see `from_str`).
    fn spec() -> impl Strategy<Value = GpsSourceSpec> {
        let path = "[a-zA-Z0-9_./ @-]{0,12}[a-zA-Z0-9_.]";
        let speed = prop_oneof![
            Just(ReplaySpeed::AsFastAsPossible),
            (1e-6..=MAX_REPLAY_SPEED).prop_map(ReplaySpeed::Times),
            (1u32..=1000).prop_map(|v| ReplaySpeed::Times(f64::from(v))),
        ];
        let host = prop_oneof!["[a-z0-9.-]{1,20}", "[0-9a-f:]{0,10}:[0-9a-f]{1,4}"];
        prop_oneof![
            proptest::option::of(path).prop_map(|r| GpsSourceSpec::Simulator { route: r.map(PathBuf::from) }),
            (path, proptest::option::of(300u32..=4_000_000))
                .prop_filter("a path ending in @NUMBER needs its baud", |(p, b)| {
                    b.is_some() || p.rsplit_once('@').is_none_or(|(_, s)| s.parse::<u32>().is_err())
                })
                .prop_map(|(port, baud)| GpsSourceSpec::Serial { port, baud }),
            (path, speed).prop_map(|(p, speed)| GpsSourceSpec::Replay { path: PathBuf::from(p), speed }),
            (host, 1u16..).prop_map(|(host, port)| GpsSourceSpec::Gpsd { host, port }),
            proptest::sample::select(GPS_BAUDS.to_vec()).prop_map(|baud| GpsSourceSpec::ThroughVest { baud }),
        ]
    }

    proptest! {
        #[test]
        fn text_form_round_trips(s in spec()) {
            let text = s.to_string();
            prop_assert_eq!(text.parse::<GpsSourceSpec>(), Ok(s), "{}", text);
        }

        #[test]
        fn serde_form_round_trips(s in spec()) {
            let json = serde_json::to_string(&s).unwrap();
            let back = serde_json::from_str::<GpsSourceSpec>(&json).unwrap();
            // serde_json's default float parser may miss the nearest double by one unit in the last place.
            if let (
                GpsSourceSpec::Replay { path: a, speed: ReplaySpeed::Times(x) },
                GpsSourceSpec::Replay { path: b, speed: ReplaySpeed::Times(y) },
            ) = (&back, &s)
            {
                prop_assert!(a == b && (x - y).abs() <= 1e-12 * y.abs(), "{}", json);
            } else {
                prop_assert_eq!(back, s, "{}", json);
            }
        }

        #[test]
        fn no_text_makes_the_parser_panic(t in "\\PC{0,40}") {
            let _ = t.parse::<GpsSourceSpec>();
        }
    }
}
