//! [`EmulatedPort`]: the emulated unit as an in-process transport for the vest worker.

use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use crate::wtcu::emulator::UnitConfig;
use crate::wtcu::engine::{Engine, EngineEvent};

/// The emulated unit as an in-process transport: writes feed the [`Engine`] at the wall-clock time, reads
/// return its replies, waiting at most the read timeout (the engine's timers run inside reads).
#[derive(Debug)]
pub struct EmulatedPort {
    engine: Engine,
    /// The simulated wearer told of every tactor change ([`UnitConfig::skin`]).
    skin: Option<crate::sim::SharedTruth>,
    pending: std::collections::VecDeque<u8>,
    read_timeout: Duration,
}

impl EmulatedPort {
    /// A fresh unit built from `config`; reads wait at most `read_timeout`.
    pub fn new(config: &UnitConfig, read_timeout: Duration) -> Self {
        Self {
            engine: config.build(),
            skin: config.skin.clone(),
            pending: std::collections::VecDeque::new(),
            read_timeout,
        }
    }

    /// The unit behind the port.
    pub fn engine(&self) -> &Engine {
        &self.engine
    }
}

impl Read for EmulatedPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let deadline = Instant::now() + self.read_timeout;
        loop {
            let now = Instant::now();
            self.engine.handle_timeout(now);
            while let Some(frame) = self.engine.poll_transmit() {
                self.pending.extend(frame);
            }
            while let Some(ev) = self.engine.poll_event() {
                if let (EngineEvent::TactorsChanged(mask), Some(skin)) = (ev, &self.skin) {
                    skin.touch(mask, now);
                }
            }
            if !self.pending.is_empty() {
                let n = buf.len().min(self.pending.len());
                for (dst, src) in buf.iter_mut().zip(self.pending.drain(..n)) {
                    *dst = src;
                }
                return Ok(n);
            }
            if now >= deadline {
                return Err(io::Error::new(io::ErrorKind::TimedOut, "no data from the emulated unit"));
            }
            let wake = self.engine.poll_timeout().map_or(deadline, |t| t.min(deadline));
            std::thread::sleep(wake.saturating_duration_since(now).max(Duration::from_micros(100)));
        }
    }
}

impl Write for EmulatedPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.engine.handle_bytes(buf, Instant::now());
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
