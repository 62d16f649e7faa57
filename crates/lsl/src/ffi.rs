//! The liblsl C functions vestnav calls, bound at run time (signatures from liblsl's `lsl_c.h`:
//! `lsl/common.h`, `lsl/streaminfo.h`, `lsl/outlet.h`, `lsl/xml.h`). The only unsafe code of vestnav.
#![allow(unsafe_code)]

use std::ffi::{CString, c_char, c_void};
use std::sync::Arc;

use libloading::Library;

use crate::search::Candidate;
use crate::{LslError, StreamSpec, bounded};

type CreateStreaminfo =
    unsafe extern "C" fn(*const c_char, *const c_char, i32, f64, i32, *const c_char) -> *mut c_void;
type Destroy = unsafe extern "C" fn(*mut c_void);
type GetDesc = unsafe extern "C" fn(*mut c_void) -> *mut c_void;
type AppendChild = unsafe extern "C" fn(*mut c_void, *const c_char) -> *mut c_void;
type AppendChildValue = unsafe extern "C" fn(*mut c_void, *const c_char, *const c_char) -> *mut c_void;
type CreateOutlet = unsafe extern "C" fn(*mut c_void, i32, i32) -> *mut c_void;
type PushDouble = unsafe extern "C" fn(*mut c_void, *const f64, f64, i32) -> i32;
type PushStr = unsafe extern "C" fn(*mut c_void, *const *const c_char, f64, i32) -> i32;
type Clock = unsafe extern "C" fn() -> f64;
type Version = unsafe extern "C" fn() -> i32;

/// The bound functions, with the library that holds them (kept loaded while any of them may be called).
pub(crate) struct Api {
    pub(crate) path: String,
    pub(crate) library_version: i32,
    create_streaminfo: CreateStreaminfo,
    destroy_streaminfo: Destroy,
    get_desc: GetDesc,
    append_child: AppendChild,
    append_child_value: AppendChildValue,
    create_outlet: CreateOutlet,
    destroy_outlet: Destroy,
    push_sample_dtp: PushDouble,
    push_sample_strtp: PushStr,
    local_clock: Clock,
    /// Last field: dropped after everything above (plain function pointers, which need it loaded).
    _library: Library,
}

/// Versions of liblsl accepted: 1.10 (the first with the C API used here) up to major version 1.
const VERSIONS: std::ops::RangeInclusive<i32> = 110..=199;

impl Api {
    /// Loads `candidate` and binds every function; any missing one, or an implausible version, refuses it.
    pub(crate) fn open(candidate: &Candidate) -> Result<Api, String> {
        if let Candidate::File(path) = candidate {
            // A clear reason for the common cases before the system loader's words.
            match std::fs::metadata(path) {
                Err(e) => return Err(format!("cannot read it: {e}")),
                Ok(m) if !m.is_file() => return Err("not a regular file".to_owned()),
                Ok(m) if m.len() == 0 => return Err("empty file".to_owned()),
                Ok(_) => {}
            }
        }
        // SAFETY: loading a library runs its initialisers. The candidates are liblsl's names and files a
        // user installed (or named in VESTNAV_LIBLSL), trusted as any program on the PATH is.
        let library = unsafe {
            match candidate {
                Candidate::File(p) => Library::new(p),
                Candidate::Name(n) => Library::new(n),
            }
        }
        .map_err(|e| format!("not loadable: {e}"))?;
        // SAFETY: each symbol is read with the signature liblsl's headers declare for that name.
        unsafe {
            macro_rules! bind {
                ($name:literal) => {
                    *library
                        .get(concat!($name, "\0").as_bytes())
                        .map_err(|_| format!("not a liblsl: it has no {}", $name))?
                };
            }
            let library_version: Version = bind!("lsl_library_version");
            let protocol_version: Version = bind!("lsl_protocol_version");
            let api = Api {
                path: candidate.display(),
                library_version: library_version(),
                create_streaminfo: bind!("lsl_create_streaminfo"),
                destroy_streaminfo: bind!("lsl_destroy_streaminfo"),
                get_desc: bind!("lsl_get_desc"),
                append_child: bind!("lsl_append_child"),
                append_child_value: bind!("lsl_append_child_value"),
                create_outlet: bind!("lsl_create_outlet"),
                destroy_outlet: bind!("lsl_destroy_outlet"),
                push_sample_dtp: bind!("lsl_push_sample_dtp"),
                push_sample_strtp: bind!("lsl_push_sample_strtp"),
                local_clock: bind!("lsl_local_clock"),
                _library: library,
            };
            if !VERSIONS.contains(&api.library_version) {
                return Err(format!(
                    "liblsl version {} is not supported (1.10 to 1.99)",
                    api.library_version
                ));
            }
            let protocol = protocol_version();
            if protocol / 100 != 1 {
                return Err(format!("LSL protocol {protocol} is not version 1.x"));
            }
            Ok(api)
        }
    }

    pub(crate) fn local_clock(&self) -> f64 {
        // SAFETY: takes nothing, returns a number; thread-safe in liblsl.
        unsafe { (self.local_clock)() }
    }
}

/// A C string from text a user or a device may have written: NUL bytes refused by name.
fn c_string(text: &str, what: &'static str) -> Result<CString, LslError> {
    CString::new(text).map_err(|_| LslError::Nul { what })
}

/// One stream outlet. Stays on the thread that made it (liblsl objects are not shared here); dropping it
/// withdraws the stream.
pub struct Outlet {
    api: Arc<Api>,
    handle: *mut c_void,
    name: String,
    channels: usize,
}

impl std::fmt::Debug for Outlet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Outlet")
            .field("name", &self.name)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}

impl Outlet {
    pub(crate) fn open(api: Arc<Api>, spec: &StreamSpec) -> Result<Outlet, LslError> {
        let null = |what| LslError::Null { what, stream: spec.name.clone() };
        let name = c_string(&spec.name, "the stream name")?;
        let kind = c_string(&spec.kind, "the stream type")?;
        let source = c_string(&spec.source_id, "the source id")?;
        let channels = i32::try_from(spec.channels).map_err(|_| null("stream info"))?;
        let rate = if spec.rate_hz.is_finite() && spec.rate_hz >= 0.0 { spec.rate_hz } else { 0.0 };
        let labels = spec
            .labels
            .iter()
            .map(|(l, u)| Ok((c_string(l, "a channel label")?, c_string(u, "a channel unit")?)))
            .collect::<Result<Vec<_>, LslError>>()?;
        // SAFETY: every pointer passed is a live NUL-terminated string or an object liblsl returned and we
        // checked for NULL; the stream info is destroyed once, after the outlet copied it (outlet.h).
        unsafe {
            let info = (api.create_streaminfo)(
                name.as_ptr(),
                kind.as_ptr(),
                channels,
                rate,
                spec.format.code(),
                source.as_ptr(),
            );
            if info.is_null() {
                return Err(null("stream info"));
            }
            if !labels.is_empty() {
                let desc = (api.get_desc)(info);
                let list = if desc.is_null() { desc } else { (api.append_child)(desc, c"channels".as_ptr()) };
                if !list.is_null() {
                    for (label, unit) in &labels {
                        let ch = (api.append_child)(list, c"channel".as_ptr());
                        if ch.is_null() {
                            break;
                        }
                        (api.append_child_value)(ch, c"label".as_ptr(), label.as_ptr());
                        if !unit.as_bytes().is_empty() {
                            (api.append_child_value)(ch, c"unit".as_ptr(), unit.as_ptr());
                        }
                    }
                }
            }
            // chunk size 0 (each push is one chunk); 360: liblsl's default buffer (x100 samples for an
            // irregular stream), bounding what a slow reader makes the outlet keep.
            let outlet = (api.create_outlet)(info, 0, 360);
            (api.destroy_streaminfo)(info);
            if outlet.is_null() {
                return Err(null("outlet"));
            }
            Ok(Outlet { api, handle: outlet, name: spec.name.clone(), channels: spec.channels })
        }
    }

    /// The stream's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Pushes one sample of numbers timestamped `at` (liblsl's clock), sent at once. Never waits for a
    /// reader: liblsl queues it (bounded by the outlet's buffer, oldest dropped).
    pub fn push_f64(&self, values: &[f64], at: f64) -> Result<(), LslError> {
        if values.len() != self.channels {
            return Err(LslError::Shape {
                stream: self.name.clone(),
                expected: self.channels,
                got: values.len(),
            });
        }
        // SAFETY: `values` holds exactly the stream's channel count of doubles; the outlet is live.
        let code = unsafe { (self.api.push_sample_dtp)(self.handle, values.as_ptr(), at, 1) };
        self.checked(code)
    }

    /// Pushes one single-channel string sample (cut to [`crate::MAX_STRING_BYTES`]) timestamped `at`.
    pub fn push_str(&self, text: &str, at: f64) -> Result<(), LslError> {
        if self.channels != 1 {
            return Err(LslError::Shape { stream: self.name.clone(), expected: self.channels, got: 1 });
        }
        let s = c_string(bounded(text), "the sample")?;
        let ptrs = [s.as_ptr()];
        // SAFETY: one live C string for the one channel; the outlet is live.
        let code = unsafe { (self.api.push_sample_strtp)(self.handle, ptrs.as_ptr(), at, 1) };
        self.checked(code)
    }

    fn checked(&self, code: i32) -> Result<(), LslError> {
        if code == 0 { Ok(()) } else { Err(LslError::Push { stream: self.name.clone(), code }) }
    }
}

impl Drop for Outlet {
    fn drop(&mut self) {
        // SAFETY: the outlet came from lsl_create_outlet, was checked non-NULL and is destroyed once.
        unsafe { (self.api.destroy_outlet)(self.handle) }
    }
}
