//! The stop path: how STOP ALL and every way out of the program reach every vest, from any thread.
//!
//! The station keeps the [`VestStopper`] of each running vest worker in one [`StopPath`]. STOP ALL from
//! anywhere (the operator's key in a view, a network command, a signal) goes through it to each worker's
//! atomic request, which the worker serves before anything else on its next turn (≤ 2 ms): no queue, no
//! frame, no other thread is in the way. The locks inside are only held to clone or swap the list.
//!
//! Exit in bounded time ([`EXIT_DEADLINE`]): on SIGTERM, SIGINT or SIGHUP the signal thread started by
//! [`exit_on_signals`] sends a fresh STOP ALL frame to every vest, waits at most [`EXIT_STOP_WAIT`] for
//! the acknowledgements, asks the view (if any) to close, and ends the process by the deadline whatever the
//! view, the unit or the other threads are doing.

use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_device::wtcu::worker::VestStopper;

/// How long exit waits for the units to acknowledge STOP ALL.
pub const EXIT_STOP_WAIT: Duration = Duration::from_millis(150);
/// The process ends at most this long after a signal, whatever the unit or the window does.
pub const EXIT_DEADLINE: Duration = Duration::from_millis(250);

/// A callback that asks a view to close (e.g. a window's close request).
pub type Closer = Box<dyn Fn() + Send + Sync>;

/// Where STOP ALL and the exit paths find every vest (see the module doc). Clone it freely: every clone is
/// the same path.
#[derive(Clone, Default)]
pub struct StopPath(Arc<Inner>);

#[derive(Default)]
struct Inner {
    vests: Mutex<Vec<(u64, VestStopper)>>,
    closer: Mutex<Option<Closer>>,
    signal: AtomicI32,
}

impl std::fmt::Debug for StopPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.0.vests.lock().map_or(0, |v| v.len());
        f.debug_struct("StopPath").field("vests", &n).finish_non_exhaustive()
    }
}

impl StopPath {
    /// Adds a vest under `id` (replacing one registered under the same id).
    pub fn register(&self, id: u64, stopper: VestStopper) {
        if let Ok(mut v) = self.0.vests.lock() {
            v.retain(|(i, _)| *i != id);
            v.push((id, stopper));
        }
    }

    /// Forgets the vest registered under `id`.
    pub fn unregister(&self, id: u64) {
        if let Ok(mut v) = self.0.vests.lock() {
            v.retain(|(i, _)| *i != id);
        }
    }

    fn stoppers(&self) -> Vec<VestStopper> {
        self.0.vests.lock().map(|v| v.iter().map(|(_, s)| s.clone()).collect()).unwrap_or_default()
    }

    /// How many vests are on the path.
    pub fn len(&self) -> usize {
        self.0.vests.lock().map_or(0, |v| v.len())
    }

    /// Whether no vest is on the path.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// STOP ALL to the vest registered under `id` only (one station's own stop, when several stations
    /// share the path). Never blocks beyond cloning the list.
    pub fn stop(&self, id: u64) {
        let one =
            self.0.vests.lock().ok().and_then(|v| v.iter().find(|(i, _)| *i == id).map(|(_, s)| s.clone()));
        if let Some(s) = one {
            s.stop_all();
        }
    }

    /// STOP ALL to every vest now: each worker sends it within one read timeout and latches automatic
    /// cues off. Never blocks beyond cloning the list.
    pub fn stop_all(&self) {
        for s in self.stoppers() {
            s.stop_all();
        }
    }

    /// A fresh STOP ALL frame to every vest, then every worker ends; waits at most `wait` in all. Returns
    /// whether every vest acknowledged (`false` too when there is none).
    pub fn stop_and_close_all(&self, wait: Duration) -> bool {
        let stoppers = self.stoppers();
        // Ask them all first, so the waits overlap.
        for s in &stoppers {
            s.stop_all();
        }
        let end = Instant::now() + wait;
        let mut all = !stoppers.is_empty();
        for s in &stoppers {
            all &= s.stop_and_close(end.saturating_duration_since(Instant::now()));
        }
        all
    }

    /// Sets what asks the view to close (a window's close request); `None` for a headless station.
    pub fn set_closer(&self, closer: Option<Closer>) {
        if let Ok(mut c) = self.0.closer.lock() {
            *c = closer;
        }
    }

    /// Records that the process ends because of signal `sig` and asks the view to close; returns whether
    /// there was a view to ask.
    pub fn close_for_signal(&self, sig: i32) -> bool {
        self.0.signal.store(sig, Ordering::SeqCst);
        self.0.closer.lock().ok().is_some_and(|c| {
            c.as_ref().is_some_and(|close| {
                close();
                true
            })
        })
    }

    /// The signal the process is ending for, if any.
    pub fn signal(&self) -> Option<i32> {
        Some(self.0.signal.load(Ordering::SeqCst)).filter(|s| *s != 0)
    }
}

/// Ends the process on SIGTERM, SIGINT or SIGHUP after stopping every vest (see the module doc); the exit
/// status is 128 + the signal's number, as a killed program's. `before_exit` runs after the vests are
/// stopped (flush a log, say goodbye on a network), within what is left of [`EXIT_DEADLINE`]; it must not
/// block.
#[cfg(unix)]
pub fn exit_on_signals(stop: StopPath, before_exit: impl Fn() + Send + 'static) -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGINT, SIGHUP])?;
    std::thread::Builder::new().name("vestnav-signals".into()).spawn(move || {
        if let Some(sig) = signals.forever().next() {
            let start = Instant::now();
            // The vests first, whatever any other thread is doing.
            let acked = stop.stop_and_close_all(EXIT_STOP_WAIT);
            let how = if acked {
                "acknowledged by the unit"
            } else {
                "not acknowledged (no vest, or the unit's watchdog stops the tactors)"
            };
            eprintln!("vestnav: signal {sig}: STOP ALL {how}; exiting");
            before_exit();
            // Then a normal close of the view, so a window's renderer is torn down on its own thread; if it
            // does not get there by the deadline (stalled, or no window), end the process from here.
            if stop.close_for_signal(sig) {
                let margin = Duration::from_millis(10);
                std::thread::sleep(EXIT_DEADLINE.saturating_sub(start.elapsed() + margin));
            }
            std::process::exit(128 + sig);
        }
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_device::wtcu::VestConfig;
    use vestnav_device::wtcu::VestHandle;
    use vestnav_device::wtcu::engine::EngineConfig;

    #[test]
    fn stop_reaches_every_registered_vest_and_close_is_bounded() {
        let path = StopPath::default();
        assert!(!path.stop_and_close_all(Duration::from_millis(10)), "no vest: nothing acknowledged");
        let a = VestHandle::spawn(VestConfig::Emulated(EngineConfig::default().into()), Vec::new()).unwrap();
        let b = VestHandle::spawn(VestConfig::Emulated(EngineConfig::default().into()), Vec::new()).unwrap();
        path.register(1, a.stopper());
        path.register(2, b.stopper());
        path.register(2, b.stopper());
        assert_eq!(path.len(), 2);
        path.stop_all();
        assert!(a.is_halted() && b.is_halted());
        let t = Instant::now();
        path.stop_and_close_all(EXIT_STOP_WAIT);
        assert!(t.elapsed() < EXIT_STOP_WAIT + Duration::from_millis(100));
        // Both end (within the wait on a quiet machine; a loaded one may schedule them a little later).
        let until = Instant::now() + Duration::from_secs(2);
        while (a.is_running() || b.is_running()) && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(!a.is_running() && !b.is_running());
        path.unregister(1);
        assert_eq!(path.len(), 1);
    }
}
