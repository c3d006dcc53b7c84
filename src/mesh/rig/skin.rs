//! Posing: morph targets, then linear blend or dual quaternion skinning.
//!
//! Per pose, the node globals and one matrix (or dual quaternion) per joint are computed once; the
//! per-vertex work is then a pure function of the vertex index over shared read-only tables, so the
//! `iter_mut().enumerate().for_each` loops can become rayon's `par_iter_mut()` without change.

use glam::{DMat3, DMat4, DQuat, DVec3};

use super::{Asset, Pose, RigError, Skin};

/// How joint transforms are blended at a vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skinning {
    /// `x' = sum_j w_j (G_j B_j^-1) x`: exact for affine joints, but blending rotations linearly
    /// shrinks twisted or bent regions (the candy wrapper).
    Linear,
    /// Dual quaternion linear blending (Kavan et al. 2007): keeps volume under twist, but only
    /// for rigid joint transforms.
    DualQuaternion,
}

/// `G_j B_j^-1` must be a rotation to this accuracy for dual quaternion skinning (a dual quaternion
/// cannot carry scale or shear; dropping it silently would move the mesh).
pub const RIGID_TOLERANCE: f64 = 1e-9;

/// Extra allowance when the inverse bind matrices come from the file: they are f32, so even a
/// rigid bind pose gives `(G B^-1)^T (G B^-1)` off the identity by a few f32 roundings (~4e-7).
/// This admits only that rounding, not a modelled scale (1 + 1e-6 scale is already refused).
pub const F32_BIND_SLACK: f64 = 8.0 * f32::EPSILON as f64;

/// A unit dual quaternion `real + eps dual` for the rigid motion `x -> R x + t`, with
/// `dual = 1/2 (t, 0) real`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualQuat {
    pub real: DQuat,
    pub dual: DQuat,
}

impl DualQuat {
    pub(crate) fn from_rotation_translation(rotation: DQuat, translation: DVec3) -> DualQuat {
        let t = DQuat::from_xyzw(translation.x, translation.y, translation.z, 0.0);
        DualQuat { real: rotation, dual: (t * rotation) * 0.5 }
    }

    /// Applies the motion, assuming `real` is unit (as after [`DualQuat::normalized`]). The
    /// translation is the vector part of `2 dual conj(real)`, which ignores any part of `dual`
    /// parallel to `real` that blending leaves behind.
    pub(crate) fn transform_point(&self, p: DVec3) -> DVec3 {
        let t = (self.dual * self.real.conjugate()) * 2.0;
        self.real.mul_vec3(p) + DVec3::new(t.x, t.y, t.z)
    }

    /// Divides by the length of the real part (DLB's normalisation).
    pub(crate) fn normalized(self) -> DualQuat {
        let inv = 1.0 / self.real.length();
        DualQuat { real: self.real * inv, dual: self.dual * inv }
    }
}

/// How far a matrix's linear part is from a rotation: `max |A^T A - I|` (about twice the relative
/// scale error), infinite for a reflection or degenerate matrix.
pub fn rigid_deviation(m: &DMat4) -> f64 {
    let a = DMat3::from_mat4(*m);
    if a.determinant() <= 0.0 || !a.is_finite() {
        return f64::INFINITY;
    }
    let e = a.transpose() * a - DMat3::IDENTITY;
    e.to_cols_array().iter().fold(0.0, |acc, x| acc.max(x.abs()))
}

impl Asset {
    /// Global matrix of every node (mesh space of the scene root) for the pose.
    pub(crate) fn global_matrices(&self, pose: &Pose) -> Result<Vec<DMat4>, RigError> {
        self.check_pose(pose)?;
        let mut globals = vec![DMat4::IDENTITY; self.nodes.len()];
        for &n in self.node_order() {
            let local = pose.locals[n].matrix();
            globals[n] = match self.nodes[n].parent {
                Some(p) => globals[p] * local,
                None => local,
            };
        }
        Ok(globals)
    }

    /// `G_j B_j^-1` per skin joint; empty without a skin.
    pub fn joint_matrices(&self, pose: &Pose) -> Result<Vec<DMat4>, RigError> {
        let globals = self.global_matrices(pose)?;
        Ok(self.skin.as_ref().map_or_else(Vec::new, |s| joint_matrices(s, &globals)))
    }

    /// Welded vertex positions after morphing and skinning (m).
    pub(crate) fn pose_positions(&self, pose: &Pose, skinning: Skinning) -> Result<Vec<DVec3>, RigError> {
        let mut out = Vec::new();
        self.pose_positions_into(pose, skinning, &mut out)?;
        Ok(out)
    }

    /// As [`Asset::pose_positions`], reusing `out` so a caller posing every frame does not allocate
    /// per vertex. Morphs come first (`x = X + sum_k w_k D_k`), then skinning; a mesh without a skin
    /// is moved by its node's global matrix (a skinned mesh's own node transform is ignored, as the
    /// spec says).
    pub(crate) fn pose_positions_into(
        &self,
        pose: &Pose,
        skinning: Skinning,
        out: &mut Vec<DVec3>,
    ) -> Result<(), RigError> {
        let globals = self.global_matrices(pose)?;
        let active: Vec<(&[DVec3], f64)> = self
            .morphs
            .iter()
            .zip(&pose.morph_weights)
            .filter(|(_, &w)| w != 0.0)
            .map(|(m, &w)| (m.deltas.as_slice(), w))
            .collect();
        let morphed = |v: usize| active.iter().fold(self.rest[v], |x, (d, w)| x + *w * d[v]);
        out.clear();
        out.resize(self.rest.len(), DVec3::ZERO);
        let Some(skin) = &self.skin else {
            let g = self.mesh_node.map_or(DMat4::IDENTITY, |n| globals[n]);
            out.iter_mut().enumerate().for_each(|(v, o)| *o = g.transform_point3(morphed(v)));
            return Ok(());
        };
        let mats = joint_matrices(skin, &globals);
        match skinning {
            Skinning::Linear => out.iter_mut().enumerate().for_each(|(v, o)| {
                let (joints, weights) = self.influences.of(v);
                *o = linear_blend(morphed(v), joints, weights, &mats);
            }),
            Skinning::DualQuaternion => {
                let dqs = dual_quats(skin, &mats)?;
                out.iter_mut().enumerate().for_each(|(v, o)| {
                    let (joints, weights) = self.influences.of(v);
                    *o = dual_quat_blend(morphed(v), joints, weights, &dqs);
                });
            }
        }
        Ok(())
    }

    fn check_pose(&self, pose: &Pose) -> Result<(), RigError> {
        if pose.locals.len() != self.nodes.len() || pose.morph_weights.len() != self.morphs.len() {
            return Err(RigError::PoseMismatch(format!(
                "{} node transforms and {} morph weights for an asset of {} nodes and {} morph targets",
                pose.locals.len(),
                pose.morph_weights.len(),
                self.nodes.len(),
                self.morphs.len()
            )));
        }
        Ok(())
    }
}

fn joint_matrices(skin: &Skin, globals: &[DMat4]) -> Vec<DMat4> {
    skin.joints.iter().zip(&skin.inverse_bind).map(|(&j, b)| globals[j] * *b).collect()
}

/// Each joint matrix as a unit dual quaternion, refusing non-rigid ones (see [`RIGID_TOLERANCE`]).
fn dual_quats(skin: &Skin, mats: &[DMat4]) -> Result<Vec<DualQuat>, RigError> {
    let tolerance = RIGID_TOLERANCE + if skin.inverse_bind_from_file { F32_BIND_SLACK } else { 0.0 };
    mats.iter()
        .zip(&skin.joint_names)
        .map(|(m, name)| {
            let deviation = rigid_deviation(m);
            if deviation > tolerance {
                return Err(RigError::NotRigid { joint: name.clone(), deviation, tolerance });
            }
            let rotation = DQuat::from_mat3(&DMat3::from_mat4(*m)).normalize();
            Ok(DualQuat::from_rotation_translation(rotation, m.w_axis.truncate()))
        })
        .collect()
}

fn linear_blend(x: DVec3, joints: &[u32], weights: &[f64], mats: &[DMat4]) -> DVec3 {
    joints.iter().zip(weights).fold(DVec3::ZERO, |acc, (&j, &w)| acc + w * mats[j as usize].transform_point3(x))
}

/// DLB: signs aligned to the vertex's first influence (q and -q are the same motion, but blending
/// them would cancel), weighted sum, normalised, applied.
pub(super) fn dual_quat_blend(x: DVec3, joints: &[u32], weights: &[f64], dqs: &[DualQuat]) -> DVec3 {
    let Some(&j0) = joints.first() else { return x };
    let pivot = dqs[j0 as usize].real;
    let zero = DualQuat { real: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), dual: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0) };
    let sum = joints.iter().zip(weights).fold(zero, |acc, (&j, &w)| {
        let dq = dqs[j as usize];
        let w = if dq.real.dot(pivot) < 0.0 { -w } else { w };
        DualQuat { real: acc.real + dq.real * w, dual: acc.dual + dq.dual * w }
    });
    sum.normalized().transform_point(x)
}
