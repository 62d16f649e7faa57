//! Issue 23 items 2 and 6: the field tests are fed by every source through the station, with no window.
//! A drift test completes on the built-in simulator (its fixes in order on the receiver's clock); after
//! switching the source to a replay at run time a new drift test records the replay's fixes, and when the
//! replay reaches the end of its file the test ends "source ended" — with no GPS alarm.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;
use std::time::{Duration, Instant};

use vestnav_core::fieldtest_live::{Clock, Phase, SOURCE_CHANGED, SOURCE_ENDED};
use vestnav_device::gps::{ReplaySpeed, SourceState};
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::GpsSourceConfig;
use vestnav_station::{Station, StationOptions};

fn pump_until(station: &mut Station, within: Duration, mut done: impl FnMut(&Station) -> bool) -> bool {
    let end = Instant::now() + within;
    while Instant::now() < end {
        station.pump(|_| {});
        if done(station) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

#[test]
fn drift_tests_run_on_the_simulator_then_on_a_replay() {
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions { gps: Some(GpsSourceConfig::Simulator { route: None }), ..Default::default() },
    );
    station.connect_gps(Vec::new());
    assert!(pump_until(&mut station, Duration::from_secs(10), |s| s.field_tests.latest().is_some()));
    station.field_tests.drift.target_s = 3.0;
    station.field_tests.start_drift();
    assert!(
        pump_until(&mut station, Duration::from_secs(15), |s| s.field_tests.drift.phase == Phase::Done),
        "drift test on the simulator: {:?}, {} refused",
        station.field_tests.drift.phase,
        station.field_tests.rejected
    );
    assert_eq!(station.field_tests.rejected, 0, "every simulated fix in order");
    assert_eq!(station.field_tests.drift.recording().clock(), Some(Clock::Receiver));
    assert!(station.field_tests.drift.stats.as_ref().unwrap().fixes >= 4);

    // A second test running when the source changes ends "source changed".
    station.field_tests.drift.target_s = 600.0;
    station.field_tests.start_drift();
    let replay = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs/mr-350p.log");
    station.set_gps_source(GpsSourceConfig::Replay { path: replay, speed: ReplaySpeed::Times(4.0) });
    station.connect_gps(Vec::new());
    assert_eq!(station.field_tests.drift.phase, Phase::Ended(SOURCE_CHANGED));
    assert!(pump_until(&mut station, Duration::from_secs(10), |s| s.field_tests.latest().is_some()));
    station.field_tests.start_drift();
    assert!(
        pump_until(&mut station, Duration::from_secs(15), |s| s.gps.state == Some(SourceState::Finished)),
        "the replay did not finish"
    );
    let fixes = station.field_tests.drift.stats.as_ref().map_or(0, |s| s.fixes);
    assert!(fixes >= 5, "the replay's fixes were recorded: {fixes}");
    assert_eq!(station.field_tests.rejected, 0);
    assert_eq!(station.field_tests.drift.phase, Phase::Ended(SOURCE_ENDED));
    assert_eq!(station.gps_alarm(Instant::now()), None, "a finished replay raises no alarm");
    // Still none when the last fix has grown old.
    std::thread::sleep(Duration::from_millis(200));
    station.pump(|_| {});
    assert_eq!(station.gps_alarm(Instant::now() + Duration::from_mins(1)), None);
}
