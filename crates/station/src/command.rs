//! The station's commands and state as data: what an operator can ask of a station ([`Command`], applied
//! by [`Station::apply`]) and what a station shows of itself ([`Snapshot`], made by
//! [`Station::snapshot`]). Both serialise with serde, so a view in another process (a console over a
//! network, a lab logger) sends and reads the same things a view in this process calls and reads.
//!
//! Everything inside is the station's own type (settings, guidance status, vest commands, waypoints,
//! fixes); the only additions are the ages a remote reader needs in place of this process's `Instant`s.

use std::time::Instant;

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{Cue, TactorMask};
use vestnav_device::gps::{Fix, SourceState};
use vestnav_device::wtcu::{LinkState, UnitStatus, VestCommand};

use crate::guidance::GuidanceStatus;
use crate::route::{MAX_WAYPOINTS, Waypoint, check_waypoint};
use crate::state::{GpsAlarm, Severity, Subject};
use crate::study::{StudyCommand, StudyView};
use crate::{Station, StationSettings};

/// What an operator can ask of a station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Command {
    /// STOP ALL: every tactor off, automatic cues latched off until [`Command::Resume`].
    StopAll,
    /// Automatic cues again (the operator's deliberate resume).
    Resume,
    /// A manual command to the vest (a FIRE, a pattern, an intensity); holds automatic cues off for the
    /// manual hold. `cue` names it when it is one of the vocabulary's cues.
    Manual {
        /// What the vest is to do.
        command: VestCommand,
        /// The named cue it is, if any.
        #[serde(default)]
        cue: Option<Cue>,
    },
    /// Replaces the whole route (each waypoint with its own arrival radius, if any) and sets the next one.
    SetRoute {
        /// The route's name.
        name: String,
        /// The waypoints, in order (at most [`MAX_WAYPOINTS`]).
        waypoints: Vec<Waypoint>,
        /// Index of the waypoint to head for.
        #[serde(default)]
        next: usize,
        /// The path the route follows between its waypoints (a walk planned along footways): guidance
        /// then measures the cross-track error from it. Each waypoint must sit within
        /// [`vestnav_device::route_file::PATH_MATCH_M`] of its vertex. Absent: straight legs.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        path: Option<vestnav_core::guidance::RoutePath>,
    },
    /// Heads for waypoint `index` next.
    NextWaypoint {
        /// Index into the route.
        index: usize,
    },
    /// New settings (guidance's and the GPS alarm's limits).
    Settings(StationSettings),
    /// Records a mark in the session log at the wearer's position.
    Mark {
        /// What the mark is (at most 200 characters).
        label: String,
    },
    /// A command to the study runner (see [`crate::study`]).
    Study(StudyCommand),
    /// Adds a receiver beside the primary GPS, compared with it ([`crate::receivers`]): `spec` in `--gps`'s
    /// text form (`serial:PATH[@BAUD]`, `gpsd://HOST:PORT`, `replay:FILE[@SPEED]`, `sim`), at most
    /// [`MAX_RECEIVER_SPEC`] bytes. It opens a device on the station's machine.
    AddReceiver {
        /// Where its fixes come from.
        spec: String,
    },
    /// Removes comparison receiver `number` (its number in the comparison, 2 and up).
    RemoveReceiver {
        /// Its number.
        number: usize,
    },
}

impl Command {
    /// Whether this command can make a tactor run (a late or repeated one must never be played).
    pub fn can_play(&self) -> bool {
        matches!(self, Self::Manual { command, .. } if *command != VestCommand::StopAll)
            || matches!(
                self,
                Self::Study(StudyCommand::Start | StudyCommand::Resume | StudyCommand::Respond { .. })
            )
    }

    /// The command in a few words, for notices and the session log.
    pub fn describe(&self) -> String {
        match self {
            Self::StopAll => "STOP ALL".to_owned(),
            Self::Resume => "resume".to_owned(),
            Self::Manual { command, .. } => command.describe(),
            Self::SetRoute { name, waypoints, path: None, .. } => {
                format!("route {name} ({} waypoints)", waypoints.len())
            }
            Self::SetRoute { name, waypoints, path: Some(p), .. } => {
                format!("route {name} ({} waypoints, path of {} points)", waypoints.len(), p.points().len())
            }
            Self::NextWaypoint { index } => format!("next waypoint {}", index + 1),
            Self::Settings(_) => "settings".to_owned(),
            Self::Mark { label } => format!("mark {label}"),
            Self::Study(c) => c.describe(),
            Self::AddReceiver { spec } if spec.len() > MAX_RECEIVER_SPEC => {
                format!("add receiver ({} bytes)", spec.len())
            }
            Self::AddReceiver { spec } => format!("add receiver {spec}"),
            Self::RemoveReceiver { number } => format!("remove receiver {number}"),
        }
    }
}

/// Longest mark label accepted [characters].
const MAX_MARK_LABEL: usize = 200;
/// Longest receiver spec accepted by [`Command::AddReceiver`] [bytes] (a device path or a host name and
/// port fit many times over).
pub const MAX_RECEIVER_SPEC: usize = 512;

/// Reads [`Command::AddReceiver`]'s spec at the boundary: at most [`MAX_RECEIVER_SPEC`] bytes in `--gps`'s
/// grammar. The station and the broker's sender (`vestnav_remote::wire`) both read it here.
pub fn parse_receiver_spec(spec: &str) -> Result<vestnav_device::gps::GpsSourceSpec, String> {
    if spec.len() > MAX_RECEIVER_SPEC {
        return Err(format!("receiver refused: its spec is longer than {MAX_RECEIVER_SPEC} bytes"));
    }
    spec.trim().parse().map_err(|e| format!("receiver refused: {e}"))
}

/// The ranges of the operator's settings: one home for the console's settings file (clamped into them)
/// and for settings from a command (refused outside them).
pub mod ranges {
    use std::ops::RangeInclusive;

    /// Arrival radius [m].
    pub const ARRIVAL_RADIUS_M: RangeInclusive<f64> = 1.0..=100.0;
    /// Time between automatic cues [s].
    pub const CUE_INTERVAL_S: RangeInclusive<f64> = 0.5..=60.0;
    /// How long an operator's manual cue holds automatic cues back [s].
    pub const MANUAL_HOLD_S: RangeInclusive<f64> = 0.0..=600.0;
    /// A fix this old is stale [s].
    pub const STALE_AFTER_S: RangeInclusive<f64> = 1.0..=60.0;
    /// A fix this old is lost [s]; never below the stale age.
    pub const LOST_AFTER_MAX_S: f64 = 600.0;
    /// A cue's on-time [ms].
    pub const ON_MS: RangeInclusive<u16> = 20..=2000;
    /// Farther than this from a planned path is off it [m] (above GPS noise, below a block's width).
    pub const OFF_PATH_M: RangeInclusive<f64> = 5.0..=100.0;
    /// Off the path this long re-plans from the wearer [s].
    pub const REROUTE_AFTER_S: RangeInclusive<f64> = 3.0..=300.0;
}

impl StationSettings {
    /// Checks every value against its range ([`ranges`]); the message names the field. Values from a
    /// network or a file go through this before they reach guidance.
    pub fn check(&self) -> Result<(), String> {
        let g = &self.guidance;
        let within = |name: &str, v: f64, r: std::ops::RangeInclusive<f64>| {
            if v.is_finite() && r.contains(&v) {
                Ok(())
            } else {
                Err(format!("{name}: {v} is outside [{}, {}]", r.start(), r.end()))
            }
        };
        within("arrival radius [m]", g.arrival_radius_m, ranges::ARRIVAL_RADIUS_M)?;
        within("cue interval [s]", g.cue_interval_s, ranges::CUE_INTERVAL_S)?;
        within("manual hold [s]", g.manual_hold_s, ranges::MANUAL_HOLD_S)?;
        within("stale after [s]", g.stale_after_s, ranges::STALE_AFTER_S)?;
        within("lost after [s]", self.lost_after_s, g.stale_after_s..=ranges::LOST_AFTER_MAX_S)?;
        within("off the path [m]", g.off_path_m, ranges::OFF_PATH_M)?;
        within("re-route after [s]", g.reroute_after_s, ranges::REROUTE_AFTER_S)?;
        if !ranges::ON_MS.contains(&g.on_ms) {
            let r = ranges::ON_MS;
            return Err(format!("on-time [ms]: {} is outside [{}, {}]", g.on_ms, r.start(), r.end()));
        }
        Ok(())
    }
}

impl Station {
    /// Applies one command, as the same calls a local view makes. Returns what to tell the operator when it
    /// was refused (nothing changed then); STOP ALL is never refused.
    pub fn apply(&mut self, command: Command) -> Result<(), String> {
        match command {
            Command::StopAll => self.stop_all(),
            Command::Resume => self.resume_guidance(),
            Command::Manual { command, cue } => self.send_manual(command, cue)?,
            Command::SetRoute { name, waypoints, next, path } => {
                if waypoints.len() > MAX_WAYPOINTS {
                    return Err(format!("route refused: more than {MAX_WAYPOINTS} waypoints"));
                }
                for (i, w) in waypoints.iter().enumerate() {
                    check_waypoint(&w.name, w.lat_deg, w.lon_deg, w.arrival_radius_m)
                        .map_err(|e| format!("route refused: waypoint {}: {e}", i + 1))?;
                }
                if next > waypoints.len() {
                    return Err(format!("route refused: next waypoint {} of {}", next + 1, waypoints.len()));
                }
                if let Some(p) = &path {
                    let (earth, gap_m) =
                        (vestnav_core::geo::Earth::Wgs84, vestnav_device::route_file::PATH_MATCH_M);
                    p.fits(&waypoints, earth, gap_m).map_err(|e| format!("route refused: {e}"))?;
                }
                let name = name.trim();
                let name =
                    if name.is_empty() { "route".to_owned() } else { name.chars().take(200).collect() };
                self.route_mut()
                    .replace_with_path(name, waypoints, path)
                    .map_err(|e| format!("route refused: {e}"))?;
                self.route_mut().set_next(next);
            }
            Command::NextWaypoint { index } => {
                let n = self.route().waypoints().len();
                if index >= n {
                    return Err(format!("next waypoint {} refused: the route has {n}", index + 1));
                }
                self.route_mut().set_next(index);
            }
            Command::Settings(s) => {
                s.check().map_err(|e| format!("settings refused: {e}"))?;
                self.set_settings(s);
            }
            Command::Mark { label } => {
                if label.chars().count() > MAX_MARK_LABEL {
                    return Err(format!("mark refused: longer than {MAX_MARK_LABEL} characters"));
                }
                self.mark(&label);
            }
            Command::Study(c) => self.study_command(c)?,
            Command::AddReceiver { spec } => {
                let spec = parse_receiver_spec(&spec)?;
                self.add_receiver(spec).map_err(|e| format!("receiver refused: {e}"))?;
            }
            Command::RemoveReceiver { number } => self.remove_receiver_number(number)?,
        }
        Ok(())
    }

    /// What the station shows of itself at `now`, for a view in another process.
    pub fn snapshot(&self, now: Instant) -> Snapshot {
        let age = |t: Instant| now.saturating_duration_since(t).as_secs_f64();
        let fix = self.gps.last_position.as_ref().map(|f| {
            // The satellite list is the GPS panel's; counts per constellation stay.
            let mut f = f.clone();
            f.satellites.clear();
            f
        });
        let stop = match (self.vest.stop, self.stop_alarm(now)) {
            (None, _) => None,
            (Some(_), Some(a)) => {
                Some(StopSnapshot::Unconfirmed { for_s: a.for_.as_secs_f64(), acked: a.acked, on: a.on })
            }
            (Some(s), None) => match s.acked_at {
                Some(_) => Some(StopSnapshot::Confirmed),
                None => Some(StopSnapshot::Pending),
            },
        };
        Snapshot {
            gps_state: self.gps.state.clone(),
            gps_alarm: self.gps_alarm(now),
            fix,
            fix_age_s: self.position_age(now).map(|a| a.as_secs_f64()),
            route: RouteSummary {
                name: self.route().name().to_owned(),
                waypoints: self.route().waypoints().len(),
                next: self.route().next(),
                revision: self.route().revision(),
            },
            vest_link: self.vest.state.clone(),
            vest_lost: self.vest.lost.clone(),
            last_reply: self.vest.last_reply.as_ref().map(|r| ReplySnapshot {
                text: r.text.clone(),
                refused: r.refused,
                age_s: age(r.at),
            }),
            tactors_on: self.vest.tactors_on,
            battery: self.vest.status.map(|(s, at)| BatterySnapshot { status: s, age_s: age(at) }),
            halted: self.vest.halted.clone(),
            stop,
            auto: self.settings().guidance.auto,
            guidance: self.guidance.clone(),
            notices: self
                .notices
                .all()
                .iter()
                .rev()
                .take(MAX_SNAPSHOT_NOTICES)
                .map(|n| NoticeSnapshot {
                    severity: n.severity,
                    subject: n.subject,
                    text: n.text.clone(),
                    age_s: age(n.since),
                })
                .collect(),
            study: self.study_view(),
            lab: self.lab_status(),
            receivers: self.receivers_snapshot(now),
        }
    }
}

/// Most notices a snapshot carries (the newest).
pub const MAX_SNAPSHOT_NOTICES: usize = 16;

/// What a station shows of itself (see [`Station::snapshot`]). Ages are at the moment it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Snapshot {
    /// The GPS source's state (`None`: no source running).
    pub gps_state: Option<SourceState>,
    /// The GPS alarm, if any.
    pub gps_alarm: Option<GpsAlarm>,
    /// The latest fix with a position (its satellite list left out).
    pub fix: Option<Fix>,
    /// Its age [s].
    pub fix_age_s: Option<f64>,
    /// The route guidance follows.
    pub route: RouteSummary,
    /// The vest link (`None`: no vest worker).
    pub vest_link: Option<LinkState>,
    /// Why the vest link was last lost, while it is not ready again.
    pub vest_lost: Option<String>,
    /// The unit's latest acknowledgement or refusal.
    pub last_reply: Option<ReplySnapshot>,
    /// Tactors on as the unit reports them (`None`: unknown).
    pub tactors_on: Option<TactorMask>,
    /// The unit's latest status report (battery).
    pub battery: Option<BatterySnapshot>,
    /// Why automatic cues are latched off, when they are.
    pub halted: Option<String>,
    /// The latest STOP ALL and its confirmation (`None`: no stop since the last deliberate command).
    pub stop: Option<StopSnapshot>,
    /// Automatic cues on.
    pub auto: bool,
    /// Guidance's latest decision (cue, hold, distance, heading).
    pub guidance: Option<GuidanceStatus>,
    /// The newest notices (at most [`MAX_SNAPSHOT_NOTICES`], newest first).
    pub notices: Vec<NoticeSnapshot>,
    /// The study session loaded, if any.
    #[serde(default)]
    pub study: Option<StudyView>,
    /// The lab outputs (LSL, OSC) and their counts (`None`: none asked for). Absent from older stations.
    #[serde(default)]
    pub lab: Option<crate::lab::LabStatus>,
    /// The receivers side by side (`None`: none compared). Absent from older stations.
    #[serde(default)]
    pub receivers: Option<crate::receivers::ReceiversSnapshot>,
}

impl Snapshot {
    /// The same snapshot with every age zeroed: two snapshots that differ only by the passing of time
    /// compare equal (a publisher sends on change).
    #[must_use]
    pub fn without_ages(&self) -> Self {
        let mut s = self.clone();
        s.fix_age_s = s.fix_age_s.map(|_| 0.0);
        if let Some(r) = &mut s.last_reply {
            r.age_s = 0.0;
        }
        if let Some(b) = &mut s.battery {
            b.age_s = 0.0;
        }
        if let Some(StopSnapshot::Unconfirmed { for_s, .. }) = &mut s.stop {
            *for_s = 0.0;
        }
        if let Some(crate::state::GpsAlarm::Stale { age_s }) = &mut s.gps_alarm {
            *age_s = 0.0;
        }
        for n in &mut s.notices {
            n.age_s = 0.0;
        }
        for r in s.receivers.iter_mut().flat_map(|r| &mut r.sources) {
            r.stale_for_s = r.stale_for_s.map(|_| 0.0);
        }
        s
    }
}

/// The route in a snapshot (the waypoints themselves go with [`Command::SetRoute`] and the route topic).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RouteSummary {
    /// Name.
    pub name: String,
    /// How many waypoints.
    pub waypoints: usize,
    /// Index of the next waypoint.
    pub next: usize,
    /// The route's revision (bumped by every change).
    pub revision: u64,
}

/// The unit's latest acknowledgement or refusal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplySnapshot {
    /// What happened, in words.
    pub text: String,
    /// A refusal rather than an acknowledgement.
    pub refused: bool,
    /// Its age [s].
    pub age_s: f64,
}

/// The unit's latest status report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatterySnapshot {
    /// The report (battery voltage and charge, faults, firmware).
    pub status: UnitStatus,
    /// Its age [s].
    pub age_s: f64,
}

/// The latest STOP ALL, as the unit confirmed it or not.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum StopSnapshot {
    /// Asked for, within the unit's time to acknowledge it.
    Pending,
    /// Acknowledged by the unit, and no tactor reported on since.
    Confirmed,
    /// STOP NOT CONFIRMED: not acknowledged in time, or tactors still reported on.
    Unconfirmed {
        /// How long since it was asked for [s].
        for_s: f64,
        /// Whether the unit acknowledged it.
        acked: bool,
        /// Tactors the unit reports on, when it reports any.
        on: Option<TactorMask>,
    },
}

/// One notice in a snapshot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoticeSnapshot {
    /// How bad.
    pub severity: Severity,
    /// About what.
    pub subject: Subject,
    /// What happened and what to do.
    pub text: String,
    /// Its age [s].
    pub age_s: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip_through_json() {
        let commands = vec![
            Command::StopAll,
            Command::Resume,
            Command::Manual {
                command: VestCommand::Fire { mask: TactorMask::from_indices([1, 2]), duration_ms: 200 },
                cue: Some(Cue::Forward),
            },
            Command::SetRoute {
                name: "loop".into(),
                waypoints: vec![Waypoint {
                    name: "A".into(),
                    lat_deg: 51.5,
                    lon_deg: -0.1,
                    arrival_radius_m: Some(5.0),
                }],
                next: 0,
                path: None,
            },
            Command::SetRoute {
                name: "walk".into(),
                waypoints: vec![Waypoint {
                    name: "B".into(),
                    lat_deg: 51.5,
                    lon_deg: -0.1,
                    arrival_radius_m: None,
                }],
                next: 0,
                path: Some(
                    vestnav_core::guidance::RoutePath::new(
                        vec![
                            vestnav_core::geo::LatLon::new(51.499, -0.1),
                            vestnav_core::geo::LatLon::new(51.4995, -0.1005),
                            vestnav_core::geo::LatLon::new(51.5, -0.1),
                        ],
                        vec![2],
                    )
                    .unwrap(),
                ),
            },
            Command::NextWaypoint { index: 3 },
            Command::Settings(StationSettings::default()),
            Command::Mark { label: "bench".into() },
            Command::Study(StudyCommand::Respond { answer: "T3".into() }),
            Command::Study(StudyCommand::Load {
                protocol: "loc.toml".into(),
                participant: "P01".into(),
                session: "1".into(),
                out_dir: "results".into(),
            }),
            Command::AddReceiver { spec: "gpsd://127.0.0.1:2947".into() },
            Command::RemoveReceiver { number: 2 },
        ];
        for c in commands {
            let text = serde_json::to_string(&c).unwrap();
            let back: Command = serde_json::from_str(&text).unwrap();
            assert_eq!(back, c, "{text}");
        }
        // The wire form other tools write by hand.
        let c: Command = serde_json::from_str(r#"{"type":"next_waypoint","index":2}"#).unwrap();
        assert_eq!(c, Command::NextWaypoint { index: 2 });
        let c: Command =
            serde_json::from_str(r#"{"type":"study","action":"respond","answer":"T6"}"#).unwrap();
        assert_eq!(c, Command::Study(StudyCommand::Respond { answer: "T6".into() }));
        assert!(serde_json::from_str::<Command>(r#"{"type":"self_destruct"}"#).is_err());
        // A path is checked as it is read: a waypoint vertex past its end is refused.
        let bad = r#"{"type":"set_route","name":"x","waypoints":[{"name":"A","lat_deg":51.5,"lon_deg":-0.1}],
            "path":{"points":[{"lat_deg":51.5,"lon_deg":-0.1},{"lat_deg":51.6,"lon_deg":-0.1}],"at":[5]}}"#;
        let e = serde_json::from_str::<Command>(bad).unwrap_err().to_string();
        assert!(e.contains("waypoints must sit on the path"), "{e}");
    }

    #[test]
    fn settings_out_of_range_are_named() {
        let mut s = StationSettings::default();
        assert_eq!(s.check(), Ok(()));
        s.guidance.arrival_radius_m = f64::NAN;
        assert!(s.check().unwrap_err().starts_with("arrival radius"));
        s = StationSettings::default();
        s.guidance.on_ms = 60_000;
        assert!(s.check().unwrap_err().starts_with("on-time"));
    }
}
