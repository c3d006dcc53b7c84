//! Prescribed motions of a patch, evaluated by the Motion stage as maps of the rest position:
//! keyframed compression and cylinder bending, blend shapes (LK14 5.3) and per-frame sequences
//! (KCK18 bodies); and the captures that run after a frame's solve (H15 4.3).

use bevy_ecs::prelude::*;
use glam::DVec3;

use super::keyframes::{Interpolation, Keyframes};

#[derive(Clone, Debug, PartialEq)]
pub enum MotionKind {
    /// Uniform compression along `axis`: x_a = c_a + (1 - strain) (X_a - c_a).
    Compress { axis: usize, predict: bool },
    /// Cylinder of curvature kappa (1/m) about an axis through the centre, bending the
    /// in-plane direction orthogonal to it towards +z.
    Bend { axis: usize },
    /// A procedural joint bend by the keyframed angle (radians).
    Joint(Joint),
    /// Blend shapes (LK14 5.3): x_i = X_i + sum_t w_t(frame) d_t,i, one displacement field per
    /// target over the layer's vertices, in mesh order.
    Blend(BlendShape),
    /// Per frame from `start` (the last frame holds after): displacements from rest (KCK18
    /// bodies: articulated poses, OBJ sequences).
    Sequence { frames: Vec<Vec<DVec3>>, start: u32 },
    /// A glTF body posed by its rig (issue 62): every position at once (`Motion::layer_pose`),
    /// whatever the motions before it did.
    Rig(std::sync::Arc<super::rig::RigMotion>),
    /// A layer embedded in a body (issue 62): written after every body has moved, from the
    /// body's positions (`systems/motion.rs`); `carriers` are the body's motions, which say
    /// whether its load holds.
    Embed { embedding: std::sync::Arc<super::rig::Embedding>, carriers: Vec<Motion> },
}

/// A hinge joint (issue 24): points turn about the line through `pivot` along `axis` (unit) by
/// the angle times a smoothstep of their distance along `along` (unit) from the pivot: none at
/// -width / 2, all at +width / 2 and beyond (the bone past the joint turns rigidly, the skin over
/// the joint blends, as two-bone linear blend skinning with a smooth weight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint {
    pub pivot: DVec3,
    pub axis: DVec3,
    pub along: DVec3,
    pub width: f64,
}

impl Joint {
    /// The point `p` with the joint turned by `angle` (radians).
    pub fn bend(&self, p: DVec3, angle: f64) -> DVec3 {
        let t = (((p - self.pivot).dot(self.along) / self.width) + 0.5).clamp(0.0, 1.0);
        let a = angle * t * t * (3.0 - 2.0 * t);
        if a == 0.0 {
            return p;
        }
        self.pivot + glam::DQuat::from_axis_angle(self.axis, a) * (p - self.pivot)
    }
}

/// A blend shape's targets: displacements from the base mesh and keyframed weights.
#[derive(Clone, Debug, PartialEq)]
pub struct BlendShape {
    pub targets: Vec<(Vec<DVec3>, Keyframes)>,
    pub interpolation: Interpolation,
}

impl BlendShape {
    /// The weight of each target at `frame`.
    pub fn weights(&self, frame: f64) -> Vec<f64> {
        self.targets.iter().map(|(_, k)| k.at(frame, self.interpolation)).collect()
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    pub layers: Vec<Entity>,
    pub kind: MotionKind,
    pub keyframes: Keyframes,
}

impl Motion {
    /// Maps a point (vertex `index` of its layer, already mapped by earlier motions) at `frame`.
    pub fn apply(&self, index: usize, p: DVec3, centre: DVec3, frame: f64) -> DVec3 {
        let v = self.keyframes.at(frame, Interpolation::Linear);
        match &self.kind {
            &MotionKind::Compress { axis, .. } => {
                let mut q = p;
                q[axis] = centre[axis] + (1.0 - v) * (p[axis] - centre[axis]);
                q
            }
            &MotionKind::Bend { axis } => {
                // s: arc length along the bent direction; the cylinder axis is `axis`.
                let bent = if axis == 1 { 0 } else { 1 };
                crate::physics::prestrain::wrap_on_cylinder(p, centre, v, bent)
            }
            MotionKind::Joint(j) => j.bend(p, v),
            MotionKind::Sequence { frames, start } => {
                frames.get(sequence_index(frames.len(), *start, frame)).map_or(p, |d| p + d[index])
            }
            MotionKind::Blend(b) => {
                let w = b.weights(frame);
                p + b.targets.iter().zip(w).map(|((d, _), w)| w * d[index]).sum::<DVec3>()
            }
            // Whole-layer motions: `layer_pose` and the Motion stage's embedding pass.
            MotionKind::Rig(_) | MotionKind::Embed { .. } => p,
        }
    }

    /// The positions of every vertex of its layer at `frame`, for motions that pose a layer as
    /// a whole (a rig); None for the per-point maps of `apply`.
    pub(crate) fn layer_pose(&self, frame: f64) -> Option<Vec<DVec3>> {
        match &self.kind {
            MotionKind::Rig(r) => Some(r.positions(frame)),
            _ => None,
        }
    }

    /// Whether it maps every point at `frame` as it did at `frame - 1` (past its last keyframe,
    /// or between two equal keys), up to the round-off of interpolating at a key (0.1 x 3 / 3).
    pub fn holds_at(&self, frame: f64) -> bool {
        let before = frame - 1.0;
        let same = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(b.abs());
        match &self.kind {
            MotionKind::Blend(b) => b.weights(frame).into_iter().zip(b.weights(before)).all(|(a, b)| same(a, b)),
            MotionKind::Sequence { frames, start } => {
                sequence_index(frames.len(), *start, frame) == sequence_index(frames.len(), *start, before)
            }
            MotionKind::Rig(r) => r.holds_at(frame),
            MotionKind::Embed { carriers, .. } => carriers.iter().all(|m| m.holds_at(frame)),
            _ => {
                same(self.keyframes.at(frame, Interpolation::Linear), self.keyframes.at(before, Interpolation::Linear))
            }
        }
    }
}

/// The frame of a sequence of `len` frames from `start` shown at `frame` (the last holds after).
fn sequence_index(len: usize, start: u32, frame: f64) -> usize {
    ((frame - start as f64).max(0.0) as usize).min(len.saturating_sub(1))
}

/// The keyframes after `frame` of `motions` (a blend shape's: its targets' weight keys), sorted,
/// each once.
pub fn keyframes_after(motions: &[&Motion], frame: u32) -> Vec<u32> {
    let mut keys: Vec<u32> = motions
        .iter()
        .flat_map(|m| match &m.kind {
            MotionKind::Blend(b) => b.targets.iter().flat_map(|(_, k)| k.0.iter().map(|k| k.0)).collect(),
            MotionKind::Rig(r) => r.key_frames(),
            MotionKind::Embed { carriers, .. } => keyframes_after(&carriers.iter().collect::<Vec<_>>(), frame),
            _ => m.keyframes.0.iter().map(|k| k.0).collect::<Vec<_>>(),
        })
        .filter(|&k| k > frame)
        .collect();
    keys.sort_unstable();
    keys.dedup();
    keys
}

/// `rest` moved by each of `motions` in turn at `frame`, about `centre`.
pub fn pose_at(motions: &[&Motion], rest: &[DVec3], centre: DVec3, frame: f64) -> Vec<DVec3> {
    let posed = LayerPoses::new(motions, frame);
    rest.iter().enumerate().map(|(i, &p)| posed.apply(motions, i, p, centre, frame)).collect()
}

/// The whole-layer poses (`Motion::layer_pose`) of a layer's motions at one frame, evaluated once
/// for all its vertices.
pub struct LayerPoses(Vec<Option<Vec<DVec3>>>);

impl LayerPoses {
    pub fn new(motions: &[&Motion], frame: f64) -> Self {
        LayerPoses(motions.iter().map(|m| m.layer_pose(frame)).collect())
    }

    /// Vertex `index` at rest position `p` moved by each of `motions` in turn (a whole-layer pose
    /// replaces what the motions before it did).
    pub fn apply(&self, motions: &[&Motion], index: usize, p: DVec3, centre: DVec3, frame: f64) -> DVec3 {
        motions.iter().zip(&self.0).fold(p, |q, (m, posed)| match posed {
            Some(v) => v[index],
            None => m.apply(index, q, centre, frame),
        })
    }
}

/// The motions that drive a patch's prescribed coordinates, and the centre they act about.
#[derive(Component, Clone, Debug, Default)]
pub struct PatchMotion {
    pub motions: Vec<Motion>,
    pub centre: DVec3,
}

/// Whether a patch's load this frame is the last frame's (a component beside `PatchMotion`,
/// written by the Motion stage): every motion holds and no capture changed the rest state
/// after the last solve. From frame 2 on only: frame 1 loads the initial state.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadHeld(pub bool);

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_turns_the_far_side_rigidly_and_blends_across_its_width() {
        let j = Joint { pivot: DVec3::new(1.0, 0.0, -0.5), axis: DVec3::Y, along: DVec3::X, width: 0.4 };
        let angle = std::f64::consts::FRAC_PI_2;
        let near = DVec3::new(0.7, 0.3, 0.0);
        assert_eq!(j.bend(near, angle), near, "behind the blend zone nothing moves");
        // Beyond it: a rigid rotation about the hinge line (distances to the pivot line kept).
        let (a, b) = (DVec3::new(1.5, 0.2, 0.0), DVec3::new(2.0, -0.1, 0.1));
        let (ta, tb) = (j.bend(a, angle), j.bend(b, angle));
        assert!(((ta - tb).length() - (a - b).length()).abs() < 1e-12);
        // (0.5, 0.2, 0.5) from the pivot turns a quarter about +y to (0.5, 0.2, -0.5).
        assert!((ta - DVec3::new(1.5, 0.2, -1.0)).length() < 1e-12, "{ta}");
        // In the zone the angle grows smoothly: the pivot's own section turns by half.
        let mid = DVec3::new(1.0, 0.0, 0.0);
        let turned = j.bend(mid, angle) - j.pivot;
        let half = (turned.x.atan2(turned.z) - (mid - j.pivot).x.atan2((mid - j.pivot).z)).abs();
        assert!((half - angle / 2.0).abs() < 1e-12, "{half}");
    }

    #[test]
    fn keyframes_interpolate_linearly_and_smoothly() {
        let k = Keyframes(vec![(0, 0.0), (10, 1.0), (20, 0.5)]);
        assert_eq!(k.at(-1.0, Interpolation::Smooth), 0.0);
        assert_eq!(k.at(5.0, Interpolation::Linear), 0.5);
        assert_eq!(k.at(5.0, Interpolation::Smooth), 0.5, "symmetric about the midpoint");
        assert!((k.at(2.0, Interpolation::Smooth) - 0.104).abs() < 1e-12, "eases in");
        assert_eq!(k.at(10.0, Interpolation::Smooth), 1.0);
        assert_eq!(k.at(15.0, Interpolation::Linear), 0.75);
        assert_eq!(k.at(99.0, Interpolation::Linear), 0.5);
        assert_eq!(k.at(7.0, Interpolation::Linear), 0.7);
    }

    #[test]
    fn a_motion_holds_past_its_last_key_and_between_equal_keys() {
        let squeeze = |keys: Vec<(u32, f64)>| Motion {
            layers: vec![],
            kind: MotionKind::Compress { axis: 0, predict: false },
            keyframes: Keyframes(keys),
        };
        let m = squeeze(vec![(0, 0.0), (3, 0.1), (6, 0.1), (8, 0.2)]);
        let holds: Vec<bool> = (1..=10).map(|f| m.holds_at(f as f64)).collect();
        // (at frame 3, 0.1 x 3 / 3 is 0.1 to one ulp)
        assert_eq!(holds, [false, false, false, true, true, true, false, false, true, true]);
        let b = BlendShape {
            targets: vec![(vec![DVec3::X], Keyframes(vec![(0, 0.0), (3, 1.0)]))],
            interpolation: Interpolation::Smooth,
        };
        let blend = Motion { layers: vec![], kind: MotionKind::Blend(b), keyframes: Keyframes(vec![]) };
        assert!(!blend.holds_at(3.0) && blend.holds_at(4.0));
        let sequence = Motion {
            layers: vec![],
            kind: MotionKind::Sequence { frames: vec![vec![DVec3::ZERO]; 3], start: 5 },
            keyframes: Keyframes(vec![]),
        };
        let holds: Vec<bool> = (4..=9).map(|f| sequence.holds_at(f as f64)).collect();
        assert_eq!(holds, [true, true, false, false, true, true], "frames 0, 1, 2 at 5, 6, 7; the last after");
    }

    #[test]
    fn later_keyframes_are_sorted_once_and_posed_in_turn() {
        let b = BlendShape {
            targets: vec![(vec![DVec3::X], Keyframes(vec![(0, 0.0), (6, 1.0)]))],
            interpolation: Interpolation::Linear,
        };
        let blend = Motion { layers: vec![], kind: MotionKind::Blend(b), keyframes: Keyframes(vec![(9, 9.0)]) };
        let squeeze = Motion {
            layers: vec![],
            kind: MotionKind::Compress { axis: 0, predict: false },
            keyframes: Keyframes(vec![(0, 0.0), (3, 0.5), (6, 0.5)]),
        };
        let both = [&blend, &squeeze];
        assert_eq!(keyframes_after(&both, 2), vec![3, 6], "the blend's own keys are not its weights'");
        assert_eq!(keyframes_after(&both, 6), Vec::<u32>::new());
        // (displaced by the blend, then squeezed to half about the origin)
        assert_eq!(pose_at(&both, &[DVec3::new(1.0, 2.0, 0.0)], DVec3::ZERO, 6.0), vec![DVec3::new(1.0, 2.0, 0.0)]);
    }

    #[test]
    fn a_blend_adds_weighted_target_displacements() {
        let b = BlendShape {
            targets: vec![
                (vec![DVec3::X, DVec3::Y], Keyframes(vec![(0, 0.0), (10, 1.0)])),
                (vec![DVec3::Z, DVec3::Z], Keyframes(vec![(0, 0.5)])),
            ],
            interpolation: Interpolation::Linear,
        };
        let m = Motion { layers: vec![], kind: MotionKind::Blend(b), keyframes: Keyframes(vec![]) };
        let q = m.apply(1, DVec3::ONE, DVec3::ZERO, 5.0);
        assert_eq!(q, DVec3::new(1.0, 1.5, 1.5));
    }
}
