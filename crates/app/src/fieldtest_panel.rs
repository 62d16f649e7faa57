//! The Field-test panel: drift and cone tests as guided procedures (being built).

/// What the operator did in the panel that the app must act on.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldTestAction {
    /// The operator marked a cone: the app logs it in the session log.
    Mark {
        /// Human-readable label of the mark, e.g. "cone 3".
        label: String,
    },
}

/// Guided drift and cone tests fed with every GPS fix.
#[derive(Default)]
pub struct FieldTestPanel {
    fixes: Vec<(f64, f64, f64, Option<f64>)>,
}

impl FieldTestPanel {
    /// An idle panel.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds one fix (time in seconds, WGS-84 degrees, speed over ground if known).
    pub fn push_position(&mut self, t_s: f64, lat_deg: f64, lon_deg: f64, speed_m_s: Option<f64>) {
        self.fixes.push((t_s, lat_deg, lon_deg, speed_m_s));
    }

    /// Draws the panel; returns an action when the operator marked a cone.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<FieldTestAction> {
        ui.label(format!("{} fixes", self.fixes.len()));
        None
    }
}
