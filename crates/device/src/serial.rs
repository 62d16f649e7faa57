//! Serial-port discovery and opening.
//!
//! A Bluetooth SPP device (the BT-359 GPS, the WTCU) shows up as an ordinary serial port: `/dev/rfcomm*`
//! on Linux, an outgoing `COMn` on Windows, `/dev/cu.*` on macOS. Pseudo-terminals from the emulators
//! (`/dev/pts/N`) are serial ports too, and the console opens them exactly like hardware.

use std::time::Duration;

use serialport::{SerialPort, SerialPortType};

/// What kind of device a port most likely is, for the operator's port picker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PortKind {
    /// A Bluetooth serial link (SPP / RFCOMM).
    Bluetooth,
    /// A USB serial adapter or USB GPS mouse.
    Usb,
    /// A PCI or on-board UART.
    Pci,
    /// A pseudo-terminal, usually one of vestnav's own emulators.
    Pty,
    /// Anything else the OS reports.
    Other,
}

/// One serial port the operator can pick.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct PortInfo {
    /// The path or name to open (`/dev/rfcomm0`, `COM5`, `/dev/pts/3`).
    pub name: String,
    /// Our best guess of the kind of device behind it.
    pub kind: PortKind,
    /// A human description (USB product string, "Bluetooth", ...), empty when unknown.
    pub description: String,
}

/// Errors opening or listing serial ports.
#[derive(Debug, thiserror::Error)]
pub enum SerialError {
    /// The OS refused to list or open the port (missing, busy, no permission).
    #[error("serial port {port}: {source}")]
    Port {
        /// The port we tried.
        port: String,
        /// What the OS said.
        #[source]
        source: serialport::Error,
    },
}

/// Lists the serial ports, Bluetooth ones first, then USB, then the rest, each group by name.
///
/// `/dev/rfcomm*` nodes are listed even where the enumerator misses them (it often does: they are
/// created on demand by `rfcomm bind`).
pub fn list_ports() -> Vec<PortInfo> {
    let mut ports: Vec<PortInfo> = serialport::available_ports()
        .unwrap_or_default()
        .into_iter()
        .map(|p| {
            let (kind, description) = match &p.port_type {
                SerialPortType::BluetoothPort => (PortKind::Bluetooth, "Bluetooth".to_owned()),
                SerialPortType::UsbPort(usb) => (
                    PortKind::Usb,
                    usb.product.clone().unwrap_or_else(|| format!("USB {:04x}:{:04x}", usb.vid, usb.pid)),
                ),
                SerialPortType::PciPort => (PortKind::Pci, String::new()),
                SerialPortType::Unknown => (kind_from_name(&p.port_name), String::new()),
            };
            PortInfo { name: p.port_name, kind, description }
        })
        .collect();
    if let Ok(dir) = std::fs::read_dir("/dev") {
        for entry in dir.flatten() {
            let name = format!("/dev/{}", entry.file_name().to_string_lossy());
            if name.starts_with("/dev/rfcomm") && !ports.iter().any(|p| p.name == name) {
                ports.push(PortInfo { name, kind: PortKind::Bluetooth, description: "Bluetooth".to_owned() });
            }
        }
    }
    ports.sort_by(|a, b| rank(a.kind).cmp(&rank(b.kind)).then_with(|| a.name.cmp(&b.name)));
    ports
}

fn rank(kind: PortKind) -> u8 {
    match kind {
        PortKind::Bluetooth => 0,
        PortKind::Usb => 1,
        PortKind::Pty => 2,
        PortKind::Pci => 3,
        PortKind::Other => 4,
    }
}

/// Guesses a port's kind from its name alone.
pub fn kind_from_name(name: &str) -> PortKind {
    if name.starts_with("/dev/rfcomm") || name.contains("Bluetooth") {
        PortKind::Bluetooth
    } else if name.starts_with("/dev/ttyUSB") || name.starts_with("/dev/ttyACM") || name.contains("usbserial")
    {
        PortKind::Usb
    } else if name.starts_with("/dev/pts/") {
        PortKind::Pty
    } else {
        PortKind::Other
    }
}

/// Whether an IO error on a port with a read or write timeout only means "nothing yet" (timed out, would
/// block, interrupted): the transport's one rule, used by every worker and server loop.
pub fn is_timeout(e: &std::io::Error) -> bool {
    use std::io::ErrorKind;
    matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted)
}

/// Opens `port` at `baud`, 8N1, with a short read timeout so a worker can check for shutdown between reads.
pub fn open(port: &str, baud: u32, read_timeout: Duration) -> Result<Box<dyn SerialPort>, SerialError> {
    serialport::new(port, baud)
        .timeout(read_timeout)
        .open()
        .map_err(|source| SerialError::Port { port: port.to_owned(), source })
}

/// A pseudo-terminal pair, the one PTY wrapper of vestnav (the emulators, the tests): we read and write the
/// master; other processes open [`Pty::path`] exactly like a hardware serial port.
#[cfg(unix)]
#[derive(Debug)]
pub struct Pty {
    /// Our side; its reads time out (see [`Pty::open_with_timeout`]).
    pub master: serialport::TTYPort,
    /// The slave's path (`/dev/pts/N`): what another process opens.
    pub path: String,
    /// Our own handle on the slave, kept open so the slave stays valid (and writes do not fail) until
    /// someone opens the path, and so consoles may come and go without the master seeing a hang-up. Drop
    /// it with the master to make the port vanish.
    pub slave: serialport::TTYPort,
}

#[cfg(unix)]
impl Pty {
    /// Opens a new PTY pair (`serialport::TTYPort::pair`) whose master reads time out after 100 ms.
    pub fn open() -> std::io::Result<Self> {
        Self::open_with_timeout(Duration::from_millis(100))
    }

    /// Opens a new PTY pair whose master reads time out after `read_timeout`.
    pub fn open_with_timeout(read_timeout: Duration) -> std::io::Result<Self> {
        let (mut master, slave) = serialport::TTYPort::pair().map_err(std::io::Error::other)?;
        master.set_timeout(read_timeout).map_err(std::io::Error::other)?;
        let path = slave.name().ok_or_else(|| std::io::Error::other("PTY without a name"))?;
        Ok(Self { master, path, slave })
    }

    /// The slave's path (`/dev/pts/N`): what another process opens.
    pub fn path(&self) -> &str {
        &self.path
    }
}

#[cfg(unix)]
impl std::io::Write for Pty {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.master.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.master.flush()
    }
}

#[cfg(unix)]
impl std::io::Read for Pty {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.master.read(buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_classify() {
        assert_eq!(kind_from_name("/dev/rfcomm0"), PortKind::Bluetooth);
        assert_eq!(kind_from_name("/dev/ttyUSB3"), PortKind::Usb);
        assert_eq!(kind_from_name("/dev/pts/7"), PortKind::Pty);
        assert_eq!(kind_from_name("COM4"), PortKind::Other);
    }

    #[test]
    fn missing_port_is_a_clear_error() {
        let err = open("/dev/does-not-exist-vestnav", 4800, Duration::from_millis(10)).unwrap_err();
        assert!(err.to_string().contains("/dev/does-not-exist-vestnav"));
    }
}
