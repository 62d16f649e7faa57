//! A figure's data as CSV, for spreadsheets: the same numbers the PNG draws.

use std::fmt::Write as _;

use vestnav_plot::{Figure, Panel};

/// Quotes a CSV field if it contains a separator, quote or line break (RFC 4180).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// The figure's data in long form: one row per point, `panel,series,x,y,value` (heat maps: `panel,cell,x,y,
/// value` at each cell centre), reference lines as rows with an empty coordinate, circles with their radius
/// as `value`. `header` lines (summary numbers) come first, each prefixed with `# `.
pub fn figure_csv(header: &[String], figure: &Figure) -> String {
    let mut out = String::new();
    for h in header {
        let _ = writeln!(out, "# {}", h.replace(['\n', '\r'], " "));
    }
    let _ = writeln!(out, "panel,series,x,y,value");
    for panel in &figure.panels {
        match panel {
            Panel::Chart(c) => {
                let title = field(&c.title);
                for s in &c.series {
                    let label = field(&s.label);
                    for (x, y) in s.x.iter().zip(&s.y) {
                        let _ = writeln!(out, "{title},{label},{x},{y},");
                    }
                }
                for l in &c.hlines {
                    let _ = writeln!(out, "{title},{},,{},", field(&format!("hline: {}", l.label)), l.value);
                }
                for l in &c.vlines {
                    let _ = writeln!(out, "{title},{},{},,", field(&format!("vline: {}", l.label)), l.value);
                }
                for k in &c.circles {
                    let label = field(&format!("circle: {}", k.label));
                    let _ = writeln!(out, "{title},{label},{},{},{}", k.cx, k.cy, k.r);
                }
            }
            Panel::Heatmap(h) => {
                let title = field(&h.title);
                let nx = h.nx.max(1);
                let dx = (h.x_extent.1 - h.x_extent.0) / nx as f64;
                let dy = (h.y_extent.1 - h.y_extent.0) / h.ny.max(1) as f64;
                for (k, v) in h.values.iter().enumerate() {
                    let x = h.x_extent.0 + ((k % nx) as f64 + 0.5) * dx;
                    let y = h.y_extent.0 + ((k / nx) as f64 + 0.5) * dy;
                    let _ = writeln!(out, "{title},cell,{x},{y},{v}");
                }
                for (x, y, label) in &h.points {
                    let _ = writeln!(out, "{title},{},{x},{y},", field(&format!("point: {label}")));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_plot::{Chart, Heatmap, Series};

    #[test]
    fn long_form_with_quoted_fields_and_cell_centres() {
        let chart = Chart::new("a, \"quoted\" title")
            .series(Series::line("s1", vec![1.0, 2.0], vec![3.0, 4.0]))
            .hline(0.5, "ref");
        let heat = Heatmap::new("h", (0.0, 2.0), (0.0, 1.0), 2, 1, vec![7.0, 8.0]);
        let csv = figure_csv(&["summary line".to_string()], &Figure::new().push(chart).push(heat));
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], "# summary line");
        assert_eq!(lines[1], "panel,series,x,y,value");
        assert_eq!(lines[2], "\"a, \"\"quoted\"\" title\",s1,1,3,");
        assert_eq!(lines[3], "\"a, \"\"quoted\"\" title\",s1,2,4,");
        assert_eq!(lines[4], "\"a, \"\"quoted\"\" title\",hline: ref,,0.5,");
        assert_eq!(lines[5], "h,cell,0.5,0.5,7");
        assert_eq!(lines[6], "h,cell,1.5,0.5,8");
    }
}
