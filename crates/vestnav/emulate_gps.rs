//! `vestnav emulate gps`: an NMEA GPS emulator on a pseudo-terminal.
//!
//! With `--simulate --pty` it is also a receiver that can be configured: it reads what the console writes
//! to the PTY and answers as `--receiver` would (`vestnav_device::gps::receiver_config::emulator`): a
//! `SiRF` III with static navigation on (the default), a u-blox 8 or an M9/F9. The rate, static navigation /
//! static hold and the protocol it is switched to take effect on the next epoch.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_device::gps::ReplaySpeed;
use vestnav_device::gps::receiver_config::emulator::{
    EmulatedFamily, EmulatedReceiver, EmulatedSettings, Protocol,
};
use vestnav_device::gps::sim::{SimulatedReceiver, demo_route, load_route_gpx, whole_second_now};
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
    /// Route for --simulate (GPX: route, track or waypoints); default the built-in demo route (assets/routes/demo.gpx).
    #[arg(long, requires = "simulate")]
    pub route: Option<PathBuf>,
    /// Serve on a new pseudo-terminal and print its path (default: write to standard output).
    #[arg(long)]
    pub pty: bool,
    /// Replay speed factor (1 = recorded speed, 0 = as fast as possible, at most 1000).
    #[arg(long, default_value_t = ReplaySpeed::default())]
    pub speed: ReplaySpeed,
    /// Walking pace for --simulate [m/s].
    #[arg(long, default_value_t = 1.4)]
    pub pace_m_s: f64,
    /// Random seed of the simulated receiver error.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulate without `SiRF` static navigation (no position pinning below 1.2 m/s).
    #[arg(long)]
    pub no_static_nav: bool,
    /// The receiver --simulate imitates, which decides the configuration commands it answers on the
    /// PTY: sirf3 (the thesis's BT-359: static navigation on until switched off with MID 143), ublox8
    /// (UBX CFG-RATE/-NAV5/-GNSS/-CFG, static hold off) or ublox9 (UBX-CFG-VALSET).
    #[arg(long, default_value = "sirf3", value_parser = parse_receiver, requires = "simulate")]
    pub receiver: EmulatedFamily,
    /// Keep serving: loop the replay, or walk the route again when it ends.
    #[arg(long)]
    pub repeat: bool,
}

fn parse_receiver(s: &str) -> Result<EmulatedFamily, String> {
    EmulatedFamily::from_name(s).ok_or_else(|| format!("{s:?}: one of sirf3, ublox8, ublox9"))
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
    if let Some(path) = &args.replay {
        let mut out = output(args.pty)?;
        let stop = AtomicBool::new(false);
        let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        loop {
            let mut err = None;
            replay_lines(&data, args.speed, &stop, |line| match write_line(&mut out, line) {
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
    let route = match &args.route {
        Some(p) => load_route_gpx(p)?,
        None => demo_route()?,
    };
    simulate(args, &route)
}

/// The simulated receiver's link: a PTY that is read for configuration commands, or standard output.
enum Link {
    #[cfg(unix)]
    Pty(vestnav_device::serial::Pty),
    Stdout(std::io::Stdout),
}

impl Link {
    fn open(pty: bool) -> anyhow::Result<Self> {
        if pty {
            #[cfg(unix)]
            {
                // Short read timeouts: the commands are answered within ~20 ms, as a receiver would.
                let p = vestnav_device::serial::Pty::open_with_timeout(Duration::from_millis(20))?;
                println_path(p.path());
                return Ok(Self::Pty(p));
            }
            #[cfg(not(unix))]
            anyhow::bail!("--pty needs a Unix pseudo-terminal");
        }
        Ok(Self::Stdout(std::io::stdout()))
    }

    /// Writes and flushes; a PTY nobody reads drops the bytes, as a receiver keeps sending.
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let r = match self {
            #[cfg(unix)]
            Self::Pty(p) => p.write_all(bytes).and_then(|()| p.flush()),
            Self::Stdout(o) => o.write_all(bytes).and_then(|()| o.flush()),
        };
        match r {
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(()),
            r => r,
        }
    }

    /// What the console wrote, waiting at most until `until` (nothing on standard output).
    fn receive(&mut self, buf: &mut [u8], until: Instant) -> usize {
        match self {
            #[cfg(unix)]
            Self::Pty(p) => {
                use std::io::Read as _;
                if Instant::now() >= until {
                    return 0;
                }
                p.read(buf).unwrap_or(0)
            }
            Self::Stdout(_) => {
                std::thread::sleep(until.saturating_duration_since(Instant::now()));
                0
            }
        }
    }
}

/// How often the emulated receiver repeats its power-on banner.
const BANNER_EVERY: std::time::Duration = std::time::Duration::from_secs(30);

fn apply(rx: &mut SimulatedReceiver, s: &EmulatedSettings) {
    rx.set_static_hold(s.static_hold_m_s, s.static_hold_max_dist_m);
}

/// The walker, epoch by epoch at the configured rate, answering configuration commands in between.
fn simulate(args: &GpsArgs, route: &[(f64, f64)]) -> anyhow::Result<()> {
    let mut link = Link::open(args.pty)?;
    // Static navigation comes from the emulated receiver's settings (SiRF III: on unless --no-static-nav).
    let model = GnssErrorModel::sirf3_no_static_nav();
    let mut emu = EmulatedReceiver::new(args.receiver, !args.no_static_nav);
    let mut buf = [0u8; 1024];
    // The power-on banner ($PSRFTXT on a SiRF III), repeated every BANNER_EVERY so a console that opens the
    // port later still learns the family from the stream (a real receiver sends it at power-on only).
    let mut banner_due = Instant::now();
    loop {
        let mut rx = SimulatedReceiver::new(route, args.pace_m_s, model, args.seed, whole_second_now())?;
        apply(&mut rx, emu.settings());
        let mut due = Instant::now();
        while !rx.finished() {
            if Instant::now() >= due {
                let period = emu.settings().period;
                let epoch = rx.next_epoch(period.as_secs_f64());
                // In SiRF binary the receiver keeps navigating but sends no NMEA.
                if emu.settings().protocol == Protocol::Nmea {
                    if Instant::now() >= banner_due {
                        link.send(&emu.banner()).context("writing the banner")?;
                        banner_due = Instant::now() + BANNER_EVERY;
                    }
                    link.send(epoch.as_bytes()).context("writing NMEA")?;
                }
                due += period;
                // Never catch up in a burst after a stall: a receiver's epochs are its own clock.
                if due + period < Instant::now() {
                    due = Instant::now() + period;
                }
            }
            let n = link.receive(&mut buf, due);
            if n > 0 {
                emu.handle_bytes(&buf[..n]);
                let reply = emu.take_output();
                if !reply.is_empty() {
                    link.send(&reply).context("writing a reply")?;
                }
                for line in emu.take_log() {
                    eprintln!("emulated {}: {line}", args.receiver.name());
                }
                if emu.take_changed() {
                    apply(&mut rx, emu.settings());
                }
            }
        }
        if !args.repeat {
            return Ok(());
        }
    }
}
