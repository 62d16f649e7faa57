//! Fuzzing on stable Rust: seeded mutation harnesses over real inputs, plus proptest where structure helps,
//! for everything that reads bytes from a device, a file or the network — the NMEA decoder, gpsd JSON, the
//! WTCU codec and both ends of its protocol, GPX, CSV and the session-log reader.
//!
//! Each target asserts no panic (every case runs under `catch_unwind`), a time per input linear in its
//! size, bounded output, and its own invariants. A failure is minimised and saved under
//! `target/tmp/fuzz-findings/` with the seed that found it (`FUZZ_REPLAY=<target>:<seed>` reruns just that
//! case). Environment: `FUZZ_CASES` (cases per target, or a multiplier like `100x`; also turns on the long
//! run's larger inputs), `FUZZ_SECONDS` (time budget per target), `FUZZ_SEED` (hex), `FUZZ_HANG_S`,
//! `FUZZ_TIME_FACTOR`. `scripts/fuzz.sh` runs the long version.

// Test helpers outside `#[test]` functions may unwrap too: a failure there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod csv;
mod gpsd;
mod gpx;
mod harness;
mod mutate;
mod nmea;
mod session_log;
mod wtcu;
