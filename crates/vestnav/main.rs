//! vestnav: the console (no subcommand) and headless subcommands.
//!
//! This file only parses the command line and dispatches; each subcommand family lives in its own module.

mod accuracy;
mod analyze;
mod broker_args;
mod cli;
mod completions;
mod doctor;
mod emulate_gps;
mod emulate_vest;
mod fieldtest;
mod gps_configure;
mod lab_args;
mod nav;
mod nmea;
mod ntrip;
mod route_plan;
mod sim_tactor;
mod sim_wave;
mod station;
mod study;
mod study_run;
mod tiles;

use clap::Parser;

use cli::{
    AnalyzeCommand, Cli, Command, EmulateCommand, FieldtestCommand, GpsCommand, MapCommand, NavCommand,
    NmeaCommand, RouteCommand, SimCommand, TilesCommand,
};

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    init_tracing();
    quiet_on_broken_pipe();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) if is_broken_pipe(&err) => std::process::ExitCode::from(EXIT_BROKEN_PIPE),
        Err(err) => {
            eprintln!("vestnav: {}", error_text(&err));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each said once: a cause whose text the line already holds (an
/// error type that prints its source and also returns it as its cause, such as "cannot write X: os error"
/// then "os error") is left out.
fn error_text(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

/// Diagnostics (serial, gpsd, vest transport and map tile failures) go to stderr, filtered by `RUST_LOG`
/// (`RUST_LOG=vestnav_device=info`, `RUST_LOG=debug`); without it only warnings and errors are shown. The
/// `log` records of dependencies (walkers' tile fetches) are forwarded too. Stdout stays the subcommands'.
fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    // A second subscriber (none here) is the only way this fails; logging is then simply off.
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}

/// Exit status when the reader of our output went away (`vestnav ... | head`): 128 + SIGPIPE, as a
/// program killed by the signal would report to the shell.
const EXIT_BROKEN_PIPE: u8 = 141;

/// Whether `err` comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        e.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            || e.downcast_ref::<serde_json::Error>()
                .is_some_and(|j| j.io_error_kind() == Some(std::io::ErrorKind::BrokenPipe))
    })
}

/// Rust ignores SIGPIPE, so `println!` to a closed pipe panics. A report cut short by `head` is not an
/// error the user needs a backtrace for: end quietly with the shell's broken-pipe status instead.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.contains("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(i32::from(EXIT_BROKEN_PIPE));
        }
        default(info);
    }));
}

/// The files `--gps`, `--tiles` and `--map` name, checked before the console's window opens: a missing
/// replay, a bad route, a tile file that is not PMTiles/MBTiles, a missing tile folder or a file that is no
/// OSM extract end the program with a clear error (and a non-zero exit) instead of a window that says less.
fn check_console_files(
    gps: Option<&vestnav_device::gps::GpsSourceSpec>,
    tiles: Option<&vestnav_tiles::TileSourceConfig>,
    map: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    if let Some(path) = map {
        check_map_file(path)?;
    }
    if let Some(spec) = gps {
        spec.check_files().map_err(|e| anyhow::anyhow!("--gps {spec}: {e}"))?;
    }
    if let Some(
        t @ (vestnav_tiles::TileSourceConfig::PmTiles(_)
        | vestnav_tiles::TileSourceConfig::MbTiles(_)
        | vestnav_tiles::TileSourceConfig::Folder(_)),
    ) = tiles
    {
        // Local stores need no cache folder.
        vestnav_tiles::store::open(t, &std::env::temp_dir())
            .map(drop)
            .map_err(|e| anyhow::anyhow!("--tiles: {e}"))?;
    }
    Ok(())
}

/// `--map`'s file (the console's and `vestnav station`'s): a regular file within the size limit that starts
/// as an OSM extract, else a clear error naming it. The full read comes later, off the command thread.
pub(crate) fn check_map_file(path: &std::path::Path) -> anyhow::Result<()> {
    vestnav_osm::Extract::check_file(path).map_err(|e| anyhow::anyhow!("--map {e}"))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let Some(command) = cli.command else {
        check_console_files(cli.gps.as_ref(), cli.tiles.as_ref(), cli.map.as_deref())?;
        if let Some(p) = &cli.study {
            // A protocol named at start is checked before the window opens, as the devices and files are.
            vestnav_core::study::Protocol::load(p).map_err(|e| anyhow::anyhow!("--study: {e}"))?;
        }
        let screenshot = cli.screenshot.map(|path| vestnav_app::Screenshot {
            path,
            after: std::time::Duration::from_secs_f64(cli.screenshot_after_s),
            size: cli.screenshot_size,
        });
        let remote = cli.broker.config().map(|c| {
            let operator = c.user.clone().unwrap_or_else(|| "operator".to_owned());
            (c, operator)
        });
        return vestnav_app::run(
            vestnav_app::console::DeviceOverrides {
                gps: cli.gps,
                vest: cli.vest,
                tiles: cli.tiles,
                map: cli.map,
                study: cli.study.map(|protocol| vestnav_app::study_panel::StudyLaunch {
                    protocol,
                    wearer: cli.study_wearer,
                    out_dir: None,
                }),
            },
            screenshot,
            remote,
        );
    };
    match command {
        Command::Sim(SimCommand::Tactor(a)) => sim_tactor::run_tactor(&a),
        Command::Sim(SimCommand::Sweep(a)) => sim_tactor::run_sweep(&a),
        Command::Sim(SimCommand::DampingFor(a)) => sim_tactor::run_damping_for(&a),
        Command::Sim(SimCommand::TwoPoint(a)) => sim_wave::run_two_point(&a),
        Command::Sim(SimCommand::Wave(a)) => sim_wave::run_wave(&a),
        Command::Analyze(AnalyzeCommand::TactorData(a)) => analyze::run_tactor_data(&a),
        Command::Nmea(NmeaCommand::Decode(a)) => nmea::run_decode(&a),
        Command::Nmea(NmeaCommand::Record(a)) => nmea::run_record(&a),
        Command::Gps(GpsCommand::Configure(a)) => gps_configure::run(&a),
        Command::Emulate(EmulateCommand::Vest(a)) => emulate_vest::run(&a),
        Command::Emulate(EmulateCommand::Gps(a)) => emulate_gps::run(&a),
        Command::Nav(NavCommand::Simulate(a)) => nav::run_simulate(&a),
        Command::Fieldtest(FieldtestCommand::Drift(a)) => fieldtest::run_drift(&a),
        Command::Fieldtest(FieldtestCommand::Cones(a)) => fieldtest::run_cones(&a),
        Command::Fieldtest(FieldtestCommand::Accuracy(a)) => accuracy::run_accuracy(&a),
        Command::Fieldtest(FieldtestCommand::Compare(a)) => accuracy::run_compare(&a),
        Command::Ntrip(a) => ntrip::run(&a),
        Command::Tiles(TilesCommand::Prefetch(a)) => tiles::run_prefetch(&a),
        Command::Station(a) => station::run(&a),
        Command::Study(s) => study::run(&s),
        Command::Doctor(a) => doctor::run(&a),
        Command::Route(RouteCommand::Plan(a)) => route_plan::run_plan(&a),
        Command::Map(MapCommand::Render(a)) => route_plan::run_render(&a),
        Command::Completions(a) => completions::run_completions(&a),
        Command::Man => completions::run_man(),
    }
}
