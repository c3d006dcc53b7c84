//! One dilatation per cell of tetrahedra (issue 27): the bulk term of a volume layer's model,
//! lambda / 2 g(J)^2, evaluated once per hexahedral cell at the cell's volume ratio
//! J_c = sum_e V_e J_e / sum_e V_e instead of once per tetrahedron.
//!
//! Why: a linear tetrahedron has one volume constraint per element and a slab has about six
//! tetrahedra per vertex, so near incompressibility (lambda >> mu) the constraints outnumber the
//! three displacements per vertex and the mesh locks (VALIDATION.md case 8 at nu = 0.495: the
//! wavelength 11 % short, the onset 36 % late). One dilatation per cell of six tetrahedra (eight
//! vertices) leaves one constraint per vertex, as in the hexahedron with selectively reduced
//! integration of its volumetric term; for the lambda term it is the F-bar patch method (de
//! Souza Neto et al. 2005): the term sees F_bar = (J_c / J_e)^(1/3) F_e, whose determinant is J_c.
//!
//! Each model's lambda term is written as lambda / 2 g(J)^2: g = ln J for Bazant-Hencky (H15 eq.
//! 5.21: lambda / 8 ln^2 det C), g = J - 1 for Stable Neo-Hookean (its lambda term, alpha
//! expanded: the rest is a function of mu only), and g = J - 1 for the corotational and St.
//! Venant-Kirchhoff models, whose lambda terms (tr S - 3, tr E) equal J - 1 to first order in the
//! strain. The tetrahedra of such a layer are evaluated with lambda = 0.

use glam::DVec3;
use nalgebra::{Matrix3, SMatrix, SVector};
use serde::{Deserialize, Serialize};

use super::material::ConstitutiveModel;
use super::psd::Filter;

/// Where a volume layer evaluates its model's lambda term.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum VolumeElement {
    /// In every linear tetrahedron: locks as Poisson's ratio nears 0.5.
    #[default]
    Tet,
    /// Once per hexahedral cell of six tetrahedra, at the cell's volume ratio.
    Cell,
}

/// From this Poisson's ratio up a volume layer's default is `VolumeElement::Cell`. Measured on
/// VALIDATION.md case 7 (20 film elements per wavelength, 20 graded through the depth), onset
/// error per tet against per cell: nu 0.45 +0.7 / -1.2 %, 0.46 +1.7 / -1.4 %, 0.47 +2.5 / -1.6 %,
/// 0.48 +4.7 / -1.7 %, 0.49 +8.4 / -1.8 %, 0.495 +19 / -1.8 %; the cell costs about 1.2-1.3x
/// per increment (`cargo bench -p skinsim-cli --bench volume_element`).
pub(crate) const CELL_FROM_POISSON: f64 = 0.47;

impl VolumeElement {
    /// The default for a volume layer of Poisson's ratio `poisson`.
    pub(crate) fn default_for(poisson: f64) -> Self {
        if poisson >= CELL_FROM_POISSON {
            VolumeElement::Cell
        } else {
            VolumeElement::Tet
        }
    }
}

/// Vertices and tetrahedra of a cell: a hexahedron of the slab mesher (two prisms of three).
pub(crate) const CELL_VERTS: usize = 8;
pub(crate) const CELL_TETS: usize = 6;
const N: usize = 3 * CELL_VERTS;

/// The volume measure g(J) of a model's lambda term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dilatation {
    /// g = ln J (Bazant-Hencky).
    Log,
    /// g = J - 1.
    Linear,
}

impl Dilatation {
    pub fn of(model: ConstitutiveModel) -> Self {
        match model {
            ConstitutiveModel::BazantHencky => Dilatation::Log,
            _ => Dilatation::Linear,
        }
    }

    /// (g, g', g'') at J; g = +inf (no energy defined) for J <= 0 with the log measure.
    #[inline]
    fn at(self, j: f64) -> (f64, f64, f64) {
        match self {
            Dilatation::Log if j > 0.0 => (j.ln(), 1.0 / j, -1.0 / (j * j)),
            Dilatation::Log => (f64::INFINITY, f64::INFINITY, f64::INFINITY),
            Dilatation::Linear => (j - 1.0, 1.0, 0.0),
        }
    }
}

/// Rest data of one cell: its tetrahedra (corner indices into the cell's vertices), each one's
/// weight w_e = V_e det(B_e) (so that V_e J_e = w_e det(Ds_e), prestrain included), the cell's
/// rest volume and its bulk stiffness sum_e lambda_e V_e.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellRest {
    pub tets: [[u8; 4]; CELL_TETS],
    pub weight: [f64; CELL_TETS],
    pub volume: f64,
    pub bulk: f64,
    pub dilatation: Dilatation,
}

#[inline]
fn det_ds(x: &[DVec3; CELL_VERTS], t: [u8; 4]) -> f64 {
    let p = t.map(|i| x[i as usize]);
    (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0]))
}

/// The cell's volume ratio J_c.
pub(crate) fn volume_ratio(rest: &CellRest, x: &[DVec3; CELL_VERTS]) -> f64 {
    (0..CELL_TETS).map(|e| rest.weight[e] * det_ds(x, rest.tets[e])).sum::<f64>() / rest.volume
}

/// Energy only: bulk / 2 g(J_c)^2.
pub fn energy(rest: &CellRest, x: &[DVec3; CELL_VERTS]) -> f64 {
    let (g, _, _) = rest.dilatation.at(volume_ratio(rest, x));
    0.5 * rest.bulk * g * g
}

fn skew(v: DVec3) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Energy, gradient (24) and Hessian (24 x 24). With E = B/2 g^2: dE = B g g' dJ and
/// d2E = B (g'^2 + g g'') dJ dJ^T + B g g' d2J. A projecting filter keeps the first term only
/// (positive semi-definite while g'^2 + g g'' >= 0, that is J <= e for the log measure): the
/// second, the curvature of the volume, is indefinite and vanishes with g at the rest volume.
pub fn eval(rest: &CellRest, x: &[DVec3; CELL_VERTS], filter: Filter) -> (f64, SVector<f64, N>, SMatrix<f64, N, N>) {
    let mut dj = SVector::<f64, N>::zeros();
    let mut j = 0.0;
    let exact = filter == Filter::Exact;
    // d2 det(Ds) summed over the tetrahedra: the exact Hessian only.
    let mut curvature = exact.then(SMatrix::<f64, N, N>::zeros);
    for (e, t) in rest.tets.iter().enumerate() {
        let w = rest.weight[e] / rest.volume;
        let p = t.map(|i| x[i as usize]);
        let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
        j += w * e1.dot(e2.cross(e3));
        // d det / d x_1..3 = e2 x e3, e3 x e1, e1 x e2; d / d x_0 = minus their sum.
        let g = [e2.cross(e3), e3.cross(e1), e1.cross(e2)];
        let g0 = -(g[0] + g[1] + g[2]);
        for (k, gk) in [g0, g[0], g[1], g[2]].into_iter().enumerate() {
            let r = 3 * t[k] as usize;
            dj[r] += w * gk.x;
            dj[r + 1] += w * gk.y;
            dj[r + 2] += w * gk.z;
        }
        if let Some(curvature) = curvature.as_mut() {
            // Blocks d2 det / dx_a dx_b (a, b = 1..3): H12 = -[e3], H13 = [e2], H23 = -[e1]
            // (skew cross-product matrices), symmetric overall; rows of x_0 minus the sums.
            let mut hb = [[Matrix3::zeros(); 3]; 3];
            hb[0][1] = -skew(e3);
            hb[0][2] = skew(e2);
            hb[1][2] = -skew(e1);
            (hb[1][0], hb[2][0], hb[2][1]) = (hb[0][1].transpose(), hb[0][2].transpose(), hb[1][2].transpose());
            let mut full = [[Matrix3::zeros(); 4]; 4];
            for a in 0..3 {
                for b in 0..3 {
                    full[a + 1][b + 1] = hb[a][b];
                    full[0][b + 1] -= hb[a][b];
                    full[a + 1][0] -= hb[a][b];
                    full[0][0] += hb[a][b];
                }
            }
            for a in 0..4 {
                for b in 0..4 {
                    let (ra, rb) = (3 * t[a] as usize, 3 * t[b] as usize);
                    let mut view = curvature.fixed_view_mut::<3, 3>(ra, rb);
                    view += full[a][b] * w;
                }
            }
        }
    }
    let (g, g1, g2) = rest.dilatation.at(j);
    let b = rest.bulk;
    let energy = 0.5 * b * g * g;
    let grad = dj * (b * g * g1);
    let mut h = dj * dj.transpose() * (b * (g1 * g1 + g * g2));
    match curvature {
        Some(c) => h += c * (b * g * g1),
        // Projected: the Gauss-Newton part, with a negative coefficient (J > e) dropped.
        None if g1 * g1 + g * g2 < 0.0 => h.fill(0.0),
        None => {}
    }
    (energy, grad, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// The slab mesher's cell: corners 0-3 at the bottom (i, j), (i+1, j), (i+1, j+1), (i, j+1),
    /// 4-7 above them; its six tets as `tet_slab` makes them.
    fn unit_cell(model: ConstitutiveModel, bulk_density: f64) -> (CellRest, [DVec3; 8]) {
        let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        let x: [DVec3; 8] = std::array::from_fn(|i| {
            let (a, b) = corners[i % 4];
            DVec3::new(a, b, (i / 4) as f64)
        });
        let mut tets = Vec::new();
        for tri in [[0u8, 1, 2], [0, 2, 3]] {
            let (i0, j0, k0) = (tri[0], tri[1], tri[2]);
            for t in [[i0, j0, k0, k0 + 4], [i0, j0, j0 + 4, k0 + 4], [i0, i0 + 4, j0 + 4, k0 + 4]] {
                let mut t = t;
                if det_ds(&x, t) < 0.0 {
                    t.swap(1, 2);
                }
                tets.push(t);
            }
        }
        let tets: [[u8; 4]; 6] = tets.try_into().unwrap();
        // w_e = V_e det(Dm_e^-1) = 1 / 6 without prestrain.
        let weight = [1.0 / 6.0; 6];
        let rest = CellRest { tets, weight, volume: 1.0, bulk: bulk_density, dilatation: Dilatation::of(model) };
        (rest, x)
    }

    fn deformed(x: &[DVec3; 8], seed: f64, scale: f64) -> [DVec3; 8] {
        std::array::from_fn(|i| {
            let s = seed + i as f64;
            x[i] + scale * DVec3::new((1.3 * s).sin(), (2.1 * s).cos(), (0.7 * s + 1.0).sin())
        })
    }

    #[test]
    fn rest_volume_and_weights_are_consistent() {
        let (rest, x) = unit_cell(ConstitutiveModel::BazantHencky, 1.0);
        assert!((volume_ratio(&rest, &x) - 1.0).abs() < 1e-14);
        let tets_volume: f64 = rest.tets.iter().map(|&t| det_ds(&x, t) / 6.0).sum();
        assert!((tets_volume - 1.0).abs() < 1e-14, "the six tets fill the cell: {tets_volume}");
        let (e, g, _) = eval(&rest, &x, Filter::Exact);
        assert!(e.abs() < 1e-30 && g.norm() < 1e-14, "rest state: zero energy and force");
    }

    /// VALIDATION.md A1: gradient and Hessian against central differences, both measures,
    /// compressed, stretched and strongly distorted cells.
    #[test]
    fn derivatives_match_central_differences() {
        for model in [ConstitutiveModel::BazantHencky, ConstitutiveModel::StableNeoHookean] {
            let (rest, x0) = unit_cell(model, 2.5);
            // The last cell is inverted (J_c < 0): allowed by the linear measure only.
            for (seed, scale, squash) in
                [(0.3, 0.05, 1.0), (1.7, 0.2, 0.6), (4.1, 0.3, 1.3), (2.2, 0.01, 0.2), (3.3, 0.1, -0.4)]
            {
                let mut x = deformed(&x0, seed, scale);
                x.iter_mut().for_each(|p| p.z *= squash);
                let (e, g, h) = eval(&rest, &x, Filter::Exact);
                if squash < 0.0 {
                    assert!(volume_ratio(&rest, &x) < 0.0);
                    if rest.dilatation == Dilatation::Log {
                        assert!(e.is_infinite(), "no Bazant-Hencky energy for an inverted cell");
                        continue;
                    }
                }
                assert!((e - energy(&rest, &x)).abs() <= 1e-14 * e.abs().max(1e-14));
                let shifted = |k: usize, d: f64| {
                    let mut y = x;
                    y[k / 3][k % 3] += d;
                    y
                };
                let mut best_g: f64 = f64::INFINITY;
                let mut best_h: f64 = f64::INFINITY;
                for step in [1e-4, 1e-5, 1e-6, 1e-7, 1e-8] {
                    let fd_g = SVector::<f64, N>::from_fn(|k, _| {
                        (energy(&rest, &shifted(k, step)) - energy(&rest, &shifted(k, -step))) / (2.0 * step)
                    });
                    best_g = best_g.min((fd_g - g).norm() / g.norm());
                    let mut fd_h = SMatrix::<f64, N, N>::zeros();
                    for k in 0..N {
                        let col = (eval(&rest, &shifted(k, step), Filter::Exact).1
                            - eval(&rest, &shifted(k, -step), Filter::Exact).1)
                            / (2.0 * step);
                        fd_h.set_column(k, &col);
                    }
                    best_h = best_h.min((fd_h - h).norm() / h.norm());
                }
                assert!(best_g < 1e-6 && best_h < 1e-6, "{model:?} {seed}: gradient {best_g:e}, Hessian {best_h:e}");
                assert!((h - h.transpose()).norm() <= 1e-12 * h.norm());
            }
        }
    }

    /// VALIDATION.md A2: rotations and translations change neither J_c nor the energy.
    #[test]
    fn rigid_motions_leave_no_energy() {
        let (rest, x0) = unit_cell(ConstitutiveModel::BazantHencky, 1.0);
        let x = deformed(&x0, 0.9, 0.1);
        let r = DMat3::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 2.0);
        let moved: [DVec3; 8] = std::array::from_fn(|i| r * x[i] + DVec3::new(3.0, -2.0, 0.5));
        assert!((energy(&rest, &moved) - energy(&rest, &x)).abs() < 1e-13 * energy(&rest, &x));
        let rigid: [DVec3; 8] = std::array::from_fn(|i| r * x0[i] + DVec3::new(3.0, -2.0, 0.5));
        let (e, g, _) = eval(&rest, &rigid, Filter::Exact);
        assert!(e < 1e-28 && g.norm() < 1e-13, "{e} {}", g.norm());
    }

    /// VALIDATION.md A3 for the split: under a uniform deformation (every J_e = J_c) the tets
    /// with lambda = 0 plus the cell have the energy and forces of the tets with their lambda, for
    /// the models whose lambda term is exactly lambda / 2 g(J)^2; to second order in the strain for
    /// the others.
    #[test]
    fn split_matches_the_per_tet_model_under_uniform_deformation() {
        use super::super::material::Lame;
        use super::super::tet;
        let lame = Lame::solid(1.0, 0.45);
        for (model, exact) in [
            (ConstitutiveModel::BazantHencky, true),
            (ConstitutiveModel::StableNeoHookean, true),
            (ConstitutiveModel::Corotational, false),
            (ConstitutiveModel::StVenantKirchhoff, false),
        ] {
            let (mut rest, x0) = unit_cell(model, 0.0);
            rest.bulk = lame.lambda * rest.volume;
            for strain in [1e-3, 0.1] {
                let f = glam::DMat3::from_cols_array(&[
                    1.0 - strain,
                    0.2 * strain,
                    0.0,
                    0.1 * strain,
                    1.0,
                    0.3 * strain,
                    0.0,
                    0.0,
                    1.0 + 0.5 * strain,
                ]);
                let x: [DVec3; 8] = std::array::from_fn(|i| f * x0[i]);
                let (mut e_full, mut g_full) = (0.0, SVector::<f64, N>::zeros());
                let (mut e_split, mut g_split) = cell_parts(&rest, &x);
                for t in rest.tets {
                    let tr = tet::TetRest::from_rest(t.map(|i| x0[i as usize]), glam::DMat3::IDENTITY).unwrap();
                    let xt = t.map(|i| x[i as usize]);
                    let full = tet::eval(model, lame, &tr, &xt, Filter::Exact);
                    let dev = tet::eval(model, Lame { lambda: 0.0, ..lame }, &tr, &xt, Filter::Exact);
                    e_full += full.0;
                    e_split += dev.0;
                    for (k, &c) in t.iter().enumerate() {
                        for d in 0..3 {
                            g_full[3 * c as usize + d] += full.1[3 * k + d];
                            g_split[3 * c as usize + d] += dev.1[3 * k + d];
                        }
                    }
                }
                // Exact: to the round-off of densities that cancel O(1) terms (scale: the energy
                // at unit strain); else to O(strain) relative.
                let scale = lame.mu + lame.lambda;
                let (tol_e, tol_g) = if exact {
                    (1e-13 * scale, 1e-12 * scale)
                } else {
                    (5.0 * strain * e_full, 5.0 * strain * g_full.norm())
                };
                assert!((e_split - e_full).abs() < tol_e, "{model:?} {strain}: {e_split} vs {e_full}");
                assert!((g_split - g_full).norm() < tol_g, "{model:?} {strain}: {}", (g_split - g_full).norm());
            }
        }
    }

    fn cell_parts(rest: &CellRest, x: &[DVec3; 8]) -> (f64, SVector<f64, N>) {
        let (e, g, _) = eval(rest, x, Filter::Exact);
        (e, g)
    }

    /// VALIDATION.md A4: the projected Hessian is positive semi-definite, inverted cells and
    /// J > e included (then it is zero).
    #[test]
    fn projected_hessian_is_psd() {
        for model in [ConstitutiveModel::BazantHencky, ConstitutiveModel::Corotational] {
            let (rest, x0) = unit_cell(model, 1.0);
            for (seed, scale, stretch) in [(0.1, 0.3, 1.0), (2.0, 0.1, 0.3), (5.0, 0.2, 3.0), (1.0, 0.05, -0.5)] {
                let mut x = deformed(&x0, seed, scale);
                x.iter_mut().for_each(|p| p.z *= stretch);
                for filter in [Filter::Clamp, Filter::Abs] {
                    let (e, _, h) = eval(&rest, &x, filter);
                    if !e.is_finite() {
                        continue; // an inverted cell under the log measure has no energy
                    }
                    let eig = nalgebra::SymmetricEigen::new(h).eigenvalues;
                    let max = eig.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(eig.iter().all(|&v| v >= -1e-12 * max.max(1e-30)), "{model:?} {stretch}: {eig:?}");
                }
            }
        }
    }
}
