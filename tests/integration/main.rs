//! Integration tests of the vestnav binary and of the crates working together, one module per topic.

// Test helpers outside `#[test]` functions may unwrap too: a failure there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod gps;
mod latency;
mod nav;
mod safety;
mod sim_tactor;
mod sim_wave;
mod wtcu;
mod wtcu_pair;
mod wtcu_v2;
