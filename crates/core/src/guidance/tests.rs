//! Unit tests of guidance: route progress, cue selection, rate limiting, manual overrides and strategies.

use super::*;
use approx::assert_relative_eq;

const O: LatLon = LatLon::new(42.3575, -71.1010);

fn route_line(n: usize, spacing_m: f64, bearing_deg: f64, config: RouteConfig) -> Route {
    let wps = (0..n)
        .map(|i| Waypoint::at(format!("w{i}"), Earth::Wgs84.direct(O, bearing_deg, spacing_m * i as f64)))
        .collect();
    Route::new(wps, config).unwrap()
}

/// A fix of a walker at `p` at time `t_s`, nudged ~1 cm per second so the position is never frozen.
fn mv(p: LatLon, cog_deg: f64, t_s: f64) -> NavInput {
    NavInput::moving(LatLon::new(p.lat_deg + 1e-7 * t_s, p.lon_deg), cog_deg, 1.4)
}

fn at(bearing_deg: f64, distance_m: f64) -> LatLon {
    Earth::Wgs84.direct(O, bearing_deg, distance_m)
}

#[test]
fn a_cue_that_never_reached_the_wearer_is_not_counted_as_played() {
    // 50 m south of the first waypoint, walking east: it is 90° to the left.
    let mut g = Guidance::new(
        route_line(3, 100.0, 0.0, RouteConfig::default()),
        GuidanceConfig::default(),
        StrategyKind::BearingOnly,
    );
    let p = at(180.0, 50.0);
    let d = g.update(&mv(p, 90.0, 0.0), 0.0);
    assert_eq!(d.cue, Some(Cue::TurnLeft));
    // Played: the pattern is running, nothing new until it ends and the repeat interval passes.
    assert_eq!(g.update(&mv(p, 90.0, 0.1), 0.1).cue, None);
    // Not played (say the vest refused it): the same cue goes at the next update.
    let mut g2 = Guidance::new(
        route_line(3, 100.0, 0.0, RouteConfig::default()),
        GuidanceConfig::default(),
        StrategyKind::BearingOnly,
    );
    assert_eq!(g2.update(&mv(p, 90.0, 0.0), 0.0).cue, Some(Cue::TurnLeft));
    g2.not_played();
    assert_eq!(g2.update(&mv(p, 90.0, 0.1), 0.1).cue, Some(Cue::TurnLeft));
    // Taking back is one-shot: an update that decided nothing has nothing to take back.
    assert_eq!(g2.update(&mv(p, 90.0, 0.2), 0.2).cue, None);
    g2.not_played();
    assert_eq!(g2.update(&mv(p, 90.0, 0.3), 0.3).cue, None);
}

#[test]
fn thresholds_classify_by_bearing_error() {
    let t = CueThresholds::default();
    assert_eq!(t.classify(0.0, None), Cue::Forward);
    assert_eq!(t.classify(14.0, None), Cue::Forward);
    assert_eq!(t.classify(20.0, None), Cue::SlightRight);
    assert_eq!(t.classify(-20.0, None), Cue::SlightLeft);
    assert_eq!(t.classify(90.0, None), Cue::TurnRight);
    assert_eq!(t.classify(-90.0, None), Cue::TurnLeft);
    assert_eq!(t.classify(170.0, None), Cue::TurnAround);
    assert_eq!(t.classify(-150.0, None), Cue::TurnAround);
    // Hysteresis: at 17° a walker already told "forward" stays forward; at 21° it changes.
    assert_eq!(t.classify(17.0, Some(Cue::Forward)), Cue::Forward);
    assert_eq!(t.classify(21.0, Some(Cue::Forward)), Cue::SlightRight);
    assert_eq!(t.classify(12.0, Some(Cue::SlightRight)), Cue::SlightRight);
    assert_eq!(t.classify(9.0, Some(Cue::SlightRight)), Cue::Forward);
}

#[test]
fn heading_source_rules() {
    let route = route_line(2, 100.0, 0.0, RouteConfig::default());
    let mut cfg = GuidanceConfig::default();
    let g = Guidance::new(route.clone(), cfg, StrategyKind::BearingOnly);
    let mut input =
        NavInput { position: Some(O), cog_deg: Some(10.0), speed_m_s: Some(1.2), ..NavInput::default() };
    assert_eq!(g.select_heading(&input).0, HeadingSource::Cog);
    input.speed_m_s = Some(0.3);
    assert_eq!(g.select_heading(&input), (HeadingSource::None, None));
    input.compass_deg = Some(100.0);
    // No declination configured: the compass is not trusted.
    assert_eq!(g.select_heading(&input).0, HeadingSource::None);
    cfg.declination_deg = Some(-14.2);
    let g = Guidance::new(route, cfg, StrategyKind::BearingOnly);
    let (src, h) = g.select_heading(&input);
    assert_eq!(src, HeadingSource::Compass);
    assert_relative_eq!(h.unwrap(), 85.8, max_relative = 1e-12);
    input.true_heading_deg = Some(200.0);
    assert_eq!(g.select_heading(&input), (HeadingSource::TrueHeading, Some(200.0)));
    input.speed_m_s = Some(1.0);
    assert_eq!(g.select_heading(&input).0, HeadingSource::Cog);
}

#[test]
fn stale_missing_or_headingless_fix_gives_attention_only() {
    let route = route_line(2, 100.0, 0.0, RouteConfig::default());
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
    let d = g.update(&NavInput::default(), 0.0);
    assert_eq!((d.cue, d.state), (Some(Cue::Attention), NavState::Hold));
    let mut stale = NavInput::moving(at(180.0, 50.0), 0.0, 1.4);
    stale.fix_age_s = 4.0;
    let d = g.update(&stale, 10.0);
    assert_eq!(d.cue, Some(Cue::Attention));
    assert!(d.reason.contains("stale"), "{}", d.reason);
    // Standing still with COG only: no heading, no direction.
    let still = NavInput::moving(at(180.0, 50.0), 0.0, 0.2);
    let d = g.update(&still, 20.0);
    assert_eq!(d.cue, Some(Cue::Attention));
    assert_eq!(d.heading_source, HeadingSource::None);
    // Poor HDOP.
    let mut poor = NavInput::moving(at(180.0, 50.0), 0.0, 1.4);
    poor.hdop = Some(8.0);
    let d = g.update(&poor, 30.0);
    assert_eq!(d.state, NavState::Hold);
    // Non-finite input never panics nor directs.
    let nan = NavInput::moving(LatLon::new(f64::NAN, 0.0), f64::NAN, f64::NAN);
    let d = g.update(&nan, 40.0);
    assert_eq!(d.state, NavState::Hold);
}

#[test]
fn a_pinned_position_while_moving_holds() {
    let route = route_line(2, 200.0, 0.0, RouteConfig::default());
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
    let p = at(180.0, 50.0);
    for t in 0..=5 {
        let d = g.update(&NavInput::moving(p, 0.0, 1.0), f64::from(t));
        assert_eq!(d.state, NavState::Guiding, "t = {t}");
    }
    let d = g.update(&NavInput::moving(p, 0.0, 1.0), 6.0);
    assert_eq!((d.state, d.cue), (NavState::Hold, Some(Cue::Attention)));
    assert!(d.reason.contains("frozen"), "{}", d.reason);
    // A new position ends it.
    let d = g.update(&NavInput::moving(at(180.0, 48.0), 0.0, 1.0), 7.0);
    assert_eq!(d.state, NavState::Guiding);
}

#[test]
fn rate_limit_one_cue_at_a_time_and_repeat_intervals() {
    let route = route_line(2, 200.0, 0.0, RouteConfig::default());
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
    // Heading east while the waypoint is north: turn left.
    let p = at(180.0, 50.0);
    let d = g.update(&mv(p, 90.0, 0.0), 0.0);
    assert_eq!(d.cue, Some(Cue::TurnLeft));
    // Turn pattern = 4 x 250 ms = 1 s, + 0.5 s gap; the same cue needs 3 s after the pattern ended.
    assert_relative_eq!(g.allowed_from_s(Cue::TurnRight), 1.5);
    assert_relative_eq!(g.allowed_from_s(Cue::TurnLeft), 4.0);
    assert_relative_eq!(
        g.allowed_from_s(Cue::RotateLeft(crate::vest::TurnStep::Deg60)),
        4.0,
        epsilon = 1e-12
    );
    assert_eq!(g.update(&mv(p, 90.0, 1.0), 1.0).cue, None);
    assert_eq!(g.update(&mv(p, 90.0, 3.9), 3.9).cue, None);
    assert_eq!(g.update(&mv(p, 90.0, 4.0), 4.0).cue, Some(Cue::TurnLeft));
    // A different cue only waits for the pattern end (5.0) + gap.
    assert_relative_eq!(g.allowed_from_s(Cue::Forward), 5.5);
    assert_eq!(g.update(&mv(p, 0.0, 5.4), 5.4).cue, None);
    let d = g.update(&mv(p, 0.0, 5.5), 5.5);
    assert_eq!(d.cue, Some(Cue::Forward));
    // Forward (1 s pattern, ends 6.5) repeats 10 s after its end only.
    for t in [7.0, 10.0, 16.4] {
        let d = g.update(&mv(p, 0.0, t), t);
        assert_eq!((d.cue, d.wanted), (None, Some(Cue::Forward)), "t = {t}");
    }
    assert_eq!(g.update(&mv(p, 0.0, 16.5), 16.5).cue, Some(Cue::Forward));
}

#[test]
fn manual_override_and_stop_all_priority() {
    let route = route_line(2, 200.0, 0.0, RouteConfig::default());
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
    let p = at(180.0, 50.0);
    let d = g.manual(Cue::Stop, 0.0);
    assert_eq!(d.cue, Some(Cue::Stop));
    // Muted for the pattern (0.5 s) + 10 s.
    let d = g.update(&mv(p, 90.0, 5.0), 5.0);
    assert_eq!((d.cue, d.state, d.wanted), (None, NavState::Manual, Some(Cue::TurnLeft)));
    assert_eq!(g.update(&mv(p, 90.0, 11.0), 11.0).cue, Some(Cue::TurnLeft));
    // STOP ALL wins over manual cues and automatic ones until resume.
    let d = g.stop_all(12.0);
    assert!(d.stop_all);
    assert_eq!(g.manual(Cue::Forward, 13.0).cue, None);
    assert_eq!(g.update(&mv(p, 90.0, 20.0), 20.0).cue, None);
    g.resume();
    assert_eq!(g.update(&mv(p, 90.0, 21.0), 21.0).cue, Some(Cue::TurnLeft));
}

#[test]
fn arrival_needs_confirmation_and_back_rearms() {
    let mut route = route_line(3, 100.0, 90.0, RouteConfig::default());
    let near0 = at(0.0, 3.0);
    assert_eq!(route.observe(Earth::Wgs84, near0), None);
    assert_eq!(route.observe(Earth::Wgs84, at(0.0, 30.0)), None); // a noisy jump out resets
    assert_eq!(route.observe(Earth::Wgs84, near0), None);
    assert_eq!(route.observe(Earth::Wgs84, near0), Some(RouteEvent::Arrived(0)));
    assert_eq!(route.active_index(), 1);
    route.back();
    assert_eq!(route.active_index(), 0);
    // Standing on waypoint 0 after `back`: not re-arrived until we leave 12 m and come back.
    for _ in 0..5 {
        assert_eq!(route.observe(Earth::Wgs84, near0), None);
    }
    assert_eq!(route.observe(Earth::Wgs84, at(90.0, 20.0)), None);
    assert_eq!(route.observe(Earth::Wgs84, near0), None);
    assert_eq!(route.observe(Earth::Wgs84, near0), Some(RouteEvent::Arrived(0)));
    // Skip to the last, then finish.
    assert_eq!(route.skip(), None);
    assert_eq!(route.active_index(), 2);
    assert_eq!(route.skip(), Some(RouteEvent::Finished));
    assert!(route.is_finished());
}

#[test]
fn a_waypoints_own_radius_decides_its_arrival() {
    // Waypoint 0 with its own 30 m radius: a fix 20 m away arrives (the route's 8 m would not), and the
    // re-arm radius scales with it (12 m x 30/8 = 45 m). Waypoint 1 keeps the route's 8 m.
    let cfg = RouteConfig { confirm_fixes: 1, ..RouteConfig::default() };
    let wps = vec![
        Waypoint::at("wide", O).with_arrival_radius_m(Some(30.0)),
        Waypoint::at("plain", Earth::Wgs84.direct(O, 90.0, 200.0)),
    ];
    let mut route = Route::new(wps, cfg).unwrap();
    assert_eq!(route.active_radii_m(), (30.0, 45.0, 60.0));
    assert_eq!(route.observe(Earth::Wgs84, at(0.0, 20.0)), Some(RouteEvent::Arrived(0)));
    assert_eq!(route.active_radii_m(), (8.0, 12.0, 16.0));
    let near1 = Earth::Wgs84.direct(O, 90.0, 180.0); // 20 m before waypoint 1
    assert_eq!(route.observe(Earth::Wgs84, near1), None);
    let bad = vec![Waypoint::at("w", O).with_arrival_radius_m(Some(-1.0))];
    assert!(Route::new(bad, cfg).is_err());
}

#[test]
fn passing_abeam_advances() {
    let mut route = route_line(3, 100.0, 90.0, RouteConfig::default());
    route.skip(); // active = w1 at 100 m east; leg w0 -> w1
    // 105 m east and 12 m north: past w1, outside 8 m but within 16 m.
    let p = Earth::Wgs84.direct(at(90.0, 105.0), 0.0, 12.0);
    assert_eq!(route.observe(Earth::Wgs84, p), Some(RouteEvent::Passed(1)));
    assert_eq!(route.active_index(), 2);
}

#[test]
fn looped_route_wraps() {
    let cfg = RouteConfig { looped: true, confirm_fixes: 1, ..RouteConfig::default() };
    let mut route = route_line(2, 100.0, 0.0, cfg);
    assert_eq!(route.observe(Earth::Wgs84, O), Some(RouteEvent::Arrived(0)));
    assert_eq!(route.observe(Earth::Wgs84, at(0.0, 100.0)), Some(RouteEvent::Arrived(1)));
    assert_eq!(route.active_index(), 0);
    assert_eq!(route.laps(), 1);
    assert!(!route.is_finished());
    assert_eq!(route.previous().map(|w| w.name.as_str()), Some("w1"));
}

#[test]
fn arrival_then_finish_cues() {
    let cfg = RouteConfig { confirm_fixes: 1, ..RouteConfig::default() };
    let route = route_line(2, 100.0, 0.0, cfg);
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::Pursuit);
    let d = g.update(&NavInput::moving(O, 0.0, 1.4), 0.0);
    assert_eq!((d.event, d.cue), (Some(RouteEvent::Arrived(0)), Some(Cue::Arrived)));
    let d = g.update(&NavInput::moving(at(0.0, 50.0), 0.0, 1.4), 5.0);
    assert_eq!(d.cue, Some(Cue::Forward));
    let d = g.update(&NavInput::moving(at(0.0, 99.0), 0.0, 1.4), 6.0);
    assert_eq!((d.event, d.state), (Some(RouteEvent::Finished), NavState::Finished));
    // The forward pattern (1 s) is still playing: the stop waits for it.
    assert_eq!(d.cue, None);
    let d = g.update(&mv(at(0.0, 99.0), 0.0, 7.0), 7.0);
    assert_eq!(d.cue, Some(Cue::Stop));
    let d = g.update(&mv(at(0.0, 99.0), 0.0, 20.0), 20.0);
    assert_eq!(d.cue, None);
}

#[test]
fn pursuit_corrects_cross_track_and_bearing_does_not() {
    // Leg w0 -> w1 due north, 200 m; wearer 20 m east of the leg, 50 m along, heading north.
    let route = || {
        let mut r = route_line(2, 200.0, 0.0, RouteConfig::default());
        r.skip();
        r
    };
    let p = Earth::Wgs84.direct(at(0.0, 50.0), 90.0, 20.0);
    let mut bearing = Guidance::new(route(), GuidanceConfig::default(), StrategyKind::BearingOnly);
    let mut pursuit = Guidance::new(route(), GuidanceConfig::default(), StrategyKind::Pursuit);
    let db = bearing.update(&NavInput::moving(p, 0.0, 1.4), 0.0);
    let dp = pursuit.update(&NavInput::moving(p, 0.0, 1.4), 0.0);
    // Bearing-only: atan(20/150) = 7.6° left -> forward. Pursuit: atan(20/15) = 53.1° left -> turn left.
    assert_relative_eq!(
        db.bearing_error_deg.unwrap(),
        -(20.0f64 / 150.0).atan().to_degrees(),
        epsilon = 0.05
    );
    assert_relative_eq!(dp.bearing_error_deg.unwrap(), -(20.0f64 / 15.0).atan().to_degrees(), epsilon = 0.05);
    assert_eq!(db.cue, Some(Cue::Forward));
    assert_eq!(dp.cue, Some(Cue::TurnLeft));
    assert_relative_eq!(dp.cross_track_m.unwrap(), 20.0, epsilon = 0.01);
}

proptest::proptest! {
    #[test]
    fn no_input_panics_and_stale_fixes_never_direct(
        lat in proptest::num::f64::ANY, lon in proptest::num::f64::ANY,
        age in proptest::num::f64::ANY, speed in proptest::num::f64::ANY,
        cog in proptest::num::f64::ANY, hdg in proptest::num::f64::ANY,
        hdop in proptest::num::f64::ANY, now in -1e6..1e6f64, has_pos: bool,
    ) {
        let route = route_line(3, 100.0, 45.0, RouteConfig::default());
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::Pursuit);
        let input = NavInput {
            position: has_pos.then_some(LatLon::new(lat, lon)),
            fix_age_s: age,
            speed_m_s: Some(speed),
            cog_deg: Some(cog),
            true_heading_deg: Some(hdg),
            compass_deg: None,
            hdop: Some(hdop),
            accuracy_m: None,
        };
        let d = g.update(&input, now);
        let trustworthy = has_pos && age.is_finite() && age <= 3.0;
        if !trustworthy {
            proptest::prop_assert!(matches!(d.cue, None | Some(Cue::Attention)), "{:?}", d.cue);
        }
        proptest::prop_assert!(d.bearing_error_deg.is_none_or(f64::is_finite));
    }
}

/// An L-shaped path from `O`: 100 m east, then 100 m north, every 10 m a vertex; two waypoints, its ends.
fn l_path_route(config: RouteConfig) -> Route {
    let e = Earth::Wgs84;
    let corner = e.direct(O, 90.0, 100.0);
    let mut pts: Vec<LatLon> = (0..=10).map(|i| e.direct(O, 90.0, 10.0 * f64::from(i))).collect();
    pts.extend((1..=10).map(|i| e.direct(corner, 0.0, 10.0 * f64::from(i))));
    let wps = vec![Waypoint::at("start", pts[0]), Waypoint::at("end", pts[20])];
    let path = RoutePath::new(pts, vec![0, 20]).unwrap();
    let mut r = Route::new(wps, config).unwrap().with_path(Some(path)).unwrap();
    let _ = r.skip(); // heading for "end"
    r
}

#[test]
fn a_wearer_beside_a_bent_path_is_steered_back_to_it_not_along_the_chord() {
    // 50 m along the eastern arm and 10 m north of it (left of the path), walking east. The straight leg
    // from start to end is the diagonal, which passes 28 m north-west of the wearer: measured from it the
    // wearer is right of the route and would be told to turn left. Along the path the wearer is 10 m left
    // of it: the aim 15 m ahead on the path is at bearing 90 + atan(10/15) = 123.7°, a turn to the right.
    let e = Earth::Wgs84;
    let p = e.direct(e.direct(O, 90.0, 50.0), 0.0, 10.0);
    for kind in StrategyKind::ALL {
        let mut g = Guidance::new(l_path_route(RouteConfig::default()), GuidanceConfig::default(), kind);
        let d = g.update(&mv(p, 90.0, 0.0), 0.0);
        assert_relative_eq!(d.cross_track_m.unwrap(), -10.0, max_relative = 1e-3);
        assert_relative_eq!(
            d.bearing_deg.unwrap(),
            90.0 + (10.0f64 / 15.0).atan().to_degrees(),
            epsilon = 0.05
        );
        assert!(matches!(d.cue, Some(Cue::TurnRight | Cue::SlightRight)), "{kind:?}: {d:?}");
        // Without the path the straight leg says the opposite.
        let straight = {
            let mut r =
                Route::new(l_path_route(RouteConfig::default()).waypoints().to_vec(), RouteConfig::default())
                    .unwrap();
            let _ = r.skip();
            r
        };
        let mut g = Guidance::new(straight, GuidanceConfig::default(), kind);
        let d = g.update(&mv(p, 90.0, 0.0), 0.0);
        assert!(d.cross_track_m.unwrap() > 20.0, "{d:?}");
        assert!(matches!(d.cue, Some(Cue::TurnLeft | Cue::SlightLeft)), "{kind:?}: {d:?}");
    }
    // On the northern arm, 6 m east of it (right of northward travel), walking north: steer left.
    let q = e.direct(e.direct(e.direct(O, 90.0, 100.0), 0.0, 40.0), 90.0, 6.0);
    let mut g =
        Guidance::new(l_path_route(RouteConfig::default()), GuidanceConfig::default(), StrategyKind::Pursuit);
    let d = g.update(&mv(q, 0.0, 0.0), 0.0);
    assert_relative_eq!(d.cross_track_m.unwrap(), 6.0, max_relative = 1e-3);
    assert!(matches!(d.cue, Some(Cue::SlightLeft | Cue::TurnLeft)), "{d:?}");
}

#[test]
fn off_the_path_for_the_set_time_asks_for_a_new_route_once_per_excursion() {
    let e = Earth::Wgs84;
    let config = GuidanceConfig { off_path_m: 20.0, off_path_s: 15.0, ..GuidanceConfig::default() };
    let mut g = Guidance::new(l_path_route(RouteConfig::default()), config, StrategyKind::Pursuit);
    let on = e.direct(e.direct(O, 90.0, 30.0), 0.0, 5.0);
    let off = e.direct(e.direct(O, 90.0, 30.0), 180.0, 30.0);
    let d = g.update(&mv(on, 90.0, 0.0), 0.0);
    assert_eq!((d.off_path_s, d.reroute), (None, false));
    // Off from t = 1 s: asked at t = 16 s, not before.
    for t in 1..=20 {
        let t = f64::from(t);
        let d = g.update(&mv(off, 90.0, t), t);
        assert_relative_eq!(d.off_path_s.unwrap(), t - 1.0, epsilon = 1e-6);
        assert_eq!(d.reroute, t >= 16.0, "t = {t}");
    }
    // Back on the path: the excursion is over.
    let d = g.update(&mv(on, 90.0, 21.0), 21.0);
    assert_eq!((d.off_path_s, d.reroute), (None, false));
}

/// Passing a waypoint without arriving is judged along the path where the route has one. Positions are
/// east/north metres from `O` on the L-shaped path (east arm to the corner at (100, 0), north arm to the end
/// at (100, 100)); arrival radius 5 m, pass radius 16 m, so none of these positions arrives.
#[test]
fn passing_a_waypoint_is_judged_along_a_bent_path_not_the_straight_leg() {
    let e = Earth::Wgs84;
    let en = |east: f64, north: f64| e.direct(e.direct(O, 90.0, east), 0.0, north);
    let config = RouteConfig {
        arrival_radius_m: 5.0,
        rearm_radius_m: 7.5,
        pass_radius_m: 16.0,
        ..RouteConfig::default()
    };
    // The last waypoint, reached up the north arm. (110, 97): beside it, 3 m short of it along the arm,
    // though past it along the diagonal chord (146 m of 141 m). (88, 108): 8 m past it along the arm,
    // though short of it along the chord (139 m of 141 m).
    let straight = |p: LatLon| {
        let mut r = Route::new(l_path_route(config).waypoints().to_vec(), config).unwrap();
        let _ = r.skip();
        r.observe(e, p)
    };
    let along = |p: LatLon| l_path_route(config).observe(e, p);
    assert_eq!(straight(en(110.0, 97.0)), Some(RouteEvent::Finished));
    assert_eq!(along(en(110.0, 97.0)), None);
    assert_eq!(straight(en(88.0, 108.0)), None);
    assert_eq!(along(en(88.0, 108.0)), Some(RouteEvent::Finished));

    // A waypoint at the corner, with the north arm after it. (95, 8): 5 m from the north arm, 8 m from the
    // east one, so past the corner along the path, though 5 m short of it along the straight leg from the
    // start. (106, -5): past the corner along the straight (eastward) leg, but its nearest point of the path
    // is the corner itself: not past it.
    let corner_route = |with_path: bool| {
        let l = l_path_route(config);
        let path = l.path().unwrap().clone();
        let pts = path.points().to_vec();
        let wps = vec![
            Waypoint::at("start", pts[0]),
            Waypoint::at("corner", pts[10]),
            Waypoint::at("end", pts[20]),
        ];
        let path = with_path.then(|| RoutePath::new(pts, vec![0, 10, 20]).unwrap());
        let mut r = Route::new(wps, config).unwrap().with_path(path).unwrap();
        let _ = r.skip(); // heading for the corner
        r
    };
    assert_eq!(corner_route(false).observe(e, en(95.0, 8.0)), None);
    assert_eq!(corner_route(true).observe(e, en(95.0, 8.0)), Some(RouteEvent::Passed(1)));
    assert_eq!(corner_route(false).observe(e, en(106.0, -5.0)), Some(RouteEvent::Passed(1)));
    assert_eq!(corner_route(true).observe(e, en(106.0, -5.0)), None);
}

/// Issue 23 item 3: a receiver diagnosed as pinned (zero speed, so the engine's own check cannot see it)
/// holds guidance with the reason, even on the waypoint itself: no arrival from a frozen position, and
/// attention cues instead of silence; once it is no longer frozen, the same fix arrives.
#[test]
fn a_position_diagnosed_frozen_holds_and_never_arrives() {
    let route = route_line(2, 200.0, 0.0, RouteConfig::default());
    let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
    g.set_position_frozen(Some("SiRF static navigation".to_owned()));
    let on_wp = at(0.0, 0.0);
    let still = NavInput { speed_m_s: Some(0.0), ..NavInput::moving(on_wp, 0.0, 0.0) };
    for t in 0..5 {
        let d = g.update(&still, f64::from(t));
        assert_eq!(d.state, NavState::Hold, "t = {t}");
        assert!(d.event.is_none(), "no arrival: {:?}", d.event);
        assert!(d.reason.contains("position frozen (SiRF static navigation)"), "{}", d.reason);
        if t == 0 {
            assert_eq!(d.cue, Some(Cue::Attention), "the wearer is told, not left in silence");
        }
    }
    // Cleared: the same fixes count again (arrival is confirmed over a few fixes).
    g.set_position_frozen(None);
    let arrived =
        (5..12).any(|t| matches!(g.update(&still, f64::from(t)).event, Some(RouteEvent::Arrived(_))));
    assert!(arrived, "the waypoint is reached once the position is trusted again");
}
