//! Instruments for tests, here and in the crates above: things a test needs from the operating system
//! that the standard library does not offer.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::os::fd::OwnedFd;

/// A loopback TCP port that refuses every connection for as long as this value lives.
///
/// The socket is bound but never listens, so a connection to it is refused (RST) and no other socket can
/// take the port meanwhile. Binding a listener and dropping it is not the same: another test may bind the
/// freed ephemeral port before the connection that was meant to be refused.
#[cfg(unix)]
#[derive(Debug)]
pub struct RefusingPort {
    _socket: OwnedFd,
    addr: SocketAddr,
}

#[cfg(unix)]
impl RefusingPort {
    /// Binds a new TCP socket to an ephemeral port of 127.0.0.1.
    pub fn bind() -> std::io::Result<Self> {
        use rustix::net::{AddressFamily, SocketType, bind, getsockname, ipproto, socket};
        let socket = socket(AddressFamily::INET, SocketType::STREAM, Some(ipproto::TCP))?;
        bind(&socket, &SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0))?;
        let addr = SocketAddr::try_from(getsockname(&socket)?)
            .map_err(|_| std::io::Error::other("getsockname: not an IP address"))?;
        Ok(RefusingPort { _socket: socket, addr })
    }

    /// The refused address (127.0.0.1 and the bound port).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The bound port.
    pub fn port(&self) -> u16 {
        self.addr.port()
    }
}

/// Sends signal number `signal` (1 HUP, 2 INT, 9 KILL, 15 TERM, ...) to process `pid`, from this process:
/// a test that times what a signal causes starts its clock right before, without a `kill` process's
/// start-up in the measurement.
#[cfg(unix)]
pub fn send_signal(pid: u32, signal: i32) -> std::io::Result<()> {
    use rustix::process::{Pid, Signal, kill_process};
    let pid = i32::try_from(pid)
        .ok()
        .and_then(Pid::from_raw)
        .ok_or_else(|| std::io::Error::other(format!("not a process id: {pid}")))?;
    let signal = Signal::from_named_raw(signal)
        .ok_or_else(|| std::io::Error::other(format!("not a signal number: {signal}")))?;
    kill_process(pid, signal)?;
    Ok(())
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_connection_is_refused_and_the_port_stays_taken() {
        let port = RefusingPort::bind().unwrap();
        let err = std::net::TcpStream::connect(port.addr()).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::ConnectionRefused);
        // Nobody else can bind it while we hold it.
        assert!(std::net::TcpListener::bind(port.addr()).is_err());
    }

    #[test]
    fn a_signal_reaches_the_process() {
        let mut child = std::process::Command::new("sleep").arg("30").spawn().unwrap();
        send_signal(child.id(), 15).unwrap();
        let status = child.wait().unwrap();
        assert_eq!(std::os::unix::process::ExitStatusExt::signal(&status), Some(15));
        assert!(send_signal(0, 15).is_err(), "0 is not a process");
        assert!(send_signal(child.id(), 999).is_err(), "999 is not a signal");
    }
}
