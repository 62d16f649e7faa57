//! The GPS panel: source picker, connection, replay controls, the fix in numbers, sky plot, signal bars,
//! alarm, the raw sentence monitor and the Record toggle.

use std::collections::VecDeque;
use std::path::PathBuf;

use std::time::Instant;

use egui::{Color32, RichText, Stroke, vec2};
use vestnav_device::gps::record::{RecordingStatus, RecordingTap, new_recording_path};
use vestnav_device::gps::{Constellation, Fix, FixMode, RawLine, ReplayProgress, Satellite, SourceState};
use vestnav_device::heading::{Attitude, HeadingOrigin, HeadingReference};
use vestnav_device::serial::{PortInfo, PortKind};

use vestnav_station::{GpsAlarm, Station};

use crate::config::{Config, GpsSourceConfig, ReplaySpeed};
use crate::file_dialog::RecentKind;
use crate::gps_receiver::ReceiverUi;

/// The GPS panel's own widget state (what it shows comes from the station).
#[derive(Debug, Default)]
pub struct GpsUi {
    /// Editor state of the source picker.
    pub picker: SourcePicker,
    /// The raw sentence monitor (the last sentences received).
    pub monitor: RawMonitor,
    /// The Record toggle: the source's sentences to a file (kept across reconnections).
    pub recording: RecordUi,
    /// The Receiver section: the configuration to send and the last run's outcomes (kept across
    /// reconnections).
    pub receiver: ReceiverUi,
    /// A replay starts again at the end of its file (kept across reconnections).
    pub loop_replay: bool,
    /// The RTK (NTRIP) window.
    pub ntrip: crate::ntrip_panel::NtripUi,
}

impl GpsUi {
    /// The state for the configured GPS `source` (the picker shows it).
    pub fn from_config(source: &GpsSourceConfig) -> Self {
        Self { picker: SourcePicker::from_config(source), ..Self::default() }
    }
}

/// (Re)connects the GPS `station` runs to the source configured in `cfg`, with the panel's recording tap
/// (it records whatever source runs and outlives the connection, like the picker) and an emptied monitor. A
/// replay file that connects goes into the recent files.
pub fn connect(station: &mut Station, cfg: &mut Config, gps_ui: &mut GpsUi) {
    station.set_gps_source(cfg.gps.clone());
    let taps = vec![gps_ui.recording.tap.outbox()];
    gps_ui.monitor = gps_ui.monitor.emptied();
    station.connect_gps(taps);
    if let Some(ctl) = station.gps_worker().and_then(vestnav_station::devices::GpsWorker::replay_control) {
        ctl.set_looped(gps_ui.loop_replay);
    }
    if station.gps_connected()
        && let GpsSourceConfig::Replay { path, .. } = &cfg.gps
    {
        // Relative replay paths are ignored by the list (it holds absolute paths only).
        cfg.recent.push(RecentKind::Nmea, path);
    }
}

/// Baud rates offered (the BT-359 talks 4800 by default); `None` = automatic detection.
pub const BAUDS: [Option<u32>; 7] =
    [None, Some(4800), Some(9600), Some(19200), Some(38400), Some(57600), Some(115_200)];

/// Which source kind the picker shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceKind {
    /// Built-in simulator.
    #[default]
    Simulator,
    /// Serial / Bluetooth port.
    Serial,
    /// NMEA log replay.
    Replay,
    /// gpsd over TCP.
    Gpsd,
    /// The receiver forwarded by the vest unit.
    ThroughVest,
}

/// The replay file's dialog: an NMEA log (gpsd's `.log`, our recordings' `.nmea`) or any file.
const NMEA_OPEN: crate::file_dialog::DialogSpec = crate::file_dialog::DialogSpec {
    mode: crate::file_dialog::Mode::Open,
    title: "Replay an NMEA log",
    filter: ("NMEA logs", &["nmea", "log", "txt"]),
};

/// The editable fields of the source picker (kept while the operator switches kinds).
#[derive(Debug, Clone, Default)]
pub struct SourcePicker {
    /// Kind shown.
    pub kind: SourceKind,
    /// Serial port.
    pub port: String,
    /// Baud, `None` = auto.
    pub baud: Option<u32>,
    /// Replay file.
    pub replay_path: String,
    /// Replay speed factor (0 = as fast as possible).
    pub replay_speed: f64,
    /// gpsd host.
    pub gpsd_host: String,
    /// gpsd port.
    pub gpsd_port: u16,
    /// Baud of the receiver on the vest unit's UART.
    pub vest_gps_baud: u32,
    /// Ports found by the last scan.
    pub ports: Vec<PortInfo>,
    /// The replay file's "Browse…" dialog.
    pub replay_browse: crate::file_dialog::Browse,
    /// A port scan was done.
    pub scanned: bool,
}

impl SourcePicker {
    /// The picker showing `cfg`.
    pub fn from_config(cfg: &GpsSourceConfig) -> Self {
        let mut p = Self {
            replay_speed: 1.0,
            gpsd_host: "127.0.0.1".into(),
            gpsd_port: 2947,
            vest_gps_baud: 9600,
            ..Self::default()
        };
        match cfg {
            GpsSourceConfig::Simulator { .. } => p.kind = SourceKind::Simulator,
            GpsSourceConfig::Serial { port, baud } => {
                p.kind = SourceKind::Serial;
                p.port.clone_from(port);
                p.baud = *baud;
            }
            GpsSourceConfig::Replay { path, speed } => {
                p.kind = SourceKind::Replay;
                p.replay_path = path.display().to_string();
                p.replay_speed = speed.factor();
            }
            GpsSourceConfig::Gpsd { host, port } => {
                p.kind = SourceKind::Gpsd;
                p.gpsd_host.clone_from(host);
                p.gpsd_port = *port;
            }
            GpsSourceConfig::ThroughVest { baud } => {
                p.kind = SourceKind::ThroughVest;
                p.vest_gps_baud = *baud;
            }
        }
        p
    }

    /// The source the picker describes, or why it is incomplete. A relative replay file is taken in `base`
    /// (the last file's folder, else the documents folder), never in the working directory.
    pub fn to_config(&self, base: &std::path::Path) -> Result<GpsSourceConfig, String> {
        match self.kind {
            SourceKind::Simulator => Ok(GpsSourceConfig::default()),
            SourceKind::Serial if self.port.trim().is_empty() => Err("pick a serial port".into()),
            SourceKind::Serial => {
                Ok(GpsSourceConfig::Serial { port: self.port.trim().to_owned(), baud: self.baud })
            }
            SourceKind::Replay if self.replay_path.trim().is_empty() => Err("enter an NMEA file".into()),
            SourceKind::Replay => Ok(GpsSourceConfig::Replay {
                path: crate::file_dialog::resolve(&self.replay_path, base)
                    .unwrap_or_else(|| PathBuf::from(self.replay_path.trim())),
                speed: ReplaySpeed::from_factor(self.replay_speed).map_err(|e| e.to_string())?,
            }),
            SourceKind::Gpsd if self.gpsd_host.trim().is_empty() => Err("enter the gpsd host".into()),
            SourceKind::Gpsd => {
                Ok(GpsSourceConfig::Gpsd { host: self.gpsd_host.trim().to_owned(), port: self.gpsd_port })
            }
            SourceKind::ThroughVest => Ok(GpsSourceConfig::ThroughVest { baud: self.vest_gps_baud }),
        }
    }
}

/// Sentences the raw monitor keeps (older ones are dropped).
pub const MONITOR_LINES: usize = 500;

/// One sentence in the raw monitor.
#[derive(Debug, Clone, PartialEq)]
pub struct MonitorLine {
    /// When its bytes arrived (wall clock, local time).
    pub at: chrono::DateTime<chrono::Local>,
    /// The sentence as received.
    pub text: String,
}

/// The raw sentence monitor: the last [`MONITOR_LINES`] sentences, pausable, filtered by talker or type.
#[derive(Debug, Clone, Default)]
pub struct RawMonitor {
    /// The sentences kept, oldest first.
    pub lines: VecDeque<MonitorLine>,
    /// Frozen: new sentences are counted, not kept.
    pub paused: bool,
    /// Shown only: sentences whose tag (`GPGGA` of `$GPGGA,...`) contains this, ignoring case.
    pub filter: String,
    /// Sentences that arrived while paused.
    pub missed: u64,
    /// The monitor (and the recording folder) is shown.
    pub open: bool,
}

impl RawMonitor {
    /// The same settings (pause, filter) with no lines: for a new source.
    #[must_use]
    pub fn emptied(&self) -> Self {
        Self { paused: self.paused, filter: self.filter.clone(), open: self.open, ..Self::default() }
    }

    /// Keeps `line` (unless paused); `now` is the instant its arrival time is measured from.
    pub fn push(&mut self, line: RawLine, now: Instant) {
        if self.paused {
            self.missed += 1;
            return;
        }
        let ago =
            chrono::Duration::from_std(now.saturating_duration_since(line.received_at)).unwrap_or_default();
        self.lines.push_back(MonitorLine { at: chrono::Local::now() - ago, text: line.text });
        while self.lines.len() > MONITOR_LINES {
            self.lines.pop_front();
        }
    }

    /// Whether `text` passes the filter: its tag (talker and type, e.g. `GPGGA`) contains the filter.
    pub fn shows(&self, text: &str) -> bool {
        let f = self.filter.trim();
        if f.is_empty() {
            return true;
        }
        let tag = text.trim_start_matches(['$', '!']).split([',', '*']).next().unwrap_or("");
        tag.to_ascii_uppercase().contains(&f.to_ascii_uppercase())
    }

    /// The lines shown, oldest first.
    pub fn visible(&self) -> impl Iterator<Item = &MonitorLine> {
        self.lines.iter().filter(|l| self.shows(&l.text))
    }
}

/// The Record toggle's state: the tap on the source's sentences, the folder new recordings go to, and
/// the last error.
#[derive(Debug, Clone)]
pub struct RecordUi {
    /// Records the running source's sentences (one more consumer of its events).
    pub tap: RecordingTap,
    /// Folder of new recordings (each gets a new timestamped name).
    pub folder: String,
    /// Why the last Record failed to start.
    pub error: Option<String>,
}

impl Default for RecordUi {
    fn default() -> Self {
        Self {
            tap: RecordingTap::default(),
            folder: default_recording_folder().display().to_string(),
            error: None,
        }
    }
}

/// Where recordings go by default: `recordings/` in the user's data directory (on Linux
/// `~/.local/share/vestnav/recordings`), else in the documents folder, else the current directory.
pub fn default_recording_folder() -> PathBuf {
    if let Some(p) = directories::ProjectDirs::from("org", "vestnav", "vestnav") {
        return p.data_dir().join("recordings");
    }
    directories::UserDirs::new()
        .and_then(|u| u.document_dir().map(|d| d.join("vestnav-recordings")))
        .unwrap_or_else(|| PathBuf::from("."))
}

impl RecordUi {
    /// Starts a recording in a new file in the folder (created if missing); the error names the file.
    pub fn start(&mut self) {
        let folder = PathBuf::from(self.folder.trim());
        if let Err(e) = std::fs::create_dir_all(&folder) {
            self.error = Some(format!("{}: {e}", folder.display()));
            return;
        }
        let path = new_recording_path(&folder, chrono::Local::now());
        self.error = self.tap.start(&path).err();
    }

    /// The status line: file, sentences and bytes written, error.
    pub fn status_text(status: &RecordingStatus) -> String {
        let what = if status.active { "recording" } else { "recorded" };
        let mut text = format!(
            "{what} {}: {} sentences, {} bytes",
            status.path.display(),
            status.sentences,
            status.bytes
        );
        if let Some(e) = &status.error {
            text += " (stopped: ";
            text += e;
            text.push(')');
        }
        text
    }
}

/// `ms` as `m:ss`.
pub fn clock_text(ms: u64) -> String {
    format!("{}:{:02}", ms / 60_000, (ms % 60_000) / 1000)
}

/// The replay's position in words: `1:05 / 10:00 (12 / 340 kB)`.
pub fn replay_progress_text(p: &ReplayProgress) -> String {
    format!(
        "{} / {} ({} / {} kB)",
        clock_text(p.position_ms),
        clock_text(p.span_ms),
        p.position_bytes / 1000,
        p.total_bytes / 1000
    )
}

/// Degrees as `42° 21' 22.32" N`.
pub fn dms(value_deg: f64, pos: char, neg: char) -> String {
    let hemi = if value_deg < 0.0 { neg } else { pos };
    let total_s = (value_deg.abs() * 3600.0 * 100.0).round() / 100.0;
    let d = (total_s / 3600.0).floor();
    let m = ((total_s - d * 3600.0) / 60.0).floor();
    let s = total_s - d * 3600.0 - m * 60.0;
    format!("{d:.0}° {m:02.0}' {s:05.2}\" {hemi}")
}

pub use vestnav_station::source_state_label as state_label;

/// Whether the epoch shown is current, or only the last one known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Freshness {
    /// The source is running and the epoch's bytes arrived at most `stale_after_s` ago.
    Current,
    /// Anything else: the link is lost or closed, or the epoch is older than the stale limit (or its arrival
    /// time is unknown). Mode, satellites and signal describe the sky of `age_s` ago, not now.
    LastKnown {
        /// Age of the epoch [s] (`None`: unknown).
        age_s: Option<f64>,
    },
}

/// The freshness of epoch `fix` at `now`, from its arrival instant and the source's state alone (never
/// from what was shown before): current only while `source_running` and the epoch is at most
/// `stale_after_s` old — the limit at which the GPS alarm calls the fix stale.
pub fn freshness(fix: &Fix, source_running: bool, now: Instant, stale_after_s: f64) -> Freshness {
    let age_s = fix.age(now).map(|a| a.as_secs_f64());
    if source_running && age_s.is_some_and(|a| a <= stale_after_s) {
        Freshness::Current
    } else {
        Freshness::LastKnown { age_s }
    }
}

/// Draws the GPS section: what `station` reports of the GPS and the commands to it, the settings in `cfg` it
/// edits, and its own state `gps_ui`; `now` is the clock fix ages are measured on.
pub fn show(station: &mut Station, cfg: &mut Config, gps_ui: &mut GpsUi, ui: &mut egui::Ui, now: Instant) {
    let base = cfg.recent.base();
    picker_ui(cfg, gps_ui, ui, &base);
    ui.horizontal_wrapped(|ui| {
        let connected = station.gps_connected();
        if ui.add_enabled(!connected, egui::Button::new("Connect GPS")).clicked() {
            match gps_ui.picker.to_config(&cfg.recent.base()) {
                Ok(src) => {
                    cfg.gps = src;
                    connect(station, cfg, gps_ui);
                }
                Err(e) => station.notices.raise(
                    vestnav_station::Severity::Warning,
                    vestnav_station::Subject::Gps,
                    format!("GPS: {e}"),
                ),
            }
        }
        if ui.add_enabled(connected, egui::Button::new("Disconnect GPS")).clicked() {
            station.disconnect_gps();
        }
        ui.label(RichText::new(state_label(station.gps.state.as_ref())).strong());
        // Both on the connect row: closed, the monitor and the recording take no room above the vest grid.
        record_toggle(gps_ui, ui);
        ui.toggle_value(&mut gps_ui.monitor.open, "NMEA monitor");
        ui.toggle_value(&mut gps_ui.receiver.open, "Receiver")
            .on_hover_text(
                "Configure the receiver: rate, constellations, dynamic model, static hold; RTK corrections (NTRIP)",
            );
    });
    if let Some(n) = &station.gps.notice {
        ui.label(RichText::new(n).small().weak());
    }
    crate::ntrip_panel::status_ui(station, ui, now);
    pinned_ui(station, cfg, gps_ui, ui, now);
    replay_ui(station, cfg, gps_ui, ui);
    record_ui(gps_ui, ui);
    monitor_ui(gps_ui, ui);

    // The alarm itself (state, what to do, "Silence alarm") is the banner strip's GPS line.
    let alarm = station.gps_alarm(now);

    if let Some(a) = &station.gps.attitude {
        let (text, stale) = attitude_line(a, now, cfg.stale_after_s);
        // Stale like a stale fix: the same limit and the same orange.
        let color = if stale { Color32::from_rgb(220, 140, 0) } else { ui.visuals().text_color() };
        ui.label(RichText::new(text).color(color));
    }

    let Some(fix) = station.gps.fix.clone() else {
        ui.label("no fix yet");
        return;
    };
    let age = station.position_age(now).map(|a| a.as_secs_f64());
    let running =
        station.gps_connected() && !matches!(station.gps.state, None | Some(SourceState::Lost { .. }));
    let fresh = freshness(&fix, running, now, cfg.stale_after_s);
    if let Freshness::LastKnown { age_s } = fresh {
        let what = if matches!(alarm, Some(GpsAlarm::Lost { .. })) { "FIX LOST" } else { "NOT CURRENT" };
        ui.label(
            RichText::new(format!(
                "{what}: showing the last known fix, {}",
                crate::map_panel::age_text(age_s)
            ))
            .strong()
            .color(ui.visuals().warn_fg_color),
        );
    } else {
        // The same line, saying the fix is current, so the panel keeps its height when the fix ages.
        ui.label(RichText::new("CURRENT fix").strong());
    }
    fix_grid(ui, &fix, age, station.gps.fixes, fresh);
    if let Some(st) = &station.gps.stats {
        ui.label(
            RichText::new(format!(
                "{} sentences, {} epochs, {} rejected ({} bad checksums)",
                st.sentences,
                st.epochs,
                st.rejected(),
                st.bad_checksum
            ))
            .small(),
        );
    }
    if !fix.satellites.is_empty() {
        let grey = matches!(fresh, Freshness::LastKnown { .. });
        // 110 points high: with the connect row's toggles on a second line at the side panel's 360 points,
        // the vest grid still sits above the fold of a 1400x880 window.
        ui.horizontal(|ui| {
            sky_plot(ui, &fix.satellites, SKY_HEIGHT_PT, grey);
            signal_bars(ui, &fix.satellites, vec2(170.0, SKY_HEIGHT_PT), grey);
        });
        if let Freshness::LastKnown { age_s } = fresh {
            ui.label(
                RichText::new(format!("sky and signal: last known, {}", crate::map_panel::age_text(age_s)))
                    .weak(),
            );
        }
        satellite_table(ui, &fix.satellites, fresh, &mut cfg.show_satellite_table);
    }
}

/// The pinned-receiver diagnosis (cause named from the stream's family) with its one-click fix through
/// the receiver configuration path; the outcome shows in the Receiver window's log.
fn pinned_ui(station: &Station, cfg: &Config, gps_ui: &mut GpsUi, ui: &mut egui::Ui, now: Instant) {
    let Some(p) = station.pinned(now) else { return };
    ui.label(RichText::new(p.text()).strong().color(ui.visuals().warn_fg_color));
    let Some(remedy) = p.remedy() else { return };
    let label = if remedy.sirf_static_nav.is_some() { "Static navigation off" } else { "Static hold off" };
    let available = crate::gps_receiver::availability(station, &cfg.gps);
    let busy = gps_ui.receiver.ticket.is_some();
    let b = ui.add_enabled(available.is_ok() && !busy, egui::Button::new(label));
    let b = match &available {
        Err(why) => b.on_disabled_hover_text(why),
        Ok(()) => b,
    };
    if b.clicked() {
        gps_ui.receiver.send(station, remedy);
        gps_ui.receiver.open = true;
    }
}

/// Pause/resume, Loop, the seek bar and elapsed/total time of a replay source; at the end of the file
/// "Replay finished" with **Restart** (its own state: no stale or lost-fix alarm).
fn replay_ui(station: &mut Station, cfg: &mut Config, gps_ui: &mut GpsUi, ui: &mut egui::Ui) {
    let Some(ctl) = station.gps_worker().and_then(vestnav_station::devices::GpsWorker::replay_control) else {
        return;
    };
    let progress = ctl.progress();
    if station.gps.state == Some(SourceState::Finished) {
        let mut restart = false;
        ui.horizontal(|ui| {
            let name = match &cfg.gps {
                GpsSourceConfig::Replay { path, .. } => path.display().to_string(),
                _ => "the file".to_owned(),
            };
            ui.label(RichText::new(format!("Replay finished: the end of {name}")).strong());
            restart = ui.button("Restart").clicked();
            ui.checkbox(&mut gps_ui.loop_replay, "Loop");
        });
        if restart {
            connect(station, cfg, gps_ui);
        }
        return;
    }
    ui.horizontal(|ui| {
        if ui.checkbox(&mut gps_ui.loop_replay, "Loop").changed() {
            ctl.set_looped(gps_ui.loop_replay);
        }
        let paused = ctl.is_paused();
        if ui.button(if paused { "Resume replay" } else { "Pause replay" }).clicked() {
            ctl.set_paused(!paused);
        }
        let mut fraction = progress.fraction();
        let bar = ui.add(
            egui::Slider::new(&mut fraction, 0.0..=1.0)
                .show_value(false)
                .text(replay_progress_text(&progress)),
        );
        // Seek once the operator lets go (or clicks), not at every pixel of a drag.
        if bar.drag_stopped() || (bar.changed() && !bar.dragged()) {
            ctl.seek_fraction(fraction);
        }
    });
    if progress.position_bytes < progress.total_bytes || ctl.is_paused() {
        ui.ctx().request_repaint_after(std::time::Duration::from_millis(250));
    }
}

/// The Record toggle.
fn record_toggle(gps_ui: &mut GpsUi, ui: &mut egui::Ui) {
    let r = &mut gps_ui.recording;
    let recording = r.tap.is_recording();
    let mut on = recording;
    if ui.toggle_value(&mut on, if recording { "Stop recording" } else { "Record NMEA" }).changed() {
        if on {
            r.start();
        } else {
            r.tap.stop();
        }
    }
}

/// The recording's folder (with the monitor open), the file being written, sentences and bytes, the error.
fn record_ui(gps_ui: &mut GpsUi, ui: &mut egui::Ui) {
    let open = gps_ui.monitor.open;
    let r = &mut gps_ui.recording;
    let recording = r.tap.is_recording();
    if open {
        ui.horizontal(|ui| {
            let label = ui.label("Folder");
            ui.add_enabled(!recording, egui::TextEdit::singleline(&mut r.folder).desired_width(220.0))
                .labelled_by(label.id);
        });
    }
    if let Some(e) = &r.error {
        ui.label(RichText::new(format!("cannot record: {e}")).color(ui.visuals().error_fg_color));
    }
    if let Some(st) = r.tap.status() {
        let color = if st.error.is_some() { ui.visuals().error_fg_color } else { ui.visuals().text_color() };
        ui.label(RichText::new(RecordUi::status_text(&st)).small().color(color));
        if st.active {
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(500));
        }
    }
}

/// The raw sentence monitor: the last sentences with their arrival time, pausable, filtered.
fn monitor_ui(gps_ui: &mut GpsUi, ui: &mut egui::Ui) {
    let m = &mut gps_ui.monitor;
    if !m.open {
        return;
    }
    ui.group(|ui| {
        ui.label(RichText::new(format!("NMEA monitor: last {} sentences", m.lines.len())).strong());
        ui.horizontal(|ui| {
            let label = if m.paused { "Resume monitor" } else { "Pause monitor" };
            ui.toggle_value(&mut m.paused, label);
            let label = ui.label("Filter");
            ui.add(egui::TextEdit::singleline(&mut m.filter).hint_text("e.g. GGA").desired_width(80.0))
                .labelled_by(label.id);
            if ui.button("Clear").clicked() {
                m.lines.clear();
                m.missed = 0;
            }
            if m.paused && m.missed > 0 {
                ui.label(RichText::new(format!("{} not shown (paused)", m.missed)).small().weak());
            }
        });
        // Body-size monospace, one sentence a line: a long sentence scrolls sideways instead of wrapping
        // into a column of fragments.
        egui::ScrollArea::both()
            .max_height(220.0)
            .stick_to_bottom(!m.paused)
            .auto_shrink([false, true])
            .show(ui, |ui| {
                for l in m.visible() {
                    ui.add(
                        egui::Label::new(
                            RichText::new(format!("{}  {}", l.at.format("%H:%M:%S%.3f"), l.text)).monospace(),
                        )
                        .wrap_mode(egui::TextWrapMode::Extend),
                    );
                }
            });
    });
}

/// A constellation's name as receivers' tools show it.
pub fn constellation_name(c: Constellation) -> &'static str {
    match c {
        Constellation::Gps => "GPS",
        Constellation::Sbas => "SBAS",
        Constellation::Glonass => "GLONASS",
        Constellation::Galileo => "Galileo",
        Constellation::Beidou => "BeiDou",
        Constellation::Qzss => "QZSS",
        Constellation::Navic => "NavIC",
        Constellation::Unknown => "?",
    }
}

/// The satellite table as u-center and xgps show it: PRN, constellation, elevation, azimuth, SNR, used;
/// sorted by constellation and PRN. Greyed under a "last known" heading when the epoch is not current.
/// Collapsed at first (its header gives the count): open, it would push the vest grid below the fold. Whether
/// it is open is remembered (`open`, a setting).
fn satellite_table(ui: &mut egui::Ui, sats: &[Satellite], fresh: Freshness, open: &mut bool) {
    let grey = matches!(fresh, Freshness::LastKnown { .. });
    let title = match fresh {
        Freshness::Current => format!("Satellites ({} in view)", sats.len()),
        Freshness::LastKnown { age_s } => {
            format!("Satellites ({} in view, last known, {})", sats.len(), crate::map_panel::age_text(age_s))
        }
    };
    let shown =
        egui::CollapsingHeader::new(title).id_salt("gps-satellites").open(Some(*open)).show(ui, |ui| {
            let mut rows: Vec<&Satellite> = sats.iter().collect();
            rows.sort_by_key(|s| (s.constellation, s.prn));
            let cell = |text: String| if grey { RichText::new(text).weak() } else { RichText::new(text) };
            let deg = |v: Option<f64>| {
                v.filter(|x| x.is_finite()).map_or_else(|| "—".to_owned(), |x| format!("{x:.0}°"))
            };
            egui::Grid::new("gps-satellites-grid").num_columns(6).striped(true).show(ui, |ui| {
                for h in ["PRN", "System", "Elev.", "Azim.", "SNR dB-Hz", "Used"] {
                    ui.label(cell(h.to_owned()).strong());
                }
                ui.end_row();
                for s in rows {
                    ui.label(cell(s.prn.to_string()));
                    ui.label(cell(constellation_name(s.constellation).to_owned()));
                    ui.label(cell(deg(s.elevation_deg)));
                    ui.label(cell(deg(s.azimuth_deg)));
                    let snr = s
                        .snr_dbhz
                        .filter(|x| x.is_finite())
                        .map_or_else(|| "—".to_owned(), |x| format!("{x:.0}"));
                    ui.label(cell(snr).color(snr_color(s.snr_dbhz, true, grey)));
                    ui.label(cell(if s.used { "yes" } else { "no" }.to_owned()));
                    ui.end_row();
                }
            });
        });
    if shown.header_response.clicked() {
        *open = !*open;
    }
}

/// The simulator's option: the route walked, or a wearer steered by the vest.
fn simulator_ui(cfg: &mut Config, ui: &mut egui::Ui) {
    ui.checkbox(&mut cfg.sim_follows_vest, "steered by the vest").on_hover_text(
        "Off: the simulated receiver walks the loaded route at 1.4 m/s with a SiRF-like error model. \
         On, with the emulated vest: the simulated wearer starts at the route's first waypoint, feels the \
         tactors, recognises 92 % of the cues and turns 0.8 s after each (the wearer model of `vestnav nav \
         simulate`), instead of walking the route. Taken when the GPS connects.",
    );
}

fn picker_ui(cfg: &mut Config, gps_ui: &mut GpsUi, ui: &mut egui::Ui, base: &std::path::Path) {
    let p = &mut gps_ui.picker;
    let label = |k: SourceKind| match k {
        SourceKind::Simulator => "Simulator",
        SourceKind::Serial => "Serial / Bluetooth port",
        SourceKind::Replay => "NMEA file replay",
        SourceKind::Gpsd => "gpsd",
        SourceKind::ThroughVest => "Through the vest unit",
    };
    ui.horizontal(|ui| {
        egui::ComboBox::from_label("GPS source").selected_text(label(p.kind)).show_ui(ui, |ui| {
            for k in [
                SourceKind::Simulator,
                SourceKind::Serial,
                SourceKind::Replay,
                SourceKind::Gpsd,
                SourceKind::ThroughVest,
            ] {
                ui.selectable_value(&mut p.kind, k, label(k));
            }
        });
        // The simulator's one option beside it: no row of its own above the vest grid.
        if p.kind == SourceKind::Simulator {
            simulator_ui(cfg, ui);
        }
    });
    match p.kind {
        SourceKind::Simulator => {}
        SourceKind::Serial => {
            if !p.scanned {
                p.ports = vestnav_device::serial::list_ports();
                p.scanned = true;
            }
            ui.horizontal(|ui| {
                let found = ui.label("Found ports");
                egui::ComboBox::from_id_salt("gps-port")
                    .selected_text(if p.port.is_empty() { "pick a port" } else { p.port.as_str() })
                    .show_ui(ui, |ui| {
                        for port in &p.ports {
                            let bt = if port.kind == PortKind::Bluetooth { "[BT] " } else { "" };
                            let text = format!("{bt}{} {}", port.name, port.description);
                            ui.selectable_value(&mut p.port, port.name.clone(), text);
                        }
                        if p.ports.is_empty() {
                            ui.label("no serial ports found");
                        }
                    })
                    .response
                    .labelled_by(found.id);
                if ui.button("Rescan").on_hover_text("Scan ports again").clicked() {
                    p.ports = vestnav_device::serial::list_ports();
                }
            });
            ui.horizontal(|ui| {
                let name = ui.label("Port");
                ui.text_edit_singleline(&mut p.port).labelled_by(name.id);
            });
            egui::ComboBox::from_label("Baud")
                .selected_text(p.baud.map_or_else(|| "auto".to_owned(), |b| b.to_string()))
                .show_ui(ui, |ui| {
                    for b in BAUDS {
                        ui.selectable_value(
                            &mut p.baud,
                            b,
                            b.map_or_else(|| "auto".to_owned(), |b| b.to_string()),
                        );
                    }
                });
        }
        SourceKind::Replay => replay_picker(p, &cfg.recent, ui, base),
        SourceKind::Gpsd => {
            ui.horizontal(|ui| {
                ui.label("Host");
                ui.add(egui::TextEdit::singleline(&mut p.gpsd_host).desired_width(120.0));
                ui.label("Port");
                ui.add(egui::DragValue::new(&mut p.gpsd_port).range(1..=65535));
            });
        }
        SourceKind::ThroughVest => {
            egui::ComboBox::from_label("Receiver baud").selected_text(p.vest_gps_baud.to_string()).show_ui(
                ui,
                |ui| {
                    for b in vestnav_device::wtcu::message::GPS_BAUDS {
                        ui.selectable_value(&mut p.vest_gps_baud, b, b.to_string());
                    }
                },
            );
            ui.label(
                RichText::new(
                    "the receiver wired to the vest unit's second UART, its bytes carried inside the vest's \
                     link (needs a protocol v2 unit with a GPS receiver and a connected vest)",
                )
                .small()
                .weak(),
            );
        }
    }
}

/// The replay source's fields: the NMEA file (typed, Browse…, Recent) and the speed.
fn replay_picker(
    p: &mut SourcePicker,
    recent: &crate::file_dialog::RecentFiles,
    ui: &mut egui::Ui,
    base: &std::path::Path,
) {
    ui.horizontal(|ui| {
        ui.label("NMEA file");
        if let Some(path) = crate::file_dialog::recent_menu(ui, recent, RecentKind::Nmea) {
            p.replay_path = path.display().to_string();
        }
    });
    crate::file_dialog::path_field(
        ui,
        &mut p.replay_path,
        &mut p.replay_browse,
        NMEA_OPEN,
        base,
        "walk.nmea",
    );
    ui.add(
        egui::Slider::new(&mut p.replay_speed, 0.0..=100.0)
            .logarithmic(true)
            .text("speed ×")
            .custom_formatter(|v, _| if v <= 0.0 { "max".into() } else { format!("{v:.1}") }),
    );
}

/// The GPS input's latest heading reading (HDG compass or gpsd ATT) as one line, and whether it is stale
/// (older than `stale_after_s`, the limit a fix goes stale at).
pub fn attitude_line(a: &Attitude, now: Instant, stale_after_s: f64) -> (String, bool) {
    let reference = match a.reference {
        HeadingReference::Magnetic => "magnetic",
        HeadingReference::True => "true",
    };
    let origin = match a.origin {
        HeadingOrigin::Nmea => "NMEA HDG",
        HeadingOrigin::Gpsd => "gpsd ATT",
        HeadingOrigin::Vest => "vest",
    };
    let pitch = a.pitch_deg.map(|p| format!(" · pitch {p:.1}°")).unwrap_or_default();
    let roll = a.roll_deg.map(|r| format!(" · roll {r:.1}°")).unwrap_or_default();
    let age_s = a.age(now).as_secs_f64();
    let stale = age_s > stale_after_s;
    let mark = if stale { " · STALE" } else { "" };
    (
        format!("Heading {:.1}° {reference} ({origin}){pitch}{roll} · {age_s:.1} s ago{mark}", a.heading_deg),
        stale,
    )
}

/// The value of a row describing the receiver's current state: as is while the epoch is current, struck
/// through and greyed with "last known, N s ago" when it is not.
fn live_value(text: String, fresh: Freshness) -> RichText {
    match fresh {
        Freshness::Current => RichText::new(text),
        Freshness::LastKnown { age_s } => {
            RichText::new(format!("{text} (last known, {})", crate::map_panel::age_text(age_s)))
                .strikethrough()
                .weak()
        }
    }
}

fn fix_grid(ui: &mut egui::Ui, f: &Fix, age_s: Option<f64>, fixes: u64, fresh: Freshness) {
    let opt = |v: Option<f64>, unit: &str, prec: usize| {
        v.filter(|x| x.is_finite()).map_or_else(|| "—".to_owned(), |x| format!("{x:.prec$} {unit}"))
    };
    let live = |text: String| live_value(text, fresh);
    egui::Grid::new("gps-fix").num_columns(2).striped(true).show(ui, |ui| {
        if f.has_position()
            && let (Some(lat), Some(lon)) = (f.lat_deg, f.lon_deg)
        {
            ui.label("Latitude");
            ui.label(format!("{lat:.7}°  {}", dms(lat, 'N', 'S')));
            ui.end_row();
            ui.label("Longitude");
            ui.label(format!("{lon:.7}°  {}", dms(lon, 'E', 'W')));
            ui.end_row();
        }
        ui.label("UTC");
        let utc = f
            .time
            .map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true))
            .or_else(|| f.time_of_day.map(|t| t.format("%H:%M:%S%.3f").to_string()));
        ui.label(utc.as_deref().unwrap_or("—"));
        ui.end_row();
        // Related values share a row (two labels each), so the grid stays short enough for the vest grid
        // to sit above the fold.
        ui.label("Fix · satellites");
        let mode = match f.mode {
            None | Some(FixMode::NoFix) => "no fix",
            Some(FixMode::Fix2D) => "2D",
            Some(FixMode::Fix3D) => "3D",
        };
        let quality = f.quality.map_or_else(|| "—".to_owned(), |q| format!("{q:?}"));
        let n = |v: Option<u32>| v.map_or_else(|| "—".to_owned(), |v| v.to_string());
        ui.horizontal(|ui| {
            ui.label(live(format!("{mode} · {quality}")));
            ui.label(live(format!("{} used / {} in view", n(f.sats_used), n(f.sats_visible))));
        });
        ui.end_row();
        ui.label("Position error · DOP");
        // The figure guidance uses, and whose it is: the receiver's own estimate when it sends one. Each
        // number carries its name, so "3.0 m" and the DOPs cannot be read as one "GST 1.0 / 1.8".
        let error = match f.error {
            Some(e) => format!("±{} (from {})", opt(Some(e.horizontal_m), "m", 1), e.source.describe()),
            None => opt(None, "m", 1),
        };
        ui.horizontal(|ui| {
            ui.label(live(error))
                .on_hover_text("Estimated horizontal position error, and where it comes from");
            ui.label(live(format!("HDOP {} · PDOP {}", opt(f.hdop, "", 1), opt(f.pdop, "", 1))))
                .on_hover_text("Dilution of precision: satellite geometry, no unit (lower is better)");
        });
        ui.end_row();
        ui.label("Altitude");
        ui.label(opt(f.alt_m, "m", 1));
        ui.end_row();
        ui.label("Speed · course");
        ui.horizontal(|ui| {
            ui.label(live(opt(f.speed_m_s, "m/s", 2)));
            ui.label(live(opt(f.course_deg, "°", 0)));
        });
        ui.end_row();
        ui.label("Fix age");
        ui.label(format!("{} ({fixes} fixes)", opt(age_s, "s", 1)));
        ui.end_row();
    });
}

/// A satellite's colour by its signal; all grey (`grey`) when the epoch is not current.
fn snr_color(snr: Option<f64>, used: bool, grey: bool) -> Color32 {
    let base = match snr {
        _ if grey => Color32::GRAY,
        Some(s) if s >= 35.0 => Color32::from_rgb(40, 170, 60),
        Some(s) if s >= 25.0 => Color32::from_rgb(200, 170, 30),
        Some(_) => Color32::from_rgb(220, 90, 40),
        None => Color32::GRAY,
    };
    if used { base } else { base.gamma_multiply(0.45) }
}

/// Height of the sky plot and the signal bars [points].
const SKY_HEIGHT_PT: f32 = 110.0;

/// Polar sky plot: north up, elevation 90° at the centre, the horizon on the rim.
fn sky_plot(ui: &mut egui::Ui, sats: &[Satellite], size: f32, grey: bool) {
    let (rect, _) = ui.allocate_exact_size(vec2(size, size), egui::Sense::hover());
    let p = ui.painter_at(rect);
    let c = rect.center();
    let r = size / 2.0 - 10.0;
    let grid = Stroke::new(1.0, ui.visuals().weak_text_color());
    for el in [0.0_f32, 30.0, 60.0] {
        p.circle_stroke(c, r * (90.0 - el) / 90.0, grid);
    }
    p.line_segment([c - vec2(0.0, r), c + vec2(0.0, r)], grid);
    p.line_segment([c - vec2(r, 0.0), c + vec2(r, 0.0)], grid);
    let font = egui::FontId::proportional(10.0);
    p.text(c - vec2(0.0, r + 5.0), egui::Align2::CENTER_CENTER, "N", font.clone(), ui.visuals().text_color());
    for s in sats {
        let (Some(el), Some(az)) = (s.elevation_deg, s.azimuth_deg) else { continue };
        if !(el.is_finite() && az.is_finite()) {
            continue;
        }
        let rr = r * ((90.0 - el.clamp(0.0, 90.0)) / 90.0) as f32;
        let a = (az as f32).to_radians();
        let pos = c + vec2(rr * a.sin(), -rr * a.cos());
        p.circle_filled(pos, 5.0, snr_color(s.snr_dbhz, s.used, grey));
        p.text(
            pos + vec2(0.0, -9.0),
            egui::Align2::CENTER_CENTER,
            s.prn.to_string(),
            font.clone(),
            ui.visuals().text_color(),
        );
    }
}

/// Signal bars: one per satellite, height = C/N0 (0..50 dB-Hz), bright when used.
fn signal_bars(ui: &mut egui::Ui, sats: &[Satellite], size: egui::Vec2, grey: bool) {
    let (rect, _) = ui.allocate_exact_size(size, egui::Sense::hover());
    let p = ui.painter_at(rect);
    let n = sats.len().clamp(1, 24);
    let w = rect.width() / n as f32;
    let font = egui::FontId::proportional(9.0);
    for (i, s) in sats.iter().take(n).enumerate() {
        let h = (rect.height() - 14.0) * (s.snr_dbhz.unwrap_or(0.0).clamp(0.0, 50.0) / 50.0) as f32;
        let x0 = rect.left() + i as f32 * w + 1.0;
        let bottom = rect.bottom() - 12.0;
        p.rect_filled(
            egui::Rect::from_min_max(egui::pos2(x0, bottom - h), egui::pos2(x0 + w - 2.0, bottom)),
            1.0,
            snr_color(s.snr_dbhz, s.used, grey),
        );
        p.text(
            egui::pos2(x0 + w / 2.0, bottom + 6.0),
            egui::Align2::CENTER_CENTER,
            s.prn.to_string(),
            font.clone(),
            ui.visuals().text_color(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dms_formats_hemispheres() {
        // 42.3562° = 42° 21' 22.32"
        assert_eq!(dms(42.3562, 'N', 'S'), "42° 21' 22.32\" N");
        assert_eq!(dms(-71.1, 'E', 'W'), "71° 06' 00.00\" W");
    }

    /// The GPS-side heading line: reference, origin, pitch/roll when given, age, stale past the fix limit.
    #[test]
    fn attitude_line_shows_reference_origin_and_staleness() {
        let t0 = Instant::now();
        let mut a = Attitude {
            heading_deg: 229.8,
            reference: HeadingReference::Magnetic,
            pitch_deg: None,
            roll_deg: None,
            quality_pct: None,
            field_ut: None,
            raw_mag_ut: None,
            origin: HeadingOrigin::Nmea,
            received_at: t0,
        };
        let (text, stale) = attitude_line(&a, t0 + std::time::Duration::from_millis(500), 3.0);
        assert_eq!(text, "Heading 229.8° magnetic (NMEA HDG) · 0.5 s ago");
        assert!(!stale);
        a.reference = HeadingReference::True;
        a.origin = HeadingOrigin::Gpsd;
        a.pitch_deg = Some(2.77);
        a.roll_deg = Some(0.0);
        let (text, stale) = attitude_line(&a, t0 + std::time::Duration::from_secs(4), 3.0);
        assert_eq!(text, "Heading 229.8° true (gpsd ATT) · pitch 2.8° · roll 0.0° · 4.0 s ago · STALE");
        assert!(stale);
    }

    /// Current only while the source runs and the epoch is within the stale limit; the age is the epoch's.
    #[test]
    fn freshness_follows_the_epoch_age_and_the_source() {
        let t0 = Instant::now();
        let f = Fix { received_at: Some(t0), ..Fix::default() };
        let at = |s: f64| t0 + std::time::Duration::from_secs_f64(s);
        assert_eq!(freshness(&f, true, at(2.0), 3.0), Freshness::Current);
        assert_eq!(freshness(&f, true, at(4.0), 3.0), Freshness::LastKnown { age_s: Some(4.0) });
        assert_eq!(freshness(&f, false, at(1.0), 3.0), Freshness::LastKnown { age_s: Some(1.0) });
        let unknown = Fix::default();
        assert_eq!(freshness(&unknown, true, at(0.0), 3.0), Freshness::LastKnown { age_s: None });
    }

    #[test]
    fn picker_round_trips_every_source() {
        for src in [
            GpsSourceConfig::default(),
            GpsSourceConfig::Serial { port: "/dev/rfcomm0".into(), baud: None },
            GpsSourceConfig::Replay { path: "a.nmea".into(), speed: ReplaySpeed::Times(4.0) },
            GpsSourceConfig::Gpsd { host: "h".into(), port: 1234 },
            GpsSourceConfig::ThroughVest { baud: 38_400 },
        ] {
            let base = std::path::Path::new("/data/walks");
            let back = SourcePicker::from_config(&src).to_config(base).unwrap();
            match src {
                // A relative replay file is taken in the base folder, not the working directory.
                GpsSourceConfig::Replay { speed, .. } => {
                    assert_eq!(back, GpsSourceConfig::Replay { path: base.join("a.nmea"), speed });
                }
                src => assert_eq!(back, src),
            }
        }
    }
}
