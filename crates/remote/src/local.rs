//! Stations in this process: a second (third…) vest and GPS on this machine's own ports, driven from the
//! same console as its own station, with no broker. Each runs on its own `station-NAME` thread, which owns
//! the [`Station`] and turns it as `vestnav station` does; the console sees it through the same
//! [`StationView`] as a station on a broker (so the Stations window, the drive controls and the map are
//! one code for both), and drives it through the same [`Command`]s.
//!
//! Safety: every local station shares the console's [`StopPath`] (each under its own id), so the
//! console's STOP ALL, a signal and every exit reach its vest with no thread in the way, the station's
//! thread included. A station's own Stop reaches only its vest. Removing a station (or dropping
//! [`LocalStations`]) stops its vest and closes its devices.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_station::command::Command;
use vestnav_station::devices::DeviceFactory;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig};
use vestnav_station::stop::{EXIT_STOP_WAIT, StopPath};
use vestnav_station::{Liveness, RouteStart, Station, StationOptions, StationSettings};

use crate::fleet::{EVENTS_KEPT, FleetError, StationView, push_track};
use crate::wire::{
    EventKind, EventMsg, Hello, LinkReport, RouteMsg, SCHEMA, Sender, StateMsg, check_name, now_ms,
};

/// Most local stations in one process (each holds two ports and three threads).
pub const MAX_LOCAL: usize = 8;
/// Commands queued to one station's thread.
const QUEUE: usize = 64;
/// The thread's turn: it pumps the station at least this often.
const TURN: Duration = Duration::from_millis(20);
/// A new station's thread says its stop-path id within this (building a station loads nothing large: no
/// route file, no autosave).
const STARTUP: Duration = Duration::from_secs(5);
/// Its state is copied for the views at least this often, and on change.
const STATE_EVERY: Duration = Duration::from_secs(1);

/// Where a local station's devices are.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalStationConfig {
    /// Its name (a topic level's rules: letters, digits, `-`, `_`).
    pub name: String,
    /// Its vest.
    pub vest: VestSourceConfig,
    /// Its GPS.
    pub gps: GpsSourceConfig,
    /// Where its session log goes (`None`: no log).
    pub log_dir: Option<PathBuf>,
}

enum Order {
    Command { seq: u64, command: Command },
}

struct Member {
    /// Its vest's id on the stop path.
    stop_id: u64,
    orders: SyncSender<Order>,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

#[derive(Default)]
struct Shared {
    views: BTreeMap<String, StationView>,
    waker: Option<vestnav_core::Waker>,
}

/// Every local station of this process (see the module doc).
pub struct LocalStations {
    from: Sender,
    stop: StopPath,
    shared: Arc<Mutex<Shared>>,
    members: BTreeMap<String, Member>,
    seq: AtomicU64,
}

impl LocalStations {
    /// No station yet. `from` names the commands (the console's operator), `stop` is the process's stop
    /// path (the console's), which every local station joins.
    pub fn new(from: Sender, stop: StopPath) -> Self {
        Self { from, stop, shared: Arc::default(), members: BTreeMap::new(), seq: AtomicU64::new(0) }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Calls `waker` whenever a station's view changes (a repaint request).
    pub fn set_waker(&self, waker: vestnav_core::Waker) {
        self.lock().waker = Some(waker);
    }

    /// This client as the stations' events name it.
    pub fn sender(&self) -> &Sender {
        &self.from
    }

    /// Whether a local station is called `name`.
    pub fn contains(&self, name: &str) -> bool {
        self.members.contains_key(name)
    }

    /// How many run.
    pub fn len(&self) -> usize {
        self.members.len()
    }

    /// Whether none runs.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// Starts a station on its own thread with the devices of `config`, made by `factory`; it connects
    /// them at once (a port that fails is said in its notices and its view, as for the console's own).
    pub fn add(
        &mut self,
        config: LocalStationConfig,
        factory: Box<dyn DeviceFactory + Send>,
    ) -> Result<(), String> {
        check_name(&config.name).map_err(|e| format!("station name: {e}"))?;
        if self.members.contains_key(&config.name) {
            return Err(format!("a local station is already called {:?}", config.name));
        }
        if self.members.len() >= MAX_LOCAL {
            return Err(format!("at most {MAX_LOCAL} local stations"));
        }
        let name = config.name.clone();
        let stop = self.stop.clone();
        let (orders, rx) = sync_channel(QUEUE);
        let quit = Arc::new(AtomicBool::new(false));
        self.lock().views.insert(
            name.clone(),
            StationView {
                name: name.clone(),
                hello: Some(Hello {
                    name: name.clone(),
                    online: true,
                    schema: SCHEMA.into(),
                    link_bound_s: 0.0,
                }),
                ..StationView::default()
            },
        );
        let turn = Turn {
            name: name.clone(),
            from: self.from.clone(),
            shared: self.shared.clone(),
            quit: quit.clone(),
            state_seq: 0,
            last_state: None,
            route_sent: None,
        };
        // The station is built on its own thread (its devices are that thread's); it says its vest's id
        // on the stop path first.
        let (id_tx, id_rx) = sync_channel(1);
        let LocalStationConfig { vest, gps, log_dir, .. } = config;
        let spawned = std::thread::Builder::new().name(format!("station-{name}")).spawn(move || {
            let station = Station::new(
                factory,
                StationOptions {
                    settings: StationSettings::default(),
                    gps: Some(gps),
                    vest: Some(vest),
                    log_dir,
                    waker: None,
                    liveness: Some(Liveness { view: None, ..Liveness::default() }),
                    stop,
                    route: RouteStart { file: None, autosave: None },
                },
            );
            let _ = id_tx.send(station.stop_id());
            turn.run(station, &rx);
        });
        let started = spawned.map_err(|e| format!("cannot start station {name}: {e}")).and_then(|thread| {
            if let Ok(stop_id) = id_rx.recv_timeout(STARTUP) {
                Ok((thread, stop_id))
            } else {
                quit.store(true, Ordering::Relaxed);
                Err(format!("station {name} did not start within {} s", STARTUP.as_secs()))
            }
        });
        let (thread, stop_id) = match started {
            Ok(t) => t,
            Err(e) => {
                self.lock().views.remove(&name);
                return Err(e);
            }
        };
        self.members.insert(name, Member { stop_id, orders, quit, thread: Some(thread) });
        Ok(())
    }

    /// Stops station `name`'s vest, closes its devices and forgets it (bounded wait).
    pub fn remove(&mut self, name: &str) {
        if let Some(mut m) = self.members.remove(name) {
            end(&mut m);
        }
        self.lock().views.remove(name);
    }

    /// Every local station as last turned, by name.
    pub fn stations(&self) -> Vec<StationView> {
        self.lock().views.values().cloned().collect()
    }

    /// One station.
    pub fn station(&self, name: &str) -> Option<StationView> {
        self.lock().views.get(name).cloned()
    }

    /// Sends `command` to station `name`; returns its sequence number (its event answers it). A STOP ALL
    /// reaches the vest through the stop path first, then the station.
    pub fn send(&self, name: &str, command: Command) -> Result<u64, FleetError> {
        let m =
            self.members.get(name).ok_or_else(|| FleetError::Name(format!("no local station {name:?}")))?;
        let stop = command == Command::StopAll;
        if stop {
            self.stop.stop(m.stop_id);
        }
        let seq = self.seq.fetch_add(1, Ordering::Relaxed) + 1;
        match m.orders.try_send(Order::Command { seq, command }) {
            Ok(()) => Ok(seq),
            Err(TrySendError::Full(_)) => Err(FleetError::Queue(format!("station {name} is busy"))),
            Err(TrySendError::Disconnected(_)) => Err(FleetError::Queue(format!("station {name} has ended"))),
        }
    }

    /// STOP ALL for every local station: every vest on the stop path now, then each station latches its
    /// automatic cues off. Returns the stations whose thread could not take the order (their vest is
    /// stopped all the same).
    pub fn stop_all(&self) -> Vec<String> {
        self.stop.stop_all();
        self.members.keys().filter(|n| self.send(n, Command::StopAll).is_err()).cloned().collect()
    }

    /// Stops every station and waits (bounded) for each to close.
    pub fn shutdown(&mut self) {
        for m in self.members.values_mut() {
            m.quit.store(true, Ordering::Relaxed);
        }
        for (_, mut m) in std::mem::take(&mut self.members) {
            end(&mut m);
        }
        self.lock().views.clear();
    }
}

impl Drop for LocalStations {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Asks a station's thread to end and waits for it a bounded time (its vest's STOP ALL frame and close
/// take at most [`EXIT_STOP_WAIT`]; the GPS close is bounded too).
fn end(m: &mut Member) {
    m.quit.store(true, Ordering::Relaxed);
    if let Some(t) = m.thread.take()
        && crate::broker::wait_for_end(&t, EXIT_STOP_WAIT + Duration::from_secs(1))
    {
        let _ = t.join();
    }
}

/// A station's thread.
struct Turn {
    name: String,
    from: Sender,
    shared: Arc<Mutex<Shared>>,
    quit: Arc<AtomicBool>,
    state_seq: u64,
    last_state: Option<(Instant, vestnav_station::command::Snapshot)>,
    route_sent: Option<u64>,
}

impl Turn {
    fn run(mut self, mut station: Station, orders: &Receiver<Order>) {
        station.connect_vest();
        station.connect_gps(Vec::new());
        loop {
            station.pump(|_| {});
            self.publish(&station, Instant::now());
            if self.quit.load(Ordering::Relaxed) {
                break;
            }
            match orders.recv_timeout(TURN) {
                Ok(Order::Command { seq, command }) => self.apply(&mut station, seq, command),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        station.shutdown();
        let mut s = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(v) = s.views.get_mut(&self.name)
            && let Some(h) = &mut v.hello
        {
            h.online = false;
        }
    }

    fn apply(&self, station: &mut Station, seq: u64, command: Command) {
        let what = command.describe();
        let (kind, text) = match station.apply(command) {
            Ok(()) => (EventKind::Applied, format!("{what} (#{seq})")),
            Err(e) => (EventKind::Refused, e),
        };
        let msg = EventMsg { at_ms: now_ms(), kind, answers: Some((self.from.clone(), seq)), text };
        let mut s = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(v) = s.views.get_mut(&self.name) {
            if v.events.len() >= EVENTS_KEPT {
                v.events.pop_front();
            }
            v.events.push_back((Instant::now(), msg));
        }
        wake(&s);
    }

    /// Copies the station's state (on change, and at least every [`STATE_EVERY`]) and its route (on a new
    /// revision) into its view; the copy's time is the contact.
    fn publish(&mut self, station: &Station, now: Instant) {
        let snap = station.snapshot(now);
        let due = self.last_state.as_ref().is_none_or(|(t, last)| {
            now.saturating_duration_since(*t) >= STATE_EVERY || last.without_ages() != snap.without_ages()
        });
        let route = station.route();
        let route_due = self.route_sent != Some(route.revision());
        if !due && !route_due {
            return;
        }
        let mut s = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(v) = s.views.get_mut(&self.name) else { return };
        if route_due {
            v.route = Some(std::sync::Arc::new(RouteMsg::of(route)));
            self.route_sent = Some(route.revision());
        }
        if due {
            self.state_seq += 1;
            let msg = StateMsg {
                name: self.name.clone(),
                at_ms: now_ms(),
                seq: self.state_seq,
                // In the same process: the console is always in contact, and its exit stops the vest.
                link: LinkReport {
                    operator_contact: true,
                    heartbeat_age_s: None,
                    bound_s: 0.0,
                    continue_armed: false,
                    on_loss: None,
                    stop_in_force: snap.stop.is_some(),
                },
                station: snap.clone(),
            };
            push_track(v, &msg);
            v.state = Some(msg);
            v.state_arrived_ms = Some(now_ms());
            v.last_contact = Some(now);
            self.last_state = Some((now, snap));
        }
        wake(&s);
    }
}

fn wake(s: &Shared) {
    if let Some(w) = &s.waker {
        w();
    }
}
