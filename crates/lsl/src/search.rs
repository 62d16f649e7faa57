//! Where liblsl is looked for, in order:
//!
//! 1. `VESTNAV_LIBLSL`: a file path. When set, only it is tried (a library the operator named that fails
//!    to load is reported, never silently replaced by another one).
//! 2. `PYLSL_LIB`: the file pylsl itself is told to use, if set.
//! 3. The system's names: `liblsl.so`, `liblsl.so.2`, `liblsl.so.1` (Linux), `liblsl.dylib`, `lsl.dll`,
//!    resolved by the system loader (`LD_LIBRARY_PATH`, `ldconfig`'s cache, …).
//! 4. pylsl's bundled copy: `pylsl/lib/liblsl*` under the usual site-packages folders (a virtualenv, the
//!    user's, pyenv's and conda's versions, `/usr/local/lib/python3*`, `/usr/lib/python3*`), without
//!    running Python;
//! 5. last, the site-packages folders `python3` itself reports (`site.getsitepackages()`, bounded to 3 s;
//!    pylsl is not imported).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// One place liblsl may be.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Candidate {
    /// A file.
    File(PathBuf),
    /// A library name the system's loader resolves.
    Name(String),
}

impl Candidate {
    /// The candidate in words.
    pub fn display(&self) -> String {
        match self {
            Self::File(p) => p.display().to_string(),
            Self::Name(n) => format!("{n} (system library)"),
        }
    }
}

/// What the search reads from the process's environment (a value, so tests give their own).
#[derive(Debug, Clone, Default)]
pub struct Environment {
    /// `VESTNAV_LIBLSL`.
    pub explicit: Option<OsString>,
    /// `PYLSL_LIB`.
    pub pylsl_lib: Option<OsString>,
    /// `VIRTUAL_ENV`.
    pub virtual_env: Option<PathBuf>,
    /// `CONDA_PREFIX`.
    pub conda_prefix: Option<PathBuf>,
    /// The home folder.
    pub home: Option<PathBuf>,
    /// Whether to ask `python3` for its site-packages folders when nothing else was found.
    pub ask_python: bool,
}

impl Environment {
    /// This process's environment.
    pub fn current() -> Self {
        let path = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
        Self {
            explicit: std::env::var_os(crate::ENV_LIBLSL).filter(|v| !v.is_empty()),
            pylsl_lib: std::env::var_os("PYLSL_LIB").filter(|v| !v.is_empty()),
            virtual_env: path("VIRTUAL_ENV"),
            conda_prefix: path("CONDA_PREFIX"),
            home: path("HOME").or_else(|| path("USERPROFILE")),
            ask_python: true,
        }
    }
}

/// The system library names, most specific last.
fn system_names() -> &'static [&'static str] {
    if cfg!(target_os = "macos") {
        &["liblsl.dylib", "liblsl.2.dylib"]
    } else if cfg!(windows) {
        &["lsl.dll", "liblsl.dll"]
    } else {
        &["liblsl.so", "liblsl.so.2", "liblsl.so.1"]
    }
}

/// The candidates in search order. Folders looked into that hold no pylsl are not listed; when
/// `VESTNAV_LIBLSL` is set it is the only candidate. `tried` gets a line for each step that found nothing.
pub fn candidates(
    env: &Environment,
    tried: &mut Vec<(String, String)>,
) -> Box<dyn Iterator<Item = Candidate>> {
    if let Some(p) = &env.explicit {
        return Box::new(std::iter::once(Candidate::File(PathBuf::from(p))));
    }
    let mut ready = Vec::new();
    if let Some(p) = &env.pylsl_lib {
        ready.push(Candidate::File(PathBuf::from(p)));
    }
    ready.extend(system_names().iter().map(|n| Candidate::Name((*n).to_owned())));
    let bundled = pylsl_libraries(&site_dirs(env));
    if bundled.is_empty() {
        tried.push(("pylsl in the usual site-packages folders".to_owned(), "not installed".to_owned()));
    }
    ready.extend(bundled.into_iter().map(Candidate::File));
    // Python is asked only when everything above failed (the iterator is lazy).
    let known = ready.clone();
    let ask = env.ask_python;
    let from_python = std::iter::once(()).filter(move |()| ask).flat_map(move |()| {
        pylsl_libraries(&python_site_dirs())
            .into_iter()
            .map(Candidate::File)
            .filter(|c| !known.contains(c))
            .collect::<Vec<_>>()
    });
    Box::new(ready.into_iter().chain(from_python))
}

/// The site-packages folders looked into without running Python.
fn site_dirs(env: &Environment) -> Vec<PathBuf> {
    let mut roots: Vec<PathBuf> = Vec::new();
    // Folders that hold `python3.X` folders, each with site-packages or dist-packages.
    let mut lib_roots: Vec<PathBuf> = Vec::new();
    if let Some(v) = &env.virtual_env {
        lib_roots.push(v.join("lib"));
        roots.push(v.join("Lib").join("site-packages"));
    }
    if let Some(c) = &env.conda_prefix {
        lib_roots.push(c.join("lib"));
    }
    if let Some(h) = &env.home {
        lib_roots.push(h.join(".local/lib"));
        for base in [".pyenv/versions", "miniconda3/envs", "anaconda3/envs", "mambaforge/envs"] {
            for v in children(&h.join(base)) {
                lib_roots.push(v.join("lib"));
            }
        }
        for conda in ["miniconda3", "anaconda3", "mambaforge", "miniforge3"] {
            lib_roots.push(h.join(conda).join("lib"));
        }
        lib_roots.push(h.join("Library/Python"));
    }
    lib_roots.extend(["/usr/local/lib", "/usr/lib", "/opt/homebrew/lib"].map(PathBuf::from));
    roots.push(PathBuf::from("/usr/lib/python3/dist-packages"));
    for lib in lib_roots {
        for py in children(&lib) {
            let named = py.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("python3"));
            if named || lib.ends_with("Library/Python") {
                roots.push(py.join("site-packages"));
                roots.push(py.join("dist-packages"));
                roots.push(py.join("lib/python/site-packages"));
            }
        }
    }
    roots
}

/// The folders inside `dir` (none when it cannot be read), bounded.
fn children(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else { return Vec::new() };
    rd.filter_map(Result::ok).take(256).map(|e| e.path()).filter(|p| p.is_dir()).collect()
}

/// pylsl's bundled libraries under `site_dirs`: `pylsl/lib/liblsl*` (or `lsl*.dll`), shortest name first.
fn pylsl_libraries(site_dirs: &[PathBuf]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for dir in site_dirs {
        let lib = dir.join("pylsl").join("lib");
        let Ok(rd) = std::fs::read_dir(&lib) else { continue };
        let mut here: Vec<PathBuf> = rd
            .filter_map(Result::ok)
            .take(64)
            .map(|e| e.path())
            .filter(|p| {
                p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                    let n = n.to_ascii_lowercase();
                    (n.starts_with("liblsl") || n.starts_with("lsl"))
                        && [".so", ".dylib", ".dll"].iter().any(|e| n.contains(e))
                })
            })
            .collect();
        here.sort_by_key(|p| p.as_os_str().len());
        for p in here {
            if !found.contains(&p) {
                found.push(p);
            }
        }
    }
    found
}

/// The site-packages folders `python3` reports, or none (no Python, or no answer within 3 s).
fn python_site_dirs() -> Vec<PathBuf> {
    let script = "import site,sys\nfor d in site.getsitepackages()+[site.getusersitepackages()]: print(d)";
    for python in ["python3", "python"] {
        let Ok(mut child) = Command::new(python)
            .args(["-I", "-c", script])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
        else {
            continue;
        };
        let deadline = Instant::now() + Duration::from_secs(3);
        loop {
            match child.try_wait() {
                Ok(Some(_)) => break,
                Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
                _ => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Vec::new();
                }
            }
        }
        let mut out = String::new();
        if let Some(mut s) = child.stdout.take() {
            use std::io::Read as _;
            let _ = s.by_ref().take(64 * 1024).read_to_string(&mut out);
        }
        return out.lines().map(str::trim).filter(|l| !l.is_empty()).map(PathBuf::from).collect();
    }
    Vec::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_explicit_library_is_the_only_candidate() {
        let env = Environment { explicit: Some("/nowhere/liblsl.so".into()), ..Environment::default() };
        let mut tried = Vec::new();
        let c: Vec<_> = candidates(&env, &mut tried).collect();
        assert_eq!(c, vec![Candidate::File("/nowhere/liblsl.so".into())]);
    }

    #[test]
    fn a_pylsl_lib_folder_is_found_in_a_virtualenv() {
        let dir = std::env::temp_dir().join(format!("vestnav-lsl-search-{}", std::process::id()));
        let lib = dir.join("lib/python3.12/site-packages/pylsl/lib");
        std::fs::create_dir_all(&lib).unwrap();
        std::fs::write(lib.join("liblsl.so"), b"x").unwrap();
        std::fs::write(lib.join("README"), b"x").unwrap();
        let env = Environment { virtual_env: Some(dir.clone()), ..Environment::default() };
        let mut tried = Vec::new();
        let c: Vec<_> = candidates(&env, &mut tried).collect();
        assert!(c.contains(&Candidate::File(lib.join("liblsl.so"))), "{c:?}");
        assert!(!c.contains(&Candidate::File(lib.join("README"))));
        // The system names come before pylsl's copy.
        let sys = c.iter().position(|x| matches!(x, Candidate::Name(_))).unwrap();
        let bundled = c.iter().position(|x| *x == Candidate::File(lib.join("liblsl.so"))).unwrap();
        assert!(sys < bundled);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
