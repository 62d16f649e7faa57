//! The vest: 16 tactors in a 4x4 grid on the lower back, masks of tactors and timed patterns (thesis §6).
//!
//! Numbering, used everywhere in vestnav (CLI, protocol, UI): the grid is seen **from behind the wearer**
//! (the operator's view of the back), row-major from the top-left. Row 0 is the top row, column 0 is on the
//! wearer's left. Tactor `i` sits at row `i / 4`, column `i % 4`; bit `i` of a [`TactorMask`] is tactor `i`.
//!
//! ```text
//!   wearer's left            wearer's right
//!        0    1    2    3      (top)
//!        4    5    6    7
//!        8    9   10   11
//!       12   13   14   15      (bottom, near the waist)
//! ```
//!
//! Published patterns (thesis §6): "stop" fires the four corners; "turn left/right" sweeps a vibrating column
//! across the back toward the turn; a tactor is normally on for 500 ms. The rest of the vocabulary below
//! (forward, slight turns, turn around, attention, arrived) is vestnav's own design in the same spirit.

use serde::{Deserialize, Serialize};

/// Number of tactors on the vest.
pub const TACTOR_COUNT: usize = 16;
/// Rows and columns of the grid.
pub const GRID: usize = 4;
/// Default on-time of a tactor, as in the thesis's vest controller [ms].
pub const DEFAULT_ON_MS: u16 = 500;
/// Current drawn by one running tactor [A] (thesis §4: ~70 mA at 200 Hz drive).
pub const TACTOR_CURRENT_A: f64 = 0.070;

/// The label of tactor `index` everywhere a person reads one (the Vest panel's grid, the drive controls,
/// a study's stimuli, responses and results): `T0`..`T15`, the tactor's bit in a [`TactorMask`].
pub fn tactor_label(index: usize) -> String {
    format!("T{index}")
}

/// Parses a tactor label (`T0`..`T15`, case-insensitive, surrounding blanks allowed) to its index.
pub fn parse_tactor_label(label: &str) -> Option<usize> {
    let digits = label.trim().strip_prefix(['T', 't'])?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok().filter(|&n| n < TACTOR_COUNT)
}

/// The tactors next to tactor `index` on the grid, in the order above, below, left, right (two in a
/// corner, three on an edge, four inside; none for an index off the vest): the places a wearer most often
/// mistakes it for (the simulated wearers of study mode draw their confusions from these).
pub fn grid_neighbours(index: usize) -> Vec<usize> {
    if index >= TACTOR_COUNT {
        return Vec::new();
    }
    let (r, c) = (index / GRID, index % GRID);
    [
        (r > 0).then(|| index - GRID),
        (r + 1 < GRID).then_some(index + GRID),
        (c > 0).then(|| index - 1),
        (c + 1 < GRID).then_some(index + 1),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// A set of tactors: bit `i` is tactor `i` (see the module doc for the numbering).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct TactorMask(pub u16);

impl TactorMask {
    /// No tactor.
    pub const NONE: Self = Self(0);
    /// All 16 tactors.
    pub const ALL: Self = Self(0xFFFF);
    /// The four corners: 0, 3, 12, 15.
    pub const CORNERS: Self = Self(1 | 1 << 3 | 1 << 12 | 1 << 15);

    /// The single tactor `index`; `None` if `index >= 16`.
    pub fn single(index: usize) -> Option<Self> {
        (index < TACTOR_COUNT).then(|| Self(1 << index))
    }

    /// The tactor at `row`, `col` (0-based, see the module doc); `None` outside the grid.
    pub fn at(row: usize, col: usize) -> Option<Self> {
        (row < GRID && col < GRID).then(|| Self(1 << (row * GRID + col)))
    }

    /// Every tactor of column `col` (0 = wearer's left).
    pub fn column(col: usize) -> Self {
        (0..GRID).filter_map(|row| Self::at(row, col)).fold(Self::NONE, |a, b| a | b)
    }

    /// Every tactor of row `row` (0 = top).
    pub fn row(row: usize) -> Self {
        (0..GRID).filter_map(|col| Self::at(row, col)).fold(Self::NONE, |a, b| a | b)
    }

    /// Builds a mask from tactor indices; indices `>= 16` are ignored.
    pub fn from_indices(indices: impl IntoIterator<Item = usize>) -> Self {
        indices.into_iter().filter_map(Self::single).fold(Self::NONE, |a, b| a | b)
    }

    /// Whether tactor `index` is in the set.
    pub fn contains(self, index: usize) -> bool {
        index < TACTOR_COUNT && self.0 & (1 << index) != 0
    }

    /// How many tactors are in the set.
    pub fn count(self) -> u32 {
        self.0.count_ones()
    }

    /// Whether the set is empty.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The indices in the set, ascending.
    pub fn indices(self) -> impl Iterator<Item = usize> {
        (0..TACTOR_COUNT).filter(move |&i| self.contains(i))
    }

    /// Supply current if every tactor in the set runs [A], at [`TACTOR_CURRENT_A`] each.
    pub fn current_a(self) -> f64 {
        f64::from(self.count()) * TACTOR_CURRENT_A
    }
}

impl std::ops::BitOr for TactorMask {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

impl std::ops::BitAnd for TactorMask {
    type Output = Self;
    fn bitand(self, rhs: Self) -> Self {
        Self(self.0 & rhs.0)
    }
}

/// One step of a pattern: these tactors on for this long (then the next frame starts).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Frame {
    /// Tactors on during the frame (an empty mask is a pause).
    pub mask: TactorMask,
    /// Length of the frame [ms].
    pub duration_ms: u16,
}

/// A timed sequence of frames, played `repeats` times (1 = once).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Pattern {
    /// Name shown to the operator.
    pub name: String,
    /// The frames, in order.
    pub frames: Vec<Frame>,
    /// How many times the frames are played; at least 1.
    pub repeats: u8,
}

impl Pattern {
    /// What a wearer feels of the pattern, durations aside: each change of the tactors that are on (off
    /// included) over every repeat, without the off before the first or after the last. Frames of no
    /// duration are not felt.
    pub fn felt_masks(&self) -> Vec<TactorMask> {
        let played = (0..self.repeats.max(1)).flat_map(|_| self.frames.iter());
        felt(played.filter(|f| f.duration_ms > 0).map(|f| f.mask))
    }

    /// Total time the pattern takes [ms], all repeats included: `max(repeats, 1) * sum(duration_ms)`, saturating
    /// at `u32::MAX` (a pattern read from a file may hold any number of frames).
    pub fn total_ms(&self) -> u32 {
        let once: u64 = self.frames.iter().map(|f| u64::from(f.duration_ms)).sum();
        saturate_u32(once.saturating_mul(u64::from(self.repeats.max(1))))
    }

    /// Longest continuous on-time of any single tactor over the whole played pattern, all repeats included
    /// [ms]: the maximum of [`Self::longest_on_ms_of`] over the 16 tactors.
    pub fn longest_on_ms(&self) -> u32 {
        (0..TACTOR_COUNT).map(|t| self.longest_on_ms_of(t)).max().unwrap_or(0)
    }

    /// Longest continuous on-time of tactor `tactor` over the whole played pattern, all repeats included [ms].
    ///
    /// A run is a stretch of consecutive frames containing the tactor; frames of 0 ms are skipped (they
    /// neither add on-time nor interrupt a run). With `r = max(repeats, 1)` passes over frames of total time
    /// `T`, in closed form (no expansion of the repeats):
    /// - on in every (non-empty) frame: the tactor never goes off, the run is `r * T`;
    /// - otherwise it is off somewhere in each pass, so no run spans more than one wrap:
    ///   `max(M, S + P)` where `M` is the longest run within one pass, `P` the on-time of the leading run
    ///   (frames from the first one), `S` that of the trailing run (frames up to the last one), and the wrap
    ///   term `S + P` only counts when `r >= 2`.
    ///
    /// Saturates at `u32::MAX`.
    pub fn longest_on_ms_of(&self, tactor: usize) -> u32 {
        let frames = || self.frames.iter().filter(|f| f.duration_ms > 0);
        let repeats = u64::from(self.repeats.max(1));
        if frames().all(|f| f.mask.contains(tactor)) {
            let once: u64 = frames().map(|f| u64::from(f.duration_ms)).sum();
            return saturate_u32(once.saturating_mul(repeats));
        }
        let (mut longest, mut run) = (0u64, 0u64);
        for f in frames() {
            run = if f.mask.contains(tactor) { run + u64::from(f.duration_ms) } else { 0 };
            longest = longest.max(run);
        }
        if repeats >= 2 {
            let leading = self.leading_run_once(tactor);
            let trailing: u64 = frames()
                .rev()
                .take_while(|f| f.mask.contains(tactor))
                .map(|f| u64::from(f.duration_ms))
                .sum();
            longest = longest.max(trailing + leading);
        }
        saturate_u32(longest)
    }

    /// Continuous on-time of tactor `tactor` from the very start of the pattern [ms]: how long a tactor that
    /// is already on when the pattern starts stays on without a break. `r * T` when it is on in every
    /// (non-empty) frame (see [`Self::longest_on_ms_of`]), otherwise `P`, the on-time of the leading run
    /// (0 when the first non-empty frame does not contain it). Saturates at `u32::MAX`.
    pub fn leading_on_ms(&self, tactor: usize) -> u32 {
        let frames = || self.frames.iter().filter(|f| f.duration_ms > 0);
        if frames().all(|f| f.mask.contains(tactor)) {
            let once: u64 = frames().map(|f| u64::from(f.duration_ms)).sum();
            return saturate_u32(once.saturating_mul(u64::from(self.repeats.max(1))));
        }
        saturate_u32(self.leading_run_once(tactor))
    }

    /// On-time of the run of `tactor` that starts with the first non-empty frame, within one pass [ms].
    fn leading_run_once(&self, tactor: usize) -> u64 {
        self.frames
            .iter()
            .filter(|f| f.duration_ms > 0)
            .take_while(|f| f.mask.contains(tactor))
            .map(|f| u64::from(f.duration_ms))
            .sum()
    }

    /// Largest number of tactors on at once in any frame.
    pub fn max_simultaneous(&self) -> u32 {
        self.frames.iter().map(|f| f.mask.count()).max().unwrap_or(0)
    }
}

fn saturate_u32(ms: u64) -> u32 {
    u32::try_from(ms).unwrap_or(u32::MAX)
}

/// The named cues of vestnav's tactile vocabulary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Cue {
    /// Keep going straight: the two middle columns pulse bottom-to-top.
    Forward,
    /// Bear slightly left: the left column, once.
    SlightLeft,
    /// Bear slightly right: the right column, once.
    SlightRight,
    /// Turn left: a column sweeps right-to-left across the back (thesis §6).
    TurnLeft,
    /// Turn right: a column sweeps left-to-right across the back (thesis §6).
    TurnRight,
    /// Turn around: the bottom row then a sweep top-to-bottom, twice.
    TurnAround,
    /// Stop: the four corners (thesis §6).
    Stop,
    /// Attention / hold (no reliable direction): the middle four, twice.
    Attention,
    /// Waypoint reached: a short burst of all tactors (waypoint belts, thesis §6), as two halves to stay
    /// inside the current budget.
    Arrived,
    /// Standing still, turn left on the spot by about this much: a half-height column sweeps right-to-left
    /// across the lower back, the longer the sweep the larger the turn ([`TurnStep`]).
    RotateLeft(TurnStep),
    /// Standing still, turn right on the spot by about this much (mirror of [`Cue::RotateLeft`]).
    RotateRight(TurnStep),
}

/// Size of a turn-in-place cue: the thesis's "turn a certain number of degrees" (future work), in four
/// grades a wearer can tell apart by the length of the sweep (see `docs/guidance.md`, turn-by-degrees).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum TurnStep {
    /// About 30° (a bearing error up to 45°): a two-column sweep from the middle to the turn side.
    Deg30,
    /// About 60° (45°–75°): a three-column sweep.
    Deg60,
    /// About 90° (75°–112.5°): the four-column sweep across the whole back.
    Deg90,
    /// 135° or more (beyond 112.5°): the four-column sweep twice.
    Deg135,
}

impl TurnStep {
    /// Every grade, smallest first.
    pub const ALL: [Self; 4] = [Self::Deg30, Self::Deg60, Self::Deg90, Self::Deg135];

    /// The nominal turn of this grade [deg].
    pub fn degrees(self) -> f64 {
        match self {
            Self::Deg30 => 30.0,
            Self::Deg60 => 60.0,
            Self::Deg90 => 90.0,
            Self::Deg135 => 135.0,
        }
    }

    /// The grade whose nominal turn is nearest to `|error_deg|`: boundaries at the midpoints 45°, 75° and
    /// 112.5° (a tie goes to the smaller turn, so a wearer never overshoots by more than half a grade).
    /// A non-finite error gives the smallest grade.
    pub fn for_error_deg(error_deg: f64) -> Self {
        let e = error_deg.abs();
        if !e.is_finite() || e <= 45.0 {
            Self::Deg30
        } else if e <= 75.0 {
            Self::Deg60
        } else if e <= 112.5 {
            Self::Deg90
        } else {
            Self::Deg135
        }
    }

    /// Columns swept by the turn-in-place pattern of this grade (two for 30°, up to all four).
    pub fn columns(self) -> usize {
        match self {
            Self::Deg30 => 2,
            Self::Deg60 => 3,
            Self::Deg90 | Self::Deg135 => GRID,
        }
    }

    /// Times the sweep is played (twice for 135°+, once otherwise).
    pub fn sweeps(self) -> u8 {
        if self == Self::Deg135 { 2 } else { 1 }
    }
}

impl Cue {
    /// Every cue, in the order shown to the operator.
    pub const ALL: [Self; 9] = [
        Self::Stop,
        Self::Forward,
        Self::SlightLeft,
        Self::SlightRight,
        Self::TurnLeft,
        Self::TurnRight,
        Self::TurnAround,
        Self::Attention,
        Self::Arrived,
    ];

    /// The graded turn-in-place cues (not in [`Cue::ALL`], the operator's manual buttons): left then right,
    /// smallest turn first.
    pub const TURN_IN_PLACE: [Self; 8] = [
        Self::RotateLeft(TurnStep::Deg30),
        Self::RotateLeft(TurnStep::Deg60),
        Self::RotateLeft(TurnStep::Deg90),
        Self::RotateLeft(TurnStep::Deg135),
        Self::RotateRight(TurnStep::Deg30),
        Self::RotateRight(TurnStep::Deg60),
        Self::RotateRight(TurnStep::Deg90),
        Self::RotateRight(TurnStep::Deg135),
    ];

    /// The cue a wearer who knows the vocabulary recognises in a sequence of tactor states (each change of
    /// the tactors on, as [`Pattern::felt_masks`] gives it; offs before and after are ignored): the cue of
    /// [`Cue::ALL`] or [`Cue::TURN_IN_PLACE`] whose pattern feels the same, at any on-time. `None` for
    /// anything else (a tactor fired by hand, a pattern cut short by STOP ALL, a user's pattern).
    pub fn recognise(masks: &[TactorMask]) -> Option<Self> {
        let seq = felt(masks.iter().copied());
        if seq.is_empty() {
            return None;
        }
        Self::ALL
            .into_iter()
            .chain(Self::TURN_IN_PLACE)
            .find(|c| c.pattern(DEFAULT_ON_MS).felt_masks() == seq)
    }

    /// The turn-in-place cue toward a bearing error `error_deg` (positive = aim to the right), graded by
    /// [`TurnStep::for_error_deg`].
    pub fn rotate_toward(error_deg: f64) -> Self {
        let step = TurnStep::for_error_deg(error_deg);
        if error_deg > 0.0 { Self::RotateRight(step) } else { Self::RotateLeft(step) }
    }

    /// Whether this is a turn-in-place cue.
    pub fn is_turn_in_place(self) -> bool {
        matches!(self, Self::RotateLeft(_) | Self::RotateRight(_))
    }

    /// Human name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Forward => "forward",
            Self::SlightLeft => "slight left",
            Self::SlightRight => "slight right",
            Self::TurnLeft => "turn left",
            Self::TurnRight => "turn right",
            Self::TurnAround => "turn around",
            Self::Stop => "stop",
            Self::Attention => "attention",
            Self::Arrived => "arrived",
            Self::RotateLeft(TurnStep::Deg30) => "turn in place left 30°",
            Self::RotateLeft(TurnStep::Deg60) => "turn in place left 60°",
            Self::RotateLeft(TurnStep::Deg90) => "turn in place left 90°",
            Self::RotateLeft(TurnStep::Deg135) => "turn in place left 135°+",
            Self::RotateRight(TurnStep::Deg30) => "turn in place right 30°",
            Self::RotateRight(TurnStep::Deg60) => "turn in place right 60°",
            Self::RotateRight(TurnStep::Deg90) => "turn in place right 90°",
            Self::RotateRight(TurnStep::Deg135) => "turn in place right 135°+",
        }
    }

    /// The pattern of this cue with `on_ms` per step (the thesis's 500 ms by default).
    pub fn pattern(self, on_ms: u16) -> Pattern {
        let step = |mask: TactorMask| Frame { mask, duration_ms: on_ms };
        let short = |mask: TactorMask| Frame { mask, duration_ms: on_ms / 2 };
        let pause = Frame { mask: TactorMask::NONE, duration_ms: on_ms / 2 };
        let middle_cols = TactorMask::column(1) | TactorMask::column(2);
        let (frames, repeats) = match self {
            Self::Forward => ((0..GRID).rev().map(|r| short(TactorMask::row(r) & middle_cols)).collect(), 1),
            Self::SlightLeft => (vec![step(TactorMask::column(0))], 1),
            Self::SlightRight => (vec![step(TactorMask::column(3))], 1),
            Self::TurnLeft => ((0..GRID).rev().map(|c| short(TactorMask::column(c))).collect(), 1),
            Self::TurnRight => ((0..GRID).map(|c| short(TactorMask::column(c))).collect(), 1),
            Self::TurnAround => {
                let mut f: Vec<Frame> = (0..GRID).map(|r| short(TactorMask::row(r))).collect();
                f.push(pause);
                (f, 2)
            }
            Self::Stop => (vec![step(TactorMask::CORNERS)], 1),
            Self::Attention => {
                let centre = TactorMask::from_indices([5, 6, 9, 10]);
                (vec![short(centre), pause], 2)
            }
            Self::Arrived => {
                let top = TactorMask::row(0) | TactorMask::row(1);
                let bottom = TactorMask::row(2) | TactorMask::row(3);
                (vec![short(top), short(bottom), short(top), short(bottom)], 1)
            }
            Self::RotateLeft(step) => rotate_frames(step, false, on_ms),
            Self::RotateRight(step) => rotate_frames(step, true, on_ms),
        };
        Pattern { name: self.name().to_owned(), frames, repeats }
    }
}

/// Frames of a turn-in-place cue: the lower half of a column (rows 2 and 3, two tactors) sweeps toward the
/// turn side over [`TurnStep::columns`] columns, ending at the outer column of that side, `on_ms / 2` per
/// column; for [`TurnStep::Deg135`] a pause of `on_ms / 2` follows and the whole is played twice.
/// A sequence of tactor states as felt: consecutive equal states merged, offs at either end dropped.
fn felt(masks: impl Iterator<Item = TactorMask>) -> Vec<TactorMask> {
    let mut out: Vec<TactorMask> = Vec::new();
    for m in masks {
        if out.last() != Some(&m) && !(out.is_empty() && m == TactorMask::NONE) {
            out.push(m);
        }
    }
    while out.last() == Some(&TactorMask::NONE) {
        out.pop();
    }
    out
}

fn rotate_frames(step: TurnStep, right: bool, on_ms: u16) -> (Vec<Frame>, u8) {
    let lower = TactorMask::row(2) | TactorMask::row(3);
    let n = step.columns();
    let cols: Vec<usize> = if right { (GRID - n..GRID).collect() } else { (0..n).rev().collect() };
    let mut frames: Vec<Frame> = cols
        .into_iter()
        .map(|c| Frame { mask: TactorMask::column(c) & lower, duration_ms: on_ms / 2 })
        .collect();
    if step.sweeps() > 1 {
        frames.push(Frame { mask: TactorMask::NONE, duration_ms: on_ms / 2 });
    }
    (frames, step.sweeps())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cue_feels_different_and_is_recognised_at_any_on_time() {
        let cues: Vec<Cue> = Cue::ALL.into_iter().chain(Cue::TURN_IN_PLACE).collect();
        for (i, a) in cues.iter().enumerate() {
            for b in &cues[i + 1..] {
                assert_ne!(a.pattern(500).felt_masks(), b.pattern(500).felt_masks(), "{a:?} and {b:?}");
            }
            for on_ms in [20, 500, 2000] {
                assert_eq!(Cue::recognise(&a.pattern(on_ms).felt_masks()), Some(*a), "{a:?} at {on_ms} ms");
            }
        }
        // Offs around a pattern and a frame repeated are felt as one state.
        let col = TactorMask::column;
        assert_eq!(
            Cue::recognise(&[TactorMask::NONE, col(3), col(3), col(2), col(1), col(0), TactorMask::NONE]),
            Some(Cue::TurnLeft)
        );
        // Part of a pattern, or one column lit by hand, is no cue... except where it is one: column 0 alone
        // is "slight left".
        assert_eq!(Cue::recognise(&[col(3), col(2)]), None);
        assert_eq!(Cue::recognise(&[TactorMask::from_indices([5])]), None);
        assert_eq!(Cue::recognise(&[]), None);
        assert_eq!(Cue::recognise(&[col(0)]), Some(Cue::SlightLeft));
    }

    #[test]
    fn grid_neighbours_are_the_four_adjacent_cells() {
        // Counted on the 4x4 grid by hand: row r, column c is tactor 4r + c.
        assert_eq!(grid_neighbours(0), vec![4, 1]);
        assert_eq!(grid_neighbours(3), vec![7, 2]);
        assert_eq!(grid_neighbours(5), vec![1, 9, 4, 6]);
        assert_eq!(grid_neighbours(13), vec![9, 12, 14]);
        assert_eq!(grid_neighbours(15), vec![11, 14]);
        assert!(grid_neighbours(16).is_empty());
        // Adjacency is symmetric, and 24 edges join the 16 cells of a 4x4 grid.
        let mut edges = 0;
        for t in 0..TACTOR_COUNT {
            for n in grid_neighbours(t) {
                assert!(grid_neighbours(n).contains(&t), "{t} and {n}");
                edges += 1;
            }
        }
        assert_eq!(edges, 2 * 24);
    }

    #[test]
    fn numbering_matches_the_grid() {
        assert_eq!(TactorMask::at(0, 0), Some(TactorMask(1)));
        assert_eq!(TactorMask::at(3, 3), Some(TactorMask(1 << 15)));
        assert_eq!(TactorMask::column(0), TactorMask::from_indices([0, 4, 8, 12]));
        assert_eq!(TactorMask::row(3), TactorMask::from_indices([12, 13, 14, 15]));
        assert_eq!(TactorMask::CORNERS.indices().collect::<Vec<_>>(), vec![0, 3, 12, 15]);
        assert!(TactorMask::single(16).is_none());
    }

    #[test]
    fn turn_cues_sweep_toward_the_turn() {
        let left = Cue::TurnLeft.pattern(500);
        let cols: Vec<_> = left.frames.iter().map(|f| f.mask.indices().next().unwrap() % GRID).collect();
        assert_eq!(cols, vec![3, 2, 1, 0]);
        let right = Cue::TurnRight.pattern(500);
        let cols: Vec<_> = right.frames.iter().map(|f| f.mask.indices().next().unwrap() % GRID).collect();
        assert_eq!(cols, vec![0, 1, 2, 3]);
    }

    #[test]
    fn every_cue_stays_within_half_the_vest_and_the_on_time() {
        for cue in Cue::ALL {
            let p = cue.pattern(DEFAULT_ON_MS);
            assert!(p.max_simultaneous() <= 8, "{cue:?}");
            assert!(p.longest_on_ms() <= u32::from(DEFAULT_ON_MS), "{cue:?}: {}", p.longest_on_ms());
            assert!(p.total_ms() > 0);
        }
    }

    /// The device's default limits (crates/device `wtcu::limits::Limits::default()`, restated here because
    /// core cannot depend on device): 8 tactors at once, 2000 ms continuous on-time, 32 frames, 10 s per
    /// pattern, 5000 ms on per tactor in any 10 s window.
    fn within_device_limits(p: &Pattern) -> Result<(), String> {
        if p.frames.is_empty() || p.frames.len() > 32 || p.repeats == 0 {
            return Err(format!("{} frames, {} repeats", p.frames.len(), p.repeats));
        }
        if p.frames.iter().any(|f| f.duration_ms == 0) {
            return Err("a 0 ms frame".to_owned());
        }
        let most = p.frames.iter().map(|f| f.mask.0.count_ones()).max().unwrap_or(0);
        if most > 8 {
            return Err(format!("{most} tactors at once"));
        }
        let total: u32 =
            p.frames.iter().map(|f| u32::from(f.duration_ms)).sum::<u32>() * u32::from(p.repeats);
        if total > 10_000 {
            return Err(format!("{total} ms in total"));
        }
        for t in 0..TACTOR_COUNT {
            let longest = expanded_longest_ms(p, t);
            if longest > 2000 {
                return Err(format!("tactor {t} on for {longest} ms"));
            }
            // The whole pattern is within 10 s, so its total on-time bounds every 10 s window.
            let on: u32 =
                p.frames.iter().filter(|f| f.mask.contains(t)).map(|f| u32::from(f.duration_ms)).sum();
            if on * u32::from(p.repeats) > 5000 {
                return Err(format!("tactor {t} duty {} ms", on * u32::from(p.repeats)));
            }
        }
        Ok(())
    }

    #[test]
    fn turn_in_place_cues_respect_the_device_limits_at_every_on_time() {
        for cue in Cue::TURN_IN_PLACE.into_iter().chain(Cue::ALL) {
            for on_ms in [100, DEFAULT_ON_MS, 1000, 2000] {
                let p = cue.pattern(on_ms);
                assert_eq!(within_device_limits(&p), Ok(()), "{cue:?} at {on_ms} ms");
            }
        }
    }

    #[test]
    fn turn_in_place_sweeps_grow_with_the_turn_and_end_on_the_turn_side() {
        let lower = TactorMask::from_indices([8, 9, 10, 11, 12, 13, 14, 15]);
        for (right, make) in [(false, Cue::RotateLeft as fn(TurnStep) -> Cue), (true, Cue::RotateRight)] {
            for (step, columns, sweeps) in [
                (TurnStep::Deg30, 2, 1),
                (TurnStep::Deg60, 3, 1),
                (TurnStep::Deg90, 4, 1),
                (TurnStep::Deg135, 4, 2),
            ] {
                let p = make(step).pattern(DEFAULT_ON_MS);
                let on: Vec<&Frame> = p.frames.iter().filter(|f| !f.mask.is_empty()).collect();
                assert_eq!((on.len(), p.repeats), (columns, sweeps), "{step:?}");
                let cols: Vec<usize> = on
                    .iter()
                    .map(|f| {
                        // One half column: two tactors of one column, both in the lower half.
                        assert_eq!(f.mask.count(), 2);
                        assert_eq!(f.mask & lower, f.mask);
                        let c: Vec<usize> = f.mask.indices().map(|i| i % GRID).collect();
                        assert_eq!(c[0], c[1]);
                        c[0]
                    })
                    .collect();
                // Ends on the outer column of the turn side, one column per frame toward it.
                assert_eq!(*cols.last().unwrap(), if right { 3 } else { 0 }, "{step:?}");
                for w in cols.windows(2) {
                    let next = if right { w[0] + 1 } else { w[0].wrapping_sub(1) };
                    assert_eq!(w[1], next, "{cols:?}");
                }
            }
        }
        // No turn-in-place cue feels like a walking cue.
        for a in Cue::TURN_IN_PLACE {
            for b in Cue::ALL {
                assert_ne!(a.pattern(DEFAULT_ON_MS).frames, b.pattern(DEFAULT_ON_MS).frames, "{a:?} {b:?}");
            }
        }
    }

    #[test]
    fn turn_grades_are_the_nearest_nominal_turn() {
        for e in (0..=1800).map(|i| f64::from(i) / 10.0) {
            // Independent truth: the grade minimising |e - nominal|, the smaller on a tie.
            let best = TurnStep::ALL
                .into_iter()
                .min_by(|a, b| (e - a.degrees()).abs().total_cmp(&(e - b.degrees()).abs()))
                .unwrap();
            assert_eq!(TurnStep::for_error_deg(e), best, "{e}");
            assert_eq!(TurnStep::for_error_deg(-e), best, "{e}");
        }
        assert_eq!(Cue::rotate_toward(-50.0), Cue::RotateLeft(TurnStep::Deg60));
        assert_eq!(Cue::rotate_toward(170.0), Cue::RotateRight(TurnStep::Deg135));
        assert_eq!(TurnStep::for_error_deg(f64::NAN), TurnStep::Deg30);
        let names: std::collections::HashSet<_> = Cue::TURN_IN_PLACE.iter().map(|c| c.name()).collect();
        assert_eq!(names.len(), 8);
    }

    fn frame(mask: u16, duration_ms: u16) -> Frame {
        Frame { mask: TactorMask(mask), duration_ms }
    }

    fn pattern(frames: Vec<Frame>, repeats: u8) -> Pattern {
        Pattern { name: "test".to_owned(), frames, repeats }
    }

    /// Independent truth: the pattern expanded millisecond by millisecond, every repeat, longest streak.
    fn expanded_longest_ms(p: &Pattern, tactor: usize) -> u32 {
        let (mut longest, mut run) = (0u32, 0u32);
        for _ in 0..p.repeats.max(1) {
            for f in &p.frames {
                for _ in 0..f.duration_ms {
                    run = if f.mask.contains(tactor) { run + 1 } else { 0 };
                    longest = longest.max(run);
                }
            }
        }
        longest
    }

    #[test]
    fn a_tactor_on_in_every_frame_runs_for_every_repeat() {
        // The issue's bypass: 8 tactors, one 1000 ms frame, 5 repeats = 5000 ms without a break.
        let p = pattern(vec![frame(0x00FF, 1000)], 5);
        assert_eq!(p.longest_on_ms(), 5000);
        assert_eq!(p.longest_on_ms_of(0), 5000);
        assert_eq!(p.longest_on_ms_of(8), 0);
        assert_eq!(p.leading_on_ms(7), 5000);
        // On in two frames out of two, three repeats: 3 x (300 + 400).
        let p = pattern(vec![frame(0b01, 300), frame(0b11, 400)], 3);
        assert_eq!(p.longest_on_ms_of(0), 2100);
        assert_eq!(p.longest_on_ms_of(1), 400);
    }

    #[test]
    fn runs_wrap_between_repeats_once() {
        // Tactor 0: 300 on, 200 off, 400 on; repeated, the 400 + 300 wrap is the longest.
        let p = pattern(vec![frame(1, 300), frame(0, 200), frame(1, 400)], 3);
        assert_eq!(p.longest_on_ms_of(0), 700);
        assert_eq!(p.leading_on_ms(0), 300);
        assert_eq!(pattern(p.frames.clone(), 1).longest_on_ms_of(0), 400);
        // A 0 ms frame is no break.
        let p = pattern(vec![frame(1, 300), frame(0, 0), frame(1, 400)], 1);
        assert_eq!(p.longest_on_ms_of(0), 700);
        assert_eq!(p.leading_on_ms(0), 700);
        // 255 repeats of 65535 ms do not overflow.
        let p = pattern(vec![frame(1, u16::MAX)], u8::MAX);
        assert_eq!(p.longest_on_ms(), 255 * 65_535);
        assert_eq!(p.total_ms(), 255 * 65_535);
    }

    proptest::proptest! {
        #[test]
        fn closed_form_matches_the_expanded_pattern(
            raw in proptest::collection::vec((0u16..8, 0u16..40), 1..7),
            repeats in 0u8..6,
            tactor in 0usize..3,
        ) {
            let p = pattern(raw.into_iter().map(|(m, d)| frame(m, d)).collect(), repeats);
            proptest::prop_assert_eq!(p.longest_on_ms_of(tactor), expanded_longest_ms(&p, tactor));
            // Leading run: streak from the first millisecond.
            let mut lead = 0u32;
            'outer: for _ in 0..p.repeats.max(1) {
                for f in &p.frames {
                    for _ in 0..f.duration_ms {
                        if !f.mask.contains(tactor) {
                            break 'outer;
                        }
                        lead += 1;
                    }
                }
            }
            proptest::prop_assert_eq!(p.leading_on_ms(tactor), lead);
        }
    }
}
