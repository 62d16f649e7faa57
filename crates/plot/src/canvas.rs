//! Drawing primitives shared by charts and heatmaps: the data->pixel transform, clipped polylines with
//! per-column decimation, markers, frames and axes.

use tiny_skia::{
    FillRule, LineCap, LineJoin, Mask, Paint, Path, PathBuilder, Pixmap, Rect, Stroke, StrokeDash, Transform,
};

use crate::text::{HAlign, TextStyle, VAlign, draw_text, text_width};
use crate::ticks::{self, Ticks};
use crate::{Color, Marker, Scale};

/// Sizes of the text roles, in pixels.
pub(crate) const TITLE_PX: f32 = 16.0;
pub(crate) const LABEL_PX: f32 = 14.0;
pub(crate) const TICK_PX: f32 = 12.5;
pub(crate) const LEGEND_PX: f32 = 12.5;
pub(crate) const NOTE_PX: f32 = 12.0;

pub(crate) const INK: Color = Color::rgb(30, 30, 30);
pub(crate) const GRID: Color = Color::rgb(226, 226, 226);
pub(crate) const GRID_MINOR: Color = Color::rgb(242, 242, 242);
pub(crate) const REF_LINE: Color = Color::rgb(90, 90, 90);

/// Tick mark length outside the frame, pixels.
pub(crate) const TICK_LEN: f32 = 5.0;

/// Largest pixel coordinate handed to tiny-skia; lines are clipped before this, so it only bounds markers.
const FAR_PX: f64 = 1e6;

/// One axis: a data interval mapped onto a pixel interval (through log10 on a log axis).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Axis {
    pub(crate) scale: Scale,
    pub(crate) lo: f64,
    pub(crate) hi: f64,
    /// Pixel position of `lo`.
    pub(crate) px_lo: f64,
    /// Pixel position of `hi`.
    pub(crate) px_hi: f64,
    /// Ticks only at whole numbers (an axis that counts things).
    pub(crate) integer: bool,
}

impl Axis {
    fn transformed(&self, v: f64) -> Option<f64> {
        match self.scale {
            Scale::Linear => v.is_finite().then_some(v),
            Scale::Log10 => (v.is_finite() && v > 0.0).then(|| v.log10()),
        }
    }

    /// Pixel coordinate of the data value `v`:
    /// `px = px_lo + (t(v) - t(lo)) / (t(hi) - t(lo)) * (px_hi - px_lo)`, `t` = identity or log10.
    /// `None` for values that cannot be shown (non-finite, non-positive on a log axis).
    pub(crate) fn to_px(self, v: f64) -> Option<f64> {
        let (t, t0, t1) = (self.transformed(v)?, self.transformed(self.lo)?, self.transformed(self.hi)?);
        // Halving first keeps the difference finite for ranges near f64::MAX.
        let fraction = (t / 2.0 - t0 / 2.0) / (t1 / 2.0 - t0 / 2.0);
        let px = self.px_lo + fraction * (self.px_hi - self.px_lo);
        px.is_finite().then_some(px)
    }

    /// Ticks for this axis with at most about `max_ticks` labels.
    pub(crate) fn ticks(&self, max_ticks: usize) -> Ticks {
        ticks::axis_ticks(self.scale, self.lo, self.hi, max_ticks, self.integer)
    }
}

/// Plot area in pixels (left, top, right, bottom), whole pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Area {
    pub(crate) left: f32,
    pub(crate) top: f32,
    pub(crate) right: f32,
    pub(crate) bottom: f32,
}

impl Area {
    pub(crate) fn width(&self) -> f32 {
        self.right - self.left
    }
    pub(crate) fn height(&self) -> f32 {
        self.bottom - self.top
    }
    fn contains(&self, x: f64, y: f64, slack: f64) -> bool {
        x >= f64::from(self.left) - slack
            && x <= f64::from(self.right) + slack
            && y >= f64::from(self.top) - slack
            && y <= f64::from(self.bottom) + slack
    }
}

pub(crate) fn paint(color: Color) -> Paint<'static> {
    let mut paint = Paint { anti_alias: true, ..Paint::default() };
    paint.set_color(color.to_skia());
    paint
}

pub(crate) fn stroke(width: f32, dashed: bool) -> Stroke {
    let width = if width.is_finite() { width.clamp(0.1, 50.0) } else { 1.5 };
    Stroke {
        width,
        line_cap: if dashed { LineCap::Butt } else { LineCap::Round },
        line_join: LineJoin::Round,
        dash: if dashed {
            StrokeDash::new(vec![4.0 * width.max(1.5), 2.5 * width.max(1.5)], 0.0)
        } else {
            None
        },
        ..Stroke::default()
    }
}

/// A mask that is opaque inside `area` only: everything data-related is clipped by it.
pub(crate) fn clip_mask(pixmap: &Pixmap, area: Area) -> Option<Mask> {
    let mut mask = Mask::new(pixmap.width(), pixmap.height())?;
    let rect = Rect::from_ltrb(area.left, area.top, area.right, area.bottom)?;
    mask.fill_path(&PathBuilder::from_rect(rect), FillRule::Winding, false, Transform::identity());
    Some(mask)
}

/// Clip the segment `a`-`b` to the rectangle (Liang-Barsky); `None` if it lies outside.
fn clip_segment(a: (f64, f64), b: (f64, f64), r: (f64, f64, f64, f64)) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (p, q) in [(-dx, a.0 - r.0), (dx, r.2 - a.0), (-dy, a.1 - r.1), (dy, r.3 - a.1)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
            if t0 > t1 {
                return None;
            }
        }
    }
    Some(((a.0 + t0 * dx, a.1 + t0 * dy), (a.0 + t1 * dx, a.1 + t1 * dy)))
}

/// Points of one pixel column run: (index, point) of the first, lowest, highest and last sample.
struct Bucket {
    column: i64,
    first: (usize, (f64, f64)),
    min: (usize, (f64, f64)),
    max: (usize, (f64, f64)),
    last: (usize, (f64, f64)),
}
/// Emit a bucket's distinct points in their original order.
fn flush(bucket: Option<Bucket>, out: &mut Vec<Option<(f64, f64)>>) {
    if let Some(b) = bucket {
        let mut picks = [b.first, b.min, b.max, b.last];
        picks.sort_by_key(|p| p.0);
        let mut previous = usize::MAX;
        for (index, point) in picks {
            if index != previous {
                out.push(Some(point));
                previous = index;
            }
        }
    }
}

/// Pixel points of a series, `None` where a value breaks the line (NaN, inf, non-positive on log).
///
/// Runs of consecutive points falling in the same pixel column are reduced to their first, minimum,
/// maximum and last points (in their original order), so 100k-point traces draw fast and every peak stays.
pub(crate) fn pixel_points(x: &[f64], y: &[f64], xa: &Axis, ya: &Axis) -> Vec<Option<(f64, f64)>> {
    let n = x.len().min(y.len());
    let mut out: Vec<Option<(f64, f64)>> = Vec::with_capacity(n.min(8192));
    let mut bucket: Option<Bucket> = None;
    for i in 0..n {
        let (Some(px), Some(py)) = (xa.to_px(x[i]), ya.to_px(y[i])) else {
            flush(bucket.take(), &mut out);
            out.push(None);
            continue;
        };
        let point = (px.clamp(-1e15, 1e15), py.clamp(-1e15, 1e15));
        let column = point.0.floor() as i64;
        match bucket.as_mut() {
            Some(b) if b.column == column => {
                if point.1 < b.min.1.1 {
                    b.min = (i, point);
                }
                if point.1 > b.max.1.1 {
                    b.max = (i, point);
                }
                b.last = (i, point);
            }
            _ => {
                flush(bucket.take(), &mut out);
                bucket = Some(Bucket {
                    column,
                    first: (i, point),
                    min: (i, point),
                    max: (i, point),
                    last: (i, point),
                });
            }
        }
    }
    flush(bucket, &mut out);
    out
}

/// Stroke the polyline through `points` (breaking at `None`), clipped to `area` geometrically and by `mask`.
pub(crate) fn draw_polyline(
    pixmap: &mut Pixmap,
    points: &[Option<(f64, f64)>],
    area: Area,
    color: Color,
    stroke_style: &Stroke,
    mask: Option<&Mask>,
) {
    let slack = f64::from(stroke_style.width) + 2.0;
    let rect = (
        f64::from(area.left) - slack,
        f64::from(area.top) - slack,
        f64::from(area.right) + slack,
        f64::from(area.bottom) + slack,
    );
    let mut builder = PathBuilder::new();
    let mut pen: Option<(f64, f64)> = None;
    let mut single: Vec<(f64, f64)> = Vec::new();
    let mut run_len = 0usize;
    for pair in points.windows(2) {
        match (pair[0], pair[1]) {
            (Some(a), Some(b)) => {
                if let Some((c0, c1)) = clip_segment(a, b, rect) {
                    if pen != Some(c0) {
                        builder.move_to(c0.0 as f32, c0.1 as f32);
                    }
                    builder.line_to(c1.0 as f32, c1.1 as f32);
                    pen = Some(c1);
                    run_len += 1;
                } else {
                    pen = None;
                }
            }
            _ => pen = None,
        }
    }
    // Isolated points (between breaks) get a dot so a single sample stays visible.
    for (i, p) in points.iter().enumerate() {
        if let Some(p) = p {
            let before = i > 0 && points[i - 1].is_some();
            let after = points.get(i + 1).is_some_and(Option::is_some);
            if !before && !after && area.contains(p.0, p.1, 0.0) {
                single.push(*p);
            }
        }
    }
    let p = paint(color);
    if run_len > 0
        && let Some(path) = builder.finish()
    {
        pixmap.stroke_path(&path, &p, stroke_style, Transform::identity(), mask);
    }
    if !single.is_empty() {
        let mut dots = PathBuilder::new();
        for (x, y) in single {
            dots.push_circle(x as f32, y as f32, stroke_style.width.max(2.0) * 0.75);
        }
        if let Some(path) = dots.finish() {
            pixmap.fill_path(&path, &p, FillRule::Winding, Transform::identity(), mask);
        }
    }
}

/// Append one marker shape centred at `(x, y)` with half-size `r` to `builder`.
fn push_marker(builder: &mut PathBuilder, marker: Marker, x: f32, y: f32, r: f32) {
    match marker {
        Marker::None => {}
        Marker::Circle => builder.push_circle(x, y, r),
        Marker::Square => {
            if let Some(rect) = Rect::from_ltrb(x - r * 0.9, y - r * 0.9, x + r * 0.9, y + r * 0.9) {
                builder.push_rect(rect);
            }
        }
        Marker::Cross => {
            builder.move_to(x - r, y - r);
            builder.line_to(x + r, y + r);
            builder.move_to(x - r, y + r);
            builder.line_to(x + r, y - r);
        }
    }
}

/// Marker half-size in pixels for a series line width.
pub(crate) fn marker_radius(width_px: f32) -> f32 {
    let w = if width_px.is_finite() { width_px.clamp(0.5, 20.0) } else { 1.5 };
    (w * 1.6 + 1.6).max(3.0)
}

/// Draw `marker` at every visible point; markers on the same half-pixel are drawn once.
pub(crate) fn draw_markers(
    pixmap: &mut Pixmap,
    points: impl Iterator<Item = (f64, f64)>,
    area: Area,
    marker: Marker,
    color: Color,
    width_px: f32,
    mask: Option<&Mask>,
) {
    if marker == Marker::None {
        return;
    }
    let r = marker_radius(width_px);
    let mut seen = std::collections::HashSet::new();
    let mut builder = PathBuilder::new();
    for (x, y) in points {
        if !area.contains(x, y, f64::from(r)) {
            continue;
        }
        let key = ((x * 2.0).round() as i64, (y * 2.0).round() as i64);
        if seen.insert(key) {
            push_marker(
                &mut builder,
                marker,
                x.clamp(-FAR_PX, FAR_PX) as f32,
                y.clamp(-FAR_PX, FAR_PX) as f32,
                r,
            );
        }
    }
    fill_or_stroke_markers(pixmap, builder.finish(), marker, color, width_px, mask);
}

fn fill_or_stroke_markers(
    pixmap: &mut Pixmap,
    path: Option<Path>,
    marker: Marker,
    color: Color,
    width_px: f32,
    mask: Option<&Mask>,
) {
    let Some(path) = path else { return };
    let p = paint(color);
    if marker == Marker::Cross {
        pixmap.stroke_path(&path, &p, &stroke(width_px.max(1.5), false), Transform::identity(), mask);
    } else {
        pixmap.fill_path(&path, &p, FillRule::Winding, Transform::identity(), mask);
        // A thin white rim separates overlapping markers.
        let rim = paint(Color::rgba(255, 255, 255, 200));
        pixmap.stroke_path(&path, &rim, &stroke(0.7, false), Transform::identity(), mask);
    }
}

/// A single marker (legend samples).
pub(crate) fn draw_marker(pixmap: &mut Pixmap, marker: Marker, x: f32, y: f32, color: Color, width_px: f32) {
    let mut builder = PathBuilder::new();
    push_marker(&mut builder, marker, x, y, marker_radius(width_px));
    fill_or_stroke_markers(pixmap, builder.finish(), marker, color, width_px, None);
}

/// A straight line in pixels.
pub(crate) fn draw_line(pixmap: &mut Pixmap, from: (f32, f32), to: (f32, f32), color: Color, s: &Stroke) {
    let mut b = PathBuilder::new();
    b.move_to(from.0, from.1);
    b.line_to(to.0, to.1);
    if let Some(path) = b.finish() {
        pixmap.stroke_path(&path, &paint(color), s, Transform::identity(), None);
    }
}

/// A filled rectangle in pixels.
pub(crate) fn fill_rect(pixmap: &mut Pixmap, l: f32, t: f32, r: f32, b: f32, color: Color) {
    if let Some(rect) = Rect::from_ltrb(l, t, r, b) {
        pixmap.fill_rect(rect, &paint(color), Transform::identity(), None);
    }
}

/// A rectangle outline in pixels, on pixel centres so a 1 px line stays crisp.
pub(crate) fn stroke_rect(pixmap: &mut Pixmap, l: f32, t: f32, r: f32, b: f32, color: Color, width: f32) {
    if let Some(rect) = Rect::from_ltrb(l + 0.5, t + 0.5, r - 0.5, b - 0.5) {
        let path = PathBuilder::from_rect(rect);
        let s = Stroke { width, line_join: LineJoin::Miter, ..Stroke::default() };
        pixmap.stroke_path(&path, &paint(color), &s, Transform::identity(), None);
    }
}

/// Tick positions in pixels for an axis, keeping those inside the plot span.
pub(crate) fn tick_pixels(axis: &Axis, values: &[f64]) -> Vec<f32> {
    let (a, b) = (axis.px_lo.min(axis.px_hi) - 0.5, axis.px_lo.max(axis.px_hi) + 0.5);
    values.iter().filter_map(|v| axis.to_px(*v)).filter(|p| *p >= a && *p <= b).map(|p| p as f32).collect()
}

/// Widest label of a tick set, pixels.
pub(crate) fn widest_label(t: &Ticks) -> f32 {
    t.major.iter().map(|(_, l)| text_width(l, TICK_PX)).fold(0.0, f32::max)
}

/// X ticks that fit: fewer labels until neighbours are at least a gap apart.
pub(crate) fn fitting_x_ticks(axis: &Axis, width_px: f32) -> Ticks {
    let mut max_ticks = ((width_px / 70.0) as usize).clamp(2, 12);
    loop {
        let t = axis.ticks(max_ticks);
        let pixels = tick_pixels(axis, &t.major.iter().map(|(v, _)| *v).collect::<Vec<_>>());
        let min_gap = pixels.windows(2).map(|w| (w[1] - w[0]).abs()).fold(f32::INFINITY, f32::min);
        if max_ticks <= 2 || min_gap >= widest_label(&t) + 14.0 {
            return t;
        }
        max_ticks -= 1;
    }
}

/// Y ticks: about one label per 55 px.
pub(crate) fn fitting_y_ticks(axis: &Axis, height_px: f32) -> Ticks {
    axis.ticks(((height_px / 55.0) as usize).clamp(2, 10))
}

/// Grid, frame, tick marks and tick labels of a plot area.
pub(crate) fn draw_axes(pixmap: &mut Pixmap, area: Area, xa: &Axis, ya: &Axis, xt: &Ticks, yt: &Ticks) {
    let thin = stroke(1.0, false);
    let crisp = |p: f32| p.round() + 0.5;
    for v in tick_pixels(xa, &xt.minor) {
        draw_line(pixmap, (crisp(v), area.top), (crisp(v), area.bottom), GRID_MINOR, &thin);
    }
    for v in tick_pixels(ya, &yt.minor) {
        draw_line(pixmap, (area.left, crisp(v)), (area.right, crisp(v)), GRID_MINOR, &thin);
    }
    let xs: Vec<f64> = xt.major.iter().map(|(v, _)| *v).collect();
    let ys: Vec<f64> = yt.major.iter().map(|(v, _)| *v).collect();
    for v in tick_pixels(xa, &xs) {
        draw_line(pixmap, (crisp(v), area.top), (crisp(v), area.bottom), GRID, &thin);
    }
    for v in tick_pixels(ya, &ys) {
        draw_line(pixmap, (area.left, crisp(v)), (area.right, crisp(v)), GRID, &thin);
    }
}

/// Frame and tick marks/labels, drawn after the data so they stay on top.
pub(crate) fn draw_frame_and_labels(
    pixmap: &mut Pixmap,
    area: Area,
    xa: &Axis,
    ya: &Axis,
    xt: &Ticks,
    yt: &Ticks,
) {
    let thin = stroke(1.0, false);
    let crisp = |p: f32| p.round() + 0.5;
    for v in tick_pixels(xa, &xt.minor) {
        draw_line(pixmap, (crisp(v), area.bottom), (crisp(v), area.bottom + TICK_LEN * 0.6), INK, &thin);
    }
    for v in tick_pixels(ya, &yt.minor) {
        draw_line(pixmap, (area.left - TICK_LEN * 0.6, crisp(v)), (area.left, crisp(v)), INK, &thin);
    }
    let style = TextStyle::new(TICK_PX).color(INK);
    for (v, label) in &xt.major {
        if let Some(p) = tick_pixels(xa, &[*v]).first() {
            draw_line(pixmap, (crisp(*p), area.bottom), (crisp(*p), area.bottom + TICK_LEN), INK, &thin);
            let y = area.bottom + TICK_LEN + 4.0;
            draw_text(pixmap, label, *p, y, HAlign::Center, VAlign::Top, 0.0, style);
        }
    }
    for (v, label) in &yt.major {
        if let Some(p) = tick_pixels(ya, &[*v]).first() {
            draw_line(pixmap, (area.left - TICK_LEN, crisp(*p)), (area.left, crisp(*p)), INK, &thin);
            let x = area.left - TICK_LEN - 4.0;
            draw_text(pixmap, label, x, *p, HAlign::Right, VAlign::Middle, 0.0, style);
        }
    }
    stroke_rect(pixmap, area.left, area.top, area.right, area.bottom, INK, 1.0);
}

/// Panel title centred over `centre_x`, axis labels centred on the plot area.
pub(crate) fn draw_titles(
    pixmap: &mut Pixmap,
    area: Area,
    title: &str,
    x_label: &str,
    y_label: &str,
    y_label_x: f32,
    panel_width: f32,
) {
    if !title.is_empty() {
        let t = fit_text(title, TITLE_PX, panel_width - 16.0);
        let cx = f32::midpoint(area.left, area.right);
        let w = text_width(&t, TITLE_PX);
        let cx = cx.clamp(8.0 + w / 2.0, (panel_width - 8.0 - w / 2.0).max(8.0 + w / 2.0));
        draw_text(pixmap, &t, cx, 10.0, HAlign::Center, VAlign::Top, 0.0, TextStyle::new(TITLE_PX).bold());
    }
    let label_style = TextStyle::new(LABEL_PX).color(INK);
    if !x_label.is_empty() {
        let y = area.bottom + TICK_LEN + 4.0 + TICK_PX + 8.0;
        let t = fit_text(x_label, LABEL_PX, panel_width - 16.0);
        draw_text(
            pixmap,
            &t,
            f32::midpoint(area.left, area.right),
            y,
            HAlign::Center,
            VAlign::Top,
            0.0,
            label_style,
        );
    }
    if !y_label.is_empty() {
        let t = fit_text(y_label, LABEL_PX, area.height() + 40.0);
        let cy = f32::midpoint(area.top, area.bottom);
        draw_text(pixmap, &t, y_label_x, cy, HAlign::Center, VAlign::Top, -90.0, label_style);
    }
}

/// `text` shortened with an ellipsis to fit `max_width_px`.
pub(crate) fn fit_text(text: &str, size_px: f32, max_width_px: f32) -> String {
    if text_width(text, size_px) <= max_width_px {
        return text.to_string();
    }
    let mut chars: Vec<char> = text.chars().collect();
    while !chars.is_empty() {
        chars.pop();
        let candidate: String = chars.iter().collect::<String>() + "…";
        if text_width(&candidate, size_px) <= max_width_px {
            return candidate;
        }
    }
    String::new()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn axis(lo: f64, hi: f64, px_lo: f64, px_hi: f64) -> Axis {
        Axis { scale: Scale::Linear, lo, hi, px_lo, px_hi, integer: false }
    }

    #[test]
    fn decimation_keeps_each_columns_extremes() {
        // 10 columns of 1000 samples each; brute-force min/max per column must survive.
        let n = 10_000;
        let x: Vec<f64> = (0..n).map(|i| f64::from(i) / f64::from(n)).collect();
        let y: Vec<f64> = (0..n).map(|i| (f64::from(i) * 0.37).sin() * f64::from(i % 97)).collect();
        let xa = axis(0.0, 1.0, 0.0, 10.0);
        let ya = axis(-100.0, 100.0, 1000.0, 0.0);
        let points = pixel_points(&x, &y, &xa, &ya);
        assert!(points.len() <= 4 * 10 + 1, "{} points", points.len());
        for column in 0..10 {
            let (lo, hi) = (column * 1000, (column + 1) * 1000);
            let pixel_y = |v: f64| 1000.0 - (v + 100.0) * 5.0;
            let min_y = y[lo as usize..hi as usize].iter().copied().fold(f64::INFINITY, f64::min);
            let max_y = y[lo as usize..hi as usize].iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let kept: Vec<f64> = points
                .iter()
                .flatten()
                .filter(|p| p.0.floor() as i64 == i64::from(column))
                .map(|p| p.1)
                .collect();
            let kept_top = kept.iter().copied().fold(f64::INFINITY, f64::min);
            let kept_bottom = kept.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            assert_relative_eq!(kept_top, pixel_y(max_y), epsilon = 1e-9);
            assert_relative_eq!(kept_bottom, pixel_y(min_y), epsilon = 1e-9);
        }
    }

    #[test]
    fn nan_breaks_the_line() {
        let xa = axis(0.0, 4.0, 0.0, 400.0);
        let ya = axis(0.0, 1.0, 100.0, 0.0);
        let points = pixel_points(&[0.0, 1.0, 2.0, 3.0, 4.0], &[0.0, 1.0, f64::NAN, 1.0, 0.0], &xa, &ya);
        assert_eq!(points.iter().filter(|p| p.is_none()).count(), 1);
        assert_eq!(points.len(), 5);
    }

    #[test]
    fn segments_are_clipped_to_the_rectangle() {
        // The diagonal from (-10, -10) to (20, 20) clipped to [0, 10]^2 is (0, 0)-(10, 10).
        let (a, b) = clip_segment((-10.0, -10.0), (20.0, 20.0), (0.0, 0.0, 10.0, 10.0)).unwrap();
        assert_relative_eq!(a.0, 0.0);
        assert_relative_eq!(a.1, 0.0);
        assert_relative_eq!(b.0, 10.0);
        assert_relative_eq!(b.1, 10.0);
        assert!(clip_segment((-5.0, 20.0), (20.0, 15.0), (0.0, 0.0, 10.0, 10.0)).is_none());
    }

    #[test]
    fn x_tick_labels_never_overlap() {
        for (lo, hi, width) in
            [(0.0, 123_456.0, 200.0), (-1e-7, 3.3e-7, 150.0), (0.0, 0.35, 120.0), (1e3, 1e3 + 0.7, 300.0)]
        {
            let a = axis(lo, hi, 0.0, f64::from(width));
            let t = fitting_x_ticks(&a, width);
            let px = tick_pixels(&a, &t.major.iter().map(|(v, _)| *v).collect::<Vec<_>>());
            for (i, pair) in px.windows(2).enumerate() {
                let half =
                    f32::midpoint(text_width(&t.major[i].1, TICK_PX), text_width(&t.major[i + 1].1, TICK_PX));
                assert!(pair[1] - pair[0] > half, "{lo}..{hi} at {width}px: {:?}", t.major);
            }
        }
    }
}
