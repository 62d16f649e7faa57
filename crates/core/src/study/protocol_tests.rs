use std::path::Path;

use super::*;

/// The repository's docs/study folder (the example protocols).
fn docs() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/study")
}

const MINIMAL: &str = r#"
name = "m"
task = "localization"
[localization]
[[block]]
name = "test"
repetitions = 1
"#;

fn err(text: &str) -> ProtocolError {
    Protocol::parse_in(text, "broken.toml", Path::new("/nonexistent")).expect_err("must be refused")
}

#[test]
fn every_example_protocol_parses() {
    let loc = Protocol::load(&docs().join("localization.toml")).unwrap();
    assert_eq!(loc.task, Task::Localization);
    assert_eq!(loc.stimuli.len(), 16);
    assert_eq!(loc.blocks.len(), 4);
    assert!(loc.blocks[0].training && loc.blocks[0].feedback);
    assert!(loc.blocks[1..].iter().all(|b| !b.training && !b.feedback && b.order == Order::LatinSquare));
    assert_eq!(loc.blocks[0].order, Order::Random);
    assert_eq!(loc.trials_per_participant(), 16 * 7);
    assert_eq!(loc.choices()[0], "T0");
    assert_eq!(loc.choices().len(), 16);
    // Its training block gives 2.5 s of feedback and waits; its test blocks time out after 4 s, 800 ms apart.
    let training = loc.block_timing(0);
    assert_eq!(
        (training.feedback_ms, training.response_timeout_s, training.iti_ms),
        (Some(2500), None, None)
    );
    for b in 1..4 {
        let test = loc.block_timing(b);
        assert_eq!((test.feedback_ms, test.response_timeout_s, test.iti_ms), (None, Some(4.0), Some(800)));
    }

    let pat = Protocol::load(&docs().join("pattern-id.toml")).unwrap();
    assert_eq!(pat.task, Task::PatternId);
    assert_eq!(pat.choices(), ["left", "right", "stop", "corner sweep", "double tap"]);
    // The pattern editor's file: four single-tactor frames of 200 ms around the corners.
    let sweep = pat.stimuli[3].pattern().unwrap();
    assert_eq!(sweep.frames.len(), 4);
    assert_eq!(sweep.total_ms(), 800);
    assert_eq!(pat.stimuli[3].intensity(), Some(200));
    // The cue: the same frames as the console's own turn-left cue at 300 ms.
    assert_eq!(pat.stimuli[0].pattern().unwrap().frames, crate::vest::Cue::TurnLeft.pattern(300).frames);
    let tap = pat.stimuli[4].pattern().unwrap();
    assert_eq!(tap.frames.len(), 3);
    assert_eq!(tap.frames[1].mask, TactorMask::NONE);

    let nav = Protocol::load(&docs().join("navigation.toml")).unwrap();
    assert_eq!(nav.task, Task::Navigation);
    assert_eq!(nav.stimuli.len(), 4);
    assert_eq!(nav.stimuli[1].label(), "demo/bearing-compass");
    assert!(nav.stimuli[0].pattern().is_none());
    assert!(nav.choices().is_empty());
    assert_eq!(nav.timing.iti_ms, Some(5000));
    assert_eq!(nav.timing.time_limit_s, Some(900.0));
}

#[test]
fn timing_keys_are_read_and_out_of_range_ones_name_their_line() {
    // Top-level keys, before the first table.
    let keys = "task = \"localization\"\niti_ms = 250\nfeedback_ms = 0\nresponse_timeout_s = 4.5\n";
    let text = MINIMAL.replacen("task = \"localization\"\n", keys, 1);
    let p = Protocol::parse(&text, "t.toml").unwrap();
    assert_eq!(
        p.timing,
        TimingKeys {
            iti_ms: Some(250),
            feedback_ms: Some(0),
            response_timeout_s: Some(4.5),
            time_limit_s: None
        }
    );
    assert_eq!(Protocol::parse(MINIMAL, "m.toml").unwrap().timing, TimingKeys::default());
    for (key, line) in [
        ("iti_ms = -1", 4),
        ("iti_ms = 60001", 4),
        ("feedback_ms = 70000", 4),
        ("response_timeout_s = 0.1", 4),
        ("response_timeout_s = 5000.0", 4),
        ("response_timeout_s = nan", 4),
    ] {
        let text =
            MINIMAL.replacen("task = \"localization\"\n", &format!("task = \"localization\"\n{key}\n"), 1);
        let e = err(&text);
        assert_eq!(e.line(), Some(line), "{key} -> {e}");
        assert!(e.to_string().contains("is outside"), "{e}");
    }
    let e = err("name = \"n\"\ntask = \"navigation\"\n[navigation]\nroutes = []\ntime_limit_s = 5.0\n");
    assert!(e.to_string().contains("broken.toml:5: time_limit_s = 5 is outside 10..=14400"), "{e}");
}

/// Two blocks: a training block that sets its own feedback and ITI, a test block with a response timeout;
/// the protocol's own `iti_ms` serves the test block.
const TWO_BLOCKS: &str = r#"name = "b"
task = "localization"
iti_ms = 800
feedback_ms = 1500
[localization]
stimuli = ["T0", "T1"]
[[block]]
name = "training"
training = true
repetitions = 1
feedback_ms = 4000
iti_ms = 2000
[[block]]
name = "test"
repetitions = 2
response_timeout_s = 3.0
"#;

#[test]
fn block_timing_keys_win_over_the_protocols_and_leave_the_rest_to_it() {
    let p = Protocol::parse(TWO_BLOCKS, "b.toml").unwrap();
    let keys =
        |iti, fb, rt| TimingKeys { iti_ms: iti, feedback_ms: fb, response_timeout_s: rt, time_limit_s: None };
    assert_eq!(p.blocks[0].timing, keys(Some(2000), Some(4000), None));
    assert_eq!(p.blocks[1].timing, keys(None, None, Some(3.0)));
    // Training: its own ITI and feedback, no response timeout anywhere (the runner's default then).
    assert_eq!(p.block_timing(0), keys(Some(2000), Some(4000), None));
    // Test: its own timeout, the protocol's ITI and feedback.
    assert_eq!(p.block_timing(1), keys(Some(800), Some(1500), Some(3.0)));
    assert_eq!(p.block_timing(7), p.timing);
    // As `vestnav study check` prints them.
    assert_eq!(p.block_timing(1).summary(), "iti_ms = 800, feedback_ms = 1500, response_timeout_s = 3");
    assert_eq!(TimingKeys::default().summary(), "none");
    // A protocol without block keys: every block's timing is the protocol's (as before block keys).
    let plain = TWO_BLOCKS
        .lines()
        .filter(|l| {
            !(l.starts_with("feedback_ms = 4000")
                || l.starts_with("iti_ms = 2000")
                || l.starts_with("response_timeout_s"))
        })
        .collect::<Vec<_>>()
        .join("\n");
    let plain = Protocol::parse(&plain, "plain.toml").unwrap();
    assert!(plain.blocks.iter().all(|b| b.timing.is_empty()));
    assert_eq!((plain.block_timing(0), plain.block_timing(1)), (plain.timing, plain.timing));
    // The example protocols without block keys read as before.
    for name in ["pattern-id.toml", "navigation.toml"] {
        let p = Protocol::load(&docs().join(name)).unwrap();
        assert!(p.blocks.iter().all(|b| b.timing.is_empty()), "{name}");
    }
}

#[test]
fn out_of_range_block_timing_keys_name_the_key_line_in_the_block_table() {
    // TWO_BLOCKS's line 16 is the test block's `response_timeout_s = 3.0`; lines 11 and 12 the training
    // block's `feedback_ms = 4000` and `iti_ms = 2000`.
    for (from, to, line, says) in [
        (
            "response_timeout_s = 3.0",
            "response_timeout_s = 0.2",
            16,
            "block \"test\": response_timeout_s = 0.2 is outside 0.5..=3600",
        ),
        (
            "response_timeout_s = 3.0",
            "response_timeout_s = inf",
            16,
            "block \"test\": response_timeout_s = inf is outside",
        ),
        ("iti_ms = 2000", "iti_ms = 60001", 12, "block \"training\": iti_ms = 60001 is outside 0..=60000"),
        ("iti_ms = 2000", "iti_ms = -5", 12, "block \"training\": iti_ms = -5 is outside"),
        (
            "feedback_ms = 4000",
            "feedback_ms = 99999",
            11,
            "block \"training\": feedback_ms = 99999 is outside",
        ),
        (
            "response_timeout_s = 3.0",
            "time_limit_s = 60.0",
            16,
            "time_limit_s applies to the blocks of a navigation protocol only",
        ),
        ("response_timeout_s = 3.0", "response_timeout_s = \"3\"", 16, "invalid type"),
    ] {
        let text = TWO_BLOCKS.replacen(from, to, 1);
        let e = err(&text);
        assert_eq!(e.line(), Some(line), "{to} -> {e}");
        assert_eq!(e.problems.len(), 1, "{e}");
        assert!(e.to_string().contains(says), "{to} -> {e}");
        assert!(e.to_string().starts_with(&format!("broken.toml:{line}: ")), "{e}");
    }
    // Every bad key of a file is reported, each with its line, in file order.
    let text = TWO_BLOCKS.replacen("iti_ms = 2000", "iti_ms = 70000", 1).replacen("= 3.0", "= 0.0", 1);
    let lines: Vec<Option<usize>> = err(&text).problems.iter().map(|p| p.line).collect();
    assert_eq!(lines, [Some(12), Some(16)]);
}

#[test]
fn a_navigation_block_may_set_its_own_time_limit() {
    let dir = std::env::temp_dir().join(format!("vestnav-blocktiming-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("r.gpx"), "any file: parsing only checks that it is one").unwrap();
    let text = "name = \"n\"\ntask = \"navigation\"\n[navigation]\nroutes = [\"r.gpx\"]\ntime_limit_s = 600.0\n\
                [[condition]]\nname = \"c\"\nstrategy = \"bearing\"\nheading = \"cog\"\ncue_set = \"walking\"\n\
                cue_interval_s = 3.0\n[[block]]\nname = \"practice\"\nrepetitions = 1\ntime_limit_s = 120.0\n\
                [[block]]\nname = \"test\"\nrepetitions = 1\n";
    let p = Protocol::parse_in(text, "n.toml", &dir).unwrap();
    assert_eq!((p.block_timing(0).time_limit_s, p.block_timing(1).time_limit_s), (Some(120.0), Some(600.0)));
    let e = Protocol::parse_in(&text.replace("120.0", "5.0"), "n.toml", &dir).unwrap_err();
    assert!(
        e.to_string().contains("n.toml:15: block \"practice\": time_limit_s = 5 is outside 10..=14400"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn labels_round_trip() {
    for i in 0..16 {
        assert_eq!(parse_tactor_label(&tactor_label(i)), Some(i));
    }
    assert_eq!(parse_mask_label("T0+T3"), Some(TactorMask::from_indices([0, 3])));
    assert_eq!(mask_label(TactorMask::from_indices([15, 0])), "T0+T15");
    assert_eq!(parse_tactor_label("T-1"), None);
    assert_eq!(parse_tactor_label("T+3"), None);
    assert_eq!(parse_tactor_label("T16"), None);
    assert_eq!(parse_mask_label("T0+"), None);
    assert_eq!(label_cell("T6"), Some((1, 2)));
}

#[test]
fn a_tactor_stimulus_plays_its_on_time_repeats_and_pause() {
    let s = Stimulus::Tactors {
        tactors: TactorMask::single(5).unwrap(),
        on_ms: 300,
        intensity: 9,
        repeats: 3,
        isi_ms: 200,
    };
    let p = s.pattern().unwrap();
    assert_eq!(p.repeats, 3);
    assert_eq!(p.total_ms(), 3 * 500);
    assert_eq!(p.longest_on_ms(), 300);
    assert_eq!(s.answer(), "T5");
}

#[test]
fn minimal_protocol_defaults() {
    let p = Protocol::parse(MINIMAL, "m.toml").unwrap();
    assert_eq!(p.order, Order::Random);
    assert_eq!(p.seed, 0);
    assert!(matches!(
        p.stimuli[0],
        Stimulus::Tactors { on_ms: 500, intensity: 255, repeats: 1, isi_ms: 0, .. }
    ));
}

/// Each broken file is refused with the line of its fault (counted by hand in the text).
#[test]
fn broken_files_name_their_line() {
    let cases: &[(&str, usize, &str)] = &[
        // TOML syntax error on line 3.
        ("name = \"x\"\ntask = \"localization\"\nseed = = 3\n", 3, ""),
        // Unknown key on line 3.
        ("name = \"x\"\ntask = \"localization\"\ncolour = 1\n", 3, "colour"),
        // Unknown task on line 2.
        (
            "name = \"x\"\ntask = \"juggling\"\n[localization]\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            2,
            "juggling",
        ),
        // Intensity out of range on line 5.
        (
            "name = \"x\"\ntask = \"localization\"\n[localization]\non_ms = 100\nintensity = 300\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            5,
            "intensity",
        ),
        // A tactor that does not exist, on line 4.
        (
            "name = \"x\"\ntask = \"localization\"\n[localization]\nstimuli = [\"T0\",\n  \"T16\"]\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            5,
            "T16",
        ),
        // Zero repetitions on line 7.
        (
            "name = \"x\"\ntask = \"localization\"\n[localization]\n\n[[block]]\nname = \"b\"\nrepetitions = 0\n",
            7,
            "repetitions",
        ),
        // A training block after a test block: the training block's name line (9).
        (
            "name = \"x\"\ntask = \"localization\"\n[localization]\n[[block]]\nname = \"t\"\nrepetitions = 1\n[[block]]\ntraining = true\nname = \"tr\"\nrepetitions = 1\n",
            9,
            "training",
        ),
        // Unknown order on line 3.
        (
            "name = \"x\"\ntask = \"localization\"\norder = \"alphabetical\"\n[localization]\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            3,
            "alphabetical",
        ),
        // A Latin square without participants: the order line (3).
        (
            "name = \"x\"\ntask = \"localization\"\norder = \"latin-square\"\n[localization]\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            3,
            "participants",
        ),
        // A pattern with an unknown cue on line 5.
        (
            "name = \"x\"\ntask = \"pattern-id\"\n[[pattern]]\nname = \"a\"\ncue = \"wiggle\"\n[[pattern]]\nname = \"b\"\ncue = \"stop\"\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            5,
            "wiggle",
        ),
        // A pattern file that does not exist, line 8.
        (
            "name = \"x\"\ntask = \"pattern-id\"\n[[pattern]]\nname = \"a\"\ncue = \"stop\"\n[[pattern]]\nname = \"b\"\nfile = \"missing.json\"\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            8,
            "missing.json",
        ),
        // Duplicate participant on line 4.
        (
            "name = \"x\"\ntask = \"localization\"\nparticipants = [\"A\",\n \"A\"]\n[localization]\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            4,
            "twice",
        ),
        // A navigation condition with an unknown strategy on line 7, and its route missing (line 4).
        (
            "name = \"x\"\ntask = \"navigation\"\n[navigation]\nroutes = [\"r.gpx\"]\n[[condition]]\nname = \"c\"\nstrategy = \"teleport\"\nheading = \"cog\"\ncue_set = \"walking\"\ncue_interval_s = 3.0\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            4,
            "r.gpx",
        ),
        // Wrong type (a string for an integer) on line 4.
        (
            "name = \"x\"\ntask = \"localization\"\n[localization]\non_ms = \"long\"\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            4,
            "",
        ),
        // A localization table in a pattern-id protocol, line 3.
        (
            "name = \"x\"\ntask = \"pattern-id\"\n[localization]\n[[pattern]]\nname = \"a\"\ncue = \"stop\"\n[[pattern]]\nname = \"b\"\ncue = \"forward\"\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
            3,
            "does not belong",
        ),
    ];
    for (text, line, needle) in cases {
        let e = err(text);
        assert_eq!(e.line(), Some(*line), "{text}\n-> {e}");
        assert!(e.to_string().starts_with(&format!("broken.toml:{line}: ")), "{e}");
        assert!(e.to_string().contains(needle), "{e} lacks {needle}");
    }
    // Both problems of the navigation case are reported, in line order.
    let e = err(cases[12].0);
    assert_eq!(e.problems.len(), 2, "{e}");
    assert_eq!(e.problems[1].line, Some(7));
}

#[test]
fn no_blocks_is_an_error() {
    let e = err("name = \"x\"\ntask = \"localization\"\n[localization]\n");
    assert!(e.to_string().contains("block"), "{e}");
}

#[test]
fn oversized_and_non_utf8_files_are_refused() {
    let dir = std::env::temp_dir().join(format!("vestnav-study-proto-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let big = dir.join("big.toml");
    std::fs::write(&big, vec![b'#'; MAX_PROTOCOL_BYTES as usize + 10]).unwrap();
    let e = Protocol::load(&big).unwrap_err();
    assert!(e.to_string().contains("larger than"), "{e}");
    let bin = dir.join("bin.toml");
    std::fs::write(&bin, [0xff, 0xfe, 0x00]).unwrap();
    assert!(Protocol::load(&bin).unwrap_err().to_string().contains("UTF-8"));
    assert!(Protocol::load(&dir).unwrap_err().to_string().contains("not a regular file"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn check_stimuli_names_the_refused_stimulus_line() {
    let text = "name = \"x\"\ntask = \"pattern-id\"\n[[pattern]]\nname = \"short\"\nframes = [{ tactors = \"T0\", ms = 100 }]\n[[pattern]]\nname = \"long\"\nframes = [{ tactors = \"T0\", ms = 3000 }]\n[[block]]\nname = \"b\"\nrepetitions = 1\n";
    let p = Protocol::parse(text, "x.toml").unwrap();
    let limit = |pat: &Pattern| {
        if pat.longest_on_ms() > 2000 { Err(format!("on for {} ms", pat.longest_on_ms())) } else { Ok(()) }
    };
    let e = p.check_stimuli(limit).unwrap_err();
    assert_eq!(e.problems.len(), 1);
    assert_eq!(e.line(), Some(7));
    assert!(e.to_string().contains("long: on for 3000 ms"), "{e}");
}

proptest::proptest! {
    /// No text makes the parser panic.
    #[test]
    fn parser_never_panics(text in "[a-z_\\[\\]=\"0-9 .,\\n+T-]{0,300}") {
        let _ = Protocol::parse_in(&text, "fuzz.toml", Path::new("/nonexistent"));
    }
}
