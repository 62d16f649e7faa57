//! Where the station's devices are: the GPS source and the vest, as the command line (`--gps`, `--vest`),
//! the console's settings file and the running station name them.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Where the GPS fixes come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum GpsSourceConfig {
    /// The built-in simulator walking the loaded route.
    Simulator,
    /// A serial port (Bluetooth SPP ports are serial ports); `baud: None` = automatic detection.
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate, or `None` for automatic detection.
        baud: Option<u32>,
    },
    /// An NMEA log replayed at `speed` × recorded time (0 = as fast as possible).
    Replay {
        /// The log file.
        path: PathBuf,
        /// Replay speed factor.
        speed: f64,
    },
    /// A gpsd daemon.
    Gpsd {
        /// Host name or address.
        host: String,
        /// TCP port (gpsd's default is 2947).
        port: u16,
    },
    /// The receiver on the vest unit's second UART, forwarded inside the vest's link (protocol v2 units
    /// with a GPS receiver, e.g. the reference firmware's Mega build).
    ThroughVest {
        /// The receiver's baud rate on the unit's UART.
        baud: u32,
    },
}

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

/// A GPS source named on the command line (`vestnav --gps SPEC`), with the route the simulator should
/// walk when one is given (`sim:ROUTE.gpx`).
#[derive(Debug, Clone, PartialEq)]
pub struct GpsSpec {
    /// The source.
    pub source: GpsSourceConfig,
    /// A route file to load (and, for the simulator, to walk).
    pub route: Option<PathBuf>,
}

/// The forms `--gps` takes, for messages.
pub const GPS_SPEC_FORMS: &str =
    "gpsd://HOST:PORT | serial:PATH[@BAUD] | replay:FILE[@SPEED] | sim[:ROUTE.gpx] | vest[@BAUD]";
/// The forms `--vest` takes, for messages.
pub const VEST_SPEC_FORMS: &str = "emulated | serial:PATH";

/// Parses a `--gps` value: `gpsd://HOST:PORT`, `serial:PATH[@BAUD]`, `replay:FILE[@SPEED]`,
/// `sim[:ROUTE.gpx]` or `vest[@BAUD]` (the receiver on the vest unit's second UART, default 9600 baud). A `@` suffix is only taken as a baud or speed when it parses as one, so paths with
/// `@` in them still work; a serial port without `@BAUD` detects the baud rate.
pub fn parse_gps_spec(spec: &str) -> Result<GpsSpec, String> {
    let bad = |why: &str| format!("--gps {spec:?}: {why} (expected {GPS_SPEC_FORMS})");
    if let Some(rest) = spec.strip_prefix("gpsd://") {
        let (host, port) = rest.rsplit_once(':').ok_or_else(|| bad("missing :PORT"))?;
        let host = host.trim_start_matches('[').trim_end_matches(']');
        if host.is_empty() {
            return Err(bad("missing host"));
        }
        let port: u16 = port.parse().ok().filter(|p| *p > 0).ok_or_else(|| bad("port must be 1-65535"))?;
        return Ok(GpsSpec { source: GpsSourceConfig::Gpsd { host: host.to_owned(), port }, route: None });
    }
    if let Some(rest) = spec.strip_prefix("serial:") {
        let (port, baud) = match rest.rsplit_once('@') {
            Some((p, b)) if !p.is_empty() => match b.parse::<u32>() {
                Ok(b) if (300..=4_000_000).contains(&b) => (p, Some(b)),
                Ok(_) => return Err(bad("baud must be 300-4000000")),
                Err(_) => (rest, None),
            },
            _ => (rest, None),
        };
        if port.is_empty() {
            return Err(bad("missing port path"));
        }
        return Ok(GpsSpec { source: GpsSourceConfig::Serial { port: port.to_owned(), baud }, route: None });
    }
    if let Some(rest) = spec.strip_prefix("replay:") {
        let (file, speed) = match rest.rsplit_once('@') {
            Some((f, s)) if !f.is_empty() => match s.parse::<f64>() {
                Ok(v) if v.is_finite() && (0.0..=1000.0).contains(&v) => (f, v),
                Ok(_) => return Err(bad("speed must be 0 (as fast as possible) to 1000")),
                Err(_) => (rest, 1.0),
            },
            _ => (rest, 1.0),
        };
        if file.is_empty() {
            return Err(bad("missing file"));
        }
        return Ok(GpsSpec {
            source: GpsSourceConfig::Replay { path: PathBuf::from(file), speed },
            route: None,
        });
    }
    if spec == "sim" {
        return Ok(GpsSpec { source: GpsSourceConfig::Simulator, route: None });
    }
    if spec == "vest" || spec.starts_with("vest@") {
        let baud = match spec.strip_prefix("vest@") {
            None => 9600,
            Some(b) => b
                .parse::<u32>()
                .ok()
                .filter(|b| vestnav_device::wtcu::message::GPS_BAUDS.contains(b))
                .ok_or_else(|| {
                    bad("the vest unit's receiver baud must be 4800, 9600, 19200, 38400, 57600 or 115200")
                })?,
        };
        return Ok(GpsSpec { source: GpsSourceConfig::ThroughVest { baud }, route: None });
    }
    if let Some(route) = spec.strip_prefix("sim:") {
        if route.is_empty() {
            return Err(bad("missing route file after sim:"));
        }
        return Ok(GpsSpec { source: GpsSourceConfig::Simulator, route: Some(PathBuf::from(route)) });
    }
    Err(bad("unknown source"))
}

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
    fn command_line_device_specs() {
        let g = |s: &str| parse_gps_spec(s).map(|x| (x.source, x.route));
        assert_eq!(
            g("gpsd://127.0.0.1:2947").unwrap(),
            (GpsSourceConfig::Gpsd { host: "127.0.0.1".into(), port: 2947 }, None)
        );
        assert_eq!(
            g("gpsd://[::1]:3000").unwrap().0,
            GpsSourceConfig::Gpsd { host: "::1".into(), port: 3000 }
        );
        assert_eq!(
            g("serial:/dev/rfcomm0@4800").unwrap().0,
            GpsSourceConfig::Serial { port: "/dev/rfcomm0".into(), baud: Some(4800) }
        );
        assert_eq!(
            g("serial:/dev/ttyUSB0").unwrap().0,
            GpsSourceConfig::Serial { port: "/dev/ttyUSB0".into(), baud: None }
        );
        assert_eq!(
            g("replay:walk.nmea@10").unwrap().0,
            GpsSourceConfig::Replay { path: "walk.nmea".into(), speed: 10.0 }
        );
        assert_eq!(
            g("replay:a@b.nmea").unwrap().0,
            GpsSourceConfig::Replay { path: "a@b.nmea".into(), speed: 1.0 }
        );
        assert_eq!(g("sim").unwrap(), (GpsSourceConfig::Simulator, None));
        assert_eq!(g("vest").unwrap().0, GpsSourceConfig::ThroughVest { baud: 9600 });
        assert_eq!(g("vest@38400").unwrap().0, GpsSourceConfig::ThroughVest { baud: 38_400 });
        assert!(g("vest@1234").unwrap_err().contains("4800"));
        assert_eq!(g("sim:r.gpx").unwrap(), (GpsSourceConfig::Simulator, Some("r.gpx".into())));
        for bad in [
            "gpsd://host",
            "gpsd://:1",
            "gpsd://h:0",
            "serial:",
            "serial:/dev/x@7",
            "replay:",
            "sim:",
            "tcp:x",
        ] {
            let e = parse_gps_spec(bad).unwrap_err();
            assert!(e.contains(GPS_SPEC_FORMS), "{e}");
        }
        assert_eq!(parse_vest_spec("emulated").unwrap(), VestSourceConfig::Emulated);
        assert_eq!(
            parse_vest_spec("serial:/dev/pts/3").unwrap(),
            VestSourceConfig::Serial { port: "/dev/pts/3".into() }
        );
        assert!(parse_vest_spec("serial:").is_err());
        assert!(parse_vest_spec("bluetooth").is_err());
    }
}
