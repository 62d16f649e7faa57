//! The field tests' feed: every fix with a position of whatever source runs goes to core's
//! [`FieldTests`] with its arrival time (from the fix's `received_at`) and the receiver's time of day; the
//! station tells them when the source changes, jumps or ends. A view only draws them. The reference they
//! are measured against is made here from what the operator gives (typed text, a GPX waypoint), for the
//! console and the CLI alike.

use std::path::Path;
use std::time::Instant;

use chrono::Timelike as _;
use vestnav_core::accuracy::{Reference, ReferenceOrigin, Sample};
use vestnav_core::fieldtest::receiver_time_s;
use vestnav_core::fieldtest_live::{FieldTests, LiveFix};
use vestnav_core::geo::LatLon;
use vestnav_core::guidance::Waypoint;
use vestnav_device::gps::Fix;

/// Feeds `fix` to `tests`: its arrival [s] after `epoch`, its UTC time of day (`time_of_day`, else the
/// time of `time`) in seconds, position, speed over ground, height above mean sea level and whether it is
/// good enough to average into a reference ([`Fix::good_for_reference`]). A fix without a position is not
/// fed.
pub fn feed(tests: &mut FieldTests, epoch: Instant, fix: &Fix) {
    let (Some(lat), Some(lon)) = (fix.lat_deg, fix.lon_deg) else { return };
    let arrival_s = fix.received_at.map_or(0.0, |t| t.saturating_duration_since(epoch).as_secs_f64());
    let tod = fix.time_of_day.or_else(|| fix.time.map(|t| t.time()));
    let tod_s = tod.map(|t| f64::from(t.num_seconds_from_midnight()) + f64::from(t.nanosecond()) * 1e-9);
    tests.push_fix(&LiveFix {
        arrival_s,
        tod_s,
        lat_deg: lat,
        lon_deg: lon,
        speed_m_s: fix.speed_m_s,
        height_m: fix.alt_m,
        good: fix.good_for_reference(),
    });
}

/// One fix of a receiver on its receiver-time line, for the accuracy statistics and receivers side by side
/// (`vestnav fieldtest compare` reads its logs by this rule, and the station's comparison takes its live
/// fixes by it): `None` without a valid position (2-D or 3-D mode, latitude and longitude in range); its time
/// is [`receiver_time_s`] of its UTC time of day after `prev_s`, its height the GGA altitude when finite.
pub fn receiver_sample(fix: &Fix, prev_s: Option<f64>) -> Option<Sample> {
    if !fix.has_position() {
        return None;
    }
    let pos = LatLon::new(fix.lat_deg?, fix.lon_deg?).validated().ok()?;
    let tod_s =
        fix.time_of_day.map(|t| f64::from(t.num_seconds_from_midnight()) + f64::from(t.nanosecond()) * 1e-9);
    Some(Sample { t_s: receiver_time_s(tod_s, prev_s), pos, height_m: fix.alt_m.filter(|h| h.is_finite()) })
}

/// A typed reference: `text` in any form of [`vestnav_core::coords::parse_position`] (decimal, DMS,
/// UTM/UPS, MGRS) with its stated horizontal uncertainty (1 sigma) and, for the vertical error, its height
/// above mean sea level [m]. Errors say what is wrong with which input.
pub fn typed_reference(text: &str, uncertainty_m: f64, height_m: Option<f64>) -> Result<Reference, String> {
    let pos = vestnav_core::coords::parse_position(text)?;
    let origin = ReferenceOrigin::Typed { text: Some(text.trim().to_owned()) };
    stated(Reference { origin, ..Reference::typed(pos, uncertainty_m) }, height_m)
}

/// A reference that is a waypoint of the GPX file at `path`: the one named `name`, else the file's only
/// waypoint (several without a name is an error listing them). The file is read size-limited (a FIFO or
/// device is refused).
pub fn waypoint_reference(
    path: &Path,
    name: Option<&str>,
    uncertainty_m: f64,
    height_m: Option<f64>,
) -> Result<Reference, String> {
    let file = vestnav_device::route_file::read_gpx(path).map_err(|e| e.to_string())?;
    let names =
        |w: &[Waypoint]| w.iter().take(10).map(|w| format!("{:?}", w.name)).collect::<Vec<_>>().join(", ");
    let wpt = match name.map(str::trim).filter(|n| !n.is_empty()) {
        Some(name) => file.waypoints.iter().find(|w| w.name == name).ok_or_else(|| {
            format!("{}: no waypoint named {name:?} (it has {})", path.display(), names(&file.waypoints))
        })?,
        None => match file.waypoints.as_slice() {
            [only] => only,
            [] => return Err(format!("{}: no waypoints (<wpt>)", path.display())),
            many => {
                return Err(format!("{}: several waypoints, choose one ({})", path.display(), names(many)));
            }
        },
    };
    let pos =
        LatLon::new(wpt.lat_deg, wpt.lon_deg).validated().map_err(|e| format!("{}: {e}", path.display()))?;
    let origin = ReferenceOrigin::Waypoint { file: path.display().to_string(), name: wpt.name.clone() };
    stated(Reference { origin, ..Reference::typed(pos, uncertainty_m) }, height_m)
}

/// Checks the stated uncertainty and height and sets the height.
fn stated(mut r: Reference, height_m: Option<f64>) -> Result<Reference, String> {
    if !(r.uncertainty_m.is_finite() && r.uncertainty_m >= 0.0) {
        return Err("the reference's uncertainty must be a non-negative number of metres".into());
    }
    if height_m.is_some_and(|h| !h.is_finite()) {
        return Err("the reference's height must be a number of metres".into());
    }
    r.height_m = height_m;
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GPX: &str = r#"<?xml version="1.0"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
  <wpt lat="-45.8775925" lon="170.5001265"><name>PILLAR</name></wpt>
  <wpt lat="42.3575" lon="-71.1010"><name>MIT</name></wpt>
</gpx>"#;

    /// A reference from a GPX waypoint by name; several without a name, an unknown name, a typo in a typed
    /// position and a negative uncertainty are refused saying what is wrong; a FIFO is refused without
    /// blocking (the console reads on its view's thread).
    #[test]
    fn references_from_text_and_waypoints() {
        let dir = std::env::temp_dir().join(format!("vestnav-ref-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let gpx = dir.join("marks.gpx");
        std::fs::write(&gpx, GPX).unwrap();
        let r = waypoint_reference(&gpx, Some("MIT"), 0.02, Some(12.5)).unwrap();
        assert_eq!((r.pos.lat_deg, r.pos.lon_deg), (42.3575, -71.1010));
        assert_eq!(r.height_m, Some(12.5));
        assert!(matches!(&r.origin, ReferenceOrigin::Waypoint { name, .. } if name == "MIT"));
        let several = waypoint_reference(&gpx, Some(" "), 0.0, None).unwrap_err();
        assert!(several.contains("several waypoints") && several.contains("\"PILLAR\""), "{several}");
        let unknown = waypoint_reference(&gpx, Some("NOPE"), 0.0, None).unwrap_err();
        assert!(unknown.contains("no waypoint named \"NOPE\""), "{unknown}");
        let t = typed_reference("45 52 39.333 S 170 30 0.4554 E", 0.01, None).unwrap();
        assert!((t.pos.lat_deg + 45.877_592_5).abs() < 1e-7 && (t.pos.lon_deg - 170.500_126_5).abs() < 1e-7);
        assert!(typed_reference("42.3575, -71.1010", -1.0, None).unwrap_err().contains("uncertainty"));
        assert!(typed_reference("not a place", 0.0, None).is_err());
        #[cfg(unix)]
        {
            let fifo = dir.join("fifo.gpx");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let e = waypoint_reference(&fifo, None, 0.0, None).unwrap_err();
                assert!(e.contains("fifo.gpx"), "{e}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
