//! What the station knows, all of it derived from the devices' events and their timestamps: the GPS side
//! ([`GpsState`]), the vest side ([`VestState`], with the stop's confirmation), the alarms a view shows, and
//! the typed notices ([`Notice`]) that replace free-form status strings.

use std::time::{Duration, Instant};

use vestnav_core::vest::TactorMask;
use vestnav_device::gps::{DecodeStats, Fix, SourceState};
use vestnav_device::heading::Attitude;
use vestnav_device::wtcu::{CommandKind, DeviceInfo, LinkState, UnitStatus};

/// What the GPS side shows, all of it from the source's events.
#[derive(Debug, Default, Clone)]
pub struct GpsState {
    /// The source's state (`None`: no source running).
    pub state: Option<SourceState>,
    /// Latest epoch, with or without a position.
    pub fix: Option<Fix>,
    /// Latest epoch with a position.
    pub last_position: Option<Fix>,
    /// Fixes with a position this session.
    pub fixes: u64,
    /// Latest notice from the source.
    pub notice: Option<String>,
    /// The decoder's latest counts of accepted and rejected input.
    pub stats: Option<DecodeStats>,
    /// Latest heading reading from the GPS input (an NMEA compass's HDG, gpsd's ATT).
    pub attitude: Option<Attitude>,
    /// When the operator silenced the alarm (it re-arms on the next good fix).
    pub alarm_silenced: bool,
}

/// Why the GPS alarm is on.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum GpsAlarm {
    /// The last position is older than the stale limit.
    Stale {
        /// Age [s].
        age_s: f64,
    },
    /// No position for longer than the lost limit, or the receiver reports no fix, or the link dropped.
    Lost {
        /// Why.
        reason: String,
    },
}

/// The GPS alarm of `gps` at `now`, with the stale and lost limits [s]; `running` says whether a source
/// runs at all.
pub fn gps_alarm(
    gps: &GpsState,
    running: bool,
    now: Instant,
    stale_after_s: f64,
    lost_after_s: f64,
) -> Option<GpsAlarm> {
    let state = gps.state.as_ref()?;
    if !running {
        return None;
    }
    // A source that reached its end (a replay's file) is its own state, not a lost fix: the view says
    // "replay finished" with Restart and Loop, without the alarm.
    if *state == SourceState::Finished {
        return None;
    }
    if let SourceState::Lost { reason } = state {
        return Some(GpsAlarm::Lost { reason: reason.clone() });
    }
    if let Some(f) = &gps.fix
        && !f.has_position()
        && f.age(now).is_some_and(|a| a.as_secs_f64() < stale_after_s)
    {
        return Some(GpsAlarm::Lost { reason: "receiver reports no fix".into() });
    }
    let age = gps.last_position.as_ref().and_then(|f| f.age(now))?.as_secs_f64();
    if age > lost_after_s {
        Some(GpsAlarm::Lost { reason: format!("no position for {age:.0} s") })
    } else if age > stale_after_s {
        Some(GpsAlarm::Stale { age_s: age })
    } else {
        None
    }
}

/// The latest reply of the vest, for the operator.
#[derive(Debug, Clone, PartialEq)]
pub struct VestReply {
    /// What happened, in words.
    pub text: String,
    /// A refusal (shown as an error) rather than an acknowledgement.
    pub refused: bool,
    /// When it arrived.
    pub at: Instant,
}

/// A STOP ALL must be acknowledged by the unit within this long, or it is shown as not confirmed.
pub const STOP_CONFIRM_WITHIN: Duration = Duration::from_millis(300);

/// The latest STOP ALL and whether the unit acknowledged it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StopTracking {
    /// When it was asked for (by the operator, or by the worker itself on a stalled thread).
    pub requested_at: Instant,
    /// When the unit acknowledged it.
    pub acked_at: Option<Instant>,
}

/// A stop the unit has not confirmed: the unit has not acknowledged it within [`STOP_CONFIRM_WITHIN`],
/// or its latest word (a REPORT, a STATUS, an ACK) says tactors are on since.
#[derive(Debug, Clone, PartialEq)]
pub struct StopAlarm {
    /// How long since STOP ALL was asked for.
    pub for_: Duration,
    /// Whether the unit acknowledged it (and still reports tactors on).
    pub acked: bool,
    /// Tactors the unit reports on, when it reports any.
    pub on: Option<TactorMask>,
}

/// What the vest side shows, all of it from the worker's events.
#[derive(Debug, Default, Clone)]
pub struct VestState {
    /// Link state (`None`: no worker).
    pub state: Option<LinkState>,
    /// Tactors the unit reports on (`None`: unknown, e.g. no link).
    pub tactors_on: Option<TactorMask>,
    /// What the unit said about itself at the handshake.
    pub device: Option<DeviceInfo>,
    /// The unit's last status report and when it came.
    pub status: Option<(UnitStatus, Instant)>,
    /// Latest ack or refusal.
    pub last_reply: Option<VestReply>,
    /// Why automatic cues are latched off, when they are (STOP ALL, a stalled thread).
    pub halted: Option<String>,
    /// Why the link was last lost, kept until the unit is ready again: reconnection attempts in between
    /// are still a lost vest.
    pub lost: Option<String>,
    /// Latest reading of the unit's heading stream (protocol v2), timed by its arrival.
    pub heading: Option<Attitude>,
    /// The latest STOP ALL and its confirmation (`None`: no stop since the last deliberate command).
    pub stop: Option<StopTracking>,
}

impl VestState {
    /// Whether the unit is connected and has identified itself (commands can be delivered).
    pub fn is_live(&self) -> bool {
        self.state == Some(LinkState::Ready)
    }

    /// The state as words for a top bar.
    pub fn label(&self) -> String {
        self.state.as_ref().map_or_else(|| "disconnected".to_owned(), ToString::to_string)
    }

    /// Whether the link is lost now (also while reconnecting after a loss).
    pub fn is_lost(&self) -> bool {
        matches!(
            (&self.state, &self.lost),
            (Some(LinkState::Lost { .. }), _)
                | (Some(LinkState::Connecting { .. } | LinkState::Handshaking), Some(_))
        )
    }

    /// A STOP ALL was asked for at `at`. While an earlier one is still unacknowledged, its time stays:
    /// the alarm says how long the unit has not confirmed any stop.
    pub fn stop_requested(&mut self, at: Instant) {
        if self.stop.is_none_or(|s| s.acked_at.is_some()) {
            self.stop = Some(StopTracking { requested_at: at, acked_at: None });
        }
    }

    /// The operator deliberately commanded the vest again (a manual cue, a resume): tactors on after this
    /// are theirs, not a failed stop — once the stop itself was acknowledged.
    pub fn commanded(&mut self) {
        if self.stop.is_some_and(|s| s.acked_at.is_some()) {
            self.stop = None;
        }
    }

    /// The unit acknowledged a command of `kind` at `at`.
    pub fn acked(&mut self, kind: CommandKind, at: Instant) {
        if kind == CommandKind::StopAll
            && let Some(s) = &mut self.stop
            && s.acked_at.is_none()
        {
            s.acked_at = Some(at);
        }
    }

    /// The stop alarm at `now`, if the latest STOP ALL is not confirmed (see [`StopAlarm`]): not
    /// acknowledged within [`STOP_CONFIRM_WITHIN`], or acknowledged while the unit's latest word still says
    /// tactors are on.
    pub fn stop_alarm(&self, now: Instant) -> Option<StopAlarm> {
        let s = self.stop?;
        let for_ = now.saturating_duration_since(s.requested_at);
        let on = self.tactors_on.filter(|m| !m.is_empty());
        let unacked = s.acked_at.is_none() && for_ >= STOP_CONFIRM_WITHIN;
        let still_on = s.acked_at.is_some() && on.is_some();
        (unacked || still_on).then_some(StopAlarm { for_, acked: s.acked_at.is_some(), on })
    }
}

/// How bad a notice is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub enum Severity {
    /// Cues cannot reach the wearer, data is being lost, or the operator's file was not used: red.
    Alarm,
    /// Degraded or not there yet: amber.
    Warning,
    /// Information the operator asked for or should know: blue.
    Info,
}

/// What a notice is about (where a view shows it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Subject {
    /// The vest link and the stop.
    Vest,
    /// The GPS source.
    Gps,
    /// Automatic guidance.
    Guidance,
    /// The route and its files.
    Route,
    /// The settings file.
    Settings,
    /// The session log and other recordings.
    Storage,
    /// The remote operator's link through a broker (`vestnav-remote`).
    Operator,
}

/// One typed notice for the operator: shown once, where it belongs, until dismissed or replaced by a
/// newer one of the same subject and key.
#[derive(Debug, Clone, PartialEq)]
pub struct Notice {
    /// How bad.
    pub severity: Severity,
    /// About what.
    pub subject: Subject,
    /// What happened and what to do.
    pub text: String,
    /// When it was raised.
    pub since: Instant,
}

/// The station's notices, newest last; a view drains or shows them.
#[derive(Debug, Default, Clone)]
pub struct Notices {
    items: Vec<Notice>,
    revision: u64,
}

/// Most notices kept (the oldest go first).
pub const MAX_NOTICES: usize = 64;

impl Notices {
    /// Raises a notice.
    pub fn raise(&mut self, severity: Severity, subject: Subject, text: impl Into<String>) {
        let text = text.into();
        // The same text twice in a row is one notice (a retrying failure says it once).
        if self.items.last().is_some_and(|n| n.subject == subject && n.text == text) {
            return;
        }
        if self.items.len() >= MAX_NOTICES {
            self.items.remove(0);
        }
        self.items.push(Notice { severity, subject, text, since: Instant::now() });
        self.revision += 1;
    }

    /// Every notice, oldest first.
    pub fn all(&self) -> &[Notice] {
        &self.items
    }

    /// The newest notice about `subject`.
    pub fn latest(&self, subject: Subject) -> Option<&Notice> {
        self.items.iter().rev().find(|n| n.subject == subject)
    }

    /// Dismisses the notice at `index`.
    pub fn dismiss(&mut self, index: usize) {
        if index < self.items.len() {
            self.items.remove(index);
            self.revision += 1;
        }
    }

    /// Dismisses every notice about `subject`.
    pub fn dismiss_subject(&mut self, subject: Subject) {
        let n = self.items.len();
        self.items.retain(|x| x.subject != subject);
        if self.items.len() != n {
            self.revision += 1;
        }
    }

    /// Bumped whenever the list changes.
    pub fn revision(&self) -> u64 {
        self.revision
    }
}

/// The latest cues automatic guidance handed to the vest and when (at most [`SentCues::KEPT`], newest
/// last): the operator's short history of what the wearer felt.
#[derive(Debug, Clone, Default)]
pub struct SentCues(std::collections::VecDeque<(vestnav_core::vest::Cue, Instant)>);

impl SentCues {
    /// How many are kept.
    pub const KEPT: usize = 6;

    /// Records `cue` handed over at `at`.
    pub fn push(&mut self, cue: vestnav_core::vest::Cue, at: Instant) {
        if self.0.len() == Self::KEPT {
            self.0.pop_front();
        }
        self.0.push_back((cue, at));
    }

    /// The kept cues, newest first.
    pub fn newest_first(&self) -> impl Iterator<Item = &(vestnav_core::vest::Cue, Instant)> {
        self.0.iter().rev()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_is_unconfirmed_until_acked_and_while_tactors_are_reported_on() {
        let t0 = Instant::now();
        let mut v = VestState { tactors_on: Some(TactorMask::NONE), ..VestState::default() };
        v.stop_requested(t0);
        assert_eq!(v.stop_alarm(t0 + Duration::from_millis(100)), None, "within the grace");
        let late = t0 + Duration::from_secs(2);
        let a = v.stop_alarm(late).unwrap();
        assert!(!a.acked);
        assert_eq!(a.for_, Duration::from_secs(2));
        assert_eq!(a.on, None);
        // A hostile unit: no ack, its REPORTs say 13 and 14 are on.
        let mask = TactorMask::from_indices([13, 14]);
        v.tactors_on = Some(mask);
        assert_eq!(v.stop_alarm(late).unwrap().on, Some(mask));
        // Acknowledged, but the unit still says 13 and 14 run: still not confirmed.
        v.acked(CommandKind::StopAll, t0 + Duration::from_millis(500));
        assert!(v.stop_alarm(late).unwrap().acked);
        v.tactors_on = Some(TactorMask::NONE);
        assert_eq!(v.stop_alarm(late), None, "acknowledged and all off: confirmed");
        // A deliberate command after a confirmed stop ends the tracking.
        v.commanded();
        assert!(v.stop.is_none());
    }

    #[test]
    fn notices_say_a_repeated_failure_once_and_stay_bounded() {
        let mut n = Notices::default();
        n.raise(Severity::Alarm, Subject::Storage, "disk full");
        n.raise(Severity::Alarm, Subject::Storage, "disk full");
        assert_eq!(n.all().len(), 1);
        for k in 0..100 {
            n.raise(Severity::Info, Subject::Route, format!("n{k}"));
        }
        assert_eq!(n.all().len(), MAX_NOTICES);
        assert_eq!(n.latest(Subject::Route).unwrap().text, "n99");
        n.dismiss_subject(Subject::Route);
        assert!(n.latest(Subject::Route).is_none());
    }
}
