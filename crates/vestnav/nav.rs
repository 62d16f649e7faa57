//! `vestnav nav simulate`: closed-loop guidance simulation.

use clap::Args;

/// Arguments of `vestnav nav simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {}

/// Runs `vestnav nav simulate`.
pub fn run_simulate(args: &SimulateArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav nav simulate` is being written")
}
