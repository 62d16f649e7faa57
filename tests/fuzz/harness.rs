//! The fuzzing loop shared by every target: seeded cases, panic capture, time limits, a hang watchdog,
//! minimisation of failing inputs, known-issue bookkeeping and the per-target summary.
//!
//! Every input is a byte string. Targets whose input is not naturally bytes (the WTCU simulations) read
//! their choices from the bytes with [`Choices`], as `arbitrary::Unstructured` does, so one byte-level
//! minimiser serves them all.

use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::panic::{self, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::{Mutex, Once, OnceLock};
use std::time::{Duration, Instant};

/// splitmix64: small, fast, good enough to drive mutations, and the same on every platform.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next_u64() % n as u64) as usize }
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64) < p
    }

    pub fn byte(&mut self) -> u8 {
        self.next_u64() as u8
    }

    pub fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }

    /// A size in `0..=max`, log-uniform: small sizes are as likely as large ones.
    pub fn size(&mut self, max: usize) -> usize {
        let bits = usize::BITS - max.leading_zeros();
        let b = self.below(bits as usize + 1);
        self.below((1usize << b).min(max) + 1)
    }

    pub fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.byte()).collect()
    }
}

/// Reads choices from fuzz bytes (zeros once they run out), like `arbitrary::Unstructured`.
pub struct Choices<'a> {
    data: &'a [u8],
}

impl<'a> Choices<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Self { data }
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    pub fn u8(&mut self) -> u8 {
        match self.data.split_first() {
            Some((&b, rest)) => {
                self.data = rest;
                b
            }
            None => 0,
        }
    }

    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    /// Uniform-ish in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        let v = if n <= 256 { usize::from(self.u8()) } else { usize::from(self.u16()) };
        v % n
    }

    /// True with probability about `num / 256`.
    pub fn chance(&mut self, num: u8) -> bool {
        self.u8() < num
    }

    /// Up to `n` raw bytes.
    pub fn take(&mut self, n: usize) -> &'a [u8] {
        let n = n.min(self.data.len());
        let (head, rest) = self.data.split_at(n);
        self.data = rest;
        head
    }
}

/// Named counters a target reports (fixes emitted, errors by kind...).
pub type Counts = BTreeMap<String, u64>;

/// Adds one to a counter.
pub fn bump(counts: &mut Counts, key: &str) {
    add(counts, key, 1);
}

/// Adds `n` to a counter.
pub fn add(counts: &mut Counts, key: &str, n: u64) {
    *counts.entry(key.to_owned()).or_default() += n;
}

/// A failure the target knows about: its signature contains `needle`; `why` says where the bug is.
pub struct Known {
    pub needle: &'static str,
    pub why: &'static str,
}

/// Number of cases: `FUZZ_CASES` (a multiplier of each target's default when it ends in `x`, e.g. `100x`),
/// else the target's default.
pub fn cases(default: usize) -> usize {
    match std::env::var("FUZZ_CASES") {
        Ok(v) if v.ends_with('x') => {
            v.trim_end_matches('x').parse::<usize>().map_or(default, |k| default * k)
        }
        Ok(v) => v.parse().unwrap_or(default),
        Err(_) => default,
    }
}

/// True for the long run (`FUZZ_CASES` set): targets then also try whole logs and megabyte lines.
pub fn long_run() -> bool {
    std::env::var_os("FUZZ_CASES").is_some()
}

/// Optional wall-clock budget per target (`FUZZ_SECONDS`): the target stops early when it is spent.
fn time_budget() -> Option<Duration> {
    std::env::var("FUZZ_SECONDS").ok()?.parse::<f64>().ok().map(Duration::from_secs_f64)
}

fn base_seed() -> u64 {
    std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|s| u64::from_str_radix(s.trim_start_matches("0x"), 16).ok())
        .unwrap_or(0x5EED_F00D)
}

fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xCBF2_9CE4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01B3))
}

/// The seed of case `i` of target `name`.
fn case_seed(name: &str, i: usize) -> u64 {
    let mut r = Rng::new(base_seed() ^ fnv(name) ^ (i as u64).wrapping_mul(0xA24B_AED4_963E_E407));
    r.next_u64()
}

/// Time one input may take: generous, since the test suite runs in debug on a busy 2-core machine, but
/// linear in the input (a quadratic path on a megabyte input blows through it).
fn time_limit(len: usize) -> Duration {
    let factor: f64 = std::env::var("FUZZ_TIME_FACTOR").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0);
    Duration::from_secs_f64(factor * (3.0 + 20e-6 * len as f64))
}

thread_local! {
    static IN_CASE: Cell<bool> = const { Cell::new(false) };
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Installs a panic hook that records the message and location of a panic inside a case (silently: the
/// minimiser provokes thousands) and prints every other panic as usual.
fn install_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if IN_CASE.with(Cell::get) {
                let msg = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(ToString::to_string)
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "<non-string panic>".to_owned());
                let at = info.location().map_or_else(String::new, |l| format!("{}:{}", l.file(), l.line()));
                LAST_PANIC.with(|p| *p.borrow_mut() = Some(format!("panic at {at}: {msg}")));
            } else {
                default(info);
            }
        }));
    });
}

/// The cases running now, for the hang watchdog: target -> (seed, started).
fn running() -> &'static Mutex<BTreeMap<&'static str, (u64, Instant)>> {
    static RUNNING: OnceLock<Mutex<BTreeMap<&'static str, (u64, Instant)>>> = OnceLock::new();
    RUNNING.get_or_init(|| {
        std::thread::Builder::new()
            .name("fuzz-watchdog".into())
            .spawn(|| {
                let hang = std::env::var("FUZZ_HANG_S").ok().and_then(|v| v.parse().ok()).unwrap_or(120.0);
                loop {
                    std::thread::sleep(Duration::from_secs(1));
                    let map = running().lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                    for (name, (seed, start)) in map.iter() {
                        if start.elapsed().as_secs_f64() > hang {
                            eprintln!(
                                "FUZZ HANG: target {name} case seed {seed:#018x} has run for more than {hang} s; \
                                 reproduce with FUZZ_REPLAY={name}:{seed:x}"
                            );
                            std::process::exit(101);
                        }
                    }
                }
            })
            .expect("watchdog thread");
        Mutex::new(BTreeMap::new())
    })
}

/// A target's check: the code under test run on one input, the first broken invariant as the error.
type CheckFn<'a> = dyn Fn(&[u8], &mut Counts) -> Result<(), String> + 'a;

/// What one input did.
enum Verdict {
    Ok,
    Fail(String),
}

/// Runs `check` on `input` with panics captured and the time measured.
fn run_one(check: &CheckFn<'_>, input: &[u8], counts: &mut Counts) -> (Verdict, Duration) {
    IN_CASE.with(|c| c.set(true));
    let start = Instant::now();
    let result = panic::catch_unwind(AssertUnwindSafe(|| check(input, counts)));
    let took = start.elapsed();
    IN_CASE.with(|c| c.set(false));
    let verdict = match result {
        Ok(Ok(())) if took > time_limit(input.len()) => Verdict::Fail(format!(
            "slow: {} ms for {} bytes (limit {} ms)",
            took.as_millis(),
            input.len(),
            time_limit(input.len()).as_millis()
        )),
        Ok(Ok(())) => Verdict::Ok,
        Ok(Err(e)) => Verdict::Fail(format!("invariant: {e}")),
        Err(_) => Verdict::Fail(LAST_PANIC.with(|p| p.borrow_mut().take()).unwrap_or_else(|| "panic".into())),
    };
    (verdict, took)
}

/// The part of a failure message that identifies the bug: the panic location, or the invariant's name
/// (the text before its first `:` after the kind).
fn signature(msg: &str) -> String {
    if let Some(rest) = msg.strip_prefix("panic at ") {
        return format!("panic at {}", rest.split(": ").next().unwrap_or(rest));
    }
    if msg.starts_with("slow") {
        return "slow".into();
    }
    msg.splitn(3, ':').take(2).collect::<Vec<_>>().join(":")
}

/// Shrinks `input` while `check` still fails with the same signature (delta debugging over byte ranges).
fn minimise(check: &CheckFn<'_>, input: &[u8], sig: &str) -> (Vec<u8>, String) {
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut cur = input.to_vec();
    let mut last_msg = String::new();
    let still_fails = |cand: &[u8], last: &mut String| {
        let mut scratch = Counts::new();
        match run_one(check, cand, &mut scratch).0 {
            Verdict::Fail(m) if signature(&m) == sig => {
                *last = m;
                true
            }
            _ => false,
        }
    };
    if !still_fails(&cur, &mut last_msg) {
        return (cur, "(did not reproduce alone)".into());
    }
    let mut chunk = cur.len().div_ceil(2).max(1);
    while Instant::now() < deadline {
        let mut i = 0;
        let mut progress = false;
        while i < cur.len() && Instant::now() < deadline {
            let mut cand = cur.clone();
            cand.drain(i..(i + chunk).min(cur.len()));
            if still_fails(&cand, &mut last_msg) {
                cur = cand;
                progress = true;
            } else {
                i += chunk;
            }
        }
        if !progress {
            if chunk == 1 {
                break;
            }
            chunk = chunk.div_ceil(2);
        }
    }
    (cur, last_msg)
}

/// Printable form of an input: text with escapes, cut to `max` bytes.
pub fn escape(bytes: &[u8], max: usize) -> String {
    let mut s = String::new();
    for &b in bytes.iter().take(max) {
        match b {
            b'\n' => s.push_str("\\n"),
            b'\r' => s.push_str("\\r"),
            b'\\' => s.push_str("\\\\"),
            b'"' => s.push_str("\\\""),
            0x20..=0x7e => s.push(char::from(b)),
            _ => {
                let _ = write!(s, "\\x{b:02x}");
            }
        }
    }
    if bytes.len() > max {
        let _ = write!(s, "... ({} bytes)", bytes.len());
    }
    s
}

fn findings_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-findings")
}

/// One target: `generate` makes an input from a seeded generator, `check` runs the code under test on it and
/// returns the first broken invariant. Panics at the end listing every new failure (minimised, saved
/// under `target/tmp/fuzz-findings/`); failures matching `known` are reported but do not fail the test.
pub fn fuzz(
    name: &'static str,
    default_cases: usize,
    known: &[Known],
    generate: impl Fn(&mut Rng) -> Vec<u8>,
    check: impl Fn(&[u8], &mut Counts) -> Result<(), String>,
) {
    install_hook();
    let replay = std::env::var("FUZZ_REPLAY").ok();
    let seeds: Vec<u64> = match replay.as_deref().and_then(|r| r.split_once(':')) {
        Some((n, s)) if n == name => vec![u64::from_str_radix(s.trim_start_matches("0x"), 16).unwrap_or(0)],
        Some(_) => return,
        None => (0..cases(default_cases)).map(|i| case_seed(name, i)).collect(),
    };
    let budget = time_budget();
    let start = Instant::now();
    let mut counts = Counts::new();
    let (mut done, mut total_bytes, mut max_len) = (0usize, 0u64, 0usize);
    let mut slowest = (Duration::ZERO, 0usize, 0u64);
    let mut failures: BTreeMap<String, (u64, String, Vec<u8>)> = BTreeMap::new();
    let mut hits: BTreeMap<String, u64> = BTreeMap::new();
    for seed in seeds {
        if budget.is_some_and(|b| start.elapsed() > b) {
            break;
        }
        let input = generate(&mut Rng::new(seed));
        if replay.is_some() {
            // A replayed case is saved whatever it does, for a closer look.
            let _ = std::fs::create_dir_all(findings_dir());
            let _ = std::fs::write(findings_dir().join(format!("{name}-{seed:016x}-replay.bin")), &input);
        }
        running()
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .insert(name, (seed, Instant::now()));
        let (verdict, took) = run_one(&check, &input, &mut counts);
        running().lock().unwrap_or_else(std::sync::PoisonError::into_inner).remove(name);
        done += 1;
        total_bytes += input.len() as u64;
        max_len = max_len.max(input.len());
        if took > slowest.0 {
            slowest = (took, input.len(), seed);
        }
        if let Verdict::Fail(msg) = verdict {
            let sig = signature(&msg);
            *hits.entry(sig.clone()).or_default() += 1;
            failures.entry(sig).or_insert((seed, msg, input));
        }
    }
    let elapsed = start.elapsed();
    let mut report = format!(
        "FUZZ-SUMMARY {name}: {done} inputs, {:.1} MB (largest {} B) in {:.1} s ({:.0} inputs/s); slowest {} ms \
         ({} B, seed {:x}); peak RSS of the process {} MB; failures {}",
        total_bytes as f64 / 1e6,
        max_len,
        elapsed.as_secs_f64(),
        done as f64 / elapsed.as_secs_f64().max(1e-9),
        slowest.0.as_millis(),
        slowest.1,
        slowest.2,
        peak_rss_mb(),
        hits.values().sum::<u64>(),
    );
    for (k, v) in &counts {
        let _ = write!(report, "\n    {k}: {v}");
    }
    let mut new_failures = Vec::new();
    for (sig, (seed, msg, input)) in &failures {
        let (small, small_msg) = minimise(&check, input, sig);
        let dir = findings_dir();
        let _ = std::fs::create_dir_all(&dir);
        let path = dir.join(format!("{name}-{seed:016x}.bin"));
        let _ = std::fs::write(&path, &small);
        let known_issue = known.iter().find(|k| sig.contains(k.needle) || msg.contains(k.needle));
        let _ = write!(
            report,
            "\n  {} [{} hits] {sig}\n    first: seed {seed:#x} (FUZZ_REPLAY={name}:{seed:x}): {}\n    minimised \
             ({} B, {}): \"{}\"\n    -> {}",
            if known_issue.is_some() { "KNOWN" } else { "NEW" },
            hits[sig],
            cut(msg, 300),
            small.len(),
            cut(&small_msg, 300),
            escape(&small, 600),
            path.display()
        );
        if let Some(k) = known_issue {
            let _ = write!(report, "\n    known issue: {}", k.why);
        } else {
            new_failures.push(sig.clone());
        }
    }
    eprintln!("{report}");
    assert!(new_failures.is_empty(), "{name}: new failures {new_failures:?}; see the report above");
}

fn cut(s: &str, max: usize) -> String {
    if s.len() <= max {
        return s.to_owned();
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}...", &s[..end])
}

/// Peak resident set size of this process [MB] (`VmHWM`), 0 where /proc is missing.
pub fn peak_rss_mb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(0, |kb| kb / 1024)
}

/// Reads every file in `dir` whose name ends with `suffix`, sorted by name; an absent folder gives none.
pub fn read_dir_files(dir: &std::path::Path, suffix: &str) -> Vec<(String, Vec<u8>)> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<(String, Vec<u8>)> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.ends_with(suffix)))
        .filter_map(|p| Some((p.file_name()?.to_string_lossy().into_owned(), std::fs::read(&p).ok()?)))
        .collect();
    v.sort();
    v
}

/// The real gpsd logs: ours in `tests/data/gpsd-logs`, and the shared extra ones when present.
pub fn gpsd_log_dirs() -> Vec<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    vec![root.join("tests/data/gpsd-logs"), root.join("../shared/data/gpsd-logs-more")]
}
