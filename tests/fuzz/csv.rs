//! Target 5: measured-trace CSV (`vestnav_core::analysis::parse_csv`) on generated files (headers or not,
//! every separator, time columns in s and ms with tiny and huge steps, extreme values, ragged rows) and on
//! byte mutations of them, with each time-column mode and hostile sample rates.

use vestnav_core::analysis::{TimeColumn, parse_csv};

use crate::harness::{self, Choices, Counts, Known, Rng, bump};
use crate::mutate::{EXTREME_NUMBERS, mutate};

fn value(rng: &mut Rng) -> String {
    match rng.below(10) {
        0 => (*rng.pick(EXTREME_NUMBERS)).to_owned(),
        1 => format!("\"{}\"", rng.below(100)),
        _ => format!("{:.6}", (rng.next_u64() as f64 / u64::MAX as f64 - 0.5) * 4.0),
    }
}

fn generated(rng: &mut Rng) -> String {
    let sep = *rng.pick(&[",", ";", "\t", " ", "  "]);
    let cols = 1 + rng.size(12);
    let rows = rng.size(if harness::long_run() { 50_000 } else { 2000 });
    let time = rng.chance(0.6);
    let ms = rng.chance(0.3);
    let step: f64 =
        *rng.pick(&[1e-3, 1e-4, 0.5, 1.0, 5e-324, 1e-310, 1e-300, 1e300, 1e308, -1e-3, 0.0, 1.0 / 3.0]);
    let mut s = String::new();
    if rng.chance(0.2) {
        s.push_str("# comment\n");
    }
    if rng.chance(0.6) {
        let mut h: Vec<String> = (0..cols).map(|c| format!("trial{c}")).collect();
        if time {
            (*rng.pick(&["t", "time", "time_ms", "t_s", "ms", "\"time [s]\"", "seconds", "x"]))
                .clone_into(&mut h[0]);
        }
        if rng.chance(0.1) {
            h.push("extra".into());
        }
        s.push_str(&h.join(sep));
        s.push('\n');
    }
    for r in 0..rows {
        let mut fields: Vec<String> = (0..cols).map(|_| value(rng)).collect();
        if time {
            let t = r as f64 * step * if ms { 1000.0 } else { 1.0 };
            fields[0] = format!("{t:e}");
        }
        if rng.chance(0.002) {
            fields.pop();
        }
        s.push_str(&fields.join(sep));
        s.push_str(if rng.chance(0.1) { "\r\n" } else { "\n" });
    }
    if rng.chance(0.2) {
        s.push_str("\n\n");
    }
    s
}

fn generate(rng: &mut Rng) -> Vec<u8> {
    let mut data = generated(rng).into_bytes();
    if rng.chance(0.6) {
        let rounds = 1 + rng.size(8);
        mutate(rng, &mut data, &[], rounds, 4 << 20);
    }
    // The time-column mode and the sample rate ride in the first two bytes.
    let mut v = vec![rng.byte(), rng.byte()];
    v.extend(data);
    v
}

fn check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let mut c = Choices::new(input);
    let mode = [TimeColumn::Auto, TimeColumn::Present, TimeColumn::Absent][c.below(3)];
    let rate = [1000.0, 1.0, 0.0, -1.0, f64::NAN, f64::INFINITY, 5e-324, 1e308, 44_100.0][c.below(9)];
    let text = String::from_utf8_lossy(c.take(usize::MAX));
    bump(counts, "inputs");
    let lines = text.lines().count();
    match parse_csv(&text, mode, rate) {
        Ok(set) => {
            bump(counts, "parsed");
            if !(set.sample_rate_hz.is_finite() && set.sample_rate_hz > 0.0) {
                return Err(format!(
                    "sample rate not finite and positive: {} Hz (mode {mode:?}, given {rate})",
                    set.sample_rate_hz
                ));
            }
            if set.names.len() != set.traces.len() || set.traces.is_empty() {
                return Err(format!("{} names for {} traces", set.names.len(), set.traces.len()));
            }
            let n = set.traces[0].len();
            if n == 0 || n > lines || set.traces.iter().any(|t| t.len() != n) {
                return Err(format!(
                    "trace lengths {:?} for {lines} lines",
                    set.traces.iter().map(Vec::len).collect::<Vec<_>>()
                ));
            }
            if let Some(v) = set.traces.iter().flatten().find(|v| !v.is_finite()) {
                return Err(format!("non-finite sample {v}"));
            }
        }
        Err(e) => {
            bump(counts, "errors");
            let msg = e.to_string();
            if msg.is_empty() || msg.len() > 1024 {
                return Err(format!(
                    "unclear error ({} bytes): {}",
                    msg.len(),
                    msg.chars().take(200).collect::<String>()
                ));
            }
        }
    }
    Ok(())
}

const KNOWN: &[Known] = &[];

#[test]
fn csv_parser_survives_mutated_traces() {
    harness::fuzz("csv", 3000, KNOWN, generate, check);
}

/// The reproducer of the known issue above; passes once `parse_csv` refuses (or caps) such a step.
#[test]
fn subnormal_time_step_does_not_give_an_infinite_rate() {
    if let Ok(set) = parse_csv("0e4 5\n1e-323 1\n", TimeColumn::Present, 1.0) {
        assert!(set.sample_rate_hz.is_finite(), "sample rate {} Hz", set.sample_rate_hz);
    }
}
