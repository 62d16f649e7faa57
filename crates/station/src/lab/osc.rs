//! Open Sound Control 1.0 messages over UDP, written by hand from the specification: an address pattern and
//! a type tag string (each an OSC-string: ASCII, NUL-terminated, padded with NULs to a multiple of 4 bytes),
//! then the arguments, big-endian: `f` float32, `d` float64 (the spec's non-standard but common 64-bit
//! double), `s` an OSC-string, `i` int32.

use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};

/// The longest text argument sent [bytes]; longer text is cut at a character boundary.
const MAX_TEXT: usize = 1024;

/// One argument.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Arg<'a> {
    /// `s`: text (NUL bytes, which an OSC-string cannot hold, are left out).
    Str(&'a str),
    /// `f`.
    Float(f32),
    /// `d`.
    Double(f64),
    /// `i`.
    #[cfg_attr(not(test), allow(dead_code))]
    Int(i32),
}

/// Appends `s` as an OSC-string: its bytes, then 1 to 4 NULs up to a multiple of 4.
fn put_string(out: &mut Vec<u8>, s: &str) {
    out.extend(s.bytes().filter(|&b| b != 0));
    out.push(0);
    while !out.len().is_multiple_of(4) {
        out.push(0);
    }
}

/// `text` cut to at most [`MAX_TEXT`] bytes at a character boundary.
fn bounded(text: &str) -> &str {
    let mut end = text.len().min(MAX_TEXT);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

/// The bytes of one OSC message.
pub(crate) fn message(address: &str, args: &[Arg<'_>]) -> Vec<u8> {
    let mut out = Vec::with_capacity(64);
    put_string(&mut out, address);
    let tags: String = std::iter::once(',')
        .chain(args.iter().map(|a| match a {
            Arg::Str(_) => 's',
            Arg::Float(_) => 'f',
            Arg::Double(_) => 'd',
            Arg::Int(_) => 'i',
        }))
        .collect();
    put_string(&mut out, &tags);
    for a in args {
        match a {
            Arg::Str(s) => put_string(&mut out, bounded(s)),
            Arg::Float(f) => out.extend(f.to_be_bytes()),
            Arg::Double(d) => out.extend(d.to_be_bytes()),
            Arg::Int(i) => out.extend(i.to_be_bytes()),
        }
    }
    out
}

/// A UDP socket aimed at one OSC receiver; sending never waits.
pub(crate) struct Sender {
    socket: UdpSocket,
}

impl Sender {
    /// A non-blocking socket of `to`'s address family, connected to it.
    pub(crate) fn open(to: SocketAddr) -> std::io::Result<Sender> {
        let local: SocketAddr = match to {
            SocketAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, 0).into(),
            SocketAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, 0).into(),
        };
        let socket = UdpSocket::bind(local)?;
        socket.connect(to)?;
        socket.set_nonblocking(true)?;
        Ok(Sender { socket })
    }

    /// Sends one message (a full socket buffer or an unreachable port is an error, not a wait).
    pub(crate) fn send(&self, msg: &[u8]) -> std::io::Result<()> {
        self.socket.send(msg).map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The specification's first example: "/oscillator/4/frequency" with the float 440.0.
    #[test]
    fn the_specs_float_example() {
        let m = message("/oscillator/4/frequency", &[Arg::Float(440.0)]);
        let mut expected = b"/oscillator/4/frequency\0".to_vec();
        expected.extend([0x2c, 0x66, 0, 0, 0x43, 0xdc, 0, 0]);
        assert_eq!(m, expected);
    }

    /// The specification's second example: "/foo" with 1000, -1, "hello", 1.234 and 5.678.
    #[test]
    fn the_specs_mixed_example() {
        let m = message(
            "/foo",
            &[Arg::Int(1000), Arg::Int(-1), Arg::Str("hello"), Arg::Float(1.234), Arg::Float(5.678)],
        );
        let expected: Vec<u8> = vec![
            0x2f, 0x66, 0x6f, 0x6f, 0, 0, 0, 0, // "/foo"
            0x2c, 0x69, 0x69, 0x73, 0x66, 0x66, 0, 0, // ",iisff"
            0, 0, 0x03, 0xe8, // 1000
            0xff, 0xff, 0xff, 0xff, // -1
            0x68, 0x65, 0x6c, 0x6c, 0x6f, 0, 0, 0, // "hello"
            0x3f, 0x9d, 0xf3, 0xb6, // 1.234
            0x40, 0xb5, 0xb2, 0x2d, // 5.678
        ];
        assert_eq!(m, expected);
    }

    #[test]
    fn hostile_text_stays_a_valid_bounded_string() {
        let long = format!("a\0b{}", "é".repeat(4000));
        let m = message("/vestnav/vest", &[Arg::Str(&long)]);
        assert_eq!(m.len() % 4, 0);
        assert!(m.len() <= 16 + 4 + MAX_TEXT + 4);
        // One NUL-terminated string after the tags: no NUL inside it.
        let body = &m[20..];
        let end = body.iter().position(|&b| b == 0).unwrap();
        assert!(std::str::from_utf8(&body[..end]).unwrap().starts_with("ab"));
        assert!(body[end..].iter().all(|&b| b == 0));
    }
}
