//! The map's tools: the mouse position in decimal degrees, DMS, UTM and MGRS; go-to-coordinates (typed in
//! any of those); the measuring tool (geodesic distance and bearing between two clicks); and the overlays
//! drawn on top of the map (north arrow, legend, the measured line, field-test cone marks and drift fixes).
//!
//! Reading and writing typed positions (decimal, DMS, UTM/UPS, MGRS) lives in core's `coords`, shared with
//! the CLI; distances and bearings come from core's `geo` (Karney's geodesics on WGS-84). Nothing here
//! projects by hand.

use egui::{Color32, Pos2, Stroke, vec2};
pub use vestnav_core::coords::{
    MGRS_DIGITS, format_decimal, format_dms, format_dms_angle, format_mgrs, format_utm, parse_position,
};
use vestnav_core::geo::{Earth, Inverse, LatLon};

/// Every readout of the mouse position, one per line, as the map shows them.
pub fn coordinate_lines(p: LatLon) -> [String; 4] {
    let or_err = |r: Result<String, String>| r.unwrap_or_else(|e| format!("({e})"));
    [
        format!("Decimal  {}", format_decimal(p)),
        format!("DMS  {}", format_dms(p)),
        format!("UTM  {}", or_err(format_utm(p))),
        format!("MGRS  {}", or_err(format_mgrs(p, MGRS_DIGITS))),
    ]
}

/// The measuring tool's result between two clicked points: Karney's geodesic on WGS-84 (core's `geo`).
pub fn measure(a: LatLon, b: LatLon) -> Inverse {
    Earth::Wgs84.inverse(a, b)
}

/// A measured distance and bearing in words: "238.9 m · bearing 0.0°" (kilometres past 10 km).
pub fn measurement_text(m: &Inverse) -> String {
    let d = if m.distance_m < 10_000.0 {
        format!("{:.1} m", m.distance_m)
    } else {
        format!("{:.3} km", m.distance_m / 1000.0)
    };
    format!("{d} · bearing {:.1}°", m.initial_bearing_deg)
}

/// What the field-test panel shows on the map while a test runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldOverlay {
    /// Cone marks of a running cone test: label and position.
    pub cones: Vec<(String, LatLon)>,
    /// Fixes of a running drift test.
    pub drift: Vec<LatLon>,
    /// The field tests' reference (the truth), drawn whenever one is set.
    pub reference: Option<ReferenceMark>,
}

/// The reference on the map: a marker, its stated uncertainty as a circle, and a label.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceMark {
    /// Where it is.
    pub pos: LatLon,
    /// Its stated horizontal uncertainty (1 sigma) [m]: the circle's radius.
    pub uncertainty_m: f64,
    /// The label beside the marker (`reference ±0.020 m`).
    pub label: String,
}

impl ReferenceMark {
    /// The mark of `r`.
    pub fn of(r: &vestnav_core::accuracy::Reference) -> Self {
        Self {
            pos: r.pos,
            uncertainty_m: r.uncertainty_m,
            label: format!("reference ±{:.3} m", r.uncertainty_m),
        }
    }

    /// Draws the marker (a diamond), the uncertainty circle (radius `uncertainty_m * px_per_m`, at least a
    /// few pixels so a centimetre circle stays visible around the marker) and the label at screen point `c`.
    pub fn draw(&self, painter: &egui::Painter, c: Pos2, px_per_m: f64, font: egui::FontId, ink: Color32) {
        let color = REFERENCE_COLOR;
        let r = (self.uncertainty_m * px_per_m).clamp(0.0, 1.0e5) as f32;
        painter.circle(c, r.max(9.0), color.gamma_multiply(0.15), Stroke::new(1.5, color));
        let d = 6.0;
        let diamond = vec![c + vec2(0.0, -d), c + vec2(d, 0.0), c + vec2(0.0, d), c + vec2(-d, 0.0)];
        painter.add(egui::Shape::convex_polygon(diamond, color, Stroke::new(1.0, Color32::WHITE)));
        let at = c + vec2(
            r.max(9.0) * std::f32::consts::FRAC_1_SQRT_2 + 4.0,
            -r.max(9.0) * std::f32::consts::FRAC_1_SQRT_2 - 4.0,
        );
        let galley = painter.layout_no_wrap(self.label.clone(), font, ink);
        let rect = egui::Align2::LEFT_BOTTOM.anchor_size(at, galley.size());
        painter.rect_filled(rect.expand(2.0), 3.0, Color32::from_black_alpha(60));
        painter.galley(rect.min, galley, ink);
    }
}

/// The reference's colour on the map and in the legend.
pub const REFERENCE_COLOR: Color32 = Color32::from_rgb(200, 0, 160);

impl FieldOverlay {
    /// Whether there is nothing to draw.
    pub fn is_empty(&self) -> bool {
        self.cones.is_empty() && self.drift.is_empty() && self.reference.is_none()
    }
}

/// The tools' state kept between frames.
#[derive(Debug, Clone, Default)]
pub struct MapTools {
    /// Left clicks measure instead of adding waypoints.
    pub measuring: bool,
    /// The measuring tool's points (0, 1 or 2; a third click starts again).
    pub measure_points: Vec<LatLon>,
    /// The go-to field, as typed.
    pub goto_text: String,
    /// Why the last go-to was refused.
    pub goto_error: Option<String>,
    /// The position under the mouse in the latest frame.
    pub pointer: Option<LatLon>,
    /// The map's rectangle in the latest frame (screen points).
    pub map_rect: Option<egui::Rect>,
    /// Field-test marks to draw (set by the console each frame).
    pub field: FieldOverlay,
}

impl MapTools {
    /// A measuring click at `p`: the first point, the second, or a new first after two.
    pub fn measure_click(&mut self, p: LatLon) {
        if self.measure_points.len() >= 2 {
            self.measure_points.clear();
        }
        self.measure_points.push(p);
    }

    /// The measurement once two points are clicked.
    pub fn measurement(&self) -> Option<Inverse> {
        match self.measure_points.as_slice() {
            [a, b] => Some(measure(*a, *b)),
            _ => None,
        }
    }
}

/// Draws a north arrow in the top-right corner of `rect` (the map is always drawn north up).
pub fn draw_north_arrow(painter: &egui::Painter, rect: egui::Rect, ink: Color32, fill: Color32) {
    let c = rect.right_top() + vec2(-28.0, 38.0);
    painter.circle_filled(c, 18.0, fill);
    let tip = c + vec2(0.0, -14.0);
    let left = c + vec2(-7.0, 9.0);
    let right = c + vec2(7.0, 9.0);
    painter.add(egui::Shape::convex_polygon(vec![tip, right, c + vec2(0.0, 4.0), left], ink, Stroke::NONE));
    painter.text(
        c + vec2(0.0, -16.0),
        egui::Align2::CENTER_BOTTOM,
        "N",
        egui::FontId::proportional(13.0),
        ink,
    );
}

/// One legend line: a colour swatch (dot) and its meaning.
pub type LegendItem = (Color32, &'static str);

/// Draws the legend (top left of `rect`): one dot and label per item.
pub fn draw_legend(
    painter: &egui::Painter,
    rect: egui::Rect,
    items: &[LegendItem],
    ink: Color32,
    fill: Color32,
) {
    let font = egui::FontId::proportional(11.0);
    let line_h = 15.0;
    let width = 8.0
        + items
            .iter()
            .map(|(_, t)| painter.layout_no_wrap((*t).to_owned(), font.clone(), ink).size().x)
            .fold(0.0, f32::max)
        + 22.0;
    let top_left = rect.left_top() + vec2(8.0, 8.0);
    let bg = egui::Rect::from_min_size(top_left, vec2(width, line_h * items.len() as f32 + 8.0));
    painter.rect_filled(bg, 3.0, fill);
    for (k, (color, text)) in items.iter().enumerate() {
        let y = top_left.y + 4.0 + line_h * (k as f32 + 0.5);
        painter.circle_filled(Pos2::new(top_left.x + 10.0, y), 4.5, *color);
        painter.text(Pos2::new(top_left.x + 20.0, y), egui::Align2::LEFT_CENTER, *text, font.clone(), ink);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Karney's own published inverse example (`GeographicLib` documentation, "Geodesic calculations"; python
    /// geographiclib docs): Wellington (41.32S, 174.81E) to Salamanca (40.96N, 5.50W): s12 =
    /// 19959679.267353821 m, azi1 = 161.067669986160°, azi2 = 18.825195123247°.
    #[test]
    fn measuring_matches_karneys_published_example() {
        let m = measure(LatLon::new(-41.32, 174.81), LatLon::new(40.96, -5.50));
        assert_relative_eq!(m.distance_m, 19_959_679.267_353_82, max_relative = 1e-12);
        assert_relative_eq!(m.initial_bearing_deg, 161.067_669_986_160, max_relative = 1e-10);
        assert_relative_eq!(m.final_bearing_deg, 18.825_195_123_247, max_relative = 1e-9);
        assert_eq!(measurement_text(&m), "19959.679 km · bearing 161.1°");
        let mut t = MapTools::default();
        t.measure_click(LatLon::new(0.0, 0.0));
        assert!(t.measurement().is_none());
        t.measure_click(LatLon::new(1.0, 0.0));
        // One degree of latitude at the equator: 110 574.389 m (GeodSolve).
        assert_relative_eq!(t.measurement().unwrap().distance_m, 110_574.389, max_relative = 1e-8);
        t.measure_click(LatLon::new(5.0, 5.0));
        assert_eq!(t.measure_points.len(), 1);
    }
}
