//! Rendering tests: PNG validity, the data->pixel transform checked against closed-form positions, and
//! robustness against hostile input.

// Test helpers outside #[test] functions panic on purpose when an image is not what it should be.
#![allow(clippy::unwrap_used)]

use approx::assert_relative_eq;
use proptest::prelude::*;
use vestnav_plot::{Chart, Color, Figure, Heatmap, Marker, PlotError, Scale, Series};

/// Width and height from a PNG's IHDR chunk (PNG spec: 8-byte signature, then length, "IHDR", w, h).
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (w, h)
}

fn rgb(pixmap: &tiny_skia::Pixmap, x: u32, y: u32) -> (u8, u8, u8) {
    let c = pixmap.pixel(x, y).unwrap().demultiply();
    (c.red(), c.green(), c.blue())
}

fn is_ink(c: (u8, u8, u8)) -> bool {
    c.0 < 80 && c.1 < 80 && c.2 < 80
}

/// The plot frame found from the image alone: rows/columns that are mostly dark ink.
/// Returns pixel edges (left, top, right, bottom) of the area inside and including the 1 px frame.
fn find_frame(pixmap: &tiny_skia::Pixmap) -> (f64, f64, f64, f64) {
    let (w, h) = (pixmap.width(), pixmap.height());
    let rows: Vec<u32> =
        (0..h).filter(|&y| (0..w).filter(|&x| is_ink(rgb(pixmap, x, y))).count() > w as usize / 2).collect();
    let cols: Vec<u32> =
        (0..w).filter(|&x| (0..h).filter(|&y| is_ink(rgb(pixmap, x, y))).count() > h as usize / 2).collect();
    assert!(rows.len() >= 2 && cols.len() >= 2, "frame not found: rows {rows:?} cols {cols:?}");
    let (top, bottom) = (*rows.first().unwrap(), *rows.last().unwrap());
    let (left, right) = (*cols.first().unwrap(), *cols.last().unwrap());
    (f64::from(left), f64::from(top), f64::from(right + 1), f64::from(bottom + 1))
}

/// Centre (in pixel-edge coordinates) of the run of pixels matching `pred` along a column or row.
fn centre_of(indices: impl Iterator<Item = u32>, mut pred: impl FnMut(u32) -> bool) -> f64 {
    let hits: Vec<u32> = indices.filter(|&i| pred(i)).collect();
    assert!(!hits.is_empty(), "no matching pixels");
    hits.iter().map(|&i| f64::from(i) + 0.5).sum::<f64>() / hits.len() as f64
}

const RED: Color = Color::rgb(220, 0, 0);
const BLUE: Color = Color::rgb(0, 0, 220);

fn is_red(c: (u8, u8, u8)) -> bool {
    c.0 > 150 && c.1 < 100 && c.2 < 100
}

fn is_blue(c: (u8, u8, u8)) -> bool {
    c.2 > 150 && c.0 < 100 && c.1 < 100
}

#[test]
fn png_has_requested_size() {
    let chart = Chart::new("t").series(Series::line("a", vec![0.0, 1.0], vec![0.0, 1.0]));
    let png = Figure::single(chart.clone()).render_png().unwrap();
    assert_eq!(png_size(&png), (900, 560));

    let sheet = Figure::new()
        .title("sheet")
        .columns(2)
        .panel_size(300, 200)
        .push(chart.clone())
        .push(chart.clone())
        .push(chart);
    let png = sheet.render_png().unwrap();
    // Two columns, two rows, plus the 40 px sheet-title band.
    assert_eq!(png_size(&png), (600, 440));
    assert_eq!(sheet.size_px(), (600, 440));
}

#[test]
fn horizontal_and_vertical_lines_land_on_closed_form_pixels() {
    let chart = Chart::new("")
        .x_range(0.0, 1.0)
        .y_range(0.0, 1.0)
        .series(Series::line("", vec![0.0, 1.0], vec![0.5, 0.5]).width(6.0).color(RED))
        .series(Series::line("", vec![0.25, 0.25], vec![0.0, 1.0]).width(6.0).color(BLUE));
    let pixmap = Figure::single(chart).render_pixmap().unwrap();
    let (left, top, right, bottom) = find_frame(&pixmap);
    let probe_x = (left + 0.75 * (right - left)) as u32;
    let y = centre_of(top as u32..bottom as u32, |y| is_red(rgb(&pixmap, probe_x, y)));
    assert_relative_eq!(y, f64::midpoint(top, bottom), epsilon = 0.75);
    let probe_y = (top + 0.2 * (bottom - top)) as u32;
    let x = centre_of(left as u32..right as u32, |x| is_blue(rgb(&pixmap, x, probe_y)));
    assert_relative_eq!(x, left + 0.25 * (right - left), epsilon = 0.75);
}

#[test]
fn log_axis_maps_decades_evenly() {
    // On a 1..100 log axis, 10 sits in the middle and 1e1.5 three quarters up.
    let chart = Chart::new("")
        .x_range(0.0, 1.0)
        .y_range(1.0, 100.0)
        .y_scale(Scale::Log10)
        .series(Series::line("", vec![0.0, 0.5], vec![10.0, 10.0]).width(5.0).color(RED))
        .series(Series::line("", vec![0.5, 1.0], vec![10f64.powf(1.5); 2]).width(5.0).color(BLUE));
    let pixmap = Figure::single(chart).render_pixmap().unwrap();
    let (left, top, right, bottom) = find_frame(&pixmap);
    let x1 = (left + 0.25 * (right - left)) as u32;
    let x2 = (left + 0.75 * (right - left)) as u32;
    let y_red = centre_of(top as u32..bottom as u32, |y| is_red(rgb(&pixmap, x1, y)));
    let y_blue = centre_of(top as u32..bottom as u32, |y| is_blue(rgb(&pixmap, x2, y)));
    assert_relative_eq!(y_red, f64::midpoint(top, bottom), epsilon = 0.75);
    assert_relative_eq!(y_blue, bottom - 0.75 * (bottom - top), epsilon = 0.75);
}

#[test]
fn equal_aspect_draws_a_round_circle() {
    // A wide panel and a tall data extent: with equal aspect a unit circle must be as wide as tall.
    let chart = Chart::new("")
        .equal_aspect()
        .circle(0.0, 0.0, 1.0, "")
        .series(Series::scatter("", vec![0.0, 0.0], vec![-3.0, 3.0]).color(Color::rgb(255, 255, 255)));
    let pixmap = Figure::single(chart).render_pixmap().unwrap();
    let (left, top, right, bottom) = find_frame(&pixmap);
    let (cx, cy) = ((f64::midpoint(left, right)) as u32, (f64::midpoint(top, bottom)) as u32);
    let grey = |c: (u8, u8, u8)| c.0 < 140 && c.0 == c.1 && c.1 == c.2;
    let row: Vec<u32> = (left as u32 + 2..right as u32 - 2).filter(|&x| grey(rgb(&pixmap, x, cy))).collect();
    let col: Vec<u32> = (top as u32 + 2..bottom as u32 - 2).filter(|&y| grey(rgb(&pixmap, cx, y))).collect();
    let width = f64::from(row.last().unwrap() - row.first().unwrap());
    let height = f64::from(col.last().unwrap() - col.first().unwrap());
    assert!(width > 20.0, "circle too small: {width}");
    assert_relative_eq!(width, height, max_relative = 0.03);
}

#[test]
fn heatmap_row_zero_is_at_the_bottom() {
    // Two rows: bottom row low (dark purple), top row high (yellow).
    let heat = Heatmap::new("", (0.0, 1.0), (0.0, 1.0), 1, 2, vec![0.0, 1.0]);
    let pixmap = Figure::single(heat).render_pixmap().unwrap();
    let (w, h) = (pixmap.width(), pixmap.height());
    // Scan the column at 30 % of the width, which lies inside the cell area.
    let x = w * 3 / 10;
    let yellow: Vec<u32> = (0..h)
        .filter(|&y| {
            let c = rgb(&pixmap, x, y);
            c.0 > 200 && c.1 > 200 && c.2 < 80
        })
        .collect();
    let purple: Vec<u32> = (0..h)
        .filter(|&y| {
            let c = rgb(&pixmap, x, y);
            c.0 < 90 && c.1 < 20 && c.2 > 60
        })
        .collect();
    assert!(!yellow.is_empty() && !purple.is_empty());
    assert!(yellow.iter().max() < purple.iter().min());
}

#[test]
fn degenerate_inputs_render() {
    let cases = vec![
        Chart::new("empty"),
        Chart::new("single point").series(Series::line("p", vec![1.0], vec![2.0])),
        Chart::new("all nan").series(Series::line("n", vec![f64::NAN; 10], vec![f64::NAN; 10])),
        Chart::new("mismatched").series(Series::scatter("m", vec![1.0, 2.0, 3.0], vec![1.0])),
        Chart::new("flat").series(Series::line("f", vec![0.0, 0.0], vec![3.0, 3.0])),
        Chart::new("log of negatives").y_scale(Scale::Log10).series(Series::line(
            "l",
            vec![0.0, 1.0],
            vec![-1.0, 0.0],
        )),
        Chart::new("huge").series(Series::line(
            "h",
            vec![-f64::MAX, f64::MAX],
            vec![f64::MAX, f64::MIN_POSITIVE],
        )),
        Chart::new("reversed range").x_range(5.0, -5.0).y_range(f64::NAN, 1.0),
        Chart::new("bad widths")
            .series(Series::line("w", vec![0.0, 1.0], vec![0.0, 1.0]).width(f32::NAN).marker(Marker::Cross)),
        Chart::new("refs only")
            .hline(f64::INFINITY, "inf")
            .vline(2.0, "v")
            .circle(0.0, 0.0, f64::NAN, "c")
            .annotate(f64::NAN, 0.0, "a"),
    ];
    for chart in cases {
        let png = Figure::single(chart).panel_size(320, 240).render_png().unwrap();
        assert_eq!(png_size(&png), (320, 240));
    }
    let heats = vec![
        Heatmap::new("zero", (0.0, 1.0), (0.0, 1.0), 0, 0, vec![]),
        Heatmap::new("short", (0.0, 1.0), (1.0, 1.0), 4, 4, vec![1.0, f64::NAN]),
        Heatmap::new("const", (f64::NAN, 1.0), (0.0, 1.0), 2, 2, vec![3.0; 4])
            .value_range(2.0, 2.0)
            .equal_aspect(),
    ];
    for heat in heats {
        Figure::single(heat).panel_size(320, 240).render_png().unwrap();
    }
    assert_eq!(png_size(&Figure::new().render_png().unwrap()), (640, 400));
}

#[test]
fn invalid_sizes_are_errors() {
    let chart = Chart::new("x");
    assert!(matches!(
        Figure::single(chart.clone()).panel_size(0, 10).render_png(),
        Err(PlotError::InvalidSize { .. })
    ));
    assert!(matches!(
        Figure::single(chart).panel_size(100_000, 100_000).render_png(),
        Err(PlotError::InvalidSize { .. })
    ));
}

#[test]
fn save_png_writes_atomically_and_reports_bad_paths() {
    let dir = std::env::temp_dir().join(format!("vestnav-plot-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("out.png");
    let figure = Figure::single(Chart::new("saved")).panel_size(200, 150);
    figure.save_png(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(png_size(&bytes), (200, 150));
    // Only the final file remains: no temporary left behind.
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, vec![std::ffi::OsString::from("out.png")]);
    std::fs::remove_dir_all(&dir).unwrap();

    let err = figure.save_png(&dir.join("missing/dir/out.png")).unwrap_err();
    assert!(matches!(err, PlotError::Io { .. }));
    assert!(err.to_string().contains("missing"), "{err}");
}

#[test]
fn a_million_point_line_keeps_its_peak() {
    // One sample spike in a million-point flat trace must survive decimation.
    let n = 1_000_000;
    let x: Vec<f64> = (0..n).map(f64::from).collect();
    let mut y = vec![0.0; n as usize];
    y[654_321] = 1.0;
    let chart = Chart::new("").y_range(0.0, 1.0).series(Series::line("", x, y).color(RED).width(2.0));
    let pixmap = Figure::single(chart).render_pixmap().unwrap();
    let (left, top, right, bottom) = find_frame(&pixmap);
    let near_top = (top + 0.05 * (bottom - top)) as u32;
    let reds: Vec<u32> = (left as u32..right as u32).filter(|&x| is_red(rgb(&pixmap, x, near_top))).collect();
    assert!(!reds.is_empty(), "spike lost");
    let expected = left + 654_321.0 / 999_999.0 * (right - left);
    assert_relative_eq!(f64::from(reds[0]), expected, epsilon = 3.0);
}

fn special_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e6..1e6f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(f64::MAX),
        1 => Just(-f64::MAX),
        1 => Just(0.0),
        1 => Just(f64::MIN_POSITIVE),
        1 => any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_series_never_panic(
        x in prop::collection::vec(special_f64(), 0..40),
        y in prop::collection::vec(special_f64(), 0..40),
        range in prop::option::of((special_f64(), special_f64())),
        log_x in any::<bool>(),
        log_y in any::<bool>(),
        equal in any::<bool>(),
        refs in (special_f64(), special_f64(), special_f64()),
    ) {
        let scale = |log: bool| if log { Scale::Log10 } else { Scale::Linear };
        let mut chart = Chart::new("prop")
            .x_label("x [m]")
            .y_label("y [m]")
            .x_scale(scale(log_x))
            .y_scale(scale(log_y))
            .series(Series::line("line", x.clone(), y.clone()).dashed())
            .series(Series::scatter("points", y.clone(), x.clone()).marker(Marker::Square))
            .hline(refs.0, "h")
            .vline(refs.1, "v")
            .circle(refs.0, refs.1, refs.2, "c")
            .annotate(refs.2, refs.0, "a");
        if let Some((a, b)) = range {
            chart = chart.x_range(a, b).y_range(b, a);
        }
        if equal {
            chart = chart.equal_aspect();
        }
        let n = x.len().min(8);
        let heat = Heatmap::new("h", (refs.0, refs.1), range.unwrap_or((0.0, 1.0)), n, 3, y.clone());
        let png = Figure::new().columns(2).panel_size(240, 180).push(chart).push(heat).render_png().unwrap();
        prop_assert_eq!(png_size(&png), (480, 180));
    }
}
