//! The console's frame: the panels' layout, the top bar, the banner strip, the theme, the guidance controls
//! and the keyboard keys.
//!
//! The banner strip under the top bar gives one line per device and for guidance whenever it is not OK:
//! a strong colour, the state in capitals and what to do. [`Console::banners`] derives the lines each frame
//! from the device events' state and timestamps (the vest's link state, the GPS alarm on fix ages, the
//! guidance worker's latest status) — never from what an earlier frame showed.
//!
//! The audible alarm ([`AudibleAlarm`]): on the frame the GPS banner turns to FIX LOST, and on the frame the
//! vest banner turns to VEST LOST, the terminal bell rings once (`BEL` written to stderr: no audio stack);
//! it rings again only after the state has recovered and is lost anew. View > "Audible alarm" turns it off
//! (remembered in the config). Tests hear it through [`Console::set_bell`].

use std::time::{Duration, Instant};

use egui::{Color32, RichText, vec2};
use vestnav_core::guidance::{HeadingSource, NavState, StrategyKind};
use vestnav_core::vest::Cue;
use vestnav_device::gps::SourceState;
use vestnav_device::wtcu::LinkState;
use vestnav_station::{Severity as NoticeSeverity, Subject};

use super::{Console, GpsAlarm, Tab, layout};
use crate::config::Config;
use crate::fieldtest_panel::{FieldTestAction, FieldTestPanel};

/// Text size of the banner lines [pt] (large-text option: [`BANNER_PT_LARGE`]): readable outdoors.
pub const BANNER_PT: f32 = 18.0;
/// Text size of the banner lines with the large-text option [pt].
pub const BANNER_PT_LARGE: f32 = 22.0;

/// How bad the state a banner line reports is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// Cues cannot reach the wearer, or guidance cannot steer: red.
    Alarm,
    /// Degraded or not there yet (connecting, stale fix): amber.
    Warning,
    /// Not a fault, but the wearer gets no automatic cues (manual guidance): blue.
    Notice,
}

/// What a banner line is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BannerSubject {
    /// STOP ALL not confirmed by the unit: first, above everything else.
    Stop,
    /// The vest link.
    Vest,
    /// The GPS source and its fix.
    Gps,
    /// Automatic guidance.
    Guidance,
    /// A notice of the station the operator must read (a broken file kept aside, storage failing, a
    /// route refused): shown until dismissed.
    Notice(usize),
}

/// One line of the banner strip: the state and what to do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Banner {
    /// Its device, or guidance.
    pub subject: BannerSubject,
    /// Its colour.
    pub severity: Severity,
    /// `STATE: detail. Consequence. What to do.`
    pub text: String,
}

impl Banner {
    fn new(subject: BannerSubject, severity: Severity, text: String) -> Self {
        Self { subject, severity, text }
    }
}

/// Rings once per transition to GPS fix loss, to vest link loss and to an unconfirmed stop (see the
/// module doc); an unconfirmed stop rings every second while it lasts, whatever the setting.
pub(crate) struct AudibleAlarm {
    bell: Box<dyn FnMut() + Send>,
    /// (fix lost, vest lost, stop not confirmed) on the last frame.
    was: (bool, bool, bool),
    last_stop_ring: Option<Instant>,
}

impl Default for AudibleAlarm {
    fn default() -> Self {
        Self { bell: Box::new(terminal_bell), was: (false, false, false), last_stop_ring: None }
    }
}

impl AudibleAlarm {
    /// Takes this frame's states; rings when one of them has just become lost and `enabled`.
    fn update(&mut self, now: (bool, bool, bool), enabled: bool) {
        let rising = (now.0 && !self.was.0) || (now.1 && !self.was.1);
        self.was = now;
        if rising && enabled {
            (self.bell)();
        }
        // A tactor may still run on the wearer: this one cannot be turned off, and repeats.
        if now.2 {
            let t = Instant::now();
            if self.last_stop_ring.is_none_or(|l| t.duration_since(l) >= Duration::from_secs(1)) {
                self.last_stop_ring = Some(t);
                (self.bell)();
            }
        } else {
            self.last_stop_ring = None;
        }
    }
}

/// The terminal bell: `BEL` on stderr (a terminal beeps or flashes; nothing happens without one).
fn terminal_bell() {
    use std::io::Write as _;
    let mut err = std::io::stderr();
    let _ = err.write_all(b"\x07").and_then(|()| err.flush());
}

impl Console {
    /// Replaces what the audible alarm rings (the terminal bell) — tests count the rings.
    pub fn set_bell(&mut self, bell: impl FnMut() + Send + 'static) {
        self.alarm.bell = Box::new(bell);
    }

    /// Whether the GPS fix and the vest link are lost now: the same states the banners call FIX LOST and
    /// VEST LOST.
    fn lost_states(&self, now: Instant) -> (bool, bool, bool) {
        let fix_lost = matches!(self.gps_alarm(now), Some(GpsAlarm::Lost { .. }));
        (fix_lost, self.station.vest.is_lost(), self.station.stop_alarm(now).is_some())
    }

    /// Draws one frame (also the entry point of the kittest tests).
    #[allow(clippy::too_many_lines)] // the frame's layout in one place: panels in the order they are drawn
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        self.frame_pump();
        // Remote stations wake the window when one of them says something new.
        if let Some(r) = &mut self.remote
            && !r.stations().has_waker()
        {
            let ctx = ui.ctx().clone();
            r.stations_mut().set_waker(std::sync::Arc::new(move || ctx.request_repaint()));
        }
        // The remote stations' wearers for the map, as the broker last told of them.
        self.map.remote_wearers =
            self.remote.as_ref().map_or_else(Vec::new, |r| r.wearers(self.cfg.stale_after_s));
        apply_theme(ui, &self.cfg);
        let now = Instant::now();
        let anim_s = ui.input(|i| i.time);
        self.handle_keys(ui);

        let ctx = ui.ctx().clone();
        // The top bar's place is reserved here; the bar itself is drawn last, in a layer above every
        // window and modal (`console/layout.rs`).
        let bar_h = if self.cfg.large_text { layout::TOP_BAR_H.1 } else { layout::TOP_BAR_H.0 };
        let bar = egui::Panel::top("vestnav-top")
            .exact_size(bar_h)
            .resizable(false)
            .show(ui, |ui| {
                ui.allocate_space(ui.available_size());
            })
            .response
            .rect;
        layout::keep_windows_below(&ctx, bar.bottom());
        let banners = self.banners(now);
        let lost = self.lost_states(now);
        self.alarm.update(lost, self.cfg.audible_alarm);
        egui::Panel::bottom("vestnav-status").show(ui, |ui| {
            ui.horizontal(|ui| {
                let status = self.latest_notice().map_or_else(String::new, |n| n.text.clone());
                ui.label(RichText::new(status).small());
                if let Some(p) = self.log_path() {
                    ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                        if self.station.log_failing() {
                            ui.label(
                                RichText::new(format!("log: {} — NOT recording", p.display()))
                                    .small()
                                    .color(ui.visuals().error_fg_color),
                            );
                        } else {
                            ui.label(RichText::new(format!("log: {}", p.display())).small().weak());
                        }
                    });
                }
            });
        });
        if self.side_open {
            let wide = ctx.content_rect().width() >= layout::WIDE_WINDOW;
            let side_w = if wide { layout::SIDE_W.1 } else { layout::SIDE_W.0 };
            egui::Panel::left("vestnav-side").exact_size(side_w).resizable(false).show(ui, |ui| {
                self.now_ui(ui, now);
                ui.separator();
                egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| {
                    // On a short screen the GPS section starts closed (its state is in the top bar and the
                    // banners), so the vest grid is in view.
                    let tall = ctx.content_rect().height() >= 800.0;
                    egui::CollapsingHeader::new("GPS").default_open(tall).show(ui, |ui| {
                        crate::gps_panel::show(&mut self.station, &mut self.cfg, &mut self.gps_ui, ui, now);
                    });
                    egui::CollapsingHeader::new("Vest").default_open(true).show(ui, |ui| {
                        crate::vest_panel::show(
                            &mut self.station,
                            &mut self.cfg,
                            &mut self.vest_ui,
                            &mut self.compass_wizard,
                            &mut self.pattern_editor.open,
                            ui,
                        );
                    });
                    egui::CollapsingHeader::new("Guidance").default_open(true).show(ui, |ui| {
                        self.guidance_ui(ui);
                    });
                });
            });
        } else {
            egui::Panel::left("vestnav-side-collapsed").exact_size(34.0).resizable(false).show(ui, |ui| {
                if ui.button(">>").on_hover_text("Show the side panel (GPS, Vest, Guidance)").clicked() {
                    self.side_open = true;
                }
                crate::vest_panel::mini_grid(ui, self.station.vest.tactors_on, 24.0);
            });
        }
        self.pattern_editor.window(&mut self.station, &mut self.cfg, ui.ctx());
        crate::gps_receiver::window(
            &self.station,
            &self.cfg.gps,
            &mut self.gps_ui.receiver,
            &mut self.gps_ui.ntrip.open,
            ui.ctx(),
        );
        let base = self.cfg.recent.base();
        crate::ntrip_panel::window(
            &mut self.station,
            &mut self.cfg.ntrip,
            &mut self.gps_ui.ntrip,
            &base,
            ui.ctx(),
        );
        self.lab_ui(ui.ctx());
        let pt = if self.cfg.large_text { BANNER_PT_LARGE } else { BANNER_PT };
        // Two lines of banner text and their margins, whether there are banners or not: nothing below
        // moves when they come and go (more scroll inside the strip).
        let strip_h = 2.0 * (pt * 1.35 + 12.0) + 6.0;
        egui::CentralPanel::default().show(ui, |ui| {
            egui::Panel::top("vestnav-banners").exact_size(strip_h).resizable(false).show(ui, |ui| {
                egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| {
                    self.banner_strip(ui, &banners, anim_s);
                });
            });
            self.central_ui(ui);
        });
        egui::Area::new(egui::Id::unique("vestnav-top-bar"))
            .order(egui::Order::Tooltip)
            .fixed_pos(bar.min)
            .constrain(false)
            .show(&ctx, |ui| {
                egui::Frame::new()
                    .fill(ui.visuals().panel_fill)
                    .inner_margin(egui::Margin::symmetric(8, 5))
                    .show(ui, |ui| {
                        ui.set_min_size(vec2(bar.width() - 16.0, bar.height() - 10.0));
                        ui.set_max_width(bar.width() - 16.0);
                        self.top_bar(ui, now);
                    });
            });

        // `--study-wearer`'s simulated wearer answers the console's own study whichever tab is shown.
        if let Some(d) = self.study.simulate(&mut self.station, Instant::now()) {
            ui.ctx().request_repaint_after(d);
        }
        // Every settings change of the frame reaches the station here, once (ticking automatic cues back
        // on is the operator's deliberate resume).
        self.settings_changed();
        if let Some(d) = self.next_turn(Instant::now()) {
            ui.ctx().request_repaint_after(d);
        }
    }

    /// The active tab.
    fn central_ui(&mut self, ui: &mut egui::Ui) {
        match self.tab {
            Tab::Map => {
                let fix = self.station.gps.last_position.clone();
                let guidance = self.station.guidance.clone();
                let walking = self.cfg.walking_speed_m_s;
                self.map.tools.field = FieldTestPanel::map_overlay(&self.station.field_tests);
                let (route, track, notices) = self.station.route_view();
                self.map.ui(
                    ui,
                    route,
                    track,
                    fix.as_ref(),
                    guidance.as_ref(),
                    walking,
                    &mut self.cfg,
                    notices,
                );
            }
            Tab::Simulation => {
                self.sim_panel.base = self.cfg.recent.base();
                self.sim_panel.ui(ui);
            }
            Tab::FieldTests => {
                self.field_panel.base = self.cfg.recent.base();
                if let Some(FieldTestAction::Mark { label }) =
                    self.field_panel.ui(&mut self.station.field_tests, ui)
                {
                    self.mark(&label);
                }
                if self.field_panel.comparing {
                    self.field_panel.receivers.ui(&mut self.station, ui);
                }
            }
            Tab::SessionLog => {
                let dir = self.log_dir();
                let current = self.log_path().map(std::path::Path::to_path_buf);
                self.log_viewer.ui(ui, &dir, current.as_deref(), &mut self.map, &mut self.cfg.recent);
            }
            Tab::Study => {
                let now = Instant::now();
                let lab_open = &mut self.lab_window.open;
                self.study.ui(
                    ui,
                    &mut self.station,
                    self.remote.as_mut(),
                    &mut self.cfg.recent,
                    lab_open,
                    now,
                );
            }
        }
    }

    fn handle_keys(&mut self, ui: &egui::Ui) {
        let typing = ui.ctx().text_edit_focused();
        // STOP ALL has its own key; Esc is left to close menus and pop-ups, as everywhere else. The key is
        // taken before any widget is drawn, so Space never also presses the focused button (STOP ALL once
        // more, or whatever else holds the focus after a click).
        if !typing {
            let space = ui.input_mut(|i| i.consume_key(i.modifiers, egui::Key::Space));
            if space {
                self.stop_all();
            }
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
                    format!("GPS: {}", crate::gps_panel::state_label(self.station.gps.state.as_ref())),
                    gps_color(self.station.gps.state.as_ref()),
                ),
            };
            ui.label(RichText::new(gps_text).color(gps_color).strong());
            ui.separator();
            if self.station.stop_alarm(now).is_some() {
                ui.label(
                    RichText::new("Vest: STOP NOT CONFIRMED").color(Color32::from_rgb(230, 40, 40)).strong(),
                );
            } else {
                ui.label(
                    RichText::new(format!("Vest: {}", self.station.vest.label()))
                        .color(vest_color(self.station.vest.state.as_ref()))
                        .strong(),
                );
            }
            ui.separator();
            let (g, color) = match (&self.station.vest.halted, self.cfg.guidance_auto) {
                (Some(_), _) => ("Guidance: HALTED", Color32::from_rgb(230, 40, 40)),
                (None, true) => ("Guidance: AUTO", ui.visuals().text_color()),
                (None, false) => ("Guidance: manual", ui.visuals().text_color()),
            };
            ui.label(RichText::new(g).color(color).strong());
            ui.separator();
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.cfg.light_theme, "Light high-contrast theme")
                    .on_hover_text("Dark text on white, for sunlight");
                ui.checkbox(&mut self.cfg.large_text, "Large text");
                ui.checkbox(&mut self.cfg.audible_alarm, "Audible alarm")
                    .on_hover_text("Ring the terminal bell once when the GPS fix or the vest link is lost");
                ui.separator();
                if ui.button("Lab outputs (LSL, OSC)…").clicked() {
                    self.lab_window.open = true;
                }
                if ui.button("Broker…").clicked() {
                    self.broker_window.open = true;
                }
                if ui
                    .button("Stations…")
                    .on_hover_text(
                        "Every station: on the broker, and vests and GPS on this machine's other ports",
                    )
                    .clicked()
                {
                    let stop = self.station.stop_path().clone();
                    let logs = Some(self.log_dir());
                    self.remote
                        .get_or_insert_with(|| crate::remote_panel::RemotePanel::new(stop, logs))
                        .open = true;
                }
            });
            ui.separator();
            ui.selectable_value(&mut self.tab, Tab::Map, "Map");
            ui.selectable_value(&mut self.tab, Tab::Simulation, "Simulation");
            ui.selectable_value(&mut self.tab, Tab::FieldTests, "Field tests");
            ui.selectable_value(&mut self.tab, Tab::SessionLog, "Session log");
            ui.selectable_value(&mut self.tab, Tab::Study, "Study");
        });
    }

    /// The banner strip's lines at `now`: an unconfirmed stop first, then one per device and one for
    /// guidance, each only when not OK, then the station's alarms and warnings until dismissed.
    pub fn banners(&self, now: Instant) -> Vec<Banner> {
        let mut lines: Vec<Banner> =
            [self.stop_banner(now), self.vest_banner(), self.gps_banner(now), self.guidance_banner(now)]
                .into_iter()
                .flatten()
                .collect();
        for (k, n) in self.station.notices.all().iter().enumerate() {
            let severity = match n.severity {
                NoticeSeverity::Alarm => Severity::Alarm,
                NoticeSeverity::Warning => Severity::Warning,
                NoticeSeverity::Info => continue,
            };
            // A refused STOP ALL is the stop banner's and the vest line's business already.
            if n.subject == Subject::Vest && lines.iter().any(|b| b.subject == BannerSubject::Stop) {
                continue;
            }
            lines.push(Banner::new(BannerSubject::Notice(k), severity, n.text.clone()));
        }
        lines
    }

    fn stop_banner(&self, now: Instant) -> Option<Banner> {
        let a = self.station.stop_alarm(now)?;
        Some(Banner::new(
            BannerSubject::Stop,
            Severity::Alarm,
            format!("STOP NOT CONFIRMED: {}", vestnav_station::stop_alarm_text(&a)),
        ))
    }

    fn vest_banner(&self) -> Option<Banner> {
        let alarm = |text: String| Some(Banner::new(BannerSubject::Vest, Severity::Alarm, text));
        let lost = |reason: &str, retry: &str| {
            format!(
                "VEST LOST: {reason}. Cues cannot reach the wearer. Check the unit's power and range; \
                 reconnecting{retry}..."
            )
        };
        match (&self.station.vest.state, &self.station.vest.lost) {
            (Some(LinkState::Ready), _) => None,
            (Some(LinkState::Lost { reason }), _) => alarm(lost(reason, "")),
            (Some(LinkState::Connecting { attempt }), Some(reason)) => {
                alarm(lost(reason, &format!(" (attempt {attempt})")))
            }
            (Some(LinkState::Handshaking), Some(reason)) => alarm(lost(reason, " (handshaking)")),
            (Some(LinkState::Connecting { attempt }), None) => Some(Banner::new(
                BannerSubject::Vest,
                Severity::Warning,
                format!(
                    "VEST CONNECTING (attempt {attempt}): cues cannot reach the wearer yet. Check the unit is \
                     switched on and in range."
                ),
            )),
            (Some(LinkState::Handshaking), None) => Some(Banner::new(
                BannerSubject::Vest,
                Severity::Warning,
                "VEST HANDSHAKING: waiting for the unit to identify itself; cues cannot reach the wearer yet."
                    .to_owned(),
            )),
            (Some(LinkState::Disconnected) | None, _) => alarm(
                "VEST DISCONNECTED: no vest link. Cues cannot reach the wearer. Connect the vest in the Vest \
                 panel."
                    .to_owned(),
            ),
        }
    }

    fn gps_banner(&self, now: Instant) -> Option<Banner> {
        let line = |severity, text: String| Some(Banner::new(BannerSubject::Gps, severity, text));
        let advice = "Check the receiver's link and its view of the sky.";
        match self.gps_alarm(now) {
            Some(GpsAlarm::Lost { reason }) => line(
                Severity::Alarm,
                format!("GPS FIX LOST: {reason}. No position: guidance cannot steer the wearer. {advice}"),
            ),
            Some(GpsAlarm::Stale { age_s }) => line(
                Severity::Warning,
                format!("GPS STALE: last position {age_s:.0} s old. Cues hold until a fresh fix. {advice}"),
            ),
            None if !self.gps_connected() || self.station.gps.state.is_none() => line(
                Severity::Alarm,
                match &self.station.gps.state {
                    // The source could not start (a missing replay file, a port that is not there): say which.
                    Some(SourceState::Lost { reason }) => format!(
                        "GPS NOT CONNECTED: {reason}. Guidance has no position. Pick another source in the GPS \
                         panel, or fix this one and connect again."
                    ),
                    _ => {
                        "GPS DISCONNECTED: no GPS source. Guidance has no position. Pick a source in the GPS \
                          panel and connect it."
                            .to_owned()
                    }
                },
            ),
            // A replay at the end of its file: its own state, not a lost fix (no alarm, no bell).
            None if self.station.gps.state == Some(SourceState::Finished) => line(
                Severity::Notice,
                "SOURCE FINISHED: the GPS source reached its end; guidance has no new position. Restart it \
                 (or tick Loop) in the GPS panel, or pick another source."
                    .to_owned(),
            ),
            None if self.station.gps.last_position.is_none()
                && !matches!(self.station.gps.state, Some(SourceState::Finished | SourceState::Stopped)) =>
            {
                line(
                    Severity::Warning,
                    format!("GPS NO FIX YET: no position received. Guidance waits for one. {advice}"),
                )
            }
            None => None,
        }
    }

    fn guidance_banner(&self, now: Instant) -> Option<Banner> {
        let line = |severity, text: String| Some(Banner::new(BannerSubject::Guidance, severity, text));
        if let Some(why) = &self.station.vest.halted {
            return line(
                Severity::Alarm,
                format!(
                    "GUIDANCE HALTED: {why}. No automatic cues. Press Resume automatic cues when it is safe."
                ),
            );
        }
        if !self.cfg.guidance_auto {
            return line(
                Severity::Notice,
                "GUIDANCE MANUAL: automatic cues are off; only tactors fired by hand reach the wearer. Tick \
                 Automatic cues in the Guidance panel to guide."
                    .to_owned(),
            );
        }
        let st = self.station.guidance.as_ref();
        let hold = if !self.station.vest.is_live() {
            "no vest. The wearer gets no cues until the vest link is back.".to_owned()
        } else if self.gps_alarm(now).is_some() || self.station.gps.last_position.is_none() {
            "no fix. No directional cues without a current position.".to_owned()
        } else if let Some(p) = self.station.pinned(now) {
            // Not "the wearer stands still": the receiver holds its position (cause from its stream).
            p.text()
        } else if let Some(h) = st.and_then(|s| s.hold.as_ref()) {
            format!("{h}.")
        } else if st.is_some_and(|s| s.heading_source == HeadingSource::None && !s.finished) {
            "no heading. The wearer stands still and no compass is in use: ask them to walk a few steps, \
             or connect the vest's compass."
                .to_owned()
        } else if let Some(s) = st.filter(|s| s.state == NavState::Hold) {
            format!("{}.", s.reason)
        } else {
            return None;
        };
        line(Severity::Alarm, format!("GUIDANCE ON HOLD: {hold}"))
    }

    fn banner_strip(&mut self, ui: &mut egui::Ui, banners: &[Banner], anim_s: f64) {
        let pt = if self.cfg.large_text { BANNER_PT_LARGE } else { BANNER_PT };
        ui.add_space(2.0);
        if banners.is_empty() {
            ui.label(
                RichText::new(
                    "No alarms: the vest, the GPS and guidance report nothing the operator must act on.",
                )
                .size(pt * 0.8)
                .weak(),
            );
        }
        let mut dismiss = None;
        let mut resume = false;
        for b in banners {
            let (fill, text) = match b.severity {
                Severity::Alarm => (Color32::from_rgb(190, 20, 20), Color32::WHITE),
                Severity::Warning => (Color32::from_rgb(245, 165, 0), Color32::BLACK),
                Severity::Notice => (Color32::from_rgb(25, 75, 165), Color32::WHITE),
            };
            // The GPS alarm blinks until the operator silences it (it re-arms on the next good fix); the
            // text stays either way.
            let alarm = b.subject == BannerSubject::Gps && b.severity != Severity::Notice;
            let stop = b.subject == BannerSubject::Stop;
            let blink = ((alarm && !self.station.gps.alarm_silenced) || stop) && anim_s.fract() < 0.5;
            egui::Frame::new()
                .fill(if blink { fill.gamma_multiply(0.8) } else { fill })
                .inner_margin(egui::Margin::symmetric(10, 5))
                .show(ui, |ui| {
                    ui.set_width(ui.available_width());
                    ui.horizontal(|ui| {
                        if alarm
                            && !self.station.gps.alarm_silenced
                            && ui.button(RichText::new("Silence alarm").size(pt * 0.8)).clicked()
                        {
                            self.station.gps.alarm_silenced = true;
                        }
                        if let BannerSubject::Notice(k) = b.subject
                            && ui.button(RichText::new("Dismiss").size(pt * 0.8)).clicked()
                        {
                            dismiss = Some(k);
                        }
                        if b.subject == BannerSubject::Guidance
                            && self.station.vest.halted.is_some()
                            && ui.button(RichText::new("Resume automatic cues").size(pt * 0.8)).clicked()
                        {
                            resume = true;
                        }
                        if stop {
                            crate::vest_panel::mini_grid(ui, self.station.vest.tactors_on, pt);
                        }
                        ui.add(egui::Label::new(RichText::new(&b.text).size(pt).strong().color(text)).wrap());
                    });
                });
            ui.add_space(2.0);
        }
        if let Some(k) = dismiss {
            self.station.notices.dismiss(k);
        }
        if resume {
            self.resume_guidance();
        }
        let blinking = banners.iter().any(|b| b.subject == BannerSubject::Stop)
            || (banners.iter().any(|b| b.subject == BannerSubject::Gps) && !self.station.gps.alarm_silenced);
        if blinking {
            // A 1 Hz blink: two frames a second while an alarm is up, not four.
            ui.ctx().request_repaint_after(Duration::from_millis(500));
        }
    }

    /// The settings of a route with a path: how far off it and for how long before a re-route.
    fn path_settings_ui(&mut self, ui: &mut egui::Ui) {
        if self.station.route().path().is_some() {
            use vestnav_station::command::ranges;
            ui.add(
                egui::Slider::new(&mut self.cfg.off_path_m, ranges::OFF_PATH_M)
                    .suffix(" m")
                    .text("Off the path"),
            )
            .on_hover_text("farther than this from the planned path counts as off it");
            ui.add(
                egui::Slider::new(&mut self.cfg.reroute_after_s, ranges::REROUTE_AFTER_S)
                    .suffix(" s")
                    .text("Re-route after"),
            )
            .on_hover_text("off the path this long: plan again from where the wearer is");
        }
    }

    /// How long the wearer has been off the path, and the last re-route.
    fn path_status_ui(&self, ui: &mut egui::Ui, off_path_s: Option<f64>) {
        if let Some(off_s) = off_path_s {
            ui.label(
                RichText::new(format!(
                    "off the path for {off_s:.0} s (re-route after {:.0} s)",
                    self.cfg.reroute_after_s
                ))
                .color(Color32::from_rgb(230, 150, 0)),
            );
        }
        if let Some(line) = self.station.reroute_line() {
            ui.label(line);
        }
    }

    fn guidance_ui(&mut self, ui: &mut egui::Ui) {
        if let Some(why) = self.station.vest.halted.clone() {
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
        self.path_settings_ui(ui);
        match &self.station.guidance {
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
                ui.label(RichText::new(format!("Cue: {cue} ({sent}) · {}", st.state.name())).strong());
                ui.label(&st.reason);
                let n = |v: Option<f64>, u: &str| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.0}{u}"));
                ui.label(format!(
                    "distance {} · bearing error {} · cross-track{} {} · heading from {}",
                    n(st.distance_m, " m"),
                    n(st.bearing_error_deg, "°"),
                    if self.station.route().path().is_some() { " from the path" } else { "" },
                    st.cross_track_m.map_or_else(|| "—".to_owned(), |x| format!("{x:+.1} m")),
                    st.heading_source.name()
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
                self.path_status_ui(ui, st.off_path_s);
                if st.finished {
                    ui.label(RichText::new("Route finished").color(Color32::from_rgb(40, 160, 60)));
                }
            }
        }
        ui.horizontal(|ui| {
            let next = self.station.route().next();
            if ui.button("< Previous waypoint").clicked() && next > 0 {
                self.station.route_mut().set_next(next - 1);
            }
            if ui.button("Next waypoint >").clicked() {
                self.station.route_mut().set_next(next + 1);
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

/// Text sizes [pt] of the normal and the large-text option: large makes body text 18 pt and nothing
/// smaller than 14 pt.
fn text_styles(large: bool) -> std::collections::BTreeMap<egui::TextStyle, egui::FontId> {
    use egui::{FontFamily, FontId, TextStyle};
    if !large {
        return egui::style::default_text_styles();
    }
    [
        (TextStyle::Small, FontId::new(14.0, FontFamily::Proportional)),
        (TextStyle::Body, FontId::new(18.0, FontFamily::Proportional)),
        (TextStyle::Button, FontId::new(18.0, FontFamily::Proportional)),
        (TextStyle::Heading, FontId::new(24.0, FontFamily::Proportional)),
        (TextStyle::Monospace, FontId::new(17.0, FontFamily::Monospace)),
    ]
    .into()
}

/// A light theme for sunlight: black text on white, dark outlines, darker warning and error colours.
pub fn high_contrast_light() -> egui::Visuals {
    let mut v = egui::Visuals::light();
    let black = Color32::BLACK;
    v.panel_fill = Color32::WHITE;
    v.window_fill = Color32::WHITE;
    v.extreme_bg_color = Color32::WHITE;
    v.faint_bg_color = Color32::from_gray(232);
    v.weak_text_color = Some(Color32::from_gray(60));
    v.warn_fg_color = Color32::from_rgb(170, 70, 0);
    v.error_fg_color = Color32::from_rgb(180, 0, 0);
    v.hyperlink_color = Color32::from_rgb(0, 50, 170);
    v.window_stroke = egui::Stroke::new(1.0, black);
    for w in [
        &mut v.widgets.noninteractive,
        &mut v.widgets.inactive,
        &mut v.widgets.hovered,
        &mut v.widgets.active,
        &mut v.widgets.open,
    ] {
        w.fg_stroke.color = black;
    }
    v.widgets.noninteractive.bg_stroke = egui::Stroke::new(1.0, Color32::from_gray(90));
    v.widgets.inactive.bg_stroke = egui::Stroke::new(1.0, Color32::from_gray(40));
    v.widgets.inactive.bg_fill = Color32::from_gray(215);
    v.widgets.inactive.weak_bg_fill = Color32::from_gray(215);
    v
}

/// Applies the theme and text size of `cfg` to the context (popups, the next frames) and to this frame's
/// root `ui`, each frame; the context is only written when it differs.
fn apply_theme(ui: &mut egui::Ui, cfg: &Config) {
    let ctx = ui.ctx().clone();
    let theme = if cfg.light_theme { egui::Theme::Light } else { egui::Theme::Dark };
    if ctx.theme() != theme {
        ctx.set_theme(theme);
    }
    let visuals = if cfg.light_theme { high_contrast_light() } else { egui::Visuals::dark() };
    let sizes = text_styles(cfg.large_text);
    let current = ctx.style_of(theme);
    if current.visuals != visuals || current.text_styles != sizes {
        ctx.style_mut_of(theme, |s| {
            s.visuals = visuals;
            s.text_styles = sizes;
        });
    }
    let style = ctx.style_of(theme);
    if **ui.style() != *style {
        ui.set_style(style);
    }
}
