use super::*;
use crate::study::protocol::Protocol;

/// Rosetta Code, "Pseudo-random numbers/Splitmix64": the first five outputs for seed 1234567 (the same
/// numbers Vigna's splitmix64.c prints).
#[test]
fn splitmix64_matches_the_published_sequence() {
    let mut r = SplitMix64::new(1_234_567);
    let expected = [
        6_457_827_717_110_365_317u64,
        3_203_168_211_198_807_973,
        9_817_491_932_198_370_423,
        4_593_380_528_125_082_431,
        16_408_922_859_458_223_821,
    ];
    for e in expected {
        assert_eq!(r.next_u64(), e);
    }
}

/// The FNV-1a reference values (Fowler, Noll, Vo test vectors): "", "a", "foobar".
#[test]
fn fnv1a_matches_the_reference_values() {
    assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
}

#[test]
fn below_is_in_range_and_roughly_uniform() {
    let mut r = SplitMix64::new(7);
    let mut counts = [0u32; 6];
    for _ in 0..60_000 {
        counts[r.below(6) as usize] += 1;
    }
    // Each count ~ Binomial(60000, 1/6): mean 10000, sd ~91; 5 sd either side.
    for c in counts {
        assert!((9_540..=10_460).contains(&c), "{counts:?}");
    }
}

/// Each condition once per row and column; for even n every ordered pair adjacent exactly once (n rows),
/// for odd n exactly twice over the square and its mirror (2n rows).
#[test]
fn williams_squares_2_to_8_are_balanced() {
    for n in 2..=8 {
        let rows = williams(n);
        let expected_rows = if n % 2 == 0 { n } else { 2 * n };
        assert_eq!(rows.len(), expected_rows, "n = {n}");
        for row in &rows {
            let mut sorted = row.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..n).collect::<Vec<_>>(), "n = {n}: row {row:?}");
        }
        // Columns: each condition the same number of times in each position (once per square).
        let per_square = rows.len() / n;
        for pos in 0..n {
            let mut count = vec![0; n];
            for row in &rows {
                count[row[pos]] += 1;
            }
            assert!(count.iter().all(|&c| c == per_square), "n = {n}, column {pos}: {count:?}");
        }
        // First-order carry-over.
        let mut pairs = vec![vec![0; n]; n];
        for row in &rows {
            for w in row.windows(2) {
                pairs[w[0]][w[1]] += 1;
            }
        }
        for (a, line) in pairs.iter().enumerate() {
            for (b, &c) in line.iter().enumerate() {
                let want = if a == b { 0 } else { per_square };
                assert_eq!(c, want, "n = {n}: pair ({a}, {b}) adjacent {c} times");
            }
        }
        // The first square alone is Latin for odd n too (rows and columns).
        for pos in 0..n {
            let mut seen: Vec<usize> = rows[..n].iter().map(|r| r[pos]).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>());
        }
    }
}

fn protocol(order: &str, participants: &str, reps: u32) -> Protocol {
    let text = format!(
        "name = \"p\"\ntask = \"localization\"\nseed = 99\norder = \"{order}\"\nparticipants = [{participants}]\n[localization]\nstimuli = [\"T0\", \"T1\", \"T2\", \"T3\"]\n[[block]]\nname = \"training\"\ntraining = true\nrepetitions = 1\n[[block]]\nname = \"test\"\nrepetitions = {reps}\n"
    );
    Protocol::parse(&text, "p.toml").unwrap()
}

#[test]
fn a_seed_reproduces_the_order_and_participants_differ() {
    let p = protocol("random", "\"A\", \"B\"", 5);
    let a1 = plan(&p, "A").unwrap();
    let a2 = plan(&p.clone(), "A").unwrap();
    assert_eq!(a1, a2);
    let b = plan(&p, "B").unwrap();
    assert_ne!(a1, b);
    // Every stimulus appears `repetitions` times per block.
    assert_eq!(a1.len(), 4 + 20);
    for s in ["T0", "T1", "T2", "T3"] {
        assert_eq!(a1.iter().filter(|t| t.block == 1 && t.answer == s).count(), 5);
    }
    // Indices run 0.. and blocks come in order with their flags.
    assert!(a1.iter().enumerate().all(|(i, t)| t.index == i));
    assert!(a1[..4].iter().all(|t| t.training && t.feedback && t.block_name == "training"));
    assert!(a1[4..].iter().all(|t| !t.training && !t.feedback));
    // Another seed, another order.
    let mut q = p.clone();
    q.seed = 100;
    assert_ne!(plan(&q, "A").unwrap(), a1);
}

/// The order is the documented recipe (module doc of `plan`), restated here independently, so a change of
/// generator or shuffle shows.
#[test]
fn a_random_order_follows_the_documented_shuffle() {
    let p = protocol("random", "\"A\"", 1);
    let seed = block_seed(99, "A", 1);
    // Independent restatement of the documented recipe: Fisher–Yates from the end with Lemire's bounded
    // integers (rejection never triggers for n <= 4 except with probability < 2^-61).
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut order = [0usize, 1, 2, 3];
    for i in (1..4).rev() {
        let j = ((u128::from(next()) * (i as u128 + 1)) >> 64) as usize;
        order.swap(i, j);
    }
    let got: Vec<String> = plan(&p, "A").unwrap()[4..].iter().map(|t| t.answer.clone()).collect();
    let want: Vec<String> = order.iter().map(|&i| crate::vest::tactor_label(i)).collect();
    assert_eq!(got, want);
}

#[test]
fn blocked_order_repeats_each_stimulus_in_a_row() {
    let p = protocol("blocked", "", 3);
    let t = plan(&p, "anyone").unwrap();
    let test: Vec<&str> = t[4..].iter().map(|t| t.answer.as_str()).collect();
    assert_eq!(test, ["T0", "T0", "T0", "T1", "T1", "T1", "T2", "T2", "T2", "T3", "T3", "T3"]);
}

#[test]
fn latin_square_rows_follow_the_participants_list() {
    let p = protocol("latin-square", "\"A\", \"B\", \"C\", \"D\", \"E\"", 2);
    let square = williams(4);
    for (k, who) in ["A", "B", "C", "D", "E"].iter().enumerate() {
        let t = plan(&p, who).unwrap();
        let row: Vec<String> = square[k % 4].iter().map(|&i| crate::vest::tactor_label(i)).collect();
        let test: Vec<String> = t[4..].iter().map(|t| t.answer.clone()).collect();
        assert_eq!(test[..4], row[..]);
        assert_eq!(test[4..], row[..]);
    }
    // Across the first four participants each stimulus opens the test block once.
    let firsts: std::collections::BTreeSet<String> =
        ["A", "B", "C", "D"].iter().map(|w| plan(&p, w).unwrap()[4].answer.clone()).collect();
    assert_eq!(firsts.len(), 4);
    // Unlisted participants are refused, an explicit index is allowed.
    assert!(plan(&p, "Z").unwrap_err().to_string().contains("\"Z\""));
    let b: Vec<String> = plan(&p, "B").unwrap().iter().map(|t| t.answer.clone()).collect();
    let z: Vec<String> = plan_for(&p, "Z", 1).iter().map(|t| t.answer.clone()).collect();
    assert_eq!(z, b);
}
