//! Reading a protocol's TOML: raw tables that keep each value's span, then every value checked into a
//! [`Protocol`], each problem with its 1-based line.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::protocol::{
    Block, CUE_SETS, DEFAULT_INTENSITY, DEFAULT_ON_MS, MAX_FRAMES, MAX_PARTICIPANTS, MAX_PATTERN_FILE_BYTES,
    MAX_STIMULI, MAX_TRIALS, Order, Problem, Protocol, ProtocolError, RESPONSE_TIMEOUT_S, Stimulus,
    TIME_LIMIT_S, TIMING_MS, Task, TimingKeys, parse_mask_label,
};
use crate::guidance::{HeadingMode, StrategyKind};
use crate::vest::{Cue, Frame, Pattern, TACTOR_COUNT, TactorMask};

/// Parses and checks `text` (see [`Protocol::parse_in`]).
pub(super) fn parse(text: &str, source: &str, base: &Path) -> Result<Protocol, ProtocolError> {
    let raw: RawProtocol = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        ProtocolError::new(source, line, e.message().trim().to_owned())
    })?;
    let mut c = Checker { text, problems: Vec::new() };
    let protocol = build(&mut c, raw, source, base);
    if c.problems.is_empty() {
        Ok(protocol)
    } else {
        c.problems.sort_by_key(|p| p.line);
        Err(ProtocolError { source_name: source.to_owned(), problems: c.problems })
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProtocol {
    name: Spanned<String>,
    task: Spanned<String>,
    #[serde(default)]
    description: Option<String>,
    #[serde(default)]
    participants: Option<Spanned<Vec<Spanned<String>>>>,
    #[serde(default)]
    sessions: Option<Spanned<Vec<Spanned<String>>>>,
    #[serde(default)]
    order: Option<Spanned<String>>,
    #[serde(default)]
    seed: Option<Spanned<i64>>,
    #[serde(default)]
    iti_ms: Option<Spanned<i64>>,
    #[serde(default)]
    feedback_ms: Option<Spanned<i64>>,
    #[serde(default)]
    response_timeout_s: Option<Spanned<f64>>,
    #[serde(default, rename = "block")]
    blocks: Option<Spanned<Vec<Spanned<RawBlock>>>>,
    #[serde(default)]
    localization: Option<Spanned<RawLocalization>>,
    #[serde(default, rename = "pattern")]
    patterns: Option<Spanned<Vec<Spanned<RawPattern>>>>,
    #[serde(default)]
    navigation: Option<Spanned<RawNavigation>>,
    #[serde(default, rename = "condition")]
    conditions: Option<Spanned<Vec<Spanned<RawCondition>>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBlock {
    name: Spanned<String>,
    #[serde(default)]
    training: Option<Spanned<bool>>,
    #[serde(default)]
    feedback: Option<Spanned<bool>>,
    repetitions: Spanned<i64>,
    #[serde(default)]
    order: Option<Spanned<String>>,
    #[serde(default)]
    iti_ms: Option<Spanned<i64>>,
    #[serde(default)]
    feedback_ms: Option<Spanned<i64>>,
    #[serde(default)]
    response_timeout_s: Option<Spanned<f64>>,
    #[serde(default)]
    time_limit_s: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLocalization {
    #[serde(default)]
    stimuli: Option<Spanned<Vec<Spanned<String>>>>,
    #[serde(default)]
    on_ms: Option<Spanned<i64>>,
    #[serde(default)]
    intensity: Option<Spanned<i64>>,
    #[serde(default)]
    repeats: Option<Spanned<i64>>,
    #[serde(default)]
    isi_ms: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPattern {
    name: Spanned<String>,
    #[serde(default)]
    cue: Option<Spanned<String>>,
    #[serde(default)]
    file: Option<Spanned<String>>,
    #[serde(default)]
    frames: Option<Spanned<Vec<Spanned<RawFrame>>>>,
    #[serde(default)]
    on_ms: Option<Spanned<i64>>,
    #[serde(default)]
    repeats: Option<Spanned<i64>>,
    #[serde(default)]
    intensity: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFrame {
    tactors: String,
    ms: i64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNavigation {
    routes: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    time_limit_s: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCondition {
    name: Spanned<String>,
    strategy: Spanned<String>,
    heading: Spanned<String>,
    cue_set: Spanned<String>,
    cue_interval_s: Spanned<f64>,
}

/// The 1-based line of byte offset `at` in `text` (offsets past the end count as the last line).
pub(super) fn line_of(text: &str, at: usize) -> usize {
    let at = at.min(text.len());
    text[..at].matches('\n').count() + 1
}

/// Collects the problems of one parse, each turned into its line.
struct Checker<'a> {
    text: &'a str,
    problems: Vec<Problem>,
}

impl Checker<'_> {
    fn line<T>(&self, v: &Spanned<T>) -> usize {
        line_of(self.text, v.span().start)
    }

    fn fail<T>(&mut self, at: &Spanned<T>, message: impl Into<String>) {
        let line = self.line(at);
        self.problems.push(Problem { line: Some(line), message: message.into() });
    }

    /// An integer in `range`, or `default` when absent; out of range is a problem (and `default` returned).
    fn int(
        &mut self,
        v: Option<&Spanned<i64>>,
        what: &str,
        range: std::ops::RangeInclusive<i64>,
        default: i64,
    ) -> i64 {
        let Some(v) = v else { return default };
        let n = *v.get_ref();
        if range.contains(&n) {
            n
        } else {
            self.fail(v, format!("{what} = {n} is outside {}..={}", range.start(), range.end()));
            default
        }
    }

    /// A finite number in `range`, `None` when absent or out of range (a problem then).
    fn real(
        &mut self,
        v: Option<&Spanned<f64>>,
        what: &str,
        range: std::ops::RangeInclusive<f64>,
    ) -> Option<f64> {
        let v = v?;
        let x = *v.get_ref();
        if x.is_finite() && range.contains(&x) {
            Some(x)
        } else {
            self.fail(v, format!("{what} = {x} is outside {}..={}", range.start(), range.end()));
            None
        }
    }

    fn name(&mut self, v: &Spanned<String>, what: &str) -> String {
        let s = v.get_ref().trim();
        if s.is_empty() {
            self.fail(v, format!("{what} is empty"));
        } else if s.len() > 100 || s.chars().any(char::is_control) || s.contains(',') {
            self.fail(v, format!("{what} {s:?}: at most 100 characters, no commas or control characters"));
        }
        s.to_owned()
    }
}

fn clamp_u16(n: i64) -> u16 {
    u16::try_from(n.clamp(0, i64::from(u16::MAX))).unwrap_or(u16::MAX)
}

fn clamp_u8(n: i64) -> u8 {
    u8::try_from(n.clamp(0, i64::from(u8::MAX))).unwrap_or(u8::MAX)
}

/// Reads at most `limit` bytes of a regular file as UTF-8; errors in words.
pub(super) fn read_bounded(path: &Path, limit: u64) -> Result<String, String> {
    use std::io::Read as _;
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read: {e}"))?;
    if !meta.is_file() {
        return Err("not a regular file".to_owned());
    }
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!("larger than {limit} bytes"));
    }
    String::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_owned())
}

fn build(c: &mut Checker<'_>, raw: RawProtocol, source: &str, base: &Path) -> Protocol {
    let name = c.name(&raw.name, "name");
    let task = Task::from_name(raw.task.get_ref()).unwrap_or_else(|| {
        c.fail(
            &raw.task,
            format!("task {:?}: one of localization, pattern-id, navigation", raw.task.get_ref()),
        );
        Task::Localization
    });
    let order = raw.order.as_ref().map_or(Order::Random, |o| parse_order(c, o));
    let seed = raw.seed.as_ref().map_or(0, |s| {
        u64::try_from(*s.get_ref()).unwrap_or_else(|_| {
            c.fail(s, "seed must not be negative");
            0
        })
    });
    let participants = ids(c, raw.participants.as_ref(), "participant", MAX_PARTICIPANTS);
    let sessions = ids(c, raw.sessions.as_ref(), "session", MAX_PARTICIPANTS);
    let blocks = blocks(c, raw.blocks.as_ref(), order, text_end(c), task_of(&raw.task));
    let (stimuli, stimulus_lines) = match task {
        Task::Localization => {
            misplaced(c, raw.patterns.as_ref(), "[[pattern]]", task);
            misplaced(c, raw.navigation.as_ref(), "[navigation]", task);
            misplaced(c, raw.conditions.as_ref(), "[[condition]]", task);
            localization(c, raw.localization.as_ref())
        }
        Task::PatternId => {
            misplaced(c, raw.localization.as_ref(), "[localization]", task);
            misplaced(c, raw.navigation.as_ref(), "[navigation]", task);
            misplaced(c, raw.conditions.as_ref(), "[[condition]]", task);
            patterns(c, raw.patterns.as_ref(), base, &raw.task)
        }
        Task::Navigation => {
            misplaced(c, raw.localization.as_ref(), "[localization]", task);
            misplaced(c, raw.patterns.as_ref(), "[[pattern]]", task);
            navigation(c, raw.navigation.as_ref(), raw.conditions.as_ref(), base, &raw.task)
        }
    };
    let uses_latin = blocks.iter().any(|b| b.order == Order::LatinSquare);
    if uses_latin && participants.is_empty() {
        let at = raw.order.as_ref().map_or_else(|| c.line(&raw.name), |o| c.line(o));
        c.problems.push(Problem {
            line: Some(at),
            message:
                "a latin-square order needs the participants list (a participant's row is their place in it)"
                    .to_owned(),
        });
    }
    let timing = timing_keys(c, &raw);
    let trials: usize = blocks.iter().map(|b| b.repetitions as usize * stimuli.len()).sum();
    if trials > MAX_TRIALS {
        let line = blocks.first().map(|b| b.line);
        c.problems.push(Problem {
            line,
            message: format!("{trials} trials per participant, more than {MAX_TRIALS}"),
        });
    }
    Protocol {
        name,
        description: raw.description.unwrap_or_default(),
        source: source.to_owned(),
        task,
        participants,
        sessions,
        blocks,
        order,
        seed,
        stimuli,
        stimulus_lines,
        timing,
    }
}

/// The protocol's timing keys, each checked against its range.
fn timing_keys(c: &mut Checker<'_>, raw: &RawProtocol) -> TimingKeys {
    let time_limit = raw.navigation.as_ref().and_then(|n| n.get_ref().time_limit_s.as_ref());
    checked_timing(
        c,
        raw.iti_ms.as_ref(),
        raw.feedback_ms.as_ref(),
        raw.response_timeout_s.as_ref(),
        time_limit,
        "",
    )
}

/// Timing keys (a protocol's or a block's), each checked against its range; problems name the key's line,
/// and `within` (`block "NAME": ` or empty) says where it is.
fn checked_timing(
    c: &mut Checker<'_>,
    iti_ms: Option<&Spanned<i64>>,
    feedback_ms: Option<&Spanned<i64>>,
    response_timeout_s: Option<&Spanned<f64>>,
    time_limit_s: Option<&Spanned<f64>>,
    within: &str,
) -> TimingKeys {
    let ms = |c: &mut Checker<'_>, v: Option<&Spanned<i64>>, what: &str| {
        v.is_some()
            .then(|| c.int(v, &format!("{within}{what}"), TIMING_MS, -1))
            .and_then(|n| u32::try_from(n).ok())
    };
    TimingKeys {
        iti_ms: ms(c, iti_ms, "iti_ms"),
        feedback_ms: ms(c, feedback_ms, "feedback_ms"),
        response_timeout_s: c.real(
            response_timeout_s,
            &format!("{within}response_timeout_s"),
            RESPONSE_TIMEOUT_S,
        ),
        time_limit_s: c.real(time_limit_s, &format!("{within}time_limit_s"), TIME_LIMIT_S),
    }
}

/// The task `task` names, if it names one (its own problem is reported where it is read).
fn task_of(task: &Spanned<String>) -> Option<Task> {
    Task::from_name(task.get_ref())
}

fn text_end(c: &Checker<'_>) -> usize {
    line_of(c.text, c.text.len())
}

fn misplaced<T>(c: &mut Checker<'_>, v: Option<&Spanned<T>>, what: &str, task: Task) {
    if let Some(v) = v {
        c.fail(v, format!("{what} does not belong to a {} protocol", task.name()));
    }
}

fn parse_order(c: &mut Checker<'_>, o: &Spanned<String>) -> Order {
    Order::from_name(o.get_ref()).unwrap_or_else(|| {
        c.fail(o, format!("order {:?}: one of random, blocked, latin-square", o.get_ref()));
        Order::Random
    })
}

fn ids(
    c: &mut Checker<'_>,
    list: Option<&Spanned<Vec<Spanned<String>>>>,
    what: &str,
    max: usize,
) -> Vec<String> {
    let Some(list) = list else { return Vec::new() };
    if list.get_ref().len() > max {
        c.fail(list, format!("more than {max} {what}s"));
        return Vec::new();
    }
    let mut out: Vec<String> = Vec::new();
    for id in list.get_ref() {
        let s = c.name(id, &format!("{what} id"));
        if out.contains(&s) {
            c.fail(id, format!("{what} {s:?} is listed twice"));
        }
        out.push(s);
    }
    out
}

fn blocks(
    c: &mut Checker<'_>,
    raw: Option<&Spanned<Vec<Spanned<RawBlock>>>>,
    order: Order,
    end_line: usize,
    task: Option<Task>,
) -> Vec<Block> {
    let Some(raw) = raw.filter(|r| !r.get_ref().is_empty()) else {
        c.problems.push(Problem {
            line: Some(end_line),
            message: "no [[block]]: a protocol needs at least one block".to_owned(),
        });
        return Vec::new();
    };
    let mut out: Vec<Block> = Vec::new();
    for b in raw.get_ref() {
        let r = b.get_ref();
        let name = c.name(&r.name, "block name");
        if out.iter().any(|o| o.name == name) {
            c.fail(&r.name, format!("block {name:?} is defined twice"));
        }
        let training = r.training.as_ref().is_some_and(|t| *t.get_ref());
        if training && let Some(test) = out.iter().find(|o| !o.training) {
            c.fail(
                &r.name,
                format!(
                    "training block {name:?} comes after test block {:?}: training comes first",
                    test.name
                ),
            );
        }
        let feedback = r.feedback.as_ref().map_or(training, |f| *f.get_ref());
        let repetitions = c.int(Some(&r.repetitions), "repetitions", 1..=1000, 1);
        let block_order = r.order.as_ref().map_or(order, |o| parse_order(c, o));
        if let Some(v) = &r.time_limit_s
            && task.is_some_and(|t| t != Task::Navigation)
        {
            c.fail(
                v,
                format!("block {name:?}: time_limit_s applies to the blocks of a navigation protocol only"),
            );
        }
        let time_limit = r.time_limit_s.as_ref().filter(|_| task.is_none_or(|t| t == Task::Navigation));
        let timing = checked_timing(
            c,
            r.iti_ms.as_ref(),
            r.feedback_ms.as_ref(),
            r.response_timeout_s.as_ref(),
            time_limit,
            &format!("block {name:?}: "),
        );
        out.push(Block {
            name,
            training,
            feedback,
            repetitions: u32::try_from(repetitions).unwrap_or(1),
            order: block_order,
            line: c.line(&r.name),
            timing,
        });
    }
    out
}

fn localization(c: &mut Checker<'_>, raw: Option<&Spanned<RawLocalization>>) -> (Vec<Stimulus>, Vec<usize>) {
    let Some(raw) = raw else {
        c.problems.push(Problem {
            line: Some(text_end(c)),
            message: "a localization protocol needs a [localization] table".to_owned(),
        });
        return (Vec::new(), Vec::new());
    };
    let table_line = c.line(raw);
    let r = raw.get_ref();
    let on_ms = clamp_u16(c.int(r.on_ms.as_ref(), "on_ms", 1..=10_000, i64::from(DEFAULT_ON_MS)));
    let intensity = clamp_u8(c.int(r.intensity.as_ref(), "intensity", 1..=255, i64::from(DEFAULT_INTENSITY)));
    let repeats = clamp_u8(c.int(r.repeats.as_ref(), "repeats", 1..=20, 1));
    let isi_ms = clamp_u16(c.int(r.isi_ms.as_ref(), "isi_ms", 0..=10_000, 0));
    if repeats > 1 && isi_ms == 0 {
        let at = r.repeats.as_ref().map_or(table_line, |v| c.line(v));
        c.problems.push(Problem {
            line: Some(at),
            message: "repeats > 1 needs isi_ms > 0 (without a pause the presentations run together)"
                .to_owned(),
        });
    }
    let make = |tactors| Stimulus::Tactors { tactors, on_ms, intensity, repeats, isi_ms };
    let Some(list) = &r.stimuli else {
        let all = (0..TACTOR_COUNT).filter_map(TactorMask::single).map(make).collect::<Vec<_>>();
        let lines = vec![table_line; all.len()];
        return (all, lines);
    };
    if list.get_ref().is_empty() || list.get_ref().len() > MAX_STIMULI {
        c.fail(list, format!("stimuli: 1 to {MAX_STIMULI} tactors or sets (leave it out for all 16)"));
    }
    let (mut stimuli, mut lines) = (Vec::new(), Vec::new());
    for s in list.get_ref().iter().take(MAX_STIMULI) {
        match parse_mask_label(s.get_ref()).filter(|m| !m.is_empty()) {
            Some(mask) => {
                let st = make(mask);
                if stimuli.contains(&st) {
                    c.fail(s, format!("stimulus {:?} is listed twice", s.get_ref()));
                }
                stimuli.push(st);
                lines.push(c.line(s));
            }
            None => {
                c.fail(s, format!("stimulus {:?}: a tactor T0..T15 or a set such as \"T0+T3\"", s.get_ref()));
            }
        }
    }
    (stimuli, lines)
}

/// The named cues a pattern may use, by [`Cue::name`].
fn cue_by_name(name: &str) -> Option<Cue> {
    Cue::ALL.into_iter().chain(Cue::TURN_IN_PLACE).find(|c| c.name() == name)
}

fn patterns(
    c: &mut Checker<'_>,
    raw: Option<&Spanned<Vec<Spanned<RawPattern>>>>,
    base: &Path,
    task_at: &Spanned<String>,
) -> (Vec<Stimulus>, Vec<usize>) {
    let Some(raw) = raw.filter(|r| !r.get_ref().is_empty()) else {
        c.fail(task_at, "a pattern-id protocol needs [[pattern]] tables (at least two)");
        return (Vec::new(), Vec::new());
    };
    if raw.get_ref().len() < 2 || raw.get_ref().len() > MAX_STIMULI {
        c.fail(raw, format!("2 to {MAX_STIMULI} patterns (identification needs a choice)"));
    }
    let (mut stimuli, mut lines) = (Vec::new(), Vec::new());
    for p in raw.get_ref().iter().take(MAX_STIMULI) {
        let r = p.get_ref();
        let name = c.name(&r.name, "pattern name");
        if stimuli.iter().any(|s: &Stimulus| s.label() == name) {
            c.fail(&r.name, format!("pattern {name:?} is defined twice"));
        }
        let sources =
            usize::from(r.cue.is_some()) + usize::from(r.file.is_some()) + usize::from(r.frames.is_some());
        if sources != 1 {
            c.fail(&r.name, format!("pattern {name:?}: give exactly one of cue, file, frames"));
            continue;
        }
        if let Some(v) = &r.on_ms
            && r.cue.is_none()
        {
            c.fail(v, "on_ms applies to a cue only (frames and files carry their own times)");
        }
        let on_ms = clamp_u16(c.int(r.on_ms.as_ref(), "on_ms", 1..=10_000, i64::from(DEFAULT_ON_MS)));
        let intensity =
            clamp_u8(c.int(r.intensity.as_ref(), "intensity", 1..=255, i64::from(DEFAULT_INTENSITY)));
        let base_pattern: Option<Pattern> = if let Some(cue) = &r.cue {
            cue_by_name(cue.get_ref()).map(|k| k.pattern(on_ms)).or_else(|| {
                let names: Vec<&str> = Cue::ALL.iter().chain(&Cue::TURN_IN_PLACE).map(|k| k.name()).collect();
                c.fail(cue, format!("cue {:?}: one of {}", cue.get_ref(), names.join(", ")));
                None
            })
        } else if let Some(file) = &r.file {
            let path = base.join(file.get_ref());
            match read_bounded(&path, MAX_PATTERN_FILE_BYTES).and_then(|t| {
                serde_json::from_str::<Pattern>(&t).map_err(|e| format!("not a pattern file: {e}"))
            }) {
                Ok(p) => Some(p),
                Err(why) => {
                    c.fail(file, format!("pattern file {}: {why}", path.display()));
                    None
                }
            }
        } else {
            r.frames.as_ref().and_then(|f| inline_frames(c, f))
        };
        let Some(pat) = base_pattern else { continue };
        let repeats = clamp_u8(c.int(r.repeats.as_ref(), "repeats", 1..=20, i64::from(pat.repeats.max(1))));
        if pat.frames.is_empty()
            || pat.frames.len() > MAX_FRAMES
            || pat.frames.iter().all(|f| f.mask.is_empty())
        {
            c.fail(
                &r.name,
                format!("pattern {name:?}: 1 to {MAX_FRAMES} frames, at least one with a tactor on"),
            );
            continue;
        }
        stimuli.push(Stimulus::Pattern {
            name,
            frames: pat.frames.iter().map(|f| (f.mask.0, f.duration_ms)).collect(),
            repeats,
            intensity,
        });
        lines.push(c.line(&r.name));
    }
    (stimuli, lines)
}

fn inline_frames(c: &mut Checker<'_>, frames: &Spanned<Vec<Spanned<RawFrame>>>) -> Option<Pattern> {
    let mut out = Vec::new();
    let mut ok = true;
    for f in frames.get_ref().iter().take(MAX_FRAMES + 1) {
        let r = f.get_ref();
        let Some(mask) = parse_mask_label(&r.tactors) else {
            c.fail(f, format!("frame tactors {:?}: tactors such as \"T0+T3\" (\"\" for a pause)", r.tactors));
            ok = false;
            continue;
        };
        if !(1..=10_000).contains(&r.ms) {
            c.fail(f, format!("frame ms = {} is outside 1..=10000", r.ms));
            ok = false;
            continue;
        }
        out.push(Frame { mask, duration_ms: clamp_u16(r.ms) });
    }
    ok.then(|| Pattern { name: String::new(), frames: out, repeats: 1 })
}

fn navigation(
    c: &mut Checker<'_>,
    nav: Option<&Spanned<RawNavigation>>,
    conditions: Option<&Spanned<Vec<Spanned<RawCondition>>>>,
    base: &Path,
    task_at: &Spanned<String>,
) -> (Vec<Stimulus>, Vec<usize>) {
    let Some(nav) = nav else {
        c.fail(task_at, "a navigation protocol needs a [navigation] table with routes");
        return (Vec::new(), Vec::new());
    };
    let Some(conditions) = conditions.filter(|r| !r.get_ref().is_empty()) else {
        c.fail(task_at, "a navigation protocol needs [[condition]] tables");
        return (Vec::new(), Vec::new());
    };
    let routes = nav.get_ref().routes.get_ref();
    if routes.is_empty() {
        c.fail(&nav.get_ref().routes, "routes is empty");
    }
    let mut route_paths: Vec<(PathBuf, usize)> = Vec::new();
    for r in routes.iter().take(MAX_STIMULI) {
        let path = base.join(r.get_ref());
        if !path.is_file() {
            c.fail(r, format!("route {} is not a file", path.display()));
        }
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
        if route_paths.iter().any(|(p, _)| p.file_stem().map(|s| s.to_string_lossy().into_owned()) == stem) {
            c.fail(
                r,
                format!(
                    "route {:?}: another route has the same file name (labels are ROUTE/CONDITION)",
                    r.get_ref()
                ),
            );
        }
        route_paths.push((path, c.line(r)));
    }
    let mut conds: Vec<(Stimulus, usize)> = Vec::new();
    for k in conditions.get_ref().iter().take(MAX_STIMULI) {
        let r = k.get_ref();
        let name = c.name(&r.name, "condition name");
        if conds
            .iter()
            .any(|(s, _)| matches!(s, Stimulus::Navigation { condition, .. } if *condition == name))
        {
            c.fail(&r.name, format!("condition {name:?} is defined twice"));
        }
        if name.contains('/') {
            c.fail(&r.name, "condition name must not contain '/'");
        }
        if StrategyKind::from_name(r.strategy.get_ref()).is_none() {
            let all: Vec<&str> = StrategyKind::ALL.iter().map(|s| s.name()).collect();
            c.fail(&r.strategy, format!("strategy {:?}: one of {}", r.strategy.get_ref(), all.join(", ")));
        }
        if HeadingMode::from_name(r.heading.get_ref()).is_none() {
            let all: Vec<&str> = HeadingMode::ALL.iter().map(|s| s.name()).collect();
            c.fail(&r.heading, format!("heading {:?}: one of {}", r.heading.get_ref(), all.join(", ")));
        }
        if !CUE_SETS.contains(&r.cue_set.get_ref().as_str()) {
            c.fail(&r.cue_set, format!("cue_set {:?}: one of {}", r.cue_set.get_ref(), CUE_SETS.join(", ")));
        }
        let interval = *r.cue_interval_s.get_ref();
        if !(interval.is_finite() && (0.5..=120.0).contains(&interval)) {
            c.fail(&r.cue_interval_s, format!("cue_interval_s = {interval} is outside 0.5..=120"));
        }
        conds.push((
            Stimulus::Navigation {
                route: PathBuf::new(),
                condition: name,
                strategy: r.strategy.get_ref().clone(),
                heading: r.heading.get_ref().clone(),
                cue_set: r.cue_set.get_ref().clone(),
                cue_interval_s: interval,
            },
            c.line(&r.name),
        ));
    }
    if route_paths.len() * conds.len() > MAX_STIMULI {
        c.fail(conditions, format!("routes x conditions is more than {MAX_STIMULI}"));
    }
    let (mut stimuli, mut lines) = (Vec::new(), Vec::new());
    for (path, line) in &route_paths {
        for (cond, _) in &conds {
            let mut s = cond.clone();
            if let Stimulus::Navigation { route, .. } = &mut s {
                route.clone_from(path);
            }
            stimuli.push(s);
            lines.push(*line);
        }
    }
    (stimuli, lines)
}
