//! The simulator source: the built-in simulated receiver walking a route in real time, optionally looped.

use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::GnssErrorModel;

use super::{SourceState, Worker};
use crate::gps::sim::SimulatedReceiver;
use crate::gps::{DecoderConfig, GpsEvent, NmeaDecoder};
use crate::sim::{BodyTruth, SharedTruth};

/// The simulator's settings, as given in [`SourceConfig::Simulator`](super::SourceConfig::Simulator).
pub(super) struct SimParams<'a> {
    pub(super) route: &'a [(f64, f64)],
    pub(super) pace_m_s: f64,
    pub(super) model: GnssErrorModel,
    pub(super) seed: u64,
    pub(super) period: Duration,
    pub(super) looped: bool,
    pub(super) truth: Option<SharedTruth>,
}

pub(super) fn run_sim(w: &Worker, p: &SimParams<'_>) {
    // A walker the vest steers (the shared wearer's setting when the simulator starts) never finishes a lap.
    let steered = p.truth.as_ref().is_some_and(SharedTruth::follows_vest);
    let new_lap = |lap: u64, start| {
        let seed = p.seed.wrapping_add(lap);
        SimulatedReceiver::new(p.route, p.pace_m_s, p.model, seed, start)
            .map(|r| if steered { r.steered_by_vest(p.route, seed) } else { r })
    };
    let mut rx = match new_lap(0, crate::gps::sim::whole_second_now()) {
        Ok(r) => r,
        Err(e) => {
            w.state(SourceState::Lost { reason: e.to_string() });
            return;
        }
    };
    if !w.state(SourceState::Live { detail: "simulator".into() }) {
        return;
    }
    let mut d = NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
    let start = Instant::now();
    if steered {
        if let Some(cell) = &p.truth {
            // Nothing felt before this walk began counts.
            let _ = cell.take_touches();
        }
        if !w.send(GpsEvent::Notice(
            "simulator: the walker follows the emulated vest's cues, not the route".into(),
        )) {
            return;
        }
    }
    let mut k: u32 = 0;
    let mut lap: u64 = 0;
    loop {
        // What the wearer felt of the vest since the last epoch, on the receiver's clock.
        if let Some(cell) = p.truth.as_ref().filter(|_| steered) {
            for (at, mask) in cell.take_touches() {
                rx.touch(mask, at.saturating_duration_since(start).as_secs_f64());
            }
        }
        // A wearer asked to turn on the spot (a compass calibration) stands while turning.
        let turning = p.truth.as_ref().and_then(SharedTruth::turn);
        let text = if turning.is_some() {
            rx.next_epoch_standing(p.period.as_secs_f64())
        } else {
            rx.next_epoch(p.period.as_secs_f64())
        };
        if let Some(cell) = &p.truth {
            let t = rx.truth();
            cell.set(BodyTruth {
                heading_true_deg: turning.map_or(t.course_deg, |turn| turn.heading_at(Instant::now())),
                east_m: t.en_m.x,
                north_m: t.en_m.y,
                pace_m_s: if turning.is_some() { 0.0 } else { t.speed_m_s },
            });
        }
        // One instant for the epoch's bytes and its end: the fix is stamped when it was made, never later
        // (a quiet-gap timeout in the future stamped the first fixes an hour ahead, and the decoder, once
        // it learnt the epoch's last sentence, stamped the next ones now: times went backwards).
        let now = Instant::now();
        d.handle_bytes(text.as_bytes(), now);
        d.end_epoch(now);
        if !w.drain(&mut d) {
            return;
        }
        if rx.finished() {
            if !p.looped {
                w.state(SourceState::Finished);
                return;
            }
            lap += 1;
            // The next lap's clock continues from the last epoch, so epoch times keep increasing.
            match new_lap(lap, rx.time()) {
                Ok(r) => rx = r,
                Err(e) => {
                    w.state(SourceState::Lost { reason: e.to_string() });
                    return;
                }
            }
            let seed = p.seed.wrapping_add(lap);
            if !w.send(GpsEvent::Notice(format!(
                "simulator: route finished, starting lap {} (seed {seed})",
                lap + 1
            ))) {
                return;
            }
        }
        k = k.saturating_add(1);
        let due = start + p.period * k;
        let now = Instant::now();
        if due > now && !w.sleep(due - now) {
            return;
        }
    }
}
