//! The vestnav console (being written).

/// Opens the console window and runs until it is closed.
pub fn run() -> anyhow::Result<()> {
    eframe::run_native(
        "vestnav",
        eframe::NativeOptions::default(),
        Box::new(|_cc| Ok(Box::new(Console))),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the console window: {e}"))
}

struct Console;

impl eframe::App for Console {
    fn update(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        egui::CentralPanel::default().show(ctx, |ui| ui.label("vestnav console"));
    }
}
