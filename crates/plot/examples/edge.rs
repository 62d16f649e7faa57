//! Renders degenerate and awkward inputs on one sheet, to look at: `cargo run -p vestnav-plot --example edge`.

use vestnav_plot::{Chart, Figure, Marker, Scale, Series};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "plotedge.png".into());
    let x: Vec<f64> = (0..50).map(f64::from).collect();
    let tiny: Vec<f64> = x.iter().map(|v| v * 3e-9).collect();
    let huge: Vec<f64> = x.iter().map(|v| -2e7 + v * 1e6).collect();
    let mut many =
        Chart::new("A very long title that goes on and on to check truncation with an ellipsis here")
            .x_label("sample [-]")
            .y_label("current [A]");
    for k in 0..7 {
        let y: Vec<f64> = x.iter().map(|v| (v * 0.1 + f64::from(k)).sin() * 1e-9).collect();
        many = many.series(Series::line(format!("tactor {k}"), x.clone(), y));
    }
    let fig = Figure::new()
        .title("edge cases")
        .columns(3)
        .panel_size(440, 300)
        .push(Chart::new("empty").x_label("x [m]").y_label("y [m]"))
        .push(Chart::new("single point").series(Series::scatter("p", vec![3.0], vec![3.0])))
        .push(
            Chart::new("tiny vs huge").x_label("t [s]").y_label("x [m]").series(Series::line("", tiny, huge)),
        )
        .push(many)
        .push(Chart::new("narrow log").y_scale(Scale::Log10).series(
            Series::line("", x.clone(), x.iter().map(|v| 2.0 + v * 0.05).collect()).marker(Marker::Cross),
        ))
        .push(
            Chart::new("NaN gaps, explicit range").x_range(10.0, 40.0).y_range(-1.0, 1.0).series(
                Series::line(
                    "sin",
                    x.clone(),
                    x.iter()
                        .map(|v| if (20.0..25.0).contains(v) { f64::NAN } else { (v * 0.3).sin() * 1.5 })
                        .collect(),
                ),
            ),
        );
    fig.save_png(std::path::Path::new(&out))?;
    Ok(())
}
