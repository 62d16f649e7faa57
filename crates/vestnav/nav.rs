//! `vestnav nav simulate`: closed-loop guidance simulation of a wearer walking a GPX route.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_core::guidance::{HeadingMode, RoutePath, StrategyKind, Waypoint};
use vestnav_core::wearer::{HeadingSim, SimConfig, SimResult, SimSummary, simulate_many_along};
use vestnav_report::nav::{NavReport, nav_figure};
use vestnav_report::to_json;

/// Guidance strategy on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StrategyArg {
    /// Aim straight at the next waypoint.
    Bearing,
    /// Aim at a look-ahead point on the leg (cross-track corrected).
    Pursuit,
    /// Run both and compare them.
    Both,
}

/// GPS error model of the simulated receiver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GnssArg {
    /// `SiRF` Star III, open sky, with static-navigation pinning below 1.2 m/s.
    Sirf3,
    /// The same without static navigation.
    Sirf3NoStatic,
    /// No error at all.
    Perfect,
}

/// Heading source of the simulated wearer's guidance on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HeadingArg {
    /// The vest's compass only (turn-in-place cues while standing).
    Compass,
    /// COG when moving fast enough, else true heading, else compass (the rule before the compass).
    Cog,
    /// Compass when fresh and good, else true heading, else COG; COG while the compass seems disturbed.
    Auto,
}

impl HeadingArg {
    fn mode(self) -> HeadingMode {
        match self {
            Self::Compass => HeadingMode::Compass,
            Self::Cog => HeadingMode::Cog,
            Self::Auto => HeadingMode::Auto,
        }
    }
}

/// Arguments of `vestnav nav simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Route: a GPX file (its first route, else its waypoints). A route with a track through its points
    /// (`route plan --gpx`) follows that track as its path: guidance steers along it and the cross-track
    /// error is measured from it.
    #[arg(long)]
    pub route: PathBuf,
    /// Guidance strategy.
    #[arg(long, value_enum, default_value = "pursuit")]
    pub strategy: StrategyArg,
    /// Number of runs (seeds seed, seed+1, ...).
    #[arg(long, default_value_t = 20)]
    pub runs: usize,
    /// First random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Walking pace [m/s].
    #[arg(long, default_value_t = 1.4)]
    pub pace_m_s: f64,
    /// Simulate the wearer's heading: start standing at a random heading, a compass with steel near the
    /// route, guidance steering by this source. Several, comma-separated, are compared (e.g.
    /// `compass,cog,auto`). Without it: the wearer walks from the start and guidance uses COG.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub heading: Vec<HeadingArg>,
    /// GPS error model.
    #[arg(long, value_enum, default_value = "sirf3")]
    pub gnss: GnssArg,
    /// Arrival radius of the waypoints [m].
    #[arg(long, default_value_t = 8.0)]
    pub arrival_radius_m: f64,
    /// Look-ahead of the pursuit strategy [m].
    #[arg(long, default_value_t = 15.0)]
    pub lookahead_m: f64,
    /// Print one JSON object (summaries per strategy and every run's numbers).
    #[arg(long)]
    pub json: bool,
    /// Write a figure: the route with the first run's true path and fixes, per strategy.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Follow paths: plan every leg between the route's points along this OpenStreetMap extract's paths
    /// (`route plan`'s planner) and walk the dense result.
    #[arg(long, value_name = "AREA.osm.pbf")]
    pub osm: Option<PathBuf>,
    /// How the planner weighs ways, with --osm.
    #[arg(long, value_enum, default_value = "shortest", requires = "osm")]
    pub profile: crate::route_plan::ProfileArg,
}

/// Reads the waypoints of a GPX route file: its first route with points, else its waypoints, else its first
/// track; and the path the route follows when the file has one (a planner's GPX: a track through the
/// route's points, `RouteFile::route_path`).
pub fn load_route(path: &Path) -> anyhow::Result<(Vec<Waypoint>, Option<RoutePath>)> {
    // The reader's error names the file already.
    let file = vestnav_device::route_file::read_gpx(path)?;
    let Some(route) = file.default_route().filter(|r| !r.waypoints.is_empty()) else {
        anyhow::bail!("{}: no route points or waypoints", path.display());
    };
    // Each waypoint's own arrival radius (a vestnav GPX extension) is kept.
    Ok((route.waypoints, route.path))
}

fn strategies(arg: StrategyArg) -> Vec<StrategyKind> {
    match arg {
        StrategyArg::Bearing => vec![StrategyKind::BearingOnly],
        StrategyArg::Pursuit => vec![StrategyKind::Pursuit],
        StrategyArg::Both => StrategyKind::ALL.to_vec(),
    }
}

/// Builds the simulation settings from the arguments.
fn config(args: &SimulateArgs, kind: StrategyKind, heading: Option<HeadingArg>) -> anyhow::Result<SimConfig> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !positive(args.pace_m_s) || args.pace_m_s > 10.0 {
        anyhow::bail!("--pace-m-s must be in (0, 10]");
    }
    if !positive(args.arrival_radius_m) {
        anyhow::bail!("--arrival-radius-m must be positive");
    }
    if !positive(args.lookahead_m) {
        anyhow::bail!("--lookahead-m must be positive");
    }
    let mut c = SimConfig::new(kind);
    c.wearer.pace_m_s = args.pace_m_s;
    c.gnss = match args.gnss {
        GnssArg::Sirf3 => GnssErrorModel::sirf3_open_sky(),
        GnssArg::Sirf3NoStatic => GnssErrorModel::sirf3_no_static_nav(),
        GnssArg::Perfect => GnssErrorModel::perfect(),
    };
    c.route.arrival_radius_m = args.arrival_radius_m;
    c.route.rearm_radius_m = 1.5 * args.arrival_radius_m;
    c.route.pass_radius_m = 2.0 * args.arrival_radius_m;
    c.guidance.lookahead_m = args.lookahead_m;
    c.heading = heading.map(|h| HeadingSim::new(h.mode()));
    Ok(c)
}

/// Runs `vestnav nav simulate`.
#[allow(clippy::print_stdout)]
pub fn run_simulate(args: &SimulateArgs) -> anyhow::Result<()> {
    if args.runs == 0 || args.runs > 10_000 {
        anyhow::bail!("--runs must be between 1 and 10000");
    }
    let (mut waypoints, mut path) = load_route(&args.route)?;
    if let Some(osm) = &args.osm {
        let (w, p) = crate::route_plan::follow_paths(osm, &waypoints, args.profile.into())?;
        (waypoints, path) = (w, Some(p));
    }
    let mut all: Vec<(SimSummary, Vec<SimResult>)> = Vec::new();
    let headings: Vec<Option<HeadingArg>> =
        if args.heading.is_empty() { vec![None] } else { args.heading.iter().copied().map(Some).collect() };
    for kind in strategies(args.strategy) {
        for &heading in &headings {
            let cfg = config(args, kind, heading)?;
            let (runs, summary) = simulate_many_along(&waypoints, path.as_ref(), &cfg, args.runs, args.seed)?;
            all.push((summary, runs));
        }
    }
    if args.json {
        let mut report =
            NavReport::new(args.route.display().to_string(), waypoints.len(), args.runs, args.seed, &all);
        report.pace_m_s = Some(args.pace_m_s);
        report.path_points = path.as_ref().map(|p| p.points().len());
        print!("{}", to_json(&report)?);
    } else {
        println!(
            "route {} ({} waypoints), {} runs from seed {}, pace {:.2} m/s, GPS {:?}",
            args.route.display(),
            waypoints.len(),
            args.runs,
            args.seed,
            args.pace_m_s,
            args.gnss
        );
        match &path {
            Some(p) => println!(
                "cross-track measured from the path ({} points) between the waypoints; guidance follows it",
                p.points().len()
            ),
            None => println!("cross-track measured from the straight legs between the waypoints"),
        }
        println!(
            "{:<9} {:<8} {:>8} {:>18} {:>16} {:>16} {:>14} {:>10}",
            "strategy",
            "heading",
            "finished",
            "face wp [s]",
            "xtrack RMSE [m]",
            "time [s]",
            "cues/min",
            "missed"
        );
        for (s, _) in &all {
            let face = if s.faced_rate > 0.0 {
                format!(
                    "{:>5.1} ± {:<4.1} {:>3.0}%",
                    s.time_to_face_s.mean,
                    s.time_to_face_s.sd,
                    100.0 * s.faced_rate
                )
            } else {
                "never".to_owned()
            };
            println!(
                "{:<9} {:<8} {:>7.0}% {:>18} {:>7.2} ± {:<6.2} {:>7.0} ± {:<6.0} {:>6.1} ± {:<5.1} {:>4.2} ± {:.2}",
                s.strategy,
                s.heading_mode.as_deref().unwrap_or("-"),
                100.0 * s.finish_rate,
                face,
                s.cross_track_rmse_m.mean,
                s.cross_track_rmse_m.sd,
                s.time_s.mean,
                s.time_s.sd,
                s.cues_per_min.mean,
                s.cues_per_min.sd,
                s.waypoints_missed.mean,
                s.waypoints_missed.sd
            );
        }
    }
    if let Some(path) = &args.png {
        nav_figure(&all, args.arrival_radius_m).save_png(path)?;
        if !args.json {
            println!("figure: {}", path.display());
        }
    }
    Ok(())
}
