//! A GPS receiver "through the vest unit": the receiver on the WTCU's second UART, whose bytes travel
//! inside the vest's link (protocol v2, `GPS_DATA`; `docs/wtcu-protocol.md`).
//!
//! The vest worker owns the link and receives the chunks; a GPS source decodes them like any receiver's
//! bytes. Between the two threads sits a [`vest_gps_pipe`]: a bounded byte pipe that never blocks the
//! vest worker (a full pipe drops the newest bytes and counts them, as a UART buffer does), keeps byte
//! order, and carries the forwarding's [`ForwardingState`] so the GPS source can say why no data comes
//! (no vest link, a unit without a receiver). The GPS source tells the vest worker whether anybody
//! listens, and at which baud the receiver talks ([`VestGpsReader::set_wanted`]); the worker starts the
//! unit's forwarding only then.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

/// Most bytes waiting in the pipe (about a minute of a 9600-baud receiver).
pub const PIPE_CAPACITY: usize = 64 * 1024;

/// Where the forwarding stands, as the vest worker last saw it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ForwardingState {
    /// No vest link (not connected yet, or lost).
    NoLink,
    /// The unit is connected but cannot forward a receiver (a v1 unit, or no receiver UART).
    Unsupported(String),
    /// The unit was asked to forward at this baud (`GPS_START` sent).
    Requested {
        /// The receiver's baud rate.
        baud: u32,
    },
    /// The unit acknowledged `GPS_START`: bytes flow at this baud.
    Forwarding {
        /// The receiver's baud rate.
        baud: u32,
    },
}

#[derive(Debug)]
struct Inner {
    bytes: VecDeque<u8>,
    /// Bytes lost since the reader last asked: dropped by the unit (its `lost` field) or by a full pipe.
    lost: u64,
    state: ForwardingState,
    /// Bumped by every state change, so the reader sees even a change and its reversal.
    state_changes: u64,
}

#[derive(Debug)]
struct Shared {
    inner: Mutex<Inner>,
    ready: Condvar,
    /// The baud a source wants the receiver forwarded at; 0 = nobody listens.
    wanted: AtomicU32,
}

impl Shared {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A connected pair: the vest worker's writer and the GPS source's reader.
pub fn vest_gps_pipe() -> (VestGpsWriter, VestGpsReader) {
    let shared = Arc::new(Shared {
        inner: Mutex::new(Inner {
            bytes: VecDeque::new(),
            lost: 0,
            state: ForwardingState::NoLink,
            state_changes: 0,
        }),
        ready: Condvar::new(),
        wanted: AtomicU32::new(0),
    });
    (VestGpsWriter { shared: shared.clone() }, VestGpsReader { shared })
}

/// The vest worker's end: never blocks.
#[derive(Debug, Clone)]
pub struct VestGpsWriter {
    shared: Arc<Shared>,
}

impl VestGpsWriter {
    /// The baud a GPS source wants the receiver's bytes at, if one listens.
    pub fn wanted(&self) -> Option<u32> {
        Some(self.shared.wanted.load(Ordering::SeqCst)).filter(|&b| b != 0)
    }

    /// Appends a chunk the unit forwarded; `lost` bytes went missing before it. Bytes beyond
    /// [`PIPE_CAPACITY`] are dropped and counted as lost.
    pub fn write(&self, lost: u16, data: &[u8]) {
        let mut inner = self.shared.lock();
        inner.lost += u64::from(lost);
        let room = PIPE_CAPACITY.saturating_sub(inner.bytes.len());
        let (kept, dropped) = data.split_at(data.len().min(room));
        inner.bytes.extend(kept);
        inner.lost += dropped.len() as u64;
        drop(inner);
        self.shared.ready.notify_all();
    }

    /// Records where the forwarding stands.
    pub fn set_state(&self, state: ForwardingState) {
        let mut inner = self.shared.lock();
        if inner.state != state {
            inner.state = state;
            inner.state_changes += 1;
            drop(inner);
            self.shared.ready.notify_all();
        }
    }
}

/// The GPS source's end.
#[derive(Debug, Clone)]
pub struct VestGpsReader {
    shared: Arc<Shared>,
}

impl PartialEq for VestGpsReader {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.shared, &other.shared)
    }
}

/// What one [`VestGpsReader::read`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PipeRead {
    /// Bytes copied into the buffer.
    pub len: usize,
    /// Bytes lost since the previous read.
    pub lost: u64,
    /// The forwarding's state now, and a counter that changes with it.
    pub state: (ForwardingState, u64),
}

impl VestGpsReader {
    /// Tells the vest worker the receiver's baud while its bytes are wanted (`None`: nobody listens). The
    /// source sets it while it runs.
    pub fn set_wanted(&self, baud: Option<u32>) {
        self.shared.wanted.store(baud.unwrap_or(0), Ordering::SeqCst);
    }

    /// Copies waiting bytes into `buf`, waiting up to `timeout` for some (or for a state change).
    pub fn read(&self, buf: &mut [u8], timeout: Duration) -> PipeRead {
        let mut inner = self.shared.lock();
        if inner.bytes.is_empty() && inner.lost == 0 {
            let seen = inner.state_changes;
            inner = self
                .shared
                .ready
                .wait_timeout_while(inner, timeout, |i| i.bytes.is_empty() && i.state_changes == seen)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
        let len = buf.len().min(inner.bytes.len());
        for (slot, byte) in buf.iter_mut().zip(inner.bytes.drain(..len)) {
            *slot = byte;
        }
        let lost = std::mem::take(&mut inner.lost);
        PipeRead { len, lost, state: (inner.state.clone(), inner.state_changes) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_keep_their_order_and_overflow_is_counted() {
        let (w, r) = vest_gps_pipe();
        w.write(3, b"$GP");
        w.write(0, b"GGA");
        let mut buf = [0u8; 4];
        let got = r.read(&mut buf, Duration::ZERO);
        assert_eq!((&buf[..got.len], got.lost), (&b"$GPG"[..], 3));
        let got = r.read(&mut buf, Duration::ZERO);
        assert_eq!((&buf[..got.len], got.lost), (&b"GA"[..], 0));
        // A full pipe keeps what it holds and counts the rest.
        let big = vec![b'x'; PIPE_CAPACITY + 10];
        w.write(0, &big);
        let mut all = vec![0u8; PIPE_CAPACITY + 100];
        let got = r.read(&mut all, Duration::ZERO);
        assert_eq!((got.len, got.lost), (PIPE_CAPACITY, 10));
    }

    #[test]
    fn a_state_change_wakes_the_reader() {
        let (w, r) = vest_gps_pipe();
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            w.set_state(ForwardingState::Forwarding { baud: 9600 });
        });
        let start = std::time::Instant::now();
        let got = r.read(&mut [0u8; 8], Duration::from_secs(5));
        t.join().unwrap();
        assert!(start.elapsed() < Duration::from_secs(4));
        assert_eq!(got.state.0, ForwardingState::Forwarding { baud: 9600 });
    }
}
