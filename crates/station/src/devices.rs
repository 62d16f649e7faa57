//! How the console opens devices: a small seam between the UI and `vestnav-device`.
//!
//! The console never talks to a port itself. It asks a [`DeviceFactory`] for a GPS source or a vest
//! worker and hands it the [`Outbox`]es of its consumers (the UI, guidance, the session log); the workers
//! deliver the device crate's own events to them directly, with no thread in between. The real factory
//! ([`crate::hardware::Hardware`]) starts the device crate's workers; tests inject their own GPS and give
//! the vest worker their own transport.

use vestnav_device::gps::receiver_config::{ConfigTicket, ReceiverConfig};
use vestnav_device::gps::source::CorrectionsWriter;
use vestnav_device::gps::{GpsEvent, GpsHandle};
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::{VestEvent, VestHandle};

use crate::route::Waypoint;
use crate::sources::{GpsSourceConfig, VestSourceConfig};

/// A running GPS source; stopping it never blocks for long (see [`GpsHandle::stop`]).
pub trait GpsWorker: Send {
    /// Asks the source to stop and release its device.
    fn stop(&mut self);

    /// The pause/seek/progress controls when the source is a replay.
    fn replay_control(&self) -> Option<std::sync::Arc<vestnav_device::gps::ReplayControl>> {
        None
    }

    /// Sends a configuration to the receiver (a direct serial source only); the ticket reports each
    /// command's outcome. Other sources say why they cannot.
    fn configure(&self, config: ReceiverConfig) -> Result<ConfigTicket, String> {
        let _ = config;
        Err(vestnav_device::gps::source::CONFIG_NEEDS_SERIAL.to_owned())
    }

    /// A writer to the receiver's port for RTK corrections (a direct serial source only).
    fn corrections_writer(&self) -> Result<CorrectionsWriter, String> {
        Err(vestnav_device::gps::source::CORRECTIONS_NEED_SERIAL.to_owned())
    }
}

impl GpsWorker for GpsHandle {
    fn stop(&mut self) {
        GpsHandle::stop(self);
    }

    fn replay_control(&self) -> Option<std::sync::Arc<vestnav_device::gps::ReplayControl>> {
        GpsHandle::replay_control(self)
    }

    fn configure(&self, config: ReceiverConfig) -> Result<ConfigTicket, String> {
        GpsHandle::configure(self, config)
    }

    fn corrections_writer(&self) -> Result<CorrectionsWriter, String> {
        GpsHandle::corrections_writer(self)
    }
}

/// Opens devices for the console.
pub trait DeviceFactory {
    /// Starts a GPS source for `source`, delivering every event to every outbox. `route` is what the
    /// simulator walks.
    fn open_gps(
        &self,
        source: &GpsSourceConfig,
        route: &[Waypoint],
        outputs: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String>;

    /// The simulated wearer the simulated devices share, when this factory has one (the real one: the
    /// built-in GPS simulator and the emulated vest's compass), so a calibration can ask it to turn on the
    /// spot.
    fn simulated_wearer(&self) -> Option<vestnav_device::sim::SharedTruth> {
        None
    }

    /// Starts the vest worker for `source`, delivering every event to every outbox.
    fn open_vest(
        &self,
        source: &VestSourceConfig,
        outputs: Vec<Outbox<VestEvent>>,
    ) -> Result<VestHandle, String>;
}
