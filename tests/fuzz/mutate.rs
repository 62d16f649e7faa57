//! Byte-level mutations of real inputs (AFL/libFuzzer's classic set, plus text-protocol ones: long fields,
//! long lines, extreme numbers, line shuffles and splices), and helpers to keep mutated NMEA checksummed
//! so that hostile field values get past the framer into the sentence parser.

use crate::harness::Rng;

/// Numbers that break naive parsers and range checks.
pub const EXTREME_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-0.0",
    "1e308",
    "-1e308",
    "1e309",
    "-1e15",
    "1e15",
    "5e-324",
    "1e-320",
    "2.2250738585072014e-308",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "Infinity",
    "18446744073709551615",
    "18446744073709551616",
    "-9223372036854775808",
    "4294967295",
    "4294967296",
    "65535",
    "65536",
    "99999999999999999999999999999999",
    "9999.9999",
    "-9999.9999",
    "91",
    "-91",
    "90.0000001",
    "181",
    "-180.0000001",
    "360",
    "720",
    "-1",
    ".",
    "-",
    "+",
    "e",
    "1e",
    "0x10",
    "1.2.3",
    "٣",
    "",
];

/// Tokens spliced into text inputs.
const TOKENS: &[&[u8]] = &[
    b"\r\n",
    b"\n",
    b"\r",
    b",",
    b",,,,,,,,,,",
    b"*",
    b"$",
    b"!",
    b"#",
    b"$GPGGA,",
    b"$GPRMC,",
    b"$GPGSV,",
    b"$GPGSA,",
    b"$GNGNS,",
    b"$GPGST,",
    b"$PGRME,",
    b"$PVNAV,MARK,",
    b"$PVNAV,TS,",
    b"*00",
    b"*FF",
    b"\x00",
    b"\xff",
    b"\xb5\x62",
    b"\xa0\xa2",
    b"\"",
    b"{",
    b"}",
    b"[",
    b"]",
    b":",
    b"null",
    b"true",
    b"<",
    b">",
    b"</",
    b"/>",
    b"&amp;",
    b"&#0;",
    b"&#x10FFFF;",
    b"<![CDATA[",
    b"]]>",
    b"<!--",
    b"-->",
    b"=\"",
    b"\xc3\x28",
    b"\xed\xa0\x80",
    b"\xf4\x90\x80\x80",
    b"\xe2\x80\xae",
    b" ",
    b"\t",
    b";",
];

/// What long fields are made of.
const UNITS: [&[u8]; 8] = [b"9", b",", b"A", b"1,", b"\xff", b"0.", b" ", b"\"a\","];

/// Single bytes that matter to the formats.
const BYTES: &[u8] = &[
    0, 0xff, 0x7f, 0x80, b'$', b'!', b'*', b',', b'\r', b'\n', b'#', b'.', b'-', b'9', b'0', b'A', b'V',
    b'N', b'S', b'E', b'W', 0xb5, 0x62, 0xa0, 0xa2, b'"', b'{', b'<', b'>', b'\\', b' ',
];

/// Applies `rounds` random mutations to `data`, keeping it at most `max_len` bytes long; `others` are
/// inputs to splice from.
pub fn mutate(rng: &mut Rng, data: &mut Vec<u8>, others: &[&[u8]], rounds: usize, max_len: usize) {
    for _ in 0..rounds {
        mutate_once(rng, data, others, max_len);
        if data.len() > max_len {
            data.truncate(max_len);
        }
    }
}

fn range(rng: &mut Rng, len: usize, max: usize) -> (usize, usize) {
    let start = rng.below(len + 1);
    let n = rng.size(max.min(len - start));
    (start, start + n)
}

#[allow(clippy::too_many_lines)]
fn mutate_once(rng: &mut Rng, d: &mut Vec<u8>, others: &[&[u8]], max_len: usize) {
    let len = d.len();
    match rng.below(17) {
        // Bit flips.
        0 if len > 0 => {
            for _ in 0..=rng.size(8) {
                let i = rng.below(len);
                d[i] ^= 1 << rng.below(8);
            }
        }
        // A random or interesting byte.
        1 if len > 0 => {
            let i = rng.below(len);
            d[i] = if rng.chance(0.5) { rng.byte() } else { *rng.pick(BYTES) };
        }
        // Insert random bytes.
        2 => {
            let at = rng.below(len + 1);
            let n = rng.size(64);
            let b = rng.bytes(n);
            d.splice(at..at, b);
        }
        // Delete a range.
        3 if len > 0 => {
            let (a, b) = range(rng, len, 256);
            d.drain(a..b);
        }
        // Duplicate a chunk somewhere (or right after itself, several times).
        4 if len > 0 => {
            let (a, b) = range(rng, len, 512);
            let chunk = d[a..b].to_vec();
            let at = if rng.chance(0.5) { b } else { rng.below(len + 1) };
            for _ in 0..=rng.size(16) {
                d.splice(at..at, chunk.iter().copied());
                if d.len() > max_len {
                    break;
                }
            }
        }
        // Swap two chunks.
        5 if len > 1 => {
            let (a, b) = range(rng, len / 2, 256);
            let (c, e) = range(rng, len - len / 2, 256);
            let (c, e) = (c + len / 2, e + len / 2);
            let first = d[a..b].to_vec();
            let second = d[c..e].to_vec();
            d.splice(c..e, first);
            d.splice(a..b, second);
        }
        // Shuffle some lines.
        6 => shuffle_lines(rng, d),
        // Splice another input in: its tail replaces ours, or a chunk of it is inserted.
        7 if !others.is_empty() => {
            let o = *rng.pick(others);
            if o.is_empty() {
                return;
            }
            let (a, b) = range(rng, o.len(), 4096);
            if rng.chance(0.5) {
                let at = rng.below(len + 1);
                d.truncate(at);
                d.extend_from_slice(&o[a..]);
            } else {
                let at = rng.below(len + 1);
                d.splice(at..at, o[a..b].iter().copied());
            }
        }
        // Truncate.
        8 if len > 0 => d.truncate(rng.below(len)),
        // A very long field or line.
        9 => {
            let at = rng.below(len + 1);
            let unit = *rng.pick(&UNITS);
            let n = rng.size(max_len.min(200_000) / unit.len().max(1));
            let run: Vec<u8> = unit.iter().copied().cycle().take(n * unit.len()).collect();
            d.splice(at..at, run);
        }
        // Binary garbage or NUL runs.
        10 => {
            let at = rng.below(len + 1);
            let n = rng.size(4096);
            let run = if rng.chance(0.3) { vec![0; n] } else { rng.bytes(n) };
            d.splice(at..at, run);
        }
        // A token.
        11 => {
            let at = rng.below(len + 1);
            let t = rng.pick(TOKENS);
            d.splice(at..at, t.iter().copied());
        }
        // Replace a number with an extreme one.
        12 | 13 => replace_number(rng, d),
        // Repeat one line many times.
        14 if len > 0 => {
            let i = rng.below(len);
            let s = d[..i].iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
            let e = d[i..].iter().position(|&b| b == b'\n').map_or(len, |p| i + p + 1);
            let line = d[s..e].to_vec();
            for _ in 0..rng.size(2000) {
                if d.len() + line.len() > max_len {
                    break;
                }
                d.splice(e..e, line.iter().copied());
            }
        }
        // Replace a byte by its neighbour value (off by one in a digit or a delimiter).
        15 if len > 0 => {
            let i = rng.below(len);
            d[i] = if rng.chance(0.5) { d[i].wrapping_add(1) } else { d[i].wrapping_sub(1) };
        }
        // Drop a line ending or a whole line.
        _ if len > 0 => {
            let i = rng.below(len);
            if let Some(p) = d[i..].iter().position(|&b| b == b'\n') {
                if rng.chance(0.5) {
                    d.remove(i + p);
                } else {
                    let s = d[..i].iter().rposition(|&b| b == b'\n').map_or(0, |q| q + 1);
                    d.drain(s..=i + p);
                }
            }
        }
        _ => {}
    }
}

/// Shuffles a few of the lines (reorders epochs and records).
fn shuffle_lines(rng: &mut Rng, d: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = d.split_inclusive(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
    if lines.len() < 2 {
        return;
    }
    for _ in 0..=rng.size(lines.len()) {
        let (a, b) = (rng.below(lines.len()), rng.below(lines.len()));
        lines.swap(a, b);
    }
    *d = lines.concat();
}

/// Replaces a run of digits (with sign and dot) by an extreme number.
fn replace_number(rng: &mut Rng, d: &mut Vec<u8>) {
    if d.is_empty() {
        return;
    }
    let from = rng.below(d.len());
    let Some(s) = d[from..].iter().position(u8::is_ascii_digit).map(|p| from + p) else {
        return;
    };
    let is_num = |b: &u8| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E');
    let s = d[..s].iter().rposition(|b| !is_num(b)).map_or(0, |p| p + 1);
    let e = d[s..].iter().position(|b| !is_num(b)).map_or(d.len(), |p| s + p);
    let with: Vec<u8> = if rng.chance(0.15) {
        "9".repeat(rng.size(5000)).into_bytes()
    } else {
        rng.pick(EXTREME_NUMBERS).as_bytes().to_vec()
    };
    d.splice(s..e, with);
}

/// XOR of the bytes between `$`/`!` and `*` (NMEA 0183).
pub fn nmea_xor(body: &[u8]) -> u8 {
    body.iter().fold(0, |a, b| a ^ b)
}

/// Recomputes the `*hh` checksum of every line that looks like a sentence, so mutated sentences reach the
/// sentence parser instead of being rejected by the framer.
pub fn fix_checksums(d: &mut [u8]) {
    let mut start = 0;
    while start < d.len() {
        let end = d[start..].iter().position(|&b| b == b'\n' || b == b'\r').map_or(d.len(), |p| start + p);
        let line = &d[start..end];
        if let Some(dollar) = line.iter().rposition(|&b| b == b'$' || b == b'!')
            && let Some(star) = line[dollar..].iter().position(|&b| b == b'*').map(|p| dollar + p)
            && star + 3 <= line.len()
        {
            let x = nmea_xor(&line[dollar + 1..star]);
            let hex = format!("{x:02X}").into_bytes();
            d[start + star + 1] = hex[0];
            d[start + star + 2] = hex[1];
        }
        start = end + 1;
    }
}
