//! How vestnav writes and opens the files a user owns: one home for three rules.
//!
//! - **Replace atomically** ([`write_atomic`]): the new content goes to a uniquely named temporary file
//!   in the same folder, is flushed to the disk (`fsync`), and then renamed over the target, so a crash,
//!   a full disk or a second writer never leaves a half-written settings file, route, figure or tile.
//! - **Open regular files only** ([`open_regular`]): a FIFO, a device node or a directory given where a
//!   file is expected is refused with a clear error instead of blocking the caller forever.
//! - **Create without replacing** ([`write_new`]): the same temporary file, linked in under the new name
//!   only if that name is free.
//! - **Keep a broken file** ([`keep_aside`]): a file the program cannot read is moved to
//!   `NAME.corrupt-<UTC time>` before anything writes a fresh one, and the caller says where it went.
//!
//! ```
//! let dir = std::env::temp_dir().join(format!("vestnav-files-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("settings.json");
//! vestnav_files::write_atomic(&path, b"{}").unwrap();
//! assert_eq!(std::fs::read(&path).unwrap(), b"{}");
//! let kept = vestnav_files::keep_aside(&path).unwrap();
//! assert!(!path.exists() && kept.exists());
//! # std::fs::remove_dir_all(&dir).unwrap();
//! ```

use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Replaces `path` with `bytes` atomically: a unique temporary file beside it (so two writers never share
/// one), written, `fsync`ed, renamed over `path`, and the folder synced where the platform allows. The
/// folder must exist: a path the user typed into a missing folder is an error naming it, never a folder
/// made silently ([`ensure_parent`] for the program's own folders). On error the temporary file is removed
/// and `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// [`write_atomic`] with the content produced by `fill` writing into the temporary file (for encoders
/// that stream, e.g. a PNG or a GPX writer).
pub fn write_atomic_with(path: &Path, fill: impl FnOnce(&mut File) -> io::Result<()>) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = temp_name(path);
    let result = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        fill(&mut f)?;
        f.flush()?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
        return result;
    }
    // The rename itself is durable only once the folder is synced (POSIX); not possible on every
    // platform, and the content is already safe either way.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes a new file at `path` with `bytes`, never replacing one that exists (an
/// [`io::ErrorKind::AlreadyExists`] error then, decided by the file system, not by an earlier look). The
/// content goes to a unique temporary file first (written, `fsync`ed) and is then linked in under its name,
/// so `path` never exists half-written. On file systems without hard links (FAT on a USB stick) the file is
/// created exclusively and written in place instead.
pub fn write_new(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = temp_name(path);
    let written = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    let linked = written.and_then(|()| std::fs::hard_link(&tmp, path));
    let _ = std::fs::remove_file(&tmp);
    match linked {
        Ok(()) => {
            if let Ok(d) = File::open(&dir) {
                let _ = d.sync_all();
            }
            Ok(())
        }
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Err(e),
        // No hard links here: exclusive creation still never replaces a file.
        Err(e) if matches!(e.kind(), io::ErrorKind::Unsupported | io::ErrorKind::PermissionDenied) => {
            let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(path)?;
            f.write_all(bytes)?;
            f.sync_all()
        }
        Err(e) => Err(e),
    }
}

/// A temporary name beside `path`, unique within this process (counter) and across processes (pid):
/// `.NAME.PID.N.tmp`.
fn temp_name(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path.file_name().map_or_else(|| "file".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// Creates the folder `path` goes in, when missing: for the program's own files (settings, autosave, tile
/// cache), never for a path the user typed.
pub fn ensure_parent(path: &Path) -> io::Result<()> {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => std::fs::create_dir_all(d),
        _ => Ok(()),
    }
}

/// Opens `path` for reading only when it is a regular file (following symbolic links). A FIFO, socket,
/// device or directory is refused without being opened, so reading a hostile path never blocks.
pub fn open_regular(path: &Path) -> io::Result<File> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, not_regular(&meta)));
    }
    let f = File::open(path)?;
    // The path could have been swapped between the check and the open: check what was opened.
    let meta = f.metadata()?;
    if meta.is_file() { Ok(f) } else { Err(io::Error::new(io::ErrorKind::InvalidInput, not_regular(&meta))) }
}

fn not_regular(meta: &std::fs::Metadata) -> String {
    let ft = meta.file_type();
    let what = if ft.is_dir() {
        "a folder"
    } else if ft.is_symlink() {
        "a link"
    } else {
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt as _;
            if ft.is_fifo() {
                "a FIFO (named pipe)"
            } else if ft.is_socket() {
                "a socket"
            } else if ft.is_block_device() || ft.is_char_device() {
                "a device"
            } else {
                "not a regular file"
            }
        }
        #[cfg(not(unix))]
        {
            "not a regular file"
        }
    };
    format!("{what}, not a regular file")
}

/// Reads a regular file of at most `limit` bytes; a larger one is refused (naming both sizes) before
/// its content is read.
pub fn read_limited(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let f = open_regular(path)?;
    let len = f.metadata()?.len();
    if len > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{len} bytes, more than the {limit} bytes accepted"),
        ));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    // The file may grow after the check: never read more than the limit.
    f.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("grew past the {limit} bytes accepted while being read"),
        ));
    }
    Ok(bytes)
}

/// Moves a file that could not be read out of the way, to `NAME.corrupt-<UTC time>` beside it (a
/// numbered suffix when that name is taken), so that nothing written afterwards destroys it. Returns where
/// it went.
pub fn keep_aside(path: &Path) -> io::Result<PathBuf> {
    let stamp = chrono::Utc::now().format("%Y%m%dT%H%M%SZ");
    let name = path.file_name().map_or_else(|| "file".into(), |n| n.to_string_lossy().into_owned());
    for i in 0..1000u32 {
        let candidate = if i == 0 {
            path.with_file_name(format!("{name}.corrupt-{stamp}"))
        } else {
            path.with_file_name(format!("{name}.corrupt-{stamp}-{i}"))
        };
        if candidate.exists() {
            continue;
        }
        std::fs::rename(path, &candidate)?;
        return Ok(candidate);
    }
    Err(io::Error::new(io::ErrorKind::AlreadyExists, "no free name to keep the file aside"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vestnav-files-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temporary() {
        let d = temp_dir("atomic");
        let p = d.join("a.json");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "{names:?}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_failed_fill_keeps_the_old_content() {
        let d = temp_dir("fail");
        let p = d.join("a.json");
        write_atomic(&p, b"old").unwrap();
        let err = write_atomic_with(&p, |_| Err(io::Error::other("disk full"))).unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn write_new_never_replaces_and_leaves_no_temporary() {
        let d = temp_dir("new");
        let p = d.join("pattern.json");
        write_new(&p, b"first").unwrap();
        let err = write_new(&p, b"second").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::AlreadyExists);
        assert_eq!(std::fs::read(&p).unwrap(), b"first");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn concurrent_writers_never_share_a_temporary() {
        let d = temp_dir("concurrent");
        let p = d.join("a.txt");
        std::thread::scope(|s| {
            for t in 0..4u8 {
                let p = &p;
                s.spawn(move || {
                    for _ in 0..50 {
                        write_atomic(p, &[t; 1000]).unwrap();
                    }
                });
            }
        });
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(bytes.len(), 1000);
        assert!(bytes.iter().all(|b| *b == bytes[0]), "a torn write");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let d = temp_dir("fifo");
        let p = d.join("tile.png");
        let status = std::process::Command::new("mkfifo").arg(&p).status().unwrap();
        assert!(status.success());
        let err = open_regular(&p).unwrap_err();
        assert!(err.to_string().contains("FIFO"), "{err}");
        let err = open_regular(&d).unwrap_err();
        assert!(err.to_string().contains("folder"), "{err}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn read_limited_refuses_large_files() {
        let d = temp_dir("limit");
        let p = d.join("big");
        std::fs::write(&p, vec![0u8; 100]).unwrap();
        assert_eq!(read_limited(&p, 100).unwrap().len(), 100);
        let err = read_limited(&p, 99).unwrap_err();
        assert!(err.to_string().contains("100 bytes"), "{err}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn keep_aside_never_overwrites_an_earlier_copy() {
        let d = temp_dir("aside");
        let p = d.join("console.json");
        std::fs::write(&p, b"first").unwrap();
        let a = keep_aside(&p).unwrap();
        std::fs::write(&p, b"second").unwrap();
        let b = keep_aside(&p).unwrap();
        assert_ne!(a, b);
        assert_eq!(std::fs::read(&a).unwrap(), b"first");
        assert_eq!(std::fs::read(&b).unwrap(), b"second");
        assert!(a.file_name().unwrap().to_string_lossy().starts_with("console.json.corrupt-"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
