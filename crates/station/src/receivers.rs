//! Receivers side by side: more GPS sources beside the primary one, in one session. Each comparison source
//! is the same [`GpsSourceConfig`] the primary takes (serial, gpsd, replay, simulator), opened by the same
//! [`DeviceFactory`](crate::devices::DeviceFactory) on a reader thread of its own; its events reach only this
//! comparison (never guidance, which keeps the primary). The station takes every receiver's fixes on the
//! receiver-time line ([`crate::fieldtests::receiver_sample`], the rule `vestnav fieldtest compare` reads its
//! logs by) and compares them with core's one [`compare`] (epochs matched by receiver time with the primary,
//! their horizontal differences, each against the field tests' reference when one is set), at most once a
//! second, on a thread of its own (`receivers-compare`): at the cap of five receivers of [`MAX_SAMPLES`]
//! fixes one comparison takes about 0.4 s (`cargo bench -p vestnav-core --bench accuracy`), which must never
//! be a frame of the view's. The view's turn only hands the fixes over (shared in chunks of 4,096, so at
//! most the newest partial chunk of each receiver is copied) and takes the result back.
//!
//! **Recordings.** While a comparison runs, each receiver's sentences (the primary's too) are recorded next
//! to the session log as `<session log>.rx<k>.nmea` (the recording format of
//! [`vestnav_device::gps::record`]), so `vestnav fieldtest compare` can read the same session afterwards.
//! A gpsd source delivers JSON, not sentences: its recording stays empty, and its status says so.
//!
//! A gpsd source is asked for the device's NMEA sentences beside its JSON (`vestnav_device::gps::gpsd`),
//! so its recording holds the same sentences a serial source's would: one reader for every log.
//!
//! **Commands.** [`Command::AddReceiver`](crate::command::Command::AddReceiver) and
//! [`Command::RemoveReceiver`](crate::command::Command::RemoveReceiver) are the one way in for the
//! console's panel, `vestnav station --compare-gps` and a remote operator; [`ReceiversSnapshot`] is what the
//! station's [`Snapshot`](crate::command::Snapshot) and status lines show of them.
//!
//! **Limits.** At most [`MAX_COMPARED`] comparison sources, and [`MAX_SAMPLES`] fixes per receiver (the
//! newest beyond are not compared, said once in the warnings; the recordings go on). A source that would
//! open the primary's device, another comparison source's, or the vest's port is refused.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use vestnav_core::accuracy::{Comparison, Receiver as CompareReceiver, Sample, compare};
use vestnav_device::gps::record::{RecordingStatus, RecordingTap};
use vestnav_device::gps::{GpsEvent, GpsSourceSpec, SourceState};
use vestnav_device::outbox::{Outbox, drain_within};

use crate::devices::GpsWorker;
use crate::fieldtests::receiver_sample;
use crate::sources::{GpsSourceConfig, VestSourceConfig};
use crate::{DRAIN_BUDGET, Station, source_state_label};

/// Comparison sources at most (beside the primary).
pub const MAX_COMPARED: usize = 4;
/// Fixes kept per receiver (a day at 1 Hz).
pub const MAX_SAMPLES: usize = 86_400;
/// Epochs of two receivers match when their receiver times differ by at most this [s] (the CLI's default).
pub const TOLERANCE_S: f64 = 0.1;
/// The comparison is recomputed at most this often.
const RECOMPUTE_EVERY: Duration = Duration::from_secs(1);
/// Capacity of a comparison source's event channel (its sentences go to its recording, not here).
const CHANNEL: usize = 4096;

/// Fixes per shared chunk of a receiver's fixes ([`Samples`]).
const CHUNK: usize = 4096;

/// One receiver's fixes on its receiver-time line, append-only: full chunks of [`CHUNK`] fixes are shared
/// with the comparison thread's jobs, so a job copies at most the last partial chunk of each receiver (not
/// up to 86,400 fixes five times a second on the view's turn).
#[derive(Debug, Default)]
struct Samples {
    /// Full chunks, oldest first.
    full: Vec<Arc<[Sample]>>,
    /// The newest fixes (fewer than [`CHUNK`]).
    tail: Vec<Sample>,
    /// Fixes beyond [`MAX_SAMPLES`], not compared.
    over: u64,
}

impl Samples {
    fn len(&self) -> usize {
        self.full.len() * CHUNK + self.tail.len()
    }

    fn last(&self) -> Option<&Sample> {
        self.tail.last().or_else(|| self.full.last().and_then(|c| c.last()))
    }

    fn push(&mut self, fix: &vestnav_device::gps::Fix) -> bool {
        let prev = self.last().map(|s| s.t_s);
        let Some(s) = receiver_sample(fix, prev) else { return false };
        if self.len() >= MAX_SAMPLES {
            self.over += 1;
            return false;
        }
        self.tail.push(s);
        if self.tail.len() == CHUNK {
            self.full.push(Arc::from(std::mem::take(&mut self.tail)));
        }
        true
    }

    /// The fixes as they are now, for a comparison job: the full chunks shared, the tail copied.
    fn shared(&self) -> SharedSamples {
        SharedSamples { full: self.full.clone(), tail: self.tail.clone() }
    }
}

/// A receiver's fixes handed to another thread ([`Receivers::tracks`], and the comparison's jobs): the full chunks
/// shared, the tail copied.
#[derive(Debug, Clone)]
pub struct SharedSamples {
    full: Vec<Arc<[Sample]>>,
    tail: Vec<Sample>,
}

impl SharedSamples {
    /// The fixes in one vector (on the thread that asked for them).
    pub fn to_vec(&self) -> Vec<Sample> {
        let mut all = Vec::with_capacity(self.full.len() * CHUNK + self.tail.len());
        for c in &self.full {
            all.extend_from_slice(c);
        }
        all.extend_from_slice(&self.tail);
        all
    }
}

/// A comparison source: its reader thread, its state as last reported, its fixes and its recording.
pub struct ComparedSource {
    /// Its number in this session (the primary is 1; numbers are not reused).
    pub number: usize,
    /// Its label in the table and the figure (`2: replay:walk.nmea@1`).
    pub name: String,
    /// Where its fixes come from.
    pub spec: GpsSourceConfig,
    worker: Option<Box<dyn GpsWorker>>,
    rx: Option<Receiver<GpsEvent>>,
    /// The source's state as it last reported it (`None` before its first report).
    pub state: Option<SourceState>,
    /// Why it could not be opened, if it could not.
    pub failed: Option<String>,
    /// When its latest positioned fix arrived.
    pub last_fix_at: Option<Instant>,
    samples: Samples,
    tap: RecordingTap,
}

impl ComparedSource {
    /// Fixes taken for the comparison.
    pub fn fixes(&self) -> usize {
        self.samples.len()
    }

    /// Its recording's status (`None`: not recorded, no session log).
    pub fn recording(&self) -> Option<RecordingStatus> {
        self.tap.status()
    }
}

/// The receivers side by side of one session: the primary's fixes and recording, the comparison sources,
/// and the latest comparison.
#[derive(Default)]
pub struct Receivers {
    /// Whether the primary's fixes are being taken (while there is a comparison source).
    active: bool,
    primary: Samples,
    primary_tap: RecordingTap,
    sources: Vec<ComparedSource>,
    /// The numbering of the next source (1 is the primary).
    next_number: usize,
    comparison: Option<Result<Comparison, String>>,
    /// The same without its per-epoch series, for snapshots (made once per result).
    summary: Option<Result<Comparison, String>>,
    /// Raised when `comparison` changes ([`Self::comparison_revision`]).
    revision: u64,
    /// The reference and Earth model the comparison was computed with (a change recomputes it).
    computed_with: Option<(Option<vestnav_core::accuracy::Reference>, vestnav_core::geo::Earth)>,
    changed: bool,
    computed_at: Option<Instant>,
    /// The comparison thread, started with the first comparison.
    worker: Option<CompareWorker>,
}

/// What the comparison thread computes: the receivers' fixes (a copy), the reference and Earth model, and
/// the warnings to add to its result.
struct CompareJob {
    receivers: Vec<(String, SharedSamples)>,
    reference: Option<vestnav_core::accuracy::Reference>,
    earth: vestnav_core::geo::Earth,
    warnings: Vec<String>,
}

/// The `receivers-compare` thread: one job at a time; it ends when its job channel is dropped.
struct CompareWorker {
    jobs: SyncSender<CompareJob>,
    results: Receiver<Result<Comparison, String>>,
    /// A job was handed over and its result not yet taken.
    busy: bool,
}

impl CompareWorker {
    fn start() -> std::io::Result<Self> {
        let (jobs, job_rx) = std::sync::mpsc::sync_channel::<CompareJob>(1);
        let (result_tx, results) = std::sync::mpsc::sync_channel(1);
        std::thread::Builder::new().name("receivers-compare".into()).spawn(move || {
            for job in job_rx {
                let receivers: Vec<CompareReceiver> = job
                    .receivers
                    .iter()
                    .map(|(name, samples)| CompareReceiver { name: name.clone(), samples: samples.to_vec() })
                    .collect();
                let mut result = compare(&receivers, job.reference.as_ref(), TOLERANCE_S, job.earth)
                    .map_err(|e| e.to_string());
                if let Ok(c) = &mut result {
                    c.warnings.extend(job.warnings);
                }
                if result_tx.send(result).is_err() {
                    return;
                }
            }
        })?;
        Ok(Self { jobs, results, busy: false })
    }
}

impl Receivers {
    /// The comparison sources, in the order they were added.
    pub fn sources(&self) -> &[ComparedSource] {
        &self.sources
    }

    /// Whether a comparison runs (at least one comparison source was added and not all were removed).
    pub fn active(&self) -> bool {
        self.active
    }

    /// Fixes of the primary taken for the comparison.
    pub fn primary_fixes(&self) -> usize {
        self.primary.len()
    }

    /// The primary's recording status.
    pub fn primary_recording(&self) -> Option<RecordingStatus> {
        self.primary_tap.status()
    }

    /// The latest comparison (or why there is none: too few fixes).
    pub fn comparison(&self) -> Option<&Result<Comparison, String>> {
        self.comparison.as_ref()
    }

    /// Raised by each comparison taken (or its failure, or its clearing): a view redraws what depends on
    /// [`Self::comparison`] when this changes, without comparing or copying the comparison every frame.
    pub fn comparison_revision(&self) -> u64 {
        self.revision
    }

    /// Every receiver's fixes, the primary first, named as in the comparison (copied: for a report, on
    /// demand; the comparison thread's jobs share them).
    pub fn receivers(&self, primary_name: &str) -> Vec<CompareReceiver> {
        self.shared(primary_name)
            .into_iter()
            .map(|(name, samples)| CompareReceiver { name, samples: samples.to_vec() })
            .collect()
    }

    /// Every receiver's name and fixes, the primary first, sharing the full chunks: cheap to take on the
    /// view's turn and hand to a thread that draws them (the console's sheet).
    pub fn tracks(&self, primary_name: &str) -> Vec<(String, SharedSamples)> {
        self.shared(primary_name)
    }

    /// Every receiver's name and fixes, the primary first, sharing the full chunks.
    fn shared(&self, primary_name: &str) -> Vec<(String, SharedSamples)> {
        std::iter::once((primary_name.to_owned(), self.primary.shared()))
            .chain(self.sources.iter().map(|s| (s.name.clone(), s.samples.shared())))
            .collect()
    }

    /// Takes the comparison thread's result, if one came.
    fn take_result(&mut self) {
        let Some(w) = self.worker.as_mut().filter(|w| w.busy) else { return };
        match w.results.try_recv() {
            Ok(result) => self.accept(result),
            Err(TryRecvError::Empty) => {}
            Err(TryRecvError::Disconnected) => {
                self.worker = None;
                self.failed("the comparison thread ended".to_owned());
            }
        }
    }

    /// The comparison thread's result taken: the thread is free again. A result computed before the last
    /// receiver was removed is not shown.
    fn accept(&mut self, result: Result<Comparison, String>) {
        if let Some(w) = self.worker.as_mut() {
            w.busy = false;
        }
        if self.active {
            self.summary = Some(result.as_ref().map(Comparison::without_series).map_err(Clone::clone));
            self.comparison = Some(result);
            self.revision += 1;
        }
    }

    /// No comparison, for this reason.
    fn failed(&mut self, why: String) {
        self.summary = Some(Err(why.clone()));
        self.comparison = Some(Err(why));
        self.revision += 1;
    }

    /// Forgets the comparison (and its summary).
    fn clear(&mut self) {
        self.comparison = None;
        self.summary = None;
        self.revision += 1;
    }

    /// The primary's recording tap, for the primary source's outputs.
    pub(crate) fn primary_outbox(&self) -> Outbox<GpsEvent> {
        self.primary_tap.outbox()
    }

    /// Takes a primary fix while a comparison runs.
    pub(crate) fn primary_event(&mut self, ev: &GpsEvent) {
        match (self.active, ev) {
            (true, GpsEvent::Fix(f)) => self.changed |= self.primary.push(f),
            (true, GpsEvent::State(s)) if ends(s) => self.primary_tap.flush(),
            _ => {}
        }
    }
}

/// The receivers side by side as the station shows them (see [`Station::receivers_snapshot`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReceiversSnapshot {
    /// The primary's name in the comparison (`1: replay:walk.nmea@1`).
    pub primary: String,
    /// The primary's fixes taken for the comparison.
    pub primary_fixes: usize,
    /// The primary's recording (`None`: no session log).
    pub primary_recording: Option<RecordingStatus>,
    /// Each comparison source, in the order they were added.
    pub sources: Vec<ReceiverSnapshot>,
    /// The latest comparison without its per-epoch series ([`Comparison::without_series`]), or why there
    /// is none yet (`None`: not computed yet).
    pub comparison: Option<Result<Comparison, String>>,
}

impl ReceiversSnapshot {
    /// One line: each comparison source's state and fixes, and its difference from the primary
    /// (`2: replay:b.nmea@40 live, 96 fixes, 96 epochs matched, mean 0.0 m E 185.2 m N, RMS 185.2 m`).
    pub fn summary(&self) -> String {
        let cmp = self.comparison.as_ref().and_then(|c| c.as_ref().ok());
        let mut parts: Vec<String> = self
            .sources
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let mut t = format!("{} {}, {} fixes", s.name, s.status_text(), s.fixes);
                if let Some((c, d)) = cmp.and_then(|c| Some((c, c.differences.get(k)?))) {
                    let _ = write!(
                        t,
                        ", {} epochs matched, mean {:.1} m E {:.1} m N, RMS {:.1} m",
                        c.matched_epochs, d.mean_en_m[0], d.mean_en_m[1], d.rms_m
                    );
                }
                t
            })
            .collect();
        if let Some(Err(e)) = &self.comparison {
            parts.push(format!("no comparison yet: {e}"));
        }
        parts.join("; ")
    }
}

/// One comparison source as the station shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReceiverSnapshot {
    /// Its number in the comparison (2 and up; [`crate::command::Command::RemoveReceiver`] names it).
    pub number: usize,
    /// Its name in the comparison (`2: gpsd://127.0.0.1:2947`).
    pub name: String,
    /// Its state in words, without an age (`live`, `stale: no fix`, `failed: …`; [`ReceiverStatus::label`]).
    pub status: String,
    /// While it is stale, how long since its last fix at the snapshot [s] ([`Self::status_text`]). Absent
    /// from older stations, whose `status` held the age.
    #[serde(default)]
    pub stale_for_s: Option<f64>,
    /// Its fixes taken for the comparison.
    pub fixes: usize,
    /// Its recording (`None`: no session log).
    pub recording: Option<RecordingStatus>,
}

impl ReceiverSnapshot {
    /// Its state in words with the stale age (`stale: no fix for 4 s`).
    pub fn status_text(&self) -> String {
        match self.stale_for_s {
            Some(age_s) => ReceiverStatus::Stale { age_s }.to_string(),
            None => self.status.clone(),
        }
    }
}

/// A comparison source's state ([`Station::receiver_status`]).
#[derive(Debug, Clone, PartialEq)]
pub enum ReceiverStatus {
    /// It could not be opened, or its worker is gone: why.
    Failed(String),
    /// Live, no fix yet.
    NoFixYet,
    /// No fix for longer than the stale time: since when [s].
    Stale {
        /// Seconds since its last fix.
        age_s: f64,
    },
    /// The source's own state in words (`live`, `lost: …`, `end of input`).
    State(String),
}

impl ReceiverStatus {
    /// The state without its age, which changes every second (`stale: no fix`).
    pub fn label(&self) -> String {
        match self {
            Self::Stale { .. } => "stale: no fix".to_owned(),
            other => other.to_string(),
        }
    }

    /// How it is drawn: a failure as an error, a stale or reconnecting source as a warning.
    pub fn severity(&self) -> ReceiverSeverity {
        match self {
            Self::Failed(_) => ReceiverSeverity::Error,
            Self::State(s) if s.starts_with("lost") => ReceiverSeverity::Error,
            Self::Stale { .. } => ReceiverSeverity::Warning,
            Self::State(s) if s.starts_with("reconnecting") => ReceiverSeverity::Warning,
            _ => ReceiverSeverity::Normal,
        }
    }
}

/// How a [`ReceiverStatus`] is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReceiverSeverity {
    /// As any text.
    Normal,
    /// As a warning (stale, reconnecting).
    Warning,
    /// As an error (failed, lost).
    Error,
}

impl std::fmt::Display for ReceiverStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Failed(why) => write!(f, "failed: {why}"),
            Self::NoFixYet => f.write_str("live, no fix yet"),
            Self::Stale { age_s } => write!(f, "stale: no fix for {age_s:.0} s"),
            Self::State(s) => f.write_str(s),
        }
    }
}

/// The label of the primary receiver in the comparison.
pub fn primary_name(spec: &GpsSourceSpec) -> String {
    format!("1: {spec}")
}

/// `<session log>.rx<k>.nmea` beside the session log.
fn recording_path(log: &std::path::Path, k: usize) -> PathBuf {
    let mut name = log.file_stem().map(std::ffi::OsStr::to_os_string).unwrap_or_default();
    name.push(format!(".rx{k}.nmea"));
    log.with_file_name(name)
}

impl Station {
    /// The receivers side by side (see [`crate::receivers`]).
    pub fn receivers(&self) -> &Receivers {
        &self.receivers
    }

    /// Adds a comparison source: `spec` is opened beside the primary on a reader thread of its own; the
    /// first one starts the comparison (the primary's fixes are taken from now on) and the recordings.
    /// Refused beyond [`MAX_COMPARED`] sources, or when the source is the primary's own device. A source
    /// that cannot be opened is kept, shown failed with the reason.
    pub fn add_receiver(&mut self, spec: GpsSourceConfig) -> Result<(), String> {
        let r = &mut self.receivers;
        if r.sources.len() >= MAX_COMPARED {
            return Err(format!("at most {MAX_COMPARED} receivers beside the primary"));
        }
        if same_device(&spec, &self.gps_source) || r.sources.iter().any(|s| same_device(&spec, &s.spec)) {
            return Err(format!("{spec} is already a receiver of this session"));
        }
        if let (GpsSourceSpec::Serial { port, .. }, VestSourceConfig::Serial { port: vest }) =
            (&spec, &self.vest_source)
            && port == vest
        {
            return Err(format!("{spec} is the vest's port, not a receiver"));
        }
        if !r.active {
            r.active = true;
            r.primary = Samples::default();
            r.next_number = 2;
            r.clear();
            if let Some(log) = self.log.as_ref().map(|l| l.path().to_path_buf())
                && let Err(e) = r.primary_tap.start(&recording_path(&log, 1))
            {
                self.notices.raise(
                    crate::Severity::Warning,
                    crate::Subject::Gps,
                    format!("receiver 1 not recorded: {e}"),
                );
            }
        }
        let r = &mut self.receivers;
        let number = r.next_number;
        r.next_number += 1;
        let tap = RecordingTap::default();
        let log_path = self.log.as_ref().map(|l| l.path().to_path_buf());
        let mut failed = None;
        if let Some(log) = &log_path
            && let Err(e) = tap.start(&recording_path(log, number))
        {
            let text = format!("receiver {number} not recorded: {e}");
            self.notices.raise(crate::Severity::Warning, crate::Subject::Gps, text);
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(CHANNEL);
        let events = Outbox::mapped(tx, |ev: GpsEvent| (!matches!(ev, GpsEvent::Raw(_))).then_some(ev), None);
        let outputs = vec![events, tap.outbox()];
        let (worker, rx) = match self.factory.open_gps(&spec, &self.route.walked(), outputs) {
            Ok(w) => (Some(w), Some(rx)),
            Err(e) => {
                tap.stop();
                failed = Some(e);
                (None, None)
            }
        };
        let name = format!("{number}: {spec}");
        self.log(vestnav_device::session_log::LogEntry::Note {
            text: format!("receiver {name} added for comparison"),
        });
        self.receivers.sources.push(ComparedSource {
            number,
            name,
            spec,
            worker,
            rx,
            state: None,
            failed,
            last_fix_at: None,
            samples: Samples::default(),
            tap,
        });
        self.receivers.changed = true;
        Ok(())
    }

    /// Removes comparison source `index` (stops its reader and its recording). Removing the last one ends
    /// the comparison and the primary's recording.
    pub fn remove_receiver(&mut self, index: usize) {
        let r = &mut self.receivers;
        if index >= r.sources.len() {
            return;
        }
        let mut s = r.sources.remove(index);
        if let Some(mut w) = s.worker.take() {
            w.stop();
        }
        s.tap.stop();
        if r.sources.is_empty() {
            r.active = false;
            r.primary_tap.stop();
            r.clear();
        }
        r.changed = true;
        let text = format!("receiver {} removed from the comparison", s.name);
        self.log(vestnav_device::session_log::LogEntry::Note { text });
    }

    /// Removes the comparison source numbered `number` (its number in the comparison, 2 and up; numbers are
    /// not reused), or says there is none.
    pub fn remove_receiver_number(&mut self, number: usize) -> Result<(), String> {
        let index = self
            .receivers
            .sources
            .iter()
            .position(|s| s.number == number)
            .ok_or_else(|| format!("no receiver {number} in the comparison"))?;
        self.remove_receiver(index);
        Ok(())
    }

    /// What a status line, a snapshot and a remote view show of the receivers side by side at `now`
    /// (`None` while no receiver is compared).
    pub fn receivers_snapshot(&self, now: Instant) -> Option<ReceiversSnapshot> {
        let r = &self.receivers;
        if !r.active {
            return None;
        }
        Some(ReceiversSnapshot {
            primary: primary_name(&self.gps_source),
            primary_fixes: r.primary.len(),
            primary_recording: r.primary_tap.status(),
            sources: (0..r.sources.len())
                .filter_map(|k| {
                    let s = r.sources.get(k)?;
                    let status = self.receiver_status(k, now)?;
                    Some(ReceiverSnapshot {
                        number: s.number,
                        name: s.name.clone(),
                        status: status.label(),
                        stale_for_s: if let ReceiverStatus::Stale { age_s } = status {
                            Some(age_s)
                        } else {
                            None
                        },
                        fixes: s.fixes(),
                        recording: s.recording(),
                    })
                })
                .collect(),
            comparison: r.summary.clone(),
        })
    }

    /// Each comparison source's state: failed, no fix yet, stale (no fix for longer than the stale time),
    /// or the source's own state (`live`, `lost: …`, `end of input`).
    pub fn receiver_status(&self, index: usize, now: Instant) -> Option<ReceiverStatus> {
        let s = self.receivers.sources.get(index)?;
        if s.worker.is_none() {
            return Some(ReceiverStatus::Failed(s.failed.as_deref().unwrap_or("not open").to_owned()));
        }
        let stale_after = Duration::try_from_secs_f64(self.settings.guidance.stale_after_s)
            .unwrap_or(Duration::from_secs(3));
        Some(match (&s.state, s.last_fix_at) {
            (Some(SourceState::Live { .. }) | None, Some(at))
                if now.saturating_duration_since(at) > stale_after =>
            {
                ReceiverStatus::Stale { age_s: now.saturating_duration_since(at).as_secs_f64() }
            }
            (Some(SourceState::Live { .. }), None) => ReceiverStatus::NoFixYet,
            (state, _) => ReceiverStatus::State(source_state_label(state.as_ref())),
        })
    }

    /// The comparison's turn in [`Station::pump`]: drains each comparison source's events (within the
    /// drain budget each) and recomputes the comparison at most once a second when fixes came.
    pub(crate) fn pump_receivers(&mut self, now: Instant) {
        let r = &mut self.receivers;
        for s in &mut r.sources {
            let Some(rx) = &s.rx else { continue };
            let mut events = Vec::new();
            drain_within(rx, DRAIN_BUDGET, |ev| events.push(ev));
            for ev in events {
                match ev {
                    GpsEvent::Fix(f) => {
                        if f.has_position() {
                            s.last_fix_at = f.received_at.or(Some(now));
                        }
                        r.changed |= s.samples.push(&f);
                    }
                    // A worker's last word is Stopped: after "end of input" or "lost" it says less.
                    GpsEvent::State(SourceState::Stopped)
                        if matches!(s.state, Some(SourceState::Finished | SourceState::Lost { .. })) => {}
                    GpsEvent::State(state) => {
                        if ends(&state) {
                            s.tap.flush();
                        }
                        s.state = Some(state);
                    }
                    _ => {}
                }
            }
        }
        r.take_result();
        let with = (self.field_tests.reference().cloned(), self.field_tests.earth);
        if r.computed_with.as_ref() != Some(&with) {
            r.changed = true;
        }
        if !r.active
            || !r.changed
            || r.computed_at.is_some_and(|t| now.saturating_duration_since(t) < RECOMPUTE_EVERY)
        {
            return;
        }
        self.recompute_receivers(now);
    }

    /// Hands the comparison to its thread now (the pump does it at most once a second when fixes came);
    /// the result replaces [`Receivers::comparison`] on a later [`Station::pump`]. While one is being
    /// computed another is not started: the next pump after its result starts it.
    pub fn recompute_receivers(&mut self, now: Instant) {
        let primary = primary_name(&self.gps_source);
        let reference = self.field_tests.reference().cloned();
        let earth = self.field_tests.earth;
        let r = &mut self.receivers;
        if !r.active || r.worker.as_ref().is_some_and(|w| w.busy) {
            return;
        }
        if r.worker.is_none() {
            match CompareWorker::start() {
                Ok(w) => r.worker = Some(w),
                Err(e) => {
                    r.failed(format!("the comparison thread could not start: {e}"));
                    return;
                }
            }
        }
        let warnings: Vec<String> = std::iter::once((&primary, r.primary.over))
            .chain(r.sources.iter().map(|s| (&s.name, s.samples.over)))
            .filter(|(_, over)| *over > 0)
            .map(|(n, over)| format!("{n}: {over} fixes beyond {MAX_SAMPLES} not compared"))
            .collect();
        let job = CompareJob { receivers: r.shared(&primary), reference: reference.clone(), earth, warnings };
        let Some(w) = r.worker.as_mut() else { return };
        if w.jobs.send(job).is_err() {
            r.worker = None;
            r.failed("the comparison thread ended".to_owned());
            return;
        }
        w.busy = true;
        r.computed_with = Some((reference, earth));
        r.changed = false;
        r.computed_at = Some(now);
    }

    /// Waits up to `timeout` for the comparison being computed and takes it (a headless caller that wants
    /// the result of [`Station::recompute_receivers`] before going on; the view never waits). True when no
    /// comparison is being computed any more.
    pub fn await_comparison(&mut self, timeout: Duration) -> bool {
        let r = &mut self.receivers;
        let Some(w) = r.worker.as_mut().filter(|w| w.busy) else { return true };
        match w.results.recv_timeout(timeout) {
            Ok(result) => {
                r.accept(result);
                true
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => false,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                r.worker = None;
                true
            }
        }
    }

    /// Stops every comparison source (the station is shutting down).
    pub(crate) fn stop_receivers(&mut self) {
        while !self.receivers.sources.is_empty() {
            self.remove_receiver(self.receivers.sources.len() - 1);
        }
    }
}

/// Whether a source state ends its input for now (its recording is flushed: a reader gets all of it).
fn ends(s: &SourceState) -> bool {
    matches!(s, SourceState::Finished | SourceState::Lost { .. } | SourceState::Stopped | SourceState::Stale)
}

/// Whether two sources would open the same device (a serial port or a gpsd daemon read twice).
fn same_device(a: &GpsSourceConfig, b: &GpsSourceConfig) -> bool {
    match (a, b) {
        (GpsSourceSpec::Serial { port: p, .. }, GpsSourceSpec::Serial { port: q, .. }) => p == q,
        (GpsSourceSpec::ThroughVest { .. }, GpsSourceSpec::ThroughVest { .. }) => true,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_device::gps::Fix;

    /// A fix of receiver time `t_s` (seconds of one day) with a position.
    fn fix(t_s: u32) -> Fix {
        let tod = chrono::NaiveTime::from_num_seconds_from_midnight_opt(t_s, 0).unwrap();
        Fix {
            time_of_day: Some(tod),
            time: Some(chrono::NaiveDate::from_ymd_opt(2026, 11, 27).unwrap().and_time(tod).and_utc()),
            lat_deg: Some(52.0 + f64::from(t_s) * 1e-6),
            lon_deg: Some(5.0),
            mode: Some(vestnav_device::gps::FixMode::Fix3D),
            ..Fix::default()
        }
    }

    /// The chunked fixes hold exactly what was pushed, in order, across chunk boundaries; a job shares the
    /// full chunks (the same allocation, not a copy) and copies only the tail; the cap holds.
    #[test]
    fn fixes_are_kept_in_shared_chunks_and_capped() {
        let mut s = Samples::default();
        let n = 2 * CHUNK + 5;
        for t in 0..n {
            assert!(s.push(&fix(u32::try_from(t).unwrap())));
        }
        assert_eq!(s.len(), n);
        let shared = s.shared();
        assert_eq!((shared.full.len(), shared.tail.len()), (2, 5));
        assert!(Arc::ptr_eq(&shared.full[0], &s.full[0]), "a full chunk is shared, not copied");
        let all = shared.to_vec();
        assert_eq!(all.len(), n);
        assert!(all.windows(2).all(|w| (w[1].t_s - w[0].t_s - 1.0).abs() < 1e-9), "in order, none lost");
        // A day and ten seconds at 1 Hz (the time of day wraps at midnight; the receiver-time line does not).
        let mut capped = Samples::default();
        for t in 0..MAX_SAMPLES + 10 {
            capped.push(&fix(u32::try_from(t % 86_400).unwrap()));
        }
        assert_eq!((capped.len(), capped.over), (MAX_SAMPLES, 10));
    }
}
