//! `vestnav emulate vest`: the WTCU emulator on a pseudo-terminal (or stdin/stdout), with a live view of
//! the 4x4 grid. The unit side is `vestnav_device::wtcu::engine` (limits, patterns, watchdog); the protocol
//! is `docs/wtcu-protocol.md`.
//!
//! Replies nobody reads (a full PTY buffer, a stdout pipe nobody drains) are dropped, never waited for: the
//! unit keeps running its watchdog and limits, and a line on stderr (at most one a second) says how many
//! were dropped.

use std::fmt::Write as _;
use std::io::{self, IsTerminal, Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use vestnav_core::vest::{GRID, TactorMask};
use vestnav_device::sim::{CompassSetup, WearerMotion};
#[cfg(unix)]
use vestnav_device::wtcu::emulator::Pty;
use vestnav_device::wtcu::emulator::{EmulatorControl, SERVE_POLL, ServeEnd, UnitConfig, describe, serve};
use vestnav_device::wtcu::engine::{Engine, EngineConfig, EngineEvent, battery_pct_from_mv};
use vestnav_device::wtcu::firmware_sim::{FirmwareSim, FirmwareSimConfig, SimEvent, field_for_heading};
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::message::CommandKind;

/// Arguments of `vestnav emulate vest`.
#[allow(clippy::struct_excessive_bools)] // independent command-line switches, not a state machine
#[derive(Debug, Args)]
pub struct VestArgs {
    /// Serve the protocol on a new pseudo-terminal and print the path to open (the default).
    #[arg(long, conflicts_with = "stdio")]
    pub pty: bool,
    /// Serve the protocol on stdin/stdout instead (e.g. behind socat); the view goes to stderr.
    #[arg(long)]
    pub stdio: bool,
    /// Battery voltage the unit reports [mV] (below 3500 raises the low-battery fault).
    #[arg(long, default_value_t = 3900)]
    pub battery_mv: u16,
    /// Emulate a unit without intensity control (`SET_INTENSITY` is refused).
    #[arg(long)]
    pub no_intensity: bool,
    /// Silence from the console after which the unit stops everything [ms].
    #[arg(long, default_value_t = 1500, value_parser = clap::value_parser!(u16).range(100..))]
    pub watchdog_ms: u16,
    /// Most tactors on at once (the current budget divided by 70 mA per tactor).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub max_simultaneous: u8,
    /// Newest protocol version the unit speaks: 2 (heading) or 1 (an old unit: no compass).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub protocol: u8,
    /// Emulate a v2 unit without a magnetometer (`HEADING_START` is refused).
    #[arg(long)]
    pub no_compass: bool,
    /// The wearer's true heading while standing still [deg].
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub heading_deg: f64,
    /// Make the wearer turn in place at this rate [deg/s] (a calibration rotation); 0 = stand still.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub turn_deg_s: f64,
    /// A parked car this far east of the wearer [m] (disturbs the compass within a few metres).
    #[arg(long)]
    pub steel_east_m: Option<f64>,
    /// An ideal magnetometer (no hard/soft iron, no noise) instead of a typical uncalibrated one.
    #[arg(long)]
    pub ideal_compass: bool,
    /// Give the unit a GPS receiver on its second UART that sends this NMEA file in a loop (protocol v2,
    /// forwarded inside the link when the console asks: GPS source "through the vest unit").
    #[arg(long, value_name = "FILE")]
    pub gps_nmea: Option<PathBuf>,
    /// Run the reference firmware image (e.g. `firmware/build/wtcu-mega.elf`) in simavr instead of the
    /// built-in emulator: the same bytes a board would be flashed with, paced to real time.
    #[arg(long, value_name = "ELF", conflicts_with_all = ["stdio", "protocol", "no_intensity", "watchdog_ms", "max_simultaneous", "turn_deg_s", "steel_east_m", "ideal_compass"])]
    pub firmware: Option<PathBuf>,
    /// The simavr harness for `--firmware` (default: `wtcu-sim` beside the ELF; `make -C firmware/sim`).
    #[arg(long, value_name = "PATH", requires = "firmware")]
    pub harness: Option<PathBuf>,
    /// Baud rate of the GPS receiver (`--gps-nmea`) on the unit's UART.
    #[arg(long, default_value_t = 9600)]
    pub gps_baud: u32,
}

impl VestArgs {
    fn unit_config(&self) -> anyhow::Result<UnitConfig> {
        let gps_nmea = match &self.gps_nmea {
            Some(path) => Some(read_nmea(path)?),
            None => None,
        };
        let engine = EngineConfig {
            limits: Limits { max_simultaneous: self.max_simultaneous, ..Limits::default() },
            watchdog_ms: self.watchdog_ms,
            intensity: !self.no_intensity,
            battery_mv: self.battery_mv,
            protocol_version: self.protocol,
            gps_nmea,
            ..EngineConfig::default()
        };
        Ok(UnitConfig {
            engine,
            compass: (!self.no_compass).then_some(CompassSetup {
                motion: if self.turn_deg_s == 0.0 {
                    WearerMotion::Still { heading_deg: self.heading_deg }
                } else {
                    WearerMotion::Turning { start_deg: self.heading_deg, rate_deg_s: self.turn_deg_s }
                },
                steel_east_m: self.steel_east_m,
                ideal: self.ideal_compass,
                seed: 1,
            }),
            skin: None,
        })
    }
}

/// Most NMEA a looped receiver file may hold.
const MAX_GPS_FILE: u64 = 16 << 20;

/// The file a simulated receiver sends, checked: readable, not empty, bounded.
fn read_nmea(path: &std::path::Path) -> anyhow::Result<Arc<[u8]>> {
    let name = path.display();
    let len = std::fs::metadata(path).with_context(|| format!("{name}"))?.len();
    anyhow::ensure!(len > 0, "{name}: empty file");
    anyhow::ensure!(
        len <= MAX_GPS_FILE,
        "{name}: {len} bytes, more than the {MAX_GPS_FILE} a looped receiver file may hold"
    );
    Ok(std::fs::read(path).with_context(|| format!("{name}"))?.into())
}

/// Runs `vestnav emulate vest` until Ctrl-C, or EOF on an interactive stdin (or on stdin in `--stdio` mode).
pub fn run(args: &VestArgs) -> anyhow::Result<()> {
    if let Some(elf) = &args.firmware {
        return run_firmware(elf, args);
    }
    let mut engine = args.unit_config()?.build();
    let control = Arc::new(EmulatorControl::default());
    spawn_drop_reporter(control.clone())?;
    if args.stdio {
        let mut port = StdioPort::spawn()?;
        let mut view = View::new(io::stderr(), "stdin/stdout", args.battery_mv);
        view.header()?;
        let end = serve(&mut engine, &mut port, &control, |e, ev| view.update(e, ev))
            .context("serving the protocol on stdin/stdout")?;
        return view.finish(&end, control.replies_dropped.load(Ordering::Relaxed));
    }
    run_pty(&mut engine, &control, args)
}

#[cfg(unix)]
fn run_pty(engine: &mut Engine, control: &Arc<EmulatorControl>, args: &VestArgs) -> anyhow::Result<()> {
    let Pty { mut master, path, slave } = Pty::open_with_timeout(vestnav_device::wtcu::emulator::SERVE_POLL)
        .context("opening a pseudo-terminal")?;
    let mut out = io::stdout();
    writeln!(out, "WTCU emulator on {path}")?;
    writeln!(out, "open it from the console like a Bluetooth serial port; Ctrl-C (or EOF) ends")?;
    out.flush()?;
    // Keep our own handle on the slave: consoles may open and close it without the master seeing a hang-up.
    let _keep_slave_open = slave;
    if io::stdin().is_terminal() {
        let c = control.clone();
        // Detached: it blocks on stdin until EOF; the process ends with it either way.
        std::thread::Builder::new().name("stdin-eof".to_owned()).spawn(move || {
            let mut sink = Vec::new();
            let _ = io::stdin().lock().read_to_end(&mut sink);
            c.stop.store(true, Ordering::Relaxed);
        })?;
    }
    let mut view = View::new(io::stdout(), &path, args.battery_mv);
    view.header()?;
    let end =
        serve(engine, &mut master, control, |e, ev| view.update(e, ev)).context("serving the protocol")?;
    view.finish(&end, control.replies_dropped.load(Ordering::Relaxed))
}

#[cfg(not(unix))]
fn run_pty(_: &mut Engine, _: &Arc<EmulatorControl>, _: &VestArgs) -> anyhow::Result<()> {
    anyhow::bail!("pseudo-terminals need a Unix system; use --stdio")
}

/// Runs the firmware image in simavr and shows what its tactor pins do, until Ctrl-C or EOF on an
/// interactive stdin.
fn run_firmware(elf: &std::path::Path, args: &VestArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.gps_nmea {
        read_nmea(path)?;
    }
    let mut config = FirmwareSimConfig::new(elf);
    config.harness.clone_from(&args.harness);
    config.battery_mv = args.battery_mv;
    config.gps_nmea.clone_from(&args.gps_nmea);
    config.gps_baud = args.gps_baud;
    // A mid-latitude field (20 µT horizontal, 45 µT down) with the wearer facing --heading-deg (magnetic).
    config.mag_ut = (!args.no_compass).then(|| field_for_heading(args.heading_deg, 20.0, 45.0));
    let mut sim = FirmwareSim::spawn(&config).map_err(anyhow::Error::msg)?;
    let mut out = io::stdout();
    writeln!(out, "WTCU firmware {} (simavr, {}) on {}", elf.display(), sim.mcu().name(), sim.path())?;
    writeln!(out, "open it from the console like a Bluetooth serial port; Ctrl-C (or EOF) ends")?;
    out.flush()?;
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    if io::stdin().is_terminal() {
        let s = stop.clone();
        // Detached: it blocks on stdin until EOF; the process ends with it either way.
        std::thread::Builder::new().name("stdin-eof".to_owned()).spawn(move || {
            let mut sink = Vec::new();
            let _ = io::stdin().lock().read_to_end(&mut sink);
            s.store(true, Ordering::Relaxed);
        })?;
    }
    while !stop.load(Ordering::Relaxed) {
        let Some(event) = sim.next_event(Duration::from_millis(100)) else { continue };
        let line = match event {
            SimEvent::Pins { sim_us, mask } => {
                let on: Vec<String> = mask.indices().map(|i| i.to_string()).collect();
                format!("{:10.3} s  pins: {} on [{}]", sim_us as f64 / 1e6, mask.count(), on.join(" "))
            }
            SimEvent::Reset(sim_us) => format!("{:10.3} s  watchdog reset of the MCU", sim_us as f64 / 1e6),
            SimEvent::Rx(_) | SimEvent::Tx(_) => continue,
            SimEvent::Unparsed(line) => format!("harness said: {line}"),
            SimEvent::Ended => {
                writeln!(out, "the simulation ended")?;
                break;
            }
        };
        writeln!(out, "{line}")?;
        out.flush()?;
    }
    sim.shutdown();
    Ok(())
}

/// Says on stderr, at most once a second, how many replies were dropped because nobody read them.
fn spawn_drop_reporter(control: Arc<EmulatorControl>) -> io::Result<()> {
    // Detached: it only reads a counter; the process ends with the emulator either way.
    std::thread::Builder::new().name("drop-reporter".to_owned()).spawn(move || {
        let mut reported = 0;
        while !control.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_secs(1));
            let dropped = control.replies_dropped.load(Ordering::Relaxed);
            if dropped > reported {
                let _ = writeln!(
                    io::stderr().lock(),
                    "emulator: {} replies dropped in the last second, nobody reading ({dropped} in total)",
                    dropped - reported
                );
                reported = dropped;
            }
        }
    })?;
    Ok(())
}

/// Frames waiting for stdout; more and the unit drops its replies rather than wait for the reader.
const STDOUT_QUEUE: usize = 64;

/// stdin/stdout as a serial line: a thread reads stdin into a channel so reads can time out, another
/// writes stdout from a bounded channel so writes never block (a full channel is `WouldBlock`).
struct StdioPort {
    rx: Receiver<Vec<u8>>,
    pending: Vec<u8>,
    out: SyncSender<Vec<u8>>,
}

impl StdioPort {
    fn spawn() -> io::Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<u8>>(64);
        std::thread::Builder::new().name("stdin-reader".to_owned()).spawn(move || {
            let mut stdin = io::stdin().lock();
            let mut buf = [0u8; 512];
            while let Ok(n) = stdin.read(&mut buf) {
                if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        })?;
        let (out, to_write) = std::sync::mpsc::sync_channel::<Vec<u8>>(STDOUT_QUEUE);
        std::thread::Builder::new().name("stdout-writer".to_owned()).spawn(move || {
            let mut stdout = io::stdout().lock();
            while let Ok(bytes) = to_write.recv() {
                if stdout.write_all(&bytes).and_then(|()| stdout.flush()).is_err() {
                    break;
                }
            }
        })?;
        Ok(Self { rx, pending: Vec::new(), out })
    }
}

impl Read for StdioPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.pending.is_empty() {
            match self.rx.recv_timeout(SERVE_POLL) {
                Ok(bytes) => self.pending = bytes,
                Err(RecvTimeoutError::Timeout) => return Err(io::ErrorKind::TimedOut.into()),
                Err(RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }
}

impl Write for StdioPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self.out.try_send(buf.to_vec()) {
            Ok(()) => Ok(buf.len()),
            Err(TrySendError::Full(_)) => Err(io::ErrorKind::WouldBlock.into()),
            Err(TrySendError::Disconnected(_)) => Err(io::ErrorKind::BrokenPipe.into()),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// The live view: on a terminal, a block of lines redrawn in place on every change; otherwise one plain
/// line per event.
struct View<W: Write> {
    out: W,
    tty: bool,
    start: Instant,
    drawn_lines: usize,
    last: String,
    battery_mv: u16,
}

impl<W: Write + IsTerminal> View<W> {
    fn new(out: W, path: &str, battery_mv: u16) -> Self {
        let tty = out.is_terminal();
        Self {
            out,
            tty,
            start: Instant::now(),
            drawn_lines: 0,
            last: format!("waiting on {path}"),
            battery_mv,
        }
    }

    fn header(&mut self) -> io::Result<()> {
        if self.tty {
            self.draw(TactorMask::NONE, None)
        } else {
            writeln!(self.out, "0.000 s  {}", self.last)
        }
    }

    fn update(&mut self, engine: &Engine, event: &EngineEvent) {
        // Heartbeats come four times a second: they feed the watchdog, they are not news.
        if matches!(event, EngineEvent::Accepted { kind: CommandKind::Heartbeat, .. }) {
            return;
        }
        self.last = describe(event);
        // A broken view must not stop the unit: its watchdog and limits keep running.
        let _ = if self.tty {
            self.draw(engine.tactors_on(), Some(engine))
        } else {
            writeln!(self.out, "{:.3} s  {}", self.start.elapsed().as_secs_f64(), self.last)
        };
    }

    fn draw(&mut self, on: TactorMask, engine: Option<&Engine>) -> io::Result<()> {
        let mut block = String::new();
        if self.drawn_lines > 0 {
            // Cursor to the start of the block, then overwrite each line.
            let _ = write!(block, "\x1b[{}F", self.drawn_lines);
        }
        let line = |s: &mut String, text: &str| {
            s.push_str("\x1b[2K");
            s.push_str(text);
            s.push('\n');
        };
        let console = match engine {
            Some(e) if e.identified() && e.faults().names().contains(&"watchdog") => {
                "silent (watchdog tripped)"
            }
            Some(e) if e.identified() => "connected",
            _ => "no console yet",
        };
        line(
            &mut block,
            &format!(
                "battery {} mV ({} %)   console: {console}   on: {} of 16 ({:.0} mA)",
                self.battery_mv,
                battery_pct_from_mv(self.battery_mv),
                on.count(),
                on.current_a() * 1000.0
            ),
        );
        line(&mut block, "   wearer's left      right");
        for row in 0..GRID {
            let cells: Vec<String> = (0..GRID)
                .map(|col| {
                    let i = row * GRID + col;
                    if on.contains(i) { format!("[{i:>2}]") } else { format!(" {i:>2} ") }
                })
                .collect();
            line(&mut block, &format!("   {}", cells.join(" ")));
        }
        let stats = engine.map(Engine::stats).unwrap_or_default();
        line(
            &mut block,
            &format!(
                "frames {}  garbage {}  bad CRC {}  NAKs {}  repeats {}  watchdog trips {}",
                stats.frames_ok,
                stats.garbage,
                stats.bad_crc,
                stats.naks_sent,
                stats.duplicates,
                stats.watchdog_trips
            ),
        );
        line(&mut block, &format!("last: {}", self.last));
        self.drawn_lines = block.matches('\n').count();
        self.out.write_all(block.as_bytes())?;
        self.out.flush()
    }

    fn finish(&mut self, end: &ServeEnd, replies_dropped: u64) -> anyhow::Result<()> {
        let why = match end {
            ServeEnd::Stopped => "stopped",
            ServeEnd::Eof => "the other side closed",
            ServeEnd::Vanished => "port closed",
        };
        writeln!(self.out, "emulator ended: {why}")?;
        if replies_dropped > 0 {
            writeln!(self.out, "{replies_dropped} replies were dropped because nobody read them")?;
        }
        Ok(())
    }
}
