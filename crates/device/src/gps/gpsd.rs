//! gpsd's JSON protocol: TPV and SKY reports to [`Fix`]es (sans-IO; the TCP transport is in [`super::source`]).
//!
//! We send `?WATCH={"enable":true,"json":true}` and read one JSON object per line. A TPV with a new
//! `time` completes a fix; the latest SKY supplies DOPs and satellites. gpsd's own `eph` (its DOP model, or
//! the receiver's GST/PGRME) becomes the error estimate.

use chrono::{DateTime, Utc};

use super::fix::{Constellation, ErrorEstimate, ErrorSource, Fix, FixMode, Satellite};

/// The command that starts the JSON stream.
pub const WATCH: &str = "?WATCH={\"enable\":true,\"json\":true}\n";

/// Turns gpsd report lines into fixes.
#[derive(Debug, Default)]
pub struct GpsdClient {
    sky: Fix,
    last_time: Option<DateTime<Utc>>,
    /// Lines that were not JSON objects of a known class.
    pub ignored_lines: u64,
}

impl GpsdClient {
    /// A client with no state.
    pub fn new() -> Self {
        Self::default()
    }

    /// Handles one line; returns a fix when a TPV with a new time arrives.
    pub fn handle_line(&mut self, line: &str) -> Option<Fix> {
        let Ok(v) = serde_json::from_str::<serde_json::Value>(line.trim()) else {
            self.ignored_lines += 1;
            return None;
        };
        match v.get("class").and_then(serde_json::Value::as_str) {
            Some("SKY") => {
                self.apply_sky(&v);
                None
            }
            Some("TPV") => self.tpv(&v),
            _ => None,
        }
    }

    fn apply_sky(&mut self, v: &serde_json::Value) {
        let f = &mut self.sky;
        f.hdop = v["hdop"].as_f64().or(f.hdop);
        f.pdop = v["pdop"].as_f64().or(f.pdop);
        f.vdop = v["vdop"].as_f64().or(f.vdop);
        f.sats_used = v["uSat"].as_u64().map(|n| n as u32).or(f.sats_used);
        f.sats_visible = v["nSat"].as_u64().map(|n| n as u32).or(f.sats_visible);
        if let Some(list) = v["satellites"].as_array() {
            f.satellites = list
                .iter()
                .filter_map(|s| {
                    let prn = u16::try_from(s["PRN"].as_u64()?).ok()?;
                    // gpsd gnssid: 0 GPS, 1 SBAS, 2 Galileo, 3 BeiDou, 5 QZSS, 6 GLONASS, 7 NavIC.
                    let constellation = match s["gnssid"].as_u64() {
                        Some(0) => Constellation::Gps,
                        Some(1) => Constellation::Sbas,
                        Some(2) => Constellation::Galileo,
                        Some(3) => Constellation::Beidou,
                        Some(5) => Constellation::Qzss,
                        Some(6) => Constellation::Glonass,
                        Some(7) => Constellation::Navic,
                        _ => Constellation::from_nmea_id(prn),
                    };
                    Some(Satellite {
                        prn,
                        constellation,
                        elevation_deg: s["el"].as_f64(),
                        azimuth_deg: s["az"].as_f64(),
                        snr_dbhz: s["ss"].as_f64(),
                        used: s["used"].as_bool().unwrap_or(false),
                    })
                })
                .collect();
            f.sats_used_by.clear();
            f.sats_visible_by.clear();
            for s in &f.satellites {
                *f.sats_visible_by.entry(s.constellation).or_insert(0) += 1;
                if s.used {
                    *f.sats_used_by.entry(s.constellation).or_insert(0) += 1;
                }
            }
        }
    }

    fn tpv(&mut self, v: &serde_json::Value) -> Option<Fix> {
        let time = v["time"].as_str().and_then(|t| DateTime::parse_from_rfc3339(t).ok())?.with_timezone(&Utc);
        if self.last_time == Some(time) {
            return None;
        }
        self.last_time = Some(time);
        let mode = match v["mode"].as_u64() {
            Some(2) => FixMode::Fix2D,
            Some(3) => FixMode::Fix3D,
            _ => FixMode::NoFix,
        };
        let has_pos = mode != FixMode::NoFix;
        let mut fix = Fix {
            time: Some(time),
            time_of_day: Some(time.time()),
            mode: Some(mode),
            lat_deg: v["lat"].as_f64().filter(|_| has_pos),
            lon_deg: v["lon"].as_f64().filter(|_| has_pos),
            alt_m: v["altMSL"].as_f64().or_else(|| v["alt"].as_f64()),
            geoid_sep_m: v["geoidSep"].as_f64(),
            speed_m_s: v["speed"].as_f64(),
            course_deg: v["track"].as_f64(),
            received_at: Some(std::time::Instant::now()),
            ..self.sky.clone()
        };
        // gpsd's eph/epv: its own DOP model or the receiver's GST/PGRME ("certainty unknown", gpsd_json(5)).
        fix.error = v["eph"].as_f64().filter(|_| has_pos).map(|eph| ErrorEstimate {
            horizontal_m: eph,
            vertical_m: v["epv"].as_f64(),
            source: ErrorSource::Gpsd,
        });
        Some(fix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// gpsd's own reports from its regression output (nd-1005.log.chk) become the same fix our decoder
    /// makes from the log.
    #[test]
    fn chk_reports_become_fixes() {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../tests/data/gpsd-logs/nd-1005.log.chk"),
        )
        .unwrap();
        let mut c = GpsdClient::new();
        let fixes: Vec<Fix> = text.lines().filter_map(|l| c.handle_line(l)).collect();
        assert_eq!(fixes.len(), 16);
        assert!((fixes[0].lat_deg.unwrap() - 57.163_445).abs() < 1e-9);
        assert_eq!(fixes[0].mode, Some(FixMode::Fix3D));
        assert_eq!(fixes[0].sats_used, Some(8));
        assert!(c.ignored_lines > 0, "NMEA echo lines are ignored");
    }
}
