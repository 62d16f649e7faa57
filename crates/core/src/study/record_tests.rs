use super::*;

fn sample() -> Vec<TrialRecord> {
    let mut a = TrialRecord::new("P01", "S1", "loc, \"quoted\"", Task::Localization);
    a.block_name = "test".into();
    a.trial = 3;
    a.block = 1;
    a.stimulus = "T0+T3".into();
    a.answer = "T0+T3".into();
    a.response = Some("T0".into());
    a.correct = Some(false);
    a.stimulus_on_s = Some(12_345.678_901_234_5);
    a.response_s = Some(12_346.1);
    a.rt_ms = Some(421.098_765_5);
    a.outcome = Outcome::Answered;
    a.iti_ms = Some(750);
    a.response_timeout_s = Some(2.5);
    a.notes = "line one\nline two, with \"quotes\"".into();
    let mut b = TrialRecord::new("P01", "S1", "nav", Task::Navigation);
    b.stimulus = "demo/bearing-cog".into();
    b.answer = b.stimulus.clone();
    b.outcome = Outcome::Completed;
    b.completion_s = Some(301.5);
    b.path_m = Some(420.25);
    b.route_m = Some(400.0);
    b.cross_track_rms_m = Some(3.2);
    b.cues = Some(41);
    b.stops = Some(0);
    b.missed_waypoints = Some(1);
    b.training = true;
    b.feedback = true;
    b.iti_ms = Some(5000);
    b.feedback_ms = Some(0);
    b.time_limit_s = Some(900.0);
    let mut c = TrialRecord::new("P02", "S1", "loc", Task::Localization);
    c.outcome = Outcome::Stopped;
    vec![a, b, c]
}

#[test]
fn csv_round_trips_every_field() {
    let rows = sample();
    let text = write_csv(&rows);
    assert_eq!(read_csv(&text).unwrap(), rows);
    // One header line + three rows, one of which holds a quoted line break.
    assert_eq!(text.lines().count(), 1 + 3 + 1);
    assert!(text.starts_with("participant,session,protocol,task,block,"));
    assert_eq!(text.lines().next().unwrap().split(',').count(), CSV_COLUMNS.len());
}

#[test]
fn json_round_trips() {
    let rows = sample();
    let back: Vec<TrialRecord> = serde_json::from_str(&write_json(&rows)).unwrap();
    assert_eq!(back, rows);
}

#[test]
fn columns_may_come_in_any_order_with_extras() {
    let rows = sample();
    let text = write_csv(&rows[2..]);
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rev = |v: &[&str]| v.iter().rev().copied().collect::<Vec<_>>().join(",");
    let shuffled = format!("extra,{}\r\n\r\nx,{}\r\n", rev(&header), rev(&row));
    assert_eq!(read_csv(&shuffled).unwrap(), rows[2..]);
}

#[test]
fn hostile_csv_errors_name_the_line() {
    let good = write_csv(&sample());
    let header = csv_header();
    let row = csv_row(&sample()[2]);
    let cases: Vec<(String, usize, &str)> = vec![
        (String::new(), 1, "header"),
        ("a,b,c\n".into(), 1, "participant"),
        (format!("{header}{row}{}", row.replacen(",localization,", ",juggling,", 1)), 3, "juggling"),
        (format!("{header}{}", row.replacen(",stopped,", ",exploded,", 1)), 2, "exploded"),
        (format!("{header}{row}{row}{}", row.replacen(",0,", ",-1,", 1)), 4, "block"),
        (format!("{header}{}", row.trim_end().to_owned() + ",extra\n"), 2, "fields"),
        (format!("{header}\"unclosed,{row}"), 2, "never closed"),
        (format!("{header}a\"b{row}"), 2, "quote"),
        (format!("{header}{}", row.replacen(",stopped,", ",stopped,NaN", 1)), 2, "finite"),
        (format!("{good}{}", "x".repeat(MAX_FIELD_BYTES + 1)), 6, "longer"),
    ];
    for (text, line, needle) in cases {
        let e = read_csv(&text).unwrap_err();
        assert_eq!(e.line, line, "{e}");
        assert!(e.to_string().contains(needle), "{e} lacks {needle}");
    }
}

/// A results file written before the timing columns: the same text less those four columns (cut out of a
/// file written now), read with them empty; its JSON, without the four fields, reads the same.
#[test]
fn files_from_before_the_timing_columns_read_with_the_timing_empty() {
    let rows = sample();
    let keep: Vec<usize> = CSV_COLUMNS
        .iter()
        .enumerate()
        .filter(|(_, (n, _))| !OPTIONAL_COLUMNS.contains(n))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(keep.len(), 25, "the 25 columns of the first results files");
    // Row c has no comma or line break inside a field: cut by comma.
    let cut = |line: &str| {
        let cells: Vec<&str> = line.trim_end().split(',').collect();
        keep.iter().map(|&i| cells[i]).collect::<Vec<_>>().join(",")
    };
    let old = format!("{}\n{}\n", cut(&csv_header()), cut(&csv_row(&rows[2])));
    assert!(!old.contains("iti_ms"));
    let mut expected = rows[2].clone();
    (expected.iti_ms, expected.feedback_ms, expected.response_timeout_s, expected.time_limit_s) =
        (None, None, None, None);
    assert_eq!(read_csv(&old).unwrap(), [expected.clone()]);
    let mut json: serde_json::Value = serde_json::from_str(&write_json(&[expected.clone()])).unwrap();
    for name in OPTIONAL_COLUMNS {
        json[0].as_object_mut().unwrap().remove(name);
    }
    let back: Vec<TrialRecord> = serde_json::from_value(json).unwrap();
    assert_eq!(back, [expected]);
    // Any other column is still required.
    let e = read_csv(&old.replacen("outcome", "result", 1)).unwrap_err();
    assert!(e.to_string().contains("\"outcome\""), "{e}");
}

#[test]
fn every_column_is_documented() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/study.md")).unwrap();
    for (name, meaning) in CSV_COLUMNS {
        assert!(doc.contains(&format!("| `{name}` | {meaning} |")), "docs/study.md lacks the row of {name}");
    }
}

proptest::proptest! {
    /// Any text: an error or records, never a panic; any record written reads back the same.
    #[test]
    fn reader_never_panics(text in "[a-z0-9,\"\\r\\n.-]{0,300}") {
        let _ = read_csv(&format!("{}{text}", csv_header()));
    }

    #[test]
    fn any_strings_round_trip(p in "\\PC{0,20}", notes in "[ -~\\n\\r\",]{0,40}", rt in proptest::option::of(-1e9f64..1e9)) {
        let mut r = TrialRecord::new(&p, "s", "x", Task::PatternId);
        r.notes = notes;
        r.rt_ms = rt;
        r.response = Some(format!("{p}!"));
        let back = read_csv(&write_csv(std::slice::from_ref(&r))).unwrap();
        proptest::prop_assert_eq!(back, vec![r]);
    }
}
