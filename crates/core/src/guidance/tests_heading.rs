//! Unit tests of the heading source selector, the compass/COG disagreement warning and turn-in-place cues.

use super::*;
use crate::vest::TurnStep;
use approx::assert_relative_eq;

const O: LatLon = LatLon::new(42.3575, -71.1010);
/// Declination used throughout [deg] (Boston, ~14° W).
const DECL: f64 = -14.0;

fn at(bearing_deg: f64, distance_m: f64) -> LatLon {
    Earth::Wgs84.direct(O, bearing_deg, distance_m)
}

/// One waypoint 200 m due north of `O` (the wearer stands or walks at `O`, so the aim is at 0°).
fn guidance(mode: HeadingMode) -> Guidance {
    let route = Route::new(vec![Waypoint::at("N", at(0.0, 200.0))], RouteConfig::default()).unwrap();
    let cfg = GuidanceConfig { heading_mode: mode, declination_deg: Some(DECL), ..GuidanceConfig::default() };
    Guidance::new(route, cfg, StrategyKind::BearingOnly)
}

/// A fix at `O` nudged ~1 cm per second (never frozen), moving at `speed` on `cog`.
fn fix(speed_m_s: Option<f64>, cog_deg: Option<f64>, t_s: f64) -> NavInput {
    NavInput {
        position: Some(LatLon::new(O.lat_deg + 1e-7 * t_s, O.lon_deg)),
        speed_m_s,
        cog_deg,
        ..NavInput::default()
    }
}

/// A compass reading whose true heading is `true_deg` (magnetic = true - declination).
fn compass(true_deg: f64, age_s: f64, quality_pct: Option<u8>) -> CompassReading {
    CompassReading { magnetic_deg: true_deg - DECL, age_s, quality_pct }
}

#[test]
fn auto_prefers_a_fresh_good_compass_and_says_why() {
    let mut g = guidance(HeadingMode::Auto);
    // Walking at 1.4 m/s on COG 10°, compass (true) 20°: the compass wins, corrected once by the declination.
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 0.0), Some(compass(20.0, 0.0, Some(92))), 0.0);
    assert_eq!(d.heading_source, HeadingSource::Compass);
    assert_relative_eq!(d.heading_deg.unwrap(), 20.0, epsilon = 1e-9);
    assert_eq!(d.heading_rule, "compass (auto: compass fresh, quality 92 %)");
    // Stale (older than compass_max_age_s = 1 s): COG while moving.
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 1.0), Some(compass(20.0, 1.5, Some(92))), 1.0);
    assert_eq!(d.heading_source, HeadingSource::Cog);
    assert!(d.heading_rule.contains("stale"), "{}", d.heading_rule);
    // Poor quality: true heading first if there is one.
    let mut input = fix(Some(0.3), None, 2.0);
    input.true_heading_deg = Some(200.0);
    let d = g.update_with_compass(&input, Some(compass(20.0, 0.0, Some(40))), 2.0);
    assert_eq!((d.heading_source, d.heading_deg), (HeadingSource::TrueHeading, Some(200.0)));
    assert!(d.heading_rule.contains("quality 40 %"), "{}", d.heading_rule);
    // No quality figure (an external NMEA compass) is accepted.
    let d = g.update_with_compass(&fix(Some(0.3), None, 3.0), Some(compass(20.0, 0.0, None)), 3.0);
    assert_eq!(d.heading_source, HeadingSource::Compass);
    // Nothing usable, standing: hold with the rule as the reason.
    let d = g.update_with_compass(&fix(Some(0.3), Some(10.0), 4.0), None, 4.0);
    assert_eq!((d.heading_source, d.state), (HeadingSource::None, NavState::Hold));
    assert!(d.reason.contains("no compass"), "{}", d.reason);
}

#[test]
fn compass_mode_uses_nothing_else_and_holds_with_a_reason() {
    let mut g = guidance(HeadingMode::Compass);
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 0.0), None, 0.0);
    assert_eq!((d.state, d.cue), (NavState::Hold, Some(Cue::Attention)));
    assert!(d.reason.contains("no compass"), "{}", d.reason);
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 1.0), Some(compass(5.0, 3.0, Some(90))), 1.0);
    assert_eq!(d.state, NavState::Hold);
    assert!(d.reason.contains("stale"), "{}", d.reason);
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 2.0), Some(compass(5.0, 0.0, Some(90))), 2.0);
    assert_eq!((d.state, d.heading_source), (NavState::Guiding, HeadingSource::Compass));
    assert_relative_eq!(d.heading_deg.unwrap(), 5.0, epsilon = 1e-9);
    // Without a declination the compass is unusable: never guessed.
    let mut g = guidance(HeadingMode::Compass);
    g.set_declination_deg(None);
    let d = g.update_with_compass(&fix(Some(1.4), Some(10.0), 0.0), Some(compass(5.0, 0.0, Some(90))), 0.0);
    assert_eq!(d.state, NavState::Hold);
    assert!(d.reason.contains("no declination"), "{}", d.reason);
}

#[test]
fn declination_is_applied_once_in_every_mode() {
    // Magnetic 100°, declination -14°: true 86° (true = magnetic + declination), whichever mode picks it.
    for mode in HeadingMode::ALL {
        let mut g = guidance(mode);
        let input = fix(Some(0.2), None, 0.0);
        let reading = CompassReading { magnetic_deg: 100.0, age_s: 0.0, quality_pct: Some(95) };
        let d = g.update_with_compass(&input, Some(reading), 0.0);
        assert_eq!(d.heading_source, HeadingSource::Compass, "{mode:?}");
        assert_relative_eq!(d.heading_deg.unwrap(), 86.0, epsilon = 1e-9);
        // Bearing error to the waypoint due north: 0 - 86.
        assert_relative_eq!(d.bearing_error_deg.unwrap(), -86.0, epsilon = 0.01);
    }
    // `update` with `compass_deg` gives the same.
    let mut g = guidance(HeadingMode::Compass);
    let d = g.update(&NavInput { compass_deg: Some(100.0), ..fix(Some(0.2), None, 0.0) }, 0.0);
    assert_relative_eq!(d.heading_deg.unwrap(), 86.0, epsilon = 1e-9);
}

/// Feeds walking fixes every 0.5 s from `t0` for `secs` seconds, COG 0°, compass true `compass_true_deg`.
fn walk(g: &mut Guidance, t0: f64, secs: f64, speed: f64, compass_true_deg: f64) -> Decision {
    let mut d = None;
    let mut t = t0;
    while t <= t0 + secs + 1e-9 {
        d = Some(g.update_with_compass(
            &fix(Some(speed), Some(0.0), t),
            Some(compass(compass_true_deg, 0.0, Some(90))),
            t,
        ));
        t += 0.5;
    }
    d.unwrap()
}

#[test]
fn persistent_disagreement_while_walking_fast_warns_and_auto_prefers_cog() {
    let mut g = guidance(HeadingMode::Auto);
    // 45° apart (> 30°) at 1.4 m/s: nothing for 4.5 s, the warning from 5 s on.
    let d = walk(&mut g, 0.0, 4.5, 1.4, 45.0);
    assert!(!d.compass_disturbed);
    assert_eq!(d.heading_source, HeadingSource::Compass);
    assert_relative_eq!(d.compass_minus_cog_deg.unwrap(), 45.0, epsilon = 1e-9);
    let d = walk(&mut g, 5.0, 0.0, 1.4, 45.0);
    assert!(d.compass_disturbed, "{d:?}");
    assert_eq!(d.heading_source, HeadingSource::Cog);
    assert!(d.heading_rule.contains("disturbed"), "{}", d.heading_rule);
    assert!(d.reason.contains("compass disturbed?"), "{}", d.reason);
    // Standing, no evidence: the warning stays, and with no COG the compass is used (saying so).
    let d = g.update_with_compass(&fix(Some(0.0), None, 6.0), Some(compass(45.0, 0.0, Some(90))), 6.0);
    assert!(d.compass_disturbed);
    assert_eq!(d.heading_source, HeadingSource::Compass);
    assert!(d.heading_rule.contains("disturbed"), "{}", d.heading_rule);
    // Agreeing again (within 30°) for 5 s clears it; compass again.
    let d = walk(&mut g, 10.0, 4.5, 1.4, 10.0);
    assert!(d.compass_disturbed);
    let d = walk(&mut g, 15.0, 0.0, 1.4, 10.0);
    assert!(!d.compass_disturbed);
    assert_eq!(d.heading_source, HeadingSource::Compass);
}

#[test]
fn disagreement_needs_speed_and_persistence() {
    // At 0.9 m/s (COG trusted, but below the 1.0 m/s comparison speed) never.
    let mut g = guidance(HeadingMode::Auto);
    assert!(!walk(&mut g, 0.0, 30.0, 0.9, 90.0).compass_disturbed);
    // Interrupted runs of 4 s do not add up.
    let mut g = guidance(HeadingMode::Auto);
    for k in 0..5 {
        let t0 = f64::from(k) * 5.0;
        assert!(!walk(&mut g, t0, 4.0, 1.4, 60.0).compass_disturbed);
        assert!(!walk(&mut g, t0 + 4.5, 0.0, 1.4, 0.0).compass_disturbed);
    }
    // In compass mode the warning is raised but the compass is still used.
    let mut g = guidance(HeadingMode::Compass);
    let d = walk(&mut g, 0.0, 6.0, 1.4, 60.0);
    assert!(d.compass_disturbed);
    assert_eq!(d.heading_source, HeadingSource::Compass);
}

#[test]
fn standing_off_the_aim_turns_in_place_by_the_graded_amount() {
    // The waypoint is due north; standing, facing `h`, the cue is the graded turn toward 0°.
    for (h, cue) in [
        (90.0, Cue::RotateLeft(TurnStep::Deg90)),
        (30.0, Cue::RotateLeft(TurnStep::Deg30)),
        (300.0, Cue::RotateRight(TurnStep::Deg60)),
        (190.0, Cue::RotateRight(TurnStep::Deg135)),
        (150.0, Cue::RotateLeft(TurnStep::Deg135)),
        (260.0, Cue::RotateRight(TurnStep::Deg90)),
        (10.0, Cue::Forward),
        (341.0, Cue::Forward),
    ] {
        for speed in [Some(0.0), Some(0.5), None] {
            let mut g = guidance(HeadingMode::Compass);
            let d = g.update_with_compass(&fix(speed, None, 0.0), Some(compass(h, 0.0, Some(95))), 0.0);
            assert_eq!(d.cue, Some(cue), "heading {h}, speed {speed:?}: {}", d.reason);
            assert!(d.standing);
        }
    }
    // Walking at 1.4 m/s the walking vocabulary is used.
    let mut g = guidance(HeadingMode::Compass);
    let d = g.update_with_compass(&fix(Some(1.4), Some(90.0), 0.0), Some(compass(90.0, 0.0, Some(95))), 0.0);
    assert_eq!(d.cue, Some(Cue::TurnLeft));
    assert!(!d.standing);
    // Switched off: the walking vocabulary while standing too.
    let mut g = guidance(HeadingMode::Compass);
    let mut cfg = *g.config();
    cfg.turn_in_place = false;
    let route = g.route().clone();
    g = Guidance::new(route, cfg, StrategyKind::BearingOnly);
    let d = g.update_with_compass(&fix(Some(0.0), None, 0.0), Some(compass(90.0, 0.0, Some(95))), 0.0);
    assert_eq!(d.cue, Some(Cue::TurnLeft));
}

#[test]
fn turning_in_place_is_not_interrupted_by_a_smaller_turn_the_same_way() {
    let mut g = guidance(HeadingMode::Compass);
    let c = |h| Some(compass(h, 0.0, Some(95)));
    let d = g.update_with_compass(&fix(Some(0.0), None, 0.0), c(100.0), 0.0);
    assert_eq!(d.cue, Some(Cue::RotateLeft(TurnStep::Deg90)));
    // The sweep is 4 x 250 ms; at 1.6 s the wearer is half way round (error -50°): a 60° turn left is
    // wanted but held for the repeat interval (3 s after the end), as the wearer is still turning.
    let d = g.update_with_compass(&fix(Some(0.0), None, 1.6), c(50.0), 1.6);
    assert_eq!((d.cue, d.wanted), (None, Some(Cue::RotateLeft(TurnStep::Deg60))));
    // Faced (error -5°): Forward goes at once, a different cue.
    let d = g.update_with_compass(&fix(Some(0.0), None, 2.0), c(5.0), 2.0);
    assert_eq!(d.cue, Some(Cue::Forward));
    // Overshot by 40° to the other side: a turn right is not held by the earlier left turn.
    let d = g.update_with_compass(&fix(Some(0.0), None, 3.5), c(320.0), 3.5);
    assert_eq!(d.cue, Some(Cue::RotateRight(TurnStep::Deg30)));
}

#[test]
fn standing_on_the_waypoint_gives_no_turn_toward_gps_noise() {
    // Route: the wearer stands 3 m from the first of two waypoints (inside the 8 m arrival radius).
    let route = Route::new(
        vec![Waypoint::at("A", at(90.0, 3.0)), Waypoint::at("B", at(0.0, 100.0))],
        RouteConfig::default(),
    )
    .unwrap();
    let cfg = GuidanceConfig {
        heading_mode: HeadingMode::Compass,
        declination_deg: Some(DECL),
        ..Default::default()
    };
    let mut g = Guidance::new(route, cfg, StrategyKind::BearingOnly);
    let d = g.update_with_compass(&fix(Some(0.0), None, 0.0), Some(compass(200.0, 0.0, Some(95))), 0.0);
    assert_eq!((d.cue, d.wanted, d.state), (None, None, NavState::Guiding));
    assert!(d.reason.contains("confirming arrival"), "{}", d.reason);
    // Second fix: arrival; then the aim is B, due north, 160° to the right of 200°.
    let d = g.update_with_compass(&fix(Some(0.0), None, 1.0), Some(compass(200.0, 0.0, Some(95))), 1.0);
    assert_eq!(d.cue, Some(Cue::Arrived));
    let d = g.update_with_compass(&fix(Some(0.0), None, 2.5), Some(compass(200.0, 0.0, Some(95))), 2.5);
    assert_eq!(d.cue, Some(Cue::RotateRight(TurnStep::Deg135)), "{}", d.reason);
}
