//! Maps painted over a layer's material rectangle (H15 4.3 "painted weights").

use glam::DVec2;

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
        let span = (self.hi - self.lo).max(DVec2::splat(f64::MIN_POSITIVE));
        let t = ((uv - self.lo) / span).clamp(DVec2::ZERO, DVec2::ONE);
        let fx = t.x * (self.width - 1) as f64;
        let fy = (1.0 - t.y) * (self.height - 1) as f64;
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (ax, ay) = (fx - x0 as f64, fy - y0 as f64);
        let at = |x: usize, y: usize| self.values[y * self.width + x] as f64;
        let top = at(x0, y0) * (1.0 - ax) + at(x1, y0) * ax;
        let bottom = at(x0, y1) * (1.0 - ax) + at(x1, y1) * ax;
        top * (1.0 - ay) + bottom * ay
    }
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
}
