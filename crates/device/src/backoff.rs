//! The one reconnect backoff of vestnav's device workers (the vest worker, the serial and gpsd sources).

use std::time::Duration;

/// Exponential reconnect backoff, pure (no clock, no randomness): `delay_n = min(initial * 2^n, max)` for the
/// n-th consecutive failure (n from 0). One console per vest, so no jitter is needed against herds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    initial: Duration,
    max: Duration,
    failures: u32,
}

impl Default for Backoff {
    /// 250 ms doubling up to 5 s: a vest walking back into Bluetooth range reconnects within seconds.
    fn default() -> Self {
        Self::new(Duration::from_millis(250), Duration::from_secs(5))
    }
}

impl Backoff {
    /// A backoff from `initial` doubling up to `max`.
    pub const fn new(initial: Duration, max: Duration) -> Self {
        Self { initial, max, failures: 0 }
    }

    /// The delay before the next attempt; counts one more failure.
    pub fn next_delay(&mut self) -> Duration {
        let factor = 1u32 << self.failures.min(20);
        self.failures = self.failures.saturating_add(1);
        self.initial.saturating_mul(factor).min(self.max)
    }

    /// A connection succeeded: start from `initial` again.
    pub fn reset(&mut self) {
        self.failures = 0;
    }

    /// The delay before retry number `n` (1 = the first retry) of a backoff that starts afresh: what
    /// `next_delay` returns the `n`-th time after a reset.
    pub fn delay_for_retry(&self, n: u32) -> Duration {
        let factor = 1u32 << n.saturating_sub(1).min(20);
        self.initial.saturating_mul(factor).min(self.max)
    }

    /// Consecutive failures so far.
    pub fn failures(&self) -> u32 {
        self.failures
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nth_retry_waits_what_next_delay_gives_the_nth_time() {
        let mut b = Backoff::new(Duration::from_millis(500), Duration::from_secs(8));
        for n in 1..=8 {
            assert_eq!(b.delay_for_retry(n), b.next_delay(), "retry {n}");
        }
        assert_eq!(b.delay_for_retry(1), Duration::from_millis(500));
        assert_eq!(b.delay_for_retry(9), Duration::from_secs(8));
    }
}
