//! Confusion matrices and the information transferred through them.
//!
//! **Information transfer** (IT, "transmitted information", Miller 1956; the mutual information between
//! stimulus and response) is estimated from the confusion counts `n_ij` (stimulus `i` presented, response
//! `j` given; `n_i` row sums, `n_j` column sums, `n` the total) by maximum likelihood:
//!
//! `IT = sum_ij (n_ij / n) log2(n_ij n / (n_i n_j))` bits (terms with `n_ij = 0` count 0),
//!
//! which is `H(S) + H(R) - H(S,R)` with each entropy taken from the observed frequencies. `2^IT` is the
//! number of stimuli that could be identified without error.
//!
//! **Small-sample bias.** This estimate is biased *upward*: with few trials per cell, chance coincidences
//! look like information, and even a wearer who answers at random gets `IT > 0`. To first order (Miller
//! 1955, "Note on the bias of information estimates") each entropy is underestimated by
//! `(m - 1) / (2 n ln 2)` bits, `m` its number of occupied cells, so the estimate is too high by about
//! `(m_SR - m_S - m_R + 1) / (2 n ln 2)`, which for a fully occupied `K x K` matrix is
//! `(K - 1)^2 / (2 n ln 2)`: for 16 tactors, 0.13 bits after n = 1280 trials but some 2 bits after 80 (where
//! the first-order term is itself only a rough guide). Houtsma (1983) advises `n >= 5 K^2` trials before
//! trusting the raw estimate. [`ConfusionMatrix::it_corrected_bits`] subtracts
//! this first-order (Miller–Madow) bias; both are reported.

use serde::{Deserialize, Serialize};

/// Counts of responses per stimulus: `counts[i][j]` is how often response `labels_r[j]` followed stimulus
/// `labels_s[i]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ConfusionMatrix {
    /// Stimulus labels (rows).
    pub stimuli: Vec<String>,
    /// Response labels (columns).
    pub responses: Vec<String>,
    /// `counts[row][column]`.
    pub counts: Vec<Vec<u64>>,
}

/// `-p log2 p`, 0 for `p = 0`.
fn plogp(count: u64, total: f64) -> f64 {
    if count == 0 {
        return 0.0;
    }
    let p = count as f64 / total;
    -p * p.log2()
}

impl ConfusionMatrix {
    /// Builds the matrix of `pairs` (stimulus, response): rows in the order of `stimuli` (labels seen in
    /// `pairs` but not listed are appended in order of first appearance), columns the stimulus labels
    /// followed by any other response given.
    pub fn from_pairs<'a>(stimuli: &[String], pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> Self {
        let pairs: Vec<(&str, &str)> = pairs.into_iter().collect();
        let mut rows: Vec<String> = stimuli.to_vec();
        for (s, _) in &pairs {
            if !rows.iter().any(|r| r == s) {
                rows.push((*s).to_owned());
            }
        }
        let mut cols = rows.clone();
        for (_, r) in &pairs {
            if !cols.iter().any(|c| c == r) {
                cols.push((*r).to_owned());
            }
        }
        let mut counts = vec![vec![0u64; cols.len()]; rows.len()];
        for (s, r) in pairs {
            let (Some(i), Some(j)) = (rows.iter().position(|x| x == s), cols.iter().position(|x| x == r))
            else {
                continue;
            };
            counts[i][j] += 1;
        }
        Self { stimuli: rows, responses: cols, counts }
    }

    /// A matrix from counts (rows stimuli, columns responses), rows and columns labelled `1`, `2`, ... (so
    /// the diagonal is correct).
    pub fn from_counts(counts: Vec<Vec<u64>>) -> Self {
        let cols = counts.iter().map(Vec::len).max().unwrap_or(0);
        let counts: Vec<Vec<u64>> = counts
            .into_iter()
            .map(|mut r| {
                r.resize(cols, 0);
                r
            })
            .collect();
        Self {
            stimuli: (1..=counts.len()).map(|i| i.to_string()).collect(),
            responses: (1..=cols).map(|j| j.to_string()).collect(),
            counts,
        }
    }

    /// Total count `n`.
    pub fn total(&self) -> u64 {
        self.counts.iter().flatten().sum()
    }

    /// Row sums `n_i`.
    pub fn row_sums(&self) -> Vec<u64> {
        self.counts.iter().map(|r| r.iter().sum()).collect()
    }

    /// Column sums `n_j`.
    pub fn column_sums(&self) -> Vec<u64> {
        let mut out = vec![0u64; self.responses.len()];
        for row in &self.counts {
            for (j, &c) in row.iter().enumerate() {
                if let Some(o) = out.get_mut(j) {
                    *o += c;
                }
            }
        }
        out
    }

    /// Count on the diagonal: responses equal to the stimulus's label.
    pub fn correct(&self) -> u64 {
        self.stimuli
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let j = self.responses.iter().position(|r| r == s)?;
                self.counts.get(i)?.get(j).copied()
            })
            .sum()
    }

    /// Stimulus entropy `H(S)` from the row frequencies [bits].
    pub fn stimulus_entropy_bits(&self) -> f64 {
        let n = self.total() as f64;
        self.row_sums().iter().map(|&c| plogp(c, n)).sum()
    }

    /// Response entropy `H(R)` from the column frequencies [bits].
    pub fn response_entropy_bits(&self) -> f64 {
        let n = self.total() as f64;
        self.column_sums().iter().map(|&c| plogp(c, n)).sum()
    }

    /// Joint entropy `H(S,R)` from the cell frequencies [bits].
    pub fn joint_entropy_bits(&self) -> f64 {
        let n = self.total() as f64;
        self.counts.iter().flatten().map(|&c| plogp(c, n)).sum()
    }

    /// Maximum-likelihood information transfer `H(S) + H(R) - H(S,R)` [bits] (module doc); 0 for an empty
    /// matrix. Rounding is kept out of the sign: tiny negative results are returned as 0.
    pub fn it_bits(&self) -> f64 {
        if self.total() == 0 {
            return 0.0;
        }
        (self.stimulus_entropy_bits() + self.response_entropy_bits() - self.joint_entropy_bits()).max(0.0)
    }

    /// First-order bias of [`Self::it_bits`] [bits]: `(m_SR - m_S - m_R + 1) / (2 n ln 2)` with `m` the
    /// occupied cells, rows and columns (Miller 1955); 0 for an empty matrix.
    pub fn it_bias_bits(&self) -> f64 {
        let n = self.total();
        if n == 0 {
            return 0.0;
        }
        let occupied = |v: &[u64]| v.iter().filter(|&&c| c > 0).count() as f64;
        let cells = self.counts.iter().map(|r| occupied(r)).sum::<f64>();
        let rows = occupied(&self.row_sums());
        let cols = occupied(&self.column_sums());
        (cells - rows - cols + 1.0) / (2.0 * n as f64 * std::f64::consts::LN_2)
    }

    /// [`Self::it_bits`] less its first-order bias (Miller–Madow), at least 0 [bits].
    pub fn it_corrected_bits(&self) -> f64 {
        (self.it_bits() - self.it_bias_bits()).max(0.0)
    }

    /// Each row as fractions of its sum (rows without trials stay 0).
    pub fn row_fractions(&self) -> Vec<Vec<f64>> {
        self.counts
            .iter()
            .map(|r| {
                let s: u64 = r.iter().sum();
                r.iter().map(|&c| if s == 0 { 0.0 } else { c as f64 / s as f64 }).collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    /// Perfect identification of N equally likely stimuli transfers log2 N bits, whatever the count per
    /// stimulus.
    #[test]
    fn perfect_identification_is_log2_n() {
        for n in 2..=16usize {
            for reps in [1u64, 5, 40] {
                let counts =
                    (0..n).map(|i| (0..n).map(|j| if i == j { reps } else { 0 }).collect()).collect();
                let m = ConfusionMatrix::from_counts(counts);
                assert_relative_eq!(m.it_bits(), (n as f64).log2(), max_relative = 1e-12);
                assert_eq!(m.correct(), reps * n as u64);
            }
        }
    }

    /// Responses independent of the stimulus (every cell equal) transfer nothing; the bias term is then
    /// the whole story for a sampled matrix, and is positive.
    #[test]
    fn a_uniform_matrix_is_zero_bits() {
        for n in 2..=16usize {
            let m = ConfusionMatrix::from_counts(vec![vec![3; n]; n]);
            assert!(m.it_bits().abs() < 1e-12, "n = {n}: {}", m.it_bits());
            assert_relative_eq!(
                m.it_bias_bits(),
                ((n - 1) * (n - 1)) as f64 / (2.0 * (3 * n * n) as f64 * std::f64::consts::LN_2),
                max_relative = 1e-12
            );
            assert!(m.it_corrected_bits().abs() < 1e-15);
        }
    }

    /// A worked example from a published table: Cover and Thomas, "Elements of Information Theory"
    /// (2nd ed., Wiley 2006), Example 2.2.1, the joint distribution (rows y = 1..4, columns x = 1..4)
    ///
    /// ```text
    ///  1/8  1/16 1/32 1/32
    ///  1/16 1/8  1/32 1/32
    ///  1/16 1/16 1/16 1/16
    ///  1/4  0    0    0
    /// ```
    ///
    /// for which the book prints H(X) = 7/4, H(Y) = 2, H(X|Y) = 11/8, H(Y|X) = 13/8 and H(X,Y) = 27/8 bits,
    /// so I(X;Y) = H(X) - H(X|Y) = 3/8 = 0.375 bits. As confusion counts: 32 trials in those proportions.
    #[test]
    fn cover_and_thomas_example_2_2_1() {
        let m = ConfusionMatrix::from_counts(vec![
            vec![4, 2, 1, 1],
            vec![2, 4, 1, 1],
            vec![2, 2, 2, 2],
            vec![8, 0, 0, 0],
        ]);
        assert_relative_eq!(m.stimulus_entropy_bits(), 2.0, max_relative = 1e-12);
        assert_relative_eq!(m.response_entropy_bits(), 7.0 / 4.0, max_relative = 1e-12);
        assert_relative_eq!(m.joint_entropy_bits(), 27.0 / 8.0, max_relative = 1e-12);
        assert_relative_eq!(m.it_bits(), 0.375, max_relative = 1e-12);
        // Doubling every count changes the estimate not at all, its bias by half.
        let double = ConfusionMatrix::from_counts(
            m.counts.iter().map(|r| r.iter().map(|c| 2 * c).collect()).collect(),
        );
        assert_relative_eq!(double.it_bits(), 0.375, max_relative = 1e-12);
        assert_relative_eq!(double.it_bias_bits(), m.it_bias_bits() / 2.0, max_relative = 1e-12);
    }

    /// A symmetric channel (N equally likely stimuli, correct with probability P, errors spread evenly over
    /// the N - 1 others) has the closed form `log2 N + P log2 P + (1 - P) log2((1 - P)/(N - 1))` bits
    /// (Wolpaw et al. 2000's bits per selection).
    #[test]
    fn symmetric_channel_matches_the_closed_form() {
        for (n, per_row, hits) in [(4usize, 12u64, 9u64), (8, 70, 42), (16, 30, 15)] {
            let miss = (per_row - hits) / (n as u64 - 1);
            assert_eq!(miss * (n as u64 - 1), per_row - hits);
            let counts = (0..n).map(|i| (0..n).map(|j| if i == j { hits } else { miss }).collect()).collect();
            let m = ConfusionMatrix::from_counts(counts);
            let p = hits as f64 / per_row as f64;
            let closed = (n as f64).log2() + p * p.log2() + (1.0 - p) * ((1.0 - p) / (n as f64 - 1.0)).log2();
            assert_relative_eq!(m.it_bits(), closed, max_relative = 1e-12);
        }
    }

    #[test]
    fn pairs_build_rows_columns_and_extra_responses() {
        let stimuli: Vec<String> = ["A", "B"].iter().map(|s| (*s).to_owned()).collect();
        let m = ConfusionMatrix::from_pairs(
            &stimuli,
            [("A", "A"), ("A", "B"), ("B", "B"), ("B", "?"), ("C", "A")],
        );
        assert_eq!(m.stimuli, ["A", "B", "C"]);
        assert_eq!(m.responses, ["A", "B", "C", "?"]);
        assert_eq!(m.counts, vec![vec![1, 1, 0, 0], vec![0, 1, 0, 1], vec![1, 0, 0, 0]]);
        assert_eq!(m.correct(), 2);
        assert_eq!(m.total(), 5);
        assert!(ConfusionMatrix::from_pairs(&stimuli, []).it_bits().abs() < 1e-15);
    }
}
