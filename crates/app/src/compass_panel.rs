//! The vest's compass (WTCU protocol v2): the heading stream as the unit reports it, the WMM declination
//! applied to it, and the calibration wizard.
//!
//! Everything shown comes from the unit's HEADING readings and the instants they arrived: a reading older
//! than [`STALE_AFTER`] is shown as stale, and nothing is shown while the vest is not live. The wizard
//! collects the raw magnetometer readings while the wearer turns, fits hard and soft iron
//! (`vestnav_core::compass::fit_calibration`, with the World Magnetic Model field at the wearer's position
//! as the reference), shows the residual and the heading coverage, and on the operator's word sends the
//! calibration to the unit and keeps it in the settings for that unit.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use egui::{Color32, RichText};
use vestnav_core::compass::{Calibration, FieldReference, FitReport, fit_calibration, heading_coverage};
use vestnav_core::geo::{LatLon, magnetic_field_ned_ut, true_from_magnetic_deg};
use vestnav_device::heading::{Attitude, HeadingReference};
use vestnav_device::wtcu::VestCommand;
use vestnav_device::wtcu::message::Capabilities;

use vestnav_station::Station;

use crate::config::{Config, VestSourceConfig};

/// A heading reading older than this is stale: not shown as the wearer's heading, and not used by guidance.
pub const STALE_AFTER: Duration = Duration::from_secs(1);
/// Rate the console asks the unit to stream at.
pub const STREAM_RATE_HZ: u8 = 5;
/// Most raw readings a calibration collects (2 minutes at 5 Hz).
pub const MAX_SAMPLES: usize = 600;
/// Coverage of the heading circle below which the wizard asks the wearer to keep turning.
pub const MIN_COVERAGE: f64 = 0.8;
/// Turn rate the emulated vest's simulated wearer turns at while the wizard collects [deg/s] (a full turn
/// in 30 s, as the wizard asks of a real wearer).
pub const SIMULATED_TURN_DEG_S: f64 = 12.0;

/// The calibration wizard's state.
#[derive(Debug, Default)]
pub enum Wizard {
    /// Not calibrating.
    #[default]
    Idle,
    /// Collecting raw readings while the wearer turns.
    Collecting {
        /// Raw magnetometer readings [µT].
        samples: Vec<[f64; 3]>,
        /// When collection started.
        since: Instant,
    },
    /// A fit to accept or discard.
    Fitted(Box<FitReport>),
    /// The fit failed; why.
    Failed(String),
}

impl Wizard {
    /// Takes a raw reading while collecting (bounded: the oldest are kept, the wizard stops at the limit).
    pub fn push(&mut self, a: &Attitude) {
        if let (Self::Collecting { samples, .. }, Some(raw)) = (self, a.raw_mag_ut)
            && samples.len() < MAX_SAMPLES
        {
            samples.push(raw);
        }
    }
}

/// The unit's key in the settings' calibration table: the port it is on, or "emulated".
pub fn unit_key(vest: &VestSourceConfig) -> String {
    match vest {
        VestSourceConfig::Emulated => "emulated".to_owned(),
        VestSourceConfig::Serial { port } => port.clone(),
    }
}

fn today() -> (i32, u8, u8) {
    use chrono::Datelike as _;
    let t = chrono::Utc::now().date_naive();
    (t.year(), t.month() as u8, t.day() as u8)
}

/// Whether the live unit has a compass.
pub fn has_compass(station: &Station) -> bool {
    station.vest.is_live()
        && station.vest.device.is_some_and(|d| d.capabilities.contains(Capabilities::HEADING))
}

/// Draws the Compass section of the Vest tab: the heading `station` reports, the calibration kept in `cfg`
/// for this unit, and the calibration `wizard`.
pub fn show(station: &mut Station, cfg: &mut Config, wizard: &mut Wizard, ui: &mut egui::Ui) {
    ui.label(RichText::new("Compass").strong());
    if !station.vest.is_live() {
        ui.label("vest not live: no heading");
        return;
    }
    if !has_compass(station) {
        let v = station.vest.device.map_or(0, |d| d.protocol_version);
        ui.label(format!(
            "this unit has no compass (protocol v{v}; heading needs a v2 unit with a magnetometer)"
        ));
        return;
    }
    let now = Instant::now();
    match station.vest.heading {
        None => {
            ui.label("no heading reading yet");
        }
        Some(a) => {
            let age = a.age(now);
            let stale = age > STALE_AFTER;
            let magnetic = a.heading_deg;
            let mut text = match a.reference {
                HeadingReference::Magnetic => format!("magnetic {magnetic:.1}°"),
                HeadingReference::True => format!("true {magnetic:.1}°"),
            };
            // The declination guidance applies (WMM at the wearer's position, computed once there), so the
            // true heading shown is the one guidance steers by.
            if a.reference == HeadingReference::Magnetic
                && let Some(dec) = station.guidance.as_ref().and_then(|g| g.declination_deg)
            {
                let _ = write!(
                    text,
                    ", true {:.1}° (declination {dec:+.1}°, WMM, as guidance applies it)",
                    true_from_magnetic_deg(magnetic, dec)
                );
            }
            if let (Some(p), Some(r)) = (a.pitch_deg, a.roll_deg) {
                let _ = write!(text, " · pitch {p:+.1}° roll {r:+.1}°");
            }
            let q = a.quality_pct.unwrap_or(0);
            let _ = write!(text, " · quality {q} % · {:.1} s ago", age.as_secs_f64());
            let color = if stale {
                Color32::from_rgb(230, 60, 40)
            } else if q < 60 {
                Color32::from_rgb(230, 150, 20)
            } else {
                ui.visuals().text_color()
            };
            if stale {
                text = format!("STALE: {text}");
            }
            ui.label(RichText::new(text).color(color));
            if q == 0 && !stale {
                ui.label(RichText::new("uncalibrated (quality 0): calibrate before steering by it").weak());
            }
        }
    }
    if cfg.compass_calibrations.contains_key(&unit_key(&cfg.vest)) {
        ui.label(RichText::new(format!("calibration for {} loaded at connect", unit_key(&cfg.vest))).weak());
    }
    wizard_ui(station, cfg, wizard, ui);
}

fn wizard_ui(station: &mut Station, cfg: &mut Config, wizard: &mut Wizard, ui: &mut egui::Ui) {
    let mut next = None;
    let mut accept = None;
    match &*wizard {
        Wizard::Idle => {
            if ui.button("Calibrate compass…").clicked() {
                next = Some(Wizard::Collecting { samples: Vec::new(), since: Instant::now() });
                // The emulated vest's simulated wearer does what a real one is asked: stop and turn on the
                // spot (walking, its gait tilt and few headings would spoil the level fit).
                station.turn_simulated_wearer(Some(SIMULATED_TURN_DEG_S));
            }
        }
        Wizard::Collecting { samples, since } => next = collecting_ui(station, ui, samples, *since),
        Wizard::Fitted(r) => {
            let b = r.calibration.hard_iron_ut;
            ui.label(format!(
                "{:?} fit of {} readings: hard iron ({:.1}, {:.1}, {:.1}) µT, field {:.1} µT, residual {:.1} % RMS, \
                 coverage {:.0} %",
                r.kind,
                r.samples,
                b[0],
                b[1],
                b[2],
                r.calibration.field_ut,
                r.residual_rms_pct,
                r.coverage * 100.0
            ));
            // The fit's floor is ~1 % RMS for a 3-D fit and ~3 % for a level 2-D one (docs/heading.md); far
            // above it the wearer tilted or moved near steel while turning.
            let floor = match r.kind {
                vestnav_core::compass::FitKind::Ellipsoid3d => 1.0,
                vestnav_core::compass::FitKind::Ellipse2d => 3.0,
            };
            let poor = r.residual_rms_pct > 2.0 * floor;
            if poor {
                ui.label(
                    RichText::new(format!(
                        "residual {:.1} % is over twice this fit's floor ({floor:.0} %): redo it with the wearer \
                         standing upright, away from cars and railings",
                        r.residual_rms_pct
                    ))
                    .color(Color32::from_rgb(230, 150, 20)),
                );
            }
            ui.horizontal(|ui| {
                if ui.button(if poor { "Send anyway and save" } else { "Send to vest and save" }).clicked() {
                    accept = Some(r.calibration);
                }
                if ui.button("Discard").clicked() {
                    next = Some(Wizard::Idle);
                }
            });
        }
        Wizard::Failed(e) => {
            ui.label(RichText::new(format!("calibration failed: {e}")).color(Color32::from_rgb(230, 60, 40)));
            if ui.button("OK").clicked() {
                next = Some(Wizard::Idle);
            }
        }
    }
    if let Some(cal) = accept {
        next = Some(match cal.to_wire() {
            Ok(wire) => {
                // A refusal shows in the Vest panel's last reply.
                let _ = station.send_device(VestCommand::SetCalibration(wire));
                cfg.compass_calibrations.insert(unit_key(&cfg.vest), cal);
                Wizard::Idle
            }
            Err(e) => Wizard::Failed(e.to_string()),
        });
    }
    if let Some(n) = next {
        if !matches!(n, Wizard::Collecting { .. }) {
            station.turn_simulated_wearer(None);
        }
        *wizard = n;
    }
}

/// The collecting step: coverage so far, **Fit** once the turn covers enough of the circle.
fn collecting_ui(
    station: &Station,
    ui: &mut egui::Ui,
    samples: &[[f64; 3]],
    since: Instant,
) -> Option<Wizard> {
    let mut next = None;
    if station.vest_source() == &vestnav_station::sources::VestSourceConfig::Emulated {
        ui.label(format!(
            "The simulated wearer stands and turns on the spot at {SIMULATED_TURN_DEG_S:.0}°/s (a full circle in \
             {:.0} s); they walk on after Fit or Cancel.",
            360.0 / SIMULATED_TURN_DEG_S
        ));
    } else {
        ui.label(
            "Have the wearer turn slowly on the spot through a full circle (30 s), or trace a figure-8.",
        );
    }
    // Coverage of the raw readings about their centroid: the hard iron shifts the circle, it does
    // not change how much of it the turn has swept.
    let n = samples.len();
    let coverage = if n > 0 {
        let mean = [0, 1, 2].map(|i| samples.iter().map(|s| s[i]).sum::<f64>() / n as f64);
        let centred: Vec<[f64; 3]> = samples.iter().map(|s| [0, 1, 2].map(|i| s[i] - mean[i])).collect();
        heading_coverage(&centred)
    } else {
        0.0
    };
    ui.add(egui::ProgressBar::new(coverage as f32).text(format!(
        "{n} readings, {:.0} % of the circle, {:.0} s",
        coverage * 100.0,
        since.elapsed().as_secs_f64()
    )));
    ui.horizontal(|ui| {
        let ready = coverage >= MIN_COVERAGE;
        if ui.add_enabled(ready, egui::Button::new("Fit")).clicked() {
            let reference = station
                .gps
                .last_position
                .as_ref()
                .and_then(|f| {
                    let (y, m, d) = today();
                    magnetic_field_ned_ut(LatLon::new(f.lat_deg?, f.lon_deg?), 0.0, y, m, d).ok()
                })
                .map_or(FieldReference::NONE, FieldReference::from_ned);
            next = Some(match fit_calibration(samples, reference) {
                Ok(r) => Wizard::Fitted(Box::new(r)),
                Err(e) => Wizard::Failed(e.to_string()),
            });
        }
        if !ready {
            ui.label(RichText::new("keep turning: the fit needs 80 % of the circle").weak());
        }
        if ui.button("Cancel").clicked() {
            next = Some(Wizard::Idle);
        }
    });
    next
}

/// What the console does when a unit identifies itself: start its heading stream and load the
/// calibration kept for it in `cfg`, if it has a compass.
pub fn on_identified(station: &mut Station, cfg: &Config) {
    if !station.vest.device.is_some_and(|d| d.capabilities.contains(Capabilities::HEADING)) {
        return;
    }
    let _ = station.send_device(VestCommand::HeadingStart { rate_hz: STREAM_RATE_HZ });
    if let Some(wire) =
        cfg.compass_calibrations.get(&unit_key(&cfg.vest)).and_then(|cal: &Calibration| cal.to_wire().ok())
    {
        let _ = station.send_device(VestCommand::SetCalibration(wire));
    }
}
