//! Where the station's devices are: the GPS source (the device crate's one spec, `--gps`'s text form and
//! the settings file's serde form) and the vest (`--vest`).

use serde::{Deserialize, Serialize};

/// Where the GPS fixes come from: the device crate's one GPS source spec, under the name the station and
/// the console use.
pub use vestnav_device::gps::GpsSourceSpec as GpsSourceConfig;

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

/// The forms `--vest` takes, for messages.
pub const VEST_SPEC_FORMS: &str = "emulated | serial:PATH";

/// Parses a `--gps` value (`gpsd://HOST:PORT`, `serial:PATH[@BAUD]`, `replay:FILE[@SPEED]`,
/// `sim[:ROUTE.gpx]`, `vest[@BAUD]`), saying which option it was for when it is wrong.
pub fn parse_gps_spec(spec: &str) -> Result<GpsSourceConfig, String> {
    spec.parse().map_err(|e| format!("--gps {e}"))
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
    fn command_line_vest_specs() {
        assert_eq!(parse_vest_spec("emulated").unwrap(), VestSourceConfig::Emulated);
        assert_eq!(
            parse_vest_spec("serial:/dev/pts/3").unwrap(),
            VestSourceConfig::Serial { port: "/dev/pts/3".into() }
        );
        assert!(parse_vest_spec("serial:").is_err());
        assert!(parse_vest_spec("bluetooth").is_err());
        assert!(parse_gps_spec("tcp:x").unwrap_err().starts_with("--gps"));
    }
}
