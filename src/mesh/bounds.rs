//! Axis-aligned bounding boxes of point sets (2D material space or 3D).

use glam::{DVec2, DVec3};

/// A point type with componentwise min and max.
pub trait BoxPoint: Copy {
    const EMPTY_LO: Self;
    const EMPTY_HI: Self;
    fn lower(self, other: Self) -> Self;
    fn upper(self, other: Self) -> Self;
}

impl BoxPoint for DVec2 {
    const EMPTY_LO: Self = DVec2::INFINITY;
    const EMPTY_HI: Self = DVec2::NEG_INFINITY;
    fn lower(self, other: Self) -> Self {
        self.min(other)
    }
    fn upper(self, other: Self) -> Self {
        self.max(other)
    }
}

impl BoxPoint for DVec3 {
    const EMPTY_LO: Self = DVec3::INFINITY;
    const EMPTY_HI: Self = DVec3::NEG_INFINITY;
    fn lower(self, other: Self) -> Self {
        self.min(other)
    }
    fn upper(self, other: Self) -> Self {
        self.max(other)
    }
}

/// The (lowest, highest) corners of the points; (+inf, -inf) when there are none.
pub fn bounds<'a, P: BoxPoint + 'a>(points: impl IntoIterator<Item = &'a P>) -> (P, P) {
    points.into_iter().fold((P::EMPTY_LO, P::EMPTY_HI), |(lo, hi), p| (lo.lower(*p), hi.upper(*p)))
}

/// The length of the bounding box's diagonal.
pub fn diagonal(points: &[DVec3]) -> f64 {
    let (lo, hi) = bounds(points);
    (hi - lo).length()
}
