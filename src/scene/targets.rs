//! Procedural blend-shape targets (LK14 5.3, fig. 5-1) as displacement fields of a layer's rest
//! mesh (SI units). Each is the full (weight 1) pose.

use glam::{DVec2, DVec3};

use super::built::{BuiltTarget, LayerMesh};
use super::context::Builder;
use super::schema::{Axis, BlendTargetSpec, TargetShape};
use super::SceneError;
use crate::mesh;

impl Builder {
    /// Validates a blend shape's targets and evaluates each as displacements of the layer's
    /// rest mesh: procedural shapes about the layer's centre, OBJ targets read and checked for
    /// the layer's vertex count.
    pub(super) fn blend_targets(
        &self,
        at: &str,
        targets: &[BlendTargetSpec],
        range: (f64, f64),
        mesh: &LayerMesh,
        len: f64,
        offset: DVec3,
    ) -> Result<Vec<BuiltTarget>, SceneError> {
        if targets.is_empty() {
            return Err(self.err(format!("{at}.targets"), "a blend shape needs at least one target"));
        }
        if !(range.0 < range.1 && range.0.is_finite() && range.1.is_finite()) {
            return Err(self.err(format!("{at}.range"), format!("must be (low, high) with low < high (got {range:?})")));
        }
        let rest = mesh.rest();
        let (lo, hi) = rest.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let centre = 0.5 * (lo + hi);
        let mut out = Vec::new();
        for (ti, t) in targets.iter().enumerate() {
            let tat = format!("{at}.targets[{ti}]");
            if t.weights.is_empty() {
                return Err(self.err(format!("{tat}.weights"), "needs at least one keyframe"));
            }
            for (k, w) in t.weights.iter().enumerate() {
                if k > 0 && w.0 <= t.weights[k - 1].0 {
                    return Err(self.err(format!("{tat}.weights[{k}]"), "keyframes out of order"));
                }
                if !(w.1 >= range.0 && w.1 <= range.1) {
                    return Err(self.err(
                        format!("{tat}.weights[{k}]"),
                        format!("weight {} is outside the declared range [{}, {}]", w.1, range.0, range.1),
                    ));
                }
            }
            let positive = |field: &str, v: f64| {
                if v > 0.0 && v.is_finite() {
                    Ok(v)
                } else {
                    Err(self.err(format!("{tat}.shape.{field}"), format!("must be > 0 (got {v})")))
                }
            };
            let delta = match &t.shape {
                TargetShape::Compress { axis, strain } => {
                    if !(*strain > -1.0 && *strain < 1.0) {
                        return Err(
                            self.err(format!("{tat}.shape.strain"), format!("must be in (-1, 1) (got {strain})"))
                        );
                    }
                    compress(rest, centre, axis.index(), *strain)
                }
                TargetShape::Twist { angle, radius } => {
                    let r = match radius {
                        Some(r) => positive("radius", *r)? * len,
                        None => 0.5 * (hi - lo).truncate().min_element(),
                    };
                    twist(rest, centre, angle.to_radians(), r)
                }
                TargetShape::Pinch { radius, squeeze, lift, between } => {
                    // (drawn in from all sides, a squeeze of 1 or more collapses circles to a
                    // point; between two fingers it folds the skin over itself, up to 4: the
                    // folded middle lies within the radius)
                    if *between == Some(Axis::Z) {
                        return Err(self.err(format!("{tat}.shape.between"), "must be X or Y (fingers in the plane)"));
                    }
                    let most = if between.is_some() { 4.0 } else { 1.0 };
                    if !(*squeeze >= 0.0 && *squeeze < most) {
                        let message = format!("must be in [0, {most}) (got {squeeze})");
                        return Err(self.err(format!("{tat}.shape.squeeze"), message));
                    }
                    let radius = positive("radius", *radius)? * len;
                    pinch(rest, centre, radius, *squeeze, lift * len, between.map(Axis::index))
                }
                TargetShape::Obj(path) => {
                    let full = self.dir.join(path);
                    let field = format!("{tat}.shape");
                    if let Some(problem) = super::context::not_a_file(&full) {
                        return Err(SceneError::at_field(&full, &field, format!("target file {problem}")));
                    }
                    let m =
                        mesh::obj::load(&full, len).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
                    if m.rest.len() != rest.len() {
                        return Err(SceneError::at_field(
                            &full,
                            &field,
                            format!("the target has {} vertices, the layer {}", m.rest.len(), rest.len()),
                        ));
                    }
                    // Targets sit where the layer's mesh file does: moved by the patch offset too.
                    m.rest.iter().zip(rest).map(|(t, r)| *t + offset - *r).collect()
                }
            };
            out.push((delta, t.weights.clone()));
        }
        Ok(out)
    }
}

/// Displacements that shorten the mesh along `axis` by `strain` about `centre`.
pub fn compress(rest: &[DVec3], centre: DVec3, axis: usize, strain: f64) -> Vec<DVec3> {
    rest.iter()
        .map(|p| {
            let mut d = DVec3::ZERO;
            d[axis] = -strain * (p[axis] - centre[axis]);
            d
        })
        .collect()
}

/// A smooth falloff from 1 at r = 0 to 0 at r >= radius, with zero slope at both ends.
fn falloff(r: f64, radius: f64) -> f64 {
    let t = (1.0 - (r / radius).powi(2)).max(0.0);
    t * t
}

/// In-plane rotation about the z axis through `centre` by `angle` (radians) times the falloff:
/// the centre turns, the rim within `radius` shears, beyond it nothing moves.
pub fn twist(rest: &[DVec3], centre: DVec3, angle: f64, radius: f64) -> Vec<DVec3> {
    rest.iter()
        .map(|p| {
            let q = (*p - centre).truncate();
            let a = angle * falloff(q.length(), radius);
            let turned = DVec2::from_angle(a).rotate(q);
            (turned - q).extend(0.0)
        })
        .collect()
}

/// Draws points within `radius` towards `centre` by `squeeze` x their distance x falloff and
/// lifts them by `lift` x falloff along z. `between`: draws in along that axis only.
pub fn pinch(
    rest: &[DVec3],
    centre: DVec3,
    radius: f64,
    squeeze: f64,
    lift: f64,
    between: Option<usize>,
) -> Vec<DVec3> {
    rest.iter()
        .map(|p| {
            let mut q = (*p - centre).truncate();
            let f = falloff(q.length(), radius);
            if let Some(axis) = between {
                q[1 - axis] = 0.0;
            }
            (-squeeze * f * q).extend(lift * f)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Vec<DVec3> {
        (0..11).flat_map(|i| (0..11).map(move |j| DVec3::new(i as f64, j as f64, 0.0))).collect()
    }

    #[test]
    fn compress_shortens_about_the_centre() {
        let d = compress(&grid(), DVec3::new(5.0, 5.0, 0.0), 0, 0.2);
        assert_eq!(d[0], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(d[120], DVec3::new(-1.0, 0.0, 0.0));
    }

    #[test]
    fn twist_turns_the_centre_and_keeps_lengths_on_circles() {
        let c = DVec3::new(5.0, 5.0, 0.0);
        let rest = grid();
        let d = twist(&rest, c, 0.5, 5.0);
        for (p, d) in rest.iter().zip(&d) {
            let r0 = (*p - c).length();
            assert!(((*p + *d - c).length() - r0).abs() < 1e-12, "rotation keeps the radius");
            if r0 >= 5.0 {
                assert!(d.length() < 1e-12, "nothing moves beyond the radius");
            }
        }
        assert_eq!(d[60], DVec3::ZERO, "the centre itself stays");
    }

    #[test]
    fn pinch_lifts_and_draws_in() {
        let c = DVec3::new(5.0, 5.0, 0.0);
        let d = pinch(&grid(), c, 4.0, 0.5, 2.0, None);
        assert_eq!(d[60], DVec3::new(0.0, 0.0, 2.0));
        let near = d[61]; // (5, 6): 1 from the centre
        assert!(near.y < 0.0 && near.z > 0.0 && near.z < 2.0);
        assert_eq!(d[0], DVec3::ZERO);
    }

    /// Between fingers along x, squeezed past 1: y stays; along the centre row the middle
    /// crosses over to the other side (x is no longer monotone: the skin folds over itself)
    /// while the lift, falling with the distance, keeps the folded parts at different heights.
    #[test]
    fn pinch_between_fingers_folds_the_middle_over() {
        let c = DVec3::new(5.0, 5.0, 0.0);
        let rest = grid();
        let d = pinch(&rest, c, 4.0, 1.6, 2.0, Some(0));
        assert!(d.iter().all(|d| d.y == 0.0));
        let row: Vec<DVec3> = (0..11).map(|i| rest[i * 11 + 5] + d[i * 11 + 5]).collect();
        assert!(row[6].x < c.x && row[4].x > c.x, "the middle crosses over: {row:?}");
        assert!(row[6].z > row[7].z && row[7].z > row[8].z, "the lift falls outwards");
    }
}
