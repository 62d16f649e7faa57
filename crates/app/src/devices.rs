//! How the console opens devices: a small seam between the UI and `vestnav-device`.
//!
//! The console never talks to a port itself. It asks a [`DeviceFactory`] for a GPS worker or a vest link;
//! the real factory ([`crate::hardware::Hardware`]) starts the device crate's worker threads, tests can
//! inject their own. Workers report through an [`Outbox`] (bounded, never blocking, waking the UI).

use std::sync::Arc;

use crate::config::{GpsSourceConfig, VestSourceConfig};
use crate::model::{GpsEvent, Outbox, VestCommand, VestEvent};
use crate::route::Waypoint;

/// A running worker; dropping or stopping it ends its thread.
pub trait Worker: Send {
    /// Asks the worker to stop and release its device.
    fn stop(&mut self);
}

/// A connected vest: commands go to its worker thread, which owns the link.
pub trait VestLink: Send + Sync {
    /// Queues a command for the unit; an error means it could not even be queued (worker gone, invalid).
    fn send(&self, command: VestCommand) -> Result<(), String>;
    /// Stops every tactor, closes the link and ends the worker.
    fn close(&self);
}

/// Opens devices for the console.
pub trait DeviceFactory {
    /// Starts a GPS worker for `source`. `route` is what the simulator walks.
    fn open_gps(
        &self,
        source: &GpsSourceConfig,
        route: &[Waypoint],
        events: Outbox<GpsEvent>,
    ) -> Result<Box<dyn Worker>, String>;

    /// Starts a vest link for `source`.
    fn open_vest(
        &self,
        source: &VestSourceConfig,
        events: Outbox<VestEvent>,
    ) -> Result<Arc<dyn VestLink>, String>;
}
