//! Command-line interface: the top-level command tree (clap derive).
//!
//! Each subcommand family keeps its own argument structs in its own module; this file only names them.

use clap::{Parser, Subcommand};

use crate::{
    accuracy, analyze, completions, doctor, emulate_gps, emulate_vest, fieldtest, gps_configure, nav, nmea,
    ntrip, route_plan, sim_tactor, sim_wave, station, study, tiles,
};

/// One line: `-h`, and the NAME of the man page.
const ABOUT: &str = "Navigation console for a 16-tactor haptic vest, and the thesis physics behind it";

/// `--help` and the man page's DESCRIPTION: first of all, that no subcommand opens the window.
const LONG_ABOUT: &str = "Navigation console for a 16-tactor haptic vest, and the thesis physics behind it.

Run with no subcommand to open the console (the window), with the options below; \
the subcommands run headless and are scriptable.";

/// The usage lines say the same for `-h`, which shows no long description.
const USAGE: &str = "vestnav [OPTIONS]     opens the console (the window)
       vestnav <COMMAND>     runs a headless subcommand";

/// What `--help` says after the lists: the two subcommands it hides because an operator never needs them.
const AFTER_HELP: &str = "Shell completions: `vestnav completions <bash|zsh|fish|powershell|elvish>` prints a \
completion script; `vestnav man` prints the man page (roff). See `vestnav completions --help`.";

/// vestnav: a navigation console for a 16-tactor haptic vest, and the physics behind it.
///
/// With no subcommand, opens the console (the window). Subcommands run headless and are scriptable.
#[derive(Debug, Parser)]
#[command(
    name = "vestnav",
    version,
    about = ABOUT,
    long_about = LONG_ABOUT,
    override_usage = USAGE,
    after_help = AFTER_HELP,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// Console only: the GPS to connect at start, winning over the saved settings for this run.
    /// One of gpsd://HOST:PORT, serial:PATH[@BAUD] (no @BAUD: detected), replay:FILE[@SPEED]
    /// (SPEED 0 = as fast as possible), sim[:ROUTE.gpx] (the simulator walking ROUTE, also loaded as the
    /// route to guide along), vest[@BAUD] (the receiver on the vest unit's second UART, forwarded inside
    /// the vest's link; default 9600 baud).
    #[arg(long, value_name = "SPEC", value_parser = parse_gps)]
    pub gps: Option<vestnav_device::gps::GpsSourceSpec>,
    /// Console only: the vest to connect at start, winning over the saved settings for this run.
    /// One of emulated, serial:PATH (a WTCU on a serial or Bluetooth SPP port such as /dev/rfcomm0).
    #[arg(long, value_name = "SPEC", value_parser = parse_vest)]
    pub vest: Option<vestnav_station::sources::VestSourceConfig>,
    /// Console only: the map's tile source for this run (the saved setting otherwise). One of osm (the
    /// default), xyz:URL or a bare http(s) URL with {z}, {x}, {y} (an API key may be in the query),
    /// pmtiles:FILE, mbtiles:FILE, folder:DIR (holding {z}/{x}/{y}.png), or a path ending in .pmtiles or
    /// .mbtiles, or a folder.
    #[arg(long, value_name = "SOURCE", value_parser = parse_tiles)]
    pub tiles: Option<vestnav_tiles::TileSourceConfig>,
    /// Console only: an OpenStreetMap extract (.osm.pbf) drawn offline under the tiles at zooms 14–19, and
    /// routed on for walks along its footways (kept as the console's setting, like the Tiles window's
    /// choice).
    #[arg(long, value_name = "AREA.osm.pbf")]
    pub map: Option<std::path::PathBuf>,
    /// Console only: open the Study tab with this protocol checked and its first participant proposed
    /// (Load and Start are the operator's).
    #[arg(long, value_name = "PROTOCOL.toml")]
    pub study: Option<std::path::PathBuf>,
    /// Console only, with --study: a demonstration — the study is loaded into the results folder and
    /// started, and a simulated wearer answers each trial: `sim:P[:SEED[:RT_MS]]` reports a 4-neighbour of
    /// the true tactor with probability P (as `vestnav study run --wearer`).
    #[arg(long, value_name = "SPEC", requires = "study", value_parser = vestnav_station::study::wearer::SimulatedWearer::parse_spec)]
    pub study_wearer: Option<vestnav_station::study::wearer::WearerSpec>,
    /// Console only: save a PNG of the window after --screenshot-after seconds, then close it (the vest is
    /// stopped first, as on any close). For documentation and bug reports; works under Xvfb.
    #[arg(long, value_name = "FILE.png")]
    pub screenshot: Option<std::path::PathBuf>,
    /// Console only: how long the console runs before --screenshot is taken [s].
    #[arg(long = "screenshot-after", value_name = "SECONDS", default_value_t = 5.0, value_parser = parse_screenshot_after)]
    pub screenshot_after_s: f64,
    /// Console only: the window's size in points for --screenshot, width x height such as 1024x680 (default 1400x880).
    #[arg(long = "screenshot-size", value_name = "WxH", value_parser = parse_window_size)]
    pub screenshot_size: Option<[f32; 2]>,
    /// Console only: the MQTT broker whose stations the Stations window lists and drives (docs/remote.md);
    /// the operator's name is --user (default "operator").
    #[command(flatten)]
    pub broker: crate::broker_args::BrokerArgs,
    /// What to run; none opens the console.
    #[command(subcommand)]
    pub command: Option<Command>,
}

fn parse_gps(s: &str) -> Result<vestnav_device::gps::GpsSourceSpec, String> {
    s.parse().map_err(|e| format!("--gps {e}"))
}

fn parse_screenshot_after(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && (0.0..=3600.0).contains(v))
        .ok_or_else(|| format!("{s:?}: seconds from 0 to 3600"))
}

fn parse_window_size(s: &str) -> Result<[f32; 2], String> {
    let bad = || format!("{s:?}: WIDTHxHEIGHT in points, from 900x600 to 7680x4320 (e.g. 1024x680)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (w.trim().parse::<u16>().map_err(|_| bad())?, h.trim().parse::<u16>().map_err(|_| bad())?);
    if !(900..=7680).contains(&w) || !(600..=4320).contains(&h) {
        return Err(bad());
    }
    Ok([f32::from(w), f32::from(h)])
}

fn parse_tiles(s: &str) -> Result<vestnav_tiles::TileSourceConfig, String> {
    vestnav_tiles::parse_tiles_spec(s)
}

fn parse_vest(s: &str) -> Result<vestnav_station::sources::VestSourceConfig, String> {
    vestnav_station::sources::parse_vest_spec(s)
}

/// The headless subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate the thesis physics: tactor motor, damping sweep, skin waves, two-point.
    #[command(subcommand)]
    Sim(SimCommand),
    /// Analyse measured data.
    #[command(subcommand)]
    Analyze(AnalyzeCommand),
    /// Decode and record NMEA 0183.
    #[command(subcommand)]
    Nmea(NmeaCommand),
    /// Configure a GPS receiver on a serial port (rate, constellations, dynamic model, static hold).
    #[command(subcommand)]
    Gps(GpsCommand),
    /// Run a device emulator on a pseudo-terminal (the console connects to it like to hardware).
    #[command(subcommand)]
    Emulate(EmulateCommand),
    /// Navigation: closed-loop simulation of guidance strategies.
    #[command(subcommand)]
    Nav(NavCommand),
    /// GPS field tests: stationary drift and the cone test (thesis §5).
    #[command(subcommand)]
    Fieldtest(FieldtestCommand),
    /// Map tiles: make an area available offline (the console's prefetch, headless).
    #[command(subcommand)]
    Tiles(TilesCommand),
    /// Run the station with no window: GPS, vest, guidance and session log, commands on standard input
    /// (stop, resume, status, quit), status lines on standard output.
    Station(Box<station::StationArgs>),
    /// NTRIP client: RTK corrections (RTCM 3) from a caster to a receiver on a serial port.
    Ntrip(ntrip::NtripArgs),
    /// Check this machine's set-up: serial-port permissions, Bluetooth, OpenGL libraries, folders, optional
    /// parts; each finding with its fix.
    Doctor(doctor::DoctorArgs),
    /// Walking routes along the paths of an OpenStreetMap extract, offline.
    #[command(subcommand)]
    Route(RouteCommand),
    /// The offline map of an OpenStreetMap extract.
    #[command(subcommand)]
    Map(MapCommand),
    /// Tactile-display studies (docs/study.md): check a protocol, run a session on the vest, analyse results.
    #[command(subcommand)]
    Study(study::StudySubcommand),
    /// Print a shell completion script for vestnav to standard output.
    #[command(hide = true)]
    Completions(completions::CompletionsArgs),
    /// Print the vestnav man page (roff) to standard output.
    #[command(hide = true)]
    Man,
}

/// `vestnav sim ...`
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Simulate one tactor from rest (thesis §3.2, Figs 28–34).
    Tactor(sim_tactor::TactorArgs),
    /// Sweep the damping and fit frequency against force and current (Figs 35–38).
    Sweep(sim_tactor::SweepArgs),
    /// Print the damping that makes a tactor run at a measured peak frequency.
    DampingFor(sim_tactor::DampingForArgs),
    /// Two tactors' Gaussians summed and fitted by one Gaussian (§4.2, Figs 60–63).
    TwoPoint(sim_wave::TwoPointArgs),
    /// Skin travelling waves: attenuation, phase lag, and the field of the vest (§4.1.3, Figs 52, 57, 59).
    Wave(sim_wave::WaveArgs),
}

/// `vestnav analyze ...`
#[derive(Debug, Subcommand)]
pub enum AnalyzeCommand {
    /// Peak frequency, envelope, overshoot, settling of measured tactor traces (CSV, 10 kHz) (§3.1).
    TactorData(analyze::TactorDataArgs),
}

/// `vestnav nmea ...`
#[derive(Debug, Subcommand)]
pub enum NmeaCommand {
    /// Decode NMEA logs into one JSON object (or text line) per epoch.
    Decode(nmea::DecodeArgs),
    /// Record raw NMEA from a serial port with timestamps.
    Record(nmea::RecordArgs),
}

/// `vestnav gps ...`
#[derive(Debug, Subcommand)]
pub enum GpsCommand {
    /// Send a configuration to the receiver and report each command's acknowledgement (u-blox UBX CFG,
    /// u-blox M9/F9 CFG-VALSET, `SiRF` static navigation); --dry-run prints the frames as hex.
    Configure(gps_configure::ConfigureArgs),
}

/// `vestnav emulate ...`
#[derive(Debug, Subcommand)]
pub enum EmulateCommand {
    /// Emulate the vest's WTCU: device side of the protocol, watchdog, limits, live 4x4 view.
    Vest(emulate_vest::VestArgs),
    /// Emulate a Bluetooth NMEA GPS: replay a log or simulate a walker.
    Gps(emulate_gps::GpsArgs),
}

/// `vestnav nav ...`
#[derive(Debug, Subcommand)]
pub enum NavCommand {
    /// Closed-loop simulation of a wearer guided along a route by a strategy.
    Simulate(nav::SimulateArgs),
}

/// `vestnav fieldtest ...`
#[derive(Debug, Subcommand)]
pub enum FieldtestCommand {
    /// Stationary drift: distance from the first fix and from the mean, CEP, DRMS.
    Drift(fieldtest::DriftArgs),
    /// Cone test: consecutive distances between operator marks against the nominal spacing.
    Cones(fieldtest::ConesArgs),
    /// Accuracy against a known point: error over time, bias, CEP50/CEP95, 2DRMS, R95, share within
    /// 0.1-5 m, vertical error.
    Accuracy(accuracy::AccuracyArgs),
    /// Two or more receivers recorded at once: epochs matched by receiver time, their differences, each
    /// against the reference.
    Compare(accuracy::CompareArgs),
}

/// `vestnav tiles ...`
#[derive(Debug, Subcommand)]
pub enum TilesCommand {
    /// Download the tiles of a route's or a box's area over a zoom range into the tile cache or an
    /// MBTiles file (resumable; tiles already there are skipped).
    Prefetch(tiles::PrefetchArgs),
}

/// `vestnav route ...`
#[derive(Debug, Subcommand)]
pub enum RouteCommand {
    /// Plan a walk from --from to --to (through each --via) along an .osm.pbf extract's paths, honouring
    /// access, barriers and the profile; write it as GPX for `nav simulate` and the console.
    Plan(route_plan::PlanArgs),
}

/// `vestnav map ...`
#[derive(Debug, Subcommand)]
pub enum MapCommand {
    /// Draw an .osm.pbf extract offline into a PNG (the tiles the console's map would show), optionally
    /// with a route over it.
    Render(route_plan::RenderArgs),
}
