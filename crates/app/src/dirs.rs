//! The console's own folders on this platform (`directories::ProjectDirs` of org.vestnav.vestnav): where
//! the settings file, the session logs, the route autosave and the tile cache go when nothing else is
//! named. A leaf module: the settings ([`crate::config`]) and the file fields ([`crate::file_dialog`]) both
//! take their folders from here without importing each other.

use std::path::PathBuf;

/// The platform directories of vestnav, if the OS has a home directory.
pub(crate) fn project_dirs() -> Option<directories::ProjectDirs> {
    directories::ProjectDirs::from("org", "vestnav", "vestnav")
}

/// Directory for session logs and the tile cache when the config names none.
pub fn data_dir() -> PathBuf {
    project_dirs().map_or_else(|| std::env::temp_dir().join("vestnav"), |d| d.data_dir().to_path_buf())
}
