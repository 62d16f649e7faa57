//! How a worker thread hands events to its consumers: bounded channels that never block the worker for
//! long, with a count of what was dropped and a waker (the UI's `request_repaint`).
//!
//! A worker may feed several consumers at once (the UI, guidance, the session log): one [`Outbox`] each.
//! What happens when a consumer lags is chosen per consumer ([`Overflow`]): the UI and guidance only need
//! the newest state, so the newest message is dropped and counted; a lossless consumer (a file being
//! written, a CLI decoding as fast as possible) makes the producer wait, but only until the producer is
//! told to stop, so a stop request is never blocked by a stalled consumer.
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use vestnav_device::outbox::{Outbox, Overflow};
//!
//! let (out, rx) = Outbox::channel(2, Overflow::DropNewest, None);
//! let cancel = AtomicBool::new(false);
//! for i in 0..5 {
//!     assert!(out.send(i, &cancel));
//! }
//! assert_eq!(out.dropped(), 3);
//! assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![0, 1]);
//! ```

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::{Duration, Instant};

/// Called after a message was handed over (for example egui's `Context::request_repaint`).
pub use vestnav_core::Waker;

/// What a producer does when the consumer's channel is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// Drop the new message and count it: for consumers that only need the latest state.
    DropNewest,
    /// Wait for room, polling the producer's cancel flag every millisecond.
    Wait,
}

/// What one hand-over attempt did.
enum Put<T> {
    /// Handed over (or deliberately skipped by a filter).
    Done,
    /// The channel is full; the message comes back for a retry.
    Full(T),
    /// The consumer is gone.
    Gone,
}

type PutFn<T> = dyn Fn(T) -> Put<T> + Send + Sync;

/// The producer's end of one consumer's bounded channel.
pub struct Outbox<T> {
    put: Arc<PutFn<T>>,
    overflow: Overflow,
    dropped: Arc<AtomicU64>,
    waker: Option<Waker>,
}

impl<T> std::fmt::Debug for Outbox<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Outbox")
            .field("overflow", &self.overflow)
            .field("dropped", &self.dropped())
            .finish_non_exhaustive()
    }
}

impl<T> Clone for Outbox<T> {
    fn clone(&self) -> Self {
        Self {
            put: self.put.clone(),
            overflow: self.overflow,
            dropped: self.dropped.clone(),
            waker: self.waker.clone(),
        }
    }
}

impl<T: Send + 'static> Outbox<T> {
    /// Wraps `tx`; `waker` is called after each message handed over.
    pub fn new(tx: SyncSender<T>, overflow: Overflow, waker: Option<Waker>) -> Self {
        let put = move |msg: T| match tx.try_send(msg) {
            Ok(()) => Put::Done,
            Err(TrySendError::Full(m)) => Put::Full(m),
            Err(TrySendError::Disconnected(_)) => Put::Gone,
        };
        Self { put: Arc::new(put), overflow, dropped: Arc::default(), waker }
    }

    /// A new channel of `capacity` messages (at least one) and its outbox.
    pub fn channel(capacity: usize, overflow: Overflow, waker: Option<Waker>) -> (Self, Receiver<T>) {
        let (tx, rx) = sync_channel(capacity.max(1));
        (Self::new(tx, overflow, waker), rx)
    }

    /// An outbox into a channel of another type: `map` turns each message into the consumer's (or
    /// `None`: not for this consumer). Never waits: when full, the message is dropped and counted.
    pub fn mapped<U: Send + 'static>(
        tx: SyncSender<U>,
        map: impl Fn(T) -> Option<U> + Send + Sync + 'static,
        waker: Option<Waker>,
    ) -> Self {
        let dropped: Arc<AtomicU64> = Arc::default();
        let counter = dropped.clone();
        let put = move |msg: T| match map(msg) {
            None => Put::Done,
            Some(u) => match tx.try_send(u) {
                Ok(()) => Put::Done,
                Err(TrySendError::Full(_)) => {
                    counter.fetch_add(1, Ordering::Relaxed);
                    Put::Done
                }
                Err(TrySendError::Disconnected(_)) => Put::Gone,
            },
        };
        Self { put: Arc::new(put), overflow: Overflow::DropNewest, dropped, waker }
    }

    /// An outbox into any non-blocking consumer: `sink` takes the message and returns `false` once the
    /// consumer is gone. The sink must not block (it runs on the producer's thread).
    pub fn sink(sink: impl Fn(T) -> bool + Send + Sync + 'static) -> Self {
        let put = move |msg: T| if sink(msg) { Put::Done } else { Put::Gone };
        Self { put: Arc::new(put), overflow: Overflow::DropNewest, dropped: Arc::default(), waker: None }
    }
}

impl<T> Outbox<T> {
    /// Hands `msg` over. With [`Overflow::DropNewest`] it never waits; with [`Overflow::Wait`] it waits
    /// for room until `cancel` is set (then the message is dropped and counted). Returns `false` when the
    /// consumer is gone.
    pub fn send(&self, msg: T, cancel: &AtomicBool) -> bool {
        let mut msg = msg;
        let alive = loop {
            match (self.put)(msg) {
                Put::Done => break true,
                Put::Gone => break false,
                Put::Full(m) => {
                    if self.overflow == Overflow::DropNewest || cancel.load(Ordering::Relaxed) {
                        self.dropped.fetch_add(1, Ordering::Relaxed);
                        break true;
                    }
                    msg = m;
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
        };
        self.wake();
        alive
    }

    /// Hands `msg` over without ever waiting, whatever the overflow mode; returns `false` when the
    /// consumer is gone.
    pub fn try_send(&self, msg: T) -> bool {
        let alive = match (self.put)(msg) {
            Put::Done => true,
            Put::Full(_) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                true
            }
            Put::Gone => false,
        };
        self.wake();
        alive
    }

    /// Calls the waker, if any.
    pub fn wake(&self) {
        if let Some(w) = &self.waker {
            w();
        }
    }

    /// Messages dropped because the consumer lagged (or the producer was cancelled while waiting).
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// What this outbox does when full.
    pub fn overflow(&self) -> Overflow {
        self.overflow
    }
}

/// Drains `rx` into `handle` until it is empty or `budget` has elapsed; returns how many were handled.
///
/// The budget keeps one UI frame short when a worker floods the channel: the rest waits for the next frame
/// (rerun's `receive_messages`).
pub fn drain_within<T>(rx: &Receiver<T>, budget: Duration, mut handle: impl FnMut(T)) -> usize {
    let start = Instant::now();
    let mut n = 0;
    while let Ok(msg) = rx.try_recv() {
        handle(msg);
        n += 1;
        if n % 64 == 0 && start.elapsed() > budget {
            break;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wait_mode_gives_up_when_cancelled() {
        let (out, rx) = Outbox::channel(1, Overflow::Wait, None);
        let cancel = Arc::new(AtomicBool::new(false));
        assert!(out.send(1, &cancel));
        let c = cancel.clone();
        let t = std::thread::spawn(move || out.send(2, &c));
        std::thread::sleep(Duration::from_millis(30));
        assert!(!t.is_finished(), "waits while the consumer is full");
        cancel.store(true, Ordering::Relaxed);
        assert!(t.join().unwrap());
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![1]);
    }

    #[test]
    fn mapped_outbox_filters_converts_and_counts() {
        let (tx, rx) = sync_channel::<String>(1);
        let out = Outbox::mapped(tx, |n: u32| n.is_multiple_of(2).then(|| n.to_string()), None);
        let cancel = AtomicBool::new(false);
        for n in 1..=6 {
            assert!(out.send(n, &cancel));
        }
        // 2 went in, 4 and 6 found the channel full; odd numbers were never for this consumer.
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec!["2".to_owned()]);
        assert_eq!(out.dropped(), 2);
    }

    #[test]
    fn a_gone_consumer_is_reported() {
        let (out, rx) = Outbox::channel(1, Overflow::DropNewest, None);
        drop(rx);
        assert!(!out.send(1, &AtomicBool::new(false)));
        assert!(!out.try_send(2));
    }
}
