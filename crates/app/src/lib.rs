//! The vestnav console: an egui/eframe desktop app with which an operator guides a vest wearer to GPS
//! waypoints.
//!
//! Panels: GPS (source, fix, sky, alarm), Vest (4x4 grid as worn, patterns, STOP ALL), Guidance (automatic
//! cues and why), Map (walkers tiles or a local metric grid, waypoints, track, GPX), Simulation and Field
//! tests, and the session log viewer. The running system — devices, guidance, the route, the session log,
//! the stop path — is a [`vestnav_station::Station`] the console holds and views; [`console::Console`] is
//! the view's whole state and can be driven without a window:
//!
//! ```no_run
//! # use vestnav_app::console::{Console, ConsoleOptions};
//! # use vestnav_station::hardware::Hardware;
//! let console = Console::new(Box::new(Hardware::default()), ConsoleOptions::default());
//! assert!(console.gps_connected());
//! ```

pub mod broker_settings;
pub mod compass_panel;
pub mod config;
pub mod console;
pub mod dirs;
mod export;
pub mod fieldtest_panel;
pub mod file_dialog;
pub mod gps_panel;
pub mod gps_receiver;
pub mod lab_window;
pub mod log_viewer;
pub mod map_panel;
pub mod map_tools;
pub mod ntrip_panel;
pub mod pattern_editor;
pub mod remote_drive;
pub mod remote_panel;
pub mod route_import;
mod sim_panel;
pub mod study_panel;
pub mod tiles;
pub mod vest_panel;

use console::{Console, ConsoleOptions, DeviceOverrides, Liveness};
use vestnav_station::stop::StopPath;

/// Opens the console window and runs until it is closed or the process is told to end.
///
/// Settings come from the platform config file (see [`config`]); devices given in `devices` (the
/// command line's `--gps`/`--vest`) win over it for this run and connect at start. Without either, the
/// console starts with the built-in GPS simulator walking the demo route and the emulated vest.
///
/// Every way out stops the vest first: closing the window, and SIGTERM, SIGINT or SIGHUP (a handler
/// thread sends a fresh STOP ALL, waits at most [`vestnav_station::stop::EXIT_STOP_WAIT`] for the unit's
/// acknowledgement, then closes the window; the process ends with status 128 + the signal's number, as a
/// killed program would, within [`vestnav_station::stop::EXIT_DEADLINE`] of the signal whatever the window
/// does).
///
/// With `screenshot`, the window saves a PNG of itself once `after` has passed and then closes as any close
/// does (vest stopped first): the documentation's screenshots and bug reports come from the real window.
pub fn run(
    devices: DeviceOverrides,
    screenshot: Option<Screenshot>,
    remote: Option<(vestnav_remote::BrokerConfig, String)>,
) -> anyhow::Result<()> {
    let cfg_path = config::default_path();
    let (cfg, cfg_error) =
        cfg_path.as_deref().map_or_else(|| (config::Config::default(), None), config::Config::load);
    let log_dir = cfg.log_dir.clone().unwrap_or_else(|| config::data_dir().join("sessions"));
    let stop = StopPath::default();
    #[cfg(unix)]
    vestnav_station::stop::exit_on_signals(stop.clone(), || {})?;
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("vestnav console")
            // Wayland docks match the window to vestnav.desktop by this id (X11: StartupWMClass).
            .with_app_id("vestnav")
            .with_inner_size(screenshot.as_ref().and_then(|s| s.size).unwrap_or([1400.0, 880.0]))
            .with_min_inner_size([900.0, 600.0]),
        ..eframe::NativeOptions::default()
    };
    let guard = stop.clone();
    eframe::run_native(
        "vestnav",
        options,
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            stop.set_closer(Some(Box::new(move || {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                ctx.request_repaint();
            })));
            let mut console = Console::new(
                Box::new(vestnav_station::hardware::Hardware::default()),
                ConsoleOptions {
                    cfg,
                    cfg_path,
                    log_dir: Some(log_dir),
                    waker: Some(cc.egui_ctx.clone()),
                    devices,
                    liveness: Some(Liveness::default()),
                    stop,
                    route_autosave: Some(config::route_autosave_path()),
                },
            );
            if let Some(e) = cfg_error {
                console.say(vestnav_station::Severity::Alarm, vestnav_station::Subject::Settings, e.banner());
            }
            // `--broker` wins for this run; else the saved broker when it is to connect at start.
            let connected = match &remote {
                Some((broker, operator)) => {
                    remote_panel::RemotePanel::connect(broker, operator, console.station.stop_path().clone())
                        .map_err(|e| e.to_string())
                }
                None if console.cfg.broker_at_start => {
                    let mut p = remote_panel::RemotePanel::new(console.station.stop_path().clone(), None);
                    broker_settings::connect(&mut p, &console.cfg.broker, &console.cfg.recent.base())
                        .map(|()| p)
                }
                None => Err(String::new()),
            };
            match connected {
                Ok(mut p) => {
                    p.set_log_dir(Some(console.log_dir()));
                    console.remote = Some(p);
                }
                Err(e) if !e.is_empty() => console.say(
                    vestnav_station::Severity::Alarm,
                    vestnav_station::Subject::Operator,
                    format!("Stations not shown: {e}"),
                ),
                Err(_) => {}
            }
            Ok(Box::new(App { console, screenshot: screenshot.map(ScreenshotState::new) }))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the console window: {e}"))?;
    if let Some(sig) = guard.signal() {
        // The window has closed and the vest was stopped: end as the signal asked.
        std::process::exit(128 + sig);
    }
    Ok(())
}

/// A PNG of the window to save (`vestnav --screenshot`).
#[derive(Debug, Clone)]
pub struct Screenshot {
    /// Where the PNG goes.
    pub path: std::path::PathBuf,
    /// How long the console runs first (devices connect, the simulator walks).
    pub after: std::time::Duration,
    /// The window's inner size [points] (`None`: the console's default).
    pub size: Option<[f32; 2]>,
}

/// Where a requested screenshot stands.
struct ScreenshotState {
    shot: Screenshot,
    start: std::time::Instant,
    /// The rendered pixels arrive here from the integration.
    pixels: std::sync::mpsc::Receiver<std::sync::Arc<egui::ColorImage>>,
    sender: Option<std::sync::mpsc::SyncSender<std::sync::Arc<egui::ColorImage>>>,
}

impl ScreenshotState {
    fn new(shot: Screenshot) -> Self {
        let (sender, pixels) = std::sync::mpsc::sync_channel(1);
        Self { shot, start: std::time::Instant::now(), pixels, sender: Some(sender) }
    }

    /// Asks for the pixels once it is time, saves them when they come, then closes the window.
    fn poll(&mut self, ctx: &egui::Context) {
        if self.start.elapsed() >= self.shot.after
            && let Some(sender) = self.sender.take()
        {
            ctx.request_screenshot(move |image| {
                let _ = sender.try_send(image);
            });
        }
        if let Ok(image) = self.pixels.try_recv() {
            match save_png(&image, &self.shot.path) {
                Ok(()) => eprintln!("vestnav: screenshot saved to {}", self.shot.path.display()),
                Err(e) => eprintln!("vestnav: screenshot {}: {e}", self.shot.path.display()),
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}

/// Writes `image` as an RGBA PNG.
fn save_png(image: &egui::ColorImage, path: &std::path::Path) -> anyhow::Result<()> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(egui::Color32::to_array).collect();
    let buffer = image::RgbaImage::from_raw(u32::try_from(w)?, u32::try_from(h)?, bytes)
        .ok_or_else(|| anyhow::anyhow!("{w}x{h} pixels do not fill the image"))?;
    buffer.save_with_format(path, image::ImageFormat::Png)?;
    Ok(())
}

/// eframe's view of the console.
struct App {
    console: Console,
    screenshot: Option<ScreenshotState>,
}

impl eframe::App for App {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        // Runs even while the window is hidden: the heartbeat and the event drain go on.
        self.console.tick();
        if let Some(s) = &mut self.screenshot {
            s.poll(ctx);
        }
        // No fixed frame rate: the devices wake the window on a change, and it turns on its own only as
        // often as its ages, alarms and the vest's liveness check need (`console/layout.rs`).
        if let Some(d) = self.console.next_turn(std::time::Instant::now()) {
            ctx.request_repaint_after(d);
        }
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.console.ui(ui);
        if let Some(r) = &mut self.console.remote {
            r.ui(ui.ctx(), &self.console.station, &self.console.cfg.user_patterns);
        }
        if self.console.broker_window.open {
            let c = &mut self.console;
            let stop = c.station.stop_path().clone();
            let logs = Some(c.log_dir());
            c.broker_window.ui(ui.ctx(), &mut c.cfg, &mut c.remote, || {
                let mut p = remote_panel::RemotePanel::new(stop.clone(), logs.clone());
                p.open = true;
                p
            });
        }
    }

    fn on_exit(&mut self, _gl: Option<&eframe::glow::Context>) {
        self.console.shutdown();
    }
}
