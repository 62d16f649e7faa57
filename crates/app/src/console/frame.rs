//! The console's frame: the panels' layout, the top bar, the guidance controls and the keyboard keys.

use std::time::{Duration, Instant};

use egui::{Color32, RichText};
use vestnav_core::guidance::StrategyKind;
use vestnav_core::vest::Cue;
use vestnav_device::gps::SourceState;
use vestnav_device::wtcu::LinkState;

use super::{Console, GpsAlarm, Tab};
use crate::fieldtest_panel::FieldTestAction;

impl Console {
    /// Draws one frame (also the entry point of the kittest tests).
    #[allow(clippy::too_many_lines)] // the frame's layout in one place: panels in the order they are drawn
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        self.tick();
        let now = Instant::now();
        let anim_s = ui.input(|i| i.time);
        self.handle_keys(ui);

        egui::Panel::top("vestnav-top").show(ui, |ui| self.top_bar(ui, now));
        egui::Panel::bottom("vestnav-status").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.label(RichText::new(&self.status).small());
                if let Some(p) = self.log_path() {
                    ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                        ui.label(RichText::new(format!("log: {}", p.display())).small().weak());
                    });
                }
            });
        });
        egui::Panel::left("vestnav-side").default_size(360.0).min_size(300.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                egui::CollapsingHeader::new("GPS").default_open(true).show(ui, |ui| {
                    crate::gps_panel::show(self, ui, now, anim_s);
                });
                egui::CollapsingHeader::new("Vest").default_open(true).show(ui, |ui| {
                    crate::vest_panel::show(self, ui);
                });
                egui::CollapsingHeader::new("Guidance").default_open(true).show(ui, |ui| {
                    self.guidance_ui(ui);
                });
            });
        });
        egui::CentralPanel::default().show(ui, |ui| match self.tab {
            Tab::Map => {
                let fix = self.gps.last_position.clone();
                let walking = self.cfg.walking_speed_m_s;
                let changed = self.map.ui(
                    ui,
                    fix.as_ref(),
                    self.guidance.as_ref(),
                    walking,
                    &mut self.cfg,
                    &mut self.status,
                );
                if changed {
                    self.push_route();
                }
            }
            Tab::Simulation => self.sim_panel.ui(ui),
            Tab::FieldTests => {
                if let Some(FieldTestAction::Mark { label }) = self.field_panel.ui(ui) {
                    self.mark(&label);
                }
            }
            Tab::SessionLog => {
                let dir = self.log_dir();
                let current = self.log.as_ref().map(|l| l.path().to_path_buf());
                self.log_viewer.ui(ui, &dir, current.as_deref(), &mut self.map);
            }
        });

        // Every settings change of the frame reaches guidance here, once.
        if self.cfg != self.cfg_saved {
            if self.cfg.guidance_auto && !self.cfg_saved.guidance_auto {
                // Ticking automatic cues back on is the operator's deliberate resume (it pushes the settings).
                self.resume_guidance();
            } else {
                self.push_settings();
            }
            self.save_config();
        }
        // Fix ages and alarms change with time even when no event arrives; the frame is also the UI's
        // heartbeat.
        ui.ctx().request_repaint_after(Duration::from_millis(250));
    }

    fn handle_keys(&mut self, ui: &egui::Ui) {
        let typing = ui.ctx().text_edit_focused();
        // STOP ALL has its own key; Esc is left to close menus and pop-ups, as everywhere else.
        let space = ui.input(|i| i.key_pressed(egui::Key::Space));
        if space && !typing {
            self.stop_all();
        }
        let m = ui.input(|i| i.key_pressed(egui::Key::M));
        if m && !typing && self.tab != Tab::FieldTests {
            let n = self.map.marks + 1;
            self.map.marks = n;
            self.mark(&format!("mark {n}"));
        }
    }

    fn top_bar(&mut self, ui: &mut egui::Ui, now: Instant) {
        ui.horizontal(|ui| {
            let stop = egui::Button::new(RichText::new("STOP ALL").strong().size(18.0).color(Color32::WHITE))
                .fill(Color32::from_rgb(200, 30, 30))
                .min_size(egui::vec2(120.0, 30.0));
            if ui
                .add(stop)
                .on_hover_text("Every tactor off, automatic guidance halted (key: Space)")
                .clicked()
            {
                self.stop_all();
            }
            ui.separator();
            let alarm = self.gps_alarm(now);
            let (gps_text, gps_color) = match &alarm {
                Some(GpsAlarm::Lost { .. }) => ("GPS: FIX LOST".to_owned(), Color32::from_rgb(230, 40, 40)),
                Some(GpsAlarm::Stale { .. }) => ("GPS: STALE".to_owned(), Color32::from_rgb(230, 150, 0)),
                None => (
                    format!("GPS: {}", crate::gps_panel::state_label(self.gps.state.as_ref())),
                    gps_color(self.gps.state.as_ref()),
                ),
            };
            ui.label(RichText::new(gps_text).color(gps_color).strong());
            ui.separator();
            ui.label(
                RichText::new(format!("Vest: {}", self.vest.label()))
                    .color(vest_color(self.vest.state.as_ref()))
                    .strong(),
            );
            ui.separator();
            let (g, color) = match (&self.vest.halted, self.cfg.guidance_auto) {
                (Some(_), _) => ("Guidance: HALTED", Color32::from_rgb(230, 40, 40)),
                (None, true) => ("Guidance: AUTO", ui.visuals().text_color()),
                (None, false) => ("Guidance: manual", ui.visuals().text_color()),
            };
            ui.label(RichText::new(g).color(color).strong());
            ui.separator();
            ui.selectable_value(&mut self.tab, Tab::Map, "Map");
            ui.selectable_value(&mut self.tab, Tab::Simulation, "Simulation");
            ui.selectable_value(&mut self.tab, Tab::FieldTests, "Field tests");
            ui.selectable_value(&mut self.tab, Tab::SessionLog, "Session log");
        });
    }

    fn guidance_ui(&mut self, ui: &mut egui::Ui) {
        if let Some(why) = self.vest.halted.clone() {
            ui.label(
                RichText::new(format!("Automatic cues halted: {why}")).color(Color32::from_rgb(230, 40, 40)),
            );
            if ui.button("Resume automatic cues").clicked() {
                self.resume_guidance();
            }
        }
        // The controls edit `cfg`; the end of the frame hands every change to guidance, once (ticking
        // automatic cues on is the resume).
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.cfg.guidance_auto, "Automatic cues");
            ui.checkbox(&mut self.cfg.loop_route, "Loop route");
        });
        egui::ComboBox::from_label("Strategy").selected_text(self.cfg.strategy.clone()).show_ui(ui, |ui| {
            for k in StrategyKind::ALL {
                ui.selectable_value(&mut self.cfg.strategy, k.name().to_owned(), k.name());
            }
        });
        egui::ComboBox::from_label("Heading")
            .selected_text(self.cfg.heading_mode.name())
            .show_ui(ui, |ui| {
                for m in vestnav_core::guidance::HeadingMode::ALL {
                    ui.selectable_value(&mut self.cfg.heading_mode, m, m.name());
                }
            })
            .response
            .on_hover_text(
                "auto: the compass when fresh (< 1 s), calibrated and not disturbed, else COG while walking; \
                 compass: the compass only; cog: course over ground only (none while standing)",
            );
        ui.add(
            egui::Slider::new(&mut self.cfg.arrival_radius_m, 2.0..=50.0).suffix(" m").text("Arrival radius"),
        );
        ui.add(egui::Slider::new(&mut self.cfg.cue_interval_s, 1.0..=30.0).suffix(" s").text("Cue interval"));
        ui.add(egui::Slider::new(&mut self.cfg.manual_hold_s, 0.0..=60.0).suffix(" s").text("Manual hold"));
        match &self.guidance {
            None => {
                ui.label("waiting for the first fix");
            }
            Some(st) => {
                if let Some(hold) = &st.hold {
                    ui.label(
                        RichText::new(format!("On hold: {hold}"))
                            .color(Color32::from_rgb(230, 150, 0))
                            .strong(),
                    );
                }
                let cue = st.cue.map_or("none", Cue::name);
                let sent = if st.sent { "sent" } else { "not sent now" };
                ui.label(RichText::new(format!("Cue: {cue} ({sent}) · {}", st.state)).strong());
                ui.label(&st.reason);
                let n = |v: Option<f64>, u: &str| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.0}{u}"));
                ui.label(format!(
                    "distance {} · bearing error {} · cross-track {} · heading from {}",
                    n(st.distance_m, " m"),
                    n(st.bearing_error_deg, "°"),
                    st.cross_track_m.map_or_else(|| "—".to_owned(), |x| format!("{x:+.1} m")),
                    st.heading_source
                ));
                let heading = st.heading_deg.map_or_else(|| "none".to_owned(), |h| format!("{h:.0}° true"));
                let dec = st.declination_deg.map_or_else(
                    || "no position yet".to_owned(),
                    |d| format!("{d:+.1}° (WMM, applied once)"),
                );
                ui.label(format!("heading {heading}: {} · declination {dec}", st.heading_rule));
                if st.compass_disturbed {
                    ui.label(
                        RichText::new("compass disturbed? It disagrees with the GPS course while walking; steering by COG")
                            .color(Color32::from_rgb(230, 150, 0))
                            .strong(),
                    );
                }
                if st.finished {
                    ui.label(RichText::new("Route finished").color(Color32::from_rgb(40, 160, 60)));
                }
            }
        }
        ui.horizontal(|ui| {
            if ui.button("< Previous waypoint").clicked() && self.map.next > 0 {
                self.map.next -= 1;
                self.push_route();
            }
            if ui.button("Next waypoint >").clicked() && self.map.next < self.map.waypoints.len() {
                self.map.next += 1;
                self.push_route();
            }
        });
    }
}

fn vest_color(s: Option<&LinkState>) -> Color32 {
    match s {
        Some(LinkState::Ready) => Color32::from_rgb(40, 170, 60),
        Some(LinkState::Connecting { .. } | LinkState::Handshaking) => Color32::from_rgb(220, 150, 0),
        Some(LinkState::Lost { .. }) => Color32::from_rgb(230, 40, 40),
        Some(LinkState::Disconnected) | None => Color32::GRAY,
    }
}

fn gps_color(s: Option<&SourceState>) -> Color32 {
    match s {
        Some(SourceState::Live { .. }) => Color32::from_rgb(40, 170, 60),
        Some(SourceState::Connecting { .. } | SourceState::Stale | SourceState::Reconnecting { .. }) => {
            Color32::from_rgb(220, 150, 0)
        }
        Some(SourceState::Lost { .. }) => Color32::from_rgb(230, 40, 40),
        Some(SourceState::Finished | SourceState::Stopped) | None => Color32::GRAY,
    }
}
