//! Renders degenerate and awkward inputs on one sheet, to look at: `cargo run -p vestnav-plot --example edge`.

use vestnav_plot::{Chart, Figure, Heatmap, Marker, Scale, Series};

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

    // A square field on a wide panel with equal aspect, as the vest maps use it.
    let n = 61;
    let values: Vec<f64> = (0..n * n)
        .map(|k| {
            let (i, j) = ((k % n) as f64 - 30.0, (k / n) as f64 - 30.0);
            (-(i * i + j * j) / 200.0).exp() * (i * 0.4).cos()
        })
        .collect();
    let points = vec![(-40.0, -40.0, "0".to_string()), (40.0, 40.0, "15*".to_string())];
    let heat = Heatmap::new(
        "Peak amplitude of the superposed waves (* = firing)",
        (-61.0, 61.0),
        (-61.0, 61.0),
        n,
        n,
        values,
    )
    .x_label("x, wearer's right [mm]")
    .y_label("y, up [mm]")
    .colorbar_label("a [m/s^2]")
    .equal_aspect()
    .points(points);
    Figure::new()
        .title("Vest field")
        .columns(2)
        .panel_size(560, 480)
        .push(heat.clone())
        .push(heat)
        .save_png(&std::path::Path::new(&out).with_extension("heat.png"))?;
    Ok(())
}
