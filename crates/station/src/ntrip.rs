//! RTK corrections for the station's receiver: device's NTRIP client on its own `ntrip` thread, writing
//! each verified RTCM 3 frame to the serial GPS source's port through the source's write handle
//! (`GpsHandle::corrections_writer`), with the receiver's latest GGA sent upstream. Nothing here waits on
//! the network: starting spawns the thread, stopping only asks it to stop, and each pump copies the
//! client's status snapshot. A lost, stalled or refusing caster shows in that status; the GPS reader and
//! everything else go on.
//!
//! Credentials come from a file (`user:password`, private: see `vestnav_device::ntrip::read_credentials`);
//! the settings hold only the file's name. The file is read on a short-lived `ntrip-start` thread, which then
//! starts the client: a slow or hostile file (a FIFO is refused by `vestnav-files`, the size is limited)
//! never holds the view's turn; its error shows as the corrections' failed state.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use vestnav_device::gps::RawLine;
use vestnav_device::ntrip::{
    NtripConfig, NtripHandle, NtripState, NtripStatus, NtripVersion, read_credentials,
};

use crate::Station;

/// Where the corrections come from (saved in the console's settings: never a password).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NtripSettings {
    /// The caster, `HOST:PORT` (plain TCP, usually port 2101).
    pub caster: String,
    /// The mountpoint (stream).
    pub mountpoint: String,
    /// The file holding `user:password` (readable by its owner only), if the caster wants credentials.
    pub credentials_file: Option<PathBuf>,
    /// Protocol version.
    pub version: NtripVersion,
    /// Send the receiver's GGA upstream every this many seconds (0: never).
    pub gga_every_s: f64,
    /// No byte from the caster for this many seconds is a stall: shown, then reconnected.
    pub stall_s: f64,
}

impl Default for NtripSettings {
    fn default() -> Self {
        Self {
            caster: String::new(),
            mountpoint: String::new(),
            credentials_file: None,
            version: NtripVersion::V2,
            gga_every_s: 10.0,
            stall_s: 10.0,
        }
    }
}

impl NtripSettings {
    /// The client's configuration, with the credentials read from their file. Errors name what is wrong.
    pub fn config(&self) -> Result<NtripConfig, String> {
        let mut c = self.checked()?;
        c.credentials = self.credentials()?;
        Ok(c)
    }

    /// The credentials read from their file (`None` without a file).
    fn credentials(&self) -> Result<Option<vestnav_device::ntrip::Credentials>, String> {
        match &self.credentials_file {
            Some(p) if !p.as_os_str().is_empty() => Ok(Some(read_credentials(p).map_err(|e| e.to_string())?)),
            _ => Ok(None),
        }
    }

    /// The client's configuration without the credentials: the settings checked, no file read.
    fn checked(&self) -> Result<NtripConfig, String> {
        let caster = self.caster.trim();
        if caster.is_empty() || !caster.contains(':') {
            return Err("NTRIP: give the caster as HOST:PORT".into());
        }
        if self.mountpoint.trim().trim_start_matches('/').is_empty() {
            return Err("NTRIP: give the mountpoint".into());
        }
        let seconds = |name: &str, s: f64| {
            Duration::try_from_secs_f64(s)
                .map_err(|_| format!("NTRIP: {name} must be a non-negative number of seconds"))
        };
        let mut c = NtripConfig::new(caster, self.mountpoint.trim());
        c.version = self.version;
        let gga = seconds("the GGA interval", self.gga_every_s)?;
        c.gga_every = (!gga.is_zero()).then_some(gga);
        c.stall_after = seconds("the stall time", self.stall_s)?.max(Duration::from_millis(200));
        Ok(c)
    }
}

/// The corrections as the station holds them: the running (or ending) client and its latest status.
pub struct Corrections {
    handle: Option<NtripHandle>,
    /// The client being started on the `ntrip-start` thread (credentials read, then spawned).
    starting: Option<Arc<Starting>>,
    /// What it was started with.
    pub settings: NtripSettings,
    /// The client's status at the last pump.
    pub status: NtripStatus,
    /// Why the station stopped it (the GPS source changed), if it did.
    pub ended: Option<String>,
}

impl Corrections {
    /// Whether the client is still meant to run (not stopped, not failed).
    pub fn running(&self) -> bool {
        self.ended.is_none() && !matches!(self.status.state, NtripState::Failed { .. } | NtripState::Stopped)
    }
}

impl Drop for Corrections {
    /// The client's thread is told to stop and released on a thread of its own: dropping never waits on
    /// the network (a connection attempt in progress ends by its own timeout).
    fn drop(&mut self) {
        if let Some(s) = self.starting.take() {
            s.cancel();
        }
        if let Some(h) = self.handle.take() {
            h.request_stop();
            let released = std::thread::Builder::new().name("ntrip-stop".into()).spawn(move || drop(h));
            if let Err(e) = released {
                tracing::warn!("ntrip: not released on a thread: {e}");
            }
        }
    }
}

/// The client being started on the `ntrip-start` thread: its result, or that nobody wants it any more.
#[derive(Default)]
struct Starting(Mutex<(bool, Option<Result<NtripHandle, String>>)>);

impl Starting {
    /// The starting thread's result; a client nobody wants any more is stopped at once.
    fn put(&self, started: Result<NtripHandle, String>) {
        let mut s = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        if s.0 {
            if let Ok(h) = started {
                h.request_stop();
            }
        } else {
            s.1 = Some(started);
        }
    }

    /// The result, once there.
    fn take(&self) -> Option<Result<NtripHandle, String>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).1.take()
    }

    /// Nobody wants the client any more: a started one is stopped, one still starting stops when it is.
    fn cancel(&self) {
        let mut s = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        s.0 = true;
        if let Some(Ok(h)) = s.1.take() {
            h.request_stop();
        }
    }
}

/// A correction older than this is shown as old (receivers drop RTK after 10–60 s without corrections).
pub const OLD_CORRECTION: Duration = Duration::from_secs(5);

impl Station {
    /// Starts RTK corrections to the running GPS source's receiver (a direct serial source only). Replaces a
    /// running client. Errors say what is missing (the source, the settings, the credentials file).
    pub fn start_ntrip(&mut self, settings: NtripSettings) -> Result<(), String> {
        let mut config = settings.checked()?;
        let writer = match self.gps_worker.as_deref() {
            Some(w) => w.corrections_writer()?,
            None => return Err("NTRIP: connect the GPS receiver's serial port first".into()),
        };
        self.stop_ntrip();
        let starting = Arc::new(Starting::default());
        let slot = starting.clone();
        let reader = settings.clone();
        std::thread::Builder::new()
            .name("ntrip-start".into())
            .spawn(move || {
                let started = reader.credentials().and_then(|credentials| {
                    config.credentials = credentials;
                    vestnav_device::ntrip::spawn(config, Box::new(writer))
                        .map_err(|e| format!("NTRIP: cannot start its thread: {e}"))
                });
                slot.put(started);
            })
            .map_err(|e| format!("NTRIP: cannot start: {e}"))?;
        self.ntrip = Some(Corrections {
            handle: None,
            starting: Some(starting),
            settings,
            status: NtripStatus::new(),
            ended: None,
        });
        Ok(())
    }

    /// Stops the corrections (without waiting: the thread ends by itself within a moment).
    pub fn stop_ntrip(&mut self) {
        let Some(c) = &mut self.ntrip else { return };
        if let Some(s) = c.starting.take() {
            s.cancel();
            c.status.state = NtripState::Stopped;
        }
        if let Some(h) = &c.handle {
            h.request_stop();
            c.status.state = NtripState::Stopped;
        }
    }

    /// The corrections, if they were started this session.
    pub fn ntrip(&self) -> Option<&Corrections> {
        self.ntrip.as_ref()
    }

    /// The corrections' one status line at `now` ([`NtripStatus::line`], with the receiver's fix quality
    /// from its latest fix), if they were started.
    pub fn ntrip_line(&self, now: Instant) -> Option<String> {
        let c = self.ntrip.as_ref()?;
        let quality = self.gps.fix.as_ref().and_then(|f| f.quality);
        Some(c.status.line(quality, now))
    }

    /// The GPS source is going: corrections to its port end with it, and say why.
    pub(crate) fn end_ntrip(&mut self, why: &str) {
        if self.ntrip.as_ref().is_some_and(Corrections::running) {
            self.stop_ntrip();
            if let Some(c) = &mut self.ntrip {
                c.ended = Some(why.to_owned());
            }
        }
    }

    /// Hands the receiver's GGA sentence to the client (sent upstream every `gga_every_s`).
    pub(crate) fn ntrip_gga(&self, line: &RawLine) {
        if let Some(h) = self.ntrip.as_ref().and_then(|c| c.handle.as_ref())
            && line.text.get(3..7) == Some("GGA,")
        {
            h.set_gga(&line.text);
        }
    }

    /// Copies the client's status (a mutex held only for the copy); a stopped client's thread is
    /// released once it has ended.
    pub(crate) fn pump_ntrip(&mut self) {
        let Some(c) = &mut self.ntrip else { return };
        if let Some(started) = c.starting.as_ref().and_then(|s| s.take()) {
            c.starting = None;
            match started {
                Ok(h) => c.handle = Some(h),
                Err(reason) => c.status.state = NtripState::Failed { reason },
            }
        }
        let Some(h) = &c.handle else { return };
        let stopping = c.status.state == NtripState::Stopped;
        let mut status = h.status();
        if stopping && status.state != NtripState::Stopped {
            status.state = NtripState::Stopped;
        }
        c.status = status;
        if h.is_finished() {
            c.handle = None;
        }
    }
}
