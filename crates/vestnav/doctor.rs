//! `vestnav doctor`: the set-up checks of `vestnav_device::doctor` on this machine, with the folders and
//! ports of the console's own settings (`vestnav_app::config`, the tile cache's folder), printed as text or
//! JSON. Exits 1 when a check found a problem, so a script can gate on it.

use std::io::Write as _;
use std::path::Path;

use clap::Args;
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_device::doctor::{self, Area, Environment, Finding, Report, Request, Verdict};

/// `vestnav doctor`
#[derive(Debug, Args)]
#[command(
    after_help = "Exit status: 0 when nothing is a problem (warnings allowed), 1 when a check found a problem.
The ports of the console's saved settings are checked besides those present under /dev."
)]
pub struct DoctorArgs {
    /// Print the findings as JSON (`findings`: area, check, verdict ok|info|warning|problem, detail, fix).
    #[arg(long)]
    pub json: bool,
    /// Also check this serial port (repeatable), e.g. --port /dev/rfcomm0.
    #[arg(long = "port", value_name = "PATH")]
    pub ports: Vec<String>,
    /// Check that this broker answers over TCP within 1 s (`mqtt://HOST[:PORT]`, `tcp://HOST:PORT`, `HOST:PORT`).
    #[arg(long, value_name = "URL")]
    pub broker: Option<String>,
}

/// The JSON document: the findings and their count per verdict.
#[derive(serde::Serialize)]
struct JsonReport<'a> {
    version: &'static str,
    problems: usize,
    warnings: usize,
    #[serde(flatten)]
    report: &'a Report,
}

pub fn run(args: &DoctorArgs) -> anyhow::Result<()> {
    let env = Environment::system();
    let config_path = vestnav_app::config::default_path();
    let (config, config_error) = match &config_path {
        // Looking must not move the user's broken file aside (the console does that when it starts).
        Some(path) => Config::inspect(path),
        None => (Config::default(), None),
    };
    let mut request = Request { ports: args.ports.clone(), folders: Vec::new(), broker: args.broker.clone() };
    for port in configured_ports(&config) {
        if !request.ports.contains(&port) {
            request.ports.push(port);
        }
    }
    if let Some(dir) = config_path.as_deref().and_then(Path::parent) {
        request.folders.push(("config folder".into(), dir.to_path_buf()));
    }
    let data = config.log_dir.clone().unwrap_or_else(vestnav_app::config::data_dir);
    request.folders.push(("data folder".into(), data));
    let tiles = config.tile_cache_dir.clone().unwrap_or_else(vestnav_tiles::cache::default_root);
    request.folders.push(("tile cache".into(), tiles));

    let mut report = doctor::run(&env, &request);
    // Beside the folders, before the optional parts.
    let at = report.findings.iter().position(|f| f.area == Area::Optional).unwrap_or(report.findings.len());
    report.findings.insert(at, config_finding(config_path.as_deref(), config_error));

    let mut out = std::io::stdout().lock();
    if args.json {
        let doc = JsonReport {
            version: env!("CARGO_PKG_VERSION"),
            problems: report.count(Verdict::Problem),
            warnings: report.count(Verdict::Warning),
            report: &report,
        };
        serde_json::to_writer_pretty(&mut out, &doc)?;
        writeln!(out)?;
    } else {
        out.write_all(doctor::render_text(&report).as_bytes())?;
    }
    out.flush()?;
    if report.worst() == Verdict::Problem {
        std::process::exit(1);
    }
    Ok(())
}

/// The serial ports named in the console's settings.
fn configured_ports(config: &Config) -> Vec<String> {
    let mut ports = Vec::new();
    if let GpsSourceConfig::Serial { port, .. } = &config.gps {
        ports.push(port.clone());
    }
    if let VestSourceConfig::Serial { port } = &config.vest {
        ports.push(port.clone());
    }
    ports.retain(|p| p.starts_with('/'));
    ports
}

/// The console's settings file: missing is fine (defaults), broken is a problem (the console ignores it).
fn config_finding(path: Option<&Path>, error: Option<String>) -> Finding {
    let (verdict, detail, fix) = match (path, error) {
        (None, _) => (Verdict::Warning, "no home folder: settings cannot be remembered".to_owned(), None),
        (Some(_), Some(e)) => (
            Verdict::Problem,
            format!("{e}: the console starts with the defaults"),
            Some("fix the file, or delete it to start from the defaults".to_owned()),
        ),
        (Some(p), None) if p.exists() => (Verdict::Ok, format!("{} reads", p.display()), None),
        (Some(p), None) => (Verdict::Ok, format!("{} not yet written (defaults)", p.display()), None),
    };
    Finding { area: Area::Folders, check: "settings".into(), verdict, detail, fix }
}
