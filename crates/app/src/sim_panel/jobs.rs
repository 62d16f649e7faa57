//! Background work of the simulation views: [`Recompute`] runs a computation on a worker thread when its
//! inputs change; [`crate::export::Exporter`] writes a view's PNG, CSV or JSON on another, so the frame never
//! waits.

use std::path::Path;
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, TryRecvError};

use crate::export::{ExportFormat, Exporter};
use std::time::{Duration, Instant};

use vestnav_report::Figure;

type ComputeFn<I, O> = fn(&I) -> Result<O, String>;
/// A run in flight: its inputs, start time and the channel its result arrives on.
type Pending<I, O> = (I, Instant, Receiver<Result<O, String>>);

/// A view's output derived from cached results, with the key it was derived from.
pub(crate) struct Derived<K> {
    /// What it was derived from (result generations, display settings).
    pub key: K,
    /// The output.
    pub out: ViewOutput,
}

/// A cached computation that runs on a worker thread when its inputs change.
///
/// Each frame the view calls [`Recompute::update`] with the inputs it wants shown. If no run is in flight and
/// the inputs differ from the last ones requested, one run starts on a named thread; its result replaces the
/// shown one when it arrives (the thread wakes the UI with `request_repaint`). Inputs changed during a run are
/// picked up by the next run, so dragging a slider never queues more than one run.
pub(crate) struct Recompute<I, O> {
    compute: ComputeFn<I, O>,
    shown: Option<(I, Arc<O>)>,
    running: Option<Pending<I, O>>,
    requested: Option<I>,
    error: Option<String>,
    last_duration: Option<Duration>,
    generation: u64,
}

impl<I, O> Recompute<I, O>
where
    I: Clone + PartialEq + Send + 'static,
    O: Send + Sync + 'static,
{
    /// A computation with nothing computed yet.
    pub fn new(compute: ComputeFn<I, O>) -> Self {
        Self {
            compute,
            shown: None,
            running: None,
            requested: None,
            error: None,
            last_duration: None,
            generation: 0,
        }
    }

    /// Collects a finished run and starts a new one if `wanted` has not been requested yet.
    pub fn update(&mut self, ctx: &egui::Context, wanted: &I) {
        self.poll();
        if self.running.is_none() && self.requested.as_ref() != Some(wanted) {
            self.start(ctx, wanted.clone());
        }
    }

    fn poll(&mut self) {
        let Some((inputs, started, rx)) = &self.running else { return };
        let outcome = match rx.try_recv() {
            Ok(result) => result,
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => {
                Err("the computation thread stopped without a result".to_string())
            }
        };
        self.last_duration = Some(started.elapsed());
        match outcome {
            Ok(output) => {
                self.shown = Some((inputs.clone(), Arc::new(output)));
                self.generation += 1;
                self.error = None;
            }
            Err(e) => self.error = Some(e),
        }
        self.running = None;
    }

    fn start(&mut self, ctx: &egui::Context, inputs: I) {
        let (tx, rx) = mpsc::sync_channel(1);
        let compute = self.compute;
        let job_inputs = inputs.clone();
        let ctx = ctx.clone();
        let spawned = std::thread::Builder::new().name("vestnav-sim".to_string()).spawn(move || {
            let result = compute(&job_inputs);
            // The panel may be gone; then nobody needs the result.
            let _ = tx.send(result);
            ctx.request_repaint();
        });
        self.requested = Some(inputs.clone());
        match spawned {
            Ok(_) => self.running = Some((inputs, Instant::now(), rx)),
            Err(e) => self.error = Some(format!("cannot start a computation thread: {e}")),
        }
    }

    /// The last successful result and the inputs it was computed for.
    pub fn shown(&self) -> Option<(&I, &Arc<O>)> {
        self.shown.as_ref().map(|(i, o)| (i, o))
    }

    /// Counts the results shown so far: derived data cached for one generation is stale for the next.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Whether a run is in flight.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// The error of the last run, if it failed.
    #[cfg(test)]
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// Wall time of the last finished run.
    #[cfg(test)]
    pub fn last_duration(&self) -> Option<Duration> {
        self.last_duration
    }

    /// Status line: computing / error / last run time.
    pub fn status_ui(&self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if self.is_running() {
                ui.spinner();
                ui.label("computing...");
            } else if let Some(d) = self.last_duration {
                ui.weak(format!("computed in {:.1} ms", d.as_secs_f64() * 1e3));
            }
            if let Some(e) = &self.error {
                ui.colored_label(ui.visuals().error_fg_color, format!("error: {e}"));
            }
        });
    }

    /// Blocks until the running computation (if any) has finished; for tests.
    #[cfg(test)]
    pub fn wait(&mut self) {
        while self.running.is_some() {
            std::thread::sleep(Duration::from_millis(2));
            self.poll();
        }
    }
}

/// What a view shows and exports: the figure (drawn on screen panel by panel and written as PNG), the summary
/// lines (shown, and the CSV header), and the result's JSON, all from `vestnav_report`.
pub(crate) struct ViewOutput {
    /// The figure.
    pub figure: Arc<Figure>,
    /// Summary lines.
    pub header: Vec<String>,
    /// The JSON of the result, or why it could not be encoded.
    pub json: Result<String, String>,
}

impl ViewOutput {
    /// The bytes an export in `format` writes: exactly what `vestnav ... --png/--json` writes for the same
    /// inputs (the CSV is the figure's data).
    pub fn bytes(&self, format: ExportFormat) -> Result<Vec<u8>, String> {
        match format {
            ExportFormat::Png => {
                self.figure.render_png().map_err(|e| format!("cannot render the figure: {e}"))
            }
            ExportFormat::Csv => Ok(vestnav_report::csv::figure_csv(&self.header, &self.figure).into_bytes()),
            ExportFormat::Json => self.json.clone().map(String::into_bytes),
        }
    }
}

/// Draws the export row of a view (relative paths taken in `base`) and starts the export the operator
/// asked for.
pub(crate) fn export_row(ui: &mut egui::Ui, exporter: &mut Exporter, out: &ViewOutput, base: &Path) {
    if let Some(request) = exporter.ui(ui, &[ExportFormat::Png, ExportFormat::Json, ExportFormat::Csv], base)
    {
        let ctx = ui.ctx().clone();
        let view = ViewOutput {
            figure: Arc::clone(&out.figure),
            header: out.header.clone(),
            json: out.json.clone(),
        };
        let format = request.format;
        exporter.start(&ctx, request, move || view.bytes(format));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recompute_runs_once_per_new_input() {
        #[allow(clippy::trivially_copy_pass_by_ref, reason = "the signature Recompute expects")]
        fn square(x: &i64) -> Result<i64, String> {
            if *x < 0 { Err("negative".to_string()) } else { Ok(x * x) }
        }
        let ctx = egui::Context::default();
        let mut job = Recompute::new(square);
        job.update(&ctx, &3);
        job.wait();
        job.update(&ctx, &3); // same input: no new run
        assert!(!job.is_running());
        assert_eq!(job.shown().map(|(i, o)| (*i, **o)), Some((3, 9)));
        assert_eq!(job.generation(), 1);
        job.update(&ctx, &-1);
        job.wait();
        assert_eq!(job.error(), Some("negative"));
        assert_eq!(job.shown().map(|(i, o)| (*i, **o)), Some((3, 9)), "the last good result stays shown");
        assert!(job.last_duration().is_some());
    }
}
