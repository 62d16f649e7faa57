//! `vestnav fieldtest drift | cones`: GPS accuracy field tests (thesis §5).

use clap::Args;

/// Arguments of `vestnav fieldtest drift`.
#[derive(Debug, Args)]
pub struct DriftArgs {}

/// Arguments of `vestnav fieldtest cones`.
#[derive(Debug, Args)]
pub struct ConesArgs {}

/// Runs `vestnav fieldtest drift`.
pub fn run_drift(args: &DriftArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav fieldtest drift` is being written")
}

/// Runs `vestnav fieldtest cones`.
pub fn run_cones(args: &ConesArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`vestnav fieldtest cones` is being written")
}
