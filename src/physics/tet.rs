//! Tetrahedron (PHYSICS.md 1.3): energy = rest volume x Psi(F), F = Ds B, B = Dm^-1 F0.

use glam::{DMat3, DVec3};
use nalgebra::{Matrix3, SMatrix, SVector};
use num_dual::Dual2SVec64;

use super::material::{solid_psi, ConstitutiveModel, Lame};
use super::membrane::chain_to_vertices;
use super::psd::{project, Filter};

/// Rest data of one tetrahedron.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TetRest {
    pub b: DMat3,
    pub volume: f64,
}

impl TetRest {
    /// Rest data from rest positions and a prestrain F0. None if degenerate or inverted.
    pub fn from_rest(x: [DVec3; 4], f0: DMat3) -> Option<Self> {
        let dm = DMat3::from_cols(x[1] - x[0], x[2] - x[0], x[3] - x[0]);
        let det = dm.determinant();
        let scale = (x[1] - x[0]).length().max((x[2] - x[0]).length()).max((x[3] - x[0]).length());
        if det.is_nan() || det <= 1e-12 * scale * scale * scale {
            return None;
        }
        Some(TetRest { b: dm.inverse() * f0, volume: det / 6.0 })
    }
}

#[inline]
fn coefficients(b: &DMat3) -> [[f64; 3]; 4] {
    let row = |k: usize| [b.col(0)[k], b.col(1)[k], b.col(2)[k]];
    let (r0, r1, r2) = (row(0), row(1), row(2));
    [[-(r0[0] + r1[0] + r2[0]), -(r0[1] + r1[1] + r2[1]), -(r0[2] + r1[2] + r2[2])], r0, r1, r2]
}

#[inline]
fn deformation_gradient(rest: &TetRest, x: &[DVec3; 4]) -> [f64; 9] {
    let c = coefficients(&rest.b);
    let mut f = [0.0; 9];
    for j in 0..3 {
        let col = x[0] * c[0][j] + x[1] * c[1][j] + x[2] * c[2][j] + x[3] * c[3][j];
        f[3 * j] = col.x;
        f[3 * j + 1] = col.y;
        f[3 * j + 2] = col.z;
    }
    f
}

/// Energy only.
pub fn energy(model: ConstitutiveModel, lame: Lame, rest: &TetRest, x: &[DVec3; 4]) -> f64 {
    let f = deformation_gradient(rest, x);
    let psi = match model {
        ConstitutiveModel::Corotational => corotational(lame, &f).0,
        _ => solid_psi(model, lame, &f),
    };
    rest.volume * psi
}

/// Energy, gradient (12) and Hessian (12x12), projected at the F level (9x9).
pub fn eval(
    model: ConstitutiveModel,
    lame: Lame,
    rest: &TetRest,
    x: &[DVec3; 4],
    filter: Filter,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let f = deformation_gradient(rest, x);
    let (psi, p, mut hf) = match model {
        ConstitutiveModel::Corotational => corotational(lame, &f),
        // Projected in closed form: no 9x9 eigendecomposition needed afterwards.
        ConstitutiveModel::BazantHencky => {
            let (psi, p, hf) = super::principal::bazant_hencky(lame, &f, filter);
            return chain_to_vertices::<9, 3, 4, 12>(rest.volume, psi, &p, &hf, &coefficients(&rest.b));
        }
        ConstitutiveModel::StVenantKirchhoff => of_c(model, lame, &f),
        ConstitutiveModel::StableNeoHookean => {
            let fd: [Dual2SVec64<9>; 9] = std::array::from_fn(|i| Dual2SVec64::from_re(f[i]).derivative(i));
            let psi = solid_psi(model, lame, &fd);
            let p = psi.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<9>).transpose();
            (psi.re, p, psi.v2.unwrap_generic(nalgebra::Const::<9>, nalgebra::Const::<9>))
        }
    };
    project(&mut hf, filter);
    chain_to_vertices::<9, 3, 4, 12>(rest.volume, psi, &p, &hf, &coefficients(&rest.b))
}

/// Symmetric 3x3 index pairs in the order of C's six independent entries.
const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Energies of C = F^T F: second-order AD over C's six entries, then the chain rule to F in
/// closed form (dPsi/dF = 2 F G, d2Psi/dF2 = 2 G (x) I + 4 F H F), cheaper than AD over F.
fn of_c(model: ConstitutiveModel, lame: Lame, f: &[f64; 9]) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let col = |j: usize| DVec3::new(f[3 * j], f[3 * j + 1], f[3 * j + 2]);
    let cols = [col(0), col(1), col(2)];
    let c: [f64; 6] = PAIRS.map(|(a, b)| cols[a].dot(cols[b]));
    let cd: [Dual2SVec64<6>; 6] = std::array::from_fn(|i| Dual2SVec64::from_re(c[i]).derivative(i));
    let psi = solid_psi_of_c(model, lame, &cd);
    let d1 = psi.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<6>);
    let d2 = psi.v2.unwrap_generic(nalgebra::Const::<6>, nalgebra::Const::<6>);
    // Full symmetric-tensor derivatives: an off-diagonal entry of C appears twice.
    let index = |a: usize, b: usize| PAIRS.iter().position(|&(p, q)| (p, q) == (a.min(b), a.max(b))).unwrap();
    let scale = |a: usize, b: usize| if a == b { 1.0 } else { 0.5 };
    let g = |a: usize, b: usize| d1[index(a, b)] * scale(a, b);
    let h = |a: usize, b: usize, c: usize, d: usize| d2[(index(a, b), index(c, d))] * scale(a, b) * scale(c, d);
    let mut p = SVector::<f64, 9>::zeros();
    for a in 0..3 {
        let pa = (0..3).fold(DVec3::ZERO, |acc, b| acc + cols[b] * (2.0 * g(a, b)));
        p.fixed_rows_mut::<3>(3 * a).copy_from_slice(&pa.to_array());
    }
    let mut hf = SMatrix::<f64, 9, 9>::zeros();
    for a in 0..3 {
        for c in 0..3 {
            let mut block = nalgebra::Matrix3::identity() * (2.0 * g(a, c));
            for b in 0..3 {
                for d in 0..3 {
                    let k = 4.0 * h(a, b, c, d);
                    if k != 0.0 {
                        let (fb, fd) = (cols[b], cols[d]);
                        block += nalgebra::Matrix3::new(
                            fb.x * fd.x,
                            fb.x * fd.y,
                            fb.x * fd.z,
                            fb.y * fd.x,
                            fb.y * fd.y,
                            fb.y * fd.z,
                            fb.z * fd.x,
                            fb.z * fd.y,
                            fb.z * fd.z,
                        ) * k;
                    }
                }
            }
            hf.fixed_view_mut::<3, 3>(3 * a, 3 * c).copy_from(&block);
        }
    }
    (psi.re, p, hf)
}

/// Bazant-Hencky (H15 eq. 5.21) and StVK as functions of C = [c11, c22, c33, c12, c13, c23].
fn solid_psi_of_c<D: num_dual::DualNum<Primitive = f64> + Copy>(model: ConstitutiveModel, lame: Lame, c: &[D; 6]) -> D {
    let [c11, c22, c33, c12, c13, c23] = *c;
    let (mu, la) = (lame.mu, lame.lambda);
    match model {
        ConstitutiveModel::BazantHencky => {
            let (k11, k22, k33) = (c22 * c33 - c23 * c23, c11 * c33 - c13 * c13, c11 * c22 - c12 * c12);
            let det = c11 * k11 - c12 * (c12 * c33 - c23 * c13) + c13 * (c12 * c23 - c22 * c13);
            let tr_inv = (k11 + k22 + k33) / det;
            let ln_det = det.ln();
            (c11 + c22 + c33 + tr_inv - 6.0) * (mu / 4.0) + ln_det * ln_det * (la / 8.0)
        }
        _ => {
            let (e11, e22, e33) = ((c11 - 1.0) * 0.5, (c22 - 1.0) * 0.5, (c33 - 1.0) * 0.5);
            let tr_e = e11 + e22 + e33;
            let off = (c12 * c12 + c13 * c13 + c23 * c23) * 0.25;
            (e11 * e11 + e22 * e22 + e33 * e33 + off * 2.0) * mu + tr_e * tr_e * (la / 2.0)
        }
    }
}

/// Corotational linear energy in closed form: Psi = mu |F - R|^2 + lambda/2 (tr S - 3)^2.
/// P = 2 mu (F - R) + lambda (tr S - 3) R; dR/dF from the three twist modes of the SVD
/// (eigenvalues 2 / (s_i + s_j)).
fn corotational(lame: Lame, f: &[f64; 9]) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let fm = Matrix3::from_column_slice(f);
    let svd = fm.svd(true, true);
    let (u, vt, s) = (svd.u.unwrap(), svd.v_t.unwrap(), svd.singular_values);
    let r = u * vt;
    let tr_s = s.sum();
    let (mu, la) = (lame.mu, lame.lambda);
    let psi = mu * (fm - r).norm_squared() + 0.5 * la * (tr_s - 3.0) * (tr_s - 3.0);
    let p = (fm - r) * (2.0 * mu) + r * (la * (tr_s - 3.0));
    let vec = |m: &Matrix3<f64>| SVector::<f64, 9>::from_column_slice(m.as_slice());
    let rv = vec(&r);
    let mut h = SMatrix::<f64, 9, 9>::identity() * (2.0 * mu) + rv * rv.transpose() * la;
    let c = la * (tr_s - 3.0) - 2.0 * mu;
    let inv_sqrt2 = std::f64::consts::FRAC_1_SQRT_2;
    for (a, b) in [(0usize, 1usize), (1, 2), (0, 2)] {
        let mut t = Matrix3::zeros();
        t[(a, b)] = -inv_sqrt2;
        t[(b, a)] = inv_sqrt2;
        let ti = vec(&(u * t * vt));
        let denom = (s[a] + s[b]).max(1e-12);
        h += ti * ti.transpose() * (c * 2.0 / denom);
    }
    (psi, SVector::<f64, 9>::from_column_slice(p.as_slice()), h)
}
