//! `vestnav nmea decode | record`.

use clap::Args;

/// Arguments of `vestnav nmea decode`.
#[derive(Debug, Args)]
pub struct DecodeArgs {}

/// Arguments of `vestnav nmea record`.
#[derive(Debug, Args)]
pub struct RecordArgs {}

/// Runs `vestnav nmea decode`.
pub fn run_decode(args: &DecodeArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav nmea decode` is being written")
}

/// Runs `vestnav nmea record`.
pub fn run_record(args: &RecordArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav nmea record` is being written")
}
