//! Receiver configuration: what the operator asks of the GPS receiver ([`ReceiverConfig`]) turned into
//! the receiver family's own commands ([`commands`]), the replies that say whether it took them
//! ([`reply`], [`session`]), and the emulated receiver that answers them ([`emulator`]).
//!
//! Families and documents (docs/gps.md, "Receiver configuration"):
//! - [`Family::Ublox`], u-blox generations 6–8: UBX CFG messages, "u-blox 8 / u-blox M8 Receiver
//!   Description incl. Protocol Specification" (UBX-13003221), §32.10 "UBX-CFG" (u-blox 7: GPS.G7-SW-12001,
//!   u-blox 6: GPS.G6-SW-10018 — the same CFG-RATE and CFG-NAV5 layouts; CFG-GNSS from u-blox 7 on);
//! - [`Family::Ublox9`], u-blox M9/F9: UBX-CFG-VALSET with configuration keys, "u-blox ZED-F9P
//!   Interface Description" (UBX-18010854), §3.10.25 "UBX-CFG-VALSET" and §4 "Configuration interface",
//!   and "NEO-M9N Interface Description" (UBX-19035940);
//! - [`Family::Sirf`], `SiRF` Star III in NMEA mode (the thesis's `GlobalSat` BT-359): `$PSRF100` from the
//!   "NMEA Reference Manual" (`SiRF`, rev. 2.2, "100—SetSerialPort") to switch to binary, MID 143 "Static
//!   Navigation" and MID 129 "Switch To NMEA Protocol" from the "`SiRF` Binary Protocol Reference Manual"
//!   (rev. 2.4), the sequence gpsd's `sirf.c` uses too.
//!
//! ```
//! use vestnav_device::gps::receiver_config::{Family, ReceiverConfig, commands};
//! let cfg = ReceiverConfig { rate_hz: Some(1), ..ReceiverConfig::new(Family::Ublox) };
//! let cmds = commands(&cfg, 9600).unwrap();
//! assert_eq!(cmds[0].bytes, [0xB5, 0x62, 0x06, 0x08, 0x06, 0x00, 0xE8, 0x03, 0x01, 0x00, 0x01, 0x00, 0x01, 0x39]);
//! ```

pub mod emulator;
pub mod reply;
pub mod session;
#[cfg(test)]
mod tests;

use std::time::Duration;

use super::{sirf, ubx};

pub use session::{CommandOutcome, ConfigEvent, ConfigReporter, ConfigSession, ConfigTicket, Outcome};

/// UBX class of the configuration messages.
pub const UBX_CFG: u8 = 0x06;
/// UBX-CFG-CFG: clear, save and load configurations.
pub const UBX_CFG_CFG: u8 = 0x09;
/// UBX-CFG-RATE: navigation/measurement rate.
pub const UBX_CFG_RATE: u8 = 0x08;
/// UBX-CFG-NAV5: navigation engine settings.
pub const UBX_CFG_NAV5: u8 = 0x24;
/// UBX-CFG-GNSS: GNSS system configuration.
pub const UBX_CFG_GNSS: u8 = 0x3E;
/// UBX-CFG-VALSET: set configuration items (generation 9).
pub const UBX_CFG_VALSET: u8 = 0x8A;
/// UBX class of the acknowledgements.
pub const UBX_ACK: u8 = 0x05;
/// UBX-ACK-ACK.
pub const UBX_ACK_ACK: u8 = 0x01;
/// UBX-ACK-NAK.
pub const UBX_ACK_NAK: u8 = 0x00;

/// `SiRF` MID 11 (0x0B), Command Acknowledgment: payload `0B <acknowledged MID>`.
pub const SIRF_MID_ACK: u8 = 0x0B;
/// `SiRF` MID 12 (0x0C), Command `NAcknowledgment`: payload `0C <refused MID>`.
pub const SIRF_MID_NACK: u8 = 0x0C;
/// `SiRF` MID 129 (0x81), Switch To NMEA Protocol.
pub const SIRF_MID_SWITCH_TO_NMEA: u8 = 0x81;
/// `SiRF` MID 143 (0x8F), Static Navigation.
pub const SIRF_MID_STATIC_NAV: u8 = 0x8F;

/// The walking speed below which the thesis's `SiRF` III holds its position with static navigation on
/// [m/s] (thesis §5; `GnssErrorModel::sirf3_open_sky`).
pub const SIRF3_STATIC_NAV_M_S: f64 = 1.2;

/// How long a command waits for its acknowledgement. u-blox: "output ... within one second" (UBX-13003221,
/// §32.9 "UBX-ACK"); `SiRF` answers as fast. 1.5 s leaves room for a Bluetooth link's latency.
pub const ACK_TIMEOUT: Duration = Duration::from_millis(1500);

/// The receiver family, which decides the command set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Family {
    /// u-blox generations 6–8 (NEO-6, NEO-7, NEO-M8 ...): UBX CFG-RATE, CFG-GNSS, CFG-NAV5, CFG-CFG.
    Ublox,
    /// u-blox generation 9 and later (NEO-M9N, ZED-F9P ...): UBX-CFG-VALSET with configuration keys.
    Ublox9,
    /// `SiRF` Star III/IV in NMEA mode: static navigation only, through a visit to `SiRF` binary.
    Sirf,
}

impl Family {
    /// Every family, for pickers.
    pub const ALL: [Self; 3] = [Self::Ublox, Self::Ublox9, Self::Sirf];

    /// The name used on the command line and in the console.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ublox => "ublox",
            Self::Ublox9 => "ublox9",
            Self::Sirf => "sirf",
        }
    }

    /// The family a stream comes from, as far as it shows (`None`: nothing identifying seen yet): `SiRF`
    /// binary frames or `$PSRF…` sentences (the power-on `$PSRFTXT` banner) say `SiRF`; UBX frames, `$PUBX`
    /// or a `TXT` naming u-blox say u-blox (generation 6–8: the stream does not tell 9 apart, the operator
    /// picks M9/F9 in the Receiver window).
    pub fn detect(stats: &crate::gps::DecodeStats) -> Option<Self> {
        if stats.sirf_frames + stats.sirf_sentences > 0 {
            Some(Self::Sirf)
        } else if stats.ubx_frames + stats.ublox_sentences > 0 {
            Some(Self::Ublox)
        } else {
            None
        }
    }

    /// A longer label for the operator.
    pub fn label(self) -> &'static str {
        match self {
            Self::Ublox => "u-blox 6/7/8 (UBX CFG)",
            Self::Ublox9 => "u-blox M9/F9 (CFG-VALSET)",
            Self::Sirf => "SiRF III/IV (NMEA mode)",
        }
    }
}

/// The GNSS a u-blox receiver may track ([`Family::Ublox`] and [`Family::Ublox9`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[allow(clippy::struct_excessive_bools)] // one switch per constellation, as CFG-GNSS has one block each
pub struct Constellations {
    /// GPS (L1C/A).
    pub gps: bool,
    /// GLONASS (L1OF).
    pub glonass: bool,
    /// Galileo (E1).
    pub galileo: bool,
    /// `BeiDou` (B1I).
    pub beidou: bool,
    /// QZSS (L1C/A; u-blox: enable together with GPS).
    pub qzss: bool,
    /// SBAS (WAAS, EGNOS, MSAS ...).
    pub sbas: bool,
}

impl Default for Constellations {
    /// GPS + GLONASS + Galileo with SBAS and QZSS: three major systems, the most a u-blox 8 tracks at once.
    fn default() -> Self {
        Self { gps: true, glonass: true, galileo: true, beidou: false, qzss: true, sbas: true }
    }
}

impl Constellations {
    /// The major systems enabled (GPS, GLONASS, Galileo, `BeiDou`; SBAS and QZSS are augmentations).
    pub fn majors(&self) -> usize {
        [self.gps, self.glonass, self.galileo, self.beidou].iter().filter(|b| **b).count()
    }

    /// Parses a comma list: `gps,glonass,galileo,beidou,qzss,sbas` (case-insensitive; `none` for empty).
    pub fn parse(list: &str) -> Result<Self, String> {
        let mut c =
            Self { gps: false, glonass: false, galileo: false, beidou: false, qzss: false, sbas: false };
        for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match name.to_ascii_lowercase().as_str() {
                "gps" => c.gps = true,
                "glonass" | "glo" => c.glonass = true,
                "galileo" | "gal" => c.galileo = true,
                "beidou" | "bds" => c.beidou = true,
                "qzss" => c.qzss = true,
                "sbas" => c.sbas = true,
                "none" => {}
                other => {
                    return Err(format!(
                        "{other:?}: not a constellation (gps, glonass, galileo, beidou, qzss, sbas)"
                    ));
                }
            }
        }
        Ok(c)
    }

    /// The comma list [`Self::parse`] reads.
    pub fn to_list(&self) -> String {
        let names = [
            (self.gps, "gps"),
            (self.glonass, "glonass"),
            (self.galileo, "galileo"),
            (self.beidou, "beidou"),
            (self.qzss, "qzss"),
            (self.sbas, "sbas"),
        ];
        names.iter().filter(|(on, _)| *on).map(|(_, n)| *n).collect::<Vec<_>>().join(",")
    }
}

/// u-blox's dynamic platform model (CFG-NAV5 `dynModel`, CFG-NAVSPG-DYNMODEL): the navigation filter's
/// assumptions on speed and acceleration (UBX-13003221 §8.1.1 "Dynamic platform", table of models).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum DynamicModel {
    /// 0: portable (the default): moderate speed and acceleration.
    Portable,
    /// 2: stationary: a timing or reference receiver that does not move.
    Stationary,
    /// 3: pedestrian: low speed, low acceleration — the vest's wearer.
    Pedestrian,
    /// 4: automotive.
    Automotive,
    /// 5: at sea.
    Sea,
    /// 6: airborne below 1 g.
    Airborne1g,
}

impl DynamicModel {
    /// Every model, for pickers.
    pub const ALL: [Self; 6] =
        [Self::Portable, Self::Stationary, Self::Pedestrian, Self::Automotive, Self::Sea, Self::Airborne1g];

    /// The `dynModel` value on the wire.
    pub fn code(self) -> u8 {
        match self {
            Self::Portable => 0,
            Self::Stationary => 2,
            Self::Pedestrian => 3,
            Self::Automotive => 4,
            Self::Sea => 5,
            Self::Airborne1g => 6,
        }
    }

    /// The model with wire value `code`.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.code() == code)
    }

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Portable => "portable",
            Self::Stationary => "stationary",
            Self::Pedestrian => "pedestrian",
            Self::Automotive => "automotive",
            Self::Sea => "sea",
            Self::Airborne1g => "airborne1g",
        }
    }

    /// The model named `name` ([`Self::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(name))
    }
}

/// What the operator asks of the receiver; `None` leaves a setting as the receiver has it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ReceiverConfig {
    /// Which command set to speak.
    pub family: Family,
    /// Navigation rate [Hz], 1–10 (u-blox).
    pub rate_hz: Option<u8>,
    /// Constellations to track (u-blox).
    pub constellations: Option<Constellations>,
    /// Dynamic platform model (u-blox).
    pub dynamic_model: Option<DynamicModel>,
    /// u-blox static hold: below this speed the position is held [m/s]; 0 turns it off. Sent in whole
    /// cm/s (0–2.55 m/s).
    pub static_hold_m_s: Option<f64>,
    /// u-blox static hold: the hold is left once the solution moves this far [m] (0–65535; M8 and later).
    pub static_hold_max_dist_m: Option<u16>,
    /// `SiRF` static navigation: `Some(false)` switches it off (what a pedestrian needs), `Some(true)` on.
    pub sirf_static_nav: Option<bool>,
    /// Also save the configuration to the receiver's non-volatile memory (u-blox: CFG-CFG to BBR and
    /// flash; generation 9: the VALSET goes to the RAM, BBR and flash layers). Without it, a power cycle
    /// undoes everything.
    pub save: bool,
}

impl ReceiverConfig {
    /// A configuration of `family` that changes nothing.
    pub fn new(family: Family) -> Self {
        Self {
            family,
            rate_hz: None,
            constellations: None,
            dynamic_model: None,
            static_hold_m_s: None,
            static_hold_max_dist_m: None,
            sirf_static_nav: None,
            save: false,
        }
    }

    /// Checks the settings against the family and the receivers' limits (docs/gps.md): the rate 1–10 Hz,
    /// the static hold 0–2.55 m/s, at least one and at most three major GNSS (u-blox 8's limit; u-blox 7
    /// tracks one of GPS or GLONASS, M9/F9 four), QZSS only with GPS, and only settings the family has.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |s: String| Err(ConfigError::Invalid(s));
        if let Some(r) = self.rate_hz
            && !(1..=10).contains(&r)
        {
            return bad(format!("rate {r} Hz: choose 1 to 10 Hz"));
        }
        if let Some(s) = self.static_hold_m_s
            && !(s.is_finite() && (0.0..=2.555).contains(&s))
        {
            return bad(format!("static hold {s} m/s: choose 0 (off) to 2.55 m/s"));
        }
        if let Some(c) = &self.constellations {
            let max = if self.family == Family::Ublox9 { 4 } else { 3 };
            if c.majors() == 0 {
                return bad("enable at least one of GPS, GLONASS, Galileo, BeiDou".into());
            }
            if c.majors() > max {
                return bad(format!(
                    "{} major GNSS: a {} tracks at most {max} at once",
                    c.majors(),
                    self.family.label()
                ));
            }
            if c.qzss && !c.gps {
                return bad("QZSS needs GPS enabled too (u-blox: same L1C/A signal)".into());
            }
        }
        let ublox_only = self.rate_hz.is_some()
            || self.constellations.is_some()
            || self.dynamic_model.is_some()
            || self.static_hold_m_s.is_some()
            || self.static_hold_max_dist_m.is_some();
        match self.family {
            Family::Sirf if ublox_only => {
                bad("a SiRF receiver in NMEA mode is configured here only for static navigation; rate, \
                 constellations, dynamic model and static hold are u-blox settings"
                    .into())
            }
            Family::Ublox | Family::Ublox9 if self.sirf_static_nav.is_some() => {
                bad("static navigation is a SiRF setting; u-blox calls it static hold".into())
            }
            _ if !ublox_only && self.sirf_static_nav.is_none() && !self.save => {
                bad("nothing to configure".into())
            }
            _ => Ok(()),
        }
    }
}

/// Why a configuration cannot be sent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// A setting out of range, or not one the family has.
    #[error("receiver configuration: {0}")]
    Invalid(String),
}

/// What confirms a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// UBX-ACK-ACK (accepted) or UBX-ACK-NAK (refused) naming this class and id.
    UbxAck {
        /// Class of the command.
        class: u8,
        /// Id of the command.
        id: u8,
    },
    /// `SiRF` MID 11 (accepted) or MID 12 (refused) naming this MID.
    SirfAck {
        /// MID of the command.
        mid: u8,
    },
    /// Nothing: the receiver changes protocol instead of answering. The next command waits `settle`.
    Nothing {
        /// Time the receiver needs before it listens again.
        settle: Duration,
    },
}

/// One command ready for the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigCommand {
    /// Its name in the documents (`CFG-RATE`, `MID 143 Static Navigation`).
    pub name: String,
    /// The whole frame or sentence.
    pub bytes: Vec<u8>,
    /// What confirms it.
    pub expect: Expect,
}

impl ConfigCommand {
    fn ubx(name: &str, id: u8, payload: &[u8]) -> Self {
        Self {
            name: name.to_owned(),
            bytes: ubx::frame(UBX_CFG, id, payload),
            expect: Expect::UbxAck { class: UBX_CFG, id },
        }
    }

    /// The bytes as spaced upper-case hex (u-center's "Messages" view pastes this form).
    pub fn hex(&self) -> String {
        hex(&self.bytes)
    }
}

/// Bytes as spaced upper-case hex.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

/// The commands that apply `cfg`, in the order to send them; `baud` is the link's current rate (the
/// `SiRF` protocol switches keep it).
///
/// u-blox 6–8: CFG-RATE, CFG-GNSS, CFG-NAV5, then CFG-CFG when saving. Generation 9: one CFG-VALSET with
/// every key. `SiRF`: `$PSRF100` (to binary), MID 143, MID 129 (back to NMEA).
pub fn commands(cfg: &ReceiverConfig, baud: u32) -> Result<Vec<ConfigCommand>, ConfigError> {
    cfg.validate()?;
    let hold_cm_s = cfg.static_hold_m_s.map(|v| (v * 100.0).round().clamp(0.0, 255.0) as u8);
    Ok(match cfg.family {
        Family::Ublox => {
            let mut out = Vec::new();
            if let Some(hz) = cfg.rate_hz {
                out.push(ConfigCommand::ubx(
                    "CFG-RATE",
                    UBX_CFG_RATE,
                    &cfg_rate_payload(meas_rate_ms(hz), 1, 1),
                ));
            }
            if let Some(c) = &cfg.constellations {
                out.push(ConfigCommand::ubx("CFG-GNSS", UBX_CFG_GNSS, &cfg_gnss_payload(&gnss_blocks(c))));
            }
            if cfg.dynamic_model.is_some() || hold_cm_s.is_some() || cfg.static_hold_max_dist_m.is_some() {
                let mut n = Nav5::default();
                if let Some(m) = cfg.dynamic_model {
                    n.mask |= NAV5_MASK_DYN;
                    n.dyn_model = m.code();
                }
                if hold_cm_s.is_some() || cfg.static_hold_max_dist_m.is_some() {
                    // One mask bit covers both fields: the one not asked for is sent as 0 (off / no limit).
                    n.mask |= NAV5_MASK_STATIC_HOLD;
                    n.static_hold_thresh_cm_s = hold_cm_s.unwrap_or(0);
                    n.static_hold_max_dist_m = cfg.static_hold_max_dist_m.unwrap_or(0);
                }
                out.push(ConfigCommand::ubx("CFG-NAV5", UBX_CFG_NAV5, &cfg_nav5_payload(&n)));
            }
            if cfg.save {
                out.push(ConfigCommand::ubx("CFG-CFG (save)", UBX_CFG_CFG, &cfg_cfg_save_payload()));
            }
            out
        }
        Family::Ublox9 => {
            let items = valset_items(cfg, hold_cm_s);
            let layers = if cfg.save { LAYER_RAM | LAYER_BBR | LAYER_FLASH } else { LAYER_RAM };
            if items.is_empty() {
                // Only "save": write the current rate back to every layer is not possible without reading
                // it first; generation 9 saves per VALSET instead.
                return Err(ConfigError::Invalid(
                    "u-blox M9/F9 save with the settings themselves (choose at least one)".into(),
                ));
            }
            vec![ConfigCommand::ubx("CFG-VALSET", UBX_CFG_VALSET, &cfg_valset_payload(layers, &items))]
        }
        Family::Sirf if baud > u32::from(u16::MAX) => {
            return Err(ConfigError::Invalid(format!(
                "{baud} baud: SiRF's MID 129 carries the baud rate in 16 bits; use the receiver at 57600 or less"
            )));
        }
        Family::Sirf => match cfg.sirf_static_nav {
            None => Vec::new(),
            Some(enable) => vec![
                ConfigCommand {
                    name: "$PSRF100 (to SiRF binary)".into(),
                    bytes: psrf100(0, baud).into_bytes(),
                    // gpsd waits for the switch too; 4800 baud needs ~60 ms for the sentence alone.
                    expect: Expect::Nothing { settle: Duration::from_millis(300) },
                },
                ConfigCommand {
                    name: "MID 143 Static Navigation".into(),
                    bytes: sirf::frame(&sirf_static_nav_payload(enable)),
                    expect: Expect::SirfAck { mid: SIRF_MID_STATIC_NAV },
                },
                ConfigCommand {
                    name: "MID 129 Switch To NMEA".into(),
                    bytes: sirf::frame(&sirf_switch_to_nmea_payload(&NmeaRates::default(), baud)),
                    expect: Expect::Nothing { settle: Duration::from_millis(300) },
                },
            ],
        },
    })
}

/// The CFG-VALSET items of a generation-9 configuration, in the order of the u-blox 6–8 messages.
fn valset_items(cfg: &ReceiverConfig, hold_cm_s: Option<u8>) -> Vec<(u32, u64)> {
    let mut items = Vec::new();
    if let Some(hz) = cfg.rate_hz {
        items.push((key::RATE_MEAS, u64::from(meas_rate_ms(hz))));
        items.push((key::RATE_NAV, 1));
        items.push((key::RATE_TIMEREF, 1));
    }
    if let Some(c) = &cfg.constellations {
        for (k, on) in [
            (key::SIGNAL_GPS_ENA, c.gps),
            (key::SIGNAL_GPS_L1CA_ENA, c.gps),
            (key::SIGNAL_SBAS_ENA, c.sbas),
            (key::SIGNAL_SBAS_L1CA_ENA, c.sbas),
            (key::SIGNAL_GAL_ENA, c.galileo),
            (key::SIGNAL_GAL_E1_ENA, c.galileo),
            (key::SIGNAL_BDS_ENA, c.beidou),
            (key::SIGNAL_BDS_B1_ENA, c.beidou),
            (key::SIGNAL_QZSS_ENA, c.qzss),
            (key::SIGNAL_QZSS_L1CA_ENA, c.qzss),
            (key::SIGNAL_GLO_ENA, c.glonass),
            (key::SIGNAL_GLO_L1_ENA, c.glonass),
        ] {
            items.push((k, u64::from(on)));
        }
    }
    if let Some(m) = cfg.dynamic_model {
        items.push((key::NAVSPG_DYNMODEL, u64::from(m.code())));
    }
    if let Some(h) = hold_cm_s {
        items.push((key::MOTION_GNSSSPEED_THRS, u64::from(h)));
    }
    if let Some(d) = cfg.static_hold_max_dist_m {
        items.push((key::MOTION_GNSSDIST_THRS, u64::from(d)));
    }
    items
}

/// The measurement period for a navigation rate: `measRate = round(1000 / rate_hz)` ms (100 ms at 10 Hz).
pub fn meas_rate_ms(rate_hz: u8) -> u16 {
    (1000.0 / f64::from(rate_hz.max(1))).round() as u16
}

/// UBX-CFG-RATE payload (UBX-13003221 §32.10.23, class 0x06 id 0x08, 6 bytes, little-endian):
///
/// | offset | type | name | unit |
/// |---|---|---|---|
/// | 0 | U2 | measRate | ms between measurements |
/// | 2 | U2 | navRate | measurement cycles per navigation solution (u-blox 8: always 1) |
/// | 4 | U2 | timeRef | 0 = UTC, 1 = GPS time (2 GLONASS, 3 `BeiDou`, 4 Galileo) |
pub fn cfg_rate_payload(meas_rate_ms: u16, nav_rate: u16, time_ref: u16) -> Vec<u8> {
    [meas_rate_ms.to_le_bytes(), nav_rate.to_le_bytes(), time_ref.to_le_bytes()].concat()
}

/// CFG-NAV5 mask bit 0: apply `dynModel`.
pub const NAV5_MASK_DYN: u16 = 1 << 0;
/// CFG-NAV5 mask bit 6: apply `staticHoldThresh` and `staticHoldMaxDist`.
pub const NAV5_MASK_STATIC_HOLD: u16 = 1 << 6;

/// The fields of UBX-CFG-NAV5 (UBX-13003221 §32.10.19, class 0x06 id 0x24, 36 bytes, little-endian);
/// only those whose bit is set in `mask` are applied by the receiver.
///
/// | offset | type | name | scale / unit |
/// |---|---|---|---|
/// | 0 | X2 | mask | bit 0 dyn, 1 minEl, 2 posFixMode, 3 drLim, 4 posMask, 5 timeMask, 6 staticHoldMask, 7 dgpsMask, 8 cnoThreshold, 10 utc |
/// | 2 | U1 | dynModel | 0 portable, 2 stationary, 3 pedestrian, 4 automotive, 5 sea, 6 airborne <1 g, 7 <2 g, 8 <4 g |
/// | 3 | U1 | fixMode | 1 2D only, 2 3D only, 3 auto |
/// | 4 | I4 | fixedAlt | 0.01 m |
/// | 8 | U4 | fixedAltVar | 0.0001 m² |
/// | 12 | I1 | minElev | deg |
/// | 13 | U1 | drLimit | s (reserved on M8) |
/// | 14 | U2 | pDop | 0.1 |
/// | 16 | U2 | tDop | 0.1 |
/// | 18 | U2 | pAcc | m |
/// | 20 | U2 | tAcc | m |
/// | 22 | U1 | staticHoldThresh | cm/s |
/// | 23 | U1 | dgnssTimeout | s |
/// | 24 | U1 | cnoThreshNumSVs | - |
/// | 25 | U1 | cnoThresh | dBHz |
/// | 26 | U1\[2\] | reserved | |
/// | 28 | U2 | staticHoldMaxDist | m |
/// | 30 | U1 | utcStandard | |
/// | 31 | U1\[5\] | reserved | |
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[allow(missing_docs)] // each field is the document's field of the same name, in the table above
pub struct Nav5 {
    pub mask: u16,
    pub dyn_model: u8,
    pub fix_mode: u8,
    pub fixed_alt_cm: i32,
    pub fixed_alt_var: u32,
    pub min_elev_deg: i8,
    pub dr_limit_s: u8,
    pub p_dop_x10: u16,
    pub t_dop_x10: u16,
    pub p_acc_m: u16,
    pub t_acc_m: u16,
    pub static_hold_thresh_cm_s: u8,
    pub dgnss_timeout_s: u8,
    pub cno_thresh_num_svs: u8,
    pub cno_thresh_dbhz: u8,
    pub static_hold_max_dist_m: u16,
    pub utc_standard: u8,
}

/// UBX-CFG-NAV5 payload (36 bytes; layout at [`Nav5`]).
pub fn cfg_nav5_payload(n: &Nav5) -> Vec<u8> {
    let mut p = Vec::with_capacity(36);
    p.extend_from_slice(&n.mask.to_le_bytes());
    p.extend_from_slice(&[n.dyn_model, n.fix_mode]);
    p.extend_from_slice(&n.fixed_alt_cm.to_le_bytes());
    p.extend_from_slice(&n.fixed_alt_var.to_le_bytes());
    p.extend_from_slice(&n.min_elev_deg.to_le_bytes());
    p.push(n.dr_limit_s);
    for v in [n.p_dop_x10, n.t_dop_x10, n.p_acc_m, n.t_acc_m] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.extend_from_slice(&[
        n.static_hold_thresh_cm_s,
        n.dgnss_timeout_s,
        n.cno_thresh_num_svs,
        n.cno_thresh_dbhz,
    ]);
    p.extend_from_slice(&[0, 0]);
    p.extend_from_slice(&n.static_hold_max_dist_m.to_le_bytes());
    p.push(n.utc_standard);
    p.extend_from_slice(&[0; 5]);
    p
}

/// CFG-GNSS `gnssId`s (UBX-13003221 appendix A "GNSS identifiers").
pub mod gnss_id {
    /// GPS.
    pub const GPS: u8 = 0;
    /// SBAS.
    pub const SBAS: u8 = 1;
    /// Galileo.
    pub const GALILEO: u8 = 2;
    /// `BeiDou`.
    pub const BEIDOU: u8 = 3;
    /// IMES.
    pub const IMES: u8 = 4;
    /// QZSS.
    pub const QZSS: u8 = 5;
    /// GLONASS.
    pub const GLONASS: u8 = 6;
}

/// One CFG-GNSS configuration block (8 bytes): `gnssId` U1, `resTrkCh` U1 (channels reserved), `maxTrkCh`
/// U1 (at most), reserved U1, `flags` X4 (bit 0 enable, bits 16–23 `sigCfgMask`: 0x01 = the L1 signal of
/// each system: GPS L1C/A, SBAS L1C/A, Galileo E1, `BeiDou` B1I, QZSS L1C/A, GLONASS L1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(missing_docs)] // the document's fields, as above
pub struct GnssBlock {
    pub gnss_id: u8,
    pub res_trk_ch: u8,
    pub max_trk_ch: u8,
    pub enable: bool,
    pub sig_cfg_mask: u8,
}

/// The blocks for `c`, with u-blox 8's default channel split (UBX-13003221 §32.10.13 "default
/// configuration": GPS 8–16, SBAS 1–3, Galileo 4–8, `BeiDou` 8–16, IMES 0–8, QZSS 0–3, GLONASS 8–14;
/// the reserved channels sum to 29 of 32).
pub fn gnss_blocks(c: &Constellations) -> Vec<GnssBlock> {
    let b = |gnss_id, res_trk_ch, max_trk_ch, enable| GnssBlock {
        gnss_id,
        res_trk_ch,
        max_trk_ch,
        enable,
        sig_cfg_mask: 0x01,
    };
    vec![
        b(gnss_id::GPS, 8, 16, c.gps),
        b(gnss_id::SBAS, 1, 3, c.sbas),
        b(gnss_id::GALILEO, 4, 8, c.galileo),
        b(gnss_id::BEIDOU, 8, 16, c.beidou),
        b(gnss_id::QZSS, 0, 3, c.qzss),
        b(gnss_id::GLONASS, 8, 14, c.glonass),
    ]
}

/// UBX-CFG-GNSS payload (UBX-13003221 §32.10.13, class 0x06 id 0x3E, 4 + 8 N bytes):
/// `msgVer` U1 = 0, `numTrkChHw` U1 (read-only, 0 when writing), `numTrkChUse` U1 (0xFF = all the
/// hardware has), `numConfigBlocks` U1, then the [`GnssBlock`]s. The receiver restarts its GNSS
/// subsystem after a change (a cold start of tracking, about half a minute without fixes).
pub fn cfg_gnss_payload(blocks: &[GnssBlock]) -> Vec<u8> {
    let mut p = vec![0, 0, 0xFF, u8::try_from(blocks.len()).unwrap_or(u8::MAX)];
    for b in blocks.iter().take(255) {
        let flags = u32::from(b.enable) | (u32::from(b.sig_cfg_mask) << 16);
        p.extend_from_slice(&[b.gnss_id, b.res_trk_ch, b.max_trk_ch, 0]);
        p.extend_from_slice(&flags.to_le_bytes());
    }
    p
}

/// CFG-CFG `saveMask`: every section (ioPort, msgConf, infMsg, navConf, rxmConf, senConf, rinvConf,
/// antConf, logConf, ftsConf and the reserved bits).
pub const CFG_SAVE_ALL: u32 = 0x0000_FFFF;
/// CFG-CFG `deviceMask`: BBR (bit 0), flash (1), EEPROM (2), SPI flash (4).
pub const CFG_DEVICES_ALL: u8 = 0x17;

/// UBX-CFG-CFG payload that saves the current configuration (UBX-13003221 §32.10.3, class 0x06 id 0x09,
/// 13 bytes, little-endian): `clearMask` X4 = 0, `saveMask` X4 = [`CFG_SAVE_ALL`], `loadMask` X4 = 0,
/// `deviceMask` X1 = [`CFG_DEVICES_ALL`].
pub fn cfg_cfg_save_payload() -> Vec<u8> {
    let mut p = Vec::with_capacity(13);
    p.extend_from_slice(&0u32.to_le_bytes());
    p.extend_from_slice(&CFG_SAVE_ALL.to_le_bytes());
    p.extend_from_slice(&0u32.to_le_bytes());
    p.push(CFG_DEVICES_ALL);
    p
}

/// CFG-VALSET layer bit: RAM (the running configuration).
pub const LAYER_RAM: u8 = 0x01;
/// CFG-VALSET layer bit: battery-backed RAM.
pub const LAYER_BBR: u8 = 0x02;
/// CFG-VALSET layer bit: flash.
pub const LAYER_FLASH: u8 = 0x04;

/// Configuration key ids of generation 9 ("u-blox ZED-F9P Interface Description" UBX-18010854 §4.9
/// "Configuration reference", and the NEO-M9N Interface Description UBX-19035940 §5). Bits 28–30 of an id
/// give its value's size ([`key_value_size`]).
pub mod key {
    /// CFG-RATE-MEAS (U2, ms): nominal time between measurements.
    pub const RATE_MEAS: u32 = 0x3021_0001;
    /// CFG-RATE-NAV (U2): measurements per navigation solution.
    pub const RATE_NAV: u32 = 0x3021_0002;
    /// CFG-RATE-TIMEREF (E1): 0 UTC, 1 GPS, 2 GLONASS, 3 `BeiDou`, 4 Galileo.
    pub const RATE_TIMEREF: u32 = 0x2021_0003;
    /// CFG-NAVSPG-DYNMODEL (E1): the dynamic platform model (codes as CFG-NAV5's `dynModel`).
    pub const NAVSPG_DYNMODEL: u32 = 0x2011_0021;
    /// CFG-MOTION-GNSSSPEED\_THRS (U1, cm/s): the static-hold speed threshold.
    pub const MOTION_GNSSSPEED_THRS: u32 = 0x2025_0038;
    /// CFG-MOTION-GNSSDIST\_THRS (U2, m): the distance that ends a static hold.
    pub const MOTION_GNSSDIST_THRS: u32 = 0x3025_003B;
    /// CFG-SIGNAL-GPS\_ENA (L).
    pub const SIGNAL_GPS_ENA: u32 = 0x1031_001F;
    /// CFG-SIGNAL-GPS\_L1CA\_ENA (L).
    pub const SIGNAL_GPS_L1CA_ENA: u32 = 0x1031_0001;
    /// CFG-SIGNAL-SBAS\_ENA (L).
    pub const SIGNAL_SBAS_ENA: u32 = 0x1031_0020;
    /// CFG-SIGNAL-SBAS\_L1CA\_ENA (L).
    pub const SIGNAL_SBAS_L1CA_ENA: u32 = 0x1031_0005;
    /// CFG-SIGNAL-GAL\_ENA (L).
    pub const SIGNAL_GAL_ENA: u32 = 0x1031_0021;
    /// CFG-SIGNAL-GAL\_E1\_ENA (L).
    pub const SIGNAL_GAL_E1_ENA: u32 = 0x1031_0007;
    /// CFG-SIGNAL-BDS\_ENA (L).
    pub const SIGNAL_BDS_ENA: u32 = 0x1031_0022;
    /// CFG-SIGNAL-BDS\_B1\_ENA (L).
    pub const SIGNAL_BDS_B1_ENA: u32 = 0x1031_000D;
    /// CFG-SIGNAL-QZSS\_ENA (L).
    pub const SIGNAL_QZSS_ENA: u32 = 0x1031_0024;
    /// CFG-SIGNAL-QZSS\_L1CA\_ENA (L).
    pub const SIGNAL_QZSS_L1CA_ENA: u32 = 0x1031_0012;
    /// CFG-SIGNAL-GLO\_ENA (L).
    pub const SIGNAL_GLO_ENA: u32 = 0x1031_0025;
    /// CFG-SIGNAL-GLO\_L1\_ENA (L).
    pub const SIGNAL_GLO_L1_ENA: u32 = 0x1031_0018;

    /// Every key this module writes (the emulated generation-9 receiver knows these).
    pub const KNOWN: [u32; 18] = [
        RATE_MEAS,
        RATE_NAV,
        RATE_TIMEREF,
        NAVSPG_DYNMODEL,
        MOTION_GNSSSPEED_THRS,
        MOTION_GNSSDIST_THRS,
        SIGNAL_GPS_ENA,
        SIGNAL_GPS_L1CA_ENA,
        SIGNAL_SBAS_ENA,
        SIGNAL_SBAS_L1CA_ENA,
        SIGNAL_GAL_ENA,
        SIGNAL_GAL_E1_ENA,
        SIGNAL_BDS_ENA,
        SIGNAL_BDS_B1_ENA,
        SIGNAL_QZSS_ENA,
        SIGNAL_QZSS_L1CA_ENA,
        SIGNAL_GLO_ENA,
        SIGNAL_GLO_L1_ENA,
    ];
}

/// The size in bytes of a key's value, from the key id's bits 28–30 (UBX-18010854 §4.3 "Configuration
/// items": 1 = one bit (sent as one byte), 2 = one byte, 3 = two, 4 = four, 5 = eight).
pub fn key_value_size(key_id: u32) -> Option<usize> {
    match (key_id >> 28) & 0x7 {
        1 | 2 => Some(1),
        3 => Some(2),
        4 => Some(4),
        5 => Some(8),
        _ => None,
    }
}

/// UBX-CFG-VALSET payload (UBX-18010854 §3.10.25, class 0x06 id 0x8A, version 0): `version` U1 = 0,
/// `layers` X1 ([`LAYER_RAM`] ...), `reserved` U1\[2\], then per item the key id (U4, little-endian) and
/// its value, little-endian, of [`key_value_size`] bytes. At most 64 items per message.
pub fn cfg_valset_payload(layers: u8, items: &[(u32, u64)]) -> Vec<u8> {
    let mut p = vec![0, layers, 0, 0];
    for &(k, v) in items.iter().take(64) {
        let size = key_value_size(k).unwrap_or(1);
        p.extend_from_slice(&k.to_le_bytes());
        p.extend_from_slice(&v.to_le_bytes()[..size]);
    }
    p
}

/// `$PSRF100,<protocol>,<baud>,8,1,0*hh` with CR LF: "100—SetSerialPort" of `SiRF`'s NMEA Reference Manual
/// (protocol 0 = `SiRF` binary, 1 = NMEA; 8 data bits, 1 stop bit, no parity).
pub fn psrf100(protocol: u8, baud: u32) -> String {
    let body = format!("PSRF100,{protocol},{baud},8,1,0");
    let ck = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{ck:02X}\r\n")
}

/// `SiRF` MID 143 "Static Navigation" payload (Binary Protocol Reference Manual, "Static Navigation -
/// Message ID 143", 2 bytes): MID 0x8F, then 0x00 = disable, 0x01 = enable.
pub fn sirf_static_nav_payload(enable: bool) -> Vec<u8> {
    vec![SIRF_MID_STATIC_NAV, u8::from(enable)]
}

/// Output periods of the NMEA sentences after MID 129 [s between sentences; 0 = off].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(missing_docs)]
pub struct NmeaRates {
    pub gga: u8,
    pub gll: u8,
    pub gsa: u8,
    pub gsv: u8,
    pub rmc: u8,
    pub vtg: u8,
    pub mss: u8,
}

impl Default for NmeaRates {
    /// The BT-359's factory output as gpsd restores it: GGA, GSA, RMC every second, GSV every 5 s.
    fn default() -> Self {
        Self { gga: 1, gll: 0, gsa: 1, gsv: 5, rmc: 1, vtg: 0, mss: 0 }
    }
}

/// `SiRF` MID 129 "Switch To NMEA Protocol" payload (Binary Protocol Reference Manual, "Switch To NMEA
/// Protocol - Message ID 129", 24 bytes, big-endian):
///
/// | offset | bytes | field |
/// |---|---|---|
/// | 0 | 1 | MID 0x81 |
/// | 1 | 1 | mode: 0 enable NMEA debug messages, 1 disable, 2 keep the last setting |
/// | 2 | 2 × 10 | rate (s) and checksum flag (1 = on) of GGA, GLL, GSA, GSV, RMC, VTG, MSS, then three slots |
///
/// The last three slots are "EPE (unused), ZDA, unused" in the manual but "EPE, EPE, ZDA" in gpsd's
/// `sirf_to_nmea`: which one is ZDA is ambiguous, so all three are sent with rate 0 (docs/gps.md, "`SiRF`
/// binary").
/// | 22 | 2 | baud rate |
pub fn sirf_switch_to_nmea_payload(rates: &NmeaRates, baud: u32) -> Vec<u8> {
    let mut p = vec![SIRF_MID_SWITCH_TO_NMEA, 2];
    for r in [rates.gga, rates.gll, rates.gsa, rates.gsv, rates.rmc, rates.vtg, rates.mss, 0, 0] {
        p.extend_from_slice(&[r, 1]);
    }
    p.extend_from_slice(&[0, 0]);
    p.extend_from_slice(&u16::try_from(baud).unwrap_or(4800).to_be_bytes());
    p
}
