//! Folders the program writes: writable (or creatable) with free space.

use std::path::Path;

use super::{Area, Environment, Finding, Verdict, owner_of, permits};

/// Whether `role`'s folder `path` (absolute, as on the checked machine) is writable, or can be created,
/// with free space.
pub fn folder_finding(env: &Environment, role: &str, path: &Path) -> Finding {
    let finding = |verdict, detail: String| Finding::new(Area::Folders, role, verdict, detail);
    let shown = path.display();
    // The folder, or the nearest existing folder above it (it is created on first use).
    let mut existing = path.to_path_buf();
    let mut steps = 0;
    let meta = loop {
        match std::fs::metadata(env.at(&existing)) {
            Ok(m) => break m,
            Err(e)
                if matches!(e.kind(), std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory)
                    && steps < 64 =>
            {
                steps += 1;
                if !existing.pop() {
                    return finding(Verdict::Problem, format!("{shown}: no part of the path exists"));
                }
            }
            Err(e) => {
                return finding(Verdict::Problem, format!("cannot inspect {}: {e}", existing.display()));
            }
        }
    };
    let where_ = if existing == path {
        format!("{shown}")
    } else {
        format!("{} (to create {shown})", existing.display())
    };
    if !meta.is_dir() {
        return finding(Verdict::Problem, format!("{} is not a folder", existing.display()))
            .fix(format!("move the file {} aside", existing.display()));
    }
    if !permits(&env.identity, owner_of(&meta), 0o3) {
        return finding(Verdict::Problem, format!("{where_} is not writable by {}", env.identity.user))
            .fix(format!("sudo chown -R {} {}", env.identity.user, existing.display()));
    }
    if let Err(e) = probe_write(&env.at(&existing)) {
        return finding(Verdict::Problem, format!("{where_} cannot be written: {e}")).fix(
            if e.raw_os_error() == Some(READ_ONLY_FS) {
                "the file system is mounted read-only: remount it read-write, or choose another folder in the console's settings".to_owned()
            } else {
                format!("make {} writable for {}", existing.display(), env.identity.user)
            },
        );
    }
    match free_bytes(&env.at(&existing)) {
        Err(e) => finding(Verdict::Warning, format!("{where_} is writable; free space unknown: {e}")),
        Ok(free) if free < env.space.problem_below => {
            finding(Verdict::Problem, format!("{where_}: only {} free", human_bytes(free)))
                .fix("free disk space (the tile cache can be emptied in the console's Tiles window)")
        }
        Ok(free) if free < env.space.warning_below => finding(
            Verdict::Warning,
            format!("{where_}: {} free, little for a tile cache", human_bytes(free)),
        )
        .fix("free disk space, or lower the tile cache limit in the console's Tiles window"),
        Ok(free) => finding(Verdict::Ok, format!("{where_} is writable, {} free", human_bytes(free))),
    }
}

/// EROFS on Linux.
pub(super) const READ_ONLY_FS: i32 = 30;

/// Creates and removes a file in `dir`: what a mode check cannot see (a read-only mount, an ACL).
pub(super) fn probe_write(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".vestnav-doctor-{}", std::process::id()));
    std::fs::OpenOptions::new().write(true).create_new(true).open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(unix)]
pub(super) fn free_bytes(dir: &Path) -> std::io::Result<u64> {
    let s = rustix::fs::statvfs(dir)?;
    Ok(s.f_bavail.saturating_mul(s.f_frsize))
}

#[cfg(not(unix))]
pub(super) fn free_bytes(_dir: &Path) -> std::io::Result<u64> {
    Err(std::io::Error::other("not measured on this platform"))
}

/// `1.5 GB`, `320 MB`.
pub(super) fn human_bytes(bytes: u64) -> String {
    let mb = bytes as f64 / 1e6;
    if mb >= 1000.0 { format!("{:.1} GB", mb / 1000.0) } else { format!("{mb:.0} MB") }
}
