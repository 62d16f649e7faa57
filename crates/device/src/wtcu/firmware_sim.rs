//! The reference WTCU firmware (`firmware/`) running in simavr, as a unit the console can open.
//!
//! `firmware/build/wtcu-sim` (the harness in `firmware/sim/`) loads the very `.elf` one would flash,
//! runs it instruction by instruction paced to wall-clock time, bridges the link UART to a
//! pseudo-terminal and reports what the tactor pins do on the simulated clock. [`FirmwareSim::spawn`]
//! starts it and parses its reports; the console then opens [`FirmwareSim::path`] exactly like
//! `/dev/rfcomm0`. `vestnav emulate vest --firmware` and the conformance suite (`tests/hil`) use it.
//!
//! The harness's stdout is a line protocol (`firmware/sim/README.md`): `pty PATH` first, then
//! `pins <sim_us> <mask hex>`, `rx <sim_us>` (a frame delimiter reached the unit's UART), `tx <sim_us>`
//! (the unit sent one) and `reset <sim_us>` (a watchdog reset). Every line is checked; a line that does
//! not parse is reported as [`SimEvent::Unparsed`], never trusted.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, sync_channel};
use std::time::Duration;

use vestnav_core::vest::TactorMask;

/// The two boards the firmware is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mcu {
    /// Arduino Mega 2560: tactors, heading (LSM303AGR), GPS forwarding.
    Atmega2560,
    /// Arduino Nano/Uno: tactors only.
    Atmega328p,
}

impl Mcu {
    /// simavr's name of the part.
    pub fn name(self) -> &'static str {
        match self {
            Self::Atmega2560 => "atmega2560",
            Self::Atmega328p => "atmega328p",
        }
    }

    /// The part an AVR ELF was built for, from its header: `e_machine` must be AVR (83) and the low
    /// bits of `e_flags` name the architecture (avr5 = `ATmega328P`, avr6 = `ATmega2560`).
    pub fn of_elf(path: &Path) -> Result<Self, String> {
        let name = path.display();
        let bytes = std::fs::read(path).map_err(|e| format!("{name}: {e}"))?;
        let header = bytes.get(..40).ok_or_else(|| format!("{name}: too short for an ELF file"))?;
        if &header[..4] != b"\x7fELF" || header[4] != 1 || header[5] != 1 {
            return Err(format!("{name}: not a 32-bit little-endian ELF file"));
        }
        let machine = u16::from_le_bytes([header[18], header[19]]);
        if machine != 83 {
            return Err(format!("{name}: ELF for machine {machine}, not AVR (83)"));
        }
        let flags = u32::from_le_bytes([header[36], header[37], header[38], header[39]]);
        match flags & 0x7f {
            5 => Ok(Self::Atmega328p),
            6 => Ok(Self::Atmega2560),
            arch => Err(format!("{name}: AVR architecture avr{arch}; the firmware targets avr5 or avr6")),
        }
    }
}

/// How to run the firmware.
#[derive(Debug, Clone)]
pub struct FirmwareSimConfig {
    /// The firmware image (`firmware/build/wtcu-mega.elf` or `wtcu-nano.elf`).
    pub elf: PathBuf,
    /// The harness; `None`: `wtcu-sim` beside the ELF.
    pub harness: Option<PathBuf>,
    /// Battery voltage on the ADC pin's divider \[mV\].
    pub battery_mv: u16,
    /// NMEA the GPS receiver on the unit's second UART sends, looped (Mega only).
    pub gps_nmea: Option<PathBuf>,
    /// The receiver's baud rate.
    pub gps_baud: u32,
    /// The magnetic field at the sensor, body frame (x forward, y right, z down) \[µT\]; `None`: no
    /// magnetometer on the bus.
    pub mag_ut: Option<[f64; 3]>,
    /// The accelerometer's specific force, body frame \[g\]: a level unit at rest reads `[0, 0, -1]`
    /// (the reaction to gravity points up, z points down; `docs/heading.md`).
    pub accel_g: [f64; 3],
}

impl FirmwareSimConfig {
    /// The default run of `elf`: 3900 mV, no GPS, a 20 µT horizontal / 45 µT vertical field facing
    /// magnetic north.
    pub fn new(elf: impl Into<PathBuf>) -> Self {
        Self {
            elf: elf.into(),
            harness: None,
            battery_mv: 3900,
            gps_nmea: None,
            gps_baud: 9600,
            mag_ut: Some([20.0, 0.0, 45.0]),
            accel_g: [0.0, 0.0, -1.0],
        }
    }
}

/// The field a wearer facing `heading_deg` (magnetic) measures on the vest's back, from the horizontal
/// and downward components of the local field \[µT\]: the horizontal field points to magnetic north,
/// which is `heading_deg` to the left of forward.
pub fn field_for_heading(heading_deg: f64, horizontal_ut: f64, down_ut: f64) -> [f64; 3] {
    let h = heading_deg.to_radians();
    [horizontal_ut * h.cos(), -horizontal_ut * h.sin(), down_ut]
}

/// One report of the harness.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimEvent {
    /// The tactor outputs changed to `mask` at `sim_us`.
    Pins {
        /// Simulated time \[µs\].
        sim_us: u64,
        /// Tactors driven.
        mask: TactorMask,
    },
    /// A frame delimiter from the console reached the unit's UART at `sim_us`.
    Rx(u64),
    /// The unit sent a frame delimiter at `sim_us`.
    Tx(u64),
    /// The MCU was reset by its watchdog at `sim_us`.
    Reset(u64),
    /// A line that does not parse (kept for the error report).
    Unparsed(String),
    /// The harness ended (its stdout closed).
    Ended,
}

/// Parses one line of the harness's stdout (after the `pty` line).
pub fn parse_line(line: &str) -> SimEvent {
    let mut it = line.split_ascii_whitespace();
    let (kind, time) = (it.next(), it.next().and_then(|t| t.parse::<u64>().ok()));
    let event = match (kind, time) {
        (Some("pins"), Some(sim_us)) => it
            .next()
            .filter(|m| m.len() == 4)
            .and_then(|m| u16::from_str_radix(m, 16).ok())
            .map(|m| SimEvent::Pins { sim_us, mask: TactorMask(m) }),
        (Some("rx"), Some(t)) => Some(SimEvent::Rx(t)),
        (Some("tx"), Some(t)) => Some(SimEvent::Tx(t)),
        (Some("reset"), Some(t)) => Some(SimEvent::Reset(t)),
        _ => None,
    };
    match event {
        Some(e) if it.next().is_none() => e,
        _ => SimEvent::Unparsed(line.chars().take(200).collect()),
    }
}

/// A running simulated unit. Dropping it ends the simulation (the harness exits when its stdin closes).
#[derive(Debug)]
pub struct FirmwareSim {
    child: Child,
    stdin: Option<ChildStdin>,
    path: String,
    mcu: Mcu,
    events: Receiver<SimEvent>,
}

/// Most harness reports waiting unread; further ones are dropped (a reader that never reads must not
/// make the harness block on its stdout, which would stall the simulated unit).
const EVENT_QUEUE: usize = 1 << 16;

impl FirmwareSim {
    /// Starts the harness on `config.elf` and waits (up to 5 s) for its pseudo-terminal.
    pub fn spawn(config: &FirmwareSimConfig) -> Result<Self, String> {
        let mcu = Mcu::of_elf(&config.elf)?;
        let harness = match &config.harness {
            Some(h) => h.clone(),
            None => config.elf.parent().unwrap_or(Path::new(".")).join("wtcu-sim"),
        };
        if !harness.is_file() {
            return Err(format!(
                "{}: the simavr harness is missing (build it with `make -C firmware/sim`)",
                harness.display()
            ));
        }
        let mut cmd = Command::new(&harness);
        cmd.arg("--mcu").arg(mcu.name()).arg("--elf").arg(&config.elf);
        cmd.arg("--battery-mv").arg(config.battery_mv.to_string());
        if let Some(gps) = &config.gps_nmea {
            cmd.arg("--gps").arg(gps).arg("--gps-baud").arg(config.gps_baud.to_string());
        }
        match config.mag_ut {
            Some([x, y, z]) => {
                let [ax, ay, az] = config.accel_g;
                cmd.arg("--mag").arg(format!("{x},{y},{z}")).arg("--accel").arg(format!("{ax},{ay},{az}"));
            }
            None => {
                cmd.arg("--no-sensor");
            }
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| format!("{}: cannot start: {e}", harness.display()))?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().ok_or("the harness has no stdout")?;
        let (tx, rx) = sync_channel::<SimEvent>(EVENT_QUEUE);
        let (path_tx, path_rx) = sync_channel::<String>(1);
        std::thread::Builder::new()
            .name("wtcu-sim-reader".to_owned())
            .spawn(move || {
                let mut lines = BufReader::new(stdout).lines();
                if let Some(Ok(first)) = lines.next() {
                    let _ = path_tx.send(first);
                }
                for line in lines.map_while(Result::ok) {
                    let _ = tx.try_send(parse_line(&line));
                }
                let _ = tx.try_send(SimEvent::Ended);
            })
            .map_err(|e| format!("cannot start the harness reader: {e}"))?;
        let mut sim = Self { child, stdin, path: String::new(), mcu, events: rx };
        match path_rx.recv_timeout(Duration::from_secs(5)) {
            Ok(line) => match line.strip_prefix("pty ") {
                Some(path) if !path.trim().is_empty() => path.trim().clone_into(&mut sim.path),
                _ => return Err(format!("{}: unexpected first line {line:?}", harness.display())),
            },
            Err(_) => {
                return Err(format!(
                    "{}: no pseudo-terminal within 5 s (it exited or hung; see its messages above)",
                    harness.display()
                ));
            }
        }
        Ok(sim)
    }

    /// The pseudo-terminal to open, like a Bluetooth serial port.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The part being simulated.
    pub fn mcu(&self) -> Mcu {
        self.mcu
    }

    /// The next report, waiting up to `timeout`.
    pub fn next_event(&self, timeout: Duration) -> Option<SimEvent> {
        match self.events.recv_timeout(timeout) {
            Ok(e) => Some(e),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => Some(SimEvent::Ended),
        }
    }

    /// Every report waiting now.
    pub fn drain_events(&self) -> Vec<SimEvent> {
        self.events.try_iter().collect()
    }

    /// Changes the battery voltage on the ADC divider \[mV\].
    pub fn set_battery_mv(&mut self, mv: u16) -> std::io::Result<()> {
        self.command(&format!("battery {mv}"))
    }

    /// Changes the magnetic field at the sensor (body frame) \[µT\].
    pub fn set_field_ut(&mut self, [x, y, z]: [f64; 3]) -> std::io::Result<()> {
        self.command(&format!("mag {x} {y} {z}"))
    }

    fn command(&mut self, line: &str) -> std::io::Result<()> {
        let stdin = self.stdin.as_mut().ok_or_else(|| std::io::Error::other("the harness has ended"))?;
        writeln!(stdin, "{line}")?;
        stdin.flush()
    }

    /// Whether the harness still runs.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Ends the simulation and waits for the harness (at most 2 s, then kills it).
    pub fn shutdown(&mut self) {
        let _ = self.command("quit");
        self.stdin = None;
        for _ in 0..100 {
            if !self.is_running() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for FirmwareSim {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn harness_lines_parse_and_junk_is_not_trusted() {
        assert_eq!(
            parse_line("pins 1027146 9009"),
            SimEvent::Pins { sim_us: 1_027_146, mask: TactorMask(0x9009) }
        );
        assert_eq!(parse_line("rx 5"), SimEvent::Rx(5));
        assert_eq!(parse_line("tx 6"), SimEvent::Tx(6));
        assert_eq!(parse_line("reset 7"), SimEvent::Reset(7));
        for junk in ["pins 1 90090", "pins x 0001", "rx", "rx 1 2", "hello", "pins 1 zzzz", ""] {
            assert!(matches!(parse_line(junk), SimEvent::Unparsed(_)), "{junk}");
        }
    }

    #[test]
    fn the_field_of_a_wearer_facing_east_points_left() {
        let [x, y, z] = field_for_heading(90.0, 20.0, 45.0);
        assert!(x.abs() < 1e-12 && (y + 20.0).abs() < 1e-12 && (z - 45.0).abs() < 1e-12);
    }

    #[test]
    fn elf_headers_are_checked() {
        let dir = std::env::temp_dir().join(format!("vestnav-elf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut header = vec![0u8; 52];
        header[..6].copy_from_slice(b"\x7fELF\x01\x01");
        header[18] = 83;
        for (flags, want) in [(6u32, Ok(Mcu::Atmega2560)), (5, Ok(Mcu::Atmega328p))] {
            header[36..40].copy_from_slice(&(flags | 0x80).to_le_bytes());
            let p = dir.join("unit.elf");
            std::fs::write(&p, &header).unwrap();
            assert_eq!(Mcu::of_elf(&p), want);
        }
        header[18] = 62; // x86-64
        let p = dir.join("host.elf");
        std::fs::write(&p, &header).unwrap();
        assert!(Mcu::of_elf(&p).unwrap_err().contains("host.elf"));
        assert!(Mcu::of_elf(&dir.join("missing.elf")).unwrap_err().contains("missing.elf"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
