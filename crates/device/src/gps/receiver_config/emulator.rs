//! The configuration side of the emulated receiver (`vestnav emulate gps --receiver ...`): reads what a
//! console writes to it and answers as the receiver family would (sans-IO: bytes in, settings and reply
//! bytes out; the emulator's loop applies the settings to its simulated receiver).
//!
//! - u-blox ([`EmulatedFamily::Ublox8`], [`EmulatedFamily::Ublox9`]): UBX-CFG-RATE, -NAV5, -GNSS, -CFG
//!   (and -VALSET on generation 9) are checked against their layouts and limits and answered with
//!   UBX-ACK-ACK, anything malformed or unsupported in the CFG class with UBX-ACK-NAK; a good checksum is
//!   required before anything is answered, as on the receivers. Static hold is off by default (u-blox's
//!   default `staticHoldThresh` 0).
//! - `SiRF` III ([`EmulatedFamily::Sirf3`]): static navigation on by default (the thesis's BT-359 holds
//!   the position below 1.2 m/s). `$PSRF100,0,...` switches to `SiRF` binary (NMEA output stops), MID 143
//!   is answered with MID 11 and applied, MID 129 switches back to NMEA; any other MID gets MID 12.

use std::time::Duration;

use super::{
    SIRF_MID_ACK, SIRF_MID_NACK, SIRF_MID_STATIC_NAV, SIRF_MID_SWITCH_TO_NMEA, SIRF3_STATIC_NAV_M_S, UBX_ACK,
    UBX_ACK_ACK, UBX_ACK_NAK, UBX_CFG, UBX_CFG_CFG, UBX_CFG_GNSS, UBX_CFG_NAV5, UBX_CFG_RATE, UBX_CFG_VALSET,
    gnss_id, key, key_value_size,
};
use crate::gps::framing::{Frame, Framer};
use crate::gps::{sirf, ubx};

/// Which receiver the emulator imitates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EmulatedFamily {
    /// The thesis's `SiRF` Star III (`GlobalSat` BT-359) in NMEA mode.
    Sirf3,
    /// A u-blox 8 (NEO-M8N) speaking NMEA, configured with UBX CFG messages.
    Ublox8,
    /// A u-blox M9/F9, configured with UBX-CFG-VALSET.
    Ublox9,
}

impl EmulatedFamily {
    /// The `--receiver` name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Sirf3 => "sirf3",
            Self::Ublox8 => "ublox8",
            Self::Ublox9 => "ublox9",
        }
    }

    /// The family named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Sirf3, Self::Ublox8, Self::Ublox9].into_iter().find(|f| f.name().eq_ignore_ascii_case(name))
    }
}

/// The protocol the emulated receiver currently speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// NMEA sentences out.
    Nmea,
    /// `SiRF` binary (after `$PSRF100,0`): no NMEA until MID 129.
    SirfBinary,
}

/// What the emulated receiver is set to.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatedSettings {
    /// Time between epochs.
    pub period: Duration,
    /// Static navigation / static hold threshold [m/s] (`None`: off).
    pub static_hold_m_s: Option<f64>,
    /// u-blox `staticHoldMaxDist` [m] (`None`: no limit).
    pub static_hold_max_dist_m: Option<f64>,
    /// u-blox dynamic model code.
    pub dyn_model: u8,
    /// The protocol spoken.
    pub protocol: Protocol,
    /// Enabled GNSS, by u-blox `gnssId` (bit n = gnssId n).
    pub gnss_mask: u8,
}

/// The emulated receiver's configuration state machine.
#[derive(Debug)]
pub struct EmulatedReceiver {
    family: EmulatedFamily,
    settings: EmulatedSettings,
    /// The GPS framer, reading the console's commands (bounded; checksums verified).
    framer: Framer,
    out: Vec<u8>,
    changed: bool,
    log: Vec<String>,
}

impl EmulatedReceiver {
    /// A receiver of `family` in its power-on state at 1 Hz; `static_nav` says whether a `SiRF` III has
    /// static navigation on (the factory default: true).
    pub fn new(family: EmulatedFamily, static_nav: bool) -> Self {
        let static_hold_m_s = (family == EmulatedFamily::Sirf3 && static_nav).then_some(SIRF3_STATIC_NAV_M_S);
        Self {
            family,
            settings: EmulatedSettings {
                period: Duration::from_secs(1),
                static_hold_m_s,
                static_hold_max_dist_m: None,
                dyn_model: 0,
                protocol: Protocol::Nmea,
                gnss_mask: (1 << gnss_id::GPS)
                    | (1 << gnss_id::SBAS)
                    | (1 << gnss_id::QZSS)
                    | (1 << gnss_id::GLONASS),
            },
            framer: Framer::new(),
            out: Vec::new(),
            changed: false,
            log: Vec::new(),
        }
    }

    /// What the receiver sends when it starts, before its first epoch: a `SiRF` III's `$PSRFTXT` lines
    /// (software version, as the `GlobalSat` receivers of the gpsd logs print them), a u-blox's `$GNTXT`
    /// naming the maker. This is how the console tells the family from the stream.
    pub fn banner(&self) -> Vec<u8> {
        let lines: &[&str] = match self.family {
            EmulatedFamily::Sirf3 => {
                &["PSRFTXT,Version GSW3.2.4 (vestnav emulated SiRF III)", "PSRFTXT,Baud rate: 4800"]
            }
            EmulatedFamily::Ublox8 | EmulatedFamily::Ublox9 => {
                &["GNTXT,01,01,02,u-blox AG - www.u-blox.com (vestnav emulated)"]
            }
        };
        lines.iter().map(|l| crate::gps::framing::with_checksum(l)).collect::<String>().into_bytes()
    }

    /// The current settings.
    pub fn settings(&self) -> &EmulatedSettings {
        &self.settings
    }

    /// True once since the settings last changed (the caller re-applies them).
    pub fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// Bytes to write back (acknowledgements), emptied.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// What was done since the last call, one line each (for the emulator's stderr).
    pub fn take_log(&mut self) -> Vec<String> {
        std::mem::take(&mut self.log)
    }

    /// Bytes from the console.
    pub fn handle_bytes(&mut self, bytes: &[u8]) {
        let mut framer = std::mem::take(&mut self.framer);
        framer.feed(bytes, |f, _| self.handle_frame(f));
        self.framer = framer;
    }

    fn handle_frame(&mut self, f: Frame<'_>) {
        match (self.family, self.settings.protocol, f) {
            (EmulatedFamily::Sirf3, Protocol::Nmea, Frame::Nmea(s)) => {
                // `$PSRF100,0,4800,8,1,0*0F`: the fields between `$` and the checksum.
                let body = s.get(1..).and_then(|t| t.rsplit_once('*')).map_or("", |(b, _)| b);
                let fields: Vec<&str> = body.split(',').collect();
                if fields.first() == Some(&"PSRF100") && fields.get(1) == Some(&"0") && fields.len() == 6 {
                    self.settings.protocol = Protocol::SirfBinary;
                    self.changed = true;
                    self.log.push(format!("$PSRF100: switched to SiRF binary at {} baud", fields[2]));
                }
            }
            (EmulatedFamily::Sirf3, Protocol::SirfBinary, Frame::Sirf { payload }) => self.sirf(payload),
            (
                EmulatedFamily::Ublox8 | EmulatedFamily::Ublox9,
                _,
                Frame::Ubx { class: UBX_CFG, id, payload },
            ) => {
                let ok = self.ubx_cfg(id, payload);
                let (ack_id, word) = if ok { (UBX_ACK_ACK, "ACK") } else { (UBX_ACK_NAK, "NAK") };
                self.log.push(format!("UBX-CFG 0x{id:02X} ({} bytes): {word}", payload.len()));
                self.out.extend(ubx::frame(UBX_ACK, ack_id, &[UBX_CFG, id]));
            }
            // Everything else (NMEA input to a u-blox, binary to a SiRF in NMEA mode, other UBX classes) is
            // ignored, as the receivers do.
            _ => {}
        }
    }

    fn sirf(&mut self, p: &[u8]) {
        let Some(&mid) = p.first() else { return };
        let ok = match (mid, p.len()) {
            (SIRF_MID_STATIC_NAV, 2) if p[1] <= 1 => {
                self.settings.static_hold_m_s = (p[1] == 1).then_some(SIRF3_STATIC_NAV_M_S);
                self.changed = true;
                self.log.push(format!("MID 143: static navigation {}", if p[1] == 1 { "on" } else { "off" }));
                true
            }
            (SIRF_MID_SWITCH_TO_NMEA, 24) => {
                self.settings.protocol = Protocol::Nmea;
                self.changed = true;
                self.log.push("MID 129: switched to NMEA".into());
                // The receiver switches instead of acknowledging.
                return;
            }
            _ => false,
        };
        let reply = if ok { SIRF_MID_ACK } else { SIRF_MID_NACK };
        self.out.extend(sirf::frame(&[reply, mid]));
    }

    /// Applies one CFG message; false = NAK.
    fn ubx_cfg(&mut self, id: u8, p: &[u8]) -> bool {
        match (id, p.len()) {
            (UBX_CFG_RATE, 6) => {
                let meas = u16::from_le_bytes([p[0], p[1]]);
                let nav = u16::from_le_bytes([p[2], p[3]]);
                let time_ref = u16::from_le_bytes([p[4], p[5]]);
                // u-blox 8: measRate >= 25 ms (we emulate up to 10 Hz), navRate 1..127, timeRef 0..4.
                if !(100..=10_000).contains(&meas) || !(1..=127).contains(&nav) || time_ref > 4 {
                    return false;
                }
                self.settings.period = Duration::from_millis(u64::from(meas) * u64::from(nav));
                self.changed = true;
                true
            }
            (UBX_CFG_NAV5, 36) => {
                let mask = u16::from_le_bytes([p[0], p[1]]);
                if mask & 1 != 0 {
                    if !matches!(p[2], 0 | 2..=8) {
                        return false;
                    }
                    self.settings.dyn_model = p[2];
                }
                if mask & (1 << 6) != 0 {
                    let thresh = p[22];
                    let dist = u16::from_le_bytes([p[28], p[29]]);
                    self.settings.static_hold_m_s = (thresh > 0).then(|| f64::from(thresh) / 100.0);
                    self.settings.static_hold_max_dist_m = (dist > 0).then(|| f64::from(dist));
                }
                self.changed = true;
                true
            }
            (UBX_CFG_GNSS, n) if n >= 4 && (n - 4) % 8 == 0 && usize::from(p[3]) == (n - 4) / 8 => {
                if p[0] != 0 {
                    return false;
                }
                let mut mask = 0u8;
                for b in p[4..].chunks_exact(8) {
                    if b[0] > gnss_id::GLONASS || b[1] > b[2] {
                        return false;
                    }
                    if b[4] & 1 == 1 {
                        mask |= 1 << b[0];
                    }
                }
                // Unchanged systems keep their state; then u-blox 8's limits (UBX-13003221 §32.10.13 notes).
                let named: u8 = p[4..].chunks_exact(8).fold(0, |m, b| m | (1 << b[0]));
                let mask = (self.settings.gnss_mask & !named) | mask;
                let majors = [gnss_id::GPS, gnss_id::GALILEO, gnss_id::BEIDOU, gnss_id::GLONASS]
                    .iter()
                    .filter(|g| mask & (1 << **g) != 0)
                    .count();
                if majors == 0 || majors > 3 || self.family == EmulatedFamily::Ublox9 {
                    // Generation 9 has no CFG-GNSS: VALSET's CFG-SIGNAL keys replace it.
                    return false;
                }
                self.settings.gnss_mask = mask;
                self.changed = true;
                true
            }
            (UBX_CFG_CFG, 12 | 13) => true,
            (UBX_CFG_VALSET, n) if n >= 4 && self.family == EmulatedFamily::Ublox9 => self.valset(p),
            _ => false,
        }
    }

    /// CFG-VALSET: every key must be known and its value whole, else nothing is applied (the receiver's
    /// transaction rule: "all or nothing", UBX-18010854 §3.10.25).
    fn valset(&mut self, p: &[u8]) -> bool {
        if p[0] != 0 || !matches!(p[1] & 0x07, 1..=7) {
            return false;
        }
        let mut items = Vec::new();
        let mut rest = &p[4..];
        while !rest.is_empty() {
            let Some(k) = rest.get(..4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])) else {
                return false;
            };
            let Some(size) = key_value_size(k).filter(|_| key::KNOWN.contains(&k)) else { return false };
            let Some(v) = rest.get(4..4 + size) else { return false };
            let mut le = [0u8; 8];
            le[..size].copy_from_slice(v);
            items.push((k, u64::from_le_bytes(le)));
            rest = &rest[4 + size..];
        }
        let mut s = self.settings.clone();
        let (mut meas, mut nav) = (None, None);
        for (k, v) in items {
            match k {
                key::RATE_MEAS => meas = Some(v),
                key::RATE_NAV => nav = Some(v),
                key::RATE_TIMEREF if v > 4 => return false,
                key::NAVSPG_DYNMODEL if !matches!(v, 0 | 2..=12) => return false,
                key::NAVSPG_DYNMODEL => s.dyn_model = v as u8,
                key::MOTION_GNSSSPEED_THRS => s.static_hold_m_s = (v > 0).then(|| v as f64 / 100.0),
                key::MOTION_GNSSDIST_THRS => s.static_hold_max_dist_m = (v > 0).then_some(v as f64),
                key::SIGNAL_GPS_ENA => set_bit(&mut s.gnss_mask, gnss_id::GPS, v),
                key::SIGNAL_SBAS_ENA => set_bit(&mut s.gnss_mask, gnss_id::SBAS, v),
                key::SIGNAL_GAL_ENA => set_bit(&mut s.gnss_mask, gnss_id::GALILEO, v),
                key::SIGNAL_BDS_ENA => set_bit(&mut s.gnss_mask, gnss_id::BEIDOU, v),
                key::SIGNAL_QZSS_ENA => set_bit(&mut s.gnss_mask, gnss_id::QZSS, v),
                key::SIGNAL_GLO_ENA => set_bit(&mut s.gnss_mask, gnss_id::GLONASS, v),
                _ => {}
            }
        }
        if let Some(m) = meas {
            let n = nav.unwrap_or(1);
            if !(25..=10_000).contains(&m) || !(1..=127).contains(&n) {
                return false;
            }
            s.period = Duration::from_millis(m * n);
        }
        self.settings = s;
        self.changed = true;
        true
    }
}

fn set_bit(mask: &mut u8, bit: u8, on: u64) {
    if on == 0 {
        *mask &= !(1 << bit);
    } else {
        *mask |= 1 << bit;
    }
}
