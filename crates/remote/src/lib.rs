//! vestnav stations and consoles through an MQTT broker, with no window: a station next to the wearer
//! (a Raspberry Pi in a backpack with the vest and the GPS) publishes its state and takes commands through
//! [`StationBridge`]; an operator's console, or an observer, finds every station and drives them through
//! [`Fleet`]. Topics and payloads are versioned ([`wire`], `docs/remote.md`); the broker is any standard one
//! (Mosquitto in the tests), reached with TLS and credentials from files ([`broker`]).
//!
//! Safety across the network: STOP ALL is a retained `QoS` 1 order that every station obeys from its
//! connection thread straight to its stop path, also after a reconnection, until an operator resumes it;
//! each station stops its vest when its operator's heartbeat is missing past a bound (unless the operator
//! armed "continue the route if the link drops"); a command more than a second late is refused, a repeat
//! is played once.
//!
//! ```no_run
//! use vestnav_remote::{BrokerConfig, Fleet, FleetOptions};
//! let broker = BrokerConfig { url: "mqtts://broker.lan:8883".into(), ..BrokerConfig::default() };
//! let fleet = Fleet::connect(&broker, FleetOptions::operator("alice"))?;
//! for s in fleet.stations() {
//!     println!("{}: {}", s.name, s.contact_label(std::time::Instant::now(), fleet.options().stale_after));
//! }
//! fleet.stop_all()?;
//! # Ok::<(), vestnav_remote::FleetError>(())
//! ```

pub mod bridge;
pub mod broker;
pub mod fleet;
pub mod local;
pub mod stations;
pub mod wire;

pub use bridge::{BridgeError, BridgeOptions, StationBridge};
pub use broker::{BrokerConfig, ConfigError};
pub use fleet::{Fleet, FleetError, FleetOptions, StationView};
pub use local::{LocalStationConfig, LocalStations};
pub use stations::Stations;
