//! Pure physics of the vestnav tactile vest: no IO, no threads, no clock.
//!
//! Time is always a parameter. The modules follow the MIT thesis the vest comes from:
//! - [`tactor`]: the pancake-motor tactor ODE (thesis §3.2) and its summary figures;
//! - [`sweep`]: damping sweeps, power-law fits and damping calibration (§3.2.2–3.2.3);
//! - [`fit`]: least-squares line and power-law fits with R^2;
//! - [`analysis`]: measured force/acceleration series (§3.1): peak frequency, envelope, statistics;
//! - [`wave`]: skin travelling waves and their linear superposition (§4.1.3);
//! - [`twopoint`]: the two-point simulation, a two-Gaussian sum fitted by one Gaussian (§4.2);
//! - [`vest`]: the 4x4 tactor grid, tactor masks, timed patterns and the named cues.
//!
//! And the navigation logic of the console, pure in the same way:
//! - [`compass`]: magnetometer heading: tilt compensation, hard/soft-iron calibration fit, a sensor model;
//! - [`geo`]: WGS-84 and thesis-sphere distances, local frames, cross-track, WMM declination;
//! - [`guidance`]: route, heading source, cue selection, rate limiting, manual overrides, strategies;
//! - [`gnss_sim`]: a GNSS error model (noise, wandering bias, static-navigation pinning) and a route walker;
//! - [`wearer`]: the closed-loop simulated wearer used to compare strategies;
//! - [`fieldtest`]: GPS drift and cone-test statistics (§5); [`fieldtest_live`]: the tests run live on a
//!   stream of fixes (time base, walking, pinning, source ended); [`pinned`]: a receiver holding its
//!   position while the wearer walks;
//! - [`accuracy`]: GPS accuracy against a reference (CEP, DRMS, bias, vertical), receivers side by side;
//! - [`coords`]: typed positions (decimal, DMS, UTM/UPS, MGRS) read and written.
//! - [`study`]: study protocols, trial plans, results and their analysis (localization, pattern
//!   identification, navigation).
//!
//! ```
//! use vestnav_core::tactor::{TactorParams, Preset};
//! let p = TactorParams::preset(Preset::ThesisSim);
//! // Closed-form steady speed omega = Kt u / (R b + Kt^2), thesis: 834.2 rad/s.
//! assert!((p.steady_state().omega_rad_s - 834.22).abs() < 0.01);
//! ```

/// Called by a producer when it has news for its consumer (the console passes egui's `request_repaint`):
/// the one waker type of the device workers' outboxes and the tile loaders alike, so one closure serves
/// both. A plain callback type — core itself never calls one and starts no thread.
pub type Waker = std::sync::Arc<dyn Fn() + Send + Sync>;

pub mod accuracy;
pub mod analysis;
pub mod compass;
pub mod coords;
pub mod fieldtest;
pub mod fieldtest_live;
pub mod fit;
pub mod geo;
pub mod gnss_sim;
pub mod guidance;
pub mod pinned;
pub mod study;
pub mod sweep;
pub mod tactor;
pub mod twopoint;
pub mod vest;
pub mod wave;
pub mod wearer;
