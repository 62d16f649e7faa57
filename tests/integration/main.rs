//! Integration tests of the vestnav binary and of the crates working together, one module per topic.

// Test helpers outside `#[test]` functions may unwrap too: a failure there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod cli;
mod gps;
mod gps_config;
mod latency;
mod nav;
mod safety;
mod sim_tactor;
mod sim_wave;
mod tiles_cli;
// Several tests of each serve the emulated unit on a PTY (`PtyEmulator::spawn` exists on Unix only), so
// neither module compiles elsewhere. `latency` and `safety` gate themselves (`#![cfg(unix)]`).
#[cfg(unix)]
mod wtcu;
#[cfg(unix)]
mod wtcu_gps;
mod wtcu_pair;
#[cfg(unix)]
mod wtcu_v2;
