//! `vestnav sim tactor | sweep | damping-for`: the tactor model from the command line.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

/// Parameter preset of the tactor model.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PresetArg {
    /// R = 62 ohm, the value the thesis's simulations used.
    ThesisSim,
    /// R = 67 ohm, as measured.
    Measured,
}

/// Mass of the tactor body.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MassArg {
    /// 3.7 g, bare motor with screw.
    Unencased,
    /// 4.95 g, in its case.
    Encased,
}

/// Options shared by the tactor-model commands.
#[derive(Debug, Clone, Args)]
pub struct ModelArgs {
    /// Parameter preset.
    #[arg(long, value_enum, default_value = "thesis-sim")]
    pub preset: PresetArg,
    /// Tactor body mass.
    #[arg(long, value_enum, default_value = "unencased")]
    pub mass: MassArg,
    /// Viscous damping b [N m s] (default: the thesis's 6.3e-8).
    #[arg(long)]
    pub damping: Option<f64>,
    /// Drive voltage [V] (default 3.3).
    #[arg(long)]
    pub voltage: Option<f64>,
    /// Radius of the eccentric's centre of mass [mm] (2.57 CAD, 3.2 fitted).
    #[arg(long)]
    pub radius_mm: Option<f64>,
}

/// `vestnav sim tactor`
#[derive(Debug, Args)]
pub struct TactorArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Simulated time from rest [s]; the last half is the analysis window.
    #[arg(long, default_value_t = 10.0)]
    pub duration_s: f64,
    /// Print the summary as one JSON object (SI units).
    #[arg(long)]
    pub json: bool,
    /// Write the traces (t, theta, omega, x, v, a, force, torque, current) as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a figure: the thesis's Figs 28–34 as one sheet.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `vestnav sim sweep`
#[derive(Debug, Args)]
pub struct SweepArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Number of damping values.
    #[arg(long, default_value_t = 40)]
    pub points: usize,
    /// Lowest steady rotation frequency of the sweep [Hz].
    #[arg(long, default_value_t = 80.0)]
    pub min_hz: f64,
    /// Highest steady rotation frequency of the sweep [Hz].
    #[arg(long, default_value_t = 200.0)]
    pub max_hz: f64,
    /// Print the sweep and its fits as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure sheet (Figs 35–38).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `vestnav sim damping-for`
#[derive(Debug, Args)]
pub struct DampingForArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// The tactor's measured peak frequency [Hz].
    #[arg(long)]
    pub frequency_hz: f64,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure of the calibrated tactor's force (Figs 39–41 model side).
    #[arg(long)]
    pub png: Option<PathBuf>,
}


/// Runs `sim tactor`.
pub fn run_tactor(args: &TactorArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`sim tactor` is being written")
}

/// Runs `sim sweep`.
pub fn run_sweep(args: &SweepArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`sim sweep` is being written")
}

/// Runs `sim damping-for`.
pub fn run_damping_for(args: &DampingForArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`sim damping-for` is being written")
}
