//! NTRIP client: RTK corrections from a caster to a serial receiver.
//!
//! NTRIP 1.0 (plain HTTP/1.0-like: the caster answers `ICY 200 OK`, or `SOURCETABLE 200 OK` for an unknown
//! mountpoint) and 2.0 (HTTP/1.1 with `Ntrip-Version: Ntrip/2.0`, chunked transfer) over plain TCP with
//! `std::net::TcpStream` and timeouts: no TLS (casters serve plain TCP, port 2101), no async runtime.
//! Credentials come from a file ([`read_credentials`]: `user:password` on its first line, refused when
//! others may read it, as ssh refuses a private key), never from the command line.
//!
//! [`spawn`] starts one named worker thread (`ntrip`) that connects, checks the caster's answer, hands the
//! receiver each RTCM 3 frame whose CRC-24Q checks ([`crate::rtcm3`]; junk never reaches the receiver),
//! sends the receiver's latest GGA upstream every N seconds (casters of virtual reference stations need
//! it), and reconnects with the workers' [`Backoff`] when the caster goes away or stalls (no byte for
//! `stall_after`). A wrong password or mountpoint ends the worker with an error that says so. Everything the
//! operator needs — state, correction age, bytes per second, message types — is in [`NtripStatus`], read
//! without ever waiting on the network. [`NtripHandle::stop`] returns within [`STOP_WAIT`].

use std::collections::{BTreeMap, VecDeque};
use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs as _};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::backoff::Backoff;
use crate::gps::FixQuality;
use crate::rtcm3;

/// The protocol version spoken to the caster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NtripVersion {
    /// NTRIP 1.0: `GET /MOUNT HTTP/1.0`, answered `ICY 200 OK`.
    V1,
    /// NTRIP 2.0: HTTP/1.1 with `Ntrip-Version: Ntrip/2.0`, chunked transfer.
    V2,
}

/// A user name and password for the caster (HTTP Basic). `Debug` hides the password.
#[derive(Clone, PartialEq, Eq)]
pub struct Credentials {
    /// User name.
    pub user: String,
    /// Password.
    pub password: String,
}

impl std::fmt::Debug for Credentials {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Credentials").field("user", &self.user).field("password", &"***").finish()
    }
}

/// Errors of the NTRIP client. Each names the caster (or the file) it is about.
#[derive(Debug, thiserror::Error)]
pub enum NtripError {
    /// The credentials file cannot be used.
    #[error("credentials file {path}: {reason}")]
    Credentials {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Connecting, reading or writing failed.
    #[error("caster {caster}: {what}: {source}")]
    Io {
        /// `host:port`.
        caster: String,
        /// What was being done.
        what: &'static str,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The caster refused the user name or password (HTTP 401).
    #[error("caster {caster}: wrong user name or password for mountpoint {mountpoint} ({status})")]
    Unauthorized {
        /// `host:port`.
        caster: String,
        /// The mountpoint asked for.
        mountpoint: String,
        /// The caster's status line.
        status: String,
    },
    /// The caster has no such mountpoint (HTTP 404, or a source table instead of data).
    #[error("caster {caster}: no mountpoint {mountpoint} (see `vestnav ntrip --sourcetable`) ({status})")]
    NoMountpoint {
        /// `host:port`.
        caster: String,
        /// The mountpoint asked for.
        mountpoint: String,
        /// The caster's status line.
        status: String,
    },
    /// The caster's answer is not NTRIP.
    #[error("caster {caster}: unexpected answer: {detail}")]
    BadResponse {
        /// `host:port`.
        caster: String,
        /// What was wrong (the status line, an oversized header, a broken chunk).
        detail: String,
    },
    /// No answer, or no data, in time.
    #[error("caster {caster}: {what}")]
    Timeout {
        /// `host:port`.
        caster: String,
        /// What took too long.
        what: String,
    },
    /// The caster closed the connection.
    #[error("caster {caster}: connection closed by the caster")]
    Closed {
        /// `host:port`.
        caster: String,
    },
}

impl NtripError {
    /// Whether trying again cannot help (wrong credentials or mountpoint, not NTRIP): the worker stops.
    pub fn is_permanent(&self) -> bool {
        matches!(
            self,
            Self::Credentials { .. }
                | Self::Unauthorized { .. }
                | Self::NoMountpoint { .. }
                | Self::BadResponse { .. }
        )
    }
}

/// Largest credentials file read [bytes].
const CREDENTIALS_LIMIT: u64 = 4096;

/// Reads `user:password` from the first line of `path` (the password may contain `:`). The file must be a
/// regular file that neither its group nor others may read or write (mode `0600` or stricter on Unix), as
/// ssh requires of a private key.
pub fn read_credentials(path: &Path) -> Result<Credentials, NtripError> {
    let fail = |reason: String| NtripError::Credentials { path: path.display().to_string(), reason };
    let file = vestnav_files::open_regular(path).map_err(|e| fail(e.to_string()))?;
    let meta = file.metadata().map_err(|e| fail(e.to_string()))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let mode = meta.permissions().mode() & 0o777;
        if mode & 0o077 != 0 {
            return Err(fail(format!(
                "permissions {mode:03o} let others read it: run `chmod 600 {}`",
                path.display()
            )));
        }
    }
    if meta.len() > CREDENTIALS_LIMIT {
        return Err(fail(format!("{} bytes: not a credentials file", meta.len())));
    }
    let mut text = String::new();
    file.take(CREDENTIALS_LIMIT)
        .read_to_string(&mut text)
        .map_err(|e| fail(format!("not UTF-8 text ({e})")))?;
    let line = text.lines().next().unwrap_or("").trim_end_matches('\r');
    let Some((user, password)) = line.split_once(':') else {
        return Err(fail("the first line must be user:password".to_string()));
    };
    if user.is_empty() || user.chars().chain(password.chars()).any(char::is_control) {
        return Err(fail("the first line must be user:password (no control characters)".to_string()));
    }
    Ok(Credentials { user: user.to_string(), password: password.to_string() })
}

/// Base64 (RFC 4648 §4, with padding) of `bytes`, for HTTP Basic authentication.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk.first().copied().unwrap_or(0),
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 0x3F) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// What to connect to and how.
#[derive(Debug, Clone)]
pub struct NtripConfig {
    /// `host:port` of the caster.
    pub caster: String,
    /// The mountpoint (without the leading `/`).
    pub mountpoint: String,
    /// User name and password, if the caster wants them.
    pub credentials: Option<Credentials>,
    /// Protocol version.
    pub version: NtripVersion,
    /// Send the receiver's latest GGA upstream this often (`None`: never).
    pub gga_every: Option<Duration>,
    /// Connecting and waiting for the caster's answer, each at most this long.
    pub connect_timeout: Duration,
    /// No byte from the caster for this long is a stall: shown, then the worker reconnects.
    pub stall_after: Duration,
}

impl NtripConfig {
    /// Defaults: NTRIP 2.0, GGA every 10 s, 10 s to connect, stall after 10 s.
    pub fn new(caster: impl Into<String>, mountpoint: impl Into<String>) -> Self {
        Self {
            caster: caster.into(),
            mountpoint: mountpoint.into().trim_start_matches('/').to_string(),
            credentials: None,
            version: NtripVersion::V2,
            gga_every: Some(Duration::from_secs(10)),
            connect_timeout: Duration::from_secs(10),
            stall_after: Duration::from_secs(10),
        }
    }
}

/// The request line and headers for `path` (`/` for the source table).
fn request(config: &NtripConfig, path: &str) -> String {
    let mut r = match config.version {
        NtripVersion::V1 => {
            format!("GET /{path} HTTP/1.0\r\nUser-Agent: NTRIP vestnav/{}\r\n", env!("CARGO_PKG_VERSION"))
        }
        NtripVersion::V2 => format!(
            "GET /{path} HTTP/1.1\r\nHost: {}\r\nNtrip-Version: Ntrip/2.0\r\nUser-Agent: NTRIP vestnav/{}\r\n\
             Connection: close\r\n",
            config.caster,
            env!("CARGO_PKG_VERSION")
        ),
    };
    if let Some(c) = &config.credentials {
        r += "Authorization: Basic ";
        r += &base64(format!("{}:{}", c.user, c.password).as_bytes());
        r += "\r\n";
    }
    r.push_str("\r\n");
    r
}

/// What the caster answered.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Answer {
    /// Data follows (`ICY 200 OK`, or HTTP 200 with a data content type); `chunked` for chunked transfer.
    Data { chunked: bool },
    /// A source table follows.
    SourceTable,
}

/// Largest response head accepted [bytes].
const HEAD_LIMIT: usize = 16 * 1024;

/// Reads the caster's answer head from `stream` until `deadline`; returns the answer and the body bytes
/// already read.
fn read_answer(
    stream: &mut TcpStream,
    config: &NtripConfig,
    deadline: Instant,
    stop: &AtomicBool,
) -> Result<(Answer, Vec<u8>), NtripError> {
    let caster = &config.caster;
    let mut buf = Vec::new();
    let mut chunk = [0u8; 2048];
    loop {
        // A v1 answer's status line may be followed by data at once: decide on the first line.
        if let Some(end) = find(&buf, b"\r\n") {
            let status = String::from_utf8_lossy(buf.get(..end).unwrap_or(&[])).into_owned();
            if status.starts_with("ICY 200") {
                return Ok((Answer::Data { chunked: false }, buf.get(end + 2..).unwrap_or(&[]).to_vec()));
            }
            if status.starts_with("SOURCETABLE 200") {
                return Ok((Answer::SourceTable, buf.get(end + 2..).unwrap_or(&[]).to_vec()));
            }
            if status.starts_with("HTTP/") {
                if let Some(head_end) = find(&buf, b"\r\n\r\n") {
                    let head =
                        String::from_utf8_lossy(buf.get(..head_end).unwrap_or(&[])).to_ascii_lowercase();
                    let body = buf.get(head_end + 4..).unwrap_or(&[]).to_vec();
                    let code = status.split_whitespace().nth(1).unwrap_or("");
                    let mountpoint = config.mountpoint.clone();
                    return match code {
                        "200" => {
                            let chunked = head
                                .lines()
                                .any(|l| l.starts_with("transfer-encoding:") && l.contains("chunked"));
                            if head
                                .lines()
                                .any(|l| l.starts_with("content-type:") && l.contains("sourcetable"))
                            {
                                Ok((Answer::SourceTable, body))
                            } else {
                                Ok((Answer::Data { chunked }, body))
                            }
                        }
                        "401" | "403" => {
                            Err(NtripError::Unauthorized { caster: caster.clone(), mountpoint, status })
                        }
                        "404" => Err(NtripError::NoMountpoint { caster: caster.clone(), mountpoint, status }),
                        _ => Err(NtripError::BadResponse { caster: caster.clone(), detail: status }),
                    };
                }
            } else {
                let shown: String = status.chars().take(80).collect();
                return Err(NtripError::BadResponse {
                    caster: caster.clone(),
                    detail: format!("status line {shown:?}"),
                });
            }
        }
        if buf.len() > HEAD_LIMIT {
            return Err(NtripError::BadResponse {
                caster: caster.clone(),
                detail: format!("no end of the answer's header in {HEAD_LIMIT} bytes"),
            });
        }
        if Instant::now() >= deadline || stop.load(Ordering::Relaxed) {
            return Err(NtripError::Timeout {
                caster: caster.clone(),
                what: "no answer to the request in time".into(),
            });
        }
        match stream.read(&mut chunk) {
            Ok(0) => return Err(NtripError::Closed { caster: caster.clone() }),
            Ok(n) => buf.extend_from_slice(chunk.get(..n).unwrap_or(&[])),
            Err(e) if is_timeout(&e) => {}
            Err(source) => {
                return Err(NtripError::Io { caster: caster.clone(), what: "reading the answer", source });
            }
        }
    }
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
    )
}

/// Connects to the caster with `config.connect_timeout` per address and a short read timeout.
fn connect(config: &NtripConfig) -> Result<TcpStream, NtripError> {
    let caster = &config.caster;
    let io = |what, source| NtripError::Io { caster: caster.clone(), what, source };
    let addrs = caster.to_socket_addrs().map_err(|e| io("resolving the address", e))?;
    let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "no address");
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, config.connect_timeout) {
            Ok(s) => {
                s.set_read_timeout(Some(Duration::from_millis(100)))
                    .map_err(|e| io("setting a timeout", e))?;
                s.set_write_timeout(Some(config.connect_timeout)).map_err(|e| io("setting a timeout", e))?;
                // Corrections are small and late ones are useless: never wait to fill a segment.
                let _ = s.set_nodelay(true);
                return Ok(s);
            }
            Err(e) => last = e,
        }
    }
    Err(io("connecting", last))
}

/// Decodes HTTP/1.1 chunked transfer coding (RFC 9112 §7.1), bounded: chunk-size lines longer than 256
/// bytes or sizes above 16 MiB are errors; extensions and trailers are ignored.
#[derive(Debug, Default)]
pub struct Dechunker {
    line: Vec<u8>,
    remaining: usize,
    state: ChunkState,
}

#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
enum ChunkState {
    #[default]
    Size,
    Data,
    DataEnd,
    Done,
}

impl Dechunker {
    /// Feeds bytes of the body; appends the decoded data to `out`. `Err` names what was malformed.
    pub fn feed(&mut self, mut data: &[u8], out: &mut Vec<u8>) -> Result<(), String> {
        while let Some((&b, rest)) = data.split_first() {
            match self.state {
                ChunkState::Size | ChunkState::DataEnd => {
                    data = rest;
                    if b != b'\n' {
                        if self.line.len() >= 256 {
                            return Err("chunk-size line longer than 256 bytes".into());
                        }
                        self.line.push(b);
                        continue;
                    }
                    let line = String::from_utf8_lossy(&self.line).trim().to_string();
                    self.line.clear();
                    if self.state == ChunkState::DataEnd {
                        if !line.is_empty() {
                            return Err(format!("chunk not ended by CRLF ({line:?})"));
                        }
                        self.state = ChunkState::Size;
                        continue;
                    }
                    let size = line.split(';').next().unwrap_or("").trim();
                    let n =
                        usize::from_str_radix(size, 16).map_err(|_| format!("bad chunk size {size:?}"))?;
                    if n > 16 << 20 {
                        return Err(format!("chunk of {n} bytes"));
                    }
                    (self.remaining, self.state) =
                        if n == 0 { (0, ChunkState::Done) } else { (n, ChunkState::Data) };
                }
                ChunkState::Data => {
                    let take = self.remaining.min(data.len());
                    let (now, rest) = data.split_at(take);
                    out.extend_from_slice(now);
                    data = rest;
                    self.remaining -= take;
                    if self.remaining == 0 {
                        self.state = ChunkState::DataEnd;
                    }
                }
                ChunkState::Done => return Ok(()),
            }
        }
        Ok(())
    }

    /// Whether the last (zero-size) chunk has come.
    pub fn is_done(&self) -> bool {
        self.state == ChunkState::Done
    }
}

/// One stream of a caster's source table (`STR` record, NTRIP 2.0 §6 / 1.0 appendix).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Stream {
    /// Mountpoint.
    pub mountpoint: String,
    /// Identifier (often the nearest town).
    pub identifier: String,
    /// Data format (`RTCM 3.2`, ...).
    pub format: String,
    /// Format details (message types and rates).
    pub format_details: String,
    /// Navigation systems (`GPS+GLO+GAL`).
    pub nav_system: String,
    /// Country code.
    pub country: String,
    /// Latitude [deg], if parseable.
    pub lat_deg: Option<f64>,
    /// Longitude [deg], if parseable.
    pub lon_deg: Option<f64>,
    /// Whether the caster wants GGA from the client (`1`: a virtual reference station).
    pub nmea: bool,
    /// Authentication: `N` none, `B` basic, `D` digest.
    pub authentication: String,
}

/// A caster's source table.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SourceTable {
    /// The `STR` records.
    pub streams: Vec<Stream>,
    /// `CAS` (other casters) and `NET` (networks) records, as lines.
    pub other: Vec<String>,
    /// Lines that are none of those (skipped).
    pub skipped_lines: usize,
}

/// Parses the source table text (records up to `ENDSOURCETABLE`).
pub fn parse_sourcetable(text: &str) -> SourceTable {
    let mut table = SourceTable::default();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.starts_with("ENDSOURCETABLE") {
            break;
        }
        let f: Vec<&str> = line.split(';').collect();
        match f.first().copied() {
            Some("STR") if f.len() >= 12 => {
                let get = |k: usize| f.get(k).copied().unwrap_or("").to_string();
                table.streams.push(Stream {
                    mountpoint: get(1),
                    identifier: get(2),
                    format: get(3),
                    format_details: get(4),
                    nav_system: get(6),
                    country: get(8),
                    lat_deg: f.get(9).and_then(|s| s.parse().ok()).filter(|v: &f64| v.is_finite()),
                    lon_deg: f.get(10).and_then(|s| s.parse().ok()).filter(|v: &f64| v.is_finite()),
                    nmea: get(11) == "1",
                    authentication: get(15),
                });
            }
            Some("CAS" | "NET") => table.other.push(line.to_string()),
            _ => table.skipped_lines += 1,
        }
    }
    table
}

/// Largest source table read [bytes].
const SOURCETABLE_LIMIT: usize = 4 << 20;

/// Fetches the caster's source table (`GET /`), within `config.connect_timeout` per step and 30 s in all.
pub fn fetch_sourcetable(config: &NtripConfig) -> Result<SourceTable, NtripError> {
    let caster = &config.caster;
    let never = AtomicBool::new(false);
    let mut stream = connect(config)?;
    stream.write_all(request(config, "").as_bytes()).map_err(|source| NtripError::Io {
        caster: caster.clone(),
        what: "sending the request",
        source,
    })?;
    let start = Instant::now();
    let (answer, mut body) = read_answer(&mut stream, config, start + config.connect_timeout, &never)?;
    let chunked = matches!(answer, Answer::Data { chunked: true });
    let mut chunk = [0u8; 4096];
    let mut raw = std::mem::take(&mut body);
    loop {
        let text_so_far = find(&raw, b"ENDSOURCETABLE").is_some();
        if text_so_far || raw.len() > SOURCETABLE_LIMIT {
            break;
        }
        if start.elapsed() > Duration::from_secs(30) {
            return Err(NtripError::Timeout {
                caster: caster.clone(),
                what: "source table not complete in 30 s".into(),
            });
        }
        match stream.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => raw.extend_from_slice(chunk.get(..n).unwrap_or(&[])),
            Err(e) if is_timeout(&e) => {}
            Err(source) => {
                return Err(NtripError::Io {
                    caster: caster.clone(),
                    what: "reading the source table",
                    source,
                });
            }
        }
    }
    let text = if chunked {
        let mut out = Vec::new();
        let mut d = Dechunker::default();
        d.feed(&raw, &mut out)
            .map_err(|detail| NtripError::BadResponse { caster: caster.clone(), detail })?;
        out
    } else {
        raw
    };
    Ok(parse_sourcetable(&String::from_utf8_lossy(&text)))
}

/// Where the worker is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NtripState {
    /// Connecting (or waiting for the caster's answer).
    Connecting,
    /// Receiving corrections.
    Connected,
    /// Lost or stalled; trying again after a delay. The reason says what happened.
    Reconnecting {
        /// What went wrong.
        reason: String,
    },
    /// Ended by an error that another try cannot fix (wrong credentials or mountpoint).
    Failed {
        /// The error.
        reason: String,
    },
    /// Stopped by the operator.
    Stopped,
}

/// Everything the screen shows about the corrections, as one snapshot.
#[derive(Debug, Clone, PartialEq)]
pub struct NtripStatus {
    /// Where the worker is.
    pub state: NtripState,
    /// Successful connections so far.
    pub connects: u64,
    /// Stalls detected (no byte for `stall_after`).
    pub stalls: u64,
    /// Bytes received from the caster (after chunk decoding).
    pub bytes: u64,
    /// Bytes per second over the last 5 s.
    pub bytes_per_s: f64,
    /// When the last verified frame arrived (the correction age is measured from it).
    pub last_frame_at: Option<Instant>,
    /// Verified frames forwarded to the receiver.
    pub frames: u64,
    /// Frames with a bad CRC (dropped).
    pub bad_crc: u64,
    /// Verified frames per message type.
    pub message_types: BTreeMap<u16, u64>,
    /// GGA sentences sent upstream.
    pub gga_sent: u64,
    /// Frames the receiver's port refused (write errors or timeouts).
    pub write_errors: u64,
    /// The last error, for the operator.
    pub last_error: Option<String>,
}

impl Default for NtripStatus {
    fn default() -> Self {
        Self::new()
    }
}

impl NtripStatus {
    /// A client connecting, nothing received yet (also what a client being started shows).
    pub fn new() -> Self {
        Self {
            state: NtripState::Connecting,
            connects: 0,
            stalls: 0,
            bytes: 0,
            bytes_per_s: 0.0,
            last_frame_at: None,
            frames: 0,
            bad_crc: 0,
            message_types: BTreeMap::new(),
            gga_sent: 0,
            write_errors: 0,
            last_error: None,
        }
    }

    /// Time since the last verified frame (`None` before the first).
    pub fn correction_age(&self, now: Instant) -> Option<Duration> {
        self.last_frame_at.map(|t| now.saturating_duration_since(t))
    }

    /// The message types as `1005(3) 1077(12) ...`.
    pub fn message_types_text(&self) -> String {
        self.message_types.iter().map(|(t, n)| format!("{t}({n})")).collect::<Vec<_>>().join(" ")
    }

    /// The one status line (the CLI prints it every second, the console shows it): state, correction
    /// age, rate, frames and types, GGA sent, and the receiver's fix quality from its GGA
    /// ([`receiver_fix_text`]).
    pub fn line(&self, receiver: Option<FixQuality>, now: Instant) -> String {
        let state = match &self.state {
            NtripState::Connecting => "connecting".to_string(),
            NtripState::Connected => "connected".to_string(),
            NtripState::Reconnecting { reason } => format!("reconnecting ({reason})"),
            NtripState::Failed { reason } => format!("failed ({reason})"),
            NtripState::Stopped => "stopped".to_string(),
        };
        let age =
            self.correction_age(now).map_or_else(|| "-".to_string(), |a| format!("{:.1} s", a.as_secs_f64()));
        format!(
            "{state}: age {age}, {:.0} B/s, {} frames [{}], GGA sent {}, receiver {}",
            self.bytes_per_s,
            self.frames,
            self.message_types_text(),
            self.gga_sent,
            receiver_fix_text(receiver)
        )
    }
}

/// The receiver's fix quality in words, from its GGA quality digit: 4 is "RTK fixed", 5 "RTK float".
pub fn receiver_fix_text(quality: Option<FixQuality>) -> &'static str {
    match quality {
        Some(FixQuality::Rtk) => "RTK fixed",
        Some(FixQuality::FloatRtk) => "RTK float",
        Some(FixQuality::Dgps) => "DGPS",
        Some(FixQuality::Gps) => "autonomous",
        Some(FixQuality::Pps) => "PPS",
        Some(FixQuality::Invalid) => "no fix",
        Some(FixQuality::Estimated) => "estimated",
        Some(FixQuality::Manual | FixQuality::Simulation) => "not measured",
        None => "unknown",
    }
}

/// State shared between the worker and its handle.
struct Shared {
    stop: AtomicBool,
    status: Mutex<NtripStatus>,
    gga: Mutex<Option<String>>,
}

impl Shared {
    fn update(&self, f: impl FnOnce(&mut NtripStatus)) {
        // A poisoned lock only means a panic elsewhere mid-update: the counters are still usable.
        let mut s = self.status.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        f(&mut s);
    }
}

/// Longest [`NtripHandle::stop`] waits for the worker.
pub const STOP_WAIT: Duration = Duration::from_millis(300);

/// The running client: status snapshots, the GGA to send, and stop.
pub struct NtripHandle {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl NtripHandle {
    /// A snapshot of the status (never waits on the network: the worker holds the lock only to update it).
    pub fn status(&self) -> NtripStatus {
        self.shared.status.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
    }

    /// The receiver's latest GGA sentence (`$..GGA,...*hh`), sent upstream every `gga_every`. Anything
    /// else is ignored (returns false): a hostile line never reaches the caster.
    pub fn set_gga(&self, sentence: &str) -> bool {
        let s = sentence.trim_end();
        let ok = s.len() <= 120
            && s.starts_with('$')
            && s.get(3..7) == Some("GGA,")
            && s.bytes().all(|b| (0x20..0x7F).contains(&b));
        if ok {
            *self.shared.gga.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(s.to_string());
        }
        ok
    }

    /// Asks the worker to stop without waiting for it (a view's thread never waits on the network): it
    /// stops within [`STOP_WAIT`], or at the end of a connection attempt in progress.
    pub fn request_stop(&self) {
        self.shared.stop.store(true, Ordering::Relaxed);
    }

    /// Whether the worker has ended (failed or stopped).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Stops the worker and returns the last status; waits at most [`STOP_WAIT`] (its reads time out
    /// every 100 ms).
    pub fn stop(mut self) -> NtripStatus {
        self.shutdown();
        self.status()
    }

    /// Asks the worker to stop and waits for it at most [`STOP_WAIT`]: a worker stuck in a connection
    /// attempt (bounded by `connect_timeout`) is left to end by itself, so stopping never blocks.
    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        let Some(t) = self.thread.take() else { return };
        let until = Instant::now() + STOP_WAIT;
        while !t.is_finished() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(5));
        }
        if t.is_finished() {
            let _ = t.join();
        }
    }
}

impl Drop for NtripHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Starts the client on a thread named `ntrip`: verified RTCM 3 frames go to `receiver` (a serial port).
pub fn spawn(config: NtripConfig, receiver: Box<dyn Write + Send>) -> std::io::Result<NtripHandle> {
    let shared = Arc::new(Shared {
        stop: AtomicBool::new(false),
        status: Mutex::new(NtripStatus::new()),
        gga: Mutex::new(None),
    });
    let worker = Arc::clone(&shared);
    let thread =
        std::thread::Builder::new().name("ntrip".into()).spawn(move || run(&config, receiver, &worker))?;
    Ok(NtripHandle { shared, thread: Some(thread) })
}

fn run(config: &NtripConfig, mut receiver: Box<dyn Write + Send>, shared: &Shared) {
    let mut backoff = Backoff::new(Duration::from_secs(1), Duration::from_secs(30));
    while !shared.stop.load(Ordering::Relaxed) {
        shared.update(|s| s.state = NtripState::Connecting);
        let result = session(config, receiver.as_mut(), shared, &mut backoff);
        match result {
            Ok(()) => break,
            Err(e) if e.is_permanent() => {
                let reason = e.to_string();
                shared.update(|s| {
                    s.last_error = Some(reason.clone());
                    s.state = NtripState::Failed { reason };
                });
                return;
            }
            Err(e) => {
                let reason = e.to_string();
                tracing::warn!("ntrip: {reason}");
                shared.update(|s| {
                    s.last_error = Some(reason.clone());
                    s.state = NtripState::Reconnecting { reason };
                });
                let until = Instant::now() + backoff.next_delay();
                while Instant::now() < until && !shared.stop.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(50));
                }
            }
        }
    }
    shared.update(|s| s.state = NtripState::Stopped);
}

/// One connection: request, answer, then corrections until stopped (`Ok`) or an error.
fn session(
    config: &NtripConfig,
    receiver: &mut (dyn Write + Send),
    shared: &Shared,
    backoff: &mut Backoff,
) -> Result<(), NtripError> {
    let caster = &config.caster;
    let mut stream = connect(config)?;
    stream.write_all(request(config, &config.mountpoint).as_bytes()).map_err(|source| NtripError::Io {
        caster: caster.clone(),
        what: "sending the request",
        source,
    })?;
    let (answer, first) =
        read_answer(&mut stream, config, Instant::now() + config.connect_timeout, &shared.stop)?;
    let chunked = match answer {
        Answer::Data { chunked } => chunked,
        Answer::SourceTable => {
            return Err(NtripError::NoMountpoint {
                caster: caster.clone(),
                mountpoint: config.mountpoint.clone(),
                status: "the caster sent its source table".into(),
            });
        }
    };
    backoff.reset();
    shared.update(|s| {
        s.connects += 1;
        s.state = NtripState::Connected;
    });
    let mut dechunker = chunked.then(Dechunker::default);
    let mut framer = rtcm3::Framer::default();
    let mut window: VecDeque<(Instant, usize)> = VecDeque::new();
    let mut last_data = Instant::now();
    // Send the first GGA as soon as there is one (a virtual reference station waits for it).
    let mut last_gga: Option<Instant> = None;
    let mut pending = first;
    let mut buf = [0u8; 4096];
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let now = Instant::now();
        if let Some(every) = config.gga_every
            && last_gga.is_none_or(|t| now.duration_since(t) >= every)
        {
            let gga = shared.gga.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
            if let Some(g) = gga {
                stream.write_all(format!("{g}\r\n").as_bytes()).map_err(|source| NtripError::Io {
                    caster: caster.clone(),
                    what: "sending GGA",
                    source,
                })?;
                last_gga = Some(now);
                shared.update(|s| s.gga_sent += 1);
            }
        }
        let raw: Vec<u8> = if pending.is_empty() {
            match stream.read(&mut buf) {
                Ok(0) => return Err(NtripError::Closed { caster: caster.clone() }),
                Ok(n) => buf.get(..n).unwrap_or(&[]).to_vec(),
                Err(e) if is_timeout(&e) => {
                    if now.duration_since(last_data) >= config.stall_after {
                        shared.update(|s| s.stalls += 1);
                        return Err(NtripError::Timeout {
                            caster: caster.clone(),
                            what: format!("stalled: no data for {:.1} s", config.stall_after.as_secs_f64()),
                        });
                    }
                    continue;
                }
                Err(source) => {
                    return Err(NtripError::Io {
                        caster: caster.clone(),
                        what: "reading corrections",
                        source,
                    });
                }
            }
        } else {
            std::mem::take(&mut pending)
        };
        last_data = Instant::now();
        let data = match dechunker.as_mut() {
            Some(d) => {
                let mut out = Vec::with_capacity(raw.len());
                d.feed(&raw, &mut out)
                    .map_err(|detail| NtripError::BadResponse { caster: caster.clone(), detail })?;
                if d.is_done() {
                    return Err(NtripError::Closed { caster: caster.clone() });
                }
                out
            }
            None => raw,
        };
        deliver(&data, last_data, &mut window, &mut framer, receiver, shared);
    }
}

/// Hands the verified frames of `data` (arrived at `at`) to the receiver and updates the status: the rate
/// over the last 5 s (`window`), frames, message types, write errors.
fn deliver(
    data: &[u8],
    at: Instant,
    window: &mut VecDeque<(Instant, usize)>,
    framer: &mut rtcm3::Framer,
    receiver: &mut (dyn Write + Send),
    shared: &Shared,
) {
    window.push_back((at, data.len()));
    while window.front().is_some_and(|(t, _)| at.duration_since(*t) > Duration::from_secs(5))
        || window.len() > 4096
    {
        window.pop_front();
    }
    let span = window.front().map_or(0.0, |(t, _)| at.duration_since(*t).as_secs_f64()).max(1.0);
    let rate = window.iter().map(|(_, n)| *n).sum::<usize>() as f64 / span;
    let mut frames: Vec<(Option<u16>, bool)> = Vec::new();
    framer.feed(data, |f| {
        let ok = receiver.write_all(f.bytes).and_then(|()| receiver.flush()).is_ok();
        frames.push((f.message_type(), ok));
    });
    let stats = framer.stats();
    shared.update(|s| {
        s.bytes += data.len() as u64;
        s.bytes_per_s = rate;
        s.bad_crc = stats.bad_crc;
        for (t, ok) in &frames {
            s.frames += 1;
            s.last_frame_at = Some(at);
            if let Some(t) = t {
                *s.message_types.entry(*t).or_insert(0) += 1;
            }
            if !ok {
                s.write_errors += 1;
                s.last_error = Some("the receiver's port refused a correction frame".into());
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RFC 4648 §10 test vectors.
    #[test]
    fn base64_rfc4648_vectors() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
        // RFC 7617 §2's example: Aladdin / open sesame.
        assert_eq!(base64(b"Aladdin:open sesame"), "QWxhZGRpbjpvcGVuIHNlc2FtZQ==");
    }

    /// RFC 9112 §7.1's shape: sizes in hex, an extension, a zero chunk and a trailer; fed byte by byte.
    #[test]
    fn dechunks_split_input() {
        let body = b"4\r\nWiki\r\n7;ext=1\r\npedia i\r\nB\r\nn \r\nchunks.\r\n0\r\nTrailer: x\r\n\r\n";
        let mut d = Dechunker::default();
        let mut out = Vec::new();
        for b in body {
            d.feed(std::slice::from_ref(b), &mut out).unwrap();
        }
        assert_eq!(out, b"Wikipedia in \r\nchunks.");
        assert!(d.is_done());
        assert!(Dechunker::default().feed(b"zz\r\n", &mut out).is_err());
        assert!(Dechunker::default().feed(&[b'1'; 300], &mut out).is_err());
    }

    #[test]
    fn source_table_records() {
        let text = "STR;RTCM3EPH;Wettzell;RTCM 3.2;1019,1020;2;GPS+GLO;IGS;DEU;49.14;12.88;0;0;BKG;none;B;N;3600;\r\n\
                    CAS;caster.example;2101;Example;BKG;0;DEU;50.1;8.7;0.0.0.0;0;http://example\r\n\
                    STR;VRS;Somewhere;RTCM 3;1004;2;GPS;NET;USA;40.0;-105.0;1;1;x;none;B;Y;9600;\r\n\
                    ENDSOURCETABLE\r\nSTR;after;the;end;;;;;;;;;;;;;;\r\n";
        let t = parse_sourcetable(text);
        assert_eq!(t.streams.len(), 2);
        assert_eq!(t.streams[0].mountpoint, "RTCM3EPH");
        assert_eq!(t.streams[0].lat_deg, Some(49.14));
        assert!(!t.streams[0].nmea && t.streams[1].nmea);
        assert_eq!(t.other.len(), 1);
    }

    #[test]
    fn requests_carry_version_and_basic_auth() {
        let mut c = NtripConfig::new("127.0.0.1:2101", "/MOUNT");
        c.credentials = Some(Credentials { user: "Aladdin".into(), password: "open sesame".into() });
        let v2 = request(&c, &c.mountpoint);
        assert!(v2.starts_with("GET /MOUNT HTTP/1.1\r\n"));
        assert!(v2.contains("Ntrip-Version: Ntrip/2.0\r\n"));
        assert!(v2.contains("Authorization: Basic QWxhZGRpbjpvcGVuIHNlc2FtZQ==\r\n"));
        c.version = NtripVersion::V1;
        let v1 = request(&c, "");
        assert!(v1.starts_with("GET / HTTP/1.0\r\n") && v1.ends_with("\r\n\r\n"));
        assert!(!format!("{:?}", c.credentials).contains("sesame"));
    }
}
