//! `vestnav emulate gps`: an NMEA GPS emulator on a pseudo-terminal.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_device::gps::sim::{DEFAULT_ROUTE, SimulatedReceiver, load_route_gpx, whole_second_now};
use vestnav_device::gps::source::replay_lines;

/// Arguments of `vestnav emulate gps`.
// Independent command-line switches, not a state machine.
#[allow(clippy::struct_excessive_bools)]
#[derive(Debug, Args)]
pub struct GpsArgs {
    /// Replay this NMEA log (or recording) in real time.
    #[arg(long, conflicts_with = "simulate", required_unless_present = "simulate")]
    pub replay: Option<PathBuf>,
    /// Simulate a walker along a route with `SiRF` III-like error.
    #[arg(long)]
    pub simulate: bool,
    /// Route for --simulate (GPX: route, track or waypoints); default assets/routes/demo.gpx.
    #[arg(long, requires = "simulate")]
    pub route: Option<PathBuf>,
    /// Serve on a new pseudo-terminal and print its path (default: write to standard output).
    #[arg(long)]
    pub pty: bool,
    /// Replay speed factor (1 = recorded speed).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Walking pace for --simulate [m/s].
    #[arg(long, default_value_t = 1.4)]
    pub pace_m_s: f64,
    /// Random seed of the simulated receiver error.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulate without `SiRF` static navigation (no position pinning below 1.2 m/s).
    #[arg(long)]
    pub no_static_nav: bool,
    /// Keep serving: loop the replay, or walk the route again when it ends.
    #[arg(long)]
    pub repeat: bool,
}

fn output(pty: bool) -> anyhow::Result<Box<dyn Write>> {
    if pty {
        #[cfg(unix)]
        {
            let p = vestnav_device::serial::Pty::open()?;
            // The one line other programs (and tests) read to find the port.
            println_path(p.path());
            return Ok(Box::new(DropWhenUnread(p)));
        }
        #[cfg(not(unix))]
        anyhow::bail!("--pty needs a Unix pseudo-terminal");
    }
    Ok(Box::new(std::io::stdout()))
}

/// A receiver keeps sending when nobody listens: when the PTY's buffer is full (no reader), drop the
/// bytes instead of failing.
#[cfg(unix)]
struct DropWhenUnread(vestnav_device::serial::Pty);

#[cfg(unix)]
impl Write for DropWhenUnread {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.0.write(buf) {
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(buf.len()),
            r => r,
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self.0.flush() {
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(()),
            r => r,
        }
    }
}

#[allow(clippy::print_stdout)] // the PTY path on stdout is the interface for scripts
fn println_path(path: &str) {
    println!("{path}");
    let _ = std::io::stdout().flush();
}

/// Writes one log line to the device side; `#` comment lines of gpsd's test logs are not device output.
fn write_line(out: &mut Box<dyn Write>, line: &[u8]) -> std::io::Result<()> {
    if line.first() == Some(&b'#') {
        return Ok(());
    }
    out.write_all(line)?;
    out.flush()
}

/// Runs `vestnav emulate gps`.
pub fn run(args: &GpsArgs) -> anyhow::Result<()> {
    let mut out = output(args.pty)?;
    let stop = AtomicBool::new(false);
    if let Some(path) = &args.replay {
        let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        loop {
            let mut err = None;
            replay_lines(&data, Some(args.speed), &stop, |line| match write_line(&mut out, line) {
                Ok(()) => true,
                Err(e) => {
                    err = Some(e);
                    false
                }
            });
            if let Some(e) = err {
                return Err(e).context("writing NMEA");
            }
            if !args.repeat {
                return Ok(());
            }
        }
    }
    let demo = PathBuf::from("assets/routes/demo.gpx");
    let route = if let Some(p) = &args.route {
        load_route_gpx(p)?
    } else if demo.exists() {
        load_route_gpx(&demo)?
    } else {
        DEFAULT_ROUTE.to_vec()
    };
    let model = if args.no_static_nav {
        GnssErrorModel::sirf3_no_static_nav()
    } else {
        GnssErrorModel::sirf3_open_sky()
    };
    loop {
        let mut rx = SimulatedReceiver::new(&route, args.pace_m_s, model, args.seed, whole_second_now())?;
        let start = Instant::now();
        let mut k = 0u32;
        while !rx.finished() {
            out.write_all(rx.next_epoch(1.0).as_bytes())
                .and_then(|()| out.flush())
                .context("writing NMEA")?;
            k += 1;
            let due = start + Duration::from_secs(u64::from(k));
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
        }
        if !args.repeat {
            return Ok(());
        }
    }
}
