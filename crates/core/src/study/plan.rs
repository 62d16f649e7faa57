//! Trial plans: the trials of one participant in presentation order, the same for the same protocol and
//! participant on every machine and every version of vestnav.
//!
//! - **random**: each block's trials (every stimulus `repetitions` times) shuffled by Fisher–Yates with
//!   [`SplitMix64`] seeded by [`block_seed`] (the protocol's seed, the participant's id, the block's index);
//!   our own generator, so a crate upgrade never changes an order already used in a study.
//! - **blocked**: each stimulus `repetitions` times in a row, stimuli in the protocol's order.
//! - **latin-square**: participant `k` (their place in the protocol's list) takes row `k mod R` of the
//!   balanced Latin square of [`williams`] (`R = n` rows for an even number `n` of stimuli, `2n` for odd
//!   `n`), presented `repetitions` times in a row.

use serde::{Deserialize, Serialize};

use super::protocol::{Order, Protocol, ProtocolError, Stimulus};

/// One trial of a participant's plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedTrial {
    /// 0-based position in the session.
    pub index: usize,
    /// 0-based block index in the protocol.
    pub block: usize,
    /// The block's name.
    pub block_name: String,
    /// A training trial.
    pub training: bool,
    /// The wearer is told the correct answer after responding.
    pub feedback: bool,
    /// What the vest presents.
    pub stimulus: Stimulus,
    /// The correct choice ([`Stimulus::answer`]).
    pub answer: String,
}

/// `SplitMix64` (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014; the
/// constants of Vigna's reference `splitmix64.c`): `state += 0x9E3779B97F4A7C15`, then
/// `z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9`, `z = (z ^ (z >> 27)) * 0x94D049BB133111EB`, `z ^ (z >> 31)`.
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator starting from `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform integer in `0..n` (`n >= 1`), without modulo bias (Lemire's multiply-shift with
    /// rejection, "Fast random integer generation in an interval", 2019).
    pub fn below(&mut self, n: u64) -> u64 {
        let n = n.max(1);
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = u128::from(self.next_u64()) * u128::from(n);
            if (m as u64) >= threshold {
                return (m >> 64) as u64;
            }
        }
    }

    /// Shuffles `items` in place (Fisher–Yates, from the end).
    pub fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = self.below(i as u64 + 1) as usize;
            items.swap(i, j);
        }
    }
}

/// 64-bit FNV-1a of `bytes` (offset basis 0xcbf29ce484222325, prime 0x100000001b3).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3))
}

/// The seed of a random block's shuffle: one `SplitMix64` output from
/// `seed ^ fnv1a(participant) ^ (block + 1) * 0x9E3779B97F4A7C15`, so participants and blocks get
/// unrelated orders and the same triple always the same one.
pub fn block_seed(seed: u64, participant: &str, block: usize) -> u64 {
    let mixed = seed ^ fnv1a(participant.as_bytes()) ^ (block as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    SplitMix64::new(mixed).next_u64()
}

/// A balanced Latin square (Williams 1949) of `n` conditions `0..n`, as rows of presentation orders.
///
/// First row `0, 1, n-1, 2, n-2, 3, ...`; row `i` adds `i` to every entry (mod `n`). Every condition appears
/// once in each row and each column.
/// - `n` even: the `n` rows are balanced for first-order carry-over: every ordered pair `(a, b)`, `a != b`,
///   follows immediately in exactly one row.
/// - `n` odd: no balanced square of order 3, 5 or 7 exists (row-complete Latin squares of those orders
///   do not), so the square is followed by its mirror image (each row reversed): `2n` rows in which every
///   ordered pair follows immediately exactly twice and each condition stands in each position twice.
///   Counterbalancing is then complete with a multiple of `2n` participants.
///
/// `n = 0` gives no rows, `n = 1` the single row `[0]`.
pub fn williams(n: usize) -> Vec<Vec<usize>> {
    if n == 0 {
        return Vec::new();
    }
    let mut first = Vec::with_capacity(n);
    let (mut lo, mut hi) = (0usize, n);
    for j in 0..n {
        if j % 2 == 0 {
            first.push(lo);
            lo += 1;
        } else {
            hi -= 1;
            first.push(hi);
        }
    }
    let mut rows: Vec<Vec<usize>> = (0..n).map(|i| first.iter().map(|&v| (v + i) % n).collect()).collect();
    if n % 2 == 1 && n > 1 {
        let mirrored: Vec<Vec<usize>> = rows.iter().map(|r| r.iter().rev().copied().collect()).collect();
        rows.extend(mirrored);
    }
    rows
}

/// The plan of `participant`: their place in the protocol's participants list chooses the Latin-square
/// row; random orders use their id. A participant not in a non-empty list is an error (a typo would
/// silently change the counterbalancing).
pub fn plan(p: &Protocol, participant: &str) -> Result<Vec<PlannedTrial>, ProtocolError> {
    let index = match p.participant_index(participant) {
        Some(i) => i,
        None if p.participants.is_empty() => 0,
        None => {
            return Err(ProtocolError::new(
                &p.source,
                None,
                format!("participant {participant:?} is not in the protocol's participants list"),
            ));
        }
    };
    Ok(plan_for(p, participant, index))
}

/// The plan for a participant id and an explicit Latin-square index (for participants added after the
/// protocol was written: the experimenter chooses their row).
pub fn plan_for(p: &Protocol, participant: &str, index: usize) -> Vec<PlannedTrial> {
    let n = p.stimuli.len();
    let square = williams(n);
    let mut trials = Vec::with_capacity(p.trials_per_participant());
    for (b, block) in p.blocks.iter().enumerate() {
        let reps = block.repetitions as usize;
        let order: Vec<usize> = match block.order {
            Order::Blocked => (0..n).flat_map(|s| std::iter::repeat_n(s, reps)).collect(),
            Order::Random => {
                let mut all: Vec<usize> = (0..reps).flat_map(|_| 0..n).collect();
                SplitMix64::new(block_seed(p.seed, participant, b)).shuffle(&mut all);
                all
            }
            Order::LatinSquare => match square.get(index % square.len().max(1)) {
                Some(row) => (0..reps).flat_map(|_| row.iter().copied()).collect(),
                None => Vec::new(),
            },
        };
        for s in order {
            let Some(stimulus) = p.stimuli.get(s) else { continue };
            trials.push(PlannedTrial {
                index: trials.len(),
                block: b,
                block_name: block.name.clone(),
                training: block.training,
                feedback: block.feedback,
                answer: stimulus.answer(),
                stimulus: stimulus.clone(),
            });
        }
    }
    trials
}

#[cfg(test)]
#[path = "plan_tests.rs"]
mod tests;
