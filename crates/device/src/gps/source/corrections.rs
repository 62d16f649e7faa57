//! A write handle on a serial source's receiver, for RTK corrections (`crate::ntrip`): the serial worker
//! owns the port and reopens it after a loss; each time it opens the port it puts a second handle on the
//! same port (`try_clone`) here, and takes it away when the port closes. The corrections' thread writes
//! through [`CorrectionsWriter`] on its own: the GPS reader never waits for it, and it never waits for the
//! reader (the lock is held only for one write, bounded by the port's write timeout, or to swap the
//! handle).

use std::io::Write;
use std::sync::{Arc, Mutex, PoisonError};

/// Why a correction could not be written while the receiver's port is closed.
pub const PORT_NOT_OPEN: &str = "the receiver's port is not open (connecting or lost)";

/// The slot the serial worker fills with a write handle on its open port.
#[derive(Default)]
pub(crate) struct PortSlot(Mutex<Option<Box<dyn Write + Send>>>);

impl std::fmt::Debug for PortSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PortSlot")
    }
}

impl PortSlot {
    /// Puts the open port's write handle in (or `None` when the port closes).
    pub(crate) fn set(&self, writer: Option<Box<dyn Write + Send>>) {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner) = writer;
    }
}

/// Writes to the receiver's port while the serial source has it open; [`PORT_NOT_OPEN`] otherwise.
#[derive(Debug, Clone)]
pub struct CorrectionsWriter(pub(crate) Arc<PortSlot>);

impl Write for CorrectionsWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.0.0.lock().unwrap_or_else(PoisonError::into_inner).as_mut() {
            Some(w) => w.write(buf),
            None => Err(std::io::Error::new(std::io::ErrorKind::NotConnected, PORT_NOT_OPEN)),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self.0.0.lock().unwrap_or_else(PoisonError::into_inner).as_mut() {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }
}

/// Clears the slot when the port it was filled from closes (any way out of the read loop).
pub(crate) struct Filled<'a>(pub(crate) &'a PortSlot);

impl Drop for Filled<'_> {
    fn drop(&mut self) {
        self.0.set(None);
    }
}
