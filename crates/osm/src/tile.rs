//! Web Mercator tile maths (the "slippy map" scheme of OpenStreetMap, EPSG:3857): zoom `z` splits the
//! world into `2^z x 2^z` tiles of 256 px, x growing east from 180° W and y growing south from 85.05° N.

use vestnav_core::geo::{DVec2, LatLon};

/// Side of a tile [px].
pub const TILE_SIZE: u32 = 256;

/// Highest zoom a [`TileId`] accepts (a tile is then under 1 cm wide).
pub const MAX_ZOOM: u8 = 24;

/// The latitude where Web Mercator's square world ends: `atan(sinh(pi))` [deg].
pub const MAX_MERCATOR_LAT_DEG: f64 = 85.051_128_779_806_59;

/// A position in the unit Web Mercator square: x in [0, 1] east from 180° W, y in [0, 1] south from the
/// top: `x = (lon + 180) / 360`, `y = (1 - ln(tan(lat) + sec(lat)) / pi) / 2` (latitudes clamped to
/// ±[`MAX_MERCATOR_LAT_DEG`]).
pub fn mercator_from_wgs84(p: LatLon) -> DVec2 {
    let lat = p.lat_deg.clamp(-MAX_MERCATOR_LAT_DEG, MAX_MERCATOR_LAT_DEG).to_radians();
    let x = (p.lon_deg + 180.0) / 360.0;
    let y = (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / std::f64::consts::PI) / 2.0;
    DVec2::new(x, y)
}

/// The inverse of [`mercator_from_wgs84`]: `lat = atan(sinh(pi (1 - 2 y)))`, `lon = 360 x - 180`.
pub fn wgs84_from_mercator(m: DVec2) -> LatLon {
    let lat = (std::f64::consts::PI * (1.0 - 2.0 * m.y)).sinh().atan().to_degrees();
    LatLon::new(lat, m.x * 360.0 - 180.0)
}

/// One tile of the scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TileId {
    /// Zoom level.
    pub z: u8,
    /// Column, 0 at 180° W.
    pub x: u32,
    /// Row, 0 at the top.
    pub y: u32,
}

impl TileId {
    /// A tile, or `None` when `z` exceeds [`MAX_ZOOM`] or `x`/`y` are outside `0..2^z`.
    pub fn new(z: u8, x: u32, y: u32) -> Option<Self> {
        if z > MAX_ZOOM {
            return None;
        }
        let n = 1u64 << z;
        (u64::from(x) < n && u64::from(y) < n).then_some(Self { z, x, y })
    }

    /// The tile holding `p` at zoom `z` (`None` for a zoom above [`MAX_ZOOM`] or a non-finite point).
    pub fn containing(p: LatLon, z: u8) -> Option<Self> {
        if z > MAX_ZOOM || !p.lat_deg.is_finite() || !p.lon_deg.is_finite() {
            return None;
        }
        let n = f64::from(1u32 << z);
        let m = mercator_from_wgs84(p);
        let max = (1u64 << z) - 1;
        let x = ((m.x * n).floor().max(0.0) as u64).min(max);
        let y = ((m.y * n).floor().max(0.0) as u64).min(max);
        Self::new(z, u32::try_from(x).ok()?, u32::try_from(y).ok()?)
    }

    /// Tiles per side of the world at this zoom, as a float.
    pub fn scale(self) -> f64 {
        f64::from(1u32 << self.z)
    }

    /// Where `p` falls in this tile [px] from its top-left corner (outside `0..256` when not in it).
    pub fn pixel_of(self, p: LatLon) -> DVec2 {
        self.pixel_of_mercator(mercator_from_wgs84(p))
    }

    /// Where a unit-Mercator position falls in this tile [px].
    pub fn pixel_of_mercator(self, m: DVec2) -> DVec2 {
        let s = self.scale() * f64::from(TILE_SIZE);
        DVec2::new(
            m.x * s - f64::from(self.x) * f64::from(TILE_SIZE),
            m.y * s - f64::from(self.y) * f64::from(TILE_SIZE),
        )
    }

    /// The tile's extent in unit Mercator: (top-left, bottom-right).
    pub fn mercator_bounds(self) -> (DVec2, DVec2) {
        let s = self.scale();
        (
            DVec2::new(f64::from(self.x) / s, f64::from(self.y) / s),
            DVec2::new(f64::from(self.x + 1) / s, f64::from(self.y + 1) / s),
        )
    }

    /// Ground size of one pixel at the tile's centre [m]: `40 075 016.686 cos(lat) / (256 2^z)` (the
    /// equatorial circumference of WGS-84 spread over the world's pixels, shrunk by Mercator's scale).
    pub fn metres_per_pixel(self) -> f64 {
        let (a, b) = self.mercator_bounds();
        let centre = wgs84_from_mercator((a + b) / 2.0);
        40_075_016.686 * centre.lat_deg.to_radians().cos() / (self.scale() * f64::from(TILE_SIZE))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_follow_the_web_mercator_formula() {
        // Munich, lat 48.1372, lon 11.5755, at zoom 16: x = 34875.26, y = 22743.88 from the same formula
        // written independently as python's `(1 - asinh(tan(lat)) / pi) / 2 * 2**z`; 0/0/0 is the world.
        let munich = LatLon::new(48.1372, 11.5755);
        assert_eq!(TileId::containing(munich, 16), TileId::new(16, 34875, 22743));
        // Zoom 1 splits the world into quadrants at the equator and the prime meridian.
        assert_eq!(TileId::containing(LatLon::new(45.0, -90.0), 1), TileId::new(1, 0, 0));
        assert_eq!(TileId::containing(LatLon::new(-45.0, 90.0), 1), TileId::new(1, 1, 1));
        assert_eq!(TileId::containing(munich, 0), TileId::new(0, 0, 0));
        assert_eq!(TileId::new(3, 8, 0), None);
        assert_eq!(TileId::new(25, 0, 0), None);
        // The tile's north-west corner maps back to its own pixel (0, 0).
        let t = TileId { z: 15, x: 18_652, y: 9_483 };
        let (nw, _) = t.mercator_bounds();
        let px = t.pixel_of(wgs84_from_mercator(nw));
        assert!(px.x.abs() < 1e-6 && px.y.abs() < 1e-6, "{px:?}");
        // Top of the square world.
        let top = wgs84_from_mercator(DVec2::new(0.5, 0.0));
        assert!((top.lat_deg - MAX_MERCATOR_LAT_DEG).abs() < 1e-9);
    }
}
