//! Shell membrane triangle (PHYSICS.md 1.1): energy = thickness x rest area x Psi(F),
//! F = Ds B with Ds = [x1 - x0, x2 - x0] (3x2) and B = Dm^-1 F0 (2x2, prestrain folded in).

use glam::{DMat2, DVec2, DVec3};
use nalgebra::{SMatrix, SVector};
use num_dual::Dual2SVec64;

use super::material::{membrane_psi, membrane_psi_of_c, ConstitutiveModel, Lame};
use super::psd::{project, Filter};

/// Rest data of one membrane element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneRest {
    /// Dm^-1 F0: maps the deformed edge matrix to the deformation gradient.
    pub b: DMat2,
    /// Thickness x rest area (m^3): the energy weight.
    pub volume: f64,
}

impl MembraneRest {
    /// Rest data from a rest triangle in 3D (its own orthonormal 2D frame) and a prestrain F0.
    /// Returns None for a degenerate triangle.
    pub fn from_rest_triangle(x: [DVec3; 3], thickness: f64, f0: DMat2) -> Option<Self> {
        let dm = rest_edge_matrix(x)?;
        let area = 0.5 * dm.determinant();
        Some(MembraneRest { b: dm.inverse() * f0, volume: thickness * area })
    }
}

/// 2x2 rest edge matrix of a triangle in its own frame (H15 eq. 5.5-5.8: QR of the 3x2 edges).
pub(crate) fn rest_edge_matrix(x: [DVec3; 3]) -> Option<DMat2> {
    let e1 = x[1] - x[0];
    let e2 = x[2] - x[0];
    let l1 = e1.length();
    if l1 <= 0.0 {
        return None;
    }
    let t = e1 / l1;
    let n = e1.cross(e2);
    if n.length() <= 1e-14 * l1 * e2.length().max(l1) {
        return None;
    }
    let s = n.cross(t).normalize();
    Some(DMat2::from_cols(DVec2::new(l1, 0.0), DVec2::new(e2.dot(t), e2.dot(s))))
}

/// d F[:, j] / d x_v = coef[v][j] * I3.
#[inline]
fn coefficients(b: &DMat2) -> [[f64; 2]; 3] {
    let (b00, b01, b10, b11) = (b.x_axis.x, b.y_axis.x, b.x_axis.y, b.y_axis.y);
    [[-(b00 + b10), -(b01 + b11)], [b00, b01], [b10, b11]]
}

#[inline]
fn deformation_gradient(rest: &MembraneRest, x: &[DVec3; 3]) -> [f64; 6] {
    let c = coefficients(&rest.b);
    let mut f = [0.0; 6];
    for j in 0..2 {
        let col = x[0] * c[0][j] + x[1] * c[1][j] + x[2] * c[2][j];
        f[3 * j] = col.x;
        f[3 * j + 1] = col.y;
        f[3 * j + 2] = col.z;
    }
    f
}

/// Energy only (line searches).
pub fn energy(model: ConstitutiveModel, lame: Lame, rest: &MembraneRest, x: &[DVec3; 3]) -> f64 {
    rest.volume * membrane_psi(model, lame, &deformation_gradient(rest, x))
}

/// Energy, gradient (9) and Hessian (9x9). The Hessian is projected at the F level (6x6),
/// which keeps the element Hessian PSD because F is linear in x.
pub fn eval(
    model: ConstitutiveModel,
    lame: Lame,
    rest: &MembraneRest,
    x: &[DVec3; 3],
    filter: Filter,
) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let f = deformation_gradient(rest, x);
    let (psi, p, mut hf) = derivatives_in_f(model, lame, &f);
    if filter != Filter::Exact && !project_in_triangle_frame(&mut hf, &f, filter) {
        project(&mut hf, filter);
    }
    chain_to_vertices::<6, 2, 3, 9>(rest.volume, psi, &p, &hf, &coefficients(&rest.b))
}

/// Psi, dPsi/dF (6) and d2Psi/dF2 (6x6) by the chain rule through C = F^T F: second-order
/// dual numbers in the three entries of C (not the six of F: a quarter of the dual work).
/// With D = dC/dF (3x6, linear in F): H = D^T (d2Psi/dC2) D + sum_k dPsi/dC_k d2C_k/dF2.
fn derivatives_in_f(model: ConstitutiveModel, lame: Lame, f: &[f64; 6]) -> (f64, SVector<f64, 6>, SMatrix<f64, 6, 6>) {
    let (f1, f2) = (DVec3::new(f[0], f[1], f[2]), DVec3::new(f[3], f[4], f[5]));
    let c = [f1.dot(f1), f2.dot(f2), f1.dot(f2)];
    let cd: [Dual2SVec64<3>; 3] = std::array::from_fn(|i| Dual2SVec64::from_re(c[i]).derivative(i));
    let psi = membrane_psi_of_c(model, lame, cd);
    let pc = psi.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<3>);
    let hc = psi.v2.unwrap_generic(nalgebra::Const::<3>, nalgebra::Const::<3>);
    // Rows of D: dC11/dF = (2 f1, 0), dC22/dF = (0, 2 f2), dC12/dF = (f2, f1).
    let d = SMatrix::<f64, 3, 6>::from_row_slice(&[
        2.0 * f1.x,
        2.0 * f1.y,
        2.0 * f1.z,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        2.0 * f2.x,
        2.0 * f2.y,
        2.0 * f2.z,
        f2.x,
        f2.y,
        f2.z,
        f1.x,
        f1.y,
        f1.z,
    ]);
    let p = d.transpose() * pc.transpose();
    let mut h = d.transpose() * hc * d;
    for k in 0..3 {
        h[(k, k)] += 2.0 * pc[0];
        h[(k + 3, k + 3)] += 2.0 * pc[1];
        h[(k, k + 3)] += pc[2];
        h[(k + 3, k)] += pc[2];
    }
    (psi.re, p, h)
}

/// Projects the F-Hessian of an energy of C = F^T F in the frame of the deformed triangle.
/// With F = T A (T the triangle's tangent basis, n its normal), dC does not depend on the normal
/// part n db^T of dF, and dF^T dF has no cross term, so the Hessian splits into an in-plane 4x4
/// block and a normal 2x2 block (2 S, S the second Piola-Kirchhoff stress: negative under
/// compression): each is projected on its own. Returns false for a degenerate triangle.
fn project_in_triangle_frame(hf: &mut SMatrix<f64, 6, 6>, f: &[f64; 6], filter: Filter) -> bool {
    let f1 = DVec3::new(f[0], f[1], f[2]);
    let f2 = DVec3::new(f[3], f[4], f[5]);
    let n = f1.cross(f2);
    let (l1, ln) = (f1.length(), n.length());
    // (NaN-safe: a NaN length counts as degenerate)
    if ln.is_nan() || ln <= 1e-12 * l1 * f2.length() {
        return false;
    }
    let t1 = f1 / l1;
    let nn = n / ln;
    let t2 = nn.cross(t1);
    let q = nalgebra::Matrix3::from_columns(&[
        nalgebra::Vector3::new(t1.x, t1.y, t1.z),
        nalgebra::Vector3::new(t2.x, t2.y, t2.z),
        nalgebra::Vector3::new(nn.x, nn.y, nn.z),
    ]);
    // Local Hessian: each 3x3 block (column j of F, column l of F) becomes Q^T B Q.
    let mut local = SMatrix::<f64, 6, 6>::zeros();
    for j in 0..2 {
        for l in 0..2 {
            let b: nalgebra::Matrix3<f64> = hf.fixed_view::<3, 3>(3 * j, 3 * l).into_owned();
            local.fixed_view_mut::<3, 3>(3 * j, 3 * l).copy_from(&(q.transpose() * b * q));
        }
    }
    const IN_PLANE: [usize; 4] = [0, 1, 3, 4];
    const NORMAL: [usize; 2] = [2, 5];
    let mut a = SMatrix::<f64, 4, 4>::from_fn(|r, c| local[(IN_PLANE[r], IN_PLANE[c])]);
    let mut b = SMatrix::<f64, 2, 2>::from_fn(|r, c| local[(NORMAL[r], NORMAL[c])]);
    project(&mut a, filter);
    project(&mut b, filter);
    local.fill(0.0);
    for r in 0..4 {
        for c in 0..4 {
            local[(IN_PLANE[r], IN_PLANE[c])] = a[(r, c)];
        }
    }
    for r in 0..2 {
        for c in 0..2 {
            local[(NORMAL[r], NORMAL[c])] = b[(r, c)];
        }
    }
    for j in 0..2 {
        for l in 0..2 {
            let b: nalgebra::Matrix3<f64> = local.fixed_view::<3, 3>(3 * j, 3 * l).into_owned();
            hf.fixed_view_mut::<3, 3>(3 * j, 3 * l).copy_from(&(q * b * q.transpose()));
        }
    }
    true
}

/// Maps dPsi/dF and d2Psi/dF2 (F with NC columns of 3) to vertex gradient and Hessian through
/// F[:, j] = sum_v coef[v][j] x_v.
pub(crate) fn chain_to_vertices<const NF: usize, const NC: usize, const NV: usize, const NX: usize>(
    weight: f64,
    psi: f64,
    p: &SVector<f64, NF>,
    hf: &SMatrix<f64, NF, NF>,
    coef: &[[f64; NC]; NV],
) -> (f64, SVector<f64, NX>, SMatrix<f64, NX, NX>) {
    let mut g = SVector::<f64, NX>::zeros();
    for v in 0..NV {
        for j in 0..NC {
            for k in 0..3 {
                g[3 * v + k] += weight * coef[v][j] * p[3 * j + k];
            }
        }
    }
    // First contract the F-Hessian with coefficients along columns, then rows.
    let mut t = SMatrix::<f64, NX, NF>::zeros(); // t[(3v+k), (3l+m)] = sum_j c[v][j] hf[(3j+k),(3l+m)]
    for v in 0..NV {
        for j in 0..NC {
            let c = coef[v][j];
            for k in 0..3 {
                for q in 0..NF {
                    t[(3 * v + k, q)] += c * hf[(3 * j + k, q)];
                }
            }
        }
    }
    let mut h = SMatrix::<f64, NX, NX>::zeros();
    for w in 0..NV {
        for l in 0..NC {
            let c = weight * coef[w][l];
            for m in 0..3 {
                for r in 0..NX {
                    h[(r, 3 * w + m)] += c * t[(r, 3 * l + m)];
                }
            }
        }
    }
    (weight * psi, g, h)
}
