//! Byte stream to checksummed NMEA sentences: resynchronisation, binary frames, junk, limits.
//!
//! The framer is a small state machine fed arbitrary bytes. It hands out each sentence whose
//! `*hh` checksum is correct and counts everything it throws away, by reason ([`DecodeStats`]):
//! - a `$` (or `!`) in the middle of a line starts a new sentence; the interrupted one is counted as
//!   truncated (gpsd does the same; the Triton 400 log has `$GPGGA,030130$GPGLL,...`);
//! - a control or non-ASCII byte (NUL, ANSI escape, binary) inside a line truncates it;
//! - u-blox UBX (`B5 62 class id len16le payload ck_a ck_b`) and `SiRF` binary
//!   (`A0 A2 len16be payload ck16 B0 B3`) frames outside a line are skipped whole, by their length field,
//!   so a `$` inside their payload cannot start a false sentence;
//! - lines longer than [`MAX_SENTENCE_LEN`] are dropped (NMEA 0183 allows 82 characters; real receivers
//!   send up to ~100, `SkyTraq`'s PSTI is the record holder, so we accept twice the standard);
//! - sentences without a checksum, or with a wrong one, are rejected (gpsd rejects them too);
//! - lines starting with `#` are comments (gpsd's test logs) and are skipped, not counted as errors.

/// Longest sentence accepted, `$` to the last checksum digit: twice NMEA's 82 (which includes CR LF).
pub const MAX_SENTENCE_LEN: usize = 164;
/// Longest binary frame payload skipped as a frame; a longer length field means the sync bytes were junk.
const MAX_BINARY_PAYLOAD: usize = 8192;

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
    /// UBX or `SiRF` binary frames skipped.
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
}

impl DecodeStats {
    /// All rejected sentences: bad or missing checksum, overlong, truncated, malformed.
    pub fn rejected(&self) -> u64 {
        self.bad_checksum + self.missing_checksum + self.overlong + self.truncated + self.malformed
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
    }
}

impl std::fmt::Display for DecodeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} bytes, {} sentences, {} epochs, {} marks; rejected {} (bad checksum {}, no checksum {}, \
             truncated {}, overlong {}, malformed {}); ignored: {} unsupported sentences, {} binary frames, \
             {} junk bytes, {} comment lines; removed from fixes: {} invalid positions, {} implausible values",
            self.bytes,
            self.sentences,
            self.epochs,
            self.marks,
            self.rejected(),
            self.bad_checksum,
            self.missing_checksum,
            self.truncated,
            self.overlong,
            self.malformed,
            self.unsupported,
            self.binary_frames,
            self.junk_bytes,
            self.comment_lines,
            self.invalid_positions,
            self.implausible_values
        )
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
    /// Saw 0xB5 (UBX sync 1).
    UbxSync,
    /// Saw 0xA0 (`SiRF` sync 1).
    SirfSync,
    /// Reading a binary header (UBX: class, id, len16le; `SiRF`: len16be).
    BinHeader { sirf: bool, got: u8 },
    /// Skipping this many more bytes of a binary frame.
    Skip(usize),
}

/// The NMEA framer: feed bytes, get checksum-verified sentences (without CR LF).
#[derive(Debug, Clone)]
pub struct Framer {
    state: State,
    buf: Vec<u8>,
    header: [u8; 4],
    at_line_start: bool,
    stats: DecodeStats,
}

impl Default for Framer {
    /// A framer without a preallocated buffer (cheap to create as a placeholder).
    fn default() -> Self {
        Self {
            state: State::Idle,
            buf: Vec::new(),
            header: [0; 4],
            at_line_start: true,
            stats: DecodeStats::default(),
        }
    }
}

impl Framer {
    /// A framer waiting for the first sentence.
    pub fn new() -> Self {
        Self {
            state: State::Idle,
            buf: Vec::with_capacity(MAX_SENTENCE_LEN),
            header: [0; 4],
            at_line_start: true,
            stats: DecodeStats::default(),
        }
    }

    /// The counts so far.
    pub fn stats(&self) -> &DecodeStats {
        &self.stats
    }

    /// Feeds bytes; calls `on_sentence` with each sentence whose checksum is correct, e.g.
    /// `$GPGGA,...*47` (ASCII, `$` or `!` first, checksum digits last).
    pub fn feed(&mut self, data: &[u8], mut on_sentence: impl FnMut(&str, &mut DecodeStats)) {
        self.stats.bytes += data.len() as u64;
        let mut i = 0;
        while i < data.len() {
            // Fast paths: skip binary payloads and copy runs of plain sentence characters in bulk.
            match self.state {
                State::Skip(n) => {
                    let k = n.min(data.len() - i);
                    i += k;
                    if n == k {
                        self.state = State::Idle;
                        self.at_line_start = true;
                    } else {
                        self.state = State::Skip(n - k);
                    }
                    continue;
                }
                State::Line => {
                    let rest = &data[i..];
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
                            self.buf.extend_from_slice(&rest[..run]);
                        }
                        i += run;
                        continue;
                    }
                }
                _ => {}
            }
            self.step(data[i], &mut on_sentence);
            i += 1;
        }
    }

    /// Ends the stream: a sentence still being collected has no line end and is counted as truncated.
    pub fn finish(&mut self, mut on_sentence: impl FnMut(&str, &mut DecodeStats)) {
        if self.state == State::Line {
            // A complete sentence without its CR LF at the very end of a file is still a sentence.
            self.end_line(&mut on_sentence);
        }
        self.state = State::Idle;
    }

    fn step(&mut self, b: u8, on_sentence: &mut impl FnMut(&str, &mut DecodeStats)) {
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
                    self.end_line(on_sentence);
                    self.state = State::Idle;
                    self.at_line_start = true;
                }
                b'$' | b'!' => {
                    self.stats.truncated += 1;
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
            State::UbxSync => {
                if b == 0x62 {
                    self.state = State::BinHeader { sirf: false, got: 0 };
                } else {
                    self.stats.junk_bytes += 1;
                    self.state = State::Idle;
                    self.idle(b);
                }
            }
            State::SirfSync => {
                if b == 0xA2 {
                    self.state = State::BinHeader { sirf: true, got: 0 };
                } else {
                    self.stats.junk_bytes += 1;
                    self.state = State::Idle;
                    self.idle(b);
                }
            }
            State::BinHeader { sirf, got } => {
                self.header[usize::from(got)] = b;
                let got = got + 1;
                let need = if sirf { 2 } else { 4 };
                if got < need {
                    self.state = State::BinHeader { sirf, got };
                    return;
                }
                let (len, trailer) = if sirf {
                    (usize::from(u16::from_be_bytes([self.header[0], self.header[1]]) & 0x7fff), 4)
                } else {
                    (usize::from(u16::from_le_bytes([self.header[2], self.header[3]])), 2)
                };
                if len > MAX_BINARY_PAYLOAD {
                    self.stats.junk_bytes += u64::from(got) + 2;
                    self.state = State::Idle;
                } else {
                    self.stats.binary_frames += 1;
                    self.state = State::Skip(len + trailer);
                }
            }
            State::Skip(n) => {
                self.state = if n <= 1 { State::Idle } else { State::Skip(n - 1) };
                if n <= 1 {
                    self.at_line_start = true;
                }
            }
        }
    }

    fn idle(&mut self, b: u8) {
        match b {
            b'$' | b'!' => self.start_line(b),
            b'\r' | b'\n' => self.at_line_start = true,
            b'#' if self.at_line_start => {
                self.stats.comment_lines += 1;
                self.state = State::Comment;
            }
            0xB5 => self.state = State::UbxSync,
            0xA0 => self.state = State::SirfSync,
            _ => {
                self.stats.junk_bytes += 1;
                self.at_line_start = false;
            }
        }
    }

    fn start_line(&mut self, b: u8) {
        self.buf.clear();
        self.buf.push(b);
        self.state = State::Line;
        self.at_line_start = false;
    }

    fn end_line(&mut self, on_sentence: &mut impl FnMut(&str, &mut DecodeStats)) {
        // Trailing blanks after the checksum are tolerated (some receivers pad).
        while self.buf.last() == Some(&b' ') {
            self.buf.pop();
        }
        match check(&self.buf) {
            Checked::Ok => {
                self.stats.sentences += 1;
                // The line only holds printable ASCII (checked byte by byte), so this cannot fail.
                if let Ok(s) = std::str::from_utf8(&self.buf) {
                    on_sentence(s, &mut self.stats);
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
        let mut f = Framer::new();
        let mut out = Vec::new();
        f.feed(data, |s, _| out.push(s.to_owned()));
        f.finish(|s, _| out.push(s.to_owned()));
        (out, *f.stats())
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
    fn rejects_bad_and_missing_checksums() {
        let bad = GGA.replace("*77", "*78");
        let none = GGA.trim_end_matches("*77");
        let (s, st) = frame(format!("{bad}\r\n{none}\r\n{GGA}\n").as_bytes());
        assert_eq!(s.len(), 1);
        assert_eq!(st.bad_checksum, 1);
        assert_eq!(st.missing_checksum, 1);
    }

    #[test]
    fn skips_binary_frames_with_dollars_inside() {
        let mut data = vec![0xB5, 0x62, 0x01, 0x07, 0x05, 0x00, b'$', b'G', b'P', b'$', b'*', 0xAA, 0xBB];
        data.extend_from_slice(&[0xA0, 0xA2, 0x00, 0x02, b'$', b'$', 0x00, 0x00, 0xB0, 0xB3]);
        data.extend_from_slice(format!("{GGA}\r\n").as_bytes());
        let (s, st) = frame(&data);
        assert_eq!(s, vec![GGA.to_owned()]);
        assert_eq!(st.binary_frames, 2);
        assert_eq!(st.rejected(), 0);
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
