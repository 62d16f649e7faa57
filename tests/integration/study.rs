//! `vestnav study check|analyze` (issue 25): the example protocols pass with their plan printed, a broken
//! one fails with status 1 and the line of each fault, and the analysis of the example results agrees with
//! counts made here from the CSV text directly.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_vestnav")
}

fn docs(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/study").join(rel)
}

#[test]
fn check_passes_the_examples_and_prints_their_plan() {
    for name in ["localization.toml", "pattern-id.toml", "navigation.toml"] {
        let out = Command::new(bin()).args(["study", "check"]).arg(docs(name)).output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(text.contains("valid"), "{text}");
        assert!(text.contains("P01: "), "{text}");
    }
    let out = Command::new(bin())
        .args(["study", "check", "--participant", "P02"])
        .arg(docs("localization.toml"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let plan_lines = text.lines().skip_while(|l| !l.starts_with("trial\t")).count();
    assert_eq!(plan_lines, 1 + 16 * 7, "{text}");
}

#[test]
fn check_fails_with_the_lines_of_a_broken_protocol() {
    let dir = std::env::temp_dir().join(format!("vestnav-study-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.toml");
    // Line 4: intensity out of range; line 8: zero repetitions; line 12: 2.5 s on a unit whose limit is 2 s.
    std::fs::write(
        &path,
        "name = \"b\"\ntask = \"localization\"\n[localization]\nintensity = 0\n\n[[block]]\nname = \"t\"\nrepetitions = 0\n",
    )
    .unwrap();
    let out = Command::new(bin()).args(["study", "check"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("broken.toml:4: intensity = 0"), "{err}");
    assert!(err.contains("broken.toml:8: repetitions = 0"), "{err}");
    // Valid TOML, but a stimulus longer than the unit allows: refused by the device's limits.
    std::fs::write(
        &path,
        "name = \"b\"\ntask = \"localization\"\n[localization]\nstimuli = [\"T0\"]\non_ms = 2500\n[[block]]\nname = \"t\"\nrepetitions = 1\n",
    )
    .unwrap();
    let out = Command::new(bin()).args(["study", "check"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("broken.toml:4: stimulus T0: "), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn analyze_agrees_with_counts_from_the_csv_text() {
    let csv = docs("example-localization.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    // Counted here from the text (the example has no quoted fields): answered test trials, correct ones,
    // and the information transfer of their counts.
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (training, stimulus, response, correct) =
        (col("training"), col("stimulus"), col("response"), col("correct"));
    let mut cells: BTreeMap<(String, String), f64> = BTreeMap::new();
    let (mut answered, mut right) = (0.0, 0.0);
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        if f[training] == "0" && !f[response].is_empty() {
            answered += 1.0;
            right += f64::from(u8::from(f[correct] == "1"));
            *cells.entry((f[stimulus].to_owned(), f[response].to_owned())).or_default() += 1.0;
        }
    }
    let mut rows: BTreeMap<&str, f64> = BTreeMap::new();
    let mut cols: BTreeMap<&str, f64> = BTreeMap::new();
    for ((s, r), n) in &cells {
        *rows.entry(s).or_default() += n;
        *cols.entry(r).or_default() += n;
    }
    let it: f64 = cells
        .iter()
        .map(|((s, r), n)| n / answered * (n * answered / (rows[s.as_str()] * cols[r.as_str()])).log2())
        .sum();

    let dir = std::env::temp_dir().join(format!("vestnav-study-figs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = Command::new(bin())
        .args(["study", "analyze", "--json", "--figures"])
        .arg(&dir)
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["answered"].as_u64().unwrap(), answered as u64);
    approx::assert_relative_eq!(
        json["percent_correct"].as_f64().unwrap(),
        100.0 * right / answered,
        max_relative = 1e-12
    );
    approx::assert_relative_eq!(json["it_bits"].as_f64().unwrap(), it, max_relative = 1e-9);
    assert!(json["it_note"].as_str().unwrap().contains("biased upward"));
    for f in ["confusion.png", "localization-map.png", "learning-curve.png", "rt-histogram.png"] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    std::fs::remove_dir_all(&dir).unwrap();

    let out = Command::new(bin()).args(["study", "analyze"]).arg(&csv).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("information transfer: ") && text.contains("localization map"), "{text}");
    // A file that is not a results CSV names itself and the line where reading it failed (a quote in the
    // middle of a field of the TOML's third line).
    let out = Command::new(bin()).args(["study", "analyze"]).arg(docs("localization.toml")).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("localization.toml: line 3: a quote inside an unquoted field"), "{err}");
}
