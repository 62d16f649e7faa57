//! The results files of one session: the CSV every finished trial is appended to at once (fsynced, so an
//! abort, a crash or a pulled plug loses no finished trial) and the JSON written at the end. A file that
//! exists is never overwritten: the first free name of `NAME.csv`, `NAME-2.csv`, `NAME-3.csv`, … is taken,
//! decided by the file system (exclusive creation), not by an earlier look.

use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use vestnav_core::study::TrialRecord;

/// Most numbered names tried before giving up.
const MAX_NAMES: usize = 1000;

/// The open results of one session.
#[derive(Debug)]
pub struct ResultsFile {
    csv: PathBuf,
    file: File,
}

/// A file-name part from an id: letters, digits, `-` and `_` kept, anything else `_`.
fn name_part(s: &str) -> String {
    let s: String = s
        .chars()
        .take(64)
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
        .collect();
    if s.is_empty() { "_".to_owned() } else { s }
}

impl ResultsFile {
    /// Creates the CSV of (`protocol`, `participant`, `session`) in `dir` (which must exist) with its
    /// header, under the first free name.
    pub fn create(dir: &Path, protocol: &str, participant: &str, session: &str) -> Result<Self, String> {
        let meta = std::fs::metadata(dir).map_err(|e| format!("results folder {}: {e}", dir.display()))?;
        if !meta.is_dir() {
            return Err(format!("results folder {}: not a folder", dir.display()));
        }
        let stem = format!("{}_{}_{}", name_part(protocol), name_part(participant), name_part(session));
        for n in 1..=MAX_NAMES {
            let name = if n == 1 { format!("{stem}.csv") } else { format!("{stem}-{n}.csv") };
            let path = dir.join(name);
            match std::fs::OpenOptions::new().append(true).create_new(true).open(&path) {
                Ok(mut file) => {
                    file.write_all(vestnav_core::study::record::csv_header().as_bytes())
                        .and_then(|()| file.sync_all())
                        .map_err(|e| format!("results {}: {e}", path.display()))?;
                    if let Ok(d) = File::open(dir) {
                        let _ = d.sync_all();
                    }
                    return Ok(Self { csv: path, file });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(format!("results {}: {e}", path.display())),
            }
        }
        Err(format!("results folder {}: {MAX_NAMES} results of {stem} exist already", dir.display()))
    }

    /// The CSV's path.
    pub fn csv_path(&self) -> &Path {
        &self.csv
    }

    /// Appends one row and fsyncs it.
    pub fn append(&mut self, row: &TrialRecord) -> Result<(), String> {
        let text = vestnav_core::study::record::csv_row(row);
        self.file.write_all(text.as_bytes()).and_then(|()| self.file.sync_data()).map_err(|e| {
            format!("results {}: row of trial {} not written: {e}", self.csv.display(), row.trial + 1)
        })
    }

    /// Writes every row as JSON beside the CSV (same name, `.json`; a numbered one when that exists);
    /// returns its path.
    pub fn write_json(&self, rows: &[TrialRecord]) -> Result<PathBuf, String> {
        let bytes = vestnav_core::study::write_json(rows).into_bytes();
        let stem = self.csv.with_extension("");
        for n in 1..=MAX_NAMES {
            let path = if n == 1 {
                self.csv.with_extension("json")
            } else {
                PathBuf::from(format!("{}.{n}.json", stem.display()))
            };
            match vestnav_files::write_new(&path, &bytes) {
                Ok(()) => return Ok(path),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(format!("results {}: {e}", path.display())),
            }
        }
        Err(format!("results JSON beside {}: no free name", self.csv.display()))
    }
}
