//! Sampling glTF animation clips into a [`Pose`], exactly as the glTF 2.0 spec (section 3.11 and
//! appendix C) defines the interpolations, so a clip plays here as it did in the authoring tool.

use glam::{DQuat, DVec3};

use super::{unit_quat, Pose, RigError};

/// The node property a channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
    /// Morph target weights of the mesh on the target node.
    Weights,
}

/// How values between keys are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the last key at or before the time.
    Step,
    /// Linear; rotations by slerp along the shorter arc.
    Linear,
    /// Cubic Hermite with in-tangent, value and out-tangent per key; tangents are per second, so
    /// they are scaled by the key interval. Rotations are normalised afterwards.
    CubicSpline,
}

/// One animated property of one node. Fields are private because sampling relies on the counts
/// checked when reading (values per key matching `width` and the interpolation).
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub(super) node: usize,
    pub(super) property: Property,
    pub(super) interpolation: Interpolation,
    /// Key times (s), strictly increasing.
    pub(super) times: Vec<f64>,
    /// `width` numbers per key (rotations `[x, y, z, w]`), or per CUBICSPLINE key three groups:
    /// in-tangent, value, out-tangent.
    pub(super) values: Vec<f64>,
    /// Numbers per value: 3 for translation and scale, 4 for rotation, the target count for weights.
    pub(super) width: usize,
}

/// A named animation: channels sampled together.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    pub name: String,
    channels: Vec<Channel>,
    /// The node count of the asset the clip belongs to, to check poses against.
    node_count: usize,
    /// The node whose morph weights the pose holds; weight channels of other nodes are skipped.
    morph_node: Option<usize>,
}

impl Clip {
    pub(super) fn new(name: String, channels: Vec<Channel>, node_count: usize, morph_node: Option<usize>) -> Clip {
        Clip { name, channels, node_count, morph_node }
    }

    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The time of the last key of any channel (s); the clip holds its last values after it.
    pub(crate) fn duration(&self) -> f64 {
        self.channels.iter().filter_map(|c| c.times.last().copied()).fold(0.0, f64::max)
    }

    /// Writes the clip's values at `t` seconds into `pose`; properties the clip does not animate are
    /// left as they are, so clips can be layered on a rest pose. Before its first key a channel
    /// holds the first value, after its last key the last value.
    pub fn sample(&self, t: f64, pose: &mut Pose) -> Result<(), RigError> {
        if !t.is_finite() {
            return Err(RigError::BadTime { clip: self.name.clone(), time: t });
        }
        if pose.locals.len() != self.node_count {
            return Err(RigError::PoseMismatch(format!(
                "clip {:?} animates an asset of {} nodes, the pose has {}",
                self.name,
                self.node_count,
                pose.locals.len()
            )));
        }
        for (c, ch) in self.channels.iter().enumerate() {
            let mut buf = [0.0; 4];
            match ch.property {
                Property::Weights if Some(ch.node) != self.morph_node => {}
                Property::Weights => {
                    if pose.morph_weights.len() != ch.width {
                        return Err(RigError::PoseMismatch(format!(
                            "clip {:?} channel {c} animates {} morph weights, the pose has {}",
                            self.name,
                            ch.width,
                            pose.morph_weights.len()
                        )));
                    }
                    ch.sample_into(t, &mut pose.morph_weights);
                }
                Property::Translation => {
                    ch.sample_into(t, &mut buf[..3]);
                    pose.locals[ch.node].translation = DVec3::from_slice(&buf);
                }
                Property::Scale => {
                    ch.sample_into(t, &mut buf[..3]);
                    pose.locals[ch.node].scale = DVec3::from_slice(&buf);
                }
                Property::Rotation => {
                    ch.sample_into(t, &mut buf);
                    pose.locals[ch.node].rotation =
                        unit_quat(DQuat::from_array(buf)).ok_or_else(|| RigError::BadChannel {
                            clip: self.name.clone(),
                            channel: c,
                            problem: format!("the rotation at t = {t} s interpolates to zero"),
                        })?;
                }
            }
        }
        Ok(())
    }
}

impl Channel {
    /// The animated node.
    pub fn node(&self) -> usize {
        self.node
    }

    pub fn property(&self) -> Property {
        self.property
    }

    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Key times (s), strictly increasing.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The channel's value at `t` (s) into `out` (length `width`). Rotations come out unit for
    /// STEP and LINEAR; CUBICSPLINE rotations still need normalising (the caller does it).
    fn sample_into(&self, t: f64, out: &mut [f64]) {
        let n = self.times.len();
        let (Some(&first), Some(&last)) = (self.times.first(), self.times.last()) else { return };
        if t <= first {
            out.copy_from_slice(self.value(0));
            return;
        }
        if t >= last {
            out.copy_from_slice(self.value(n - 1));
            return;
        }
        // times[k] <= t < times[k + 1]; k >= 0 because t > first.
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let interval = self.times[k + 1] - self.times[k];
        let s = (t - self.times[k]) / interval;
        match (self.interpolation, self.property) {
            (Interpolation::Step, _) => out.copy_from_slice(self.value(k)),
            (Interpolation::Linear, Property::Rotation) => {
                let q = slerp(DQuat::from_slice(self.value(k)), DQuat::from_slice(self.value(k + 1)), s);
                out.copy_from_slice(&q.to_array());
            }
            (Interpolation::Linear, _) => {
                let (a, b) = (self.value(k), self.value(k + 1));
                for (o, (a, b)) in out.iter_mut().zip(a.iter().zip(b)) {
                    *o = a + s * (b - a);
                }
            }
            (Interpolation::CubicSpline, _) => {
                let w = self.width;
                let (v0, b0) = (self.value(k), &self.values[(3 * k + 2) * w..(3 * k + 3) * w]);
                let (v1, a1) = (self.value(k + 1), &self.values[(3 * k + 3) * w..(3 * k + 4) * w]);
                let [h00, h10, h01, h11] = hermite_basis(s);
                for i in 0..w {
                    out[i] = h00 * v0[i] + interval * h10 * b0[i] + h01 * v1[i] + interval * h11 * a1[i];
                }
            }
        }
    }

    /// The value (not a tangent) of key `k`.
    fn value(&self, k: usize) -> &[f64] {
        let w = self.width;
        match self.interpolation {
            Interpolation::CubicSpline => &self.values[(3 * k + 1) * w..(3 * k + 2) * w],
            _ => &self.values[k * w..(k + 1) * w],
        }
    }
}

/// The cubic Hermite basis at `s` in [0, 1]: weights of the start value, start out-tangent, end
/// value and end in-tangent (the spec's formula; tangents still need the interval factor).
pub fn hermite_basis(s: f64) -> [f64; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2]
}

/// Spherical linear interpolation along the shorter arc (q and -q are one rotation, so `b` is
/// flipped when the quaternions point apart). The angle is taken by atan2 of the chord lengths,
/// which stays accurate for nearly equal quaternions where acos of the dot product does not.
pub fn slerp(a: DQuat, b: DQuat, s: f64) -> DQuat {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    let theta = 2.0 * (a - b).length().atan2((a + b).length());
    if theta < 1e-12 {
        return (a * (1.0 - s) + b * s).normalize();
    }
    let sin = theta.sin();
    (a * (((1.0 - s) * theta).sin() / sin) + b * ((s * theta).sin() / sin)).normalize()
}
