//! The operator's side: [`Fleet`] discovers every station on the broker, keeps what each last said and
//! when (last contact is timed by this machine's clock at arrival: a retained message replayed by the
//! broker is not contact), sends commands with sequence numbers and timestamps, sends the operator's
//! heartbeat, and STOPs one station or all of them. An observer (a lab logger, a second console) uses the
//! same client without heartbeats; the broker's ACL keeps it read-only.
//!
//! Threads: one `mqtt-fleet` thread owns the connection and beats the heartbeat every
//! [`FleetOptions::heartbeat_every`]; views read a copy of the stations through a mutex held only to copy.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rumqttc::{Client, Connection, Event, Packet, QoS, SubscribeFilter};
use vestnav_station::command::Command;

use crate::broker::{BrokerConfig, ConfigError};
use crate::wire::{
    Envelope, EventMsg, HEARTBEATS, Heartbeat, Hello, RouteMsg, STOP_ALL_TOPIC, Sender, StateMsg,
    StationTopic, StopOrder, check_name, heartbeat_topic, now_ms,
};

/// How the fleet client behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetOptions {
    /// The operator's name (its MQTT user name, by convention).
    pub operator: String,
    /// Send heartbeats (an operator) or not (an observer).
    pub heartbeats: bool,
    /// Time between two heartbeats.
    pub heartbeat_every: Duration,
    /// A station not heard from for longer is shown as stale ("no contact N s").
    pub stale_after: Duration,
}

impl FleetOptions {
    /// An operator named `operator` with the default timings.
    pub fn operator(operator: &str) -> Self {
        Self {
            operator: operator.to_owned(),
            heartbeats: true,
            heartbeat_every: Duration::from_millis(500),
            stale_after: Duration::from_secs(2),
        }
    }
}

/// Why a fleet request failed.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    /// The operator's name is not a valid topic level.
    #[error("operator name: {0}")]
    Name(String),
    /// The broker configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// No connection to the broker now.
    #[error("not connected to the broker{0}")]
    NotConnected(String),
    /// The client's queue is full or closed.
    #[error("cannot queue the message: {0}")]
    Queue(String),
    /// The connection thread could not start.
    #[error("cannot start the MQTT thread: {0}")]
    Thread(std::io::Error),
    /// A command the broker link does not carry (a route's path over
    /// [`crate::wire::MAX_WIRE_PATH_POINTS`], a message over [`crate::wire::MAX_PAYLOAD`], a receiver
    /// spec [`crate::wire::check_remote_receiver`] refuses); not sent.
    #[error("{0}")]
    TooLarge(String),
}

/// Events kept per station.
pub const EVENTS_KEPT: usize = 64;
/// Positions kept per station for its track on a map (the newest; one per state received with a fix).
pub const TRACK_KEPT: usize = 2_000;
/// Stations tracked (more are ignored and counted).
pub const MAX_STATIONS: usize = 256;

/// What the fleet knows of one station.
#[derive(Debug, Clone, Default)]
pub struct StationView {
    /// Its name.
    pub name: String,
    /// Its latest hello (online or offline).
    pub hello: Option<Hello>,
    /// Its latest state.
    pub state: Option<StateMsg>,
    /// When that state arrived [ms since 1970, this machine's clock]: with the station's `at_ms` and the
    /// fix's age, the delay from a fix on the station to this screen (when the two clocks agree).
    pub state_arrived_ms: Option<i64>,
    /// Its route.
    pub route: Option<Arc<RouteMsg>>,
    /// Its latest events, newest last, with their arrival.
    pub events: VecDeque<(Instant, EventMsg)>,
    /// When it was last heard from (a live message, not a retained replay).
    pub last_contact: Option<Instant>,
    /// Its own retained STOP or resume, as the broker holds it.
    pub own_stop: Option<StopOrder>,
    /// Its recent positions `(lat, lon)` [deg], oldest first, at most [`TRACK_KEPT`]: each new fix time
    /// in the states received (a state repeating the same fix adds nothing).
    pub track: VecDeque<(f64, f64)>,
}

impl StationView {
    /// Time since it was last heard from.
    pub fn contact_age(&self, now: Instant) -> Option<Duration> {
        self.last_contact.map(|t| now.saturating_duration_since(t))
    }

    /// Whether it is stale at `now` (never heard live, or silent for longer than `stale_after`).
    pub fn is_stale(&self, now: Instant, stale_after: Duration) -> bool {
        self.contact_age(now).is_none_or(|a| a > stale_after)
    }

    /// Its last contact in words: "0.4 s ago", or "no contact 12 s" when stale.
    pub fn contact_label(&self, now: Instant, stale_after: Duration) -> String {
        match self.contact_age(now) {
            None => "no contact yet".to_owned(),
            Some(a) if a > stale_after => format!("no contact {:.0} s", a.as_secs_f64()),
            Some(a) => format!("{:.1} s ago", a.as_secs_f64()),
        }
    }
}

#[derive(Default)]
struct Shared {
    /// Called after each message taken in (a view's repaint request).
    waker: Option<vestnav_core::Waker>,
    stations: BTreeMap<String, StationView>,
    connected: bool,
    last_error: Option<String>,
    global_stop: Option<StopOrder>,
    ignored: u64,
}

/// The operator's (or an observer's) client (see the module doc).
pub struct Fleet {
    opts: FleetOptions,
    from: Sender,
    client: Client,
    shared: Arc<Mutex<Shared>>,
    seq: AtomicU64,
    continue_route: Arc<Mutex<BTreeSet<String>>>,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Fleet {
    /// Connects to the broker in the background (the thread retries until it is up).
    pub fn connect(config: &BrokerConfig, opts: FleetOptions) -> Result<Self, FleetError> {
        check_name(&opts.operator).map_err(FleetError::Name)?;
        // A new session number per run: the stations tell this run's sequence numbers from the last's.
        let session = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let from = Sender { operator: opts.operator.clone(), session };
        let options = config.mqtt_options(&format!("vestnav-op-{}-{session:x}", opts.operator), None)?;
        let (client, connection) = Client::new(options, 256);
        let shared = Arc::new(Mutex::new(Shared::default()));
        let continue_route = Arc::new(Mutex::new(BTreeSet::new()));
        let quit = Arc::new(AtomicBool::new(false));
        let net = FleetNet {
            client: client.clone(),
            shared: shared.clone(),
            continue_route: continue_route.clone(),
            quit: quit.clone(),
            from: from.clone(),
            opts: opts.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("mqtt-fleet".into())
            .spawn(move || net.run(connection))
            .map_err(FleetError::Thread)?;
        Ok(Self {
            opts,
            from,
            client,
            shared,
            seq: AtomicU64::new(0),
            continue_route,
            quit,
            thread: Some(thread),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Calls `waker` after each message from the broker is taken in (a station's state, route, event or
    /// hello), so a view redraws when a station changes instead of polling.
    pub fn set_waker(&self, waker: vestnav_core::Waker) {
        self.lock().waker = Some(waker);
    }

    /// Whether a waker is set.
    pub fn has_waker(&self) -> bool {
        self.lock().waker.is_some()
    }

    /// The options in force.
    pub fn options(&self) -> &FleetOptions {
        &self.opts
    }

    /// This client as commands name it (a station's events answer `(sender, seq)`).
    pub fn sender(&self) -> &Sender {
        &self.from
    }

    /// Whether the broker connection is up, and the latest connection error.
    pub fn broker_status(&self) -> (bool, Option<String>) {
        let s = self.lock();
        (s.connected, s.last_error.clone())
    }

    /// Every station seen on the broker, by name.
    pub fn stations(&self) -> Vec<StationView> {
        self.lock().stations.values().cloned().collect()
    }

    /// One station.
    pub fn station(&self, name: &str) -> Option<StationView> {
        self.lock().stations.get(name).cloned()
    }

    /// Stations beyond [`MAX_STATIONS`] ignored so far.
    pub fn ignored(&self) -> u64 {
        self.lock().ignored
    }

    fn next_seq(&self) -> u64 {
        self.seq.fetch_add(1, Ordering::Relaxed) + 1
    }

    fn publish(&self, topic: String, retain: bool, bytes: Vec<u8>) -> Result<(), FleetError> {
        self.client
            .try_publish(topic, QoS::AtLeastOnce, retain, bytes)
            .map_err(|e| FleetError::Queue(e.to_string()))
    }

    /// Sends `command` to station `name`; returns its sequence number. Refused while the broker is away (a
    /// command queued now would arrive late; the station would refuse it anyway).
    pub fn send(&self, name: &str, command: Command) -> Result<u64, FleetError> {
        check_name(name).map_err(FleetError::Name)?;
        if !self.lock().connected {
            return Err(FleetError::NotConnected(String::new()));
        }
        crate::wire::check_command(&command).map_err(FleetError::TooLarge)?;
        let seq = self.next_seq();
        let env = Envelope { to: name.to_owned(), from: self.from.clone(), seq, sent_ms: now_ms(), command };
        let bytes = serde_json::to_vec(&env).map_err(|e| FleetError::Queue(e.to_string()))?;
        if bytes.len() > crate::wire::MAX_PAYLOAD {
            return Err(FleetError::TooLarge(format!(
                "{} refused: {} bytes, more than the {} a message over the broker may have",
                env.command.describe(),
                bytes.len(),
                crate::wire::MAX_PAYLOAD
            )));
        }
        self.publish(StationTopic::Cmd.of(name), false, bytes)?;
        Ok(seq)
    }

    fn stop_order(&self, stopped: bool, resumes: Option<(Sender, u64)>) -> Result<Vec<u8>, FleetError> {
        let order =
            StopOrder { stopped, from: self.from.clone(), seq: self.next_seq(), sent_ms: now_ms(), resumes };
        serde_json::to_vec(&order).map_err(|e| FleetError::Queue(e.to_string()))
    }

    /// STOP ALL: every station, as a retained `QoS` 1 order, so a station that (re)connects later stops too.
    /// Queued even while the broker is away (then the error says so: every station has stopped itself
    /// at its link bound meanwhile).
    pub fn stop_all(&self) -> Result<(), FleetError> {
        let bytes = self.stop_order(true, None)?;
        self.publish(STOP_ALL_TOPIC.to_owned(), true, bytes)?;
        self.not_connected_note()
    }

    /// STOPs station `name` (retained, `QoS` 1).
    pub fn stop(&self, name: &str) -> Result<(), FleetError> {
        check_name(name).map_err(FleetError::Name)?;
        let bytes = self.stop_order(true, None)?;
        self.publish(StationTopic::Stop.of(name), true, bytes)?;
        self.not_connected_note()
    }

    /// Resumes station `name`: lifts its own STOP and, for it, the STOP ALL in force (a newer STOP ALL
    /// stops it again).
    pub fn resume(&self, name: &str) -> Result<(), FleetError> {
        check_name(name).map_err(FleetError::Name)?;
        if !self.lock().connected {
            return Err(FleetError::NotConnected(String::new()));
        }
        let lifts = self.lock().global_stop.as_ref().filter(|g| g.stopped).map(|g| (g.from.clone(), g.seq));
        let bytes = self.stop_order(false, lifts)?;
        self.publish(StationTopic::Stop.of(name), true, bytes)
    }

    /// Arms (or disarms) "continue the route if the link drops" for station `name`; it travels in every
    /// heartbeat.
    pub fn set_continue_on_loss(&self, name: &str, armed: bool) {
        let mut c = self.continue_route.lock().unwrap_or_else(PoisonError::into_inner);
        if armed {
            c.insert(name.to_owned());
        } else {
            c.remove(name);
        }
    }

    fn not_connected_note(&self) -> Result<(), FleetError> {
        if self.lock().connected {
            Ok(())
        } else {
            Err(FleetError::NotConnected(
                ": queued; each station stops its vest by itself when its operator link times out".into(),
            ))
        }
    }

    /// Ends the connection (bounded wait).
    pub fn shutdown(&mut self) {
        let Some(thread) = self.thread.take() else { return };
        let _ = self.client.try_disconnect();
        self.quit.store(true, Ordering::Relaxed);
        if crate::broker::wait_for_end(&thread, Duration::from_millis(500)) {
            let _ = thread.join();
        }
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        self.shutdown();
    }
}

struct FleetNet {
    client: Client,
    shared: Arc<Mutex<Shared>>,
    continue_route: Arc<Mutex<BTreeSet<String>>>,
    quit: Arc<AtomicBool>,
    from: Sender,
    opts: FleetOptions,
}

impl FleetNet {
    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn run(self, mut connection: Connection) {
        let mut failures = 0u32;
        let mut next_beat = Instant::now();
        while !self.quit.load(Ordering::Relaxed) {
            let now = Instant::now();
            if self.opts.heartbeats && now >= next_beat {
                next_beat = now + self.opts.heartbeat_every;
                if self.lock().connected {
                    self.beat();
                }
            }
            let wait = next_beat
                .saturating_duration_since(now)
                .clamp(Duration::from_millis(5), Duration::from_millis(100));
            match connection.recv_timeout(wait) {
                Ok(Ok(Event::Incoming(Packet::ConnAck(_)))) => {
                    failures = 0;
                    let mut subs: Vec<SubscribeFilter> = [
                        StationTopic::Hello,
                        StationTopic::State,
                        StationTopic::Event,
                        StationTopic::Route,
                        StationTopic::Stop,
                    ]
                    .into_iter()
                    .map(|k| SubscribeFilter::new(k.all(), QoS::AtLeastOnce))
                    .collect();
                    subs.push(SubscribeFilter::new(STOP_ALL_TOPIC.to_owned(), QoS::AtLeastOnce));
                    let _ = self.client.try_subscribe_many(subs);
                    let mut s = self.lock();
                    s.connected = true;
                    s.last_error = None;
                    drop(s);
                    if self.opts.heartbeats {
                        self.beat();
                    }
                }
                Ok(Ok(Event::Incoming(Packet::Publish(p)))) => self.received(&p.topic, &p.payload, p.retain),
                Ok(Ok(_)) | Err(rumqttc::RecvTimeoutError::Timeout) => {}
                Ok(Err(e)) => {
                    failures += 1;
                    {
                        let mut s = self.lock();
                        s.connected = false;
                        s.last_error = Some(e.to_string());
                    }
                    crate::bridge::backoff(failures, &self.quit);
                }
                Err(rumqttc::RecvTimeoutError::Disconnected) => break,
            }
        }
        self.lock().connected = false;
    }

    fn beat(&self) {
        let continue_route =
            self.continue_route.lock().unwrap_or_else(PoisonError::into_inner).iter().cloned().collect();
        let hb = Heartbeat { from: self.from.clone(), sent_ms: now_ms(), continue_route };
        if let Ok(bytes) = serde_json::to_vec(&hb) {
            let _ =
                self.client.try_publish(heartbeat_topic(&self.from.operator), QoS::AtMostOnce, false, bytes);
        }
    }

    fn received(&self, topic: &str, payload: &[u8], retained: bool) {
        self.take_in(topic, payload, retained);
        let waker = self.lock().waker.clone();
        if let Some(wake) = waker {
            wake();
        }
    }

    fn take_in(&self, topic: &str, payload: &[u8], retained: bool) {
        let now = Instant::now();
        let mut s = self.lock();
        if topic == STOP_ALL_TOPIC {
            s.global_stop = serde_json::from_slice(payload).ok();
            return;
        }
        let Some((name, kind)) = StationTopic::parse(topic) else { return };
        if !s.stations.contains_key(name) {
            if s.stations.len() >= MAX_STATIONS {
                s.ignored += 1;
                return;
            }
            s.stations
                .insert(name.to_owned(), StationView { name: name.to_owned(), ..StationView::default() });
        }
        let Some(v) = s.stations.get_mut(name) else { return };
        // Only what the station itself sent now is contact (its stop topic is the operators').
        let mut contact = !retained && kind != StationTopic::Stop;
        match kind {
            StationTopic::Hello => v.hello = serde_json::from_slice(payload).ok(),
            StationTopic::State => match serde_json::from_slice::<StateMsg>(payload) {
                Ok(m) if m.name == name => {
                    push_track(v, &m);
                    v.state = Some(m);
                    v.state_arrived_ms = Some(now_ms());
                }
                _ => contact = false,
            },
            StationTopic::Event => match serde_json::from_slice::<EventMsg>(payload) {
                Ok(e) => {
                    if v.events.len() >= EVENTS_KEPT {
                        v.events.pop_front();
                    }
                    v.events.push_back((now, e));
                }
                Err(_) => contact = false,
            },
            StationTopic::Route => v.route = serde_json::from_slice(payload).ok().map(Arc::new),
            StationTopic::Stop => v.own_stop = serde_json::from_slice(payload).ok(),
            StationTopic::Cmd => contact = false,
        }
        if contact {
            v.last_contact = Some(now);
        }
    }
}

/// Adds the fix in `m` to `v`'s track when it is a new one with a finite position.
pub(crate) fn push_track(v: &mut StationView, m: &StateMsg) {
    let Some(f) = &m.station.fix else { return };
    let Some((lat, lon)) = f.lat_deg.zip(f.lon_deg) else { return };
    if !(lat.is_finite()
        && lon.is_finite()
        && (-90.0..=90.0).contains(&lat)
        && (-180.0..=180.0).contains(&lon))
    {
        return;
    }
    let same_fix = v.state.as_ref().and_then(|s| s.station.fix.as_ref()).is_some_and(|p| p.time == f.time);
    if same_fix && v.track.back() == Some(&(lat, lon)) {
        return;
    }
    if v.track.len() >= TRACK_KEPT {
        v.track.pop_front();
    }
    v.track.push_back((lat, lon));
}

/// Subscribed filters, for the docs and tests: what an operator or observer reads.
pub fn subscriptions() -> Vec<String> {
    let mut v: Vec<String> = [
        StationTopic::Hello,
        StationTopic::State,
        StationTopic::Event,
        StationTopic::Route,
        StationTopic::Stop,
    ]
    .into_iter()
    .map(StationTopic::all)
    .collect();
    v.push(STOP_ALL_TOPIC.to_owned());
    v.push(HEARTBEATS.to_owned());
    v
}
