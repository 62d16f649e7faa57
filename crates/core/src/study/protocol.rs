//! The study protocol file (TOML): who takes part, the blocks, the task and its stimuli, the order.
//!
//! The format is documented with one example per task in `docs/study.md` (files in `docs/study/`). Parsing
//! goes in two steps: serde reads the TOML into raw tables that keep each value's byte span
//! ([`toml::Spanned`], module `parse`), then [`Protocol::parse`] checks every value and turns the span into the 1-based line
//! its error names. Nothing here touches the vest: the unit's own limits are applied by
//! [`Protocol::check_stimuli`] with a check the caller passes in (vestnav-device's `wtcu::Limits`).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::vest::{Frame, GRID, Pattern, TACTOR_COUNT, TactorMask};

/// Largest protocol file read [bytes]: a protocol is a page of text, 1 MiB is far beyond any real one.
pub const MAX_PROTOCOL_BYTES: u64 = 1 << 20;
/// Largest pattern-editor file a pattern-identification protocol reads [bytes] (the editor's own bound).
pub const MAX_PATTERN_FILE_BYTES: u64 = 1 << 20;
/// Most trials one participant's plan may hold (every block, every repetition).
pub const MAX_TRIALS: usize = 20_000;
/// Most stimuli (tactors, tactor sets, patterns, or route x condition pairs) in one protocol.
pub const MAX_STIMULI: usize = 256;
/// Most participants listed in one protocol.
pub const MAX_PARTICIPANTS: usize = 10_000;
/// Most frames of one inline pattern (the unit's own limit is lower; see [`Protocol::check_stimuli`]).
pub const MAX_FRAMES: usize = 256;

/// Default on-time of a localization stimulus [ms] (the thesis's 500 ms, [`crate::vest::DEFAULT_ON_MS`]).
pub const DEFAULT_ON_MS: u16 = crate::vest::DEFAULT_ON_MS;
/// The cue sets a navigation condition may name: `walking` (the walking vocabulary only) and
/// `turn-in-place` (plus the graded turn-on-the-spot cues while standing, `GuidanceConfig::turn_in_place`).
pub const CUE_SETS: [&str; 2] = ["walking", "turn-in-place"];
/// Default intensity (the unit's full level).
pub const DEFAULT_INTENSITY: u8 = 255;

/// The kind of task a protocol runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Task {
    /// One tactor (or a set) per trial; the wearer reports where.
    Localization,
    /// One named pattern per trial; the wearer names it.
    PatternId,
    /// One route under one condition per trial; the wearer walks it.
    Navigation,
}

impl Task {
    /// Every task.
    pub const ALL: [Self; 3] = [Self::Localization, Self::PatternId, Self::Navigation];

    /// The name in protocol files and in the results' `task` column.
    pub fn name(self) -> &'static str {
        match self {
            Self::Localization => "localization",
            Self::PatternId => "pattern-id",
            Self::Navigation => "navigation",
        }
    }

    /// Parses [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// How the trials of a block are ordered (see [`crate::study::plan`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    /// Every stimulus `repetitions` times, shuffled by the protocol's seed and the participant's id.
    Random,
    /// Each stimulus `repetitions` times in a row, stimuli in the protocol's order.
    Blocked,
    /// A row of a balanced Latin square (Williams design) chosen by the participant's index, repeated.
    LatinSquare,
}

impl Order {
    /// Every order.
    pub const ALL: [Self; 3] = [Self::Random, Self::Blocked, Self::LatinSquare];

    /// The name in protocol files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Random => "random",
            Self::Blocked => "blocked",
            Self::LatinSquare => "latin-square",
        }
    }

    /// Parses [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == name)
    }
}

/// One block of trials: every stimulus of the protocol `repetitions` times.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Block {
    /// Name shown to the operator and written to the results.
    pub name: String,
    /// A training block (all training blocks come before the test blocks).
    pub training: bool,
    /// Whether the wearer is told the correct answer after each response.
    pub feedback: bool,
    /// How many times each stimulus is presented in this block (at least 1).
    pub repetitions: u32,
    /// The block's order (the protocol's unless the block sets its own).
    pub order: Order,
    /// The 1-based line of the block's table in the protocol file.
    pub line: usize,
    /// The timing keys the block sets itself; each wins over the protocol's key of the same name
    /// ([`Protocol::block_timing`]).
    #[serde(default)]
    pub timing: TimingKeys,
}

/// What the vest presents in one trial.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Stimulus {
    /// Localization: these tactors on together for `on_ms`, `repeats` times with `isi_ms` off between.
    Tactors {
        /// The tactors (one, or a set).
        tactors: TactorMask,
        /// On-time of each presentation [ms].
        on_ms: u16,
        /// Intensity level (1..=255).
        intensity: u8,
        /// Presentations per trial (at least 1).
        repeats: u8,
        /// Inter-stimulus interval: off-time after each presentation [ms].
        isi_ms: u16,
    },
    /// Pattern identification: a named pattern.
    Pattern {
        /// The pattern's name (the answer the wearer gives).
        name: String,
        /// The frames: (tactor mask, duration [ms]).
        frames: Vec<(u16, u16)>,
        /// How many times the frames play (at least 1).
        repeats: u8,
        /// Intensity level (1..=255).
        intensity: u8,
    },
    /// Navigation: a route walked under one condition.
    Navigation {
        /// The route file (GPX or vestnav route), resolved against the protocol's folder.
        route: PathBuf,
        /// The condition's name.
        condition: String,
        /// Guidance strategy name (`bearing`, `pursuit`).
        strategy: String,
        /// Heading source (`auto`, `compass`, `cog`).
        heading: String,
        /// Cue set: `walking` (no turn-in-place cues) or `turn-in-place`.
        cue_set: String,
        /// Repeat interval of a steering cue [s].
        cue_interval_s: f64,
    },
}

/// Every tactor's label, by tactor index (row-major on the back view).
pub const GRID_LABELS: [&str; TACTOR_COUNT] =
    ["T0", "T1", "T2", "T3", "T4", "T5", "T6", "T7", "T8", "T9", "T10", "T11", "T12", "T13", "T14", "T15"];

/// The label of a tactor (one home for every view: [`crate::vest::tactor_label`]).
pub use crate::vest::tactor_label;

/// The label of a set of tactors: the tactor labels joined by `+` (`T0+T3`), ascending.
pub fn mask_label(mask: TactorMask) -> String {
    mask.indices().map(tactor_label).collect::<Vec<_>>().join("+")
}

/// Parses a tactor label ([`crate::vest::parse_tactor_label`]).
pub use crate::vest::parse_tactor_label;

/// Parses a set label (`T0+T3`; one tactor alone is a set of one; an empty string is the empty set).
pub fn parse_mask_label(label: &str) -> Option<TactorMask> {
    if label.trim().is_empty() {
        return Some(TactorMask::NONE);
    }
    label.split('+').try_fold(TactorMask::NONE, |m, part| {
        parse_tactor_label(part).and_then(TactorMask::single).map(|t| m | t)
    })
}

/// The grid position (row, column) of a tactor label, for the 4x4 back view.
pub fn label_cell(label: &str) -> Option<(usize, usize)> {
    parse_tactor_label(label).map(|i| (i / GRID, i % GRID))
}

impl Stimulus {
    /// The label of this stimulus: `T2` / `T0+T3`, a pattern's name, `ROUTE/CONDITION` (route file stem).
    pub fn label(&self) -> String {
        match self {
            Self::Tactors { tactors, .. } => mask_label(*tactors),
            Self::Pattern { name, .. } => name.clone(),
            Self::Navigation { route, condition, .. } => {
                let stem = route
                    .file_stem()
                    .map_or_else(|| route.display().to_string(), |s| s.to_string_lossy().into_owned());
                format!("{stem}/{condition}")
            }
        }
    }

    /// The correct choice: the stimulus's own label (navigation trials have no choice; their label).
    pub fn answer(&self) -> String {
        self.label()
    }

    /// The vest pattern this stimulus plays; `None` for navigation (guidance plays its cues).
    ///
    /// Tactors: the frames `[(tactors, on_ms), (none, isi_ms)]` (the pause left out when `isi_ms` is 0),
    /// played `repeats` times. Patterns: their frames and repeats.
    pub fn pattern(&self) -> Option<Pattern> {
        match self {
            Self::Tactors { tactors, on_ms, repeats, isi_ms, .. } => {
                let mut frames = vec![Frame { mask: *tactors, duration_ms: *on_ms }];
                if *isi_ms > 0 {
                    frames.push(Frame { mask: TactorMask::NONE, duration_ms: *isi_ms });
                }
                Some(Pattern { name: self.label(), frames, repeats: *repeats })
            }
            Self::Pattern { name, frames, repeats, .. } => Some(Pattern {
                name: name.clone(),
                frames: frames
                    .iter()
                    .map(|&(m, ms)| Frame { mask: TactorMask(m), duration_ms: ms })
                    .collect(),
                repeats: *repeats,
            }),
            Self::Navigation { .. } => None,
        }
    }

    /// The intensity level the stimulus plays at; `None` for navigation.
    pub fn intensity(&self) -> Option<u8> {
        match self {
            Self::Tactors { intensity, .. } | Self::Pattern { intensity, .. } => Some(*intensity),
            Self::Navigation { .. } => None,
        }
    }

    /// The tactors a stimulus uses (a pattern's union of frames); empty for navigation.
    pub fn mask(&self) -> TactorMask {
        match self {
            Self::Tactors { tactors, .. } => *tactors,
            Self::Pattern { frames, .. } => {
                frames.iter().fold(TactorMask::NONE, |a, &(m, _)| a | TactorMask(m))
            }
            Self::Navigation { .. } => TactorMask::NONE,
        }
    }
}

/// One problem found in a protocol: its 1-based line when it has one, and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Problem {
    /// 1-based line in the file; `None` for a problem of the whole file (unreadable, too large).
    pub line: Option<usize>,
    /// What is wrong, in words.
    pub message: String,
}

/// Why a protocol was refused: the source (file path or name) and every problem found, each with its line.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProtocolError {
    /// The protocol's source as the caller named it (usually its path).
    pub source_name: String,
    /// The problems, in file order (at least one).
    pub problems: Vec<Problem>,
}

impl ProtocolError {
    /// One problem of `source_name`.
    pub fn new(source_name: &str, line: Option<usize>, message: impl Into<String>) -> Self {
        Self {
            source_name: source_name.to_owned(),
            problems: vec![Problem { line, message: message.into() }],
        }
    }

    /// The line of the first problem.
    pub fn line(&self) -> Option<usize> {
        self.problems.first().and_then(|p| p.line)
    }
}

impl std::fmt::Display for ProtocolError {
    /// One line per problem: `SOURCE:LINE: message` (`SOURCE: message` without a line).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, p) in self.problems.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            match p.line {
                Some(line) => write!(f, "{}:{line}: {}", self.source_name, p.message)?,
                None => write!(f, "{}: {}", self.source_name, p.message)?,
            }
        }
        Ok(())
    }
}

impl std::error::Error for ProtocolError {}

/// A validated study protocol.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Protocol {
    /// The protocol's name (written to every result row).
    pub name: String,
    /// Free text for the experimenter.
    pub description: String,
    /// Where it was read from (as given to [`Protocol::parse`]).
    pub source: String,
    /// The task.
    pub task: Task,
    /// Participant ids in the order the Latin square assigns rows (may be empty for random/blocked orders).
    pub participants: Vec<String>,
    /// Session ids the study foresees (informative; the runner takes any id).
    pub sessions: Vec<String>,
    /// The blocks, training blocks first.
    pub blocks: Vec<Block>,
    /// The default order of the blocks' trials.
    pub order: Order,
    /// Seed of the random orders.
    pub seed: u64,
    /// The stimuli, in the protocol's order (routes x conditions for navigation, route-major).
    pub stimuli: Vec<Stimulus>,
    /// The 1-based line each stimulus was defined on (parallel to `stimuli`).
    pub stimulus_lines: Vec<usize>,
    /// The timing keys the protocol sets (each wins over the runner's default for it).
    #[serde(default)]
    pub timing: TimingKeys,
}

/// Timing keys of a protocol or of one of its blocks; `None` where the file leaves the value to the next
/// level: a block's to the protocol's, the protocol's to the runner's default (the station's settings,
/// `vestnav study run`'s flags).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TimingKeys {
    /// `iti_ms`: the pause between two trials [ms] (0..=60000).
    pub iti_ms: Option<u32>,
    /// `feedback_ms`: how long feedback lasts at least [ms] (0..=60000).
    pub feedback_ms: Option<u32>,
    /// `response_timeout_s`: no response this long after stimulus onset records `no-response` [s]
    /// (0.5..=3600).
    pub response_timeout_s: Option<f64>,
    /// `[navigation] time_limit_s` (a navigation block's `time_limit_s`): a navigation trial not ended by
    /// arrival or the operator ends after this long [s] (10..=14400).
    pub time_limit_s: Option<f64>,
}

impl TimingKeys {
    /// These keys, each one left out taken from `outer` (a block's keys over its protocol's).
    #[must_use]
    pub fn over(self, outer: &Self) -> Self {
        Self {
            iti_ms: self.iti_ms.or(outer.iti_ms),
            feedback_ms: self.feedback_ms.or(outer.feedback_ms),
            response_timeout_s: self.response_timeout_s.or(outer.response_timeout_s),
            time_limit_s: self.time_limit_s.or(outer.time_limit_s),
        }
    }

    /// Whether no key is set.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// The keys set, as a protocol writes them (`iti_ms = 500, response_timeout_s = 3`); `none` when
    /// none is.
    pub fn summary(&self) -> String {
        let mut out: Vec<String> = Vec::new();
        if let Some(v) = self.iti_ms {
            out.push(format!("iti_ms = {v}"));
        }
        if let Some(v) = self.feedback_ms {
            out.push(format!("feedback_ms = {v}"));
        }
        if let Some(v) = self.response_timeout_s {
            out.push(format!("response_timeout_s = {v}"));
        }
        if let Some(v) = self.time_limit_s {
            out.push(format!("time_limit_s = {v}"));
        }
        if out.is_empty() { "none".to_owned() } else { out.join(", ") }
    }
}

/// Range of `iti_ms` and `feedback_ms` [ms].
pub const TIMING_MS: std::ops::RangeInclusive<i64> = 0..=60_000;
/// Range of `response_timeout_s` [s].
pub const RESPONSE_TIMEOUT_S: std::ops::RangeInclusive<f64> = 0.5..=3600.0;
/// Range of `[navigation] time_limit_s` [s].
pub const TIME_LIMIT_S: std::ops::RangeInclusive<f64> = 10.0..=14_400.0;

impl Protocol {
    /// Parses and validates a protocol. `source` names it in errors and locates the files it refers to
    /// (pattern files, routes: relative paths are taken in `source`'s folder).
    pub fn parse(text: &str, source: &str) -> Result<Protocol, ProtocolError> {
        let base = Path::new(source).parent().map(Path::to_path_buf).unwrap_or_default();
        Self::parse_in(text, source, &base)
    }

    /// [`Self::parse`] with the folder relative file names are taken in given explicitly.
    pub fn parse_in(text: &str, source: &str, base: &Path) -> Result<Protocol, ProtocolError> {
        if text.len() as u64 > MAX_PROTOCOL_BYTES {
            return Err(ProtocolError::new(
                source,
                None,
                format!("larger than {MAX_PROTOCOL_BYTES} bytes, not a protocol"),
            ));
        }
        super::parse::parse(text, source, base)
    }

    /// Reads and parses a protocol file, at most [`MAX_PROTOCOL_BYTES`]; errors name the path.
    pub fn load(path: &Path) -> Result<Protocol, ProtocolError> {
        let source = path.display().to_string();
        let text = super::parse::read_bounded(path, MAX_PROTOCOL_BYTES)
            .map_err(|m| ProtocolError::new(&source, None, m))?;
        Self::parse(&text, &source)
    }

    /// Checks every stimulus's vest pattern with `check` (the unit's limits, e.g. vestnav-device's
    /// `wtcu::Limits::check_pattern`); the error names each refused stimulus's line and `check`'s reason.
    pub fn check_stimuli(&self, check: impl Fn(&Pattern) -> Result<(), String>) -> Result<(), ProtocolError> {
        let problems: Vec<Problem> = self
            .stimuli
            .iter()
            .zip(&self.stimulus_lines)
            .filter_map(|(s, &line)| {
                let pattern = s.pattern()?;
                check(&pattern).err().map(|why| Problem {
                    line: Some(line),
                    message: format!("stimulus {}: {why}", s.label()),
                })
            })
            .collect();
        if problems.is_empty() {
            Ok(())
        } else {
            Err(ProtocolError { source_name: self.source.clone(), problems })
        }
    }

    /// The answers the operator can click: the 16 tactor labels `T0`..`T15` for localization (followed by
    /// the label of each tactor set the protocol presents), the pattern names for pattern identification,
    /// nothing for navigation.
    pub fn choices(&self) -> Vec<String> {
        match self.task {
            Task::Localization => {
                let mut out: Vec<String> = (0..TACTOR_COUNT).map(tactor_label).collect();
                for s in &self.stimuli {
                    let label = s.label();
                    if !out.contains(&label) {
                        out.push(label);
                    }
                }
                out
            }
            Task::PatternId => self.stimuli.iter().map(Stimulus::label).collect(),
            Task::Navigation => Vec::new(),
        }
    }

    /// Trials one participant runs (every block, every repetition).
    pub fn trials_per_participant(&self) -> usize {
        self.blocks.iter().map(|b| b.repetitions as usize * self.stimuli.len()).sum()
    }

    /// The timing keys of block `block` (0-based): the block's own keys, each one it leaves out taken from
    /// the protocol's. Keys set at neither level stay `None` (the runner's default). A block index past
    /// the last gives the protocol's keys.
    pub fn block_timing(&self, block: usize) -> TimingKeys {
        self.blocks.get(block).map_or(self.timing, |b| b.timing.over(&self.timing))
    }

    /// Where `participant` stands in [`Self::participants`] (0-based).
    pub fn participant_index(&self, participant: &str) -> Option<usize> {
        self.participants.iter().position(|p| p == participant)
    }
}

#[cfg(test)]
#[path = "protocol_tests.rs"]
mod tests;
