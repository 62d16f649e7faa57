//! Text as filled glyph outlines from fonts embedded in the binary (no system fonts).
//!
//! Glyphs come from egui's bundled Ubuntu Light, with Hack as fallback for characters Ubuntu lacks. The
//! outlines are converted to tiny-skia paths, so text can be rotated and antialiased like any other shape.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, GlyphId, OutlineCurve};
use tiny_skia::{FillRule, LineCap, LineJoin, Paint, Path, PathBuilder, Pixmap, Stroke, Transform};

use crate::Color;

struct Fonts {
    main: FontRef<'static>,
    fallback: FontRef<'static>,
}

fn fonts() -> Option<&'static Fonts> {
    static FONTS: OnceLock<Option<Fonts>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            let main = FontRef::try_from_slice(epaint_default_fonts::UBUNTU_LIGHT).ok()?;
            let fallback = FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).ok()?;
            Some(Fonts { main, fallback })
        })
        .as_ref()
}

/// Horizontal anchor of a text run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HAlign {
    Left,
    Center,
    Right,
}

/// Vertical anchor of a text run (approximate cap-height box; descenders hang below `Bottom`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum VAlign {
    Top,
    Middle,
    Bottom,
}

/// How a text run is drawn.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TextStyle {
    pub(crate) size_px: f32,
    pub(crate) color: Color,
    /// Extra stroke around the glyphs to make the light face heavier (0 = the font's own weight).
    pub(crate) embolden_px: f32,
    /// White outline of this width behind the text, to stay readable over data (0 = none).
    pub(crate) halo_px: f32,
}

impl TextStyle {
    pub(crate) fn new(size_px: f32) -> Self {
        Self { size_px, color: Color::rgb(20, 20, 20), embolden_px: 0.45, halo_px: 0.0 }
    }

    pub(crate) fn color(mut self, color: Color) -> Self {
        self.color = color;
        self
    }

    pub(crate) fn bold(mut self) -> Self {
        self.embolden_px = 0.9;
        self
    }

    pub(crate) fn halo(mut self, halo_px: f32) -> Self {
        self.halo_px = halo_px;
        self
    }
}

/// A laid-out line of text: the glyph outlines at the origin (baseline y = 0, starting at x = 0).
struct Run {
    path: Option<Path>,
    width_px: f32,
}

fn layout(text: &str, size_px: f32) -> Run {
    let Some(fonts) = fonts() else {
        return Run { path: None, width_px: 0.0 };
    };
    let mut builder = PathBuilder::new();
    let mut pen_x = 0.0_f32;
    let mut previous: Option<(bool, GlyphId)> = None;
    for c in text.chars() {
        let c = if c.is_control() { ' ' } else { c };
        let main_id = fonts.main.glyph_id(c);
        let (is_main, font, id) = if main_id.0 != 0 || fonts.fallback.glyph_id(c).0 == 0 {
            (true, &fonts.main, main_id)
        } else {
            (false, &fonts.fallback, fonts.fallback.glyph_id(c))
        };
        let scale = size_px / font.units_per_em().unwrap_or(1000.0);
        if let Some((prev_main, prev_id)) = previous
            && prev_main == is_main
        {
            pen_x += font.kern_unscaled(prev_id, id) * scale;
        }
        if let Some(outline) = font.outline(id) {
            append_outline(&mut builder, &outline.curves, pen_x, scale);
        }
        pen_x += font.h_advance_unscaled(id) * scale;
        previous = Some((is_main, id));
    }
    Run { path: builder.finish(), width_px: pen_x }
}

/// Append glyph curves (font units, y up) to `builder` in pixels (y down) at `pen_x`.
fn append_outline(builder: &mut PathBuilder, curves: &[OutlineCurve], pen_x: f32, scale: f32) {
    let map = |p: ab_glyph::Point| (pen_x + p.x * scale, -p.y * scale);
    let mut last: Option<ab_glyph::Point> = None;
    for curve in curves {
        let start = match curve {
            OutlineCurve::Line(p0, _) | OutlineCurve::Quad(p0, _, _) | OutlineCurve::Cubic(p0, _, _, _) => {
                *p0
            }
        };
        if last != Some(start) {
            if last.is_some() {
                builder.close();
            }
            let (x, y) = map(start);
            builder.move_to(x, y);
        }
        let end = match curve {
            OutlineCurve::Line(_, p1) => {
                let (x, y) = map(*p1);
                builder.line_to(x, y);
                *p1
            }
            OutlineCurve::Quad(_, p1, p2) => {
                let ((x1, y1), (x, y)) = (map(*p1), map(*p2));
                builder.quad_to(x1, y1, x, y);
                *p2
            }
            OutlineCurve::Cubic(_, p1, p2, p3) => {
                let ((x1, y1), (x2, y2), (x, y)) = (map(*p1), map(*p2), map(*p3));
                builder.cubic_to(x1, y1, x2, y2, x, y);
                *p3
            }
        };
        last = Some(end);
    }
    if last.is_some() {
        builder.close();
    }
}

/// Width of `text` in pixels at `size_px`.
pub(crate) fn text_width(text: &str, size_px: f32) -> f32 {
    layout(text, size_px).width_px
}

/// Offset from the anchor to the baseline for a vertical alignment, as a fraction of the font size.
fn baseline_offset(valign: VAlign, size_px: f32) -> f32 {
    match valign {
        VAlign::Top => 0.72 * size_px,
        VAlign::Middle => 0.36 * size_px,
        VAlign::Bottom => -0.22 * size_px,
    }
}

/// Draw one line of `text` anchored at `(x, y)`, rotated by `angle_deg` about the anchor (-90 = reading
/// bottom to top). Returns the width of the text in pixels.
#[allow(clippy::too_many_arguments)] // a text draw call is naturally this wide; a struct would only rename it
pub(crate) fn draw_text(
    pixmap: &mut Pixmap,
    text: &str,
    x: f32,
    y: f32,
    halign: HAlign,
    valign: VAlign,
    angle_deg: f32,
    style: TextStyle,
) -> f32 {
    let run = layout(text, style.size_px);
    let Some(path) = run.path else {
        return run.width_px;
    };
    if !(x.is_finite() && y.is_finite()) {
        return run.width_px;
    }
    let dx = match halign {
        HAlign::Left => 0.0,
        HAlign::Center => -0.5 * run.width_px,
        HAlign::Right => -run.width_px,
    };
    let dy = baseline_offset(valign, style.size_px);
    let transform = if angle_deg == 0.0 {
        // Snap the baseline and start to whole pixels so horizontal stems stay crisp.
        Transform::from_translate((x + dx).round(), (y + dy).round())
    } else {
        Transform::from_translate(x, y).pre_rotate(angle_deg).pre_translate(dx, dy)
    };
    let mut paint = Paint { anti_alias: true, ..Paint::default() };
    let stroke = |width: f32| Stroke {
        width,
        line_join: LineJoin::Round,
        line_cap: LineCap::Round,
        ..Stroke::default()
    };
    if style.halo_px > 0.0 {
        paint.set_color(tiny_skia::Color::from_rgba8(255, 255, 255, 230));
        pixmap.stroke_path(&path, &paint, &stroke(style.halo_px * 2.0 + style.embolden_px), transform, None);
    }
    paint.set_color(style.color.to_skia());
    pixmap.fill_path(&path, &paint, FillRule::Winding, transform, None);
    if style.embolden_px > 0.0 {
        pixmap.stroke_path(&path, &paint, &stroke(style.embolden_px), transform, None);
    }
    run.width_px
}

/// Width of a map label (see [`draw_label`]) in pixels.
pub fn label_width(text: &str, size_px: f32) -> f32 {
    text_width(text, size_px)
}

/// Draws `text` as a map label: centred on `(x, y)`, in `color`, on a white halo of `halo_px` so it reads over
/// any ground. Returns its width in pixels. Used by the offline map renderer (vestnav-osm) for street and
/// place names, so the map and the figures share one text path.
pub fn draw_label(
    pixmap: &mut Pixmap,
    text: &str,
    x: f32,
    y: f32,
    size_px: f32,
    color: Color,
    halo_px: f32,
) -> f32 {
    let style = TextStyle::new(size_px).color(color).halo(halo_px);
    draw_text(pixmap, text, x, y, HAlign::Center, VAlign::Middle, 0.0, style)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_fonts_parse_and_text_has_width() {
        assert!(fonts().is_some());
        let w = text_width("time [s]", 14.0);
        assert!(w > 30.0 && w < 90.0, "width {w}");
        assert!(text_width("", 14.0).abs() < f32::EPSILON);
        // Doubling the size doubles the width.
        let ratio = text_width("Hello", 28.0) / text_width("Hello", 14.0);
        assert!((ratio - 2.0).abs() < 1e-3);
    }

    #[test]
    fn missing_glyphs_fall_back_and_control_chars_do_not_panic() {
        assert!(text_width("θ ω µ ² ° →", 14.0) > 20.0);
        assert!(text_width("a\u{0}\tb\n", 14.0) > 0.0);
    }
}
