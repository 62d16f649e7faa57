use approx::assert_relative_eq;

use super::*;
use crate::study::plan::SplitMix64;
use crate::study::record::{read_csv, write_csv};

fn trial(
    p: &str,
    block: usize,
    training: bool,
    stimulus: &str,
    response: Option<&str>,
    rt: Option<f64>,
) -> TrialRecord {
    let mut r = TrialRecord::new(p, "S1", "loc", Task::Localization);
    r.block = block;
    r.block_name = if training { "training".into() } else { format!("test{block}") };
    r.training = training;
    r.stimulus = stimulus.into();
    r.answer = stimulus.into();
    r.response = response.map(str::to_owned);
    r.correct = response.map(|x| x == stimulus);
    r.rt_ms = rt;
    r.outcome = if response.is_some() { Outcome::Answered } else { Outcome::NoResponse };
    r
}

/// Quartiles of 1, 2, 3, 4 by type 7 (R's `quantile(1:4)`): 1.75, 2.5, 3.25.
#[test]
fn rt_quartiles_follow_type_7() {
    let s = RtStats::of(&[4.0, 1.0, 3.0, 2.0, f64::NAN]).unwrap();
    assert_eq!(s.n, 4);
    assert_relative_eq!(s.q1_ms, 1.75);
    assert_relative_eq!(s.median_ms, 2.5);
    assert_relative_eq!(s.q3_ms, 3.25);
    assert_relative_eq!(s.iqr_ms, 1.5);
    assert_relative_eq!(s.mean_ms, 2.5);
    assert!(RtStats::of(&[]).is_none());
}

#[test]
fn scoring_counts_test_answers_only() {
    let rows = vec![
        trial("A", 0, true, "T0", Some("T1"), Some(900.0)),
        trial("A", 1, false, "T0", Some("T0"), Some(400.0)),
        trial("A", 1, false, "T1", Some("T2"), Some(600.0)),
        trial("A", 1, false, "T2", None, None),
        trial("B", 1, false, "T2", Some("T2"), Some(500.0)),
    ];
    let a = analyze(&rows);
    assert_eq!(a.answered, 3);
    assert_eq!(a.correct, 2);
    assert_relative_eq!(a.percent_correct.unwrap(), 200.0 / 3.0);
    assert_eq!(a.outcomes.iter().find(|(o, _)| o == "no-response").unwrap().1, 1);
    assert_eq!(a.rt.as_ref().unwrap().n, 3);
    assert_relative_eq!(a.rt.as_ref().unwrap().median_ms, 500.0);
    // Learning curve: the training block (0 of 1) then the test block (2 of 3).
    assert_eq!(a.learning.len(), 2);
    assert_eq!(a.learning[0].percent_correct, Some(0.0));
    assert!(a.learning[0].training);
    assert_relative_eq!(a.learning[1].percent_correct.unwrap(), 200.0 / 3.0);
    // Map: T0 100 %, T1 0 %, T2 100 %, never presented: None.
    let map = a.localization_map.unwrap();
    assert_eq!(map[0][..3], [Some(100.0), Some(0.0), Some(100.0)]);
    assert_eq!(map[3][3], None);
    // Per participant.
    assert_eq!(a.per_participant.len(), 2);
    assert_eq!(a.per_participant[1].percent_correct, Some(100.0));
    // Rows in tactor order; the stray response T2 to T1 is a column.
    let m = a.confusion.as_ref().unwrap();
    assert_eq!(m.stimuli, ["T0", "T1", "T2"]);
    assert_eq!(m.counts[1], [0, 0, 1]);
    assert!(a.summary_lines().iter().any(|l| l.contains("percent correct: 66.7 %")));
}

/// Tactor `i`'s 4-neighbours on the grid.
fn neighbours(i: usize) -> Vec<usize> {
    let (r, c) = (i32::try_from(i / 4).unwrap(), i32::try_from(i % 4).unwrap());
    [(r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)]
        .into_iter()
        .filter(|&(r, c)| (0..4).contains(&r) && (0..4).contains(&c))
        .map(|(r, c)| (r * 4 + c) as usize)
        .collect()
}

/// A simulated wearer who reports the right tactor with probability `p` and otherwise one of its grid
/// neighbours at random: percent correct and information transfer of a large sample agree with the
/// channel's own values, computed here from its probabilities (not from any counts).
#[test]
fn a_simulated_wearer_gives_the_channels_values() {
    let p_correct = 0.7;
    // The true channel: P(j | i) and, with equally likely stimuli, its mutual information.
    let channel: Vec<Vec<f64>> = (0..16)
        .map(|i| {
            let nb = neighbours(i);
            (0..16)
                .map(|j| {
                    if j == i {
                        p_correct
                    } else if nb.contains(&j) {
                        (1.0 - p_correct) / nb.len() as f64
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    let col: Vec<f64> = (0..16).map(|j| channel.iter().map(|row| row[j] / 16.0).sum()).collect();
    let true_it: f64 = (0..16)
        .flat_map(|i| (0..16).map(move |j| (i, j)))
        .map(|(i, j)| {
            let pij = channel[i][j] / 16.0;
            if pij > 0.0 { pij * (pij / ((1.0 / 16.0) * col[j])).log2() } else { 0.0 }
        })
        .sum();

    let mut rng = SplitMix64::new(2008);
    let reps = 200;
    let mut rows = Vec::new();
    for _ in 0..reps {
        for i in 0..16 {
            let nb = neighbours(i);
            let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            let j = if u < p_correct { i } else { nb[rng.below(nb.len() as u64) as usize] };
            let label = crate::vest::tactor_label(i);
            rows.push(trial("sim", 1, false, &label, Some(&crate::vest::tactor_label(j)), Some(500.0)));
        }
    }
    // Through the CSV, as a real results file.
    let a = analyze(&read_csv(&write_csv(&rows)).unwrap());
    let n = f64::from(16 * reps);
    // Percent correct: binomial standard error, within 4 of them.
    let se = (p_correct * (1.0 - p_correct) / n).sqrt() * 100.0;
    assert!((a.percent_correct.unwrap() - 70.0).abs() < 4.0 * se, "{:?}", a.percent_correct);
    // IT: the corrected estimate within 0.1 bits of the channel's (3200 trials, 16 stimuli; the raw
    // estimate sits above it by about its bias).
    let it = a.it_bits.unwrap();
    let corrected = a.it_corrected_bits.unwrap();
    assert!((corrected - true_it).abs() < 0.1, "true {true_it:.3}, corrected {corrected:.3}, raw {it:.3}");
    assert!(it > corrected);
    eprintln!(
        "simulated wearer: true IT {true_it:.3} bits, raw {it:.3}, corrected {corrected:.3}, {:.1} %",
        a.percent_correct.unwrap()
    );
    assert!(a.it_note.contains("3200 trials reach 5 K^2 = 1280 for K = 16"), "{}", a.it_note);
    // The map is 70 % everywhere within sampling error of 200 trials a tactor.
    let se_cell = (0.7f64 * 0.3 / f64::from(reps)).sqrt() * 100.0;
    for row in a.localization_map.unwrap() {
        for cell in row {
            assert!((cell.unwrap() - 70.0).abs() < 4.5 * se_cell, "{cell:?}");
        }
    }
}

#[test]
fn navigation_summaries_per_condition() {
    let nav =
        |cond: &str, outcome: Outcome, t: f64, path: f64, xt: f64, cues: u32, stops: u32, missed: u32| {
            let mut r = TrialRecord::new("P", "S", "nav", Task::Navigation);
            r.stimulus = format!("park/{cond}");
            r.answer = r.stimulus.clone();
            r.outcome = outcome;
            r.completion_s = Some(t);
            r.path_m = Some(path);
            r.route_m = Some(400.0);
            r.cross_track_rms_m = Some(xt);
            r.cues = Some(cues);
            r.stops = Some(stops);
            r.missed_waypoints = Some(missed);
            r
        };
    let rows = vec![
        nav("a", Outcome::Completed, 300.0, 440.0, 2.0, 10, 0, 0),
        nav("a", Outcome::Completed, 340.0, 480.0, 4.0, 20, 1, 1),
        nav("b", Outcome::Stopped, 100.0, 100.0, 9.0, 5, 2, 3),
    ];
    let a = analyze(&rows);
    assert!(a.confusion.is_none() && a.it_bits.is_none());
    assert_eq!(a.navigation.len(), 2);
    let s = &a.navigation[0];
    assert_eq!((s.condition.as_str(), s.trials, s.completed), ("a", 2, 2));
    assert_relative_eq!(s.completion_mean_s.unwrap(), 320.0);
    assert_relative_eq!(s.path_ratio_mean.unwrap(), 1.15);
    assert_relative_eq!(s.cross_track_rms_mean_m.unwrap(), 3.0);
    assert_relative_eq!(s.cues_mean.unwrap(), 15.0);
    assert_eq!((s.stops_total, s.missed_waypoints_total), (1, 1));
    // A stopped walk has no completion time in the mean.
    assert_eq!(a.navigation[1].completed, 0);
    assert_eq!(a.navigation[1].completion_mean_s, None);
    assert!(a.summary_lines().iter().any(|l| l.starts_with("  a: 2/2, 320.0 s, 1.15")));
}

#[test]
fn empty_results_analyse_to_nothing() {
    let a = analyze(&[]);
    assert_eq!(a.trials, 0);
    assert!(a.percent_correct.is_none() && a.rt.is_none() && a.confusion.is_none());
    assert!(!a.summary_lines().is_empty());
}
