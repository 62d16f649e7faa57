//! GPS sources served by `vestnav-device` workers: serial/Bluetooth ports, NMEA replay, gpsd.

use crate::config::GpsSourceConfig;
use crate::devices::Worker;
use crate::model::{GpsEvent, Outbox};

/// Starts the device crate's worker for `source`.
pub fn open(source: &GpsSourceConfig, _events: Outbox<GpsEvent>) -> Result<Box<dyn Worker>, String> {
    Err(format!("{} is not available in this build yet", crate::console::source_kind(source)))
}
