//! Lab Streaming Layer (LSL) outlets through the liblsl found at run time: no C build, no link-time
//! dependency. A machine without liblsl runs everything else; [`Lsl::load`] says what it looked for and
//! how to install it.
//!
//! ```no_run
//! use vestnav_lsl::{ChannelFormat, Lsl, StreamSpec};
//! let lsl = Lsl::load()?;
//! let spec = StreamSpec::new("vestnav-markers", "Markers", 1, ChannelFormat::String, "vestnav-markers");
//! let outlet = lsl.outlet(&spec.with_channels(&["marker"]))?;
//! outlet.push_str("trial_start 1 training", lsl.local_clock())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Where liblsl is looked for, in order ([`search`]): the file named by `VESTNAV_LIBLSL` (only it, when
//! set), pylsl's own `PYLSL_LIB`, the system's library names, then the copy a pylsl installation carries
//! in `site-packages/pylsl/lib/`. Only the handful of C functions an outlet needs are bound (`ffi`);
//! every pointer liblsl returns is checked before use.

mod ffi;
pub mod search;

use std::fmt;
use std::sync::Arc;

pub use ffi::Outlet;

/// The environment variable that names the liblsl file to use (and only it).
pub const ENV_LIBLSL: &str = "VESTNAV_LIBLSL";

/// The longest string sample pushed [bytes]; longer text is cut at a character boundary.
pub const MAX_STRING_BYTES: usize = 4096;

/// A loaded liblsl. Cheap to clone; outlets keep the library loaded while they live.
#[derive(Clone)]
pub struct Lsl {
    api: Arc<ffi::Api>,
}

impl fmt::Debug for Lsl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Lsl").field("path", &self.api.path).field("version", &self.library_version()).finish()
    }
}

/// liblsl could not be loaded: every place looked at, and why each failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LslMissing {
    /// Each candidate tried (a path or a library name) with the reason it was not used.
    pub tried: Vec<(String, String)>,
}

/// How to get liblsl, for messages and screens.
pub const INSTALL_HINT: &str = "install liblsl: `python3 -m pip install pylsl` (its wheel carries liblsl; \
vestnav finds it in site-packages/pylsl/lib), or the liblsl package of your distribution or a release of \
github.com/sccn/liblsl; or name the library file in VESTNAV_LIBLSL";

impl fmt::Display for LslMissing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "liblsl (Lab Streaming Layer) not found. Tried:")?;
        for (what, why) in &self.tried {
            write!(f, "\n  {what}: {why}")?;
        }
        write!(f, "\nTo {INSTALL_HINT}.")
    }
}

impl std::error::Error for LslMissing {}

/// An outlet could not be made or a sample could not be pushed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LslError {
    /// A name or text holds a NUL byte, which C strings cannot carry.
    #[error("{what} holds a NUL byte")]
    Nul {
        /// Which argument.
        what: &'static str,
    },
    /// liblsl returned no object where one was asked for.
    #[error("liblsl could not create the {what} of stream {stream:?}")]
    Null {
        /// What was asked for (stream info, outlet).
        what: &'static str,
        /// The stream's name.
        stream: String,
    },
    /// A push of the wrong shape (the number of values is not the stream's channel count).
    #[error("stream {stream:?} has {expected} channels, {got} values pushed")]
    Shape {
        /// The stream's name.
        stream: String,
        /// Its channel count.
        expected: usize,
        /// The values given.
        got: usize,
    },
    /// liblsl answered a push with an error code.
    #[error("liblsl refused a sample of {stream:?} (error {code})")]
    Push {
        /// The stream's name.
        stream: String,
        /// liblsl's `lsl_error_code_t`.
        code: i32,
    },
}

/// The value type of every channel of a stream (liblsl's `lsl_channel_format_t`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChannelFormat {
    /// 32-bit float.
    Float32,
    /// 64-bit float.
    Double64,
    /// Variable-length string.
    String,
}

impl ChannelFormat {
    fn code(self) -> i32 {
        match self {
            Self::Float32 => 1,
            Self::Double64 => 2,
            Self::String => 3,
        }
    }
}

/// What an outlet announces: name, content type, channels, rate, format and source id.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamSpec {
    /// The stream's name (what `LabRecorder` lists).
    pub name: String,
    /// Its content type ("Markers", …).
    pub kind: String,
    /// Channels per sample.
    pub channels: usize,
    /// Nominal rate [Hz]; 0 for an irregular stream.
    pub rate_hz: f64,
    /// The value type.
    pub format: ChannelFormat,
    /// A stable id of the source, so a recorder picks the stream up again after a restart.
    pub source_id: String,
    /// Channel labels and units for the stream's description (`desc/channels/channel`), if any.
    pub labels: Vec<(String, String)>,
}

impl StreamSpec {
    /// An irregular-rate stream with no channel labels.
    pub fn new(name: &str, kind: &str, channels: usize, format: ChannelFormat, source_id: &str) -> Self {
        Self {
            name: name.to_owned(),
            kind: kind.to_owned(),
            channels,
            rate_hz: 0.0,
            format,
            source_id: source_id.to_owned(),
            labels: Vec::new(),
        }
    }

    /// The same stream with its channels labelled (no unit).
    #[must_use]
    pub fn with_channels(mut self, labels: &[&str]) -> Self {
        self.labels = labels.iter().map(|l| ((*l).to_owned(), String::new())).collect();
        self
    }

    /// The same stream with its channels labelled, each with its unit.
    #[must_use]
    pub fn with_units(mut self, labels: &[(&str, &str)]) -> Self {
        self.labels = labels.iter().map(|(l, u)| ((*l).to_owned(), (*u).to_owned())).collect();
        self
    }
}

impl Lsl {
    /// Finds and loads liblsl (see [`search`] for the order). The error lists every place tried and how to
    /// install it.
    pub fn load() -> Result<Lsl, LslMissing> {
        let mut tried = Vec::new();
        for candidate in search::candidates(&search::Environment::current(), &mut tried) {
            match ffi::Api::open(&candidate) {
                Ok(api) => return Ok(Lsl { api: Arc::new(api) }),
                Err(why) => tried.push((candidate.display(), why)),
            }
        }
        Err(LslMissing { tried })
    }

    /// Loads liblsl from one file (what `VESTNAV_LIBLSL` does). A file that is not a liblsl — missing,
    /// empty, another library, an implausible version — is refused with the reason.
    pub fn load_file(path: &std::path::Path) -> Result<Lsl, LslMissing> {
        let candidate = search::Candidate::File(path.to_path_buf());
        ffi::Api::open(&candidate)
            .map(|api| Lsl { api: Arc::new(api) })
            .map_err(|why| LslMissing { tried: vec![(candidate.display(), why)] })
    }

    /// liblsl's clock [s]: what every sample's timestamp is on, and what a reader's clock is synchronised
    /// to. Monotonic, better than a millisecond.
    pub fn local_clock(&self) -> f64 {
        self.api.local_clock()
    }

    /// liblsl's version, major × 100 + minor (e.g. 116 for 1.16).
    pub fn library_version(&self) -> i32 {
        self.api.library_version
    }

    /// The version as people write it ("1.16").
    pub fn version_text(&self) -> String {
        let v = self.library_version();
        format!("{}.{}", v / 100, v % 100)
    }

    /// Where the library was loaded from (a path or a system library name).
    pub fn path(&self) -> &str {
        &self.api.path
    }

    /// Opens an outlet: the stream becomes visible on the network until the outlet is dropped.
    pub fn outlet(&self, spec: &StreamSpec) -> Result<Outlet, LslError> {
        Outlet::open(self.api.clone(), spec)
    }
}

/// Cuts `text` to at most [`MAX_STRING_BYTES`] at a character boundary.
pub(crate) fn bounded(text: &str) -> &str {
    if text.len() <= MAX_STRING_BYTES {
        return text;
    }
    let mut end = MAX_STRING_BYTES;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_text_is_cut_at_a_character_boundary() {
        let s = "é".repeat(MAX_STRING_BYTES); // 2 bytes each
        let b = bounded(&s);
        assert!(b.len() <= MAX_STRING_BYTES);
        assert!(s.starts_with(b));
        assert_eq!(bounded("short"), "short");
    }

    #[test]
    fn missing_lists_what_was_tried_and_how_to_install() {
        let m = LslMissing { tried: vec![("liblsl.so".into(), "not found".into())] };
        let text = m.to_string();
        assert!(text.contains("liblsl.so: not found"), "{text}");
        assert!(text.contains("pip install pylsl"), "{text}");
        assert!(text.contains(ENV_LIBLSL), "{text}");
    }
}
