//! GPS: NMEA 0183, UBX and `SiRF` decoding into fixes, and the sources that produce them.
//!
//! - [`framing`]: bytes to checksummed sentences (resync, binary frames, junk, limits);
//! - [`assembly`]: sentences to epochs to [`Fix`]es — the sans-IO [`NmeaDecoder`];
//! - [`ubx`]: u-blox UBX binary frames, the navigation messages decoded into the same [`Fix`];
//! - [`sirf`]: `SiRF` binary frames (MID 2, 4 and 41 navigation output) decoded into the same [`Fix`];
//! - [`receiver_config`]: the operator's receiver settings as UBX / `SiRF` commands, the sans-IO session
//!   that sends them and reads the acknowledgements, and the emulated receiver's answers;
//! - [`through_vest`]: the byte pipe from the vest worker to the source reading the receiver on the vest
//!   unit's second UART;
//! - [`sim`]: the built-in simulated receiver (a walker on a GPX route or the demo route, as NMEA);
//! - [`fix`]: the fix type and its plausibility check ([`Fix::validate`], applied to every fix from every
//!   source);
//! - [`gpsd`]: gpsd's JSON protocol (TPV/SKY to [`Fix`], ATT to [`Attitude`]) and its bounded line framer;
//! - [`nmea_out`]: NMEA sentence generation (simulator, emulator);
//! - [`record`]: the timestamped recording format;
//! - [`source`]: worker threads for serial, replay, gpsd, simulator and through-the-vest sources with one
//!   event stream, and [`GpsSourceSpec`], the one way to name a source (text, serde).
//!
//! Headings: HDT/THS (a receiver's true heading) stay in their epoch's [`Fix::true_heading_deg`]; an
//! external compass's HDG and gpsd's ATT reports stand on their own as [`GpsEvent::Attitude`]
//! (docs/gps.md, "Heading sentences").
//!
//! ```
//! use vestnav_device::gps::decode_reader;
//! let log = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n";
//! let (fixes, stats) = decode_reader(log.as_bytes()).unwrap();
//! assert_eq!(fixes.len(), 1);
//! assert!((fixes[0].lat_deg.unwrap() - 57.163445).abs() < 1e-9);
//! assert_eq!(stats.rejected(), 0);
//! ```

pub mod assembly;
pub mod binary_detect;
pub mod casic;
pub mod fix;
pub mod framing;
pub mod gps_time;
pub mod gpsd;
mod le;
pub mod nmea_out;
pub mod receiver_config;
pub mod record;
pub mod rtcm3;
mod sentence;
pub mod sim;
pub mod sirf;
pub mod skytraq;
pub mod source;
pub mod through_vest;
#[cfg(test)]
mod truth_tests;
pub mod ubx;

use std::io::Read;
use std::path::Path;
use std::time::Instant;

use chrono::{DateTime, NaiveTime, Utc};

use crate::heading::Attitude;

pub use assembly::{DecoderConfig, NmeaDecoder};
pub use fix::{Constellation, ErrorEstimate, ErrorSource, Fix, FixCheck, FixMode, FixQuality, Satellite};
pub use framing::{DecodeStats, MAX_SENTENCE_LEN};
pub use source::{
    GpsHandle, GpsSource, GpsSourceSpec, ReplayControl, ReplayProgress, ReplaySpeed, SourceConfig,
    SourceState,
};

/// User equivalent range error of an autonomous (SPS) fix, 1 sigma [m], used by the DOP error model
/// `sigma_h = HDOP * UERE` when the receiver sends no GST. 5 m is the typical single-frequency SPS figure
/// (Misra & Enge, *Global Positioning System*, Table 7.4: ~5 m with broadcast ionosphere corrections).
pub const UERE_M: f64 = 5.0;
/// UERE for differential/SBAS/RTK fixes, 1 sigma [m]: a quarter of the autonomous one (gpsd divides its
/// error estimates by 4 for DGPS as well).
pub const UERE_DGPS_M: f64 = UERE_M / 4.0;

/// An operator mark (`$PVNAV,MARK,<n>,<label>*hh` in a log), tied to the receiver time of the current epoch.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mark {
    /// Mark number as written (cone number in the cone test).
    pub number: u32,
    /// Free text label (may be empty).
    pub label: String,
    /// UTC date and time of the epoch the mark falls in, when known.
    pub time: Option<DateTime<Utc>>,
    /// UTC time of day of that epoch, when known.
    pub time_of_day: Option<NaiveTime>,
    /// The recorder's wall-clock time (the last `$PVNAV,TS` before the mark), Unix ms, when recorded.
    pub recorded_unix_ms: Option<i64>,
}

/// Everything a GPS source reports, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum GpsEvent {
    /// A completed epoch.
    Fix(Box<Fix>),
    /// A heading reading that is not part of an epoch: an NMEA HDG from an external compass (magnetic,
    /// [`HeadingOrigin::Nmea`](crate::heading::HeadingOrigin::Nmea)) or a gpsd ATT report
    /// ([`HeadingOrigin::Gpsd`](crate::heading::HeadingOrigin::Gpsd)). Already checked by
    /// [`Attitude::validate`].
    Attitude(Attitude),
    /// An operator mark.
    Mark(Mark),
    /// Running counts of accepted and rejected input (sent periodically by sources and at the end).
    Stats(DecodeStats),
    /// The source's connection state changed.
    State(SourceState),
    /// Something the operator should know that is neither a state change nor an error, as one line of
    /// text (e.g. a looped simulator starting its next lap).
    Notice(String),
    /// One checksum-verified input sentence as received (for a raw monitor and a recorder); consumers
    /// that do not want it drop it.
    Raw(RawLine),
    /// The input jumped in time (a replay was paused and sought): the next fix does not continue the last
    /// one, so a track must start a new segment and nothing may be derived from the step between them.
    /// The text says what happened, for the operator and the log.
    Discontinuity(String),
}

/// One sentence as the source's framer delivered it (checksum verified; no line end).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawLine {
    /// The sentence, `$` or `!` first, checksum last (e.g. `$GPGGA,...*47`).
    pub text: String,
    /// The instant its bytes arrived (the same clock as [`Fix::received_at`]).
    pub received_at: Instant,
}

/// A heading reading of the GPS input with nothing but a heading: no pitch, roll, quality, field or raw
/// magnetometer values (the one place the GPS layer spells out [`Attitude`]'s fields).
pub(crate) fn bare_attitude(
    heading_deg: f64,
    reference: crate::heading::HeadingReference,
    origin: crate::heading::HeadingOrigin,
    received_at: Instant,
) -> Attitude {
    Attitude {
        heading_deg,
        reference,
        pitch_deg: None,
        roll_deg: None,
        quality_pct: None,
        field_ut: None,
        raw_mag_ut: None,
        origin,
        received_at,
    }
}

/// Errors of the GPS layer.
#[derive(Debug, thiserror::Error)]
pub enum GpsError {
    /// Reading the input failed.
    #[error("reading {what}: {source}")]
    Io {
        /// What was being read.
        what: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A route file could not be used.
    #[error("route {path}: {reason}")]
    Route {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// Decodes a whole NMEA stream (a log file, a recording) into one fix per epoch, plus the marks.
pub fn decode_reader_with_marks(
    mut reader: impl Read,
) -> std::io::Result<(Vec<Fix>, Vec<Mark>, DecodeStats)> {
    let mut decoder = NmeaDecoder::new(DecoderConfig::file());
    let mut fixes = Vec::new();
    let mut marks = Vec::new();
    let mut buf = vec![0u8; 64 * 1024];
    let now = Instant::now();
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        decoder.handle_bytes(&buf[..n], now);
        drain(&mut decoder, &mut fixes, &mut marks);
    }
    decoder.finish(now);
    drain(&mut decoder, &mut fixes, &mut marks);
    Ok((fixes, marks, decoder.stats()))
}

fn drain(decoder: &mut NmeaDecoder, fixes: &mut Vec<Fix>, marks: &mut Vec<Mark>) {
    while let Some(ev) = decoder.poll_event() {
        match ev {
            GpsEvent::Fix(f) => fixes.push(*f),
            GpsEvent::Mark(m) => marks.push(m),
            // A whole-file decode is about positions; attitude readings are for live consumers.
            GpsEvent::Attitude(_)
            | GpsEvent::Stats(_)
            | GpsEvent::State(_)
            | GpsEvent::Notice(_)
            | GpsEvent::Raw(_)
            | GpsEvent::Discontinuity(_) => {}
        }
    }
}

/// Decodes a whole NMEA stream into one fix per epoch.
pub fn decode_reader(reader: impl Read) -> std::io::Result<(Vec<Fix>, DecodeStats)> {
    decode_reader_with_marks(reader).map(|(f, _, s)| (f, s))
}

/// Decodes an NMEA log file into one fix per epoch.
pub fn decode_file(path: &Path) -> Result<(Vec<Fix>, DecodeStats), GpsError> {
    let file = std::fs::File::open(path)
        .map_err(|source| GpsError::Io { what: path.display().to_string(), source })?;
    decode_reader(std::io::BufReader::new(file))
        .map_err(|source| GpsError::Io { what: path.display().to_string(), source })
}
