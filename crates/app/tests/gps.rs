//! The console's GPS panel driven by label with `egui_kittest`, devices injected: fixes, staleness and loss,
//! the alarm and the banner, the satellite table, the error estimate.
#![allow(clippy::unwrap_used)]

mod common;

use common::console::*;
use egui_kittest::kittest::Queryable as _;
use std::time::{Duration, Instant};
use vestnav_app::config::{Config, GpsSourceConfig};
use vestnav_app::console::GpsAlarm;
use vestnav_app::console::Severity;
use vestnav_device::gps::{ErrorEstimate, ErrorSource, Fix, FixMode, GpsEvent};

#[test]
fn a_fix_shows_and_losing_it_raises_the_alarm() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fix.is_some());
    assert!(h.query_by_label_contains("42.3562000°").is_some());
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    // The last position's bytes arrived longer ago than the lost limit (ages run on the real clock, from
    // the instant the bytes arrived).
    let lost = h.state().cfg.lost_after_s;
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::from_secs_f64(lost + 1.0)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Lost { .. })));
    h.run_steps(1);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_some());
    // A fresh fix clears it; a receiver that reports "no fix" raises it at once.
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    let no_fix = Fix { mode: Some(FixMode::NoFix), received_at: Some(Instant::now()), ..Fix::default() };
    fake.gps(&GpsEvent::Fix(Box::new(no_fix)));
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| f.mode == Some(FixMode::NoFix)));
    h.run_steps(1);
    assert!(h.query_by_label_contains("receiver reports no fix").is_some());
}

#[test]
fn nmea_replay_shows_the_fix_then_the_no_fix_alarm() {
    let mut h = real_harness(None);
    settle(&mut h, |c| c.station.gps.fix.is_some());
    h.get_by_label("Disconnect GPS").click();
    h.run_steps(2);
    assert!(!h.state().gps_connected());
    // Pick the replay source in the combo box, by label.
    h.get_by_label("GPS source").click();
    h.run_steps(2);
    h.get_by_label("NMEA file replay").click();
    h.run_steps(2);
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/walk_then_lost.nmea");
    {
        let p = &mut h.state_mut().gps_ui.picker;
        assert_eq!(p.kind, vestnav_app::gps_panel::SourceKind::Replay);
        p.replay_path = file.to_owned();
        p.replay_speed = 10.0;
    }
    h.get_by_label("Connect GPS").click();
    // Epoch 12:00:04 is the last with a position (42.3562667 N, independent: 42° 21.3760').
    let t4 = "2026-11-22T12:00:04Z".parse::<chrono::DateTime<chrono::Utc>>().unwrap();
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| f.time == Some(t4)));
    let f = h.state().station.gps.fix.clone().unwrap();
    let (lat, lon) = (f.lat_deg.unwrap(), f.lon_deg.unwrap());
    assert!((lat - (42.0 + 21.376 / 60.0)).abs() < 1e-9, "{lat}");
    assert!((lon + 71.1).abs() < 1e-9);
    assert!(h.query_by_label_contains("-71.1000000°").is_some());
    // Then the receiver reports no fix: the alarm is raised at once.
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| !f.has_position()));
    h.run_steps(1);
    assert!(h.query_by_label_contains("GPS FIX LOST: receiver reports no fix").is_some());
    assert!(h.query_by_label_contains("GPS: FIX LOST").is_some());
    assert_eq!(
        h.state().cfg.gps,
        GpsSourceConfig::Replay { path: file.into(), speed: vestnav_device::gps::ReplaySpeed::Times(10.0) },
        "the chosen source is remembered in the config"
    );
}

/// Fault 3 of issue 15: during a stale or lost fix the panel no longer shows the last mode and satellite
/// count as current, and the wearer's dot is not the live one. Ages come from the injected fixes' arrival
/// instants (small limits keep the test short).
#[test]
fn a_stale_or_lost_fix_is_shown_as_last_known_not_live() {
    let fake = Fake::default();
    let cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        stale_after_s: 2.0,
        lost_after_s: 4.0,
        ..Config::default()
    };
    let mut h = harness_with(&fake, cfg);
    let with_sats = |age: Duration| Fix {
        sats_used: Some(8),
        sats_visible: Some(9),
        satellites: (1..=9)
            .map(|prn| vestnav_device::gps::Satellite {
                prn,
                constellation: vestnav_device::gps::Constellation::Gps,
                elevation_deg: Some(45.0),
                azimuth_deg: Some(f64::from(prn) * 40.0),
                snr_dbhz: Some(42.0),
                used: prn <= 8,
            })
            .collect(),
        ..fix(42.3562, -71.1, age)
    };
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(1);
    assert!(h.query_by_label("3D · —").is_some(), "a fresh fix shows its mode as current");
    assert!(h.query_by_label("8 used / 9 in view").is_some());
    assert!(h.query_by_label_contains("showing the last known fix").is_none());
    assert!(h.state().map.wearer_shown.is_some_and(|m| m.live));

    // Stale: the newest fix's bytes arrived 3 s ago (past 2 s).
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(3)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(1);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Stale { .. })));
    assert!(h.query_by_label_contains("NOT CURRENT: showing the last known fix, 3 s ago").is_some());
    assert!(h.query_by_label("3D · —").is_none(), "the live mode label is gone");
    assert!(h.query_by_label("8 used / 9 in view").is_none(), "the live satellite count is gone");
    assert!(h.query_by_label_contains("3D · — (last known, 3 s ago)").is_some());
    assert!(h.query_by_label_contains("sky and signal: last known").is_some());
    let m = h.state().map.wearer_shown.unwrap();
    assert!(!m.live && m.age_s.is_some_and(|a| a >= 3.0), "{m:?}");

    // Lost: 5 s (past 4 s).
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(5)))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    h.run_steps(1);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Lost { .. })));
    assert!(h.query_by_label_contains("FIX LOST: showing the last known fix, 5 s ago").is_some());
    assert!(h.query_by_label("3D · —").is_none());
    assert!(h.query_by_label_contains("8 used / 9 in view (last known, 5 s ago)").is_some());
    assert!(h.state().map.wearer_shown.is_some_and(|m| !m.live));

    // A fresh fix makes it live again.
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 4);
    h.run_steps(1);
    assert!(h.query_by_label("3D · —").is_some());
    assert!(h.state().map.wearer_shown.is_some_and(|m| m.live));
}

/// A stale fix raises the GPS line of the banner (amber, with its age and what to do); a fresh one clears it.
#[test]
fn a_stale_fix_shows_in_the_banner() {
    let fake = Fake::default();
    let cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        stale_after_s: 2.0,
        lost_after_s: 30.0,
        ..Config::default()
    };
    let mut h = harness_with(&fake, cfg);
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(1);
    assert!(banner_of(h.state(), BannerSubject::Gps).is_none());
    assert!(h.query_by_label_contains("GPS STALE").is_none());
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::from_secs(3)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(1);
    let gps = banner_of(h.state(), BannerSubject::Gps).expect("a GPS line");
    assert_eq!(gps.severity, Severity::Warning);
    assert!(gps.text.starts_with("GPS STALE: last position 3 s old"), "{gps:?}");
    assert!(h.query_by_label_contains("GPS STALE: last position 3 s old").is_some());
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    h.run_steps(1);
    assert!(banner_of(h.state(), BannerSubject::Gps).is_none());
    assert!(h.query_by_label_contains("GPS STALE").is_none());
}

/// The GPS panel's satellite table (opened by its header) lists each satellite of the epoch with its PRN,
/// system, elevation, azimuth, SNR and use, on one row; a stale epoch is labelled last known.
#[test]
fn the_satellite_table_lists_prn_and_snr() {
    use vestnav_device::gps::Constellation;
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, stale_after_s: 2.0, ..Config::default() };
    let mut h = harness_with(&fake, cfg);
    let sat = |prn, constellation, el, az, snr, used| vestnav_device::gps::Satellite {
        prn,
        constellation,
        elevation_deg: Some(el),
        azimuth_deg: Some(az),
        snr_dbhz: Some(snr),
        used,
    };
    let with_sats = |age| Fix {
        satellites: vec![
            sat(27, Constellation::Gps, 61.0, 123.0, 47.0, true),
            sat(71, Constellation::Glonass, 12.0, 301.0, 19.0, false),
        ],
        ..fix(42.3562, -71.1, age)
    };
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(2);
    h.get_by_label_contains("Satellites (2 in view)").click();
    h.run_steps(2);
    let prn = h.get_by_label("27").rect();
    let snr = h.get_by_label("47").rect();
    assert!((prn.center().y - snr.center().y).abs() < 2.0 && snr.left() > prn.right(), "{prn:?} {snr:?}");
    for cell in ["61°", "123°", "GLONASS", "71", "19", "301°"] {
        assert!(h.query_by_label(cell).is_some(), "{cell}");
    }
    assert_eq!(h.query_all_by_label("GPS").count(), 2, "the section header and the system cell");
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(5)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(2);
    assert!(h.query_by_label_contains("Satellites (2 in view, last known, 5 s ago)").is_some());
    assert!(h.query_by_label("27").is_some(), "the last known sky stays listed, greyed");
}

/// Issue 13: the error figure on screen says whose it is — the receiver's own estimate (UBX hAcc here)
/// when it sends one, else the DOP model.
#[test]
fn the_error_estimate_names_its_source() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Connect GPS").click();
    h.run_steps(2);
    let mut f = fix(42.0, -71.0, Duration::ZERO);
    f.error = Some(ErrorEstimate { horizontal_m: 1.25, vertical_m: Some(2.0), source: ErrorSource::Ubx });
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(&mut h, |c| c.station.gps.fixes >= 1);
    h.run_steps(2);
    assert!(h.query_by_label_contains("±1.2 m (from UBX hAcc)").is_some());
    let mut f = fix(42.0, -71.0, Duration::ZERO);
    f.error = Some(ErrorEstimate {
        horizontal_m: 7.5,
        vertical_m: None,
        source: ErrorSource::DopModel { uere_m: vestnav_device::gps::UERE_M },
    });
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(&mut h, |c| c.station.gps.fixes >= 2);
    h.run_steps(2);
    assert!(h.query_by_label_contains("±7.5 m (from HDOP x 5 m)").is_some());
}

/// Issue 23 item 6: a replay at the end of its file is "Replay finished" (a notice, no STALE or FIX LOST
/// alarm however old its last fix grows), with **Restart** that replays it again.
#[test]
fn a_finished_replay_is_its_own_state_with_restart() {
    let mut h = real_harness(None);
    settle(&mut h, |c| c.station.gps.fix.is_some());
    h.get_by_label("Disconnect GPS").click();
    h.run_steps(2);
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/gpsd-logs/mr-350p.log");
    {
        let c = h.state_mut();
        c.gps_ui.picker.kind = vestnav_app::gps_panel::SourceKind::Replay;
        c.gps_ui.picker.replay_path = file.to_owned();
        c.gps_ui.picker.replay_speed = 50.0;
    }
    // The picker's replay rows appear first (the button moves down).
    h.run_steps(2);
    h.get_by_label("Connect GPS").click();
    for _ in 0..10 {
        settle(&mut h, |c| c.station.gps.state == Some(vestnav_device::gps::SourceState::Finished));
    }
    assert_eq!(h.state().station.gps.state, Some(vestnav_device::gps::SourceState::Finished));
    let fixes = h.state().station.gps.fixes;
    assert!(fixes >= 10, "{fixes}");
    h.run_steps(2);
    assert!(h.query_by_label_contains("Replay finished: the end of").is_some());
    assert!(h.query_by_label_contains("SOURCE FINISHED").is_some());
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    assert!(h.query_by_label_contains("GPS STALE").is_none());
    assert_eq!(h.state().gps_alarm(Instant::now() + Duration::from_mins(1)), None);
    h.get_by_label("Restart").click();
    h.run_steps(1);
    for _ in 0..10 {
        settle(&mut h, |c| c.station.gps.fixes >= 10 && c.station.gps.state.is_some());
    }
    assert!(h.state().station.gps.fixes >= 10, "replayed again");
}

/// Issue 23 item 3: a receiver repeating one position with a `SiRF` stream is named as `SiRF` static
/// navigation on the GPS panel, with its one-click remedy (greyed with the reason on a source that cannot
/// be configured), instead of "the wearer stands still".
#[test]
fn a_pinned_sirf_receiver_is_named_with_its_remedy() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    set_route(&mut h, three_waypoints(), 0);
    let stats = vestnav_device::gps::DecodeStats { sirf_sentences: 2, ..Default::default() };
    fake.gps(&GpsEvent::Stats(stats));
    // One held fix a second for 6 s, as they arrive (the station times them by their arrival).
    for k in 1..=7 {
        if k > 1 {
            std::thread::sleep(Duration::from_secs(1));
        }
        let f = Fix { speed_m_s: Some(0.0), ..fix(42.3562, -71.1, Duration::ZERO) };
        fake.gps(&GpsEvent::Fix(Box::new(f)));
        settle(&mut h, |c| c.station.gps.fixes == k);
    }
    h.run_steps(1);
    assert!(h.query_all_by_label_contains("SiRF static navigation is pinning the position").count() >= 1);
    assert!(h.query_by_label("Static navigation off").is_some());
    // Guidance is told: it holds on the frozen position, on the banner and on its own line.
    assert!(h.query_all_by_label_contains("guidance is holding (attention cues, no direction").count() >= 1);
    settle(&mut h, |c| c.station.guidance.as_ref().is_some_and(|g| g.reason.contains("position frozen")));
    h.run_steps(1);
    let g = h.state().station.guidance.clone().unwrap();
    assert!(g.reason.contains("hold: position frozen (SiRF static navigation"), "{}", g.reason);
    assert!(h.query_by_label_contains("hold: position frozen (SiRF").is_some(), "the guidance line says so");
    assert_eq!(h.state().station.route().next(), 0, "no arrival");
    assert!(h.query_by_label_contains("ask them to walk a few steps").is_none());
    // The Receiver window starts at the family the stream shows.
    h.get_by_label("Receiver").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("the stream shows a SiRF III/IV").is_some());
    assert_eq!(h.state().gps_ui.receiver.family, vestnav_device::gps::receiver_config::Family::Sirf);
}

/// The simulator's "steered by the vest" option: beside the source picker (no row of its own above the
/// vest grid), saved in the settings, handed to the station, and taken by the simulator at the next Connect,
/// which says so where the GPS notices show.
#[test]
fn the_simulated_walker_can_be_steered_by_the_emulated_vest() {
    let mut h = real_harness(None);
    settle(&mut h, |c| c.station.gps.fix.is_some());
    let boxed = h.get_by_label("steered by the vest").rect();
    assert!(boxed.right() <= 1400.0 && boxed.bottom() <= 875.0, "visible: {boxed:?}");
    h.get_by_label("steered by the vest").click();
    h.run_steps(3);
    assert!(h.state().cfg.sim_follows_vest);
    assert!(h.state().station.settings().sim_follows_vest, "the station has it");
    h.get_by_label("Disconnect GPS").click();
    h.run_steps(2);
    h.get_by_label("Connect GPS").click();
    settle(&mut h, |c| {
        c.station.gps.notice.as_ref().is_some_and(|n| n.contains("follows the emulated vest"))
    });
    h.run_steps(2);
    assert!(h.query_by_label_contains("follows the emulated vest").is_some(), "shown under the buttons");
}
