//! A simulated wearer for demos and tests: reports the true tactor with probability `1 − p`, else one of its
//! 4-neighbours on the 4x4 back view (up, down, left, right; as many as the tactor has), chosen uniformly.
//! For choices that are not tactors (pattern names) a confusion is any other choice, uniformly. Response
//! times are drawn uniformly from [0.5, 1.5] × the mean. Seeded: the same seed gives the same answers.
//!
//! [`confusion_model`] is the same model in closed form, P(response | stimulus), from which a test computes
//! the expected percent correct and information transfer.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// The wearer's default mean response time [ms].
pub const DEFAULT_RT_MS: f64 = 800.0;

/// What a simulated wearer is: `sim:P[:SEED[:RT_MS]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WearerSpec {
    /// Probability of reporting a neighbour instead of the true tactor.
    pub p: f64,
    /// Seed of its draws.
    pub seed: u64,
    /// Mean response time [ms].
    pub rt_ms: f64,
}

/// The simulated wearer (see the module doc).
#[derive(Debug)]
pub struct SimulatedWearer {
    p: f64,
    rt_ms: f64,
    rng: StdRng,
}

/// The forms `--wearer` takes, for messages.
pub const WEARER_SPEC_FORMS: &str = "sim:P_NEIGHBOUR[:SEED[:RT_MS]] (e.g. sim:0.2, sim:0.2:7, sim:0.2:7:50)";

impl SimulatedWearer {
    /// A wearer confusing with probability `p` (0..=1), mean response time `rt_ms` (1..=60 000).
    pub fn new(p: f64, seed: u64, rt_ms: f64) -> Result<Self, String> {
        if !(p.is_finite() && (0.0..=1.0).contains(&p)) {
            return Err(format!("confusion probability {p}: between 0 and 1"));
        }
        if !(rt_ms.is_finite() && (1.0..=60_000.0).contains(&rt_ms)) {
            return Err(format!("mean response time {rt_ms} ms: between 1 and 60000"));
        }
        Ok(Self { p, rt_ms, rng: StdRng::seed_from_u64(seed) })
    }

    /// The wearer `spec` describes.
    pub fn from_spec(spec: WearerSpec) -> Result<Self, String> {
        Self::new(spec.p, spec.seed, spec.rt_ms)
    }

    /// Parses `sim:P[:SEED[:RT_MS]]` (checked as [`Self::new`] does).
    pub fn parse_spec(spec: &str) -> Result<WearerSpec, String> {
        Self::parse(spec)?;
        parse_fields(spec)
    }

    /// Parses `sim:P[:SEED[:RT_MS]]`.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let WearerSpec { p, seed, rt_ms } = parse_fields(spec)?;
        Self::new(p, seed, rt_ms)
            .map_err(|why| format!("--wearer {spec:?}: {why}; expected {WEARER_SPEC_FORMS}"))
    }

    /// The confusion probability.
    pub fn p(&self) -> f64 {
        self.p
    }

    /// What the wearer reports for a stimulus whose correct choice is `answer`, and after how long [s].
    pub fn respond(&mut self, answer: &str, choices: &[String]) -> (String, f64) {
        let rt_s = self.rt_ms * self.rng.random_range(0.5..=1.5) / 1000.0;
        let others = confusable(answer, choices);
        if others.is_empty() || self.rng.random::<f64>() >= self.p {
            return (answer.to_owned(), rt_s);
        }
        let k = self.rng.random_range(0..others.len());
        (others[k].clone(), rt_s)
    }
}

/// The fields of `sim:P[:SEED[:RT_MS]]`, unchecked.
fn parse_fields(spec: &str) -> Result<WearerSpec, String> {
    let bad = |why: String| format!("--wearer {spec:?}: {why}; expected {WEARER_SPEC_FORMS}");
    let Some(rest) = spec.strip_prefix("sim:") else { return Err(bad("not a simulated wearer".into())) };
    let mut parts = rest.split(':');
    let p = parts.next().unwrap_or("").parse::<f64>().map_err(|e| bad(format!("probability: {e}")))?;
    let seed = match parts.next() {
        Some(s) => s.parse::<u64>().map_err(|e| bad(format!("seed: {e}")))?,
        None => 1,
    };
    let rt = match parts.next() {
        Some(s) => s.parse::<f64>().map_err(|e| bad(format!("response time: {e}")))?,
        None => DEFAULT_RT_MS,
    };
    if parts.next().is_some() {
        return Err(bad("too many fields".into()));
    }
    Ok(WearerSpec { p, seed, rt_ms: rt })
}

/// The tactor index of a label.
fn tactor_of(label: &str) -> Option<usize> {
    vestnav_core::vest::parse_tactor_label(label)
}

/// The choices the wearer confuses `answer` with: its 4-neighbours among `choices` when it is a tactor,
/// else every other choice.
fn confusable(answer: &str, choices: &[String]) -> Vec<String> {
    match tactor_of(answer) {
        Some(t) => vestnav_core::vest::grid_neighbours(t)
            .into_iter()
            .map(vestnav_core::vest::tactor_label)
            .filter(|l| choices.contains(l))
            .collect(),
        None => choices.iter().filter(|c| *c != answer).cloned().collect(),
    }
}

/// The model in closed form: `m[i][j]` = P(response `choices[j]` | stimulus `choices[i]`).
pub fn confusion_model(p: f64, choices: &[String]) -> Vec<Vec<f64>> {
    choices
        .iter()
        .map(|a| {
            let others = confusable(a, choices);
            choices
                .iter()
                .map(|c| {
                    let confused = if others.contains(c) { p / others.len() as f64 } else { 0.0 };
                    if c == a { if others.is_empty() { 1.0 } else { 1.0 - p } } else { confused }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels() -> Vec<String> {
        (0..16).map(vestnav_core::vest::tactor_label).collect()
    }

    #[test]
    fn neighbours_on_the_grid() {
        let c = labels();
        // Corner T0 (row 0, col 0): T4 below, T1 right.
        assert_eq!(confusable("T0", &c), vec!["T4", "T1"]);
        // Inner T5 (row 1, col 1): T1 up, T9 down, T4 left, T6 right.
        assert_eq!(confusable("T5", &c), vec!["T1", "T9", "T4", "T6"]);
        // Edge T15 (row 3, col 3): T11 up, T14 left.
        assert_eq!(confusable("T15", &c), vec!["T11", "T14"]);
        let m = confusion_model(0.2, &c);
        for row in &m {
            approx::assert_relative_eq!(row.iter().sum::<f64>(), 1.0, epsilon = 1e-12);
        }
        approx::assert_relative_eq!(m[0][4], 0.1);
        approx::assert_relative_eq!(m[5][6], 0.05);
    }

    #[test]
    fn spec_and_frequencies() {
        assert!(SimulatedWearer::parse("sim:0.2:7:50").is_ok());
        assert!(SimulatedWearer::parse("sim:1.5").is_err());
        assert!(SimulatedWearer::parse("human").is_err());
        assert!(SimulatedWearer::parse("sim:0.2:x").is_err());
        let c = labels();
        let mut w = SimulatedWearer::parse("sim:0.3:42:100").unwrap();
        let n = 20_000;
        let mut wrong = 0;
        for i in 0..n {
            let answer = &c[i % 16];
            let (r, rt) = w.respond(answer, &c);
            assert!((0.05..=0.15).contains(&rt));
            if r != *answer {
                wrong += 1;
                assert!(confusable(answer, &c).contains(&r));
            }
        }
        // Binomial(20000, 0.3): sd 0.0032; 5 sd.
        let share = f64::from(wrong) / n as f64;
        assert!((share - 0.3).abs() < 0.016, "{share}");
    }
}
