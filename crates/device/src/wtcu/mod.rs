//! The vest's Wireless Tactile Control Unit (WTCU): vestnav's wire protocol, the console-side link, the
//! unit-side engine (what the emulator runs) and the worker thread that owns a serial port.
//!
//! Layers, each usable alone:
//! - [`message`]: requests and replies, independent of framing;
//! - [`codec`]: [`codec::WireCodec`] and vestnav's framing [`codec::FrameCodec`] (COBS + CRC-16, see
//!   `docs/wtcu-protocol.md`);
//! - [`limits`]: on-time, current budget and duty-cycle limits, shared by console and unit;
//! - [`link`]: the console side as a sans-IO state machine (handshake, acks, retransmit, heartbeat, loss),
//!   plus a pure reconnect [`link::Backoff`];
//! - [`engine`]: the unit side as a sans-IO state machine (limits, patterns, watchdog, the heading stream
//!   from any [`engine::HeadingSensor`]);
//! - [`worker`]: [`worker::VestHandle`], a named thread owning a port (or the in-process emulator);
//! - [`emulator`]: an emulated unit ([`emulator::UnitConfig`]: the engine with
//!   [`crate::sim::SimulatedCompass`]) served on a pseudo-terminal or any `Read + Write`;
//! - [`firmware_sim`]: the reference C firmware run in simavr, for the emulator's command and the
//!   conformance suite.
//!
//! The protocol layers (`message`, `codec`, `limits`, `link`, `engine`) import nothing of the emulator,
//! the worker, serial ports, the simulation or threads; the emulator and the worker stand on them.
//!
//! ```
//! use std::time::Instant;
//! use vestnav_core::vest::TactorMask;
//! use vestnav_device::wtcu::{engine::{Engine, EngineConfig}, link::{Link, LinkConfig}};
//!
//! let now = Instant::now();
//! let (mut console, mut unit) = (Link::new(LinkConfig::default()), Engine::new(EngineConfig::default()));
//! console.connect(now);
//! for _ in 0..4 {
//!     while let Some(bytes) = console.poll_transmit() { unit.handle_bytes(&bytes, now); }
//!     while let Some(bytes) = unit.poll_transmit() { console.handle_bytes(&bytes, now); }
//!     if console.is_ready() && unit.tactors_on().is_empty() { console.fire(TactorMask::CORNERS, 500, now).unwrap(); }
//! }
//! assert_eq!(unit.tactors_on(), TactorMask::CORNERS);
//! assert_eq!(console.tactors_on(), Some(TactorMask::CORNERS));
//! ```

pub mod codec;
pub mod emulator;
pub mod engine;
pub mod firmware_sim;
pub mod limits;
pub mod link;
pub mod message;
pub mod worker;

#[cfg(test)]
mod proptests;

pub use codec::{FrameCodec, WireCodec};
pub use limits::Limits;
pub use link::{Backoff, Link, LinkConfig, LinkEvent, LinkState};
pub use message::{CommandKind, DeviceInfo, NakReason, Reply, Request, UnitStatus};
pub use worker::{CommandOrigin, VestCommand, VestConfig, VestEvent, VestHandle};
