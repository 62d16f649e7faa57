//! Sentences to epochs to fixes: the sans-IO NMEA decoder.
//!
//! A receiver sends a burst of sentences per epoch (1 Hz on the BT-359). We group them:
//! - a time-bearing sentence (GGA, RMC, GLL, GNS, ZDA, GST) whose UTC time differs from the current
//!   epoch's closes the epoch;
//! - so does a second sentence of a type already seen in this epoch (except GSA and GSV, which come in
//!   several parts) — this separates epochs that carry no time at all (a receiver without a fix often
//!   sends `$GPGGA,,,,,,0,...`);
//! - an epoch that repeats the last epoch's UTC time without any position sentence (GGA, RMC, GLL, GNS,
//!   `$PASHR,POS`) is the same second said again, split off by a repeated time-less sentence or by an
//!   early close: it is dropped, not emitted as a "no fix" of a second that has a fix;
//! - with `early_emit` (live sources), the decoder learns the receiver's last sentence of a cycle (the
//!   type that ended the previous two epochs) and closes the epoch as soon as it arrives, instead of
//!   waiting for the next epoch's first sentence; [`NmeaDecoder::handle_timeout`] closes an epoch after
//!   a quiet gap. If a later sentence still carries the closed epoch's time, the learning is reset and an
//!   amended fix for the same time follows.
//!
//! GSA (DOPs, satellites used) and GSV (satellites in view) are receiver state: they persist across
//! epochs until replaced, because receivers send them less often than GGA/RMC (the `GPSlim` 236 sends GSA
//! every 5 s). The date comes from RMC or ZDA and rolls over at midnight on its own when the time of day
//! wraps before the next date arrives.
//!
//! Every fix is checked by [`Fix::validate`] as it is emitted (out-of-range positions removed, implausible
//! values removed or corrected); what was removed is counted in [`DecodeStats`].
//!
//! Binary frames (docs/gps.md, "u-blox UBX" and "Mixed streams"): the framer hands out checksum-verified
//! UBX, `SiRF`, CASIC and `SkyTraq` frames too; UBX goes to [`UbxDecoder`](super::ubx), `SiRF` to the `SiRF`
//! decoder (CASIC and `SkyTraq` to theirs), and their
//! epochs become fixes exactly like NMEA ones (validated, counted, stamped with `received_at`). While a
//! binary protocol gives fixes, it is the one source of epochs: NMEA epochs of the same receiver are
//! counted as superseded, not reported, so no second is reported twice with different contents; after
//! [`NMEA_TAKEOVER_EPOCHS`] NMEA epochs without a binary fix, NMEA takes over again. Binary frames are not
//! sent as [`GpsEvent::Raw`] (that is the NMEA text the recorder writes back as a log).
//!
//! HDG (an external magnetic compass, often at 10 Hz) is not part of any epoch: each one becomes a
//! [`GpsEvent::Attitude`] at once (magnetic, origin NMEA, `received_at` = the instant of the
//! [`NmeaDecoder::handle_bytes`] call that completed it, as for fixes), checked by
//! [`Attitude::validate`](crate::heading::Attitude::validate)
//! (a failure is counted as malformed). It neither opens nor closes an epoch, and bytes that carried only
//! HDG sentences do not hold the quiet gap open, so a compass stream does not delay fixes.

mod consensus;
mod date;
mod fix_build;

use consensus::{MAX_EPOCH_POSITIONS, consensus};
#[cfg(test)]
use fix_build::ALL_CONSTELLATIONS;

use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, Instant};

use chrono::{DateTime, NaiveDate, NaiveTime, Utc};

use super::casic::CasicDecoder;
use super::fix::{Constellation, ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, Satellite};
use super::framing::{DecodeStats, Frame, Framer};
use super::sentence::{self, Parsed, Unused};
use super::sirf::{SirfDecoder, SirfUnused};
use super::skytraq::SkyTraqDecoder;
use super::ubx::{UbxDecoder, UbxUnused, WithoutFix};
use super::{GpsEvent, Mark, UERE_DGPS_M, UERE_M};
use crate::heading::{HeadingOrigin, HeadingReference};
pub use date::{CONFIRM_EPOCHS, FIRST_DATE, LAST_DATE, in_gps_era};

/// Decoder settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecoderConfig {
    /// Close an epoch at the learned last sentence of the cycle (live use) rather than at the next
    /// epoch's first sentence (file decoding: exactly one fix per epoch).
    pub early_emit: bool,
    /// Close the current epoch when no sentence arrived for this long ([`NmeaDecoder::handle_timeout`]).
    pub quiet_gap: Duration,
}

impl DecoderConfig {
    /// For files: one fix per epoch, closed by the next epoch.
    pub fn file() -> Self {
        Self { early_emit: false, quiet_gap: Duration::from_millis(400) }
    }

    /// For live streams: fixes as soon as the epoch is complete.
    pub fn live() -> Self {
        Self { early_emit: true, quiet_gap: Duration::from_millis(400) }
    }
}

impl Default for DecoderConfig {
    fn default() -> Self {
        Self::live()
    }
}

/// Sentence kinds that appear once per epoch (a repeat starts a new epoch).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Kind {
    Gga,
    Rmc,
    Gll,
    Gns,
    Vtg,
    Zda,
    Gst,
    /// THS and HDT are separate kinds: receivers send both in one epoch (`SkyTraq` PX1172RH).
    Ths,
    Hdt,
    Pgrme,
    Gsa,
    Gsv,
    /// Ashtech `$PASHR,POS`.
    AshtechPos,
    Other,
}

/// A sentence's talker: the two characters after `$` (`GP`, `GN`, `GA`; `PG` for `$PGRME`).
fn talker_of(line: &str) -> [u8; 2] {
    match line.as_bytes() {
        [_, a, b, ..] => [*a, *b],
        _ => [0, 0],
    }
}

/// How many [`Kind`]s there are.
const KINDS: usize = Kind::Other as usize + 1;

fn kind_of(p: &Parsed) -> Kind {
    match p {
        Parsed::Gga { .. } => Kind::Gga,
        Parsed::Rmc { .. } => Kind::Rmc,
        Parsed::Gll { .. } => Kind::Gll,
        Parsed::Gns { .. } => Kind::Gns,
        Parsed::Vtg { .. } => Kind::Vtg,
        Parsed::Zda { .. } => Kind::Zda,
        Parsed::Gst { .. } => Kind::Gst,
        Parsed::Heading { ths: true, .. } => Kind::Ths,
        Parsed::Heading { ths: false, .. } => Kind::Hdt,
        Parsed::Pgrme { .. } => Kind::Pgrme,
        Parsed::Gsa { .. } => Kind::Gsa,
        Parsed::Gsv { .. } => Kind::Gsv,
        Parsed::AshtechPos { .. } => Kind::AshtechPos,
        _ => Kind::Other,
    }
}

#[derive(Debug, Clone, Default)]
struct GsaPart {
    mode: Option<FixMode>,
    ids: Vec<(Constellation, u16)>,
    pdop: Option<f64>,
    hdop: Option<f64>,
    vdop: Option<f64>,
}

type LatLon = (f64, f64);
/// GGA: position, quality, satellites, HDOP, altitude, geoid separation.
type GgaFacts = (Option<LatLon>, Option<FixQuality>, Option<u32>, Option<f64>, Option<f64>, Option<f64>);
/// RMC: valid, position, speed, course.
type RmcFacts = (bool, Option<LatLon>, Option<f64>, Option<f64>);
/// GNS: valid, position, satellites, HDOP, altitude, geoid separation.
type GnsFacts = (bool, Option<LatLon>, Option<u32>, Option<f64>, Option<f64>, Option<f64>);
/// GSV quadruple: id, elevation, azimuth, SNR.
type SatQuad = super::sentence::SatQuad;

/// What the current epoch has said so far.
#[derive(Debug, Clone, Default)]
struct Epoch {
    tod: Option<NaiveTime>,
    date: Option<NaiveDate>,
    /// Bit set of the [`Kind`]s seen (bit = discriminant).
    seen: u16,
    /// The talker (`GP`, `GA`, ...) of each [`Kind`]'s first sentence in the epoch (`[0, 0]`: none yet).
    talkers: [[u8; 2]; KINDS],
    last_kind: Option<Kind>,
    gga: Option<GgaFacts>,
    rmc: Option<RmcFacts>,
    gll: Option<(bool, Option<(f64, f64)>)>,
    gns: Option<GnsFacts>,
    vtg: Option<(Option<f64>, Option<f64>)>,
    gsa: Vec<GsaPart>,
    gst: Option<(Option<f64>, Option<f64>, Option<f64>)>,
    pgrme: Option<(Option<f64>, Option<f64>)>,
    /// Ashtech `$PASHR,POS`: the whole fix of the epoch (kept as parsed).
    ashtech: Option<Parsed>,
    heading_deg: Option<f64>,
    /// A THS with mode `V` said this epoch's heading is not valid.
    heading_invalid: bool,
    /// Anything that makes this epoch worth a fix (a position/time sentence).
    substantive: bool,
    /// The positions of the epoch's valid position sentences (GGA/RMC/GNS/GLL/Ashtech POS) in arrival
    /// order with their sentence's kind, the last [`MAX_EPOCH_POSITIONS`] kept ([`consensus`] picks the
    /// fix's).
    positions: Vec<(Kind, LatLon)>,
}

impl Epoch {
    /// A valid position sentence of `kind` said `pos`.
    fn saw_position(&mut self, kind: Kind, pos: Option<LatLon>) {
        if let Some(p) = pos {
            if self.positions.len() == MAX_EPOCH_POSITIONS {
                self.positions.remove(0);
            }
            self.positions.push((kind, p));
        }
    }

    /// A sentence that says where the receiver is, or that it does not know (GGA, RMC, GLL, GNS, Ashtech
    /// POS), was part of the epoch.
    fn has_position_sentence(&self) -> bool {
        self.gga.is_some()
            || self.rmc.is_some()
            || self.gll.is_some()
            || self.gns.is_some()
            || self.ashtech.is_some()
    }
}

/// A GSV group being collected, and the last complete one, per group key.
#[derive(Debug, Clone, Default)]
struct SkyGroup {
    constellation: Option<Constellation>,
    in_view: u16,
    pending: Vec<SatQuad>,
    next: u16,
    complete: Vec<SatQuad>,
    complete_in_view: u16,
    has_complete: bool,
}

/// The sans-IO NMEA decoder: bytes in, [`GpsEvent`]s out.
#[derive(Debug)]
pub struct NmeaDecoder {
    config: DecoderConfig,
    framer: Framer,
    epoch: Epoch,
    date: Option<NaiveDate>,
    last_tod: Option<NaiveTime>,
    last_closed_tod_ms: Option<u32>,
    /// The last emitted fix was 3D: an epoch without GSA or altitude keeps that dimension (see
    /// [`Self::build_fix`]); a fix loss clears it.
    altitude_fix: bool,
    gsa_state: Vec<GsaPart>,
    sky: BTreeMap<String, SkyGroup>,
    ender: Option<Kind>,
    ender_candidate: Option<Kind>,
    closed_by_ender: bool,
    last_input: Option<Instant>,
    /// Bytes of HDG sentences (with their line end) completed during the current `handle_bytes` call.
    attitude_bytes: usize,
    /// The last HDG magnetic variation, east positive \[deg\].
    magnetic_variation_deg: Option<f64>,
    now: Option<Instant>,
    events: VecDeque<GpsEvent>,
    last_timestamp_ms: Option<i64>,
    epochs: u64,
    /// What [`Fix::validate`] removed from the emitted fixes.
    checked: DecodeStats,
    /// Emit every sentence as a [`GpsEvent::Raw`] too ([`Self::with_raw_lines`]).
    raw_lines: bool,
    ubx: UbxDecoder,
    sirf: SirfDecoder,
    casic: CasicDecoder,
    skytraq: SkyTraqDecoder,
    /// Dates waiting for confirmation (docs/gps.md, "Date validation").
    dates: date::DateCheck,
    binary: BinaryState,
    /// The undecoded binary protocol announced ([`GpsEvent::Notice`], once).
    undecoded_noticed: Option<super::binary_detect::Protocol>,
    /// The last sentence that reached the epoch rules (a duplicate check; the buffer is reused).
    prev_sentence: String,
    /// The UBX messages without a position announced ([`GpsEvent::Notice`], once).
    without_fix_noticed: Option<WithoutFix>,
    /// The kinds of position sentence (bits of [`Kind`]) the last epoch whose sentences disagreed
    /// out-voted: they lose a tie ([`consensus`]).
    outvoted: u16,
}

/// Who gives the epochs when a receiver sends binary frames.
#[derive(Debug, Default)]
struct BinaryState {
    /// A binary frame arrived that has not completed an epoch yet (the quiet gap closes it).
    pending: bool,
    /// A binary protocol gives the fixes: NMEA epochs are superseded.
    owner: bool,
    /// NMEA epochs closed since the last binary fix.
    nmea_epochs_since: u32,
}

/// Unused binary frames, with a [`WithoutFix`] UBX message among them and no sentence or fix, after which
/// the decoder says why there is no fix ([`GpsEvent::Notice`]).
const WITHOUT_FIX_NOTICE_FRAMES: u64 = 3;

/// NMEA epochs without a binary fix after which NMEA gives the fixes again (the receiver stopped its
/// binary output).
pub const NMEA_TAKEOVER_EPOCHS: u32 = 3;

impl Default for NmeaDecoder {
    fn default() -> Self {
        Self::new(DecoderConfig::default())
    }
}

impl NmeaDecoder {
    /// A decoder with no state.
    pub fn new(config: DecoderConfig) -> Self {
        Self {
            config,
            framer: Framer::new(),
            epoch: Epoch::default(),
            date: None,
            last_tod: None,
            last_closed_tod_ms: None,
            altitude_fix: false,
            gsa_state: Vec::new(),
            sky: BTreeMap::new(),
            ender: None,
            ender_candidate: None,
            closed_by_ender: false,
            last_input: None,
            attitude_bytes: 0,
            magnetic_variation_deg: None,
            now: None,
            events: VecDeque::new(),
            last_timestamp_ms: None,
            epochs: 0,
            checked: DecodeStats::default(),
            raw_lines: false,
            ubx: UbxDecoder::new(),
            sirf: SirfDecoder::new(),
            casic: CasicDecoder::new(),
            skytraq: SkyTraqDecoder::new(),
            dates: date::DateCheck::default(),
            binary: BinaryState::default(),
            undecoded_noticed: None,
            prev_sentence: String::new(),
            without_fix_noticed: None,
            outvoted: 0,
        }
    }

    /// Also emits every checksum-verified sentence as a [`GpsEvent::Raw`] (before what it completes), for
    /// a live source's raw monitor and recorder.
    #[must_use]
    pub fn with_raw_lines(mut self) -> Self {
        self.raw_lines = true;
        self
    }

    /// Counts of accepted and rejected input so far.
    pub fn stats(&self) -> DecodeStats {
        let c = &self.checked;
        DecodeStats {
            epochs: self.epochs,
            invalid_positions: c.invalid_positions,
            implausible_values: c.implausible_values,
            nmea_epochs_superseded: c.nmea_epochs_superseded,
            accuracy_gst: c.accuracy_gst,
            accuracy_pgrme: c.accuracy_pgrme,
            accuracy_ubx: c.accuracy_ubx,
            accuracy_sirf: c.accuracy_sirf,
            accuracy_casic: c.accuracy_casic,
            implausible_dates: c.implausible_dates,
            disagreeing_positions: c.disagreeing_positions,
            accuracy_gpsd: c.accuracy_gpsd,
            accuracy_dop_model: c.accuracy_dop_model,
            ..*self.framer.stats()
        }
    }

    /// The last `$PVNAV,TS` recording timestamp seen (Unix milliseconds), if any.
    pub fn last_timestamp_ms(&self) -> Option<i64> {
        self.last_timestamp_ms
    }

    /// The magnetic variation (east positive) of the last HDG that sent one, if any. Recorded only: the
    /// console applies its own WMM declination to every magnetic heading.
    pub fn magnetic_variation_deg(&self) -> Option<f64> {
        self.magnetic_variation_deg
    }

    /// Feeds bytes received at `now`.
    pub fn handle_bytes(&mut self, data: &[u8], now: Instant) {
        self.now = Some(now);
        self.attitude_bytes = 0;
        let mut framer = std::mem::take(&mut self.framer);
        framer.feed(data, |f, stats| self.handle_frame(f, stats));
        self.framer = framer;
        if self.undecoded_noticed.is_none()
            && let Some(p) = self.framer.stats().undecoded_protocol
        {
            self.undecoded_noticed = Some(p);
            self.events.push_back(GpsEvent::Notice(p.advice()));
        }
        // UBX messages without a position and nothing else (no sentence, no fix): say why, once.
        let stats = self.framer.stats();
        if self.without_fix_noticed.is_none()
            && self.epochs == 0
            && stats.sentences == 0
            && stats.binary_frames >= WITHOUT_FIX_NOTICE_FRAMES
            && let Some(w) = stats.ubx_without_fix
        {
            self.without_fix_noticed = Some(w);
            self.events.push_back(GpsEvent::Notice(w.advice().to_owned()));
        }
        // Bytes that were nothing but HDG sentences say nothing about the epoch: they do not hold the
        // quiet gap open.
        if data.len() > self.attitude_bytes {
            self.last_input = Some(now);
        }
    }

    /// When [`Self::handle_timeout`] wants to be called next (the quiet-gap deadline), if an epoch is open.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.epoch.substantive || self.binary.pending {
            self.last_input.map(|t| t + self.config.quiet_gap)
        } else {
            None
        }
    }

    /// Closes the open epoch if nothing arrived for the quiet gap.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.now = Some(now);
        if self.poll_timeout().is_some_and(|deadline| now >= deadline) {
            self.close_epoch();
            self.finish_binary(now);
        }
    }

    /// Closes the open epoch now, stamped `now`: for a producer that writes whole epochs and knows where
    /// one ends (the simulator), instead of waiting for the quiet gap.
    pub fn end_epoch(&mut self, now: Instant) {
        self.now = Some(now);
        self.close_epoch();
        self.finish_binary(now);
    }

    /// Ends the stream: emits the last epoch (and a final sentence without line end).
    pub fn finish(&mut self, now: Instant) {
        self.now = Some(now);
        let mut framer = std::mem::take(&mut self.framer);
        framer.finish(|f, stats| self.handle_frame(f, stats));
        self.framer = framer;
        self.close_epoch();
        self.finish_binary(now);
        self.events.push_back(GpsEvent::Stats(self.stats()));
    }

    /// The next event, if any.
    pub fn poll_event(&mut self) -> Option<GpsEvent> {
        self.events.pop_front()
    }

    /// Handles one item of the framer.
    fn handle_frame(&mut self, frame: Frame<'_>, stats: &mut DecodeStats) {
        let now = self.now.unwrap_or_else(Instant::now);
        let decoded = match frame {
            Frame::Nmea(line) => return self.handle_sentence(line, stats),
            Frame::Ubx { class, id, payload } => {
                if stats.ubx_without_fix.is_none() {
                    stats.ubx_without_fix = WithoutFix::of(class, id);
                }
                self.ubx.handle(class, id, payload, now).map_err(|e| e == UbxUnused::Malformed)
            }
            Frame::Sirf { payload } => {
                self.sirf.handle(payload, now).map_err(|e| matches!(e, SirfUnused::Malformed))
            }
            Frame::Casic { class, id, payload } => {
                self.casic.handle(class, id, payload, now).map_err(|e| e == UbxUnused::Malformed)
            }
            Frame::SkyTraq { payload } => {
                self.skytraq.handle(payload, now).map_err(|e| e == UbxUnused::Malformed)
            }
            // Corrections: counted by the framer, nothing to decode.
            Frame::Rtcm3 { .. } => return,
        };
        match decoded {
            Ok(Some(fix)) => self.emit_binary(fix),
            Ok(None) => self.binary.pending = true,
            Err(true) => stats.binary_malformed += 1,
            Err(false) => stats.binary_frames += 1,
        }
    }

    /// Closes the binary decoders' open epochs (end of stream, quiet gap).
    fn finish_binary(&mut self, now: Instant) {
        if std::mem::take(&mut self.binary.pending) {
            for fix in
                [self.ubx.finish(now), self.sirf.finish(now), self.casic.finish(now)].into_iter().flatten()
            {
                self.emit_binary(fix);
            }
        }
    }

    /// A fix from a binary decoder leaves like an NMEA one: validated, counted, stamped.
    fn emit_binary(&mut self, mut fix: Fix) {
        self.binary.pending = self.ubx.has_open_epoch() || self.casic.has_open_epoch();
        self.binary.owner = true;
        self.binary.nmea_epochs_since = 0;
        fix.received_at = self.now.or(fix.received_at);
        // The date check, as for NMEA: a rejected date gives way to the running one (rolled at midnight).
        if let Some(t) = fix.time {
            let tod = Some(t.time());
            if self.dates.accept(t.date_naive(), tod, self.date, self.last_tod) {
                self.date = Some(t.date_naive());
            } else {
                self.checked.implausible_dates += 1;
                self.date = self.date.map(|d| date::roll(d, self.last_tod, tod).max(d));
                fix.time = self.date.map(|d| utc(d, t.time()));
            }
        }
        fix.validate().count_into(&mut self.checked);
        self.checked.count_accuracy(fix.error.as_ref());
        if fix.time_of_day.is_some() {
            self.last_tod = fix.time_of_day;
        }
        self.epochs += 1;
        self.events.push_back(GpsEvent::Fix(Box::new(fix)));
    }

    /// Handles one checksum-verified sentence (`$...*hh`), as if it had come through the framer.
    fn handle_sentence(&mut self, line: &str, stats: &mut DecodeStats) {
        if self.raw_lines
            && let Some(now) = self.now
        {
            self.events.push_back(GpsEvent::Raw(super::RawLine { text: line.to_owned(), received_at: now }));
        }
        // The receiver family shows in its proprietary sentences (receiver_config::Family::detect).
        let body = line.trim_start_matches('$');
        if body.starts_with("PSRF") {
            stats.sirf_sentences += 1;
        } else if body.starts_with("PUBX") || (body.get(2..5) == Some("TXT") && body.contains("u-blox")) {
            stats.ublox_sentences += 1;
        }
        let parsed = match sentence::parse(line) {
            Ok(p) => p,
            Err(Unused::Unsupported) => {
                stats.unsupported += 1;
                return;
            }
            Err(Unused::Malformed) => {
                stats.malformed += 1;
                return;
            }
        };
        match parsed {
            Parsed::Mark { number, label } => {
                stats.marks += 1;
                let tod = self.epoch.tod.or(self.last_tod);
                let time = tod.and_then(|t| self.date.map(|d| d.and_time(t).and_utc()));
                self.events.push_back(GpsEvent::Mark(Mark {
                    number,
                    label,
                    time,
                    time_of_day: tod,
                    recorded_unix_ms: self.last_timestamp_ms,
                }));
                return;
            }
            Parsed::Timestamp { unix_ms } => {
                self.last_timestamp_ms = Some(unix_ms);
                return;
            }
            Parsed::Hdg { magnetic_deg, variation_deg } => {
                self.attitude_bytes += line.len() + 2;
                if variation_deg.is_some() {
                    self.magnetic_variation_deg = variation_deg;
                }
                let Some(received_at) = self.now else { return };
                let attitude = super::bare_attitude(
                    magnetic_deg,
                    HeadingReference::Magnetic,
                    HeadingOrigin::Nmea,
                    received_at,
                );
                // The boundary check, as for fixes; the parser's range checks make a failure unlikely.
                if attitude.validate().is_err() {
                    stats.malformed += 1;
                    return;
                }
                self.events.push_back(GpsEvent::Attitude(attitude));
                return;
            }
            Parsed::Ignored => return,
            _ => {}
        }
        let kind = kind_of(&parsed);
        let time = sentence::time_of(&parsed);
        if !self.epoch_boundaries(line, kind, time) {
            stats.duplicate_sentences += 1;
            return;
        }
        if let Some(t) = time {
            self.epoch.tod = Some(t);
        }
        self.apply(parsed);
        self.epoch.seen |= 1 << kind as u16;
        self.epoch.last_kind = Some(kind);
        if self.config.early_emit && self.ender == Some(kind) && self.epoch.substantive {
            self.close_epoch();
            self.closed_by_ender = true;
        }
    }

    /// The epoch rules for a sentence of `kind` with UTC `time`, before it is applied: closes the open
    /// epoch where this sentence starts the next one. False when the sentence is a forwarding duplicate, to
    /// be skipped.
    fn epoch_boundaries(&mut self, line: &str, kind: Kind, time: Option<NaiveTime>) -> bool {
        // The same sentence twice in a row, in an epoch that has its UTC time: a multiplexer forwarding it
        // twice (the B&G Zeus² sends some VTGs so), not the start of the next epoch. GSA and GSV come in
        // parts, which may be equal (two constellations' empty GSAs): they never split an epoch anyway.
        let duplicate = !matches!(kind, Kind::Gsa | Kind::Gsv)
            && self.epoch.tod.is_some()
            && self.epoch.last_kind == Some(kind)
            && self.prev_sentence == line;
        self.prev_sentence.clear();
        self.prev_sentence.push_str(line);
        if duplicate {
            return false;
        }
        // Epoch boundaries.
        if let Some(t) = time {
            if self.closed_by_ender && self.epoch.seen == 0 {
                if self.last_closed_tod_ms == Some(sentence::tod_ms(t)) {
                    // The learned cycle end was wrong: this sentence still belongs to the closed epoch.
                    self.ender = None;
                    self.ender_candidate = None;
                }
                self.closed_by_ender = false;
            }
            if let Some(cur) = self.epoch.tod
                && sentence::tod_ms(cur) != sentence::tod_ms(t)
            {
                self.boundary();
            }
        }
        // A repeated type closes the epoch, unless the repeat carries the epoch's own UTC time: then it is
        // the same second said twice (the B&G Zeus 2 multiplexer forwards some ZDAs twice), and splitting
        // would leave a second epoch of that time with no position. NMEA 0183 ties a sentence to its
        // epoch by the UTC time field; only sentences without one need the repeat rule.
        // Nor does a repeat from another talker: a multi-constellation receiver's per-system sentences of one
        // epoch (the Telit PLS83-W's `$GPVTG` and `$GAVTG`, time-less, between its GGAs and RMCs).
        let same_second =
            time.zip(self.epoch.tod).is_some_and(|(t, cur)| sentence::tod_ms(t) == sentence::tod_ms(cur));
        let talker = talker_of(line);
        let first_talker = self.epoch.talkers[kind as usize];
        let other_talker = first_talker != [0, 0] && first_talker != talker;
        if kind != Kind::Gsa
            && kind != Kind::Gsv
            && !same_second
            && !other_talker
            && self.epoch.seen & (1 << kind as u16) != 0
        {
            self.boundary();
        }
        if self.epoch.talkers[kind as usize] == [0, 0] {
            self.epoch.talkers[kind as usize] = talker;
        }
        true
    }

    /// A boundary found by the next epoch's first sentence.
    fn boundary(&mut self) {
        self.close_epoch();
    }

    fn apply(&mut self, p: Parsed) {
        let e = &mut self.epoch;
        match p {
            Parsed::Gga { pos, quality, sats, hdop, alt_m, geoid_sep_m, .. } => {
                e.gga = Some((pos, quality, sats, given_dop(hdop), alt_m, geoid_sep_m));
                if quality.is_some_and(FixQuality::has_position) {
                    e.saw_position(Kind::Gga, pos);
                }
                e.substantive = true;
            }
            Parsed::Rmc { date, valid, pos, speed_m_s, course_deg, .. } => {
                e.rmc = Some((valid, pos, speed_m_s, course_deg));
                if valid {
                    e.saw_position(Kind::Rmc, pos);
                }
                if date.is_some() {
                    e.date = date;
                }
                e.substantive = true;
            }
            Parsed::Gll { pos, valid, .. } => {
                e.gll = Some((valid, pos));
                if valid {
                    e.saw_position(Kind::Gll, pos);
                }
                e.substantive = true;
            }
            Parsed::Gns { pos, valid, sats, hdop, alt_m, geoid_sep_m, .. } => {
                e.gns = Some((valid, pos, sats, given_dop(hdop), alt_m, geoid_sep_m));
                if valid {
                    e.saw_position(Kind::Gns, pos);
                }
                e.substantive = true;
            }
            Parsed::Zda { date, time } => {
                if date.is_some() {
                    e.date = date;
                }
                e.substantive |= time.is_some();
            }
            Parsed::Vtg { course_deg, speed_m_s } => e.vtg = Some((course_deg, speed_m_s)),
            Parsed::Gst { lat_sd_m, lon_sd_m, alt_sd_m, .. } => e.gst = Some((lat_sd_m, lon_sd_m, alt_sd_m)),
            Parsed::Pgrme { horizontal_m, vertical_m } => e.pgrme = Some((horizontal_m, vertical_m)),
            p @ Parsed::AshtechPos { .. } => {
                if let Parsed::AshtechPos { pos, quality: Some(_), .. } = p {
                    e.saw_position(Kind::AshtechPos, pos);
                }
                e.ashtech = Some(p);
                e.substantive = true;
            }
            Parsed::Heading { heading_deg, invalid, .. } => {
                e.heading_invalid |= invalid;
                e.heading_deg = heading_deg.or(e.heading_deg);
            }
            Parsed::Gsa { mode, constellation, ids, pdop, hdop, vdop } => {
                let ids = ids
                    .into_iter()
                    .map(|id| (constellation.unwrap_or_else(|| Constellation::from_nmea_id(id)), id))
                    .collect();
                let (pdop, hdop, vdop) = (given_dop(pdop), given_dop(hdop), given_dop(vdop));
                e.gsa.push(GsaPart { mode, ids, pdop, hdop, vdop });
            }
            Parsed::Gsv { key, constellation, total, number, in_view, sats } => {
                let g = self.sky.entry(key).or_default();
                if number == 1 {
                    g.pending.clear();
                    g.next = 1;
                }
                if number != g.next {
                    // Out of order or a part was lost: drop the group.
                    g.pending.clear();
                    g.next = 0;
                    return;
                }
                g.constellation = constellation;
                g.in_view = in_view;
                g.pending.extend(sats);
                g.next += 1;
                if number == total {
                    g.complete = std::mem::take(&mut g.pending);
                    g.complete_in_view = g.in_view;
                    g.has_complete = true;
                    g.next = 0;
                }
            }
            Parsed::Mark { .. } | Parsed::Timestamp { .. } | Parsed::Hdg { .. } | Parsed::Ignored => {}
        }
    }

    fn close_epoch(&mut self) {
        let mut epoch = std::mem::take(&mut self.epoch);
        // The same second said again without a position sentence (a repeated time-less sentence split it
        // off: the B&G Zeus² sends `RMC VTG ZDA RMC VTG ZDA` of one second; or a ZDA after an early-closed
        // epoch) is not a second epoch: its fix would say "no fix" for a second that has one.
        if epoch.substantive
            && !epoch.has_position_sentence()
            && epoch.tod.is_some_and(|t| self.last_closed_tod_ms == Some(sentence::tod_ms(t)))
        {
            epoch.substantive = false;
        }
        // Learn the cycle's last sentence: the type that ended two consecutive epochs (however they closed).
        if epoch.substantive
            && let Some(last) = epoch.last_kind
        {
            if self.ender_candidate == Some(last) {
                self.ender = Some(last);
            }
            self.ender_candidate = Some(last);
        }
        if epoch.substantive {
            self.emit_epoch(&epoch);
        }
        if !epoch.gsa.is_empty() {
            self.gsa_state = std::mem::take(&mut epoch.gsa);
        }
    }

    fn emit_epoch(&mut self, epoch: &Epoch) {
        // Date: this epoch's if it passes the date check (docs/gps.md, "Date validation"), else the last
        // one rolled over if the time of day wrapped past midnight.
        let own = epoch.date.filter(|&d| self.dates.accept(d, epoch.tod, self.date, self.last_tod));
        if epoch.date.is_some() && own.is_none() {
            self.checked.implausible_dates += 1;
        }
        if let Some(d) = own {
            self.date = Some(d);
        } else if let Some(d) = self.date {
            // Only forwards: an epoch without a date that jumps back in time says nothing about the day.
            self.date = Some(date::roll(d, self.last_tod, epoch.tod).max(d));
        }
        if epoch.tod.is_some() {
            self.last_tod = epoch.tod;
            self.last_closed_tod_ms = epoch.tod.map(sentence::tod_ms);
        }
        if self.binary.owner {
            self.binary.nmea_epochs_since += 1;
            if self.binary.nmea_epochs_since <= NMEA_TAKEOVER_EPOCHS {
                self.checked.nmea_epochs_superseded += 1;
                return;
            }
            // NMEA takes over: a binary epoch the receiver never closed (no EOE, no next message) is
            // emitted first, so the fixes stay in time order.
            if let Some(now) = self.now {
                self.finish_binary(now);
            }
            self.binary = BinaryState::default();
        }
        let chosen = consensus(&epoch.positions, self.outvoted);
        let mut fix = self.build_fix(epoch, chosen.position);
        if fix.has_position() && chosen.outvoted != 0 {
            self.checked.disagreeing_positions += 1;
            self.outvoted = chosen.outvoted;
        }
        // The one boundary check of every value before the fix leaves the decoder.
        fix.validate().count_into(&mut self.checked);
        self.checked.count_accuracy(fix.error.as_ref());
        self.altitude_fix = fix.mode == Some(FixMode::Fix3D);
        self.epochs += 1;
        self.events.push_back(GpsEvent::Fix(Box::new(fix)));
    }
}

fn utc(d: NaiveDate, t: NaiveTime) -> DateTime<Utc> {
    d.and_time(t).and_utc()
}

/// A DOP as the receiver means it: 0 is "not computed" (the Jackson Labs Micro JLT sends GSA DOPs of
/// 0.00 with a 3D fix). No satellite geometry has a dilution of 0, and taken as a number it would make
/// the DOP model claim an error of 0 m. (Negative and non-finite values stay: `Fix::validate` removes
/// and counts them.)
fn given_dop(dop: Option<f64>) -> Option<f64> {
    dop.filter(|&d| d.abs() > 0.0 || !d.is_finite())
}

#[cfg(test)]
mod heading_tests;
#[cfg(test)]
mod tests;
