//! `vestnav emulate gps`: an NMEA GPS emulator on a pseudo-terminal.

use clap::Args;

/// Arguments of `vestnav emulate gps`.
#[derive(Debug, Args)]
pub struct GpsArgs {}

/// Runs `vestnav emulate gps`.
pub fn run(args: &GpsArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav emulate gps` is being written")
}
