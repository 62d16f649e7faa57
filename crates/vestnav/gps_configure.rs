//! `vestnav gps configure`: configure a GPS receiver on a serial port (rate, constellations, dynamic
//! model, static hold; `SiRF` static navigation), or print the frames (`--dry-run`) to paste into u-center.

use std::io::{Read, Write};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use vestnav_device::gps::receiver_config::session::ConfigSession;
use vestnav_device::gps::receiver_config::{
    Constellations, DynamicModel, Family, Outcome, ReceiverConfig, commands,
};

/// The receiver family on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FamilyArg {
    /// u-blox 6, 7, 8 (UBX CFG-RATE, CFG-GNSS, CFG-NAV5, CFG-CFG).
    Ublox,
    /// u-blox M9/F9 (UBX-CFG-VALSET).
    Ublox9,
    /// `SiRF` III/IV in NMEA mode (static navigation through `SiRF` binary).
    Sirf,
}

/// On or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Switch it on.
    On,
    /// Switch it off.
    Off,
}

/// Arguments of `vestnav gps configure`.
#[derive(Debug, Args)]
pub struct ConfigureArgs {
    /// The receiver's serial port (/dev/ttyUSB0, /dev/rfcomm0, COM5, an emulator's /dev/pts/N).
    #[arg(long, required_unless_present = "dry_run")]
    pub port: Option<String>,
    /// Baud rate of the port; detected from the NMEA it sends when not given (--dry-run: 4800 for sirf,
    /// 9600 otherwise).
    #[arg(long)]
    pub baud: Option<u32>,
    /// The receiver family, which decides the commands.
    #[arg(long, value_enum)]
    pub family: FamilyArg,
    /// Navigation rate [Hz], 1 to 10 (u-blox).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=10))]
    pub rate: Option<u8>,
    /// Constellations to track, comma-separated: gps, glonass, galileo, beidou, qzss, sbas (u-blox; the
    /// others are switched off; a u-blox 8 tracks at most three of GPS/GLONASS/Galileo/BeiDou).
    #[arg(long, value_parser = Constellations::parse)]
    pub constellations: Option<Constellations>,
    /// Dynamic platform model (u-blox): portable, stationary, pedestrian, automotive, sea, airborne1g.
    #[arg(long, value_parser = parse_model)]
    pub dynamic_model: Option<DynamicModel>,
    /// u-blox static hold: below this speed [m/s] the position is held; 0 switches it off (0 to 2.55).
    #[arg(long, value_name = "M_S")]
    pub static_hold: Option<f64>,
    /// u-blox static hold: leave the hold once the solution moved this far [m].
    #[arg(long, value_name = "M")]
    pub static_hold_max_dist: Option<u16>,
    /// `SiRF` static navigation (the thesis's `SiRF` III holds the position below ~1.2 m/s while on).
    #[arg(long, value_enum)]
    pub sirf_static_nav: Option<OnOff>,
    /// Also save to the receiver's battery-backed RAM and flash (u-blox), so it survives a power cycle.
    #[arg(long)]
    pub save: bool,
    /// Print the commands as hex (one per line, named) instead of sending them.
    #[arg(long)]
    pub dry_run: bool,
}

fn parse_model(s: &str) -> Result<DynamicModel, String> {
    DynamicModel::from_name(s).ok_or_else(|| {
        let names: Vec<_> = DynamicModel::ALL.iter().map(|m| m.name()).collect();
        format!("{s:?}: one of {}", names.join(", "))
    })
}

impl ConfigureArgs {
    /// The configuration asked for.
    pub fn config(&self) -> ReceiverConfig {
        let family = match self.family {
            FamilyArg::Ublox => Family::Ublox,
            FamilyArg::Ublox9 => Family::Ublox9,
            FamilyArg::Sirf => Family::Sirf,
        };
        ReceiverConfig {
            rate_hz: self.rate,
            constellations: self.constellations,
            dynamic_model: self.dynamic_model,
            static_hold_m_s: self.static_hold,
            static_hold_max_dist_m: self.static_hold_max_dist,
            sirf_static_nav: self.sirf_static_nav.map(|s| s == OnOff::On),
            save: self.save,
            ..ReceiverConfig::new(family)
        }
    }
}

/// Runs `vestnav gps configure`.
#[allow(clippy::print_stdout)] // the command's report is its output
pub fn run(args: &ConfigureArgs) -> anyhow::Result<()> {
    let cfg = args.config();
    if args.dry_run {
        let baud = args.baud.unwrap_or(if cfg.family == Family::Sirf { 4800 } else { 9600 });
        for c in commands(&cfg, baud)? {
            println!("{}: {}", c.name, c.hex());
        }
        return Ok(());
    }
    let port = args.port.as_deref().context("--port is needed unless --dry-run")?;
    let (baud, _) = match args.baud {
        Some(b) => (b, Vec::new()),
        None => vestnav_device::gps::source::detect_baud(
            port,
            Duration::from_millis(1500),
            &AtomicBool::new(false),
        )
        .map_err(|e| anyhow::anyhow!("{port}: cannot detect the baud rate: {e}"))?,
    };
    let cmds = commands(&cfg, baud)?;
    let total = cmds.len();
    let mut p = vestnav_device::serial::open(port, baud, Duration::from_millis(50))?;
    let mut session = ConfigSession::new(cmds);
    let mut buf = [0u8; 1024];
    let mut failed = 0;
    let stdout = std::io::stdout();
    while !session.is_done() {
        let now = Instant::now();
        session.handle_timeout(now);
        while let Some(bytes) = session.poll_transmit(now) {
            if let Err(e) = p.write_all(&bytes).and_then(|()| p.flush()) {
                session.write_failed(&e.to_string(), now);
            }
        }
        while let Some(o) = session.poll_outcome() {
            if !matches!(o.outcome, Outcome::Accepted | Outcome::Sent) {
                failed += 1;
            }
            writeln!(stdout.lock(), "{}: {}", o.name, o.outcome.label())?;
        }
        match p.read(&mut buf) {
            Ok(n) => session.handle_bytes(&buf[..n], Instant::now()),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted) => {}
            Err(e) => return Err(e).with_context(|| format!("reading {port}")),
        }
    }
    if failed > 0 {
        anyhow::bail!("{failed} of {total} commands not accepted");
    }
    Ok(())
}
