//! The analysis of a study's results, the same numbers for the CLI, the console and the figures.
//!
//! Which trials count where:
//! - percent correct, the confusion matrix, information transfer and response times use the **test**
//!   trials (`training = 0`) that were **answered** (a response was entered); trials without a response
//!   (no-response, aborted, stopped, refused) are counted per outcome but are not scored as wrong;
//! - the learning curve takes every block, training included, in block order;
//! - the navigation summaries take every navigation trial.
//!
//! Response-time quartiles are linear interpolations between order statistics (Hyndman and Fan's type 7,
//! R's and `NumPy`'s default): the quantile `q` of `n` sorted values is `x[h] + (h - floor h)(x[h+1] - x[h])`
//! at `h = (n - 1) q` (0-based).

use serde::{Deserialize, Serialize};

use super::info::ConfusionMatrix;
use super::protocol::{GRID_LABELS, Task, parse_tactor_label};
use super::record::{Outcome, TrialRecord};

/// Percent correct and response times of one stimulus.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StimulusSummary {
    /// The stimulus's label.
    pub stimulus: String,
    /// Answered test trials.
    pub answered: usize,
    /// Of which correct.
    pub correct: usize,
    /// `100 correct / answered`; `None` without answered trials.
    pub percent_correct: Option<f64>,
    /// Median response time [ms].
    pub rt_median_ms: Option<f64>,
}

/// Percent correct and information transfer of one participant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParticipantSummary {
    /// Participant id.
    pub participant: String,
    /// Answered test trials.
    pub answered: usize,
    /// Of which correct.
    pub correct: usize,
    /// `100 correct / answered`.
    pub percent_correct: Option<f64>,
    /// Maximum-likelihood information transfer of this participant's matrix [bits].
    pub it_bits: Option<f64>,
}

/// One point of the learning curve: one block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockSummary {
    /// 0-based block index.
    pub block: usize,
    /// Block name.
    pub block_name: String,
    /// A training block.
    pub training: bool,
    /// Trials in the block (all outcomes).
    pub trials: usize,
    /// Answered trials.
    pub answered: usize,
    /// Of which correct.
    pub correct: usize,
    /// `100 correct / answered`.
    pub percent_correct: Option<f64>,
    /// Median response time [ms].
    pub rt_median_ms: Option<f64>,
}

/// Response-time statistics [ms].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RtStats {
    /// Number of response times.
    pub n: usize,
    /// Mean.
    pub mean_ms: f64,
    /// Median.
    pub median_ms: f64,
    /// First quartile.
    pub q1_ms: f64,
    /// Third quartile.
    pub q3_ms: f64,
    /// Interquartile range `q3 - q1`.
    pub iqr_ms: f64,
    /// Smallest.
    pub min_ms: f64,
    /// Largest.
    pub max_ms: f64,
}

impl RtStats {
    /// The statistics of `values` (non-finite values left out); `None` when none is left.
    pub fn of(values: &[f64]) -> Option<Self> {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let (q1, median, q3) = (quantile(&v, 0.25), quantile(&v, 0.5), quantile(&v, 0.75));
        Some(Self {
            n,
            mean_ms: v.iter().sum::<f64>() / n as f64,
            median_ms: median,
            q1_ms: q1,
            q3_ms: q3,
            iqr_ms: q3 - q1,
            min_ms: v[0],
            max_ms: v[n - 1],
        })
    }
}

/// Quantile `q` of sorted, non-empty `v` (type 7, module doc).
fn quantile(v: &[f64], q: f64) -> f64 {
    let h = (v.len() - 1) as f64 * q;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(v.len() - 1);
    v[lo] + (h - lo as f64) * (v[hi] - v[lo])
}

/// One navigation trial's numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavigationTrial {
    /// Participant id.
    pub participant: String,
    /// `ROUTE/CONDITION`.
    pub stimulus: String,
    /// The condition (the label after the last `/`).
    pub condition: String,
    /// How it ended.
    pub outcome: Outcome,
    /// Completion time [s].
    pub completion_s: Option<f64>,
    /// Path length over route length.
    pub path_ratio: Option<f64>,
    /// Cross-track RMS [m].
    pub cross_track_rms_m: Option<f64>,
    /// Cues played.
    pub cues: Option<u32>,
    /// Stops.
    pub stops: Option<u32>,
    /// Waypoints missed.
    pub missed_waypoints: Option<u32>,
}

/// Means over the navigation trials of one condition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavigationSummary {
    /// The condition.
    pub condition: String,
    /// Trials of the condition.
    pub trials: usize,
    /// Of which completed.
    pub completed: usize,
    /// Mean completion time of the completed trials [s].
    pub completion_mean_s: Option<f64>,
    /// Mean path/route length ratio.
    pub path_ratio_mean: Option<f64>,
    /// Mean cross-track RMS [m].
    pub cross_track_rms_mean_m: Option<f64>,
    /// Mean cues per trial.
    pub cues_mean: Option<f64>,
    /// Stops over all trials.
    pub stops_total: u32,
    /// Missed waypoints over all trials.
    pub missed_waypoints_total: u32,
}

/// Everything the analysis of a results file gives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyAnalysis {
    /// The protocol names in the results (normally one).
    pub protocols: Vec<String>,
    /// The task (the first row's; mixed files are analysed as one).
    pub task: Option<Task>,
    /// The participants, in order of first appearance.
    pub participants: Vec<String>,
    /// Rows read.
    pub trials: usize,
    /// Trials per outcome (name, count), every outcome listed.
    pub outcomes: Vec<(String, usize)>,
    /// Answered test trials.
    pub answered: usize,
    /// Of which correct.
    pub correct: usize,
    /// `100 correct / answered` over the answered test trials.
    pub percent_correct: Option<f64>,
    /// Per stimulus, in the confusion matrix's row order.
    pub per_stimulus: Vec<StimulusSummary>,
    /// Per participant.
    pub per_participant: Vec<ParticipantSummary>,
    /// The pooled confusion matrix of the answered test trials (`None` for navigation or without any).
    pub confusion: Option<ConfusionMatrix>,
    /// Maximum-likelihood information transfer of `confusion` [bits].
    pub it_bits: Option<f64>,
    /// Its first-order small-sample bias [bits] (see [`crate::study::info`]).
    pub it_bias_bits: Option<f64>,
    /// `it_bits - it_bias_bits`, at least 0 [bits].
    pub it_corrected_bits: Option<f64>,
    /// `log2` of the number of stimuli: the most any matrix of them can transfer [bits].
    pub stimulus_bits: Option<f64>,
    /// The bias statement printed with the numbers.
    pub it_note: String,
    /// Response times of the answered test trials.
    pub rt: Option<RtStats>,
    /// Those response times, for the histogram [ms].
    pub rt_values_ms: Vec<f64>,
    /// The learning curve: one point per block, in block order.
    pub learning: Vec<BlockSummary>,
    /// Localization: percent correct per tactor on the 4x4 back view (`[row][column]`, row 0 on top, column
    /// 0 on the wearer's left); `None` where a tactor was never presented alone.
    pub localization_map: Option<[[Option<f64>; 4]; 4]>,
    /// Navigation trials.
    pub navigation_trials: Vec<NavigationTrial>,
    /// Navigation summaries per condition.
    pub navigation: Vec<NavigationSummary>,
}

fn percent(correct: usize, of: usize) -> Option<f64> {
    (of > 0).then(|| 100.0 * correct as f64 / of as f64)
}

fn mean(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (sum, n) =
        values.into_iter().filter(|v| v.is_finite()).fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

fn median(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.into_iter().collect();
    RtStats::of(&v).map(|s| s.median_ms)
}

/// Orders stimulus labels: tactor labels by tactor (T0..T15), then the rest by first appearance.
fn ordered_labels<'a>(labels: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut seen: Vec<String> = Vec::new();
    for l in labels {
        if !seen.iter().any(|s| s == l) {
            seen.push(l.to_owned());
        }
    }
    let mut tactors: Vec<(usize, String)> =
        seen.iter().filter_map(|l| parse_tactor_label(l).map(|i| (i, l.clone()))).collect();
    tactors.sort_by_key(|(i, _)| *i);
    let rest = seen.iter().filter(|l| parse_tactor_label(l).is_none()).cloned();
    tactors.into_iter().map(|(_, l)| l).chain(rest).collect()
}

/// The analysis of `rows` (module doc for which trials count where).
pub fn analyze(rows: &[TrialRecord]) -> StudyAnalysis {
    let task = rows.first().map(|r| r.task);
    let mut protocols: Vec<String> = Vec::new();
    let mut participants: Vec<String> = Vec::new();
    for r in rows {
        if !protocols.contains(&r.protocol) {
            protocols.push(r.protocol.clone());
        }
        if !participants.contains(&r.participant) {
            participants.push(r.participant.clone());
        }
    }
    let outcomes = Outcome::ALL
        .iter()
        .map(|o| (o.name().to_owned(), rows.iter().filter(|r| r.outcome == *o).count()))
        .collect();
    let scored: Vec<&TrialRecord> =
        rows.iter().filter(|r| r.task != Task::Navigation && !r.training && r.response.is_some()).collect();
    let is_correct =
        |r: &TrialRecord| r.correct.unwrap_or_else(|| r.response.as_deref() == Some(r.answer.as_str()));
    let correct = scored.iter().filter(|r| is_correct(r)).count();

    let stimuli =
        ordered_labels(rows.iter().filter(|r| r.task != Task::Navigation).map(|r| r.stimulus.as_str()));
    let pairs = |set: &[&TrialRecord]| -> ConfusionMatrix {
        ConfusionMatrix::from_pairs(
            &stimuli,
            set.iter().map(|r| (r.stimulus.as_str(), r.response.as_deref().unwrap_or(""))),
        )
    };
    let confusion = (!scored.is_empty()).then(|| pairs(&scored));
    let per_stimulus = stimuli
        .iter()
        .map(|s| {
            let of: Vec<&&TrialRecord> = scored.iter().filter(|r| r.stimulus == *s).collect();
            let c = of.iter().filter(|r| is_correct(r)).count();
            StimulusSummary {
                stimulus: s.clone(),
                answered: of.len(),
                correct: c,
                percent_correct: percent(c, of.len()),
                rt_median_ms: median(of.iter().filter_map(|r| r.rt_ms)),
            }
        })
        .collect();
    let per_participant = participants
        .iter()
        .filter_map(|p| {
            let of: Vec<&TrialRecord> = scored.iter().copied().filter(|r| r.participant == *p).collect();
            if of.is_empty() {
                return None;
            }
            let c = of.iter().filter(|r| is_correct(r)).count();
            Some(ParticipantSummary {
                participant: p.clone(),
                answered: of.len(),
                correct: c,
                percent_correct: percent(c, of.len()),
                it_bits: Some(pairs(&of).it_bits()),
            })
        })
        .collect();
    let rt_values_ms: Vec<f64> = scored.iter().filter_map(|r| r.rt_ms).filter(|v| v.is_finite()).collect();
    let presented = stimuli.len();
    let (it_note, stimulus_bits) = match &confusion {
        Some(m) => (it_note(m, presented), (presented > 0).then(|| (presented as f64).log2())),
        None => (String::new(), None),
    };
    StudyAnalysis {
        protocols,
        task,
        participants,
        trials: rows.len(),
        outcomes,
        answered: scored.len(),
        correct,
        percent_correct: percent(correct, scored.len()),
        per_stimulus,
        per_participant,
        it_bits: confusion.as_ref().map(ConfusionMatrix::it_bits),
        it_bias_bits: confusion.as_ref().map(ConfusionMatrix::it_bias_bits),
        it_corrected_bits: confusion.as_ref().map(ConfusionMatrix::it_corrected_bits),
        confusion,
        stimulus_bits,
        it_note,
        rt: RtStats::of(&rt_values_ms),
        rt_values_ms,
        learning: learning(rows, &is_correct),
        localization_map: (task == Some(Task::Localization)).then(|| localization_map(&scored, &is_correct)),
        navigation_trials: navigation_trials(rows),
        navigation: navigation_summaries(rows),
    }
}

/// The bias statement for `m`: the first-order bias, and whether the trials reach Houtsma's `5 K^2`.
fn it_note(m: &ConfusionMatrix, k: usize) -> String {
    let n = m.total();
    let enough = 5 * (k as u64) * (k as u64);
    let verdict = if n >= enough {
        format!("{n} trials reach 5 K^2 = {enough} for K = {k} stimuli")
    } else {
        format!(
            "{n} trials are fewer than 5 K^2 = {enough} for K = {k} stimuli: read the raw estimate as an upper bound"
        )
    };
    format!(
        "maximum-likelihood estimate, biased upward with few trials per cell (first-order bias {:.3} bits, Miller 1955); {verdict}",
        m.it_bias_bits()
    )
}

fn learning(rows: &[TrialRecord], is_correct: &dyn Fn(&TrialRecord) -> bool) -> Vec<BlockSummary> {
    let mut blocks: Vec<(usize, String, bool)> = Vec::new();
    for r in rows.iter().filter(|r| r.task != Task::Navigation) {
        if !blocks.iter().any(|(b, _, _)| *b == r.block) {
            blocks.push((r.block, r.block_name.clone(), r.training));
        }
    }
    blocks.sort_by_key(|(b, _, _)| *b);
    blocks
        .into_iter()
        .map(|(block, block_name, training)| {
            let all: Vec<&TrialRecord> =
                rows.iter().filter(|r| r.task != Task::Navigation && r.block == block).collect();
            let answered: Vec<&&TrialRecord> = all.iter().filter(|r| r.response.is_some()).collect();
            let c = answered.iter().filter(|r| is_correct(r)).count();
            BlockSummary {
                block,
                block_name,
                training,
                trials: all.len(),
                answered: answered.len(),
                correct: c,
                percent_correct: percent(c, answered.len()),
                rt_median_ms: median(answered.iter().filter_map(|r| r.rt_ms)),
            }
        })
        .collect()
}

fn localization_map(
    scored: &[&TrialRecord],
    is_correct: &dyn Fn(&TrialRecord) -> bool,
) -> [[Option<f64>; 4]; 4] {
    let mut map = [[None; 4]; 4];
    for (i, label) in GRID_LABELS.iter().enumerate() {
        let of: Vec<&&TrialRecord> = scored.iter().filter(|r| r.stimulus == *label).collect();
        let c = of.iter().filter(|r| is_correct(r)).count();
        map[i / 4][i % 4] = percent(c, of.len());
    }
    map
}

fn condition_of(stimulus: &str) -> String {
    stimulus.rsplit('/').next().unwrap_or(stimulus).to_owned()
}

fn navigation_trials(rows: &[TrialRecord]) -> Vec<NavigationTrial> {
    rows.iter()
        .filter(|r| r.task == Task::Navigation)
        .map(|r| NavigationTrial {
            participant: r.participant.clone(),
            stimulus: r.stimulus.clone(),
            condition: condition_of(&r.stimulus),
            outcome: r.outcome,
            completion_s: r.completion_s,
            path_ratio: r.path_ratio(),
            cross_track_rms_m: r.cross_track_rms_m,
            cues: r.cues,
            stops: r.stops,
            missed_waypoints: r.missed_waypoints,
        })
        .collect()
}

fn navigation_summaries(rows: &[TrialRecord]) -> Vec<NavigationSummary> {
    let trials = navigation_trials(rows);
    let mut conditions: Vec<String> = Vec::new();
    for t in &trials {
        if !conditions.contains(&t.condition) {
            conditions.push(t.condition.clone());
        }
    }
    conditions
        .into_iter()
        .map(|condition| {
            let of: Vec<&NavigationTrial> = trials.iter().filter(|t| t.condition == condition).collect();
            let done: Vec<&&NavigationTrial> =
                of.iter().filter(|t| t.outcome == Outcome::Completed).collect();
            NavigationSummary {
                trials: of.len(),
                completed: done.len(),
                completion_mean_s: mean(done.iter().filter_map(|t| t.completion_s)),
                path_ratio_mean: mean(of.iter().filter_map(|t| t.path_ratio)),
                cross_track_rms_mean_m: mean(of.iter().filter_map(|t| t.cross_track_rms_m)),
                cues_mean: mean(of.iter().filter_map(|t| t.cues.map(f64::from))),
                stops_total: of.iter().filter_map(|t| t.stops).sum(),
                missed_waypoints_total: of.iter().filter_map(|t| t.missed_waypoints).sum(),
                condition,
            }
        })
        .collect()
}

impl StudyAnalysis {
    /// The analysis as lines of text (what `vestnav study analyze` prints).
    #[allow(clippy::too_many_lines, reason = "one line format per section, read top to bottom")]
    pub fn summary_lines(&self) -> Vec<String> {
        let f1 = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |x| format!("{x:.1}"));
        let f2 = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |x| format!("{x:.2}"));
        let mut out = vec![
            format!(
                "protocol {}, task {}, {} participant(s), {} trials",
                if self.protocols.is_empty() { "-".to_owned() } else { self.protocols.join(" + ") },
                self.task.map_or("-", Task::name),
                self.participants.len(),
                self.trials
            ),
            format!(
                "outcomes: {}",
                self.outcomes
                    .iter()
                    .filter(|(_, n)| *n > 0)
                    .map(|(o, n)| format!("{o} {n}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ];
        if self.task != Some(Task::Navigation) {
            out.push(format!(
                "percent correct: {} % ({} of {} answered test trials)",
                f1(self.percent_correct),
                self.correct,
                self.answered
            ));
            if let Some(it) = self.it_bits {
                out.push(format!(
                    "information transfer: {} bits (corrected {} bits; at most {} bits for these stimuli; 2^IT = {:.1} stimuli)",
                    f2(Some(it)),
                    f2(self.it_corrected_bits),
                    f2(self.stimulus_bits),
                    it.exp2()
                ));
                out.push(format!("  {}", self.it_note));
            }
            if let Some(rt) = &self.rt {
                out.push(format!(
                    "response time: mean {:.0} ms, median {:.0} ms, IQR {:.0} ms ({:.0}–{:.0}), n = {}",
                    rt.mean_ms, rt.median_ms, rt.iqr_ms, rt.q1_ms, rt.q3_ms, rt.n
                ));
            }
            out.push("per stimulus (percent correct, answered, median RT):".to_owned());
            for s in &self.per_stimulus {
                out.push(format!(
                    "  {:<16} {:>6} %  {:>4}  {:>6} ms",
                    s.stimulus,
                    f1(s.percent_correct),
                    s.answered,
                    f1(s.rt_median_ms)
                ));
            }
            out.push("learning curve (block: percent correct, answered, median RT):".to_owned());
            for b in &self.learning {
                out.push(format!(
                    "  {} {}{}: {} %, {}, {} ms",
                    b.block,
                    b.block_name,
                    if b.training && !b.block_name.contains("training") { " (training)" } else { "" },
                    f1(b.percent_correct),
                    b.answered,
                    f1(b.rt_median_ms)
                ));
            }
            for p in &self.per_participant {
                out.push(format!(
                    "participant {}: {} % of {}, IT {} bits",
                    p.participant,
                    f1(p.percent_correct),
                    p.answered,
                    f2(p.it_bits)
                ));
            }
            if let Some(map) = &self.localization_map {
                out.push(
                    "localization map, percent correct (back view, wearer's left on the left):".to_owned(),
                );
                for row in map {
                    out.push(format!(
                        "  {}",
                        row.iter().map(|c| format!("{:>6}", f1(*c))).collect::<Vec<_>>().join(" ")
                    ));
                }
            }
        }
        if !self.navigation.is_empty() {
            out.push("navigation per condition (completed/trials, time, path/route, cross-track RMS, cues, stops, missed):".to_owned());
            for n in &self.navigation {
                out.push(format!(
                    "  {}: {}/{}, {} s, {}, {} m, {} cues, {} stops, {} missed",
                    n.condition,
                    n.completed,
                    n.trials,
                    f1(n.completion_mean_s),
                    f2(n.path_ratio_mean),
                    f2(n.cross_track_rms_mean_m),
                    f1(n.cues_mean),
                    n.stops_total,
                    n.missed_waypoints_total
                ));
            }
        }
        out
    }
}

#[cfg(test)]
#[path = "analysis_tests.rs"]
mod tests;
