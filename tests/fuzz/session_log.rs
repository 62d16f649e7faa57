//! Target 6: the session-log reader (`vestnav_device::session_log::read_log` / `read_log_from`) on logs
//! written by the real serialiser, then mutated: very long lines, invalid UTF-8, NUL bytes, absurd and
//! non-finite coordinates, old-format commands, cut-off lines. The reader must keep only valid records and
//! count every fix it skips; an independent pass over the same lines says how many that must be.

use std::io::Cursor;
use std::sync::atomic::{AtomicU64, Ordering};

use vestnav_core::vest::{Frame, Pattern, TactorMask};
use vestnav_device::session_log::{
    LogEntry, LogRecord, MAX_LINE_BYTES, ReadMode, check_fix, read_log, read_log_from,
};
use vestnav_device::wtcu::{CommandOrigin, VestCommand};

use crate::harness::{self, Counts, Known, Rng, add, bump};
use crate::mutate::{EXTREME_NUMBERS, mutate};

fn coordinate(rng: &mut Rng) -> f64 {
    match rng.below(6) {
        0 => *rng.pick(&[1e308, -1e15, 91.0, -180.000_001, 5e-324, -0.0, 90.0, 180.0, f64::MAX]),
        _ => (rng.next_u64() as f64 / u64::MAX as f64 - 0.5) * 180.0,
    }
}

fn opt(rng: &mut Rng) -> Option<f64> {
    match rng.below(4) {
        0 => None,
        1 => Some(*rng.pick(&[-1.0, -0.0, 1e308, -1e-300, 0.0])),
        _ => Some(rng.below(100) as f64 * 0.1),
    }
}

fn entry(rng: &mut Rng) -> LogEntry {
    match rng.below(7) {
        0..=2 => LogEntry::Fix {
            lat_deg: coordinate(rng),
            lon_deg: coordinate(rng),
            error_m: opt(rng),
            speed_m_s: opt(rng),
            course_deg: opt(rng),
            gps_utc: rng.chance(0.5).then(|| "2026-11-22T18:00:12Z".to_owned()),
        },
        3 => LogEntry::Command {
            origin: if rng.chance(0.5) { CommandOrigin::Manual } else { CommandOrigin::Guidance },
            command: match rng.below(5) {
                0 => VestCommand::Fire {
                    mask: TactorMask(rng.next_u64() as u16),
                    duration_ms: rng.next_u64() as u16,
                },
                1 => VestCommand::Play(Pattern {
                    name: "p".repeat(rng.size(300)),
                    frames: (0..rng.size(2000))
                        .map(|_| Frame { mask: TactorMask(rng.next_u64() as u16), duration_ms: 100 })
                        .collect(),
                    repeats: rng.byte(),
                }),
                2 => VestCommand::SetIntensity { mask: TactorMask::ALL, level: rng.byte() },
                3 => VestCommand::StopAll,
                _ => VestCommand::RequestStatus,
            },
            reason: "fuzz".into(),
        },
        4 => LogEntry::Mark {
            label: "cone".into(),
            lat_deg: rng.chance(0.7).then(|| coordinate(rng)),
            lon_deg: rng.chance(0.7).then(|| coordinate(rng)),
        },
        5 => LogEntry::TactorsOn { mask: TactorMask(rng.next_u64() as u16) },
        _ => LogEntry::Note { text: "n".repeat(rng.size(1000)) },
    }
}

fn generate(rng: &mut Rng) -> Vec<u8> {
    let mut data = Vec::new();
    for i in 0..rng.size(300) {
        let rec =
            LogRecord { t_s: i as f64 * 0.05, utc: "2026-11-22T18:00:12.030Z".into(), entry: entry(rng) };
        if let Ok(line) = serde_json::to_string(&rec) {
            data.extend_from_slice(line.as_bytes());
            data.push(b'\n');
        }
    }
    if rng.chance(0.2) {
        // An old-format command and hand-written absurd numbers serde_json would never write.
        data.extend_from_slice(
            b"{\"t_s\":1.0,\"utc\":\"x\",\"kind\":\"command\",\"origin\":\"Manual\",\"command\":{\"Fire\":{\"mask\":15,\"on_ms\":500}},\"reason\":\"old\"}\n",
        );
        let n = rng.pick(EXTREME_NUMBERS);
        data.extend_from_slice(
            format!("{{\"t_s\":{n},\"utc\":\"x\",\"kind\":\"fix\",\"lat_deg\":{n},\"lon_deg\":1e999,\"error_m\":null,\"speed_m_s\":null,\"course_deg\":null,\"gps_utc\":null}}\n").as_bytes(),
        );
    }
    if rng.chance(0.05) {
        let n = MAX_LINE_BYTES - 2 + rng.below(5);
        data.extend(std::iter::repeat_n(b' ', n));
        data.push(b'\n');
    }
    if rng.chance(0.7) {
        let rounds = 1 + rng.size(10);
        let max_len = if harness::long_run() { 4 << 20 } else { 1 << 20 };
        mutate(rng, &mut data, &[], rounds, max_len);
    }
    data
}

/// What the reader must do with each line, worked out independently.
fn expected(input: &[u8]) -> (usize, usize, usize, usize) {
    let (mut lines, mut long, mut kept, mut invalid_fixes) = (0, 0, 0, 0);
    let mut parts: Vec<&[u8]> = input.split(|&b| b == b'\n').collect();
    if parts.last().is_some_and(|p| p.is_empty()) {
        parts.pop();
    }
    for (i, p) in parts.into_iter().enumerate() {
        lines += 1;
        if p.len() > MAX_LINE_BYTES {
            long += 1;
            continue;
        }
        // A byte-order mark opening the file is not part of the first record.
        let trimmed = p.trim_ascii();
        let p = if i == 0 { trimmed.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(trimmed) } else { trimmed };
        if p.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        match serde_json::from_slice::<LogRecord>(p) {
            Ok(r) if r.t_s.is_finite() => match r.entry {
                LogEntry::Fix { lat_deg, lon_deg, error_m, speed_m_s, .. }
                    if check_fix(lat_deg, lon_deg, error_m, speed_m_s).is_err() =>
                {
                    invalid_fixes += 1;
                }
                _ => kept += 1,
            },
            _ => {}
        }
    }
    (lines, long, kept, invalid_fixes)
}

fn check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let (records, stats) =
        read_log_from(Cursor::new(input), ReadMode::Lenient).map_err(|e| format!("reader error: {e:?}"))?;
    // The strict reader refuses more but never keeps anything else: when it accepts, it keeps the same.
    if let Ok((strict, _)) = read_log_from(Cursor::new(input), ReadMode::Strict)
        && strict != records
    {
        return Err(format!("strict kept {} records, lenient {}", strict.len(), records.len()));
    }
    let (lines, long, kept, invalid) = expected(input);
    if (stats.lines, stats.long_lines, records.len(), stats.invalid_fix_count())
        != (lines, long, kept, invalid)
    {
        return Err(format!(
            "counts differ: reader (lines {}, long {}, kept {}, invalid fixes {}), expected ({lines}, {long}, {kept}, {invalid})",
            stats.lines,
            stats.long_lines,
            records.len(),
            stats.invalid_fix_count()
        ));
    }
    if stats.records != records.len() || stats.examples.len() > 10 {
        return Err(format!(
            "stats inconsistent: records {} vs {}, {} examples",
            stats.records,
            records.len(),
            stats.examples.len()
        ));
    }
    if records.len() + stats.skipped() > stats.lines {
        return Err(format!("more records and skips than lines: {stats:?}"));
    }
    for r in &records {
        if !r.t_s.is_finite() {
            return Err(format!("non-finite t_s kept: {}", r.t_s));
        }
        match &r.entry {
            LogEntry::Fix { lat_deg, lon_deg, error_m, speed_m_s, .. } => {
                if !(lat_deg.is_finite()
                    && lon_deg.is_finite()
                    && lat_deg.abs() <= 90.0
                    && lon_deg.abs() <= 180.0)
                {
                    return Err(format!("invalid fix kept: {lat_deg} {lon_deg}"));
                }
                if error_m.is_some_and(|e| !(e >= 0.0 && e.is_finite()))
                    || speed_m_s.is_some_and(|s| !(s >= 0.0 && s.is_finite()))
                {
                    return Err(format!("invalid error or speed kept: {error_m:?} {speed_m_s:?}"));
                }
            }
            LogEntry::Mark { lat_deg, lon_deg, .. } => {
                let valid = match (lat_deg, lon_deg) {
                    (Some(a), Some(o)) => check_fix(*a, *o, None, None).is_ok(),
                    (None, None) => true,
                    _ => false,
                };
                if !valid {
                    return Err(format!("mark kept with an invalid position: {lat_deg:?} {lon_deg:?}"));
                }
            }
            _ => {}
        }
    }
    // One case in eight through a real file, which must read the same.
    if input.len().is_multiple_of(8) {
        static N: AtomicU64 = AtomicU64::new(0);
        let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-session-logs");
        std::fs::create_dir_all(&dir).map_err(|e| format!("temp dir: {e}"))?;
        let path =
            dir.join(format!("log-{}-{}.jsonl", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
        std::fs::write(&path, input).map_err(|e| format!("temp file: {e}"))?;
        let from_file = read_log(&path);
        let _ = std::fs::remove_file(&path);
        let (file_records, file_stats) = from_file.map_err(|e| format!("read_log failed: {e}"))?;
        if file_records != records || file_stats != stats {
            return Err("read_log on a file differs from read_log_from on the same bytes".into());
        }
        bump(counts, "read through a file");
    }
    bump(counts, "inputs");
    add(counts, "records kept", records.len() as u64);
    add(counts, "invalid fixes skipped", stats.invalid_fix_count() as u64);
    add(counts, "bad lines", stats.bad_lines as u64);
    add(counts, "long lines", stats.long_lines as u64);
    add(counts, "mark positions removed", stats.invalid_mark_positions as u64);
    Ok(())
}

const KNOWN: &[Known] = &[];

#[test]
fn session_log_reader_survives_mutated_logs() {
    harness::fuzz("session-log", 1500, KNOWN, generate, check);
}
