//! Study mode: the protocols, trial plans, results and analysis of tactile-display experiments
//! (localization, pattern identification, navigation), as `docs/study.md` describes them.
//!
//! - [`protocol`]: the study protocol file (TOML), validated with errors that name the line;
//! - [`plan`]: each participant's trials in presentation order (seeded random, blocked, balanced Latin
//!   square), the same on every machine;
//! - [`record`]: one [`TrialRecord`] per trial, the tidy results CSV and JSON;
//! - [`info`]: confusion matrices and information transfer (maximum likelihood, its bias);
//! - [`navigation`]: one navigation trial's path length, route length and cross-track RMS;
//! - [`analysis`]: percent correct, IT, response times, learning curve, localization map, navigation.
//!
//! Pure like the rest of core: the runner (vestnav-station) owns the clock, the vest and the files it
//! appends to; only [`Protocol::load`] reads a file (and the pattern files a protocol names).
//!
//! ```
//! use vestnav_core::study::{Protocol, plan};
//! let text = r#"
//! name = "corners"
//! task = "localization"
//! participants = ["P1", "P2"]
//! order = "latin-square"
//! [localization]
//! stimuli = ["T0", "T3", "T12", "T15"]
//! [[block]]
//! name = "test"
//! repetitions = 2
//! "#;
//! let p = Protocol::parse(text, "corners.toml").unwrap();
//! let trials = plan(&p, "P2").unwrap();
//! assert_eq!(trials.len(), 8);
//! assert_eq!(p.choices().len(), 16);
//! ```

pub mod analysis;
pub mod info;
pub mod navigation;
mod parse;
pub mod plan;
pub mod protocol;
pub mod record;

pub use analysis::{StudyAnalysis, analyze};
pub use plan::{PlannedTrial, plan};
pub use protocol::{Block, Order, Protocol, ProtocolError, Stimulus, Task, TimingKeys};
pub use record::{CSV_COLUMNS, Outcome, TrialRecord, read_csv, write_csv, write_json};
