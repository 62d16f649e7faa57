//! `vestnav ntrip`: RTK corrections from an NTRIP caster to a receiver on a serial port (device's
//! `ntrip`), with the receiver's GGA sent upstream and a status line every second: state, correction age,
//! bytes per second, message types and the receiver's fix quality (RTK float / fixed). `--sourcetable`
//! lists the caster's mountpoints instead.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use vestnav_device::gps::{DecoderConfig, FixQuality, GpsEvent, NmeaDecoder};
use vestnav_device::ntrip::{
    NtripConfig, NtripState, NtripVersion, fetch_sourcetable, read_credentials, spawn,
};

/// NTRIP version on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum VersionArg {
    /// NTRIP 1.0 (`ICY 200 OK`).
    #[value(name = "1")]
    V1,
    /// NTRIP 2.0 (HTTP/1.1, chunked).
    #[value(name = "2")]
    V2,
}

/// Arguments of `vestnav ntrip`.
#[derive(Debug, Args)]
pub struct NtripArgs {
    /// The caster, HOST:PORT (plain TCP; NTRIP over TLS is not supported).
    #[arg(long, value_name = "HOST:PORT")]
    pub caster: String,
    /// The mountpoint (stream) to receive.
    #[arg(long, required_unless_present = "sourcetable")]
    pub mountpoint: Option<String>,
    /// File holding `user:password` on its first line, readable by you only (chmod 600).
    #[arg(long, value_name = "FILE")]
    pub credentials: Option<PathBuf>,
    /// The receiver's serial port: corrections are written to it, its NMEA is read for GGA and fix quality.
    #[arg(long, value_name = "PORT", required_unless_present = "sourcetable")]
    pub port: Option<String>,
    /// The port's baud rate.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Send the receiver's latest GGA to the caster every S seconds (0: never).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub gga_every: f64,
    /// NTRIP version.
    #[arg(long, value_enum, default_value = "2")]
    pub ntrip_version: VersionArg,
    /// No byte from the caster for S seconds is a stall: shown, then reconnected.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub stall_s: f64,
    /// Stop after S seconds (default: run until interrupted).
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    /// Print the caster's source table (its mountpoints) and exit.
    #[arg(long)]
    pub sourcetable: bool,
}

fn seconds(name: &str, s: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s)
        .map_err(|_| anyhow::anyhow!("{name} must be a non-negative number of seconds"))
}

/// Runs `vestnav ntrip`.
#[allow(clippy::print_stdout)]
pub fn run(args: &NtripArgs) -> anyhow::Result<()> {
    let mut config = NtripConfig::new(args.caster.clone(), args.mountpoint.clone().unwrap_or_default());
    config.version = match args.ntrip_version {
        VersionArg::V1 => NtripVersion::V1,
        VersionArg::V2 => NtripVersion::V2,
    };
    config.credentials = args.credentials.as_deref().map(read_credentials).transpose()?;
    let gga_every = seconds("--gga-every", args.gga_every)?;
    config.gga_every = (!gga_every.is_zero()).then_some(gga_every);
    config.stall_after = seconds("--stall-s", args.stall_s)?.max(Duration::from_millis(200));
    if args.sourcetable {
        return print_sourcetable(&config);
    }
    let duration = args.duration_s.map(|s| seconds("--duration-s", s)).transpose()?;
    let port_name = args.port.as_deref().context("--port is needed")?;
    let port = vestnav_device::serial::open(port_name, args.baud, Duration::from_millis(100))?;
    let writer = port.try_clone().with_context(|| format!("{port_name}: a second handle for writing"))?;
    let handle = spawn(config, Box::new(writer)).context("starting the NTRIP thread")?;
    let quality: Arc<Mutex<Option<FixQuality>>> = Arc::new(Mutex::new(None));
    let stop = Arc::new(AtomicBool::new(false));
    // The receiver's side: its NMEA gives the GGA to send upstream and the fix quality to show.
    let (gga_tx, gga_rx) = std::sync::mpsc::sync_channel::<String>(4);
    let reader = spawn_receiver_reader(port, Arc::clone(&quality), Arc::clone(&stop), gga_tx)?;
    let start = Instant::now();
    let mut next_print = start;
    let result = loop {
        while let Ok(g) = gga_rx.try_recv() {
            handle.set_gga(&g);
        }
        let now = Instant::now();
        let status = handle.status();
        if let NtripState::Failed { reason } = &status.state {
            break Err(anyhow::anyhow!("{reason}"));
        }
        if now >= next_print {
            let q = *quality.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            println!("{}", status.line(q, now));
            next_print += Duration::from_secs(1);
        }
        if duration.is_some_and(|d| now.duration_since(start) >= d) {
            break Ok(());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    stop.store(true, Ordering::Relaxed);
    let last = handle.stop();
    let _ = reader.join();
    println!(
        "ntrip: {} frames, {} bytes, {} GGA sent, {} stalls, {} connects; types {}",
        last.frames,
        last.bytes,
        last.gga_sent,
        last.stalls,
        last.connects,
        last.message_types_text()
    );
    result
}

/// `--sourcetable`: the caster's mountpoints, one a line.
#[allow(clippy::print_stdout)]
fn print_sourcetable(config: &NtripConfig) -> anyhow::Result<()> {
    let table = fetch_sourcetable(config)?;
    println!("{} streams at {}", table.streams.len(), config.caster);
    for s in &table.streams {
        println!(
            "  {:<20} {:<12} {:<10} {:<16} {:>8} {:>9}  GGA {}  {}",
            s.mountpoint,
            s.format,
            s.nav_system,
            s.identifier,
            s.lat_deg.map_or_else(String::new, |v| format!("{v:.2}")),
            s.lon_deg.map_or_else(String::new, |v| format!("{v:.2}")),
            if s.nmea { "needed" } else { "no" },
            s.format_details
        );
    }
    Ok(())
}

/// The receiver's side on its own thread: its NMEA gives the GGA to send upstream and the fix quality shown.
fn spawn_receiver_reader(
    mut port: impl std::io::Read + Send + 'static,
    quality: Arc<Mutex<Option<FixQuality>>>,
    stop: Arc<AtomicBool>,
    gga_tx: std::sync::mpsc::SyncSender<String>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new().name("ntrip-receiver".into()).spawn(move || {
        let mut decoder = NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
        let mut buf = [0u8; 1024];
        let mut read_error_shown = false;
        while !stop.load(Ordering::Relaxed) {
            match port.read(&mut buf) {
                Ok(n) if n > 0 => decoder.handle_bytes(buf.get(..n).unwrap_or(&[]), Instant::now()),
                Ok(_) => {}
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
                Err(e) => {
                    // Said once; the corrections keep flowing whatever the port's reading does.
                    if !read_error_shown {
                        eprintln!("vestnav ntrip: reading the receiver's port: {e}");
                        read_error_shown = true;
                    }
                    std::thread::sleep(Duration::from_millis(100));
                }
            }
            decoder.handle_timeout(Instant::now());
            while let Some(ev) = decoder.poll_event() {
                match ev {
                    GpsEvent::Raw(line) if line.text.get(3..7) == Some("GGA,") => {
                        let _ = gga_tx.try_send(line.text);
                    }
                    GpsEvent::Fix(f) => {
                        *quality.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = f.quality;
                    }
                    _ => {}
                }
            }
        }
    })
}
