//! A perceptually uniform, colour-blind-safe sequential colormap (viridis-like).

use crate::Color;

/// Ten anchor colours of matplotlib's viridis at 0, 1/9, ..., 1 (the colour values are facts about
/// viridis; the table and interpolation here are ours).
const ANCHORS: [(u8, u8, u8); 10] = [
    (0x44, 0x01, 0x54),
    (0x48, 0x28, 0x78),
    (0x3e, 0x4a, 0x89),
    (0x31, 0x68, 0x8e),
    (0x26, 0x82, 0x8e),
    (0x1f, 0x9e, 0x89),
    (0x35, 0xb7, 0x79),
    (0x6d, 0xcd, 0x59),
    (0xb4, 0xde, 0x2c),
    (0xfd, 0xe7, 0x25),
];

/// Colour of `t` in 0..=1 (clamped), linear interpolation between the anchors; NaN gives light grey.
pub fn viridis(t: f64) -> Color {
    if t.is_nan() {
        return Color::rgb(230, 230, 230);
    }
    let position = t.clamp(0.0, 1.0) * (ANCHORS.len() - 1) as f64;
    let i = (position.floor() as usize).min(ANCHORS.len() - 2);
    let f = position - i as f64;
    let mix =
        |a: u8, b: u8| (f64::from(a) + (f64::from(b) - f64::from(a)) * f).round().clamp(0.0, 255.0) as u8;
    let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
    Color::rgb(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_clamping() {
        assert_eq!(viridis(0.0), Color::rgb(0x44, 0x01, 0x54));
        assert_eq!(viridis(1.0), Color::rgb(0xfd, 0xe7, 0x25));
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::INFINITY), viridis(1.0));
        assert_eq!(viridis(f64::NAN), Color::rgb(230, 230, 230));
    }

    #[test]
    fn lightness_increases_monotonically() {
        // Viridis is designed so perceived lightness rises from end to end; check a luma proxy.
        let luma = |c: Color| 0.299 * f64::from(c.r) + 0.587 * f64::from(c.g) + 0.114 * f64::from(c.b);
        let values: Vec<f64> = (0..=100).map(|i| luma(viridis(f64::from(i) / 100.0))).collect();
        assert!(values.windows(2).all(|w| w[1] >= w[0] - 0.5), "{values:?}");
    }
}
