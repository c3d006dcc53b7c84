//! Prescribed motions of a patch (ARCHITECTURE.md 2, BlendShapeUpdate): keyframed compression
//! and cylinder bending, evaluated as maps of the rest position.

use bevy_ecs::prelude::*;
use glam::DVec3;

/// Piecewise-linear keyframes (frame, value); held constant outside their range.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes(pub Vec<(u32, f64)>);

impl Keyframes {
    pub fn at(&self, frame: f64) -> f64 {
        let k = &self.0;
        if k.is_empty() {
            return 0.0;
        }
        if frame <= k[0].0 as f64 {
            return k[0].1;
        }
        for w in k.windows(2) {
            let (f0, v0) = (w[0].0 as f64, w[0].1);
            let (f1, v1) = (w[1].0 as f64, w[1].1);
            if frame <= f1 {
                return v0 + (v1 - v0) * (frame - f0) / (f1 - f0);
            }
        }
        k[k.len() - 1].1
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum MotionKind {
    /// Uniform compression along `axis`: x_a = c_a + (1 - strain) (X_a - c_a).
    Compress { axis: usize, predict: bool },
    /// Cylinder of curvature kappa (1/m) about an axis through the centre, bending the
    /// in-plane direction orthogonal to it towards +z.
    Bend { axis: usize },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    pub layers: Vec<Entity>,
    pub kind: MotionKind,
    pub keyframes: Keyframes,
}

impl Motion {
    /// Maps a point (already mapped by earlier motions) at `frame`.
    pub fn apply(&self, p: DVec3, centre: DVec3, frame: f64) -> DVec3 {
        let v = self.keyframes.at(frame);
        match self.kind {
            MotionKind::Compress { axis, .. } => {
                let mut q = p;
                q[axis] = centre[axis] + (1.0 - v) * (p[axis] - centre[axis]);
                q
            }
            MotionKind::Bend { axis } => {
                // s: arc length along the bent direction; the cylinder axis is `axis`.
                let bent = if axis == 1 { 0 } else { 1 };
                crate::physics::prestrain::wrap_on_cylinder(p, centre, v, bent)
            }
        }
    }
}

/// The motions that drive a patch's prescribed coordinates, and the centre they act about.
#[derive(Component, Clone, Debug, Default)]
pub struct PatchMotion {
    pub motions: Vec<Motion>,
    pub centre: DVec3,
}

/// A prestrain capture (H15 4.3): after the solve of `frame`, `fraction` (times the map at the
/// element, if any) of the current state of `layers` becomes their rest state.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    pub layers: Vec<Entity>,
    pub frame: u32,
    pub fraction: f64,
    pub map: Option<super::WeightMap>,
}

/// The captures of a patch.
#[derive(Component, Clone, Debug, Default)]
pub struct PatchCaptures(pub Vec<Capture>);
