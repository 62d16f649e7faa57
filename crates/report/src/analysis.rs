//! The JSON schema of `vestnav analyze tactor-data`: measured traces per file, the power law over all trials,
//! and the two-sample t-tests (thesis §3.1).

use serde::{Deserialize, Serialize};
use vestnav_core::analysis::{Stats, TTest, TraceSummary};
use vestnav_core::fit::PowerLawFit;

/// A result or why there is none: serialised as the value itself, or as `{"error": "..."}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Outcome<T> {
    /// The result.
    Ok(T),
    /// Why it failed.
    Err {
        /// The reason.
        error: String,
    },
}

impl<T> From<Result<T, String>> for Outcome<T> {
    fn from(r: Result<T, String>) -> Self {
        match r {
            Ok(v) => Outcome::Ok(v),
            Err(error) => Outcome::Err { error },
        }
    }
}

/// One trial (one column of a file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialReport {
    /// Column name.
    pub name: String,
    /// Its summary (keys `peak_frequency_hz`, `steady_amplitude`, ...) or the error.
    #[serde(flatten)]
    pub outcome: Outcome<TraceSummary>,
}

/// One file (one tactor or group of trials).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileReport {
    /// The file.
    pub path: String,
    /// Sample rate used [Hz].
    pub sample_rate_hz: f64,
    /// Whether the rate came from the file's time column.
    pub time_from_file: bool,
    /// Low-pass cutoff applied first [Hz].
    pub lowpass_hz: Option<f64>,
    /// Every trial.
    pub trials: Vec<TrialReport>,
    /// Peak frequency over the trials [Hz].
    pub peak_frequency_hz: Option<Stats>,
    /// Steady amplitude over the trials.
    pub steady_amplitude: Option<Stats>,
    /// Overshoot over the trials [%].
    pub overshoot_pct: Option<Stats>,
    /// 2 % settling time over the trials [s].
    pub settling_time_s: Option<Stats>,
}

/// Welch's and the pooled-variance t-test of one quantity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TTestPair {
    /// Welch's test.
    pub welch: Outcome<TTest>,
    /// Student's test with pooled variance.
    pub pooled: Outcome<TTest>,
}

/// Two-sample tests between exactly two files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupTests {
    /// Of the peak frequencies.
    pub peak_frequency_hz: TTestPair,
    /// Of the steady amplitudes.
    pub steady_amplitude: TTestPair,
}

/// JSON of `vestnav analyze tactor-data --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnalysisReport {
    /// One entry per file.
    pub files: Vec<FileReport>,
    /// `f = A n^B` (frequency against amplitude) over all trials.
    pub power_law: Outcome<PowerLawFit>,
    /// With exactly two files.
    pub t_test: Option<GroupTests>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcome_is_the_value_or_an_error_object() {
        let ok: Outcome<f64> = Ok(2.5).into();
        assert_eq!(serde_json::to_string(&ok).unwrap(), "2.5");
        let err: Outcome<f64> = Err("too short".to_string()).into();
        assert_eq!(serde_json::to_string(&err).unwrap(), r#"{"error":"too short"}"#);
        let back: Outcome<f64> = serde_json::from_str(r#"{"error":"too short"}"#).unwrap();
        assert_eq!(back, err);
    }
}
