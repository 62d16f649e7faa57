//! The Simulation panel: interactive views of the thesis physics (being built).

/// Interactive simulation views: tactor model, damping sweep, skin waves, two-point simulation.
pub struct SimPanel {
    voltage_v: f64,
}

impl Default for SimPanel {
    fn default() -> Self {
        Self::new()
    }
}

impl SimPanel {
    /// A panel with the thesis's default inputs.
    pub fn new() -> Self {
        Self { voltage_v: 3.3 }
    }

    /// Draws the panel.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        ui.add(egui::Slider::new(&mut self.voltage_v, 2.5..=3.8).text("voltage [V]"));
    }
}
