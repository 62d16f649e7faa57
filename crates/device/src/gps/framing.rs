//! Byte stream to checksummed NMEA sentences and binary frames: resynchronisation, junk, limits.
//!
//! The framer is a small state machine fed arbitrary bytes. It hands out each item it can trust
//! ([`Frame`]) and counts everything it throws away, by reason ([`DecodeStats`]):
//! - an NMEA sentence whose `*hh` checksum is correct;
//! - a u-blox UBX frame (`B5 62 class id len16le payload ck_a ck_b`) whose Fletcher checksum
//!   ([`super::ubx::checksum`]) is correct;
//! - a `SiRF` binary frame (`A0 A2 len16be payload ck16be B0 B3`) whose 15-bit checksum
//!   ([`super::sirf::checksum`]) and end sequence are correct;
//! - a CASIC binary frame (`BA CE len16le class id payload ck32le`, `ZhongKeWei` / Quectel L76K) whose
//!   32-bit word sum ([`super::casic::checksum`]) is correct;
//! - a `SkyTraq` binary frame (`A0 A1 len16be payload cs 0D 0A`, Venus 6/8) whose XOR checksum
//!   ([`super::skytraq::checksum`]) and end sequence are correct (`A0` then `A1` is `SkyTraq`, `A0 A2`
//!   `SiRF`);
//! - an RTCM 3 frame (`D3 len10 payload crc24`) whose CRC-24Q ([`super::rtcm3::crc24q`]) is correct: handed
//!   out so it is skipped whole (receivers mixing UBX, NMEA and RTCM 3 lose nothing to it).
//!
//! What it rejects:
//! - a `$` (or `!`) in the middle of a line starts a new sentence; the interrupted one is counted as
//!   truncated (gpsd does the same; the Triton 400 log has `$GPGGA,030130$GPGLL,...`);
//! - a control or non-ASCII byte (NUL, ANSI escape, binary) inside a line truncates it;
//! - a binary frame is collected whole by its length field (so a `$` inside its payload cannot start a
//!   false sentence), up to [`MAX_BINARY_PAYLOAD`] bytes of payload. A frame whose checksum or end
//!   sequence is wrong, whose length field is larger than that, or that the stream ends inside, is counted
//!   ([`DecodeStats::binary_bad_checksum`]) and never handed out; its bytes after the two sync bytes are
//!   scanned again, so a false `B5 62` or `A0 A2` in line noise cannot hide the sentences and frames
//!   behind it. (Until the false frame's length has passed, those sentences are held back: at most
//!   [`MAX_BINARY_PAYLOAD`] + 8 bytes.)
//! - lines longer than [`MAX_SENTENCE_LEN`] are dropped (NMEA 0183 allows 82 characters; real receivers
//!   go beyond it: `SkyTraq`'s PSTI is ~100, `MediaTek`'s channel status `$PMTKCHN` 203 for its 32
//!   channels, and gpsd frames and echoes it, so we accept a little more than that);
//! - sentences without a checksum, or with a wrong one, are rejected (gpsd rejects them too);
//! - lines starting with `#` are comments (gpsd's test logs) and are skipped, not counted as errors.

use super::{casic, rtcm3, sirf, skytraq, ubx};

/// Longest sentence accepted, `$` to the last checksum digit: above the longest real receiver sentence we
/// know (`MediaTek`'s 32-channel `$PMTKCHN`, 203 characters), about three times NMEA's 82.
pub const MAX_SENTENCE_LEN: usize = 256;
/// Longest binary frame payload collected; a longer length field means the sync bytes were junk. The
/// largest UBX messages of the receivers we know are far shorter (NAV-SAT with 100 satellites: 1208
/// bytes; RXM-RAWX with 32 measurements: 1040), `SiRF`'s longest (MID 8, 50 BPS data) is 43.
pub const MAX_BINARY_PAYLOAD: usize = 8192;

/// One item the framer hands out: everything in it has passed its checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame<'a> {
    /// An NMEA sentence, `$` or `!` first, checksum digits last, without CR LF (e.g. `$GPGGA,...*47`).
    Nmea(&'a str),
    /// A UBX frame: its class, id and payload.
    Ubx {
        /// Message class (0x01 NAV, ...).
        class: u8,
        /// Message id within the class.
        id: u8,
        /// The payload (without header and checksum).
        payload: &'a [u8],
    },
    /// A `SiRF` binary frame: its payload, message id (MID) first.
    Sirf {
        /// The payload (without start, length, checksum and end).
        payload: &'a [u8],
    },
    /// A CASIC binary frame: its class, id and payload.
    Casic {
        /// Message class (0x01 NAV, ...).
        class: u8,
        /// Message id within the class.
        id: u8,
        /// The payload (without header, length and checksum).
        payload: &'a [u8],
    },
    /// A `SkyTraq` binary frame: its payload, message id first (never empty).
    SkyTraq {
        /// The payload (without start, length, checksum and end).
        payload: &'a [u8],
    },
    /// An RTCM 3 frame (corrections; not decoded): its payload, message number in the first 12 bits.
    Rtcm3 {
        /// The payload (without preamble, length and CRC).
        payload: &'a [u8],
    },
}

/// Counts of what a decoder accepted and rejected, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DecodeStats {
    /// Bytes fed in.
    pub bytes: u64,
    /// Sentences with a correct checksum.
    pub sentences: u64,
    /// Sentences with a wrong checksum (rejected).
    pub bad_checksum: u64,
    /// Sentences without a `*hh` checksum (rejected).
    pub missing_checksum: u64,
    /// Lines longer than [`MAX_SENTENCE_LEN`] (NMEA) or [`super::gpsd::MAX_LINE_LEN`] (gpsd JSON), dropped
    /// without being buffered (rejected).
    pub overlong: u64,
    /// Sentences cut short by a new `$`, a control or non-ASCII byte (rejected).
    pub truncated: u64,
    /// Sentences with a correct checksum whose fields make no sense (rejected).
    pub malformed: u64,
    /// Sentences with a correct checksum of a type we do not use (ignored, not an error).
    pub unsupported: u64,
    /// UBX or `SiRF` binary frames with a correct checksum of a message we do not decode (ignored, not an
    /// error).
    pub binary_frames: u64,
    /// Bytes outside any sentence or frame (line noise, ANSI escapes, banners).
    pub junk_bytes: u64,
    /// `#` comment lines skipped.
    pub comment_lines: u64,
    /// Epochs assembled into fixes.
    pub epochs: u64,
    /// Operator marks (`$PVNAV,MARK`).
    pub marks: u64,
    /// Fixes whose position was not finite or out of range (|lat| > 90°, |lon| > 180°): the position was
    /// removed and the fix reported as no fix ([`super::Fix::validate`]).
    #[serde(default)]
    pub invalid_positions: u64,
    /// Implausible values removed or corrected in fixes (negative DOPs, speeds or error estimates, courses
    /// outside 0–360°, absurd satellite counts...; [`super::Fix::validate`]).
    #[serde(default)]
    pub implausible_values: u64,
    /// UBX frames with a correct checksum (decoded or ignored).
    #[serde(default)]
    pub ubx_frames: u64,
    /// `SiRF` binary frames with a correct checksum and end sequence (decoded or ignored).
    #[serde(default)]
    pub sirf_frames: u64,
    /// CASIC binary frames with a correct checksum (decoded or ignored).
    #[serde(default)]
    pub casic_frames: u64,
    /// `SkyTraq` binary frames with a correct checksum and end sequence (decoded or ignored).
    #[serde(default)]
    pub skytraq_frames: u64,
    /// `SiRF` proprietary NMEA sentences (`$PSRF…`, e.g. the power-on `$PSRFTXT` banner) with a correct
    /// checksum: the stream is a `SiRF` receiver's.
    #[serde(default)]
    pub sirf_sentences: u64,
    /// u-blox proprietary or identifying NMEA sentences (`$PUBX`, a `TXT` naming u-blox) with a correct
    /// checksum: the stream is a u-blox receiver's.
    #[serde(default)]
    pub ublox_sentences: u64,
    /// RTCM 3 frames with a correct CRC-24Q (corrections, skipped whole: not an error).
    #[serde(default)]
    pub rtcm3_frames: u64,
    /// Dates (RMC, ZDA, binary time messages) outside the GPS era or inconsistent with the previous
    /// epochs' date: not used for the fix's time (docs/gps.md, "Date validation").
    #[serde(default)]
    pub implausible_dates: u64,
    /// NMEA epochs whose position sentences disagreed by more than a metre (a multiplexer labelling one
    /// sentence type a second apart): the position most of them agree on was used (docs/gps.md,
    /// "`bundg_zeus_9`").
    #[serde(default)]
    pub disagreeing_positions: u64,
    /// Sentences identical to the one just before them within an epoch that has its UTC time (a multiplexer
    /// forwarding one twice): skipped, so they split no epoch (accepted, not an error).
    #[serde(default)]
    pub duplicate_sentences: u64,
    /// A binary protocol we recognise but do not decode (Trimble TSIP, Motorola Oncore, ...), confirmed by
    /// several well-formed frames: the receiver must be switched to NMEA ([`super::binary_detect`]).
    #[serde(default)]
    pub undecoded_protocol: Option<super::binary_detect::Protocol>,
    /// The first UBX message seen that carries no live position (raw subframes or measurements, a stored
    /// log read back): with no epoch, the summary says so and what to change.
    #[serde(default)]
    pub ubx_without_fix: Option<super::ubx::WithoutFix>,
    /// Binary frames rejected by the framer: a wrong checksum or `SiRF` end sequence, a length field over
    /// [`MAX_BINARY_PAYLOAD`], or a frame the stream ended inside (rejected; its bytes are scanned again).
    #[serde(default)]
    pub binary_bad_checksum: u64,
    /// Binary frames with a correct checksum of a message we decode whose length or fields make no sense
    /// (rejected).
    #[serde(default)]
    pub binary_malformed: u64,
    /// NMEA epochs not reported because a binary protocol (UBX, `SiRF`) reports the receiver's epochs
    /// (docs/gps.md, "Mixed streams").
    #[serde(default)]
    pub nmea_epochs_superseded: u64,
    /// Fixes whose error estimate came from the receiver: NMEA GST.
    #[serde(default)]
    pub accuracy_gst: u64,
    /// Fixes whose error estimate came from the receiver: Garmin `$PGRME`.
    #[serde(default)]
    pub accuracy_pgrme: u64,
    /// Fixes whose error estimate came from the receiver: UBX `hAcc`/`vAcc`.
    #[serde(default)]
    pub accuracy_ubx: u64,
    /// Fixes whose error estimate came from the receiver: `SiRF` EHPE/EVPE.
    #[serde(default)]
    pub accuracy_sirf: u64,
    /// Fixes whose error estimate came from the receiver: CASIC `hAcc`/`vAcc`.
    #[serde(default)]
    pub accuracy_casic: u64,
    /// Fixes whose error estimate is gpsd's `eph`/`epv`.
    #[serde(default)]
    pub accuracy_gpsd: u64,
    /// Fixes whose error estimate is our DOP model (`HDOP x UERE`).
    #[serde(default)]
    pub accuracy_dop_model: u64,
}

impl DecodeStats {
    /// All rejected input: sentences with a bad or missing checksum, overlong, truncated or malformed, and
    /// binary frames with a bad checksum or malformed contents.
    pub fn rejected(&self) -> u64 {
        self.bad_checksum
            + self.missing_checksum
            + self.overlong
            + self.truncated
            + self.malformed
            + self.binary_bad_checksum
            + self.binary_malformed
    }

    /// Fixes with an error estimate from the receiver itself (GST, PGRME, UBX, `SiRF`, CASIC).
    pub fn accuracy_receiver(&self) -> u64 {
        self.accuracy_gst + self.accuracy_pgrme + self.accuracy_ubx + self.accuracy_sirf + self.accuracy_casic
    }

    /// Counts one emitted fix's error estimate by its source.
    pub fn count_accuracy(&mut self, error: Option<&super::ErrorEstimate>) {
        use super::ErrorSource;
        match error.map(|e| e.source) {
            Some(ErrorSource::Gst) => self.accuracy_gst += 1,
            Some(ErrorSource::Pgrme) => self.accuracy_pgrme += 1,
            Some(ErrorSource::Ubx) => self.accuracy_ubx += 1,
            Some(ErrorSource::Sirf) => self.accuracy_sirf += 1,
            Some(ErrorSource::Casic) => self.accuracy_casic += 1,
            Some(ErrorSource::Gpsd) => self.accuracy_gpsd += 1,
            Some(ErrorSource::DopModel { .. }) => self.accuracy_dop_model += 1,
            None => {}
        }
    }

    /// Adds another set of counts to this one.
    pub fn merge(&mut self, o: &Self) {
        self.bytes += o.bytes;
        self.sentences += o.sentences;
        self.bad_checksum += o.bad_checksum;
        self.missing_checksum += o.missing_checksum;
        self.overlong += o.overlong;
        self.truncated += o.truncated;
        self.malformed += o.malformed;
        self.unsupported += o.unsupported;
        self.binary_frames += o.binary_frames;
        self.junk_bytes += o.junk_bytes;
        self.comment_lines += o.comment_lines;
        self.epochs += o.epochs;
        self.marks += o.marks;
        self.invalid_positions += o.invalid_positions;
        self.implausible_values += o.implausible_values;
        self.ubx_frames += o.ubx_frames;
        self.sirf_frames += o.sirf_frames;
        self.casic_frames += o.casic_frames;
        self.skytraq_frames += o.skytraq_frames;
        self.sirf_sentences += o.sirf_sentences;
        self.ublox_sentences += o.ublox_sentences;
        self.rtcm3_frames += o.rtcm3_frames;
        self.implausible_dates += o.implausible_dates;
        self.disagreeing_positions += o.disagreeing_positions;
        self.duplicate_sentences += o.duplicate_sentences;
        self.undecoded_protocol = self.undecoded_protocol.or(o.undecoded_protocol);
        self.ubx_without_fix = self.ubx_without_fix.or(o.ubx_without_fix);
        self.binary_bad_checksum += o.binary_bad_checksum;
        self.binary_malformed += o.binary_malformed;
        self.nmea_epochs_superseded += o.nmea_epochs_superseded;
        self.accuracy_gst += o.accuracy_gst;
        self.accuracy_pgrme += o.accuracy_pgrme;
        self.accuracy_ubx += o.accuracy_ubx;
        self.accuracy_sirf += o.accuracy_sirf;
        self.accuracy_casic += o.accuracy_casic;
        self.accuracy_gpsd += o.accuracy_gpsd;
        self.accuracy_dop_model += o.accuracy_dop_model;
    }
}

impl DecodeStats {
    /// NMEA sentences and GPS binary frames recognised by their checksum, whatever became of them (used,
    /// rejected for a wrong checksum, ignored): 0 for input that is no GPS log at all (a text file, an
    /// image), which a reader should report as such rather than as an empty log.
    pub fn recognised(&self) -> u64 {
        self.sentences
            + self.bad_checksum
            + self.ubx_frames
            + self.sirf_frames
            + self.casic_frames
            + self.skytraq_frames
            + self.rtcm3_frames
    }
}

impl std::fmt::Display for DecodeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(p) = self.undecoded_protocol {
            write!(f, "{}; ", p.advice())?;
        }
        if self.epochs == 0
            && let Some(w) = self.ubx_without_fix
        {
            write!(f, "{}; ", w.advice())?;
        }
        write!(
            f,
            "{} bytes, {} sentences, {} UBX frames, {} SiRF frames, ",
            self.bytes, self.sentences, self.ubx_frames, self.sirf_frames
        )?;
        if self.casic_frames > 0 {
            write!(f, "{} CASIC frames, ", self.casic_frames)?;
        }
        if self.skytraq_frames > 0 {
            write!(f, "{} SkyTraq frames, ", self.skytraq_frames)?;
        }
        if self.rtcm3_frames > 0 {
            write!(f, "{} RTCM 3 frames (skipped), ", self.rtcm3_frames)?;
        }
        write!(
            f,
            "{} epochs, {} marks; rejected {} (bad \
             checksum {}, no checksum {}, truncated {}, overlong {}, malformed {}, bad binary frames {}, \
             malformed binary {}); ignored: {} unsupported sentences, {} unsupported binary frames, {} junk \
             bytes, {} comment lines",
            self.epochs,
            self.marks,
            self.rejected(),
            self.bad_checksum,
            self.missing_checksum,
            self.truncated,
            self.overlong,
            self.malformed,
            self.binary_bad_checksum,
            self.binary_malformed,
            self.unsupported,
            self.binary_frames,
            self.junk_bytes,
            self.comment_lines,
        )?;
        if self.nmea_epochs_superseded > 0 {
            write!(f, ", {} NMEA epochs superseded by binary ones", self.nmea_epochs_superseded)?;
        }
        if self.duplicate_sentences > 0 {
            write!(f, ", {} sentences repeated at once (skipped)", self.duplicate_sentences)?;
        }
        if self.disagreeing_positions > 0 {
            write!(
                f,
                ", {} epochs whose sentences disagree on the position (the majority's used)",
                self.disagreeing_positions
            )?;
        }
        write!(
            f,
            "; removed from fixes: {} invalid positions, {} implausible values, {} implausible dates; \
             accuracy from the receiver {} (GST {}, PGRME {}, UBX {}, SiRF {}), gpsd {}, DOP model {}",
            self.invalid_positions,
            self.implausible_values,
            self.implausible_dates,
            self.accuracy_receiver(),
            self.accuracy_gst,
            self.accuracy_pgrme,
            self.accuracy_ubx,
            self.accuracy_sirf,
            self.accuracy_gpsd,
            self.accuracy_dop_model,
        )
    }
}

/// A binary protocol the framer collects frames of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Proto {
    Ubx,
    Sirf,
    Casic,
    SkyTraq,
    Rtcm3,
}

impl Proto {
    /// Sync bytes before the header.
    const fn sync_len(self) -> usize {
        match self {
            Self::Rtcm3 => 1,
            Self::Ubx | Self::Sirf | Self::Casic | Self::SkyTraq => 2,
        }
    }

    /// Bytes of the header after the sync bytes (UBX: class, id, len16le; `SiRF`, `SkyTraq`: len16be; CASIC:
    /// len16le, class, id; RTCM 3: reserved 6 bits and len10).
    const fn header_len(self) -> usize {
        match self {
            Self::Ubx | Self::Casic => 4,
            Self::Sirf | Self::SkyTraq | Self::Rtcm3 => 2,
        }
    }

    /// Bytes after the payload (UBX: `ck_a ck_b`; `SiRF`: ck16be, B0 B3; CASIC: ck32le; `SkyTraq`: XOR,
    /// 0D 0A; RTCM 3: CRC-24Q).
    const fn trailer_len(self) -> usize {
        match self {
            Self::Ubx => 2,
            Self::SkyTraq | Self::Rtcm3 => 3,
            Self::Sirf | Self::Casic => 4,
        }
    }

    /// The payload length a complete header announces; `None` when it cannot be a frame (RTCM 3's reserved
    /// bits set, a CASIC payload that is not whole 4-byte words, an empty `SkyTraq` payload: it has no
    /// message id).
    fn payload_len(self, header: &[u8]) -> Option<usize> {
        match (self, header) {
            (Self::Sirf, &[hi, lo]) => Some(usize::from(u16::from_be_bytes([hi, lo]))),
            (Self::Ubx, &[_, _, lo, hi]) => Some(usize::from(u16::from_le_bytes([lo, hi]))),
            (Self::Casic, &[lo, hi, _, _]) => {
                Some(usize::from(u16::from_le_bytes([lo, hi]))).filter(|n| n.is_multiple_of(4))
            }
            (Self::SkyTraq, &[hi, lo]) => Some(usize::from(u16::from_be_bytes([hi, lo]))).filter(|&n| n > 0),
            (Self::Rtcm3, &[hi, lo]) if hi & 0xFC == 0 => Some(usize::from(u16::from_be_bytes([hi, lo]))),
            _ => None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Between sentences.
    Idle,
    /// Inside a `#` comment line.
    Comment,
    /// Collecting a sentence into the buffer.
    Line,
    /// After an overlong line: discard until the end of the line.
    Discard,
    /// Saw the first of two sync bytes (UBX 0xB5, `SiRF` and `SkyTraq` 0xA0, CASIC 0xBA).
    Sync(Proto),
    /// Collecting a binary frame after its sync bytes into `bin`: the header, then payload and trailer.
    /// `total` is the frame's length after the sync bytes, known once the header is in (0 before).
    Binary { proto: Proto, total: usize },
}

/// The framer: feed bytes, get checksum-verified [`Frame`]s.
#[derive(Debug, Clone)]
pub struct Framer {
    state: State,
    buf: Vec<u8>,
    /// The binary frame being collected (after its sync bytes).
    bin: Vec<u8>,
    /// Bytes of a rejected binary frame still to be scanned again.
    rescan: Option<Vec<u8>>,
    /// Scanning such bytes: a `#` there is binary, not the start of a log's comment line (which would
    /// hide everything up to the next line end).
    rescanning: bool,
    at_line_start: bool,
    stats: DecodeStats,
    /// Watches the bytes for binary protocols we do not decode.
    detector: super::binary_detect::Detector,
}

impl Default for Framer {
    /// A framer without a preallocated buffer (cheap to create as a placeholder).
    fn default() -> Self {
        Self {
            state: State::Idle,
            buf: Vec::new(),
            bin: Vec::new(),
            rescan: None,
            rescanning: false,
            at_line_start: true,
            stats: DecodeStats::default(),
            detector: super::binary_detect::Detector::default(),
        }
    }
}

impl Framer {
    /// A framer waiting for the first sentence.
    pub fn new() -> Self {
        Self { buf: Vec::with_capacity(MAX_SENTENCE_LEN), ..Self::default() }
    }

    /// The counts so far.
    pub fn stats(&self) -> &DecodeStats {
        &self.stats
    }

    /// Feeds bytes; calls `on_frame` with each sentence or binary frame whose checksum is correct.
    pub fn feed(&mut self, data: &[u8], mut on_frame: impl FnMut(Frame<'_>, &mut DecodeStats)) {
        self.stats.bytes += data.len() as u64;
        if self.stats.undecoded_protocol.is_none() {
            self.stats.undecoded_protocol = self.detector.feed(data);
        }
        let mut i = 0;
        while i < data.len() {
            i += self.scan(data.get(i..).unwrap_or_default(), &mut on_frame);
            self.drain_rescan(&mut on_frame);
        }
    }

    /// Scans the bytes of rejected frames again until none is left (each rescan is shorter than the frame
    /// it comes from, so this ends).
    fn drain_rescan(&mut self, on_frame: &mut impl FnMut(Frame<'_>, &mut DecodeStats)) {
        while let Some(bytes) = self.rescan.take() {
            self.rescanning = true;
            let n = self.scan(&bytes, on_frame);
            self.rescanning = false;
            if let Some(mut again) = self.rescan.take() {
                // A frame inside the rescanned bytes failed too: its bytes, then the rest of these.
                again.extend_from_slice(bytes.get(n..).unwrap_or_default());
                self.rescan = Some(again);
            }
        }
    }

    /// Runs the state machine over `data` until its end or until a binary frame is rejected (then
    /// `self.rescan` is set); returns the bytes consumed.
    fn scan(&mut self, data: &[u8], on_frame: &mut impl FnMut(Frame<'_>, &mut DecodeStats)) -> usize {
        let mut i = 0;
        while i < data.len() && self.rescan.is_none() {
            let rest = data.get(i..).unwrap_or_default();
            // Fast paths: copy binary payloads and runs of plain sentence characters in bulk.
            match self.state {
                State::Binary { proto, total } if total > 0 => {
                    let k = (total - self.bin.len()).min(rest.len());
                    self.bin.extend_from_slice(rest.get(..k).unwrap_or_default());
                    i += k;
                    if self.bin.len() == total {
                        self.end_binary(proto, on_frame);
                    }
                    continue;
                }
                State::Line => {
                    let run = rest
                        .iter()
                        .position(|&b| !(0x20..=0x7e).contains(&b) || b == b'$' || b == b'!')
                        .unwrap_or(rest.len());
                    if run > 0 {
                        if self.buf.len() + run > MAX_SENTENCE_LEN {
                            self.stats.overlong += 1;
                            self.stats.junk_bytes += run as u64;
                            self.buf.clear();
                            self.state = State::Discard;
                        } else {
                            self.buf.extend_from_slice(rest.get(..run).unwrap_or_default());
                        }
                        i += run;
                        continue;
                    }
                }
                _ => {}
            }
            if let Some(&b) = rest.first() {
                self.step(b, on_frame);
            }
            i += 1;
        }
        i
    }

    /// Ends the stream: a sentence still being collected without its line end is handed out if its
    /// checksum is correct; a binary frame still being collected is rejected and its bytes scanned again.
    pub fn finish(&mut self, mut on_frame: impl FnMut(Frame<'_>, &mut DecodeStats)) {
        while let State::Binary { proto, .. } = self.state {
            self.reject_binary(proto);
            self.drain_rescan(&mut on_frame);
        }
        if self.state == State::Line {
            // A complete sentence without its CR LF at the very end of a file is still a sentence.
            self.end_line(&mut on_frame);
        }
        self.state = State::Idle;
    }

    fn step(&mut self, b: u8, on_frame: &mut impl FnMut(Frame<'_>, &mut DecodeStats)) {
        match self.state {
            State::Idle => self.idle(b),
            State::Comment => {
                if b == b'\n' || b == b'\r' {
                    self.state = State::Idle;
                    self.at_line_start = true;
                }
            }
            State::Line => match b {
                b'\r' | b'\n' => {
                    self.end_line(on_frame);
                    self.state = State::Idle;
                    self.at_line_start = true;
                }
                b'$' | b'!' => {
                    // A start character right after another (`$$GPGGA…`, as the ST Teseo LIV4F sends) is a
                    // doubled start, not a sentence cut short: nothing is lost, so nothing is counted.
                    if self.buf.len() > 1 {
                        self.stats.truncated += 1;
                    }
                    self.start_line(b);
                }
                0x20..=0x7e => {
                    if self.buf.len() >= MAX_SENTENCE_LEN {
                        self.stats.overlong += 1;
                        self.buf.clear();
                        self.state = State::Discard;
                    } else {
                        self.buf.push(b);
                    }
                }
                _ => {
                    self.stats.truncated += 1;
                    self.buf.clear();
                    self.state = State::Idle;
                    self.idle(b);
                }
            },
            State::Discard => match b {
                b'\r' | b'\n' => {
                    self.state = State::Idle;
                    self.at_line_start = true;
                }
                b'$' | b'!' => self.start_line(b),
                _ => self.stats.junk_bytes += 1,
            },
            State::Sync(proto) => {
                // `SiRF` and `SkyTraq` share the first byte (0xA0): the second tells them apart.
                let (second, proto) = match proto {
                    Proto::Sirf if b == skytraq::START[1] => (b, Proto::SkyTraq),
                    Proto::Sirf => (sirf::START[1], proto),
                    Proto::Casic => (casic::SYNC[1], proto),
                    Proto::SkyTraq => (skytraq::START[1], proto),
                    Proto::Ubx | Proto::Rtcm3 => (ubx::SYNC_2, proto),
                };
                if b == second {
                    self.bin.clear();
                    self.state = State::Binary { proto, total: 0 };
                } else {
                    self.stats.junk_bytes += 1;
                    self.state = State::Idle;
                    self.idle(b);
                }
            }
            State::Binary { proto, total } => {
                if proto == Proto::Rtcm3 && self.bin.is_empty() && b & 0xFC != 0 {
                    // Reserved bits set: the 0xD3 was a stray byte, not a preamble (not counted as a frame).
                    self.stats.junk_bytes += 1;
                    self.state = State::Idle;
                    self.idle(b);
                    return;
                }
                // Only the header is collected byte by byte (the body takes the fast path).
                self.bin.push(b);
                if total == 0 && self.bin.len() == proto.header_len() {
                    match proto.payload_len(&self.bin).filter(|&n| n <= MAX_BINARY_PAYLOAD) {
                        Some(len) => {
                            self.state = State::Binary {
                                proto,
                                total: proto.header_len() + len + proto.trailer_len(),
                            };
                        }
                        None => self.reject_binary(proto),
                    }
                }
            }
        }
    }

    fn idle(&mut self, b: u8) {
        match b {
            b'$' | b'!' => self.start_line(b),
            b'\r' | b'\n' => self.at_line_start = true,
            b'#' if self.at_line_start && !self.rescanning => {
                self.stats.comment_lines += 1;
                self.state = State::Comment;
            }
            ubx::SYNC_1 => self.state = State::Sync(Proto::Ubx),
            0xA0 => self.state = State::Sync(Proto::Sirf),
            casic::SYNC_1 => self.state = State::Sync(Proto::Casic),
            rtcm3::PREAMBLE => {
                self.bin.clear();
                self.state = State::Binary { proto: Proto::Rtcm3, total: 0 };
            }
            _ => {
                self.stats.junk_bytes += 1;
                self.at_line_start = false;
            }
        }
    }

    /// A complete binary frame is in `bin`: hand it out if its checksum (and `SiRF` end) is right.
    fn end_binary(&mut self, proto: Proto, on_frame: &mut impl FnMut(Frame<'_>, &mut DecodeStats)) {
        let frame = match (proto, self.bin.as_slice()) {
            (Proto::Sirf, [_, _, payload @ .., ck_hi, ck_lo, e0, e1]) => ([*e0, *e1] == sirf::END
                && sirf::checksum(payload) == u16::from_be_bytes([*ck_hi, *ck_lo]))
            .then_some(Frame::Sirf { payload }),
            (Proto::Ubx, [class, id, _, _, payload @ .., a, b]) => (ubx::checksum(*class, *id, payload)
                == (*a, *b))
                .then_some(Frame::Ubx { class: *class, id: *id, payload }),
            (Proto::Casic, [_, _, class, id, payload @ .., c0, c1, c2, c3]) => {
                (casic::checksum(*class, *id, payload) == u32::from_le_bytes([*c0, *c1, *c2, *c3]))
                    .then_some(Frame::Casic { class: *class, id: *id, payload })
            }
            (Proto::SkyTraq, [_, _, payload @ .., cs, e0, e1]) => ([*e0, *e1] == skytraq::END
                && skytraq::checksum(payload) == *cs)
                .then_some(Frame::SkyTraq { payload }),
            (Proto::Rtcm3, [h0, h1, payload @ .., c0, c1, c2]) => {
                let mut crc = rtcm3::CRC24Q.digest();
                crc.update(&[rtcm3::PREAMBLE, *h0, *h1]);
                crc.update(payload);
                (crc.finalize() == u32::from_be_bytes([0, *c0, *c1, *c2])).then_some(Frame::Rtcm3 { payload })
            }
            _ => None,
        };
        let Some(frame) = frame else {
            self.reject_binary(proto);
            return;
        };
        match frame {
            Frame::Sirf { .. } => self.stats.sirf_frames += 1,
            Frame::Ubx { .. } => self.stats.ubx_frames += 1,
            Frame::Casic { .. } => self.stats.casic_frames += 1,
            Frame::SkyTraq { .. } => self.stats.skytraq_frames += 1,
            Frame::Rtcm3 { .. } => self.stats.rtcm3_frames += 1,
            Frame::Nmea(_) => {}
        }
        on_frame(frame, &mut self.stats);
        self.state = State::Idle;
        self.at_line_start = true;
    }

    /// Rejects the binary frame being collected: counted, its sync bytes are junk, the bytes after them
    /// are scanned again.
    fn reject_binary(&mut self, proto: Proto) {
        self.stats.binary_bad_checksum += 1;
        self.stats.junk_bytes += proto.sync_len() as u64;
        self.state = State::Idle;
        self.at_line_start = false;
        let bytes = std::mem::take(&mut self.bin);
        self.rescan = Some(bytes);
    }

    fn start_line(&mut self, b: u8) {
        self.buf.clear();
        self.buf.push(b);
        self.state = State::Line;
        self.at_line_start = false;
    }

    fn end_line(&mut self, on_frame: &mut impl FnMut(Frame<'_>, &mut DecodeStats)) {
        // Trailing blanks after the checksum are tolerated (some receivers pad).
        while self.buf.last() == Some(&b' ') {
            self.buf.pop();
        }
        match check(&self.buf) {
            Checked::Ok => {
                self.stats.sentences += 1;
                // The line only holds printable ASCII (checked byte by byte), so this cannot fail.
                if let Ok(s) = std::str::from_utf8(&self.buf) {
                    on_frame(Frame::Nmea(s), &mut self.stats);
                }
            }
            Checked::Bad => self.stats.bad_checksum += 1,
            Checked::Missing => {
                if self.buf.len() <= 1 {
                    self.stats.truncated += 1;
                } else {
                    self.stats.missing_checksum += 1;
                }
            }
        }
        self.buf.clear();
    }
}

enum Checked {
    Ok,
    Bad,
    Missing,
}

/// NMEA checksum: XOR of every byte between the start character and `*`, sent as two hex digits.
pub fn nmea_checksum(body: &[u8]) -> u8 {
    body.iter().fold(0, |acc, &b| acc ^ b)
}

fn check(line: &[u8]) -> Checked {
    let n = line.len();
    if n < 4 || line[n - 3] != b'*' {
        return Checked::Missing;
    }
    let (Some(hi), Some(lo)) = (hex(line[n - 2]), hex(line[n - 1])) else {
        return Checked::Missing;
    };
    if nmea_checksum(&line[1..n - 3]) == (hi << 4) | lo { Checked::Ok } else { Checked::Bad }
}

fn hex(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'A'..=b'F' => Some(b - b'A' + 10),
        b'a'..=b'f' => Some(b - b'a' + 10),
        _ => None,
    }
}

/// Wraps a sentence body (the part between `$` and `*`, e.g. `GPGGA,...`) into a full sentence with its
/// checksum and CR LF.
pub fn with_checksum(body: &str) -> String {
    format!("${body}*{:02X}\r\n", nmea_checksum(body.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(data: &[u8]) -> (Vec<String>, DecodeStats) {
        let (items, stats) = frames(data);
        (items.into_iter().filter_map(|i| i.strip_prefix("NMEA ").map(str::to_owned)).collect(), stats)
    }

    /// Every item, as text: `NMEA $...`, `UBX class id payload-hex`, `SiRF payload-hex`.
    fn frames(data: &[u8]) -> (Vec<String>, DecodeStats) {
        let mut f = Framer::new();
        let mut out = Vec::new();
        let mut push = |fr: Frame<'_>, _: &mut DecodeStats| out.push(describe(fr));
        f.feed(data, &mut push);
        f.finish(&mut push);
        (out, *f.stats())
    }

    fn describe(fr: Frame<'_>) -> String {
        let hex = |p: &[u8]| {
            p.iter().fold(String::new(), |mut s, b| {
                let _ = std::fmt::Write::write_fmt(&mut s, format_args!("{b:02x}"));
                s
            })
        };
        match fr {
            Frame::Nmea(s) => format!("NMEA {s}"),
            Frame::Ubx { class, id, payload } => format!("UBX {class:02x} {id:02x} {}", hex(payload)),
            Frame::Sirf { payload } => format!("SiRF {}", hex(payload)),
            Frame::Casic { class, id, payload } => format!("CASIC {class:02x} {id:02x} {}", hex(payload)),
            Frame::SkyTraq { payload } => format!("SkyTraq {}", hex(payload)),
            Frame::Rtcm3 { payload } => format!("RTCM3 {}", hex(payload)),
        }
    }

    const GGA: &str = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77";

    #[test]
    fn accepts_a_good_sentence() {
        let (s, st) = frame(format!("{GGA}\r\n").as_bytes());
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.sentences, 1);
        assert_eq!(st.rejected(), 0);
    }

    #[test]
    fn resyncs_on_dollar_mid_line() {
        let (s, st) = frame(format!("$GPGGA,030130{GGA}\r\n").as_bytes());
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.truncated, 1);
    }

    #[test]
    fn a_doubled_start_character_is_no_truncated_sentence() {
        let (s, st) = frame(format!("${GGA}\r\n").as_bytes());
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.truncated, 0);
        assert_eq!(st.rejected(), 0);
    }

    #[test]
    fn rejects_bad_and_missing_checksums() {
        let bad = GGA.replace("*77", "*78");
        let none = GGA.trim_end_matches("*77");
        let (s, st) = frame(format!("{bad}\r\n{none}\r\n{GGA}\n").as_bytes());
        assert_eq!(s.len(), 1);
        assert_eq!(st.bad_checksum, 1);
        assert_eq!(st.missing_checksum, 1);
    }

    #[test]
    fn binary_frames_with_dollars_inside_are_handed_out_whole() {
        let mut data = ubx::frame(0x01, 0x07, b"$GP$*");
        data.extend_from_slice(&sirf::frame(b"$$"));
        data.extend_from_slice(format!("{GGA}\r\n").as_bytes());
        let (items, st) = frames(&data);
        assert_eq!(items, ["UBX 01 07 244750242a", "SiRF 2424", &format!("NMEA {GGA}")]);
        assert_eq!((st.ubx_frames, st.sirf_frames, st.sentences), (1, 1, 1));
        assert_eq!(st.rejected(), 0);
    }

    #[test]
    fn a_bad_binary_checksum_is_counted_and_hides_nothing() {
        // A UBX frame whose checksum is wrong, with a whole sentence inside its payload: the frame is
        // rejected and the sentence behind its sync bytes comes out.
        let mut bad = ubx::frame(0x01, 0x07, format!("{GGA}\r\n").as_bytes());
        let n = bad.len();
        bad[n - 1] ^= 0xFF;
        let mut sirf_bad = sirf::frame(b"\x29\x00");
        let m = sirf_bad.len();
        sirf_bad[m - 1] = 0x00; // end sequence B0 00
        let mut data = bad;
        data.extend_from_slice(&sirf_bad);
        data.extend_from_slice(format!("{GGA}\r\n").as_bytes());
        let (s, st) = frame(&data);
        assert_eq!(s, vec![GGA.to_owned(), GGA.to_owned()]);
        assert_eq!(st.binary_bad_checksum, 2);
        assert_eq!(st.ubx_frames + st.sirf_frames, 0);
    }

    #[test]
    fn a_false_sync_with_a_huge_length_hides_nothing() {
        // B5 62 in line noise followed by a length of 8000: the sentences in the next 8000 bytes would
        // be swallowed if the framer trusted the length; the stream ends inside the false frame.
        let mut data = vec![0xB5, 0x62, 0x01, 0x07, 0x40, 0x1F];
        data.extend_from_slice(format!("{GGA}\r\n{GGA}\r\n").as_bytes());
        let (s, st) = frame(&data);
        assert_eq!(s, vec![GGA.to_owned(), GGA.to_owned()]);
        assert_eq!(st.binary_bad_checksum, 1);
        // A length beyond MAX_BINARY_PAYLOAD is refused at once.
        let mut data = vec![0xA0, 0xA2, 0x7F, 0xFF];
        data.extend_from_slice(format!("{GGA}\r\n").as_bytes());
        let (s, st) = frame(&data);
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.binary_bad_checksum, 1);
    }

    #[test]
    fn nul_and_ansi_truncate() {
        let (s, st) = frame(format!("$GPGSA,A,3\x1b[0m,,\r\n$GPGGA\0\0{GGA}\r\n").as_bytes());
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.truncated, 2);
    }

    #[test]
    fn overlong_lines_are_dropped() {
        let long = format!("$GPTXT,{}*00\r\n{GGA}\r\n", "A".repeat(400));
        let (s, st) = frame(long.as_bytes());
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.overlong, 1);
    }

    #[test]
    fn comments_are_skipped() {
        let (s, st) = frame(format!("# Name: x $GPGGA,1*00\n{GGA}\n").as_bytes());
        assert_eq!(s.len(), 1);
        assert_eq!(st.comment_lines, 1);
        assert_eq!(st.rejected(), 0);
    }

    #[test]
    fn checksum_helper_matches_known_sentence() {
        let body = &GGA[1..GGA.len() - 3];
        assert_eq!(with_checksum(body), format!("{GGA}\r\n"));
    }
}
