//! One epoch's sentences into its [`Fix`]: [`NmeaDecoder::build_fix`] and its error estimate.

use super::{
    Constellation, Epoch, ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, GsaPart, LatLon, NmeaDecoder,
    Parsed, Satellite, UERE_DGPS_M, UERE_M, utc,
};

impl NmeaDecoder {
    // One straight pass over the sentence types, in priority order; splitting it would scatter the rules.
    #[allow(clippy::too_many_lines)]
    pub(super) fn build_fix(&self, e: &Epoch, chosen: Option<LatLon>) -> Fix {
        let mut fix = Fix {
            time_of_day: e.tod,
            time: e.tod.and_then(|t| self.date.map(|d| utc(d, t))),
            received_at: self.now,
            ..Fix::default()
        };
        // Position and validity: GGA, else RMC, else GNS, else GLL.
        let mut valid = None;
        let mut pos = None;
        if let Some((p, q, sats, hdop, alt, sep)) = e.gga {
            fix.quality = q;
            let ok = q.is_some_and(FixQuality::has_position);
            valid = Some(ok);
            if ok {
                pos = p;
                fix.alt_m = alt;
                fix.geoid_sep_m = sep;
            }
            fix.sats_used = sats;
            fix.hdop = hdop;
        }
        if let Some((ok, p, speed, course)) = e.rmc {
            valid = Some(valid.unwrap_or(false) || ok);
            if ok {
                pos = pos.or(p);
                fix.speed_m_s = speed;
                fix.course_deg = course;
            }
        }
        if let Some((ok, p, sats, hdop, alt, sep)) = e.gns {
            valid = Some(valid.unwrap_or(false) || ok);
            if ok {
                pos = pos.or(p);
                fix.alt_m = fix.alt_m.or(alt);
                fix.geoid_sep_m = fix.geoid_sep_m.or(sep);
            }
            fix.sats_used = fix.sats_used.filter(|&n| n > 0).or(sats);
            fix.hdop = fix.hdop.or(hdop);
        }
        if let Some((ok, p)) = e.gll {
            valid = Some(valid.unwrap_or(false) || ok);
            if ok {
                pos = pos.or(p);
            }
        }
        // Ashtech POS: a fix when its solution type is present (gpsd: "at least a 3D fix").
        let mut ashtech_3d = false;
        if let Some(Parsed::AshtechPos { pos: p, quality, sats, course_deg, speed_m_s, hdop, .. }) =
            &e.ashtech
        {
            let ok = quality.is_some() && p.is_some();
            valid = Some(valid.unwrap_or(false) || ok);
            if ok {
                pos = pos.or(*p);
                fix.quality = fix.quality.or(*quality);
                fix.course_deg = fix.course_deg.or(*course_deg);
                fix.speed_m_s = fix.speed_m_s.or(*speed_m_s);
                ashtech_3d = true;
            }
            fix.sats_used = fix.sats_used.or(*sats);
            fix.hdop = fix.hdop.or(*hdop);
        }
        if let Some((course, speed)) = e.vtg
            && valid != Some(false)
        {
            fix.course_deg = fix.course_deg.or(course);
            fix.speed_m_s = fix.speed_m_s.or(speed);
        }
        let valid = valid.unwrap_or(false) && pos.is_some();
        if valid {
            // When the epoch's sentences disagree on the position (a marine multiplexer such as the B&G
            // Zeus² labels GGA one second apart from RMC and GLL), the position most of them agree on.
            let pos = chosen.or(pos);
            fix.lat_deg = pos.map(|p| p.0);
            fix.lon_deg = pos.map(|p| p.1);
        }
        // THS mode V: the receiver says the epoch's heading (THS or HDT) is not valid.
        fix.true_heading_deg = e.heading_deg.filter(|_| !e.heading_invalid);
        // GSA: the epoch's, else the receiver's last, unless that one said "no fix" and this epoch has a
        // fix: it describes the receiver before the fix (the `MediaTek` FV-M11 sends GSA every few seconds
        // and its last one, mode 1 with no ids, would otherwise turn GGA's 3 satellites into 0).
        let stale_no_fix = valid
            && !self.gsa_state.is_empty()
            && self.gsa_state.iter().all(|g| g.mode == Some(FixMode::NoFix));
        let gsa: &[GsaPart] = match (e.gsa.is_empty(), stale_no_fix) {
            (false, _) => &e.gsa,
            (true, false) => &self.gsa_state,
            (true, true) => &[],
        };
        let gsa_mode = gsa.iter().filter_map(|g| g.mode).max();
        fix.mode = if valid {
            Some(match gsa_mode {
                Some(m @ (FixMode::Fix2D | FixMode::Fix3D)) => m,
                _ if fix.alt_m.is_some() || ashtech_3d => FixMode::Fix3D,
                // No GSA and no altitude in this epoch (an RMC/GLL-only second between GGAs, e.g. the
                // Humminbird GR16 sends GGA every 4 s): RMC and GLL carry no dimension, so the fix keeps
                // the dimension of the receiver's last altitude-bearing epoch, as gpsd does (its RMC/GLL
                // handlers raise the mode to 2D only when it is below 2D).
                _ if self.altitude_fix => FixMode::Fix3D,
                _ => FixMode::Fix2D,
            })
        } else {
            Some(FixMode::NoFix)
        };
        if let Some(g) = gsa.iter().find(|g| g.pdop.is_some() || g.vdop.is_some() || g.hdop.is_some()) {
            fix.pdop = g.pdop;
            fix.vdop = g.vdop;
            fix.hdop = fix.hdop.or(g.hdop);
        }
        if let Some(Parsed::AshtechPos { pdop, vdop, .. }) = &e.ashtech {
            fix.pdop = fix.pdop.or(*pdop);
            fix.vdop = fix.vdop.or(*vdop);
        }
        // Satellites used, deduplicated: a bit set over (constellation, id < USED_BITS_IDS), plus a sorted
        // list of the rare larger ids.
        let mut used_bits = [0u64; USED_BITS_WORDS];
        let mut used_big: Vec<(Constellation, u16)> = Vec::new();
        let mut used_by = [0u32; ALL_CONSTELLATIONS.len()];
        for &(c, id) in gsa.iter().flat_map(|g| g.ids.iter()) {
            if usize::from(id) < USED_BITS_IDS {
                let bit = c as usize * USED_BITS_IDS + usize::from(id);
                let mask = 1 << (bit % 64);
                if used_bits[bit / 64] & mask == 0 {
                    used_bits[bit / 64] |= mask;
                    used_by[c as usize] += 1;
                }
            } else {
                used_big.push((c, id));
            }
        }
        used_big.sort_unstable();
        used_big.dedup();
        for &(c, _) in &used_big {
            used_by[c as usize] += 1;
        }
        if !gsa.is_empty() {
            // An empty id list with mode 1 is the receiver saying "none used".
            fix.sats_used = Some(used_by.iter().sum());
            for (c, n) in ALL_CONSTELLATIONS.into_iter().zip(used_by) {
                if n > 0 {
                    fix.sats_used_by.insert(c, n);
                }
            }
        }
        let is_used = |c: Constellation, id: u16| {
            if usize::from(id) < USED_BITS_IDS {
                let bit = c as usize * USED_BITS_IDS + usize::from(id);
                used_bits[bit / 64] & (1 << (bit % 64)) != 0
            } else {
                used_big.binary_search(&(c, id)).is_ok()
            }
        };
        // Sky: every complete GSV group.
        let mut visible = 0u32;
        let mut visible_by = [0u32; ALL_CONSTELLATIONS.len()];
        fix.satellites.reserve(self.sky.values().map(|g| g.complete.len()).sum());
        let mut any_sky = false;
        for g in self.sky.values().filter(|g| g.has_complete) {
            any_sky = true;
            visible += u32::from(g.complete_in_view);
            for &(id, el, az, snr) in &g.complete {
                let constellation = g.constellation.unwrap_or_else(|| Constellation::from_nmea_id(id));
                visible_by[constellation as usize] += 1;
                let is_used = is_used(constellation, id);
                fix.satellites.push(Satellite {
                    prn: id,
                    constellation,
                    elevation_deg: el,
                    azimuth_deg: az,
                    snr_dbhz: snr,
                    used: is_used,
                });
            }
        }
        for (c, n) in ALL_CONSTELLATIONS.into_iter().zip(visible_by) {
            if n > 0 {
                fix.sats_visible_by.insert(c, n);
            }
        }
        if any_sky {
            fix.sats_visible = Some(visible);
        }
        fix.error = error_estimate(e, &fix);
        fix
    }
}

/// Satellite ids below this are looked up in a bit set when marking satellites used (NMEA ids are < 400).
pub(super) const USED_BITS_IDS: usize = 512;
/// Words of that bit set: one row of [`USED_BITS_IDS`] bits per [`Constellation`].
pub(super) const USED_BITS_WORDS: usize = ALL_CONSTELLATIONS.len() * USED_BITS_IDS / 64;
/// Every [`Constellation`], in discriminant order.
pub(super) const ALL_CONSTELLATIONS: [Constellation; 8] = [
    Constellation::Gps,
    Constellation::Sbas,
    Constellation::Glonass,
    Constellation::Galileo,
    Constellation::Beidou,
    Constellation::Qzss,
    Constellation::Navic,
    Constellation::Unknown,
];

/// The error estimate: GST (1-sigma lat/lon/alt from the receiver) when sent, else Garmin PGRME, else the
/// DOP model `sigma_h = HDOP * UERE`, `sigma_v = VDOP * UERE` with `UERE = UERE_M` (autonomous) or
/// `UERE_DGPS_M` (differential/RTK quality). GST: `sigma_h = sqrt(sigma_lat^2 + sigma_lon^2)`.
pub(super) fn error_estimate(e: &Epoch, fix: &Fix) -> Option<ErrorEstimate> {
    if !fix.has_position() {
        return None;
    }
    if let Some((Some(lat), Some(lon), alt)) = e.gst {
        return Some(ErrorEstimate {
            horizontal_m: lat.hypot(lon),
            vertical_m: alt,
            source: ErrorSource::Gst,
        });
    }
    if let Some((Some(h), v)) = e.pgrme {
        return Some(ErrorEstimate { horizontal_m: h, vertical_m: v, source: ErrorSource::Pgrme });
    }
    let uere_m = if fix.quality.is_some_and(FixQuality::is_differential) { UERE_DGPS_M } else { UERE_M };
    fix.hdop.map(|h| ErrorEstimate {
        horizontal_m: h * uere_m,
        vertical_m: fix.vdop.map(|v| v * uere_m),
        source: ErrorSource::DopModel { uere_m },
    })
}
