//! The station's side: [`StationBridge`] connects one [`Station`] to the broker. It publishes the station's
//! state, route and events, takes commands and stops, and supervises the operator link.
//!
//! Threads: one `mqtt-station` thread owns the MQTT connection (rumqttc's blocking client, which runs its
//! own current-thread tokio runtime inside that thread). A STOP (the global STOP ALL or the station's
//! own) goes from that thread straight to the station's [`StopPath`] — no queue, no other thread in the way
//! — and then, like everything else received, to the station's loop through a bounded channel, where
//! [`StationBridge::turn`] applies it to the [`Station`]. The station listens on no port: it only connects
//! out to the broker.

use std::collections::{BTreeMap, HashSet, VecDeque};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rumqttc::{Client, Connection, Event, LastWill, Packet, QoS};
use vestnav_device::gps::GpsSourceSpec;
use vestnav_station::command::Command;
use vestnav_station::stop::StopPath;
use vestnav_station::{Severity, Station, Subject};

use crate::broker::{BrokerConfig, ConfigError};
use crate::wire::{
    Envelope, EventKind, EventMsg, HEARTBEATS, Heartbeat, Hello, LinkReport, RouteMsg, SCHEMA,
    STOP_ALL_TOPIC, Sender, StateMsg, StationTopic, StopOrder, check_name, now_ms,
};

/// How the bridge behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct BridgeOptions {
    /// Past this long without an operator's heartbeat, the station stops the vest and halts automatic cues
    /// (unless an operator armed "continue the route if the link drops").
    pub link_bound: Duration,
    /// A command later than this (beyond the fastest recent delivery from its sender) is refused.
    pub late_after: Duration,
    /// The state is published at least this often.
    pub state_every: Duration,
    /// ... and on change, but not more often than this.
    pub state_min_gap: Duration,
    /// Hosts besides loopback an operator's `gpsd://HOST:PORT` receiver may name
    /// ([`check_gpsd_host`]; `vestnav station --remote-gpsd-host`). Empty: loopback only, so the broker
    /// cannot make the station open connections into its network.
    pub remote_gpsd_hosts: Vec<String>,
}

impl Default for BridgeOptions {
    fn default() -> Self {
        Self {
            link_bound: Duration::from_secs(3),
            late_after: Duration::from_secs(1),
            state_every: Duration::from_secs(1),
            state_min_gap: Duration::from_millis(100),
            remote_gpsd_hosts: Vec::new(),
        }
    }
}

/// What the connection thread hands to the station's loop.
enum Inbound {
    /// Connected (again).
    Up,
    /// The connection failed (the thread retries with a backoff).
    Down(String),
    /// A message.
    Msg {
        topic: String,
        payload: Vec<u8>,
        retained: bool,
        /// When it arrived (this machine's monotonic and wall clocks).
        at: Instant,
        wall_ms: i64,
    },
}

/// Capacity of the channel from the connection thread.
const INBOX: usize = 1024;
/// Capacity of rumqttc's request channel.
const REQUESTS: usize = 256;
/// Senders whose deliveries and sequence numbers are remembered.
const MAX_SENDERS: usize = 16;
/// Sequence numbers remembered per sender (a `QoS` 1 repeat is older than this by far).
const SEEN_PER_SENDER: usize = 1024;
/// How far back the fastest delivery is looked for.
const DELAY_WINDOW: Duration = Duration::from_mins(1);

/// The station's side of the broker (see the module doc).
pub struct StationBridge {
    name: String,
    opts: BridgeOptions,
    client: Client,
    rx: Receiver<Inbound>,
    quit: Arc<AtomicBool>,
    /// Messages the connection thread dropped because this loop's channel was full (never a STOP).
    dropped: Arc<std::sync::atomic::AtomicU64>,
    dropped_said: u64,
    thread: Option<JoinHandle<()>>,
    connected: bool,
    said_error: Option<String>,
    started: Instant,
    last_heartbeat: Option<Instant>,
    continue_armed: bool,
    lost_since: Option<Instant>,
    on_loss: Option<String>,
    seen: BTreeMap<Sender, (VecDeque<u64>, HashSet<u64>)>,
    delays: BTreeMap<Sender, VecDeque<(Instant, i64)>>,
    global_stop: Option<StopOrder>,
    own_stop: Option<StopOrder>,
    state_seq: u64,
    last_state: Option<(Instant, vestnav_station::command::Snapshot)>,
    route_sent: Option<u64>,
}

/// Why the bridge cannot start.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// The station's name is not a valid topic level.
    #[error("station name: {0}")]
    Name(String),
    /// The broker configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The connection thread could not start.
    #[error("cannot start the MQTT thread: {0}")]
    Thread(std::io::Error),
}

impl StationBridge {
    /// Connects station `name` to the broker (in the background: the connection thread retries until it
    /// is up). `stop` is the station's stop path, for STOPs to reach the vest from the connection thread.
    pub fn start(
        config: &BrokerConfig,
        name: &str,
        stop: StopPath,
        opts: BridgeOptions,
    ) -> Result<Self, BridgeError> {
        check_name(name).map_err(BridgeError::Name)?;
        let offline =
            Hello { name: name.to_owned(), online: false, schema: SCHEMA.into(), link_bound_s: 0.0 };
        let will = LastWill::new(
            StationTopic::Hello.of(name),
            serde_json::to_vec(&offline).unwrap_or_default(),
            QoS::AtLeastOnce,
            true,
        );
        let options = config.mqtt_options(&format!("vestnav-station-{name}"), Some(will))?;
        let (client, connection) = Client::new(options, REQUESTS);
        let (tx, rx) = sync_channel(INBOX);
        let quit = Arc::new(AtomicBool::new(false));
        let hello = Hello {
            name: name.to_owned(),
            online: true,
            schema: SCHEMA.into(),
            link_bound_s: opts.link_bound.as_secs_f64(),
        };
        let dropped = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let net = Net {
            name: name.to_owned(),
            client: client.clone(),
            tx,
            stop,
            quit: quit.clone(),
            dropped: dropped.clone(),
            hello,
        };
        let thread = std::thread::Builder::new()
            .name("mqtt-station".into())
            .spawn(move || net.run(connection))
            .map_err(BridgeError::Thread)?;
        Ok(Self {
            name: name.to_owned(),
            opts,
            client,
            rx,
            quit,
            dropped,
            dropped_said: 0,
            thread: Some(thread),
            connected: false,
            said_error: None,
            started: Instant::now(),
            last_heartbeat: None,
            continue_armed: false,
            lost_since: None,
            on_loss: None,
            seen: BTreeMap::new(),
            delays: BTreeMap::new(),
            global_stop: None,
            own_stop: None,
            state_seq: 0,
            last_state: None,
            route_sent: None,
        })
    }

    /// The station's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether the broker connection is up.
    pub fn connected(&self) -> bool {
        self.connected
    }

    /// Whether a STOP (the global one or the station's own) is in force.
    pub fn stop_in_force(&self) -> bool {
        let own = self.own_stop.as_ref();
        own.is_some_and(|o| o.stopped)
            || self.global_stop.as_ref().is_some_and(|g| {
                g.stopped && own.and_then(|o| o.resumes.as_ref()) != Some(&(g.from.clone(), g.seq))
            })
    }

    /// Waits at most `timeout` for something from the broker (the station's loop sleeps here).
    pub fn wait(&mut self, station: &mut Station, timeout: Duration) {
        match self.rx.recv_timeout(timeout) {
            Ok(msg) => self.handle(station, msg),
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {}
        }
    }

    /// The station loop's turn: applies what arrived, supervises the operator link, publishes the state
    /// and the route when due.
    pub fn turn(&mut self, station: &mut Station, now: Instant) {
        while let Ok(msg) = self.rx.try_recv() {
            self.handle(station, msg);
        }
        let dropped = self.dropped.load(Ordering::Relaxed);
        if dropped != self.dropped_said {
            let text = format!(
                "{} message(s) from the broker dropped: the station's loop fell behind",
                dropped - self.dropped_said
            );
            station.notices.raise(Severity::Warning, Subject::Operator, text.clone());
            self.event(EventKind::Refused, None, text);
            self.dropped_said = dropped;
        }
        self.supervise(station, now);
        if self.connected {
            self.publish_state(station, now);
            self.publish_route(station);
        }
    }

    fn handle(&mut self, station: &mut Station, msg: Inbound) {
        match msg {
            Inbound::Up => {
                self.connected = true;
                self.said_error = None;
                self.last_state = None;
                self.route_sent = None;
                station.notices.raise(Severity::Info, Subject::Operator, "broker connected");
            }
            Inbound::Down(e) => {
                self.connected = false;
                if self.said_error.as_deref() != Some(e.as_str()) {
                    station.notices.raise(Severity::Warning, Subject::Operator, format!("broker: {e}"));
                    self.said_error = Some(e);
                }
            }
            Inbound::Msg { topic, payload, retained, at, wall_ms } => {
                if topic == STOP_ALL_TOPIC {
                    self.stop_order(station, true, &payload, retained);
                } else if let Some((_, StationTopic::Stop)) = StationTopic::parse(&topic) {
                    self.stop_order(station, false, &payload, retained);
                } else if let Some((_, StationTopic::Cmd)) = StationTopic::parse(&topic) {
                    self.command(station, &payload, at, wall_ms);
                } else if topic.ends_with("/heartbeat")
                    && !retained
                    && let Ok(hb) = serde_json::from_slice::<Heartbeat>(&payload)
                {
                    self.delay(&hb.from, at, wall_ms - hb.sent_ms);
                    self.last_heartbeat = Some(at);
                    self.continue_armed = hb.continue_route.contains(&self.name);
                }
            }
        }
    }

    /// A STOP or resume on the global topic or the station's own.
    fn stop_order(&mut self, station: &mut Station, global: bool, payload: &[u8], retained: bool) {
        let order = if payload.is_empty() {
            None
        } else {
            match serde_json::from_slice::<StopOrder>(payload) {
                Ok(o) => Some(o),
                Err(e) => {
                    // Unreadable stop topic: stop anyway (the connection thread already did).
                    station.stop_all();
                    self.event(EventKind::Stopped, None, format!("unreadable STOP ({e}): stopped anyway"));
                    return;
                }
            }
        };
        let before = self.stop_in_force();
        let stopped = order.as_ref().is_some_and(|o| o.stopped);
        let answers = order.as_ref().map(|o| (o.from.clone(), o.seq));
        let who = order.as_ref().map_or_else(String::new, |o| format!(" from {}", o.from.operator));
        if global {
            self.global_stop = order;
        } else {
            self.own_stop = order;
        }
        let what = if global { "STOP ALL" } else { "STOP" };
        let kept = if retained { " (retained on the broker)" } else { "" };
        if stopped {
            station.stop_all();
            self.event(
                EventKind::Stopped,
                answers,
                format!("{what}{who}{kept}: vest stopped, automatic cues halted"),
            );
        } else if retained {
            // A resume replayed by the broker on (re)connection is history, not an operator's act now:
            // whatever stopped this station since (a link loss, a STOP ALL) stays until resumed anew.
            if before && !self.stop_in_force() {
                self.event(
                    EventKind::Stopped,
                    answers,
                    "a STOP was lifted while away: still halted until resumed".into(),
                );
            }
        } else if self.stop_in_force() {
            self.event(EventKind::Refused, answers, "resume refused: a newer STOP ALL is in force".into());
        } else {
            station.resume_guidance();
            self.event(EventKind::Resumed, answers, format!("resumed{who}: automatic cues on"));
        }
    }

    /// A command on the station's `cmd` topic.
    fn command(&mut self, station: &mut Station, payload: &[u8], at: Instant, wall_ms: i64) {
        let env = match serde_json::from_slice::<Envelope>(payload) {
            Ok(e) => e,
            Err(e) => {
                self.event(EventKind::Refused, None, format!("unreadable command refused: {e}"));
                return;
            }
        };
        let answers = Some((env.from.clone(), env.seq));
        if env.to != self.name {
            let text =
                format!("command #{} for station {:?} refused: this is {:?}", env.seq, env.to, self.name);
            self.event(EventKind::Refused, answers, text);
            return;
        }
        if !self.first_time(&env.from, env.seq) {
            return; // a QoS 1 repeat: played once already
        }
        let late_ms = self.delay(&env.from, at, wall_ms - env.sent_ms);
        let what = env.command.describe();
        if env.command != Command::StopAll && late_ms > self.opts.late_after.as_millis() as i64 {
            let text = format!(
                "{what} (#{} from {}) refused: {:.1} s late, not played",
                env.seq,
                env.from.operator,
                late_ms as f64 / 1000.0
            );
            station.notices.raise(Severity::Warning, Subject::Operator, text.clone());
            self.event(EventKind::Refused, answers, text);
            return;
        }
        if env.command == Command::Resume && self.stop_in_force() {
            let text =
                "resume refused: a STOP is in force on the broker; resume on the stop topic".to_owned();
            self.event(EventKind::Refused, answers, text);
            return;
        }
        if let Err(e) = crate::wire::check_command(&env.command)
            .and_then(|()| check_gpsd_host(&env.command, &self.opts.remote_gpsd_hosts))
        {
            self.event(EventKind::Refused, answers, e);
            return;
        }
        match station.apply(env.command) {
            Ok(()) => self.event(EventKind::Applied, answers, format!("{what} (#{})", env.seq)),
            Err(e) => self.event(EventKind::Refused, answers, e),
        }
    }

    /// Whether `seq` from `from` is new (and remembers it).
    fn first_time(&mut self, from: &Sender, seq: u64) -> bool {
        if !self.seen.contains_key(from) && self.seen.len() >= MAX_SENDERS {
            let oldest = self.seen.keys().next().cloned();
            if let Some(k) = oldest {
                self.seen.remove(&k);
            }
        }
        let (order, set) = self.seen.entry(from.clone()).or_default();
        if !set.insert(seq) {
            return false;
        }
        order.push_back(seq);
        if order.len() > SEEN_PER_SENDER
            && let Some(old) = order.pop_front()
        {
            set.remove(&old);
        }
        true
    }

    /// Records a delivery `delay_ms` (arrival minus sending, across two clocks) from `from` and returns how
    /// much later it is than the fastest delivery from the same sender in the last minute: the clocks'
    /// offset cancels, so the operator's and the station's clocks need not agree.
    fn delay(&mut self, from: &Sender, at: Instant, delay_ms: i64) -> i64 {
        if !self.delays.contains_key(from) && self.delays.len() >= MAX_SENDERS {
            let oldest = self.delays.keys().next().cloned();
            if let Some(k) = oldest {
                self.delays.remove(&k);
            }
        }
        let d = self.delays.entry(from.clone()).or_default();
        while d.front().is_some_and(|(t, _)| at.saturating_duration_since(*t) > DELAY_WINDOW)
            || d.len() >= 512
        {
            d.pop_front();
        }
        d.push_back((at, delay_ms));
        let fastest = d.iter().map(|(_, x)| *x).min().unwrap_or(delay_ms);
        delay_ms - fastest
    }

    /// The operator-link supervision (see [`BridgeOptions::link_bound`]).
    fn supervise(&mut self, station: &mut Station, now: Instant) {
        let since = self.last_heartbeat.unwrap_or(self.started);
        let silent = now.saturating_duration_since(since);
        let contact = self.last_heartbeat.is_some() && silent <= self.opts.link_bound;
        match (contact, self.lost_since) {
            (false, None) if silent > self.opts.link_bound => {
                self.lost_since = Some(now);
                let why = if self.last_heartbeat.is_none() {
                    format!("no operator within {:.1} s of start", self.opts.link_bound.as_secs_f64())
                } else {
                    format!("no operator heartbeat for {:.1} s", silent.as_secs_f64())
                };
                let broker = if self.connected { String::new() } else { " (broker unreachable)".to_owned() };
                let did = if self.continue_armed {
                    "guidance continues on the station's copy of the route (armed by the operator)".to_owned()
                } else {
                    station.stop_all();
                    "vest stopped, automatic cues halted until an operator resumes".to_owned()
                };
                let text = format!("OPERATOR LINK LOST: {why}{broker}; {did}");
                station.notices.raise(Severity::Alarm, Subject::Operator, text.clone());
                self.on_loss = Some(text.clone());
                self.event(EventKind::LinkLost, None, text);
            }
            (true, Some(t)) => {
                self.lost_since = None;
                let text = format!(
                    "operator link back after {:.1} s{}",
                    now.saturating_duration_since(t).as_secs_f64(),
                    if station.settings().guidance.auto {
                        ""
                    } else {
                        "; automatic cues stay off until resumed"
                    }
                );
                station.notices.raise(Severity::Info, Subject::Operator, text.clone());
                self.event(EventKind::LinkBack, None, text);
            }
            _ => {}
        }
    }

    fn link_report(&self, now: Instant) -> LinkReport {
        LinkReport {
            operator_contact: self.lost_since.is_none() && self.last_heartbeat.is_some(),
            heartbeat_age_s: self.last_heartbeat.map(|t| now.saturating_duration_since(t).as_secs_f64()),
            bound_s: self.opts.link_bound.as_secs_f64(),
            continue_armed: self.continue_armed,
            on_loss: self.on_loss.clone(),
            stop_in_force: self.stop_in_force(),
        }
    }

    fn publish_state(&mut self, station: &Station, now: Instant) {
        let snap = station.snapshot(now);
        let due = match &self.last_state {
            None => true,
            Some((t, last)) => {
                let gap = now.saturating_duration_since(*t);
                gap >= self.opts.state_every
                    || (gap >= self.opts.state_min_gap && last.without_ages() != snap.without_ages())
            }
        };
        if !due {
            return;
        }
        self.state_seq += 1;
        let msg = StateMsg {
            name: self.name.clone(),
            at_ms: now_ms(),
            seq: self.state_seq,
            link: self.link_report(now),
            station: snap.clone(),
        };
        if let Ok(bytes) = serde_json::to_vec(&msg) {
            let _ = self.client.try_publish(StationTopic::State.of(&self.name), QoS::AtMostOnce, true, bytes);
        }
        self.last_state = Some((now, snap));
    }

    fn publish_route(&mut self, station: &Station) {
        let r = station.route();
        if self.route_sent == Some(r.revision()) {
            return;
        }
        let msg = RouteMsg::of(r);
        if let Ok(bytes) = serde_json::to_vec(&msg)
            && self
                .client
                .try_publish(StationTopic::Route.of(&self.name), QoS::AtLeastOnce, true, bytes)
                .is_ok()
        {
            self.route_sent = Some(r.revision());
        }
    }

    /// Publishes an event (queued while the broker is away, sent when it is back).
    fn event(&self, kind: EventKind, answers: Option<(Sender, u64)>, text: String) {
        tracing::info!(station = %self.name, ?kind, "{text}");
        let msg = EventMsg { at_ms: now_ms(), kind, answers, text };
        if let Ok(bytes) = serde_json::to_vec(&msg) {
            let _ =
                self.client.try_publish(StationTopic::Event.of(&self.name), QoS::AtLeastOnce, false, bytes);
        }
    }

    /// Says offline (retained), disconnects and ends the connection thread (bounded wait).
    pub fn shutdown(&mut self) {
        let Some(thread) = self.thread.take() else { return };
        let offline =
            Hello { name: self.name.clone(), online: false, schema: SCHEMA.into(), link_bound_s: 0.0 };
        if let Ok(bytes) = serde_json::to_vec(&offline) {
            let _ =
                self.client.try_publish(StationTopic::Hello.of(&self.name), QoS::AtLeastOnce, true, bytes);
        }
        let _ = self.client.try_disconnect();
        // First the last will's replacement goes out with the disconnect; then the thread is told to quit.
        crate::broker::wait_for_end(&thread, Duration::from_millis(500));
        self.quit.store(true, Ordering::Relaxed);
        if crate::broker::wait_for_end(&thread, Duration::from_millis(500)) {
            let _ = thread.join();
        }
    }
}

impl Drop for StationBridge {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The connection thread's part.
struct Net {
    name: String,
    client: Client,
    tx: SyncSender<Inbound>,
    stop: StopPath,
    quit: Arc<AtomicBool>,
    dropped: Arc<std::sync::atomic::AtomicU64>,
    hello: Hello,
}

impl Net {
    fn run(self, mut connection: Connection) {
        let own_stop = StationTopic::Stop.of(&self.name);
        let mut failures = 0u32;
        while !self.quit.load(Ordering::Relaxed) {
            match connection.recv_timeout(Duration::from_millis(100)) {
                Ok(Ok(Event::Incoming(Packet::ConnAck(_)))) => {
                    failures = 0;
                    let subs = [
                        (StationTopic::Cmd.of(&self.name), QoS::AtLeastOnce),
                        (own_stop.clone(), QoS::AtLeastOnce),
                        (STOP_ALL_TOPIC.to_owned(), QoS::AtLeastOnce),
                        (HEARTBEATS.to_owned(), QoS::AtMostOnce),
                    ];
                    let _ = self.client.try_subscribe_many(
                        subs.into_iter().map(|(t, q)| rumqttc::SubscribeFilter::new(t, q)),
                    );
                    if let Ok(bytes) = serde_json::to_vec(&self.hello) {
                        let topic = StationTopic::Hello.of(&self.name);
                        let _ = self.client.try_publish(topic, QoS::AtLeastOnce, true, bytes);
                    }
                    let _ = self.tx.send(Inbound::Up);
                }
                Ok(Ok(Event::Incoming(Packet::Publish(p)))) => {
                    let at = Instant::now();
                    let is_stop = p.topic == STOP_ALL_TOPIC || p.topic == own_stop;
                    if is_stop {
                        // The vest first, from this thread: nothing queued is in the way of a STOP.
                        // An unreadable order counts as a STOP; an empty one (a cleared topic) as none.
                        let stopped = !p.payload.is_empty()
                            && serde_json::from_slice::<StopOrder>(&p.payload).ok().is_none_or(|o| o.stopped);
                        if stopped {
                            self.stop.stop_all();
                        }
                    }
                    let msg = Inbound::Msg {
                        topic: p.topic,
                        payload: p.payload.to_vec(),
                        retained: p.retain,
                        at,
                        wall_ms: now_ms(),
                    };
                    if is_stop {
                        // A STOP is never dropped: wait for room.
                        if self.tx.send(msg).is_err() {
                            break;
                        }
                    } else {
                        match self.tx.try_send(msg) {
                            Ok(()) => {}
                            Err(TrySendError::Full(_)) => {
                                self.dropped.fetch_add(1, Ordering::Relaxed);
                            }
                            Err(TrySendError::Disconnected(_)) => break,
                        }
                    }
                }
                Ok(Ok(_)) | Err(rumqttc::RecvTimeoutError::Timeout) => {}
                Ok(Err(e)) => {
                    failures += 1;
                    if self.tx.try_send(Inbound::Down(e.to_string())).is_err()
                        && self.quit.load(Ordering::Relaxed)
                    {
                        break;
                    }
                    backoff(failures, &self.quit);
                }
                Err(rumqttc::RecvTimeoutError::Disconnected) => break,
            }
        }
    }
}

/// Waits before the next connection attempt: 100 ms doubling up to 2 s, cut short by `quit`.
pub(crate) fn backoff(failures: u32, quit: &AtomicBool) {
    let wait = Duration::from_millis(100u64 << failures.min(5)).min(Duration::from_secs(2));
    let until = Instant::now() + wait;
    while Instant::now() < until && !quit.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Least privilege for a receiver added over the broker: a `gpsd://HOST:PORT` must name this machine
/// (`localhost`, a loopback address) or a host the station was started to allow (`allowed`, compared
/// case-insensitively), else an operator could make the station connect anywhere it can reach.
pub fn check_gpsd_host(command: &Command, allowed: &[String]) -> Result<(), String> {
    let Command::AddReceiver { spec } = command else { return Ok(()) };
    let Ok(GpsSourceSpec::Gpsd { host, port }) = vestnav_station::command::parse_receiver_spec(spec) else {
        return Ok(());
    };
    let bare = host.trim_start_matches('[').trim_end_matches(']');
    let loopback = bare.eq_ignore_ascii_case("localhost")
        || bare.parse::<std::net::IpAddr>().is_ok_and(|a| a.is_loopback());
    if loopback || allowed.iter().any(|h| h.eq_ignore_ascii_case(bare)) {
        return Ok(());
    }
    Err(format!(
        "receiver gpsd://{host}:{port} refused over the broker: this station lets an operator reach gpsd on \
         this machine only (start it with --remote-gpsd-host {bare} to allow that host; docs/remote.md)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Loopback in every spelling passes; another host only when allowed (any case); other commands and
    /// other receivers are not this check's.
    #[test]
    fn an_operators_gpsd_must_be_this_machine_or_allowed() {
        let add = |spec: &str| Command::AddReceiver { spec: spec.into() };
        for ok in
            ["gpsd://localhost:2947", "gpsd://127.0.0.1:2947", "gpsd://127.8.9.10:1", "gpsd://[::1]:2947"]
        {
            assert_eq!(check_gpsd_host(&add(ok), &[]), Ok(()), "{ok}");
        }
        let e = check_gpsd_host(&add("gpsd://192.168.1.20:2947"), &[]).unwrap_err();
        assert!(e.contains("--remote-gpsd-host 192.168.1.20"), "{e}");
        assert!(check_gpsd_host(&add("gpsd://gps.lab.example:2947"), &[]).is_err());
        let allowed = ["GPS.lab.example".to_owned()];
        assert_eq!(check_gpsd_host(&add("gpsd://gps.lab.example:2947"), &allowed), Ok(()));
        assert!(check_gpsd_host(&add("gpsd://other.lab.example:2947"), &allowed).is_err());
        assert_eq!(check_gpsd_host(&add("serial:/dev/ttyUSB1"), &[]), Ok(()));
        assert_eq!(check_gpsd_host(&Command::StopAll, &[]), Ok(()));
    }
}
