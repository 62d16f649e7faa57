//! `vestnav sim two-point | wave`: skin waves and the two-point simulation from the command line.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

/// `vestnav sim two-point`
#[derive(Debug, Args)]
pub struct TwoPointArgs {
    /// Distance between the two tactors [mm].
    #[arg(long, default_value_t = 11.0)]
    pub distance_mm: f64,
    /// Sweep RMSE over distances 0..=max-mm instead of one distance.
    #[arg(long)]
    pub sweep: bool,
    /// Largest distance of the sweep [mm].
    #[arg(long, default_value_t = 100.0)]
    pub max_mm: f64,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure (Figs 60/61 style, or RMSE vs distance with --sweep).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// Which wave figure to produce.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum WaveView {
    /// Amplitude versus distance for the three measured widths (Fig 52).
    Attenuation,
    /// Acceleration versus time at 0, 20, 37, 52 mm (Fig 57).
    Travelling,
    /// Superposed field of firing tactors on the 4x4 vest plane.
    Vest,
    /// The two-tactor midpoint signal (80 mm apart).
    Midpoint,
}

/// `vestnav sim wave`
#[derive(Debug, Args)]
pub struct WaveArgs {
    /// What to compute.
    #[arg(long, value_enum, default_value = "attenuation")]
    pub view: WaveView,
    /// For `vest`: tactor indices 0..16 that fire (row-major from the wearer's upper left, seen from behind).
    #[arg(long, value_delimiter = ',', default_value = "5")]
    pub tactors: Vec<usize>,
    /// For `vest`: centre-to-centre tactor spacing [mm].
    #[arg(long, default_value_t = 60.0)]
    pub spacing_mm: f64,
    /// For `vest` and `travelling`: time [s] of the snapshot.
    #[arg(long, default_value_t = 0.0)]
    pub time_s: f64,
    /// Print the numbers as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure.
    #[arg(long)]
    pub png: Option<PathBuf>,
}


/// Runs `sim two-point`.
pub fn run_two_point(args: &TwoPointArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`sim two-point` is being written")
}

/// Runs `sim wave`.
pub fn run_wave(args: &WaveArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`sim wave` is being written")
}
