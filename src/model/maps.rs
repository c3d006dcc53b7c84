//! Maps painted over a layer's material rectangle: greyscale weights (H15 4.3 "painted
//! weights") and RGB property maps (LK14 5.2).

use bevy_ecs::prelude::*;
use glam::{DVec2, DVec3};

/// Bilinear interpolation over a width x height raster stretched over [lo, hi]; row 0 is the top
/// edge (max y), as an image viewer shows it. `at(x, y)` reads a pixel.
fn bilinear<T>(width: usize, height: usize, lo: DVec2, hi: DVec2, uv: DVec2, at: impl Fn(usize, usize) -> T) -> T
where
    T: std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T>,
{
    let span = (hi - lo).max(DVec2::splat(f64::MIN_POSITIVE));
    let t = ((uv - lo) / span).clamp(DVec2::ZERO, DVec2::ONE);
    let fx = t.x * (width - 1) as f64;
    let fy = (1.0 - t.y) * (height - 1) as f64;
    let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (ax, ay) = (fx - x0 as f64, fy - y0 as f64);
    let top = at(x0, y0) * (1.0 - ax) + at(x1, y0) * ax;
    let bottom = at(x0, y1) * (1.0 - ax) + at(x1, y1) * ax;
    top * (1.0 - ay) + bottom * ay
}

/// A greyscale map in [0, 1] stretched over the material rectangle [lo, hi]; row 0 of the image
/// is the top edge (max y), as an image viewer shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightMap {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
    pub lo: DVec2,
    pub hi: DVec2,
}

impl WeightMap {
    /// Bilinear sample at a material position (clamped to the rectangle).
    pub fn sample(&self, uv: DVec2) -> f64 {
        bilinear(self.width, self.height, self.lo, self.hi, uv, |x, y| self.values[y * self.width + x] as f64)
    }
}

/// An RGB map in [0, 1]^3 stretched over the material rectangle [lo, hi], row 0 at max y.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbMap {
    pub width: usize,
    pub height: usize,
    pub values: Vec<[f32; 3]>,
    pub lo: DVec2,
    pub hi: DVec2,
}

impl RgbMap {
    /// Bilinear sample (r, g, b) at a material position (clamped to the rectangle).
    pub fn sample(&self, uv: DVec2) -> DVec3 {
        bilinear(self.width, self.height, self.lo, self.hi, uv, |x, y| {
            DVec3::from_array(self.values[y * self.width + x].map(f64::from))
        })
    }
}

/// How one channel of a property map scales the reference value: factor = lo + (hi - lo) c.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelMap {
    pub lo: f64,
    pub hi: f64,
}

impl ChannelMap {
    pub fn factor(&self, c: f64) -> f64 {
        self.lo + (self.hi - self.lo) * c
    }
}

/// A layer's property map (LK14 5.2): red scales the critical wavelength of the couplings
/// above it, green the Young's modulus, blue the thickness; a channel without a mapping is
/// ignored (factor 1). Kept on the layer so that new elements (remeshing) can be sampled.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct LayerProperties {
    pub map: RgbMap,
    pub wavelength: Option<ChannelMap>,
    pub young: Option<ChannelMap>,
    pub thickness: Option<ChannelMap>,
}

/// The three factors at one material position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PropertyFactors {
    pub wavelength: f64,
    pub young: f64,
    pub thickness: f64,
}

impl PropertyFactors {
    pub const ONE: PropertyFactors = PropertyFactors { wavelength: 1.0, young: 1.0, thickness: 1.0 };

    /// The bending stiffness factor, E h^3.
    pub fn bending(&self) -> f64 {
        self.young * self.thickness.powi(3)
    }
}

impl LayerProperties {
    pub fn at(&self, uv: DVec2) -> PropertyFactors {
        let c = self.map.sample(uv);
        let f = |m: Option<ChannelMap>, v: f64| m.map_or(1.0, |m| m.factor(v));
        PropertyFactors {
            wavelength: f(self.wavelength, c.x),
            young: f(self.young, c.y),
            thickness: f(self.thickness, c.z),
        }
    }
}

/// The factors of an optional map (all 1 without one).
pub fn factors_at(p: Option<&LayerProperties>, uv: DVec2) -> PropertyFactors {
    p.map_or(PropertyFactors::ONE, |p| p.at(uv))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_corners_and_interpolates() {
        // 2x2: top row (max y) 0, 1; bottom row 0.5, 0.5.
        let m = WeightMap {
            width: 2,
            height: 2,
            values: vec![0.0, 1.0, 0.5, 0.5],
            lo: DVec2::ZERO,
            hi: DVec2::new(2.0, 1.0),
        };
        assert_eq!(m.sample(DVec2::new(0.0, 1.0)), 0.0);
        assert_eq!(m.sample(DVec2::new(2.0, 1.0)), 1.0);
        assert_eq!(m.sample(DVec2::new(0.0, 0.0)), 0.5);
        assert_eq!(m.sample(DVec2::new(1.0, 1.0)), 0.5);
        assert_eq!(m.sample(DVec2::new(9.0, -9.0)), 0.5, "clamped");
    }

    #[test]
    fn property_channels_map_to_factors() {
        // 2x1: left pixel black, right pixel white.
        let map =
            RgbMap { width: 2, height: 1, values: vec![[0.0; 3], [1.0; 3]], lo: DVec2::ZERO, hi: DVec2::new(1.0, 1.0) };
        let p = LayerProperties {
            map,
            wavelength: None,
            young: Some(ChannelMap { lo: 1.0, hi: 64.0 }),
            thickness: Some(ChannelMap { lo: 0.25, hi: 1.0 }),
        };
        let left = p.at(DVec2::new(0.0, 0.5));
        assert_eq!((left.wavelength, left.young, left.thickness), (1.0, 1.0, 0.25));
        let mid = p.at(DVec2::new(0.5, 0.5));
        assert_eq!((mid.young, mid.thickness), (32.5, 0.625));
        assert_eq!(mid.bending(), 32.5 * 0.625f64.powi(3));
    }
}
