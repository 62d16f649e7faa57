//! `vestnav analyze tactor-data`: measured tactor traces (thesis §3.1).

use std::path::PathBuf;

use clap::Args;

/// `vestnav analyze tactor-data`
#[derive(Debug, Args)]
pub struct TactorDataArgs {
    /// CSV files: an optional time column and one column per trial.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Sample rate [Hz] when the files have no time column.
    #[arg(long, default_value_t = 10_000.0)]
    pub sample_rate_hz: f64,
    /// Low-pass the traces first (5th-order Butterworth, zero phase) at this cutoff [Hz].
    #[arg(long)]
    pub lowpass_hz: Option<f64>,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `analyze tactor-data`.
pub fn run_tactor_data(args: &TactorDataArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`analyze tactor-data` is being written")
}
