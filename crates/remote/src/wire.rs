//! The topic schema and the payloads, version 1 (`vestnav/v1/…`), as `docs/remote.md` documents them for
//! other tools. Every payload is one JSON object; every field a reader needs is here, nothing is implied.

use serde::{Deserialize, Serialize};
use vestnav_core::guidance::RoutePath;
use vestnav_device::gps::GpsSourceSpec;
use vestnav_station::command::{Command, Snapshot, parse_receiver_spec};
use vestnav_station::route::{RouteModel, Waypoint};

/// The schema's version, the second level of every topic.
pub const SCHEMA: &str = "v1";
/// The root of every topic.
pub const ROOT: &str = "vestnav/v1";
/// Longest station or operator name [bytes] (a topic level).
pub const MAX_NAME: usize = 64;
/// Largest payload a client accepts [bytes]: a route of 10,000 waypoints with a path of
/// [`MAX_WIRE_PATH_POINTS`] fits.
pub const MAX_PAYLOAD: usize = 4 << 20;
/// Largest MQTT packet a client sends or accepts [bytes]: [`MAX_PAYLOAD`] plus room for the fixed header
/// and the topic (under 200 bytes: [`ROOT`], a name of at most [`MAX_NAME`] and a sub-topic), so a payload
/// that passes the [`MAX_PAYLOAD`] check is never refused by the client for its headers.
pub const MAX_PACKET: usize = MAX_PAYLOAD + 1024;
/// Most points of a route's path carried over the broker (a route command, a station's route topic).
/// At most about 62 bytes of JSON each (every digit of an `f64` written): 40,000 points are 2.5 MB, and with
/// 10,000 waypoints named "Waypoint N" the message is 3.3 MB of [`MAX_PAYLOAD`] (measured by the test
/// `the_largest_route_with_the_largest_path_fits_in_one_message`); a walk planned node by node (a few metres
/// apart) of 100 km and more fits. Much longer names can still take a route past [`MAX_PAYLOAD`]: the
/// sender refuses it, naming its size.
pub const MAX_WIRE_PATH_POINTS: usize = 40_000;

/// Checks what the broker carries beyond what the station itself checks: a route's path of at most
/// [`MAX_WIRE_PATH_POINTS`]; a receiver to compare ([`Command::AddReceiver`]) of at most
/// [`MAX_RECEIVER_SPEC`](vestnav_station::command::MAX_RECEIVER_SPEC) bytes in `--gps`'s grammar, and only a receiver (see [`check_remote_receiver`]).
/// `Err` says why, naming the limit.
pub fn check_command(command: &Command) -> Result<(), String> {
    if let Command::AddReceiver { spec } = command {
        return check_remote_receiver(spec);
    }
    if let Command::SetRoute { path: Some(p), .. } = command
        && p.points().len() > MAX_WIRE_PATH_POINTS
    {
        return Err(format!(
            "route refused: its path has {} points, more than the {MAX_WIRE_PATH_POINTS} a route over the \
             broker may carry (docs/remote.md)",
            p.points().len()
        ));
    }
    Ok(())
}

/// A receiver an operator may open on a station's machine over the broker: a serial port
/// (`serial:PATH[@BAUD]`), a gpsd daemon (`gpsd://HOST:PORT`) or the simulator on the station's route
/// (`sim`). Least privilege: a replay or a simulator's route names a file on the station's disk, and `vest`
/// the vest's own link, none of which an operator needs to compare receivers; those are for the console
/// and `vestnav station --compare-gps` on the machine itself. The station refuses the vest's port and a
/// device already in use itself.
pub fn check_remote_receiver(spec: &str) -> Result<(), String> {
    match parse_receiver_spec(spec)? {
        GpsSourceSpec::Serial { .. }
        | GpsSourceSpec::Gpsd { .. }
        | GpsSourceSpec::Simulator { route: None } => Ok(()),
        other => Err(format!(
            "receiver {other} refused over the broker: only serial:PATH[@BAUD], gpsd://HOST:PORT or sim \
             (a file on the station's machine or the vest's link is opened there only; docs/remote.md)"
        )),
    }
}

/// The global STOP ALL (retained, `QoS` 1): every station obeys it until it is resumed.
pub const STOP_ALL_TOPIC: &str = "vestnav/v1/stop";
/// Every operator's heartbeat (`+` is the operator's name).
pub const HEARTBEATS: &str = "vestnav/v1/operator/+/heartbeat";

/// What a station publishes or receives on, below `vestnav/v1/station/<name>/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StationTopic {
    /// Online or offline (retained; the offline one is the station's last will).
    Hello,
    /// The state, on change and at least every second (retained, `QoS` 0).
    State,
    /// What it did: applied, refused, link lost, stopped (`QoS` 1).
    Event,
    /// Its route's waypoints, when they change (retained, `QoS` 1).
    Route,
    /// Commands to it (`QoS` 1).
    Cmd,
    /// Its own STOP / resume (retained, `QoS` 1).
    Stop,
}

impl StationTopic {
    /// The last topic level.
    pub fn level(self) -> &'static str {
        match self {
            Self::Hello => "hello",
            Self::State => "state",
            Self::Event => "event",
            Self::Route => "route",
            Self::Cmd => "cmd",
            Self::Stop => "stop",
        }
    }

    /// The topic of station `name`.
    pub fn of(self, name: &str) -> String {
        format!("{ROOT}/station/{name}/{}", self.level())
    }

    /// Every station's topic of this kind (a subscription filter).
    pub fn all(self) -> String {
        format!("{ROOT}/station/+/{}", self.level())
    }

    /// Splits a received topic into the station's name and the kind; `None` for anything else.
    pub fn parse(topic: &str) -> Option<(&str, Self)> {
        let rest = topic.strip_prefix(ROOT)?.strip_prefix("/station/")?;
        let (name, level) = rest.split_once('/')?;
        let kind = [Self::Hello, Self::State, Self::Event, Self::Route, Self::Cmd, Self::Stop]
            .into_iter()
            .find(|k| k.level() == level)?;
        check_name(name).ok()?;
        Some((name, kind))
    }
}

/// The heartbeat topic of operator `name`.
pub fn heartbeat_topic(name: &str) -> String {
    format!("{ROOT}/operator/{name}/heartbeat")
}

/// Checks a station or operator name: 1 to [`MAX_NAME`] ASCII letters, digits, `-` or `_` (it is a topic
/// level, so no `/`, `+` or `#`).
pub fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() || name.len() > MAX_NAME {
        return Err(format!("name {name:?}: 1 to {MAX_NAME} characters"));
    }
    if !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_') {
        return Err(format!("name {name:?}: only letters, digits, '-' and '_'"));
    }
    Ok(())
}

/// Who sent a command or a stop: the operator's name and its session (a new number each time the
/// operator's program starts, so its sequence numbers never collide with an earlier run's).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Sender {
    /// The operator's name.
    pub operator: String,
    /// The operator program's session.
    pub session: u64,
}

/// A command on `…/station/<name>/cmd`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// The station it is for (must be the station's own name, or it is refused).
    pub to: String,
    /// Who sent it.
    pub from: Sender,
    /// The sender's sequence number (per session, from 1): a repeat is played once.
    pub seq: u64,
    /// When it was sent [ms since 1970, the operator's clock].
    pub sent_ms: i64,
    /// What to do.
    pub command: Command,
}

/// A STOP or a resume on `vestnav/v1/stop` (every station) or `…/station/<name>/stop` (one).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StopOrder {
    /// Stopped (true) or resumed (false).
    pub stopped: bool,
    /// Who sent it.
    pub from: Sender,
    /// The sender's sequence number.
    pub seq: u64,
    /// When it was sent [ms since 1970].
    pub sent_ms: i64,
    /// On a station's own resume: the global STOP ALL (its sender and sequence number) this resume lifts
    /// for this station. A newer STOP ALL stops it again.
    #[serde(default)]
    pub resumes: Option<(Sender, u64)>,
}

/// An operator's heartbeat on `vestnav/v1/operator/<name>/heartbeat` (`QoS` 0, every 500 ms).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Heartbeat {
    /// Who.
    pub from: Sender,
    /// When it was sent [ms since 1970].
    pub sent_ms: i64,
    /// The stations this operator armed to continue their route if the link drops.
    #[serde(default)]
    pub continue_route: Vec<String>,
}

/// A station's `hello` (retained): online when it connects, offline as its last will or when it ends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// The station's name.
    pub name: String,
    /// Online or not.
    pub online: bool,
    /// The schema's version ([`SCHEMA`]).
    pub schema: String,
    /// Its operator-link bound [s]: past it without a heartbeat, it stops the vest.
    pub link_bound_s: f64,
}

/// How the station sees its operator link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkReport {
    /// Whether an operator's heartbeat arrived within the bound.
    pub operator_contact: bool,
    /// Age of the latest heartbeat [s] (`None`: none yet).
    pub heartbeat_age_s: Option<f64>,
    /// The bound [s].
    pub bound_s: f64,
    /// Whether an operator armed "continue the route if the link drops" for this station.
    pub continue_armed: bool,
    /// What the station did at the latest loss of the link, in words.
    pub on_loss: Option<String>,
    /// Whether a STOP (global or its own) is in force.
    pub stop_in_force: bool,
}

/// A station's `state`: its snapshot, its operator link and when it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateMsg {
    /// The station's name.
    pub name: String,
    /// When it was made [ms since 1970, the station's clock].
    pub at_ms: i64,
    /// Counts up by one per state published.
    pub seq: u64,
    /// The operator link.
    pub link: LinkReport,
    /// The station's state.
    pub station: Snapshot,
}

/// What an event is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A command was applied.
    Applied,
    /// A command was refused (late, addressed elsewhere, malformed, refused by the station).
    Refused,
    /// A STOP was obeyed.
    Stopped,
    /// A resume was obeyed.
    Resumed,
    /// The operator link was lost; the text says what the station did.
    LinkLost,
    /// The operator link is back.
    LinkBack,
}

/// A station's `event`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventMsg {
    /// When [ms since 1970, the station's clock].
    pub at_ms: i64,
    /// What about.
    pub kind: EventKind,
    /// The command it answers, when it answers one.
    #[serde(default)]
    pub answers: Option<(Sender, u64)>,
    /// What happened, in words.
    pub text: String,
}

/// A station's `route` (retained): the waypoints guidance follows, and their path when it has one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RouteMsg {
    /// The route's name.
    pub name: String,
    /// The waypoints.
    pub waypoints: Vec<Waypoint>,
    /// Index of the next waypoint.
    pub next: usize,
    /// The route's revision on the station.
    pub revision: u64,
    /// The path between the waypoints, when the route has one of at most [`MAX_WIRE_PATH_POINTS`] points
    /// (checked as it is read). Absent from older stations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<RoutePath>,
    /// How many points the station's path has (0: straight legs); more than [`MAX_WIRE_PATH_POINTS`]
    /// means it is guided along a path this message does not carry.
    #[serde(default)]
    pub path_points: usize,
}

impl RouteMsg {
    /// The message for `route` (its path left out when longer than [`MAX_WIRE_PATH_POINTS`]).
    pub fn of(route: &RouteModel) -> Self {
        let path_points = route.path().map_or(0, |p| p.points().len());
        Self {
            name: route.name().to_owned(),
            waypoints: route.waypoints().to_vec(),
            next: route.next(),
            revision: route.revision(),
            path: route.path().filter(|_| path_points <= MAX_WIRE_PATH_POINTS).cloned(),
            path_points,
        }
    }
}

/// Now [ms since 1970] on this machine's clock.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_round_trip_and_hostile_ones_are_not_stations() {
        for k in [StationTopic::Hello, StationTopic::State, StationTopic::Cmd, StationTopic::Stop] {
            assert_eq!(StationTopic::parse(&k.of("alpha-1")), Some(("alpha-1", k)));
        }
        assert_eq!(StationTopic::State.of("a"), "vestnav/v1/station/a/state");
        assert_eq!(StationTopic::parse("vestnav/v2/station/a/state"), None);
        assert_eq!(StationTopic::parse("vestnav/v1/station/a/b/state"), None);
        assert_eq!(StationTopic::parse("vestnav/v1/station/a+/state"), None);
        assert_eq!(StationTopic::parse("vestnav/v1/station/a/shell"), None);
        assert!(check_name(&"x".repeat(65)).is_err());
        assert!(check_name("a/b").is_err());
        assert!(check_name("").is_err());
    }

    /// The limits agree: a route of the most waypoints a station takes, each named, with a path of the
    /// most points the broker carries, at full `f64` precision (the longest JSON numbers), fits in one
    /// message with its envelope. Prints the bytes a path point costs (docs/remote.md quotes it).
    #[test]
    fn the_largest_route_with_the_largest_path_fits_in_one_message() {
        use vestnav_core::geo::LatLon;
        let n = MAX_WIRE_PATH_POINTS;
        let wps = vestnav_station::route::MAX_WAYPOINTS;
        // Points a few metres apart with every digit of an f64 used (an irrational step).
        let point = |i: usize| LatLon {
            lat_deg: -33.0 - i as f64 * std::f64::consts::PI * 1e-5,
            lon_deg: -151.0 - i as f64 * std::f64::consts::E * 1e-5,
        };
        let points: Vec<LatLon> = (0..n).map(point).collect();
        let at: Vec<usize> = (0..wps).map(|k| k * (n - 1) / (wps - 1)).collect();
        let waypoints: Vec<Waypoint> = at
            .iter()
            .enumerate()
            .map(|(k, &i)| Waypoint {
                name: format!("Waypoint {}", k + 1),
                lat_deg: points[i].lat_deg,
                lon_deg: points[i].lon_deg,
                arrival_radius_m: None,
            })
            .collect();
        let path = RoutePath::new(points, at).unwrap();
        let straight =
            Command::SetRoute { name: "r".into(), waypoints: waypoints.clone(), next: 0, path: None };
        let with_path = Command::SetRoute { name: "r".into(), waypoints, next: 0, path: Some(path) };
        let env = |command| Envelope {
            to: "x".repeat(MAX_NAME),
            from: Sender { operator: "y".repeat(MAX_NAME), session: u64::MAX },
            seq: u64::MAX,
            sent_ms: i64::MAX,
            command,
        };
        let bytes = |c| serde_json::to_vec(&env(c)).unwrap().len();
        let (without, with) = (bytes(straight), bytes(with_path.clone()));
        assert_eq!(check_command(&with_path), Ok(()));
        assert!(with <= MAX_PAYLOAD, "{with} bytes > {MAX_PAYLOAD}");
        let per_point = (with - without) as f64 / n as f64;
        eprintln!(
            "{wps} waypoints: {without} B; with a {n}-point path: {with} B ({per_point:.1} B a point); limit {MAX_PAYLOAD} B"
        );
    }

    #[test]
    fn only_receivers_are_opened_over_the_broker() {
        let add = |spec: &str| check_command(&Command::AddReceiver { spec: spec.into() });
        for ok in ["serial:/dev/ttyUSB1@9600", "gpsd://127.0.0.1:2947", " sim "] {
            assert_eq!(add(ok), Ok(()), "{ok}");
        }
        for (bad, why) in [
            ("replay:/etc/passwd@1", "refused over the broker"),
            ("sim:/home/x/route.gpx", "refused over the broker"),
            ("vest", "refused over the broker"),
            ("tcp:evil", "unknown source"),
            ("gpsd://host", "missing :PORT"),
        ] {
            let e = add(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
        let long = format!("serial:/dev/{}", "x".repeat(vestnav_station::command::MAX_RECEIVER_SPEC));
        assert!(add(&long).unwrap_err().contains("longer than 512 bytes"));
        assert_eq!(check_command(&Command::RemoveReceiver { number: 7 }), Ok(()));
    }

    /// The command examples of docs/remote.md read as the station reads them.
    #[test]
    fn the_documented_commands_parse() {
        let doc = include_str!("../../../docs/remote.md");
        let examples: Vec<&str> =
            doc.lines().filter(|l| l.starts_with("{\"type\":") && !l.contains('…')).collect();
        assert!(examples.len() >= 7, "{examples:?}");
        for e in examples {
            let c: Command = serde_json::from_str(e).unwrap_or_else(|err| panic!("{e}: {err}"));
            assert_eq!(serde_json::from_str::<Command>(&serde_json::to_string(&c).unwrap()).unwrap(), c);
        }
    }
}
