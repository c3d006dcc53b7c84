//! Discrete-shell hinge bending on an interior edge (PHYSICS.md 1.2; H15 eq. 5.11-5.14).
//!
//! Vertex order: x0, x1 the shared edge; x2 the opposite vertex of face (x0, x1, x2);
//! x3 the opposite vertex of face (x1, x0, x3). W = k_b 3 |e_bar|^2 / A_bar (phi(theta) - phi_bar)^2.

use glam::DVec3;
use nalgebra::{SMatrix, SVector};
use num_dual::DualNum;

use super::dual::{cross3, dot3, sub3, Dual, Real};
use serde::{Deserialize, Serialize};

use super::psd::{project, Filter};

/// phi(theta): how the hinge energy grows with the dihedral angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum HingeModel {
    /// phi = theta.
    Linear,
    /// phi = 2 sin(theta / 2).
    Sin,
    /// phi = 2 tan(theta / 2) (H15 eq. 5.13): infinite energy at a full fold.
    #[default]
    Tan,
}

impl HingeModel {
    /// phi, phi', phi'' at theta.
    pub(crate) fn phi(self, t: f64) -> (f64, f64, f64) {
        match self {
            HingeModel::Linear => (t, 1.0, 0.0),
            HingeModel::Sin => {
                let (s, c) = (t / 2.0).sin_cos();
                (2.0 * s, c, -0.5 * s)
            }
            HingeModel::Tan => {
                let tn = (t / 2.0).tan();
                let sec2 = 1.0 + tn * tn;
                (2.0 * tn, sec2, sec2 * tn)
            }
        }
    }
}

/// Rest data of one hinge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HingeRest {
    /// k_b * 3 |e_bar|^2 / A_bar (J).
    pub weight: f64,
    /// phi(theta_bar): the rest (or prestrained) bend.
    pub rest_phi: f64,
}

impl HingeRest {
    /// k_b is the hinge stiffness (N m); `PHYSICS.md 1.2`: k_b = D / 6 reproduces Kirchhoff
    /// bending on equilateral meshes.
    pub fn from_rest(model: HingeModel, k_b: f64, x: [DVec3; 4]) -> Self {
        let e2 = (x[1] - x[0]).length_squared();
        let a = 0.5 * ((x[1] - x[0]).cross(x[2] - x[0]).length() + (x[1] - x[0]).cross(x[3] - x[0]).length());
        let theta = dihedral_f64(&x);
        HingeRest { weight: k_b * 3.0 * e2 / a, rest_phi: model.phi(theta).0 }
    }
}

/// The four positions of a hinge (edge, then opposite vertices) given its vertex handles; on a
/// periodic seam the second opposite vertex stands at its image, x(v3) + x(a) - x(b).
#[inline]
pub fn positions<I: Copy>(v: [I; 4], image: Option<(I, I)>, x: impl Fn(I) -> DVec3) -> [DVec3; 4] {
    let mut p = v.map(&x);
    if let Some((a, b)) = image {
        p[3] += x(a) - x(b);
    }
    p
}

/// Signed dihedral angle (0 when flat), generic so that AD gives its derivatives.
pub fn dihedral<D: DualNum<Primitive = f64> + Copy>(x: &[[D; 3]; 4]) -> D {
    let (sub, dot, cross) = (sub3::<D>, dot3::<D>, cross3::<D>);
    let e = sub(x[1], x[0]);
    let na = cross(e, sub(x[2], x[0]));
    let nb = cross(sub(x[0], x[1]), sub(x[3], x[1]));
    let el = dot(e, e).sqrt();
    let s = dot(cross(na, nb), e) / el;
    s.atan2(dot(na, nb))
}

/// Gradient of the dihedral angle with respect to (x0, x1, x2, x3), in closed form (Bridson,
/// Marino, Fedkiw 2003): the opposite vertices move along their face normals over the heights,
/// the edge vertices by the projections of the opposite vertices on the edge. Generic so that
/// first-order AD of it gives the exact Hessian.
pub(crate) fn dihedral_gradient<D: Real>(x: &[[D; 3]; 4]) -> [[D; 3]; 4] {
    let (sub, dot, cross) = (sub3::<D>, dot3::<D>, cross3::<D>);
    let e = sub(x[1], x[0]);
    let l = dot(e, e).sqrt();
    let na = cross(e, sub(x[2], x[0]));
    let nb = cross(sub(x[0], x[1]), sub(x[3], x[1]));
    let (ia, ib) = (dot(na, na).recip(), dot(nb, nb).recip());
    let a: [D; 3] = std::array::from_fn(|k| na[k] * ia);
    let b: [D; 3] = std::array::from_fn(|k| nb[k] * ib);
    let il = l.recip();
    let d21 = dot(sub(x[2], x[1]), e) * il;
    let d31 = dot(sub(x[3], x[1]), e) * il;
    let d20 = dot(sub(x[2], x[0]), e) * il;
    let d30 = dot(sub(x[3], x[0]), e) * il;
    [
        std::array::from_fn(|k| -(d21 * a[k] + d31 * b[k])),
        std::array::from_fn(|k| d20 * a[k] + d30 * b[k]),
        std::array::from_fn(|k| -(l * a[k])),
        std::array::from_fn(|k| -(l * b[k])),
    ]
}

/// Dihedral angle in plain f64.
pub(crate) fn dihedral_f64(x: &[DVec3; 4]) -> f64 {
    dihedral(&x.map(|v| v.to_array()))
}

/// Orthonormal basis (Helmert) of the vectors of R^4 orthogonal to (1, 1, 1, 1).
const HELMERT: [[f64; 3]; 4] = {
    const A: f64 = std::f64::consts::FRAC_1_SQRT_2;
    const B: f64 = 0.408_248_290_463_863; // 1 / sqrt(6)
    const C: f64 = 0.288_675_134_594_812_9; // 1 / sqrt(12)
    [[A, B, C], [-A, B, C], [0.0, -2.0 * B, C], [0.0, 0.0, -3.0 * C]]
};

/// Projects a 12x12 element Hessian that annihilates translations (every hinge Hessian does)
/// in the 9-dimensional complement of the translations: with Q = Helmert (x) I3 orthonormal,
/// H = Q (Q^T H Q) Q^T exactly, so projecting the 9x9 middle is the same projection.
#[allow(clippy::needless_range_loop)] // index arithmetic mirrors the formula
fn project_without_translations(h: &mut SMatrix<f64, 12, 12>, filter: Filter) {
    let block = |m: &SMatrix<f64, 12, 12>, i: usize, j: usize| -> nalgebra::Matrix3<f64> {
        m.fixed_view::<3, 3>(3 * i, 3 * j).into_owned()
    };
    let mut r = SMatrix::<f64, 9, 9>::zeros();
    for a in 0..3 {
        for b in 0..3 {
            let mut acc = nalgebra::Matrix3::zeros();
            for i in 0..4 {
                for j in 0..4 {
                    let c = HELMERT[i][a] * HELMERT[j][b];
                    if c != 0.0 {
                        acc += block(h, i, j) * c;
                    }
                }
            }
            r.fixed_view_mut::<3, 3>(3 * a, 3 * b).copy_from(&acc);
        }
    }
    project(&mut r, filter);
    for i in 0..4 {
        for j in 0..4 {
            let mut acc = nalgebra::Matrix3::zeros();
            for a in 0..3 {
                for b in 0..3 {
                    let c = HELMERT[i][a] * HELMERT[j][b];
                    if c != 0.0 {
                        acc += r.fixed_view::<3, 3>(3 * a, 3 * b) * c;
                    }
                }
            }
            h.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&acc);
        }
    }
}

/// Energy only.
pub fn energy(model: HingeModel, rest: &HingeRest, x: &[DVec3; 4]) -> f64 {
    let d = model.phi(dihedral_f64(x)).0 - rest.rest_phi;
    rest.weight * d * d
}

/// Energy, gradient (12) and Hessian (12x12), projected on the full 12x12 when asked.
pub fn eval(
    model: HingeModel,
    rest: &HingeRest,
    x: &[DVec3; 4],
    filter: Filter,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let xd: [[Dual<12>; 3]; 4] = std::array::from_fn(|v| std::array::from_fn(|k| Dual::variable(x[v][k], 3 * v + k)));
    let gd = dihedral_gradient(&xd);
    let mut gt = SVector::<f64, 12>::zeros();
    let mut ht = SMatrix::<f64, 12, 12>::zeros();
    for v in 0..4 {
        for k in 0..3 {
            let g = &gd[v][k];
            gt[3 * v + k] = g.re;
            for j in 0..12 {
                ht[(3 * v + k, j)] = g.eps[j];
            }
        }
    }
    let theta = dihedral_f64(x);
    let (phi, d1, d2) = model.phi(theta);
    let d = phi - rest.rest_phi;
    // W = w d^2: W' = 2 w d phi', W'' = 2 w (phi'^2 + d phi'').
    let w1 = 2.0 * rest.weight * d * d1;
    let w2 = 2.0 * rest.weight * (d1 * d1 + d * d2);
    let mut h = gt * gt.transpose() * w2 + ht * w1;
    if filter != Filter::Exact {
        project_without_translations(&mut h, filter);
    }
    (rest.weight * d * d, gt * w1, h)
}
