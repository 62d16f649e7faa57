//! `vestnav station`: the running system with no window — the GPS, the vest, guidance, the route and the
//! session log of the console, driven from a terminal or a script.
//!
//! It prints one status line per `--status-every` seconds (JSON with `--json`) and takes commands on its
//! standard input, one per line: `stop` (STOP ALL), `resume` (automatic cues again), `status`, `quit`.
//! SIGTERM, SIGINT and SIGHUP stop the vest first and end the process within the stop path's deadline;
//! `quit`, `--for` and the end of a replay (`--exit-when-done`) stop it the same way.
//!
//! With `--compare-gps SPEC` (repeatable) more receivers run beside `--gps`, compared with it by receiver
//! time; each status line says how they differ, and the station's snapshot carries the comparison to a
//! remote console.
//!
//! With `--map AREA.osm.pbf` the station re-routes a wearer who strays off a route's path, on the extract's
//! footways: the file is checked before anything starts, then read on the station's `osm-graph` thread.
#![allow(clippy::print_stdout)] // the status lines on stdout are this command's interface for scripts

use std::fmt::Write as _;
use std::io::BufRead as _;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use vestnav_device::gps::SourceState;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig, parse_gps_spec, parse_vest_spec};
use vestnav_station::stop::StopPath;
use vestnav_station::{Liveness, RouteStart, Station, StationOptions, StationSettings};

/// `vestnav station` arguments.
#[derive(Debug, clap::Args)]
#[allow(clippy::struct_excessive_bools)] // independent command-line switches
pub struct StationArgs {
    /// The GPS: gpsd://HOST:PORT, serial:PATH[@BAUD], replay:FILE[@SPEED], sim[:ROUTE.gpx] or vest[@BAUD]
    /// (as the console's --gps).
    #[arg(long, value_name = "SPEC", value_parser = parse_gps_spec, default_value = "sim")]
    pub gps: GpsSourceConfig,
    /// A receiver to compare with --gps (repeatable, at most 4): the same forms as --gps. Its fixes are
    /// compared with the primary's by receiver time (never fed to guidance); its sentences are recorded
    /// beside the session log as SESSION.rxN.nmea for `vestnav fieldtest compare`.
    #[arg(long = "compare-gps", value_name = "SPEC", value_parser = parse_gps_spec)]
    pub compare_gps: Vec<GpsSourceConfig>,
    /// The vest: emulated, or serial:PATH (a WTCU on a serial or Bluetooth SPP port).
    #[arg(long, value_name = "SPEC", value_parser = parse_vest_spec, default_value = "emulated")]
    pub vest: VestSourceConfig,
    /// The route to guide along (GPX); default: the one named by --gps sim:ROUTE, else the demo route.
    #[arg(long, value_name = "FILE.gpx")]
    pub route: Option<PathBuf>,
    /// An OpenStreetMap extract (.osm.pbf) whose footways the station re-routes on when the wearer stays
    /// off a route's path (checked as the console's --map; read on a thread of its own).
    #[arg(long, value_name = "AREA.osm.pbf")]
    pub map: Option<PathBuf>,
    /// Where the session log goes (a new JSON Lines file per run).
    #[arg(long, value_name = "DIR")]
    pub log_dir: Option<PathBuf>,
    /// Start with automatic cues off (manual cues only until `resume`).
    #[arg(long)]
    pub no_auto: bool,
    /// With --gps sim and --vest emulated: the simulated wearer walks where the vest's cues steer them
    /// (recognising 92 % of cues, reacting in 0.8 s, as `vestnav nav simulate`'s wearer) instead of along
    /// the route.
    #[arg(long)]
    pub sim_follows_vest: bool,
    /// Seconds between status lines (0: only on `status`).
    #[arg(long, value_name = "SECONDS", default_value_t = 5.0)]
    pub status_every: f64,
    /// Status lines as JSON.
    #[arg(long)]
    pub json: bool,
    /// Run this many seconds, then stop the vest and end (for scripts and tests).
    #[arg(long = "for", value_name = "SECONDS")]
    pub for_s: Option<f64>,
    /// End (vest stopped first) when the GPS source has finished, e.g. a replay reached its end.
    #[arg(long)]
    pub exit_when_done: bool,
    /// The station's name on the broker (letters, digits, '-' and '_'); needed with --broker.
    #[arg(long, value_name = "NAME", requires = "broker")]
    pub name: Option<String>,
    /// With --broker: seconds without an operator's heartbeat after which the vest is stopped and automatic
    /// cues halted (unless the operator armed "continue the route if the link drops").
    #[arg(long, value_name = "SECONDS", default_value_t = 3.0, requires = "broker")]
    pub link_bound: f64,
    /// With --broker: a host (besides this machine) whose gpsd an operator may add as a receiver to compare
    /// (repeatable). Without it an operator's gpsd://HOST:PORT must be this machine (localhost, loopback).
    #[arg(long = "remote-gpsd-host", value_name = "HOST", requires = "broker")]
    pub remote_gpsd_hosts: Vec<String>,
    /// LSL streams and OSC messages (docs/study.md).
    #[command(flatten)]
    pub lab: crate::lab_args::LabArgs,
    /// The MQTT broker the station publishes to and takes commands from (docs/remote.md).
    #[command(flatten)]
    pub broker: crate::broker_args::BrokerArgs,
}

/// Runs the station until a signal, `quit`, `--for` or `--exit-when-done` ends it.
pub fn run(a: &StationArgs) -> anyhow::Result<()> {
    let stop = StopPath::default();
    #[cfg(unix)]
    vestnav_station::stop::exit_on_signals(stop.clone(), || {}).context("cannot watch for signals")?;
    let mut settings = StationSettings::default();
    settings.guidance.auto = !a.no_auto;
    settings.sim_follows_vest = a.sim_follows_vest;
    let route = a.route.clone().or_else(|| a.gps.sim_route().map(std::path::Path::to_path_buf));
    if let Some(r) = &route {
        // Checked before anything starts: a missing route file is the operator's to fix now.
        std::fs::metadata(r).with_context(|| format!("route {}", r.display()))?;
    }
    if let Some(m) = &a.map {
        crate::check_map_file(m)?;
    }
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: Some(a.gps.clone()),
            vest: Some(a.vest.clone()),
            log_dir: a.log_dir.clone(),
            waker: None,
            liveness: Some(Liveness { view: None, ..Liveness::default() }),
            stop,
            route: RouteStart { file: route, autosave: None },
        },
    );
    for n in station.notices.all() {
        eprintln!("vestnav station: {}", n.text);
    }
    if let Some(m) = &a.map {
        station.load_path_network(m.clone());
    }
    a.lab.start(&mut station, a.name.as_deref())?;
    station.connect_vest();
    if let Err(e) = add_compared(&mut station, &a.compare_gps) {
        station.shutdown();
        return Err(e);
    }
    station.connect_gps(Vec::new());
    let mut bridge = start_bridge(a, &station)?;
    if let Some(p) = station.log_path() {
        eprintln!("vestnav station: session log {}", p.display());
    }
    let commands = stdin_commands();
    let start = Instant::now();
    let every = Duration::from_secs_f64(a.status_every.max(0.0));
    let mut next_status = start + every;
    let mut said = station.notices.revision();
    let mut network_said = false;
    loop {
        station.pump(|_| {});
        let now = Instant::now();
        if !network_said && station.has_path_network() {
            network_said = true;
            if let Some(m) = &a.map {
                eprintln!("vestnav station: re-routing on the paths of {}", m.display());
            }
        }
        if station.notices.revision() != said {
            said = station.notices.revision();
            if let Some(n) = station.notices.all().last() {
                eprintln!("vestnav station: {}", n.text);
            }
        }
        let mut print = !every.is_zero() && now >= next_status;
        match commands.try_recv() {
            Ok(cmd) => match cmd.trim() {
                "stop" => station.stop_all(),
                "resume" => station.resume_guidance(),
                "status" => print = true,
                "quit" => break,
                "" => {}
                other => eprintln!("vestnav station: unknown command {other:?} (stop, resume, status, quit)"),
            },
            Err(mpsc::TryRecvError::Empty | mpsc::TryRecvError::Disconnected) => {}
        }
        if print {
            next_status = now + every;
            println!("{}", status_line(&station, now, start, a.json));
        }
        if done(a, &station, now.duration_since(start)) {
            break;
        }
        match &mut bridge {
            Some(b) => {
                b.turn(&mut station, now);
                b.wait(&mut station, Duration::from_millis(20));
            }
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    last_comparison(&mut station);
    let last = status_line(&station, Instant::now(), start, a.json);
    station.shutdown();
    if let Some(b) = &mut bridge {
        b.turn(&mut station, Instant::now());
        b.shutdown();
    }
    println!("{last}");
    Ok(())
}

/// Adds each `--compare-gps` receiver through the command a console or a remote operator sends: one path,
/// one set of checks; the first refusal ends the start.
fn add_compared(station: &mut Station, specs: &[GpsSourceConfig]) -> anyhow::Result<()> {
    for spec in specs {
        let command = vestnav_station::command::Command::AddReceiver { spec: spec.to_string() };
        station.apply(command).map_err(|e| anyhow::anyhow!("--compare-gps {spec}: {e}"))?;
    }
    Ok(())
}

/// While receivers are compared: one last comparison of every fix taken, so the final status line says what
/// the session measured.
fn last_comparison(station: &mut Station) {
    if !station.receivers().active() {
        return;
    }
    station.pump(|_| {});
    // A comparison already being computed may predate the last fixes: its result first, then one of all.
    let _ = station.await_comparison(Duration::from_secs(10));
    station.recompute_receivers(Instant::now());
    if !station.await_comparison(Duration::from_secs(10)) {
        eprintln!("vestnav station: the last comparison of the receivers did not come within 10 s");
    }
}

/// Whether the run is over: `--for` has elapsed, or with `--exit-when-done` the GPS has finished and no
/// comparison receiver is still delivering.
fn done(a: &StationArgs, station: &Station, elapsed: Duration) -> bool {
    a.for_s.is_some_and(|s| elapsed.as_secs_f64() >= s)
        || (a.exit_when_done
            && matches!(station.gps.state, Some(SourceState::Finished))
            && !receivers_running(station))
}

/// Whether a comparison source is still delivering (not finished, lost, stopped or failed): a replayed
/// comparison is read to its end before `--exit-when-done` ends the station.
fn receivers_running(s: &Station) -> bool {
    s.receivers().sources().iter().any(|r| {
        r.failed.is_none()
            && !matches!(
                r.state,
                Some(SourceState::Finished | SourceState::Lost { .. } | SourceState::Stopped)
            )
    })
}

/// The station's MQTT bridge when `--broker` names one (`None` without).
fn start_bridge(a: &StationArgs, station: &Station) -> anyhow::Result<Option<vestnav_remote::StationBridge>> {
    Ok(match a.broker.config() {
        Some(config) => {
            let name = a.name.as_deref().context("--broker needs --name")?;
            if !(a.link_bound.is_finite() && (0.5..=600.0).contains(&a.link_bound)) {
                anyhow::bail!("--link-bound {}: between 0.5 and 600 seconds", a.link_bound);
            }
            let opts = vestnav_remote::BridgeOptions {
                link_bound: Duration::from_secs_f64(a.link_bound),
                remote_gpsd_hosts: a.remote_gpsd_hosts.clone(),
                ..vestnav_remote::BridgeOptions::default()
            };
            let b = vestnav_remote::StationBridge::start(&config, name, station.stop_path().clone(), opts)
                .context("broker")?;
            eprintln!("vestnav station: station {name} on {}", config.url);
            Some(b)
        }
        None => None,
    })
}

/// Lines of standard input, read on their own thread (a closed input just ends the thread).
fn stdin_commands() -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    let _ = std::thread::Builder::new().name("station-stdin".into()).spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// One status line: time, GPS state and position age, vest state and the tactors on, guidance's cue or
/// hold, the alarms.
fn status_line(s: &Station, now: Instant, start: Instant, json: bool) -> String {
    let gps = vestnav_station::source_state_label(s.gps.state.as_ref());
    let age_s = s.position_age(now).map(|a| a.as_secs_f64());
    let pos = s.gps.last_position.as_ref().and_then(|f| f.lat_deg.zip(f.lon_deg));
    let vest = s.vest.label();
    let on = s.vest.tactors_on.map(|m| m.indices().collect::<Vec<_>>());
    let g = s.guidance.as_ref();
    let cue = g.and_then(|g| g.cue).map(vestnav_core::vest::Cue::name);
    let hold = g.and_then(|g| g.hold.clone());
    let alarm = s.gps_alarm(now).map(|a| format!("{a:?}"));
    let stop = s.stop_alarm(now).map(|a| vestnav_station::stop_alarm_text(&a));
    let t_s = now.duration_since(start).as_secs_f64();
    let next = s.route().next();
    if json {
        serde_json::json!({
            "t_s": t_s, "gps": gps, "position_age_s": age_s, "lat_deg": pos.map(|p| p.0), "lon_deg": pos.map(|p| p.1),
            "fixes": s.gps.fixes, "vest": vest, "tactors_on": on, "halted": s.vest.halted, "cue": cue, "hold": hold,
            "next_waypoint": next, "waypoints": s.route().waypoints().len(), "gps_alarm": alarm,
            "stop_not_confirmed": stop, "lab": s.lab_status(), "path_network": s.has_path_network(),
            "receivers": s.receivers_snapshot(now),
        })
        .to_string()
    } else {
        let age = age_s.map_or_else(|| "no fix".to_owned(), |a| format!("fix {a:.1} s old"));
        let mut line = format!(
            "t={t_s:.1}s gps: {gps} ({age}, {} fixes) · vest: {vest} · waypoint {}/{} · cue: {} · {}",
            s.gps.fixes,
            (next + 1).min(s.route().waypoints().len()),
            s.route().waypoints().len(),
            cue.unwrap_or("none"),
            hold.map_or_else(|| "guiding".to_owned(), |h| format!("hold: {h}")),
        );
        if let Some(a) = alarm {
            let _ = write!(line, " · GPS ALARM {a}");
        }
        if let Some(why) = &s.vest.halted {
            let _ = write!(line, " · HALTED: {why}");
        }
        if let Some(st) = stop {
            let _ = write!(line, " · STOP NOT CONFIRMED: {st}");
        }
        if let Some(lab) = s.lab_status() {
            let _ = write!(line, " · lab: {}", lab.summary());
        }
        if let Some(r) = s.receivers_snapshot(now) {
            let _ = write!(line, " · receivers: {}", r.summary());
        }
        line
    }
}
