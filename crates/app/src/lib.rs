//! The vestnav console: an egui/eframe desktop app with which an operator guides a vest wearer to GPS
//! waypoints.
//!
//! Panels: GPS (source, fix, sky, alarm), Vest (4x4 grid as worn, patterns, STOP ALL), Guidance (automatic
//! cues and why), Map (walkers tiles or a local metric grid, waypoints, track, GPX), Simulation and Field
//! tests, and the session log viewer. Devices, guidance and the session log run on worker threads that talk
//! to the UI over bounded channels ([`model::Outbox`]); [`console::Console`] is the whole UI state and can be
//! driven without a window:
//!
//! ```no_run
//! # use vestnav_app::{console::{Console, ConsoleOptions}, config::Config, hardware::Hardware};
//! let console = Console::new(
//!     Box::new(Hardware),
//!     ConsoleOptions { cfg: Config::default(), cfg_path: None, log_dir: None, waker: None },
//! );
//! assert!(console.gps_connected());
//! ```

pub mod config;
pub mod console;
pub mod devices;
mod fieldtest_panel;
pub mod gps_panel;
pub mod gps_source;
pub mod guidance;
pub mod hardware;
pub mod log_viewer;
pub mod map_panel;
pub mod model;
pub mod route;
pub mod session_log;
mod sim_panel;
pub mod vest_panel;

use console::{Console, ConsoleOptions};

/// Opens the console window and runs until it is closed.
///
/// Settings come from the platform config file (see [`config`]); without one, the console starts with the
/// built-in GPS simulator walking the demo route and the emulated vest.
pub fn run() -> anyhow::Result<()> {
    let cfg_path = config::default_path();
    let (cfg, cfg_error) =
        cfg_path.as_deref().map_or_else(|| (config::Config::default(), None), config::Config::load);
    let log_dir = cfg.log_dir.clone().unwrap_or_else(|| config::data_dir().join("sessions"));
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("vestnav console")
            .with_inner_size([1400.0, 880.0])
            .with_min_inner_size([900.0, 600.0]),
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "vestnav",
        options,
        Box::new(move |cc| {
            let mut console = Console::new(
                Box::new(hardware::Hardware),
                ConsoleOptions { cfg, cfg_path, log_dir: Some(log_dir), waker: Some(cc.egui_ctx.clone()) },
            );
            if let Some(e) = cfg_error {
                console.status = e;
            }
            Ok(Box::new(App(console)))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the console window: {e}"))
}

/// eframe's view of the console.
struct App(Console);

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.0.ui(ui);
    }
}
