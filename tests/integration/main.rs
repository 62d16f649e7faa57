//! Integration tests of the vestnav binary and of the crates working together, one module per topic.

// Test helpers outside `#[test]` functions may unwrap too: a failure there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

/// Held by the tests that measure time (latency, STOP ALL within 50 ms) and by the heaviest one (a real
/// console window rendering under Xvfb), so none of them runs beside another: on a 2-core machine a
/// window's software rendering can stall a measurement by hundreds of milliseconds, which says nothing
/// about the code measured. A test that panics while holding it leaves it usable (poison is ignored).
pub(crate) fn timing_exclusive() -> std::sync::MutexGuard<'static, ()> {
    static TIMING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    TIMING.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

mod accuracy;
mod cli;
mod doctor;
mod gps;
mod gps_config;
mod lab;
mod latency;
#[cfg(unix)]
mod local_stations;
mod nav;
mod osm;
mod receivers;
mod remote;
mod remote_map;
mod remote_study;
mod safety;
mod sim_tactor;
mod sim_wave;
mod sim_wearer;
mod study;
#[cfg(unix)]
mod study_nav;
mod study_run;
mod tiles_cli;
// Several tests of each serve the emulated unit on a PTY (`PtyEmulator::spawn` exists on Unix only), so
// neither module compiles elsewhere. `doctor`, `latency` and `safety` gate themselves (`#![cfg(unix)]`).
#[cfg(unix)]
mod wtcu;
#[cfg(unix)]
mod wtcu_gps;
mod wtcu_pair;
#[cfg(unix)]
mod wtcu_v2;
