//! The console's fixed regions and when the window turns.
//!
//! Regions: the top bar (STOP ALL, the devices' and guidance's states, the tabs) has its place reserved by
//! a panel of fixed height and is drawn in a layer above every window, pop-up and modal dialog
//! ([`egui::Order::Tooltip`]), so nothing covers STOP ALL and a click on it acts on the first press whatever
//! is open (a modal's backdrop does not take the click first). Windows are kept below the bar. The side
//! panel has a fixed width (text that grows does not widen it; it can be collapsed to a strip showing the
//! tactors on); its top is the "now" display — the last cue and the few before it, guidance's state and
//! Resume — which never scrolls away; the Vest section's grid comes first in its section. The banner strip
//! has a fixed height inside the central area, so banners coming and going move nothing.
//!
//! Turns: the window draws when a device reports a change the operator must see (the station's wakers,
//! `vestnav_station::view_wake`) and otherwise only as often as what it shows needs ([`Console::next_turn`]):
//! once a second for the ages it shows, at the instant a fix turns stale or lost, and often enough for the
//! vest worker's liveness check of this thread while a vest is connected, and when the study runner's next
//! timer is due (`Station::study_wake_in`).

use std::time::{Duration, Instant};

use egui::{Color32, RichText, vec2};
use vestnav_core::vest::Cue;

use super::Console;

/// Height of the top bar [pt] (normal, large text).
pub const TOP_BAR_H: (f32, f32) = (40.0, 46.0);
/// Width of the side panel below and above [`WIDE_WINDOW`] [pt].
pub const SIDE_W: (f32, f32) = (300.0, 360.0);
/// A window at least this wide [pt] gets the wider side panel.
pub const WIDE_WINDOW: f32 = 1300.0;
/// Height of the "now" display at the top of the side panel [pt].
pub const NOW_H: f32 = 72.0;
/// Text size of the current cue [pt].
pub const CUE_PT: f32 = 26.0;
/// While a vest is connected the window turns at least this often: the vest worker stops every tactor
/// when the UI thread has not turned within its bound ([`vestnav_station::Liveness::view`], 1.5 s).
pub const LIVENESS_TURN: Duration = Duration::from_millis(750);
/// Ages are shown in whole seconds: with a device connected the window turns once a second.
pub const AGE_STEP: Duration = Duration::from_secs(1);

/// Moves every window whose top is above `top` (the top bar's bottom) down to just below it: a window
/// opened or dragged there would hide its own title bar under the top bar.
pub fn keep_windows_below(ctx: &egui::Context, top: f32) {
    let windows: Vec<egui::LayerId> = ctx.memory(|m| {
        m.areas().visible_layer_ids().into_iter().filter(|l| l.order == egui::Order::Middle).collect()
    });
    for layer in windows {
        let Some(mut state) = egui::AreaState::load(ctx, layer.id) else { continue };
        let r = state.rect();
        if r.top() < top {
            state.set_left_top_pos(egui::pos2(r.left(), top + 4.0));
            ctx.memory_mut(|m| m.areas_mut().set_state(layer, state));
        }
    }
}

/// A cue's name as the operator reads it on the "now" display.
fn cue_words(cue: Cue) -> String {
    cue.name().replace('_', " ").to_uppercase()
}

/// "3 s" / "2 min" for an age.
fn short_age(age: Duration) -> String {
    let s = age.as_secs();
    if s < 120 { format!("{s} s") } else { format!("{} min", s / 60) }
}

impl Console {
    /// How long the window may wait for its next turn when no device event wakes it (`None`: until
    /// something happens): see the module doc.
    pub fn next_turn(&self, now: Instant) -> Option<Duration> {
        let mut next: Option<Duration> = None;
        let mut at_most = |d: Duration| next = Some(next.map_or(d, |n| n.min(d)));
        let vest = self.vest_connected();
        if vest {
            at_most(LIVENESS_TURN);
        }
        if vest || self.gps_connected() {
            at_most(AGE_STEP);
        }
        // Remote stations wake the window when they publish (`Fleet::set_waker`); their contact ages are
        // shown in whole seconds.
        if self.remote.is_some() {
            at_most(AGE_STEP);
        }
        // The study runner's timers (stimulus end, feedback, the interval) advance in the station's pump.
        if let Some(d) = self.station.study_wake_in() {
            at_most(d);
        }
        // A fix turns stale, then lost, with no event at all: turn at the instant it does.
        if let Some(age) = self.position_age(now) {
            for limit_s in [self.cfg.stale_after_s, self.cfg.lost_after_s] {
                let limit = Duration::from_secs_f64(limit_s.max(0.0));
                if let Some(left) = limit.checked_sub(age).filter(|d| !d.is_zero()) {
                    at_most(left + Duration::from_millis(10));
                }
            }
        }
        next
    }

    /// The "now" display: the last cue in large type with its age, guidance's state (Resume instead when
    /// halted) and the cues before it, right above the Vest section's grid; the side panel's collapse
    /// button. Fixed height.
    pub(super) fn now_ui(&mut self, ui: &mut egui::Ui, now: Instant) {
        let width = ui.available_width();
        ui.allocate_ui_with_layout(vec2(width, NOW_H), egui::Layout::top_down(egui::Align::Min), |ui| {
            ui.set_min_size(vec2(width, NOW_H));
            let last = self.station.cues.newest_first().next().copied();
            ui.horizontal(|ui| {
                let (big, color) = match last {
                    Some((cue, _)) => (cue_words(cue), ui.visuals().strong_text_color()),
                    None => ("NO CUE YET".to_owned(), ui.visuals().weak_text_color()),
                };
                ui.add(egui::Label::new(RichText::new(big).size(CUE_PT).strong().color(color)).truncate())
                    .on_hover_text("The last cue automatic guidance sent to the vest");
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Min), |ui| {
                    if ui.small_button("<< Hide").on_hover_text("Collapse the side panel").clicked() {
                        self.side_open = false;
                    }
                });
            });
            if self.station.vest.halted.is_some() {
                let resume =
                    egui::Button::new(RichText::new("Resume automatic cues").strong().color(Color32::WHITE))
                        .fill(Color32::from_rgb(40, 120, 60));
                if ui.add(resume).on_hover_text("Automatic cues on again (after STOP ALL)").clicked() {
                    self.resume_guidance();
                }
            } else {
                let state = self.guidance_words(last.map(|(_, at)| now.saturating_duration_since(at)));
                ui.add(egui::Label::new(RichText::new(state).small()).truncate());
            }
            let before: Vec<String> = self
                .station
                .cues
                .newest_first()
                .skip(1)
                .map(|(c, at)| {
                    format!(
                        "{} {} ago",
                        cue_words(*c).to_lowercase(),
                        short_age(now.saturating_duration_since(*at))
                    )
                })
                .collect();
            let history = if before.is_empty() {
                "before: —".to_owned()
            } else {
                format!("before: {}", before.join(" · "))
            };
            ui.add(egui::Label::new(RichText::new(history).small().weak()).truncate());
        });
    }

    /// Guidance's state in a few words for the "now" display, with the last cue's age.
    fn guidance_words(&self, last_age: Option<Duration>) -> String {
        let age = last_age.map_or_else(String::new, |a| format!("sent {} ago · ", short_age(a)));
        if self.station.vest.halted.is_some() {
            return format!("{age}HALTED: no automatic cues");
        }
        if !self.cfg.guidance_auto {
            return format!("{age}manual: no automatic cues");
        }
        match &self.station.guidance {
            None => format!("{age}waiting for the first fix"),
            Some(st) => match &st.hold {
                Some(h) => format!("{age}on hold: {h}"),
                None => format!("{age}{} · wants {}", st.state.name(), st.cue.map_or("no cue", Cue::name)),
            },
        }
    }
}
