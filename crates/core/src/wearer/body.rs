//! The simulated wearer's body and skin, shared by the offline closed loop ([`super::simulate_along`]) and
//! the station's live simulated wearer (the built-in GPS simulator's walker steered by the emulated vest).
//!
//! - [`Body`]: where the wearer is and faces, the turns they still have to make, walking or standing.
//!   Cues reach it as [`Body::feel`] (recognised with the model's probability, acted on `reaction_s` after
//!   the pattern ends) and time as [`Body::advance`] (turn toward the wanted heading, veer, walk).
//! - [`Skin`]: what a wearer feels of the vest, tactor changes in time, grouped into bursts (tactors off for
//!   [`Skin::QUIET_S`] ends one) and recognised as the cue whose pattern they match
//!   ([`Cue::recognise`]). Only a live wearer needs it: the offline loop hands the decided cue over.

use glam::DVec2;
use rand::RngExt;
use rand::rngs::StdRng;

use super::{HeadingSim, WearerModel, normal};
use crate::geo::{normalize_deg, wrap_deg_180};
use crate::vest::{Cue, TactorMask};

/// A recognised cue the body has still to act on.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    /// When to act [s].
    at_s: f64,
    /// Heading change [deg], turn noise included.
    change_deg: f64,
    /// A turn-in-place cue: turn standing.
    on_the_spot: bool,
}

/// The simulated wearer's body: position, heading and the turns still to make.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// True heading [deg] in [0, 360).
    pub heading_deg: f64,
    /// The heading the wearer is turning toward [deg].
    pub target_heading_deg: f64,
    /// Position east/north of the frame's origin [m].
    pub pos_en_m: DVec2,
    /// Walking (else standing).
    pub walking: bool,
    /// Told to stop: stands until the end.
    pub stopped: bool,
    /// When the last directional cue was felt or acted on [s].
    last_directional_s: f64,
    /// Recognised cues not yet acted on, in order.
    pending: Vec<Pending>,
}

impl Body {
    /// A wearer at `pos_en_m` facing `heading_deg`, walking or standing.
    pub fn new(pos_en_m: DVec2, heading_deg: f64, walking: bool) -> Self {
        let heading_deg = normalize_deg(heading_deg);
        Self {
            heading_deg,
            target_heading_deg: heading_deg,
            pos_en_m,
            walking,
            stopped: false,
            last_directional_s: 0.0,
            pending: Vec::new(),
        }
    }

    /// The wearer's speed now [m/s].
    pub fn speed_m_s(&self, w: &WearerModel) -> f64 {
        if self.walking { w.pace_m_s.max(0.1) } else { 0.0 }
    }

    /// A cue felt at `t_s` whose pattern ends at `pattern_end_s`: recognised with probability
    /// `w.recognition` (one draw from `rng`); a recognised `Stop` stops the wearer at once, a recognised
    /// directional cue is acted on `w.reaction_s` after the pattern's end (its turn plus N(0,
    /// `turn_noise_deg`²), a second draw when it turns). Returns whether it was recognised.
    pub fn feel(
        &mut self,
        w: &WearerModel,
        cue: Cue,
        pattern_end_s: f64,
        t_s: f64,
        rng: &mut StdRng,
    ) -> bool {
        if rng.random::<f64>() >= w.recognition {
            return false;
        }
        if cue == Cue::Stop {
            self.walking = false;
            self.stopped = true;
        } else if let Some(turn) = w.turn_for(cue) {
            let noise = if turn == 0.0 { 0.0 } else { w.turn_noise_deg * normal(rng) };
            self.pending.push(Pending {
                at_s: pattern_end_s + w.reaction_s,
                change_deg: turn + noise,
                on_the_spot: cue.is_turn_in_place(),
            });
            self.last_directional_s = t_s;
        }
        true
    }

    /// One step of `dt_s` at `t_s`: acts on each recognised cue whose time has come (in order), sets a
    /// standing wearer walking after `idle_walk_s` without a directional cue (with `hs`), turns toward the
    /// wanted heading at the turn rate, veers (one draw from `rng`) and walks. Returns the distance walked
    /// [m].
    pub fn advance(
        &mut self,
        w: &WearerModel,
        hs: Option<&HeadingSim>,
        t_s: f64,
        dt_s: f64,
        rng: &mut StdRng,
    ) -> f64 {
        while let Some(&p) = self.pending.first()
            && t_s >= p.at_s
        {
            self.target_heading_deg = normalize_deg(self.heading_deg + p.change_deg);
            if hs.is_some() && !self.stopped {
                // A turn-in-place cue stops the wearer; Forward and the walking cues set them walking.
                self.walking = !p.on_the_spot;
            }
            self.last_directional_s = t_s;
            self.pending.remove(0);
        }
        if let Some(h) = hs
            && !self.walking
            && !self.stopped
            && self.pending.is_empty()
            && t_s - self.last_directional_s >= h.idle_walk_s
        {
            self.walking = true;
        }
        let diff = wrap_deg_180(self.target_heading_deg - self.heading_deg);
        let rate = match hs {
            Some(h) if !self.walking => h.rotate_rate_deg_s,
            _ => w.turn_rate_deg_s,
        };
        let max_turn = rate * dt_s;
        self.heading_deg = normalize_deg(self.heading_deg + diff.clamp(-max_turn, max_turn));
        let veer = w.veer_deg_per_sqrt_s * dt_s.sqrt() * normal(rng);
        self.heading_deg = normalize_deg(self.heading_deg + veer);
        self.target_heading_deg = normalize_deg(self.target_heading_deg + veer);
        if self.walking {
            let h = self.heading_deg.to_radians();
            let step = DVec2::new(h.sin(), h.cos()) * self.speed_m_s(w) * dt_s;
            self.pos_en_m += step;
            step.length()
        } else {
            0.0
        }
    }
}

/// What a live wearer feels of the vest: the tactors' changes, grouped into bursts and recognised as cues.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Skin {
    /// The burst being felt: each change of the tactors that are on, off included.
    burst: Vec<TactorMask>,
    /// When the tactors last changed [s].
    last_change_s: f64,
    /// The tactors on now.
    on: TactorMask,
    /// When the burst began [s].
    started_s: f64,
    /// The last burst that matched no cue, and when it ended: half of a pattern whose pause was long
    /// enough to end a burst (a long `on_ms`), joined with the next one.
    unmatched: Option<(Vec<TactorMask>, f64)>,
}

impl Skin {
    /// Tactors off this long end a burst [s]: longer than the pauses inside the console's patterns at
    /// on-times below 800 ms (half the on-time), shorter than guidance's 0.5 s gap between two cues. A
    /// longer pause splits a pattern in two, which [`Self::JOIN_S`] puts together again.
    pub const QUIET_S: f64 = 0.4;
    /// An unmatched burst is joined with the next one when that begins within this [s].
    pub const JOIN_S: f64 = 1.5;

    /// The tactors on from `t_s` (a change reported by the unit).
    pub fn touch(&mut self, mask: TactorMask, t_s: f64) {
        if mask == self.on {
            return;
        }
        self.on = mask;
        if self.burst.is_empty() {
            if mask == TactorMask::NONE {
                return;
            }
            self.started_s = t_s;
        }
        // The burst stays a bounded record of one pattern: a vest that never stops changing is no cue.
        if self.burst.len() >= 64 {
            self.burst.clear();
            self.started_s = t_s;
        }
        self.burst.push(mask);
        self.last_change_s = t_s;
    }

    /// At `now_s`: the cue of a burst that has just ended (the tactors off for [`Self::QUIET_S`]) and when
    /// its pattern ended, if the burst matched one.
    pub fn felt(&mut self, now_s: f64) -> Option<(Cue, f64)> {
        if self.burst.is_empty() || self.on != TactorMask::NONE || now_s - self.last_change_s < Self::QUIET_S
        {
            return None;
        }
        let burst = std::mem::take(&mut self.burst);
        let end_s = self.last_change_s;
        if let Some(cue) = Cue::recognise(&burst) {
            self.unmatched = None;
            return Some((cue, end_s));
        }
        if let Some((mut first, first_end_s)) = self.unmatched.take()
            && self.started_s - first_end_s <= Self::JOIN_S
        {
            first.extend(burst.iter().copied());
            if let Some(cue) = Cue::recognise(&first) {
                return Some((cue, end_s));
            }
        }
        self.unmatched = Some((burst, end_s));
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vest::{DEFAULT_ON_MS, Pattern};
    use rand::SeedableRng;

    /// The tactor changes a unit makes playing `p` from `start_s`: (time, tactors on), ending off.
    fn played(p: &Pattern, start_s: f64) -> Vec<(f64, TactorMask)> {
        let mut t = start_s;
        let mut out = Vec::new();
        for _ in 0..p.repeats.max(1) {
            for f in &p.frames {
                out.push((t, f.mask));
                t += f64::from(f.duration_ms) / 1000.0;
            }
        }
        out.push((t, TactorMask::NONE));
        out
    }

    /// Feeds `events` to `skin`, asking what was felt every 10 ms until `until_s`.
    fn feel_all(skin: &mut Skin, events: &[(f64, TactorMask)], until_s: f64) -> Vec<(Cue, f64)> {
        let mut out = Vec::new();
        let mut next = events.iter().peekable();
        let mut t = 0.0;
        while t <= until_s {
            while let Some(&&(at, m)) = next.peek()
                && at <= t
            {
                skin.touch(m, at);
                next.next();
            }
            out.extend(skin.felt(t));
            t += 0.01;
        }
        out
    }

    #[test]
    fn every_cue_played_by_the_unit_is_felt_as_itself_when_it_ends() {
        for on_ms in [20, 100, DEFAULT_ON_MS, 700] {
            for cue in Cue::ALL.into_iter().chain(Cue::TURN_IN_PLACE) {
                let p = cue.pattern(on_ms);
                let events = played(&p, 1.0);
                // The last vibration's end (a trailing pause is not felt).
                let last_on = events.iter().rposition(|e| e.1 != TactorMask::NONE).unwrap();
                let end_s = events[last_on + 1].0;
                let felt = feel_all(&mut Skin::default(), &events, end_s + 1.5);
                assert_eq!(felt.len(), 1, "{cue:?} at {on_ms} ms: {felt:?}");
                assert_eq!(felt[0].0, cue, "{cue:?} at {on_ms} ms");
                assert!((felt[0].1 - end_s).abs() < 1e-9, "ends with its pattern");
            }
        }
    }

    #[test]
    fn two_cues_half_a_second_apart_are_two_cues() {
        // Guidance's gap between cues: 0.5 s after the first pattern ends.
        let first = played(&Cue::TurnLeft.pattern(DEFAULT_ON_MS), 0.5);
        let second_start = first.last().unwrap().0 + 0.5;
        let mut events = first;
        events.extend(played(&Cue::Forward.pattern(DEFAULT_ON_MS), second_start));
        let felt: Vec<Cue> = feel_all(&mut Skin::default(), &events, 10.0).into_iter().map(|f| f.0).collect();
        assert_eq!(felt, [Cue::TurnLeft, Cue::Forward]);
    }

    #[test]
    fn a_long_pause_inside_a_pattern_joins_its_halves() {
        // At 2000 ms on-time TurnAround's pause is 1 s: two bursts, neither a cue alone.
        let events = played(&Cue::TurnAround.pattern(2000), 0.0);
        let felt = feel_all(&mut Skin::default(), &events, 12.0);
        assert_eq!(felt.iter().map(|f| f.0).collect::<Vec<_>>(), [Cue::TurnAround]);
    }

    #[test]
    fn what_is_no_cue_is_not_felt_as_one() {
        // A tactor fired by hand; a turn cut short by STOP ALL; a vest that never stops changing.
        let mut skin = Skin::default();
        assert!(
            feel_all(&mut skin, &[(0.0, TactorMask::from_indices([5])), (0.5, TactorMask::NONE)], 2.0)
                .is_empty()
        );
        let cut: Vec<(f64, TactorMask)> = played(&Cue::TurnRight.pattern(DEFAULT_ON_MS), 3.0)
            .into_iter()
            .take(2)
            .chain([(3.6, TactorMask::NONE)])
            .collect();
        assert!(feel_all(&mut skin, &cut, 6.0).is_empty());
        let mut flicker = Skin::default();
        for k in 0..10_000u32 {
            flicker.touch(TactorMask::from_indices([(k % 16) as usize]), f64::from(k) * 0.01);
            assert!(flicker.burst.len() <= 64);
        }
    }

    #[test]
    fn a_felt_turn_is_made_after_the_reaction_time() {
        // A perfect wearer (always recognises, no noise, no veer) walking north, told to turn right.
        let w = WearerModel {
            recognition: 1.0,
            turn_noise_deg: 0.0,
            veer_deg_per_sqrt_s: 0.0,
            ..WearerModel::default()
        };
        let mut rng = StdRng::seed_from_u64(7);
        let mut body = Body::new(DVec2::ZERO, 0.0, true);
        assert!(body.feel(&w, Cue::TurnRight, 1.0, 0.0, &mut rng));
        let dt = 0.1;
        let mut walked = 0.0;
        for k in 0..100 {
            let t = f64::from(k) * dt;
            walked += body.advance(&w, None, t, dt, &mut rng);
            if t < 1.0 + w.reaction_s - 1e-9 {
                assert!(body.heading_deg.abs() < 1e-9, "still north at {t}");
            }
        }
        // 70° right at 90°/s, then east-north-east: 10 s at the pace.
        assert!((body.heading_deg - 70.0).abs() < 1e-9, "{}", body.heading_deg);
        assert!((walked - 10.0 * w.pace_m_s).abs() < 1e-9);
        // Stop: standing from then on.
        assert!(body.feel(&w, Cue::Stop, 11.0, 10.5, &mut rng));
        let before = body.pos_en_m;
        assert!(body.advance(&w, None, 11.0, dt, &mut rng).abs() < f64::EPSILON);
        assert!(body.speed_m_s(&w).abs() < f64::EPSILON);
        assert_eq!(body.pos_en_m, before);
    }
}
