//! Driving one station from the Stations window (on the broker or on this machine's ports): the operator
//! picks a station, and the controls act on it through `Stations::send` — manual cues on a 4x4 back-view grid (one tactor, a row, a column, the cue
//! set, the operator's saved patterns), the console's route and guidance settings sent to it, its next waypoint, Resume and Mark.
//!
//! The grid shows the tactors the station's unit reports on, from the station's last state (never from
//! what was sent); a stale station's grid is drawn grey and says so. Every command sent is listed with its
//! outcome as the station's event answers it (`applied`, `refused: …`), or as the failure to send.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use egui::{Color32, RichText, vec2};
use vestnav_core::vest::{Cue, GRID, Pattern, TactorMask};
use vestnav_device::wtcu::VestCommand;
use vestnav_remote::wire::{EventKind, Sender};
use vestnav_remote::{StationView, Stations};
use vestnav_station::Station;
use vestnav_station::command::Command;

/// Width of the drive panel's left column (the tactor grid and the lines above it) [points]: the grid's
/// four 40-point buttons with their spacing, and room to spare.
const DRIVE_GRID_COLUMN_W: f32 = 200.0;
/// Commands kept in the outcome list (the newest).
const SENT_KEPT: usize = 8;
/// A command with no answer for longer is shown as unanswered.
const ANSWER_BOUND: Duration = Duration::from_secs(3);

/// One command sent to the driven station.
#[derive(Debug, Clone)]
pub struct Sent {
    /// The station it went to.
    pub to: String,
    /// Its sequence number (`None`: it could not be sent).
    pub seq: Option<u64>,
    /// The command in a few words.
    pub what: String,
    /// When it was sent.
    pub at: Instant,
    /// Why it could not be sent.
    pub error: Option<String>,
}

/// What became of a sent command, in words, and whether it went wrong.
pub fn outcome(sent: &Sent, view: Option<&StationView>, me: &Sender, now: Instant) -> (String, bool) {
    if let Some(e) = &sent.error {
        return (format!("not sent: {e}"), true);
    }
    let answer = sent.seq.and_then(|seq| {
        view?.events.iter().rev().find(|(_, e)| e.answers.as_ref().is_some_and(|(s, n)| s == me && *n == seq))
    });
    if let Some((_, e)) = answer {
        return match e.kind {
            EventKind::Refused => (e.text.clone(), true),
            EventKind::Applied => (format!("applied: {}", e.text), false),
            _ => (e.text.clone(), false),
        };
    }
    let age = now.saturating_duration_since(sent.at);
    if age > ANSWER_BOUND {
        (format!("no answer from the station for {:.0} s", age.as_secs_f64()), true)
    } else {
        ("sent, waiting for the station".to_owned(), false)
    }
}

/// The drive controls' state.
#[derive(Debug, Default)]
pub struct Drive {
    /// The station being driven.
    pub selected: Option<String>,
    /// Commands sent, newest last.
    pub sent: VecDeque<Sent>,
    /// The next waypoint to set (1-based in the field).
    next_waypoint: usize,
    /// The mark's label.
    mark: String,
}

impl Drive {
    /// Sends `command` to the selected station and records it for the outcome list.
    pub fn send(&mut self, stations: &Stations, command: Command) {
        let Some(to) = self.selected.clone() else { return };
        let what = command.describe();
        let (seq, error) = match stations.send(&to, command) {
            Ok(seq) => (Some(seq), None),
            Err(e) => (None, Some(e.to_string())),
        };
        if self.sent.len() >= SENT_KEPT {
            self.sent.pop_front();
        }
        self.sent.push_back(Sent { to, seq, what, at: Instant::now(), error });
    }

    /// Draws the controls for the selected station (nothing when none is selected). `local` is the
    /// console's own station: its route and settings are what "send" sends.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        stations: &Stations,
        local: &Station,
        patterns: &[Pattern],
        now: Instant,
    ) {
        let Some(name) = self.selected.clone() else {
            ui.label(RichText::new("Pick a station (Drive) to send it cues, a route or settings.").weak());
            return;
        };
        let view = stations.station(&name);
        let stale_after = stations.stale_after();
        let stale = view.as_ref().is_none_or(|v| v.is_stale(now, stale_after));
        ui.horizontal(|ui| {
            ui.heading(format!("Driving {name}"));
            if ui.button("Stop driving").clicked() {
                self.selected = None;
            }
        });
        if self.selected.is_none() {
            return;
        }
        let on_ms = local.settings().guidance.on_ms;
        ui.horizontal_top(|ui| {
            ui.vertical(|ui| {
                // A fixed width (its lines wrap): the unit's tactor line changes length as tactors go on
                // and off, and a column that followed it would move the command buttons beside it under
                // the pointer.
                ui.set_width(DRIVE_GRID_COLUMN_W);
                self.grid_ui(ui, stations, view.as_ref(), stale, on_ms, now);
                // The operator's saved patterns (Vest panel), played on this station.
                ui.horizontal_wrapped(|ui| {
                    for p in patterns {
                        if ui.button(format!("Play {}", p.name)).clicked() {
                            self.send(
                                stations,
                                Command::Manual { command: VestCommand::Play(p.clone()), cue: None },
                            );
                        }
                    }
                });
            });
            ui.separator();
            ui.vertical(|ui| self.commands_ui(ui, stations, view.as_ref(), local));
        });
        ui.separator();
        let me = stations.sender_for(&name);
        for s in self.sent.iter().rev().filter(|s| s.to == name) {
            let (text, bad) = outcome(s, view.as_ref(), &me, now);
            let line = RichText::new(format!("{}: {text}", s.what));
            ui.label(if bad { line.color(ui.visuals().error_fg_color) } else { line });
        }
    }

    fn grid_ui(
        &mut self,
        ui: &mut egui::Ui,
        stations: &Stations,
        view: Option<&StationView>,
        stale: bool,
        on_ms: u16,
        now: Instant,
    ) {
        let reported = view.and_then(|v| v.state.as_ref()).and_then(|s| s.station.tactors_on);
        let state_line = match (reported, stale) {
            (_, true) => {
                let age = view.map_or_else(
                    || "no contact yet".to_owned(),
                    |v| v.contact_label(now, stations.stale_after()),
                );
                RichText::new(format!("STALE ({age}): the tactors shown may no longer be true"))
                    .color(ui.visuals().error_fg_color)
            }
            (None, false) => RichText::new("the unit reports no tactor state").weak(),
            (Some(m), false) if m.is_empty() => RichText::new("unit reports every tactor off"),
            (Some(m), false) => RichText::new(format!(
                "unit reports on: {}",
                m.indices().map(vestnav_core::vest::tactor_label).collect::<Vec<_>>().join(" ")
            )),
        };
        ui.label(state_line);
        ui.label(RichText::new("wearer's left · back view · right").small().weak());
        let mut fire = None;
        egui::Grid::new("drive-grid").spacing(vec2(4.0, 4.0)).show(ui, |ui| {
            for row in 0..GRID {
                for col in 0..GRID {
                    let i = row * GRID + col;
                    let on = reported.is_some_and(|m| m.contains(i));
                    let fill = match (on, stale) {
                        (true, true) => Color32::from_gray(150),
                        (true, false) => Color32::from_rgb(250, 170, 20),
                        (false, _) => ui.visuals().widgets.inactive.bg_fill,
                    };
                    let text = RichText::new(vestnav_core::vest::tactor_label(i)).color(if on {
                        Color32::BLACK
                    } else {
                        ui.visuals().text_color()
                    });
                    let b = egui::Button::new(text).fill(fill).min_size(vec2(40.0, 30.0));
                    if ui.add(b).on_hover_text(format!("fire tactor {i} on this station")).clicked() {
                        fire = TactorMask::single(i);
                    }
                }
                if ui.small_button(format!("row {}", row + 1)).clicked() {
                    fire = Some(TactorMask::row(row));
                }
                ui.end_row();
            }
            for col in 0..GRID {
                if ui.small_button(format!("col {}", col + 1)).clicked() {
                    fire = Some(TactorMask::column(col));
                }
            }
            ui.end_row();
        });
        if let Some(mask) = fire {
            self.send(
                stations,
                Command::Manual { command: VestCommand::Fire { mask, duration_ms: on_ms }, cue: None },
            );
        }
        ui.horizontal_wrapped(|ui| {
            for cue in Cue::ALL {
                if ui.button(cue.name()).clicked() {
                    let command = VestCommand::Play(cue.pattern(on_ms));
                    self.send(stations, Command::Manual { command, cue: Some(cue) });
                }
            }
        });
    }

    fn commands_ui(
        &mut self,
        ui: &mut egui::Ui,
        stations: &Stations,
        view: Option<&StationView>,
        local: &Station,
    ) {
        let route = local.route();
        let n = route.waypoints().len();
        if let Some(r) = view.and_then(|v| v.route.as_ref()) {
            let next = r.waypoints.get(r.next).map_or_else(|| "none".to_owned(), |w| w.name.clone());
            let along = if r.path_points > 0 {
                format!(", along a path of {} points", r.path_points)
            } else {
                String::new()
            };
            ui.label(format!("its route: {} ({} waypoints{along}), next {next}", r.name, r.waypoints.len()));
        } else {
            ui.label(RichText::new("its route: not heard yet").weak());
        }
        if ui
            .add_enabled(
                n > 0,
                egui::Button::new(format!("Send this console's route ({}, {n} waypoints)", route.name())),
            )
            .clicked()
        {
            self.send(
                stations,
                Command::SetRoute {
                    name: route.name().to_owned(),
                    waypoints: route.waypoints().to_vec(),
                    next: route.next().min(n),
                    path: route.path().cloned(),
                },
            );
        }
        let remote_n = view.and_then(|v| v.route.as_ref()).map_or(0, |r| r.waypoints.len());
        ui.horizontal(|ui| {
            ui.add_enabled(
                remote_n > 0,
                egui::DragValue::new(&mut self.next_waypoint).range(1..=remote_n.max(1)).prefix("waypoint "),
            );
            if ui.add_enabled(remote_n > 0, egui::Button::new("Set next waypoint")).clicked() {
                let index = self.next_waypoint.clamp(1, remote_n.max(1)) - 1;
                self.send(stations, Command::NextWaypoint { index });
            }
        });
        if ui
            .button("Send this console's guidance settings")
            .on_hover_text("Arrival radius, cue interval, on-time, manual hold, stale and lost ages")
            .clicked()
        {
            self.send(stations, Command::Settings(*local.settings()));
        }
        if ui.button("Resume automatic cues").clicked() {
            self.send(stations, Command::Resume);
        }
        ui.horizontal(|ui| {
            ui.add(egui::TextEdit::singleline(&mut self.mark).hint_text("mark label").desired_width(120.0));
            if ui
                .button("Mark")
                .on_hover_text("A mark in the station's session log at the wearer's position")
                .clicked()
            {
                self.send(stations, Command::Mark { label: self.mark.trim().to_owned() });
                self.mark.clear();
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_remote::wire::EventMsg;

    #[test]
    fn an_answer_is_matched_to_its_own_sender_and_number_only() {
        let now = Instant::now();
        let me = Sender { operator: "op".into(), session: 7 };
        let other = Sender { operator: "op".into(), session: 8 };
        let sent = Sent { to: "alpha".into(), seq: Some(3), what: "fire".into(), at: now, error: None };
        let ev = |from: &Sender, seq, kind, text: &str| {
            (now, EventMsg { at_ms: 0, kind, answers: Some((from.clone(), seq)), text: text.into() })
        };
        let mut view = StationView { name: "alpha".into(), ..StationView::default() };
        view.events.push_back(ev(&other, 3, EventKind::Refused, "someone else's"));
        view.events.push_back(ev(&me, 2, EventKind::Refused, "an older one"));
        assert_eq!(outcome(&sent, Some(&view), &me, now), ("sent, waiting for the station".into(), false));
        let later = now + Duration::from_secs(4);
        assert!(outcome(&sent, Some(&view), &me, later).1, "unanswered past the bound is shown as wrong");
        view.events.push_back(ev(&me, 3, EventKind::Refused, "FIRE refused: 1.4 s late, not played"));
        assert_eq!(
            outcome(&sent, Some(&view), &me, now),
            ("FIRE refused: 1.4 s late, not played".into(), true)
        );
        let failed = Sent { seq: None, error: Some("not connected to the broker".into()), ..sent };
        assert!(outcome(&failed, Some(&view), &me, now).0.starts_with("not sent"));
    }
}
