//! `vestnav emulate vest`: the WTCU emulator on a pseudo-terminal.

use clap::Args;

/// Arguments of `vestnav emulate vest`.
#[derive(Debug, Args)]
pub struct VestArgs {}

/// Runs `vestnav emulate vest`.
pub fn run(args: &VestArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav emulate vest` is being written")
}
