//! How the station feeds its lab outputs: every fix with a position and every heading reading from the GPS
//! source's thread, every acknowledgement and refusal from the vest worker's thread (both as outbox sinks,
//! stamped with the event's arrival where it has one), every command as it is sent (the station's commands
//! from the view's thread, guidance's cues from the guidance thread). None of them waits: each call is a
//! queue put (see the module above). The stop path is untouched: STOP ALL is recorded after it was
//! requested.

use std::sync::{Arc, RwLock};

use vestnav_device::gps::GpsEvent;
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::{CommandOrigin, VestCommand, VestEvent};

use super::{LabConfig, LabError, LabOutputs, LabStatus};
use crate::Station;

/// The station's lab outputs as every feeding thread sees them: swapped whole when the operator turns them
/// on or off, so sinks attached before that follow.
#[derive(Clone)]
pub struct LabTap(Arc<RwLock<Slot>>);

struct Slot {
    outputs: LabOutputs,
    /// The configuration asked for, while one is.
    config: Option<LabConfig>,
    /// Why the outputs asked for could not start.
    failed: Option<LabStatus>,
}

impl Default for LabTap {
    fn default() -> Self {
        Self(Arc::new(RwLock::new(Slot { outputs: LabOutputs::disabled(), config: None, failed: None })))
    }
}

impl LabTap {
    /// The outputs in force (disabled ones when off: their clock is still the session's).
    pub fn outputs(&self) -> LabOutputs {
        match self.0.read() {
            Ok(s) => s.outputs.clone(),
            Err(p) => p.into_inner().outputs.clone(),
        }
    }

    fn with(&self, f: impl FnOnce(&LabOutputs)) {
        if let Ok(s) = self.0.read()
            && s.outputs.is_on()
        {
            f(&s.outputs);
        }
    }

    /// A command handed to the vest worker by `origin`.
    pub fn command(&self, origin: CommandOrigin, command: &VestCommand) {
        self.with(|lab| {
            let who = match origin {
                CommandOrigin::Manual => "manual",
                CommandOrigin::Guidance => "guidance",
            };
            lab.vest(&format!("sent {who} {}", command.describe()), lab.now());
        });
    }

    fn gps(&self, ev: &GpsEvent) {
        self.with(|lab| match ev {
            GpsEvent::Fix(f) => {
                if let (Some(lat), Some(lon)) = (f.lat_deg, f.lon_deg) {
                    let at = f.received_at.map_or_else(|| lab.now(), |t| lab.at(t));
                    let acc = f.error.as_ref().map_or(f64::NAN, |e| e.horizontal_m);
                    lab.position(lat, lon, acc, at);
                }
            }
            GpsEvent::Attitude(a) => lab.heading(a.heading_deg, lab.at(a.received_at)),
            _ => {}
        });
    }

    fn vest_event(&self, ev: &VestEvent) {
        self.with(|lab| match ev {
            VestEvent::Acked { seq, kind } => lab.vest(&format!("ack {} #{seq}", kind.name()), lab.now()),
            VestEvent::Rejected { kind, origin, reason } => {
                let who = match origin {
                    Some(CommandOrigin::Guidance) => " guidance",
                    Some(CommandOrigin::Manual) => " manual",
                    None => "",
                };
                lab.vest(&format!("refused{who} {}: {reason}", kind.name()), lab.now());
            }
            VestEvent::Halted { reason } => lab.vest(&format!("halted: {reason}"), lab.now()),
            VestEvent::Resumed => lab.vest("resumed", lab.now()),
            VestEvent::Heading(a) => lab.heading(a.heading_deg, lab.at(a.received_at)),
            _ => {}
        });
    }

    /// The GPS source's outbox into the lab outputs.
    pub(crate) fn gps_sink(&self) -> Outbox<GpsEvent> {
        let tap = self.clone();
        Outbox::sink(move |ev: GpsEvent| {
            tap.gps(&ev);
            true
        })
    }

    /// The vest worker's outbox into the lab outputs.
    pub(crate) fn vest_sink(&self) -> Outbox<VestEvent> {
        let tap = self.clone();
        Outbox::sink(move |ev: VestEvent| {
            tap.vest_event(&ev);
            true
        })
    }

    /// The status a screen shows (`None`: no lab output asked for).
    pub fn status(&self) -> Option<LabStatus> {
        let s = self.0.read().ok()?;
        s.config.as_ref()?;
        s.failed.clone().or_else(|| Some(s.outputs.status()))
    }

    fn replace(&self, outputs: LabOutputs, config: Option<LabConfig>, failed: Option<LabStatus>) {
        let slot = Slot { outputs, config, failed };
        match self.0.write() {
            Ok(mut s) => *s = slot,
            Err(p) => *p.into_inner() = slot,
        }
    }
}

impl Station {
    /// Starts the lab outputs `cfg` asks for (LSL streams, OSC), replacing any running ones; `None` or a
    /// configuration asking for nothing turns them off. When they cannot start, the error is returned and
    /// shown in [`Self::lab_status`] (e.g. liblsl missing: what was tried and how to install it).
    pub fn set_lab(&mut self, cfg: Option<&LabConfig>) -> Result<(), LabError> {
        let Some(cfg) = cfg.filter(|c| c.any()) else {
            self.lab.replace(LabOutputs::disabled(), None, None);
            return Ok(());
        };
        // The old outlets close before the new ones open (same stream names).
        self.lab.replace(LabOutputs::disabled(), None, None);
        self.install_lab(cfg, LabOutputs::start(cfg))
    }

    /// Puts in force outputs started elsewhere (a view starts them on its own thread: finding liblsl may
    /// take a moment), or the error they ended with, as [`Self::set_lab`] does. Turn the old ones off first
    /// (`set_lab(None)`), so two outlets never share a name.
    pub fn install_lab(
        &mut self,
        cfg: &LabConfig,
        started: Result<LabOutputs, LabError>,
    ) -> Result<(), LabError> {
        match started {
            Ok(o) => {
                self.lab.replace(o, Some(cfg.clone()), None);
                Ok(())
            }
            Err(e) => {
                self.lab.replace(LabOutputs::disabled(), Some(cfg.clone()), Some(LabStatus::failed(cfg, &e)));
                Err(e)
            }
        }
    }

    /// The lab outputs in force, for a study runner's markers (disabled ones when off).
    pub fn lab(&self) -> LabOutputs {
        self.lab.outputs()
    }

    /// The lab outputs' configuration in force (`None`: off).
    pub fn lab_config(&self) -> Option<LabConfig> {
        self.lab.0.read().ok().and_then(|s| s.config.clone())
    }

    /// What a screen shows of the lab outputs (`None`: none asked for).
    pub fn lab_status(&self) -> Option<LabStatus> {
        self.lab.status()
    }
}
