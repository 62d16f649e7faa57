//! `--lsl` and `--osc HOST:PORT`: the lab outputs of a command that runs a station (`vestnav station`; a
//! study run), one definition for all of them.

use anyhow::Context as _;
use vestnav_station::Station;
use vestnav_station::lab::{LabConfig, parse_osc_target};

/// The lab-output options.
#[derive(Debug, Clone, clap::Args)]
pub struct LabArgs {
    /// Lab Streaming Layer streams: markers, position, heading and vest traffic, named after the station
    /// (else "vestnav"); needs liblsl (`pip install pylsl` carries it; docs/study.md).
    #[arg(long)]
    pub lsl: bool,
    /// Open Sound Control messages to HOST:PORT over UDP: /vestnav/marker, /vestnav/position,
    /// /vestnav/heading, /vestnav/vest (docs/study.md).
    #[arg(long, value_name = "HOST:PORT", value_parser = parse_osc_target)]
    pub osc: Option<std::net::SocketAddr>,
}

impl LabArgs {
    /// The configuration, streams named after `name`.
    pub fn config(&self, name: Option<&str>) -> LabConfig {
        LabConfig { lsl: self.lsl, osc: self.osc, stream_prefix: name.unwrap_or("vestnav").to_owned() }
    }

    /// Starts what was asked for on `station`; one that cannot start is the run's error (asked for on the
    /// command line, so nothing moves without it). Says on stderr what runs.
    pub fn start(&self, station: &mut Station, name: Option<&str>) -> anyhow::Result<()> {
        let cfg = self.config(name);
        if cfg.any() {
            station.set_lab(Some(&cfg)).context("lab outputs")?;
            if let Some(s) = station.lab_status() {
                eprintln!("vestnav: {}", s.summary());
            }
        }
        Ok(())
    }
}
