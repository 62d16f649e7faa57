//! Heatmaps of a regular grid with a colorbar.

use tiny_skia::{FilterQuality, PathBuilder, Pixmap, PixmapPaint, Transform};

use crate::canvas::{
    self, Area, Axis, INK, LABEL_PX, NOTE_PX, TICK_LEN, TICK_PX, TITLE_PX, draw_frame_and_labels,
    fitting_x_ticks, fitting_y_ticks, widest_label,
};
use crate::text::{HAlign, TextStyle, VAlign, draw_text};
use crate::ticks::{self, Ticks};
use crate::{Color, Scale, colormap};

/// A colour-mapped image of values on a regular `nx` by `ny` grid, with a colorbar.
#[derive(Debug, Clone)]
pub struct Heatmap {
    /// Panel title.
    pub title: String,
    /// X extent (outer cell edges, data units).
    pub x_extent: (f64, f64),
    /// Y extent (outer cell edges); row 0 at `y_extent.0`.
    pub y_extent: (f64, f64),
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Row-major values, `values[j * nx + i]`.
    pub values: Vec<f64>,
    /// X axis label with units.
    pub x_label: String,
    /// Y axis label with units.
    pub y_label: String,
    /// Colorbar label with units.
    pub colorbar_label: String,
    /// Fixed range of the colour map, else min..max of the finite values.
    pub value_range: Option<(f64, f64)>,
    /// Labelled markers `(x, y, label)` drawn on top.
    pub points: Vec<(f64, f64, String)>,
    /// One x unit as long as one y unit.
    pub equal_aspect: bool,
}

impl Heatmap {
    /// A heatmap covering `x_extent` by `y_extent` (data units, the outer edges of the cells) with
    /// `nx * ny` cells.
    ///
    /// `values` is row-major: `values[j * nx + i]` is the cell in column `i` and row `j`; cell `(i, j)` covers
    /// `x0 + i * dx ..= x0 + (i + 1) * dx` with `dx = (x1 - x0) / nx`, likewise in y, so row 0 sits at
    /// `y_extent.0` (drawn at the bottom). Missing or non-finite values are drawn light grey.
    pub fn new(
        title: impl Into<String>,
        x_extent: (f64, f64),
        y_extent: (f64, f64),
        nx: usize,
        ny: usize,
        values: Vec<f64>,
    ) -> Self {
        Self {
            title: title.into(),
            x_extent,
            y_extent,
            nx,
            ny,
            values,
            x_label: String::new(),
            y_label: String::new(),
            colorbar_label: String::new(),
            value_range: None,
            points: Vec::new(),
            equal_aspect: false,
        }
    }

    /// Label of the x axis, with units.
    #[must_use]
    pub fn x_label(mut self, label: impl Into<String>) -> Self {
        self.x_label = label.into();
        self
    }

    /// Label of the y axis, with units.
    #[must_use]
    pub fn y_label(mut self, label: impl Into<String>) -> Self {
        self.y_label = label.into();
        self
    }

    /// Label of the colorbar, with units.
    #[must_use]
    pub fn colorbar_label(mut self, label: impl Into<String>) -> Self {
        self.colorbar_label = label.into();
        self
    }

    /// Fix the value range mapped onto the colormap (default: min..max of the finite values).
    #[must_use]
    pub fn value_range(mut self, min: f64, max: f64) -> Self {
        self.value_range = Some((min, max));
        self
    }

    /// Draw cells so one x unit is as long as one y unit on screen (the plot area shrinks to fit).
    #[must_use]
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Labelled markers drawn on top, at `(x, y)` in data units.
    #[must_use]
    pub fn points(mut self, points: Vec<(f64, f64, String)>) -> Self {
        self.points = points;
        self
    }
}

/// Side length cap of the intermediate cell image; larger grids are sampled down (nearest cell).
const MAX_IMAGE_SIDE: usize = 2048;

/// Colorbar geometry, pixels.
const BAR_GAP: f32 = 16.0;
const BAR_WIDTH: f32 = 16.0;

fn finite_sorted((a, b): (f64, f64)) -> Option<(f64, f64)> {
    (a.is_finite() && b.is_finite() && (b - a).abs() > 0.0).then(|| (a.min(b), a.max(b)))
}

impl Heatmap {
    /// The value interval mapped onto the colormap.
    fn color_range(&self) -> (f64, f64) {
        let explicit = self.value_range.and_then(finite_sorted);
        let data =
            ticks::extent(self.values.iter().take(self.nx.saturating_mul(self.ny)).copied(), Scale::Linear);
        explicit.unwrap_or_else(|| ticks::resolve_range(None, data, Scale::Linear, 0.0))
    }

    /// The cells as a small image, row 0 at the bottom; `None` for an empty grid.
    fn cell_image(&self, lo: f64, hi: f64) -> Option<Pixmap> {
        let (w, h) = (self.nx.min(MAX_IMAGE_SIDE), self.ny.min(MAX_IMAGE_SIDE));
        let mut image = Pixmap::new(u32::try_from(w).ok()?, u32::try_from(h).ok()?)?;
        let span = hi - lo;
        for row in 0..h {
            let j = row * self.ny / h;
            for col in 0..w {
                let i = col * self.nx / w;
                let v = self.values.get(j * self.nx + i).copied().unwrap_or(f64::NAN);
                let t = if v.is_finite() { (v - lo) / span } else { f64::NAN };
                let c = colormap::viridis(t);
                let pixel = tiny_skia::ColorU8::from_rgba(c.r, c.g, c.b, 255).premultiply();
                // Image row 0 is the top: flip so data row 0 lands at the bottom.
                image.pixels_mut()[(h - 1 - row) * w + col] = pixel;
            }
        }
        Some(image)
    }

    /// Draw the heatmap onto a panel pixmap (already white).
    #[allow(clippy::too_many_lines)] // one linear layout-then-draw sequence; splitting it would scatter the layout state
    pub(crate) fn draw(&self, pixmap: &mut Pixmap) {
        let (width, height) = (pixmap.width() as f32, pixmap.height() as f32);
        let x_range = finite_sorted(self.x_extent)
            .unwrap_or_else(|| ticks::resolve_range(None, None, Scale::Linear, 0.0));
        let y_range = finite_sorted(self.y_extent)
            .unwrap_or_else(|| ticks::resolve_range(None, None, Scale::Linear, 0.0));
        let (c_lo, c_hi) = self.color_range();
        let top = if self.title.is_empty() { 14.0 } else { 10.0 + TITLE_PX + 14.0 };
        let x_label_h = if self.x_label.is_empty() { 0.0 } else { 8.0 + LABEL_PX + 4.0 };
        let bottom = height - (TICK_LEN + 4.0 + TICK_PX + x_label_h + 12.0);
        let y_label_w = if self.y_label.is_empty() { 0.0 } else { LABEL_PX + 10.0 };

        // The colorbar column on the right: bar, tick labels, rotated label.
        let bar_axis = |t: f32, b: f32| Axis {
            scale: Scale::Linear,
            lo: c_lo,
            hi: c_hi,
            px_lo: f64::from(b),
            px_hi: f64::from(t),
            integer: false,
        };
        let bar_ticks = fitting_y_ticks(&bar_axis(top, bottom), bottom - top);
        let bar_label_w = if self.colorbar_label.is_empty() { 0.0 } else { LABEL_PX + 8.0 };
        let right_column =
            BAR_GAP + BAR_WIDTH + TICK_LEN + 4.0 + widest_label(&bar_ticks) + 6.0 + bar_label_w + 6.0;

        let mut left = 60.0_f32;
        let mut area = Area { left, top, right: width - right_column, bottom };
        let mut x_axis = Axis {
            scale: Scale::Linear,
            lo: x_range.0,
            hi: x_range.1,
            px_lo: 0.0,
            px_hi: 1.0,
            integer: false,
        };
        let mut y_axis = Axis {
            scale: Scale::Linear,
            lo: y_range.0,
            hi: y_range.1,
            px_lo: 1.0,
            px_hi: 0.0,
            integer: false,
        };
        let (mut x_ticks, mut y_ticks) = (Ticks::default(), Ticks::default());
        for _ in 0..2 {
            area = Area {
                left: left.round(),
                top: top.round(),
                right: (width - right_column).round().max(left.round() + 10.0),
                bottom: bottom.round().max(top.round() + 10.0),
            };
            if self.equal_aspect {
                area = shrink_to_aspect(area, x_range.1 - x_range.0, y_range.1 - y_range.0);
            }
            x_axis.px_lo = f64::from(area.left);
            x_axis.px_hi = f64::from(area.right);
            y_axis.px_lo = f64::from(area.bottom);
            y_axis.px_hi = f64::from(area.top);
            y_ticks = fitting_y_ticks(&y_axis, area.height());
            x_ticks = fitting_x_ticks(&x_axis, area.width());
            left = (8.0 + y_label_w + widest_label(&y_ticks) + 4.0 + TICK_LEN + 2.0).min(width * 0.45);
        }

        if let Some(image) = self.cell_image(c_lo, c_hi) {
            let sx = area.width() / image.width() as f32;
            let sy = area.height() / image.height() as f32;
            let transform = Transform::from_row(sx, 0.0, 0.0, sy, area.left, area.top);
            let paint = PixmapPaint { quality: FilterQuality::Nearest, ..PixmapPaint::default() };
            pixmap.draw_pixmap(0, 0, image.as_ref(), &paint, transform, None);
        }
        draw_frame_and_labels(pixmap, area, &x_axis, &y_axis, &x_ticks, &y_ticks);
        self.draw_points(pixmap, area, &x_axis, &y_axis);

        // Colorbar, as tall as the (possibly shrunk) plot area.
        let bar = bar_axis(area.top, area.bottom);
        let bar_ticks = fitting_y_ticks(&bar, area.height());
        let bar_left = area.right + BAR_GAP;
        let rows = area.height().max(1.0) as usize;
        for r in 0..rows {
            let y = area.top + r as f32;
            let t = 1.0 - (f64::from(r as u32) + 0.5) / rows as f64;
            canvas::fill_rect(pixmap, bar_left, y, bar_left + BAR_WIDTH, y + 1.0, colormap::viridis(t));
        }
        let bar_area =
            Area { left: bar_left, top: area.top, right: bar_left + BAR_WIDTH, bottom: area.bottom };
        canvas::stroke_rect(pixmap, bar_area.left, bar_area.top, bar_area.right, bar_area.bottom, INK, 1.0);
        let style = TextStyle::new(TICK_PX).color(INK);
        let mut widest = 0.0_f32;
        for (v, label) in &bar_ticks.major {
            if let Some(p) = canvas::tick_pixels(&bar, &[*v]).first() {
                let y = p.round() + 0.5;
                canvas::draw_line(
                    pixmap,
                    (bar_area.right, y),
                    (bar_area.right + TICK_LEN, y),
                    INK,
                    &canvas::stroke(1.0, false),
                );
                let w = draw_text(
                    pixmap,
                    label,
                    bar_area.right + TICK_LEN + 4.0,
                    *p,
                    HAlign::Left,
                    VAlign::Middle,
                    0.0,
                    style,
                );
                widest = widest.max(w);
            }
        }
        if !self.colorbar_label.is_empty() {
            let x = bar_area.right + TICK_LEN + 4.0 + widest + 8.0;
            let label = canvas::fit_text(&self.colorbar_label, LABEL_PX, area.height() + 40.0);
            let style = TextStyle::new(LABEL_PX).color(INK);
            // Reads bottom to top, like the y-axis label.
            draw_text(
                pixmap,
                &label,
                x,
                f32::midpoint(area.top, area.bottom),
                HAlign::Center,
                VAlign::Top,
                -90.0,
                style,
            );
        }
        // The y label hugs the tick labels, also when equal aspect moved the plot area inwards.
        let y_label_x = (area.left - TICK_LEN - 4.0 - widest_label(&y_ticks) - 10.0 - LABEL_PX).max(4.0);
        canvas::draw_titles(pixmap, area, &self.title, &self.x_label, &self.y_label, y_label_x, width);
    }

    fn draw_points(&self, pixmap: &mut Pixmap, area: Area, x_axis: &Axis, y_axis: &Axis) {
        let note = TextStyle::new(NOTE_PX).color(INK).halo(2.0);
        for (x, y, label) in &self.points {
            let (Some(px), Some(py)) = (x_axis.to_px(*x), y_axis.to_px(*y)) else { continue };
            let (px, py) = (px as f32, py as f32);
            if px < area.left || px > area.right || py < area.top || py > area.bottom {
                continue;
            }
            if let Some(circle) = PathBuilder::from_circle(px, py, 3.5) {
                pixmap.fill_path(
                    &circle,
                    &canvas::paint(Color::WHITE),
                    tiny_skia::FillRule::Winding,
                    Transform::identity(),
                    None,
                );
                pixmap.stroke_path(
                    &circle,
                    &canvas::paint(INK),
                    &canvas::stroke(1.2, false),
                    Transform::identity(),
                    None,
                );
            }
            if !label.is_empty() {
                draw_text(pixmap, label, px + 5.0, py - 3.0, HAlign::Left, VAlign::Bottom, 0.0, note);
            }
        }
    }
}

/// The largest centred sub-rectangle of `area` whose width/height equals `x_span / y_span`.
fn shrink_to_aspect(area: Area, x_span: f64, y_span: f64) -> Area {
    let ratio = (x_span / y_span) as f32;
    if !(ratio.is_finite() && ratio > 0.0) {
        return area;
    }
    let (w, h) = (area.width(), area.height());
    if w / h > ratio {
        let new_w = (h * ratio).round();
        let left = (area.left + (w - new_w) / 2.0).round();
        Area { left, right: left + new_w, ..area }
    } else {
        let new_h = (w / ratio).round();
        let top = (area.top + (h - new_h) / 2.0).round();
        Area { top, bottom: top + new_h, ..area }
    }
}
