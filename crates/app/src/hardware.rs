//! The real devices: `vestnav-device`'s GPS sources and WTCU link behind the console's [`DeviceFactory`].

use std::sync::Arc;

use crate::config::{GpsSourceConfig, VestSourceConfig};
use crate::devices::{DeviceFactory, VestLink, Worker};
use crate::model::{GpsEvent, Outbox, VestEvent};
use crate::route::Waypoint;

/// Opens devices through `vestnav-device`.
#[derive(Debug, Default)]
pub struct Hardware;

impl DeviceFactory for Hardware {
    fn open_gps(
        &self,
        _source: &GpsSourceConfig,
        _route: &[Waypoint],
        _events: Outbox<GpsEvent>,
    ) -> Result<Box<dyn Worker>, String> {
        Err("GPS sources: vestnav-device not wired yet".into())
    }

    fn open_vest(
        &self,
        _source: &VestSourceConfig,
        _events: Outbox<VestEvent>,
    ) -> Result<Arc<dyn VestLink>, String> {
        Err("vest: vestnav-device not wired yet".into())
    }
}
