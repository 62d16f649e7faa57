//! Rendering of a [`Chart`] into a panel-sized pixmap: layout, ranges, data, legend.

use tiny_skia::{PathBuilder, Pixmap, Rect, Transform};

use crate::canvas::{
    self, Area, Axis, INK, LABEL_PX, LEGEND_PX, NOTE_PX, REF_LINE, TICK_LEN, TICK_PX, TITLE_PX, draw_axes,
    draw_frame_and_labels, draw_line, draw_marker, draw_markers, draw_polyline, draw_titles, fill_rect,
    fitting_x_ticks, fitting_y_ticks, pixel_points, stroke, widest_label,
};
use crate::chart::SeriesKind;
use crate::text::{HAlign, TextStyle, VAlign, draw_text, text_width};
use crate::ticks::{self, Ticks};
use crate::{Chart, Color, Marker, Scale};

/// Fraction of the data span added on each side of an automatic range.
const PAD_FRACTION: f64 = 0.04;

/// Everything the layout decided: plot area, axes and their ticks.
pub(crate) struct Layout {
    pub(crate) area: Area,
    pub(crate) x_axis: Axis,
    pub(crate) y_axis: Axis,
    pub(crate) x_ticks: Ticks,
    pub(crate) y_ticks: Ticks,
    /// Where the rotated y label's top edge sits.
    pub(crate) y_label_x: f32,
}

/// An optional (min, max) interval.
type Extent = Option<(f64, f64)>;

fn data_extents(chart: &Chart) -> (Extent, Extent) {
    let (xs, ys) = (chart.x_scale, chart.y_scale);
    let mut x = None;
    let mut y = None;
    for s in &chart.series {
        // Only points with both coordinates usable count, so a NaN y does not widen x.
        let n = s.x.len().min(s.y.len());
        let usable = |v: f64, scale: Scale| v.is_finite() && (scale == Scale::Linear || v > 0.0);
        let pairs = s.x[..n].iter().zip(&s.y[..n]).filter(|(a, b)| usable(**a, xs) && usable(**b, ys));
        let (px, py): (Vec<f64>, Vec<f64>) = pairs.map(|(a, b)| (*a, *b)).unzip();
        x = ticks::merge(x, ticks::extent(px, xs));
        y = ticks::merge(y, ticks::extent(py, ys));
    }
    for c in &chart.circles {
        if c.r.is_finite() {
            x = ticks::merge(x, ticks::extent([c.cx - c.r.abs(), c.cx + c.r.abs()], xs));
            y = ticks::merge(y, ticks::extent([c.cy - c.r.abs(), c.cy + c.r.abs()], ys));
        }
    }
    for a in &chart.annotations {
        x = ticks::merge(x, ticks::extent([a.x], xs));
        y = ticks::merge(y, ticks::extent([a.y], ys));
    }
    x = ticks::merge(x, ticks::extent(chart.vlines.iter().map(|l| l.value), xs));
    y = ticks::merge(y, ticks::extent(chart.hlines.iter().map(|l| l.value), ys));
    (x, y)
}

/// Widen one of the two linear ranges so one data unit spans the same pixels on both axes.
fn equalize(x: (f64, f64), y: (f64, f64), width_px: f64, height_px: f64) -> ((f64, f64), (f64, f64)) {
    let units_per_px = ((x.1 - x.0) / width_px).max((y.1 - y.0) / height_px);
    if !(units_per_px.is_finite() && units_per_px > 0.0) {
        return (x, y);
    }
    let widen = |(lo, hi): (f64, f64), px: f64| {
        let centre = lo / 2.0 + hi / 2.0;
        let half = units_per_px * px / 2.0;
        (centre - half, centre + half)
    };
    (widen(x, width_px), widen(y, height_px))
}

/// Decide the plot area, axis ranges and ticks for a `width` x `height` panel.
pub(crate) fn layout(chart: &Chart, width: f32, height: f32) -> Layout {
    layout_with_band(chart, width, height, 0.0)
}

/// [`layout`] with `band_px` kept free at the panel's bottom (for a legend below the plot).
fn layout_with_band(chart: &Chart, width: f32, height: f32, band_px: f32) -> Layout {
    let (x_data, y_data) = data_extents(chart);
    let any_scatter = chart.series.iter().any(|s| s.kind == SeriesKind::Scatter);
    let x_pad = if any_scatter || chart.equal_aspect || chart.series.is_empty() { PAD_FRACTION } else { 0.0 };
    let x_range = ticks::resolve_range(chart.x_range, x_data, chart.x_scale, x_pad);
    let y_range = ticks::resolve_range(chart.y_range, y_data, chart.y_scale, PAD_FRACTION * 1.25);

    let top = if chart.title.is_empty() { 14.0 } else { 10.0 + TITLE_PX + 14.0 };
    let x_label_h = if chart.x_label.is_empty() { 0.0 } else { 8.0 + LABEL_PX + 4.0 };
    let bottom_margin = TICK_LEN + 4.0 + TICK_PX + x_label_h + 12.0 + band_px;
    let y_label_w = if chart.y_label.is_empty() { 0.0 } else { LABEL_PX + 10.0 };
    let mut left = 60.0_f32;
    let mut right_margin = 20.0_f32;
    let equal = chart.equal_aspect && chart.x_scale == Scale::Linear && chart.y_scale == Scale::Linear;
    let mut result = None;
    for _ in 0..3 {
        let area = Area {
            left: left.round(),
            top: top.round(),
            right: (width - right_margin).round().max(left.round() + 10.0),
            bottom: (height - bottom_margin).round().max(top.round() + 10.0),
        };
        let (xr, yr) = if equal {
            equalize(x_range, y_range, f64::from(area.width()), f64::from(area.height()))
        } else {
            (x_range, y_range)
        };
        let x_axis = Axis {
            scale: chart.x_scale,
            lo: xr.0,
            hi: xr.1,
            px_lo: f64::from(area.left),
            px_hi: f64::from(area.right),
            integer: chart.x_integer,
        };
        let y_axis = Axis {
            scale: chart.y_scale,
            lo: yr.0,
            hi: yr.1,
            px_lo: f64::from(area.bottom),
            px_hi: f64::from(area.top),
            integer: false,
        };
        let y_ticks = fitting_y_ticks(&y_axis, area.height());
        let x_ticks = fitting_x_ticks(&x_axis, area.width());
        let new_left = 8.0 + y_label_w + widest_label(&y_ticks) + 4.0 + TICK_LEN + 2.0;
        let last_half = x_ticks.major.last().map_or(0.0, |(_, l)| text_width(l, TICK_PX) / 2.0);
        let new_right = (last_half + 6.0).max(20.0);
        let settled = (new_left - left).abs() < 1.0 && (new_right - right_margin).abs() < 1.0;
        let y_label_x = 8.0;
        result = Some(Layout { area, x_axis, y_axis, x_ticks, y_ticks, y_label_x });
        if settled {
            break;
        }
        left = new_left.min(width * 0.45);
        right_margin = new_right.min(width * 0.3);
    }
    // The loop runs at least once.
    result.unwrap_or_else(|| unreachable!())
}

/// The legend's entries: every series with a label, in order.
fn legend_entries(chart: &Chart) -> Vec<LegendEntry> {
    chart
        .series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.is_empty())
        .map(|(index, s)| LegendEntry {
            label: s.label.clone(),
            color: s.color.unwrap_or_else(|| Color::palette(index)),
            line: (s.kind == SeriesKind::Line).then_some((s.width_px, s.dashed)),
            marker: s.marker,
            width: s.width_px,
        })
        .collect()
}

/// Height of the legend band below the plot: the entries side by side, wrapped to `width`.
fn legend_band_px(entries: &[LegendEntry], width: f32) -> f32 {
    let row_h = LEGEND_PX + 7.0;
    let mut rows = 1.0;
    let mut x = 8.0;
    for e in entries {
        let w = BAND_SAMPLE_PX + 6.0 + text_width(&e.label, LEGEND_PX) + 16.0;
        if x + w > width - 8.0 && x > 8.0 {
            rows += 1.0;
            x = 8.0;
        }
        x += w;
    }
    rows * row_h + 6.0
}

const BAND_SAMPLE_PX: f32 = 26.0;

/// The layout, and where the legend goes: `None` for a corner of the plot area (the emptiest), or the
/// height of a band below the plot when every corner would cover data — the legend never hides data.
fn plan(chart: &Chart, width: f32, height: f32) -> (Layout, Option<f32>) {
    let l = layout(chart, width, height);
    let entries = legend_entries(chart);
    if entries.is_empty() {
        return (l, None);
    }
    let mut occupied = Occupancy::new(l.area);
    for s in &chart.series {
        occupied.mark(&pixel_points(&s.x, &s.y, &l.x_axis, &l.y_axis), s.kind == SeriesKind::Line);
    }
    let (box_w, box_h) = legend_box_size(l.area, &entries);
    if legend_corner(l.area, box_w, box_h, &occupied).1 == 0 {
        return (l, None);
    }
    let band = legend_band_px(&entries, width);
    (layout_with_band(chart, width, height, band), Some(band))
}

/// Draw the chart onto a panel pixmap (already white).
pub(crate) fn draw(chart: &Chart, pixmap: &mut Pixmap) {
    let (width, height) = (pixmap.width() as f32, pixmap.height() as f32);
    let (l, band) = plan(chart, width, height);
    let area = l.area;
    draw_axes(pixmap, area, &l.x_axis, &l.y_axis, &l.x_ticks, &l.y_ticks);
    let mask = canvas::clip_mask(pixmap, area);
    let mask = mask.as_ref();

    let legend = legend_entries(chart);
    let mut occupied = Occupancy::new(area);
    for (index, s) in chart.series.iter().enumerate() {
        let color = s.color.unwrap_or_else(|| Color::palette(index));
        let points = pixel_points(&s.x, &s.y, &l.x_axis, &l.y_axis);
        if s.kind == SeriesKind::Line {
            draw_polyline(pixmap, &points, area, color, &stroke(s.width_px, s.dashed), mask);
        }
        draw_markers(pixmap, points.iter().flatten().copied(), area, s.marker, color, s.width_px, mask);
        occupied.mark(&points, s.kind == SeriesKind::Line);
    }
    draw_reference_lines(chart, pixmap, &l, mask, &mut occupied);
    draw_circles(chart, pixmap, &l, mask, &mut occupied);
    let note = TextStyle::new(NOTE_PX).color(INK).halo(2.0);
    for a in &chart.annotations {
        if let (Some(x), Some(y)) = (l.x_axis.to_px(a.x), l.y_axis.to_px(a.y)) {
            let (x, y) = (x as f32, y as f32);
            if x >= area.left && x <= area.right && y >= area.top && y <= area.bottom {
                draw_text(pixmap, &a.text, x + 5.0, y - 3.0, HAlign::Left, VAlign::Bottom, 0.0, note);
            }
        }
    }
    draw_frame_and_labels(pixmap, area, &l.x_axis, &l.y_axis, &l.x_ticks, &l.y_ticks);
    match band {
        Some(band) => draw_legend_band(pixmap, height - band, width, &legend),
        None => draw_legend(pixmap, area, &legend, &occupied),
    }
    draw_titles(pixmap, area, &chart.title, &chart.x_label, &chart.y_label, l.y_label_x, width);
}

/// Reference lines with their labels; label boxes are marked in `occupied` so the legend avoids them.
fn draw_reference_lines(
    chart: &Chart,
    pixmap: &mut Pixmap,
    l: &Layout,
    mask: Option<&tiny_skia::Mask>,
    occupied: &mut Occupancy,
) {
    let area = l.area;
    let dashed = stroke(1.2, true);
    let note = TextStyle::new(NOTE_PX).color(REF_LINE).halo(2.0);
    for h in &chart.hlines {
        let Some(y) = l.y_axis.to_px(h.value) else { continue };
        let y = y as f32;
        if y < area.top - 0.5 || y > area.bottom + 0.5 {
            continue;
        }
        let y = y.round() + 0.5;
        let points =
            [Some((f64::from(area.left), f64::from(y))), Some((f64::from(area.right), f64::from(y)))];
        draw_polyline(pixmap, &points, area, REF_LINE, &dashed, mask);
        if !h.label.is_empty() {
            let (ty, valign) =
                if y - area.top > NOTE_PX + 6.0 { (y - 3.0, VAlign::Bottom) } else { (y + 4.0, VAlign::Top) };
            let w = draw_text(pixmap, &h.label, area.right - 5.0, ty, HAlign::Right, valign, 0.0, note);
            let (t, b) =
                if valign == VAlign::Bottom { (ty - NOTE_PX - 2.0, ty) } else { (ty, ty + NOTE_PX + 2.0) };
            occupied.mark_rect(area.right - 7.0 - w, t, area.right - 3.0, b);
        }
    }
    for v in &chart.vlines {
        let Some(x) = l.x_axis.to_px(v.value) else { continue };
        let x = x as f32;
        if x < area.left - 0.5 || x > area.right + 0.5 {
            continue;
        }
        let x = x.round() + 0.5;
        let points =
            [Some((f64::from(x), f64::from(area.top))), Some((f64::from(x), f64::from(area.bottom)))];
        draw_polyline(pixmap, &points, area, REF_LINE, &dashed, mask);
        if !v.label.is_empty() {
            let w = text_width(&v.label, NOTE_PX);
            let (tx, halign) = if x + 4.0 + w < area.right - 2.0 {
                (x + 4.0, HAlign::Left)
            } else {
                (x - 4.0, HAlign::Right)
            };
            draw_text(pixmap, &v.label, tx, area.top + 5.0, halign, VAlign::Top, 0.0, note);
            let (l0, r0) = if halign == HAlign::Left { (tx, tx + w) } else { (tx - w, tx) };
            occupied.mark_rect(l0 - 2.0, area.top + 3.0, r0 + 2.0, area.top + 7.0 + NOTE_PX);
        }
    }
}

/// Circles in data units with their labels; label boxes are marked in `occupied`.
fn draw_circles(
    chart: &Chart,
    pixmap: &mut Pixmap,
    l: &Layout,
    mask: Option<&tiny_skia::Mask>,
    occupied: &mut Occupancy,
) {
    let note = TextStyle::new(NOTE_PX).color(REF_LINE).halo(2.0);
    for c in &chart.circles {
        let r = c.r.abs();
        let corners = (
            l.x_axis.to_px(c.cx - r),
            l.x_axis.to_px(c.cx + r),
            l.y_axis.to_px(c.cy - r),
            l.y_axis.to_px(c.cy + r),
        );
        let (Some(x0), Some(x1), Some(y0), Some(y1)) = corners else { continue };
        let far = 1e6;
        let (x0, x1) = (x0.min(x1).max(-far) as f32, x0.max(x1).min(far) as f32);
        let (y0, y1) = (y0.min(y1).max(-far) as f32, y0.max(y1).min(far) as f32);
        let mut b = PathBuilder::new();
        if let Some(rect) = Rect::from_ltrb(x0, y0, x1.max(x0 + 0.5), y1.max(y0 + 0.5)) {
            b.push_oval(rect);
        }
        if let Some(path) = b.finish() {
            pixmap.stroke_path(
                &path,
                &canvas::paint(REF_LINE),
                &stroke(1.4, false),
                Transform::identity(),
                mask,
            );
        }
        if !c.label.is_empty() {
            let area = l.area;
            let w = text_width(&c.label, NOTE_PX);
            let (cx, cy) = (f32::midpoint(x0, x1), f32::midpoint(y0, y1));
            let (rx, ry) = ((x1 - x0) / 2.0, (y1 - y0) / 2.0);
            // Label boxes (left, top) tried in order: above the circle, at its upper right (45 degrees),
            // just inside its top; the first that fits in the plot area wins.
            let diagonal = (
                cx + rx * std::f32::consts::FRAC_1_SQRT_2 + 2.0,
                cy - ry * std::f32::consts::FRAC_1_SQRT_2 - NOTE_PX - 2.0,
            );
            let candidates = [(cx - w / 2.0, y0 - NOTE_PX - 4.0), diagonal, (cx - w / 2.0, y0 + 3.0)];
            let fits = |(bl, bt): &(f32, f32)| {
                *bl >= area.left + 2.0
                    && bl + w <= area.right - 2.0
                    && *bt >= area.top + 2.0
                    && bt + NOTE_PX <= area.bottom - 2.0
            };
            if let Some((bl, bt)) = candidates.iter().copied().find(fits) {
                draw_text(pixmap, &c.label, bl, bt, HAlign::Left, VAlign::Top, 0.0, note);
                occupied.mark_rect(bl - 2.0, bt - 2.0, bl + w + 2.0, bt + NOTE_PX + 2.0);
            }
        }
    }
}

struct LegendEntry {
    label: String,
    color: Color,
    /// Line sample (width, dashed), if the series is a line.
    line: Option<(f32, bool)>,
    marker: Marker,
    width: f32,
}

/// Coarse grid of plot-area cells touched by data, used to put the legend where it hides the least.
struct Occupancy {
    area: Area,
    columns: usize,
    rows: usize,
    cells: Vec<u32>,
}

const CELL_PX: f32 = 8.0;

impl Occupancy {
    fn new(area: Area) -> Self {
        let columns = (area.width() / CELL_PX).ceil().max(1.0) as usize;
        let rows = (area.height() / CELL_PX).ceil().max(1.0) as usize;
        Self { area, columns, rows, cells: vec![0; columns * rows] }
    }

    fn hit(&mut self, x: f64, y: f64) {
        let cx = (x - f64::from(self.area.left)) / f64::from(CELL_PX);
        let cy = (y - f64::from(self.area.top)) / f64::from(CELL_PX);
        if cx >= 0.0 && cy >= 0.0 && (cx as usize) < self.columns && (cy as usize) < self.rows {
            let i = cy as usize * self.columns + cx as usize;
            self.cells[i] = self.cells[i].saturating_add(1);
        }
    }

    fn mark_rect(&mut self, l: f32, t: f32, r: f32, b: f32) {
        let mut y = t;
        while y <= b {
            let mut x = l;
            while x <= r {
                self.hit(f64::from(x), f64::from(y));
                x += CELL_PX / 2.0;
            }
            y += CELL_PX / 2.0;
        }
    }

    fn mark(&mut self, points: &[Option<(f64, f64)>], joined: bool) {
        for p in points.iter().flatten() {
            self.hit(p.0, p.1);
        }
        if joined {
            for pair in points.windows(2) {
                if let (Some(a), Some(b)) = (pair[0], pair[1]) {
                    let length = (b.0 - a.0).hypot(b.1 - a.1);
                    let steps = (length / f64::from(CELL_PX) * 2.0).ceil().min(400.0) as usize;
                    for k in 1..steps {
                        let t = k as f64 / steps as f64;
                        self.hit(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
                    }
                }
            }
        }
    }

    /// Number of occupied cells inside a pixel rectangle.
    fn count(&self, l: f32, t: f32, r: f32, b: f32) -> u64 {
        let c0 = ((l - self.area.left) / CELL_PX).floor().max(0.0) as usize;
        let c1 = (((r - self.area.left) / CELL_PX).ceil().max(0.0) as usize).min(self.columns);
        let r0 = ((t - self.area.top) / CELL_PX).floor().max(0.0) as usize;
        let r1 = (((b - self.area.top) / CELL_PX).ceil().max(0.0) as usize).min(self.rows);
        let mut n = 0u64;
        for row in r0..r1 {
            for col in c0..c1 {
                n += u64::from(self.cells[row * self.columns + col].min(1));
            }
        }
        n
    }
}

const LEGEND_SAMPLE_PX: f32 = 30.0;
const LEGEND_PAD_PX: f32 = 8.0;

/// The legend labels as drawn in a corner box (long ones shortened to fit).
fn legend_labels(area: Area, entries: &[LegendEntry]) -> Vec<String> {
    let max_text = area.width() * 0.6 - LEGEND_SAMPLE_PX - 3.0 * LEGEND_PAD_PX;
    entries.iter().map(|e| canvas::fit_text(&e.label, LEGEND_PX, max_text)).collect()
}

/// Width and height of the corner legend box.
fn legend_box_size(area: Area, entries: &[LegendEntry]) -> (f32, f32) {
    let text_w = legend_labels(area, entries).iter().map(|l| text_width(l, LEGEND_PX)).fold(0.0, f32::max);
    let box_w = LEGEND_PAD_PX + LEGEND_SAMPLE_PX + 6.0 + text_w + LEGEND_PAD_PX;
    let box_h = LEGEND_PAD_PX * 0.75 * 2.0 + (LEGEND_PX + 7.0) * entries.len() as f32;
    (box_w, box_h)
}

/// The corner (left, top) of the plot area where a `box_w` x `box_h` legend covers the fewest occupied
/// cells, and that count.
fn legend_corner(area: Area, box_w: f32, box_h: f32, occupied: &Occupancy) -> ((f32, f32), u64) {
    let inset = 8.0;
    let candidates = [
        (area.right - inset - box_w, area.top + inset),
        (area.left + inset, area.top + inset),
        (area.right - inset - box_w, area.bottom - inset - box_h),
        (area.left + inset, area.bottom - inset - box_h),
    ];
    candidates
        .iter()
        .map(|&(l, t)| ((l, t), occupied.count(l, t, l + box_w, t + box_h)))
        .min_by_key(|(_, n)| *n)
        .unwrap_or((candidates[0], 0))
}

/// The legend in a band below the plot (`top` its upper edge): the entries side by side, wrapped.
fn draw_legend_band(pixmap: &mut Pixmap, top: f32, width: f32, entries: &[LegendEntry]) {
    let row_h = LEGEND_PX + 7.0;
    let style = TextStyle::new(LEGEND_PX).color(INK);
    let (mut x, mut cy) = (8.0, top + 3.0 + row_h / 2.0);
    for e in entries {
        let w = BAND_SAMPLE_PX + 6.0 + text_width(&e.label, LEGEND_PX) + 16.0;
        if x + w > width - 8.0 && x > 8.0 {
            x = 8.0;
            cy += row_h;
        }
        let (x0, x1) = (x, x + BAND_SAMPLE_PX);
        if let Some((line_w, dashed)) = e.line {
            draw_line(pixmap, (x0, cy), (x1, cy), e.color, &stroke(line_w.min(4.0), dashed));
        }
        if e.marker != Marker::None {
            draw_marker(pixmap, e.marker, f32::midpoint(x0, x1), cy, e.color, e.width.min(3.0));
        }
        draw_text(pixmap, &e.label, x1 + 6.0, cy, HAlign::Left, VAlign::Middle, 0.0, style);
        x += w;
    }
}

fn draw_legend(pixmap: &mut Pixmap, area: Area, entries: &[LegendEntry], occupied: &Occupancy) {
    if entries.is_empty() {
        return;
    }
    let row_h = LEGEND_PX + 7.0;
    let sample_w = LEGEND_SAMPLE_PX;
    let pad = LEGEND_PAD_PX;
    let labels = legend_labels(area, entries);
    let (box_w, box_h) = legend_box_size(area, entries);
    let ((l, t), _) = legend_corner(area, box_w, box_h, occupied);
    fill_rect(pixmap, l, t, l + box_w, t + box_h, Color::rgba(255, 255, 255, 225));
    canvas::stroke_rect(
        pixmap,
        l.round(),
        t.round(),
        (l + box_w).round(),
        (t + box_h).round(),
        Color::rgb(190, 190, 190),
        1.0,
    );
    let style = TextStyle::new(LEGEND_PX).color(INK);
    for (i, (entry, label)) in entries.iter().zip(&labels).enumerate() {
        let cy = t + pad * 0.75 + row_h * (i as f32 + 0.5);
        let (x0, x1) = (l + pad, l + pad + sample_w);
        if let Some((width, dashed)) = entry.line {
            draw_line(pixmap, (x0, cy), (x1, cy), entry.color, &stroke(width.min(4.0), dashed));
        }
        if entry.marker != Marker::None {
            draw_marker(pixmap, entry.marker, f32::midpoint(x0, x1), cy, entry.color, entry.width.min(3.0));
        }
        draw_text(pixmap, label, x1 + 6.0, cy, HAlign::Left, VAlign::Middle, 0.0, style);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Series;

    /// A legend never hides data: with every corner of the plot covered, it moves to a band below the
    /// plot area (and the x label); with a free corner, it stays there.
    #[test]
    fn the_legend_goes_where_there_is_no_data() {
        let grid: Vec<(f64, f64)> =
            (0..=40).flat_map(|i| (0..=40).map(move |j| (f64::from(i), f64::from(j)))).collect();
        let full = Chart::new("full").x_label("x [m]").series(Series::scatter(
            "everywhere",
            grid.iter().map(|p| p.0).collect(),
            grid.iter().map(|p| p.1).collect(),
        ));
        let (l, band) = plan(&full, 600.0, 400.0);
        let band = band.expect("every corner is covered: the legend goes below");
        let x_label_bottom = l.area.bottom + TICK_LEN + 4.0 + TICK_PX + 8.0 + LABEL_PX + 4.0;
        assert!(x_label_bottom <= 400.0 - band, "the band {band} px is below the x label ({x_label_bottom})");
        let diagonal = Chart::new("sparse").series(Series::line("rising", vec![0.0, 1.0], vec![0.0, 1.0]));
        let (_, band) = plan(&diagonal, 600.0, 400.0);
        assert_eq!(band, None, "the upper left corner is free");
    }
}
