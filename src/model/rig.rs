//! Motions of a real character (issue 62, PHYSICS.md 7): a glTF body posed by its own rig
//! (animation clip, keyframed joints and morph weights, skinning), and a refined layer embedded
//! in a body, carried by fixed stencils of its vertices.

use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{DQuat, DVec3};

use super::keyframes::{Interpolation, Keyframes};
use crate::mesh::rig::{Asset, Pose, Skinning};
use crate::mesh::subdivision::Stencil;

/// A glTF body's pose at each frame: the clip sampled at its time, keyframed joint turns on top,
/// keyframed morph weights in place of the clip's, then skinning, in the engine's frame.
#[derive(Clone)]
pub struct RigMotion {
    pub asset: Arc<Asset>,
    /// (clip index, first frame, speed): clip time = (frame - start) x frame_time x speed.
    pub clip: Option<(usize, u32, f64)>,
    pub frame_time: f64,
    /// (node, unit axis in the joint's frame, angle keyframes in radians).
    pub joints: Vec<(usize, DVec3, Keyframes)>,
    /// (morph target, weight keyframes).
    pub morphs: Vec<(usize, Keyframes)>,
    pub interpolation: Interpolation,
    pub skinning: Skinning,
    /// glTF (+Y up) to the engine's frame (+Z up), then where the body sits.
    pub to_world: (DQuat, DVec3),
}

impl std::fmt::Debug for RigMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RigMotion").field("clip", &self.clip).field("joints", &self.joints.len()).finish()
    }
}

impl PartialEq for RigMotion {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.asset, &other.asset)
            && self.clip == other.clip
            && self.joints == other.joints
            && self.morphs == other.morphs
            && self.skinning == other.skinning
            && self.to_world == other.to_world
    }
}

/// The rotation that takes glTF's +Y-up frame to the engine's +Z-up one: (x, y, z) -> (x, -z, y),
/// as Blender imports glTF.
pub(crate) fn y_up_to_z_up() -> DQuat {
    DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2)
}

impl RigMotion {
    /// The pose (node transforms and morph weights) at `frame`.
    pub fn pose(&self, frame: f64) -> Pose {
        let mut pose = self.asset.rest_pose();
        if let Some((clip, start, speed)) = self.clip {
            let t = ((frame - start as f64) * self.frame_time * speed).max(0.0);
            // (a finite time and a pose of the clip's own asset: sampling cannot fail)
            let _ = self.asset.clips[clip].sample(t, &mut pose);
        }
        for (node, axis, keys) in &self.joints {
            let angle = keys.at(frame, self.interpolation);
            let local = &mut pose.locals[*node];
            local.rotation = (local.rotation * DQuat::from_axis_angle(*axis, angle)).normalize();
        }
        for (target, keys) in &self.morphs {
            pose.morph_weights[*target] = keys.at(frame, self.interpolation);
        }
        pose
    }

    /// The body's vertex positions at `frame` (welded vertices, engine frame, metres).
    pub fn positions(&self, frame: f64) -> Vec<DVec3> {
        let pose = self.pose(frame);
        let (q, t) = self.to_world;
        // Dual quaternions were checked rigid at every key when the scene was built; a pose
        // between keys that is not (it cannot be: rotations and translations only) falls back
        // to linear blending rather than stopping the run.
        let mut out = self
            .asset
            .pose_positions(&pose, self.skinning)
            .or_else(|_| self.asset.pose_positions(&pose, Skinning::Linear))
            .unwrap_or_else(|_| self.asset.rest_positions().to_vec());
        out.iter_mut().for_each(|p| *p = q * *p + t);
        out
    }

    /// Whether the pose at `frame` is the pose at `frame - 1`.
    pub fn holds_at(&self, frame: f64) -> bool {
        self.pose(frame) == self.pose(frame - 1.0)
    }

    /// The frames at which its keyframes (and the clip's keys) lie.
    pub(crate) fn key_frames(&self) -> Vec<u32> {
        let mut keys: Vec<u32> = self.joints.iter().flat_map(|j| j.2 .0.iter().map(|k| k.0)).collect();
        keys.extend(self.morphs.iter().flat_map(|m| m.1 .0.iter().map(|k| k.0)));
        if let Some((clip, start, speed)) = self.clip {
            let per_frame = self.frame_time * speed;
            if per_frame > 0.0 {
                let end = self.asset.clips[clip].duration() / per_frame;
                keys.push(start + end.ceil().min(u32::MAX as f64 / 2.0) as u32);
            }
        }
        keys
    }
}

/// A layer embedded in a body (issue 62): each vertex the limit-surface stencil of the body's
/// vertices, moved `distance` along the embedded surface's normal.
#[derive(Clone, Debug, PartialEq)]
pub struct Embedding {
    /// The body layer the stencils read.
    pub base: Entity,
    pub stencils: Vec<Stencil>,
    /// The embedded layer's faces (for its normals).
    pub faces: Vec<[u32; 3]>,
    /// Along the normal (m): 0 for the refined surface itself.
    pub distance: f64,
}

impl Embedding {
    /// The embedded positions from the base's current positions.
    pub fn positions(&self, base: &[DVec3]) -> Vec<DVec3> {
        let mut out: Vec<DVec3> = self.stencils.iter().map(|s| s.apply(base)).collect();
        if self.distance != 0.0 {
            let normals = crate::mesh::shading::vertex_normals(&out, &self.faces);
            out.iter_mut().zip(normals).for_each(|(p, n)| *p += self.distance * n);
        }
        out
    }
}
