//! Every station an operator drives, whether it is on a broker ([`Fleet`]) or in this process
//! ([`LocalStations`]): one list, one way to send a command, one STOP ALL. A view (the console's Stations
//! window, its map) reads [`StationView`]s and never needs to know which kind a station is, except to
//! offer "Remove" for a local one.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use vestnav_station::command::Command;
use vestnav_station::devices::DeviceFactory;
use vestnav_station::stop::StopPath;

use crate::fleet::{Fleet, FleetError, FleetOptions, StationView};
use crate::local::{LocalStationConfig, LocalStations};
use crate::wire::Sender;

/// Every station of an operator (see the module doc).
pub struct Stations {
    fleet: Option<Fleet>,
    local: LocalStations,
    waker: Option<vestnav_core::Waker>,
}

impl Stations {
    /// No broker and no local station yet. `operator` names this console's commands to local stations;
    /// `stop` is the process's stop path, which local stations join.
    pub fn new(operator: &str, stop: StopPath) -> Self {
        let session = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64);
        let from = Sender { operator: operator.to_owned(), session };
        Self { fleet: None, local: LocalStations::new(from, stop), waker: None }
    }

    /// The broker's stations, when connected.
    pub fn fleet(&self) -> Option<&Fleet> {
        self.fleet.as_ref()
    }

    /// Connects to a broker (replacing the previous connection) or, with `None`, leaves it.
    pub fn set_fleet(&mut self, fleet: Option<Fleet>) {
        self.fleet = fleet;
        if let (Some(f), Some(w)) = (&self.fleet, &self.waker) {
            f.set_waker(w.clone());
        }
    }

    /// The stations of this process.
    pub fn local(&self) -> &LocalStations {
        &self.local
    }

    /// Calls `waker` whenever any station's view changes.
    pub fn set_waker(&mut self, waker: vestnav_core::Waker) {
        if let Some(f) = &self.fleet {
            f.set_waker(waker.clone());
        }
        self.local.set_waker(waker.clone());
        self.waker = Some(waker);
    }

    /// Whether a waker is set.
    pub fn has_waker(&self) -> bool {
        self.waker.is_some()
    }

    /// A station not heard from for longer is stale.
    pub fn stale_after(&self) -> Duration {
        self.fleet
            .as_ref()
            .map_or(FleetOptions::operator("operator").stale_after, |f| f.options().stale_after)
    }

    /// Whether station `name` runs in this process.
    pub fn is_local(&self, name: &str) -> bool {
        self.local.contains(name)
    }

    /// Every station: this process's first, then the broker's (a broker station with a local one's name is
    /// left out: commands by that name go to the local one).
    pub fn stations(&self) -> Vec<StationView> {
        let mut all = self.local.stations();
        if let Some(f) = &self.fleet {
            all.extend(f.stations().into_iter().filter(|v| !self.local.contains(&v.name)));
        }
        all
    }

    /// One station.
    pub fn station(&self, name: &str) -> Option<StationView> {
        if self.local.contains(name) {
            return self.local.station(name);
        }
        self.fleet.as_ref()?.station(name)
    }

    /// Who this console is to station `name` (its events answer commands by this sender).
    pub fn sender_for(&self, name: &str) -> Sender {
        match &self.fleet {
            Some(f) if !self.local.contains(name) => f.sender().clone(),
            _ => self.local.sender().clone(),
        }
    }

    /// Sends `command` to station `name`; returns its sequence number.
    pub fn send(&self, name: &str, command: Command) -> Result<u64, FleetError> {
        if self.local.contains(name) {
            return self.local.send(name, command);
        }
        match &self.fleet {
            Some(f) => f.send(name, command),
            None => Err(FleetError::Name(format!("no station {name:?}"))),
        }
    }

    /// Starts a local station (its name must not be one the broker already has).
    pub fn add_local(
        &mut self,
        config: LocalStationConfig,
        factory: Box<dyn DeviceFactory + Send>,
    ) -> Result<(), String> {
        if self.fleet.as_ref().is_some_and(|f| f.station(&config.name).is_some()) {
            return Err(format!("a station on the broker is already called {:?}", config.name));
        }
        self.local.add(config, factory)
    }

    /// Stops a local station's vest and ends it.
    pub fn remove_local(&mut self, name: &str) {
        self.local.remove(name);
    }

    /// STOP ALL: every vest of this process through the stop path, every local station latched, and every
    /// station on the broker. Returns what did not go as it should (every local vest is stopped anyway).
    pub fn stop_all(&self) -> Result<(), String> {
        let mut problems: Vec<String> = self
            .local
            .stop_all()
            .into_iter()
            .map(|n| format!("station {n} did not take the order"))
            .collect();
        if let Some(f) = &self.fleet
            && let Err(e) = f.stop_all()
        {
            problems.push(e.to_string());
        }
        if problems.is_empty() { Ok(()) } else { Err(problems.join("; ")) }
    }

    /// Stops station `name` only.
    pub fn stop(&self, name: &str) -> Result<(), FleetError> {
        if self.local.contains(name) {
            return self.local.send(name, Command::StopAll).map(|_| ());
        }
        match &self.fleet {
            Some(f) => f.stop(name),
            None => Err(FleetError::Name(format!("no station {name:?}"))),
        }
    }

    /// Resumes station `name`'s automatic cues.
    pub fn resume(&self, name: &str) -> Result<(), FleetError> {
        if self.local.contains(name) {
            return self.local.send(name, Command::Resume).map(|_| ());
        }
        match &self.fleet {
            Some(f) => f.resume(name),
            None => Err(FleetError::Name(format!("no station {name:?}"))),
        }
    }

    /// Ends every local station (their vests stopped) and leaves the broker.
    pub fn shutdown(&mut self) {
        self.local.shutdown();
        if let Some(f) = &mut self.fleet {
            f.shutdown();
        }
    }
}
