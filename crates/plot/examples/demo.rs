//! Renders a demo sheet of every panel kind: `cargo run -p vestnav-plot --example demo -- /tmp/plotdemo.png`.

use std::path::PathBuf;

use vestnav_plot::{Chart, Color, Figure, Heatmap, Marker, Scale, Series};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).map_or_else(|| PathBuf::from("plotdemo.png"), PathBuf::from);

    // A damped start transient and its envelope, like the thesis's eccentric-angle figures.
    let t: Vec<f64> = (0..20_000).map(|i| f64::from(i) * 2.5e-5).collect();
    let omega: Vec<f64> =
        t.iter().map(|t| 1160.0 * (1.0 - (-t / 0.02).exp()) + 30.0 * (t * 900.0).sin()).collect();
    let settled: Vec<f64> = t.iter().map(|_| 1160.0).collect();
    let transient = Chart::new("Fig 29: rotor speed")
        .x_label("time [s]")
        .y_label("omega [rad/s]")
        .series(Series::line("simulated", t.clone(), omega))
        .series(Series::line("steady state", t.clone(), settled).dashed())
        .vline(0.078, "2 % settled")
        .hline(1200.0, "limit");

    // A power-law sweep on log-log axes.
    let b: Vec<f64> = (0..12).map(|i| 1e-7 * 10f64.powf(f64::from(i) / 4.0)).collect();
    let f: Vec<f64> = b.iter().map(|b| 0.9 * b.powf(-0.48)).collect();
    let fit: Vec<f64> = b.iter().map(|b| 0.92 * b.powf(-0.479)).collect();
    let sweep = Chart::new("Fig 36: damping sweep")
        .x_label("damping b [N m s]")
        .y_label("f [Hz]")
        .x_scale(Scale::Log10)
        .y_scale(Scale::Log10)
        .series(Series::scatter("simulated", b.clone(), f).marker(Marker::Square))
        .series(Series::line("fit f = A b^B", b, fit).color(Color::rgb(200, 30, 30)));

    // A GPS scatter with CEP circles on equal axes.
    let (mut east, mut north) = (Vec::new(), Vec::new());
    for i in 0..400 {
        let a = f64::from(i) * 2.399;
        let r = (f64::from(i) / 400.0).sqrt() * 3.0;
        east.push(r * a.cos() + 0.4);
        north.push(r * a.sin() * 0.7 - 0.2);
    }
    let map = Chart::new("GPS fixes")
        .x_label("east [m]")
        .y_label("north [m]")
        .equal_aspect()
        .series(Series::scatter("fixes", east, north).width(0.8))
        .circle(0.0, 0.0, 1.5, "CEP50")
        .circle(0.0, 0.0, 3.0, "CEP95")
        .annotate(0.0, 0.0, "truth");

    // A vest field.
    let (nx, ny) = (120, 90);
    let mut values = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (i as f64 * 3.0 - 180.0, j as f64 * 3.0 - 135.0);
            values.push(
                20.0 * (-(x * x + y * y) / 4000.0).exp()
                    + 8.0 * (-((x - 80.0).powi(2) + y * y) / 2000.0).exp(),
            );
        }
    }
    let heat = Heatmap::new("vest field", (-180.0, 180.0), (-135.0, 135.0), nx, ny, values)
        .x_label("x [mm]")
        .y_label("y [mm]")
        .colorbar_label("|a| [m/s^2]")
        .points(vec![(0.0, 0.0, "5".to_string()), (80.0, 0.0, "6".to_string())]);

    Figure::single(transient.clone()).save_png(&out.with_extension("single.png"))?;
    Figure::new()
        .title("vestnav-plot demo")
        .columns(2)
        .panel_size(640, 400)
        .push(transient)
        .push(sweep)
        .push(map)
        .push(heat)
        .save_png(&out)?;
    Ok(())
}
