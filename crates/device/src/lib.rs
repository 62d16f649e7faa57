//! Everything in vestnav that talks to hardware.
//!
//! Protocols are sans-IO state machines (fed bytes and the current time, drained of events and bytes to
//! send); transports are thin `Read + Write` adapters owned by one worker thread each.
//! - [`gps`]: NMEA 0183, u-blox UBX and `SiRF` binary decoding into fixes, receiver configuration, GPS
//!   sources (serial, log replay, gpsd, simulator, the receiver behind the vest) and the one GPS source
//!   spec ([`gps::GpsSourceSpec`]);
//! - [`heading`]: one heading/attitude reading from any source (vest magnetometer, NMEA compass, gpsd);
//! - [`wtcu`]: the Wireless Tactile Control Unit protocol, link and unit engine (sans-IO), the vest
//!   worker, and the emulated unit on a PTY;
//! - [`sim`]: simulation glue: the one simulated wearer shared by the GPS simulator and the emulated
//!   unit's compass;
//! - [`serial`]: serial-port discovery and opening (Bluetooth SPP ports are serial ports), the PTY pair,
//!   and the transports' one "nothing yet" rule ([`serial::is_timeout`]);
//! - [`session_log`]: the console's session log (JSON Lines): records, writer, reader;
//! - [`route_file`]: routes in GPX (waypoints, routes, tracks) read and written;
//! - [`ntrip`]: the NTRIP client (v1, v2) forwarding RTK corrections to a serial receiver; [`rtcm3`]: RTCM 3
//!   framing with CRC-24Q;
//! - [`backoff`]: the one exponential reconnect backoff of the workers;
//! - [`doctor`]: the set-up checks of `vestnav doctor` (ports, Bluetooth, OpenGL, folders, optional parts);
//! - [`outbox`]: how workers hand events to their consumers (bounded, never blocking a stop);
//! - [`testkit`]: instruments for tests (a TCP port that refuses, a signal sent from this process).

pub mod backoff;
pub mod doctor;
pub mod gps;
pub mod heading;
pub mod ntrip;
pub mod outbox;
pub mod route_file;
pub mod rtcm3;
pub mod serial;
pub mod session_log;
pub mod sim;
pub mod testkit;
pub mod wtcu;
