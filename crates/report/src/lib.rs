//! One home for vestnav's results and figures.
//!
//! Every thesis figure, the field-test and navigation sheets, and one serde schema per result live here, on
//! top of `vestnav-core` (the physics and statistics) and `vestnav-plot` (rasterising). The command line
//! (`vestnav sim ... --png/--json`, `vestnav fieldtest ...`, `vestnav nav simulate`) and the console's Save
//! buttons both call these functions, so for the same inputs they write the same PNG and the same JSON. The
//! console also draws the very [`vestnav_plot::Figure`] it exports, panel by panel, with egui.
//!
//! - [`tactor`]: Figs 28–34 and 39–41, [`tactor::TactorReport`], [`tactor::CalibrationReport`];
//! - [`sweep`]: Figs 35–38, [`sweep::SweepReport`];
//! - [`twopoint`]: Figs 60–63 and the RMSE sweep (JSON: core's `TwoPointResult`);
//! - [`wave`]: Figs 52, 57, 59, the vest field and the midpoint signal;
//! - [`fieldtest`]: the drift (Fig 65) and cone (Figs 67–70) sheets, [`fieldtest::DriftReport`],
//!   [`fieldtest::ConesReport`];
//! - [`accuracy`]: GPS accuracy against a reference and receivers side by side,
//!   [`accuracy::AccuracyReport`], [`accuracy::CompareReport`], [`accuracy::AgainstReference`];
//! - [`nav`]: the guidance simulation, [`nav::NavReport`];
//! - [`study`]: the study figures (confusion matrix, localization map, learning curve, response times,
//!   navigation), from core's `StudyAnalysis`;
//! - [`series`]: `linspace`, time windows and `sig` (numbers with sensible precision in labels); [`csv`]: a figure's data as CSV.
//!
//! ```
//! use vestnav_core::twopoint::TwoPointSetup;
//! use vestnav_report::{to_json, twopoint};
//!
//! let setup = TwoPointSetup::THESIS;
//! let fits = twopoint::fits(&setup, &[11.0])?;
//! let json = to_json(&fits[0])?;
//! assert!(json.contains("\"rmse\""));
//! let png = twopoint::fits_figure(&setup, &fits).render_png()?;
//! assert_eq!(&png[1..4], b"PNG");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod accuracy;
pub mod analysis;
pub mod csv;
pub mod fieldtest;
pub mod nav;
pub mod series;
pub mod study;
pub mod sweep;
pub mod tactor;
pub mod twopoint;
pub mod wave;

pub use series::sig;
pub use vestnav_plot::{Figure, PlotError, decimate_minmax, viridis};

/// The JSON text of a result: pretty-printed with a final newline, exactly what the command line prints
/// and the console writes to a file.
pub fn to_json<T: serde::Serialize + ?Sized>(value: &T) -> Result<String, serde_json::Error> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    Ok(text)
}
