//! Simulation glue: the one simulated wearer that the console's simulated devices share, and the emulated
//! unit's compass that measures that wearer.
//!
//! The GPS simulator ([`crate::gps::sim`], run by the simulator source) publishes where its walker is and
//! faces in a [`SharedTruth`]; the emulated vest's [`SimulatedCompass`] (core's magnetometer model behind
//! the engine's [`HeadingSensor`] trait) reads it through [`WearerMotion::Follow`], so the compass and the
//! GPS course agree as they would on a real walk. Nothing here is a protocol: the WTCU engine knows only
//! the [`HeadingSensor`] trait, and the emulator puts the two together.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use chrono::Datelike as _;
use vestnav_core::compass::{MagnetometerModel, MagnetometerSim, SensorPose, SteelObject};
use vestnav_core::geo::LatLon;

use crate::wtcu::engine::HeadingSensor;

/// Where a simulated wearer truly is and faces: what the GPS simulator walks and the emulated vest's
/// compass measures, so the two simulated devices of one console see one wearer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyTruth {
    /// True heading of the body \[deg\].
    pub heading_true_deg: f64,
    /// Position east of the route's first waypoint \[m\].
    pub east_m: f64,
    /// Position north of the route's first waypoint \[m\].
    pub north_m: f64,
    /// Walking pace \[m/s\] (0 standing).
    pub pace_m_s: f64,
}

/// A [`BodyTruth`] shared between threads: the GPS simulator writes it every epoch, the emulated unit's
/// compass reads it. Empty until the simulator's first epoch.
#[derive(Debug, Clone, Default)]
pub struct SharedTruth(Arc<Mutex<Option<BodyTruth>>>);

impl SharedTruth {
    /// Records where the wearer is now.
    pub fn set(&self, truth: BodyTruth) {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner) = Some(truth);
    }

    /// Where the wearer is now, if anyone has said.
    pub fn get(&self) -> Option<BodyTruth> {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl PartialEq for SharedTruth {
    /// The same shared cell (not merely equal contents).
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// How the emulated wearer's body moves: the truth the emulated magnetometer measures.
#[derive(Debug, Clone, PartialEq)]
pub enum WearerMotion {
    /// Standing, facing `heading_deg` (true).
    Still {
        /// True heading \[deg\].
        heading_deg: f64,
    },
    /// Turning in place at `rate_deg_s` from `start_deg` (true): a calibration rotation.
    Turning {
        /// True heading at the start \[deg\].
        start_deg: f64,
        /// Turn rate, clockwise positive \[deg/s\].
        rate_deg_s: f64,
    },
    /// Where the GPS simulator's walker is and faces (the console's simulated wearer): one wearer for both
    /// simulated devices. Standing facing north until the simulator's first epoch.
    Follow(SharedTruth),
}

impl WearerMotion {
    /// The wearer's pose after `t_s` seconds on the unit's clock.
    pub fn pose(&self, t_s: f64) -> SensorPose {
        let standing =
            |heading_true_deg| SensorPose { t_s, heading_true_deg, east_m: 0.0, north_m: 0.0, pace_m_s: 0.0 };
        match self {
            Self::Still { heading_deg } => standing(*heading_deg),
            Self::Turning { start_deg, rate_deg_s } => {
                standing((start_deg + rate_deg_s * t_s).rem_euclid(360.0))
            }
            Self::Follow(cell) => cell.get().map_or_else(
                || standing(0.0),
                |b| SensorPose {
                    t_s,
                    heading_true_deg: b.heading_true_deg,
                    east_m: b.east_m,
                    north_m: b.north_m,
                    pace_m_s: b.pace_m_s,
                },
            ),
        }
    }
}

/// The emulated unit's magnetometer (protocol v2): which sensor, where, and how the wearer moves.
#[derive(Debug, Clone, PartialEq)]
pub struct CompassSetup {
    /// How the wearer moves.
    pub motion: WearerMotion,
    /// A parked car (a steel dipole of 30 µT m³) this far east of the wearer \[m\], if any: within 1–2 m
    /// it turns the heading by tens of degrees and lowers the quality figure.
    pub steel_east_m: Option<f64>,
    /// An ideal sensor (no iron, no noise) instead of a typical uncalibrated vest unit.
    pub ideal: bool,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Default for CompassSetup {
    fn default() -> Self {
        Self { motion: WearerMotion::Still { heading_deg: 0.0 }, steel_east_m: None, ideal: false, seed: 1 }
    }
}

/// Where the emulated wearer stands: the demo route's start by the MIT campus (42.3562° N, 71.1000° W).
/// The World Magnetic Model field there is what the emulated sensor measures.
pub const EMULATED_PLACE: (f64, f64) = (42.3562, -71.1000);

/// The emulated unit's magnetometer and accelerometer: `vestnav_core::compass`'s sensor model (hard and
/// soft iron, noise, the WMM field at [`EMULATED_PLACE`] on today's date, steel) seeing a wearer who moves
/// as [`CompassSetup::motion`] says, on the unit's clock.
#[derive(Debug)]
pub struct SimulatedCompass {
    sim: MagnetometerSim,
    motion: WearerMotion,
    start: Option<Instant>,
}

impl SimulatedCompass {
    /// The sensor for `setup`. The WMM has no model for dates it does not cover; then the field of the
    /// model's epoch at the place is used.
    pub fn new(setup: &CompassSetup) -> Self {
        let mut model =
            if setup.ideal { MagnetometerModel::ideal() } else { MagnetometerModel::typical_vest() };
        if let Some(east_m) = setup.steel_east_m {
            model.steel.push(SteelObject { east_m, north_m: 0.0, moment_ut_m3: 30.0 });
        }
        let place = LatLon::new(EMULATED_PLACE.0, EMULATED_PLACE.1);
        let today = chrono::Utc::now().date_naive();
        let date = (today.year(), today.month() as u8, today.day() as u8);
        let sim = MagnetometerSim::new(model.clone(), place, 0.0, date, setup.seed)
            .or_else(|_| MagnetometerSim::new(model.clone(), place, 0.0, (2025, 1, 1), setup.seed))
            // Boston's field (WMM2025): 14.3 µT north, -4.2 µT east, 47.9 µT down.
            .unwrap_or_else(|_| MagnetometerSim::with_field(model, [18.9, -5.1, 47.0], setup.seed));
        Self { sim, motion: setup.motion.clone(), start: None }
    }

    /// Declination of the emulated place's field, east positive \[deg\].
    pub fn declination_deg(&self) -> f64 {
        self.sim.declination_deg()
    }
}

impl HeadingSensor for SimulatedCompass {
    fn sample(&mut self, at: Instant) -> ([f64; 3], [f64; 3]) {
        let start = *self.start.get_or_insert(at);
        let t_s = at.saturating_duration_since(start).as_secs_f64();
        let s = self.sim.sample(&self.motion.pose(t_s));
        (s.raw_mag_body_ut, s.accel_body_m_s2)
    }
}
