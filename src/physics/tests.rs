//! VALIDATION.md A1-A4 for every element.

use super::hinge::{self, HingeModel, HingeRest};
use super::material::{membrane_psi, solid_psi, ConstitutiveModel as M, Lame};
use super::membrane::{self, MembraneRest};
use super::psd::Filter;
use super::tet::{self, TetRest};
use glam::{DMat2, DMat3, DQuat, DVec3};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use num_dual::Dual2SVec64;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

const MEMBRANE_MODELS: [M; 4] = [M::BazantHencky, M::StableNeoHookean, M::StVenantKirchhoff, M::Corotational];
const SOLID_MODELS: [M; 4] = [M::BazantHencky, M::StableNeoHookean, M::StVenantKirchhoff, M::Corotational];
const HINGE_MODELS: [HingeModel; 3] = [HingeModel::Linear, HingeModel::Sin, HingeModel::Tan];

fn config() -> Config {
    Config { cases: 48, rng_seed: RngSeed::Fixed(20261122), failure_persistence: None, ..Config::default() }
}

/// A1: best relative error of central differences over steps 1e-4 .. 1e-8 (scaled by the
/// configuration's size) for the gradient (from the energy) and the Hessian (from the gradient).
fn fd_errors<F, G>(x: &[f64], energy: F, eval: G) -> (f64, f64)
where
    F: Fn(&[f64]) -> f64,
    G: Fn(&[f64]) -> (DVector<f64>, DMatrix<f64>),
{
    let (g, h) = eval(x);
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    let (mut best_g, mut best_h) = (f64::INFINITY, f64::INFINITY);
    for p in 4..=8 {
        let step = 10f64.powi(-p) * scale;
        let n = x.len();
        let mut gfd = DVector::zeros(n);
        let mut hfd = DMatrix::zeros(n, n);
        for i in 0..n {
            let mut xp = x.to_vec();
            let mut xm = x.to_vec();
            xp[i] += step;
            xm[i] -= step;
            gfd[i] = (energy(&xp) - energy(&xm)) / (2.0 * step);
            let col = (eval(&xp).0 - eval(&xm).0) / (2.0 * step);
            hfd.set_column(i, &col);
        }
        best_g = best_g.min((&gfd - &g).norm() / g.norm().max(1e-300));
        best_h = best_h.min((&hfd - &h).norm() / h.norm().max(1e-300));
    }
    (best_g, best_h)
}

fn v3(x: &[f64], i: usize) -> DVec3 {
    DVec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

fn membrane_case(model: M, rest_tri: [DVec3; 3], x: [DVec3; 3]) -> (f64, f64) {
    let lame = Lame::plane_stress(2.0e6, 0.45);
    let rest = MembraneRest::from_rest_triangle(rest_tri, 1e-4, DMat2::IDENTITY).unwrap();
    let flat: Vec<f64> = x.iter().flat_map(|v| v.to_array()).collect();
    let tri = |x: &[f64]| [v3(x, 0), v3(x, 1), v3(x, 2)];
    fd_errors(
        &flat,
        |x| membrane::energy(model, lame, &rest, &tri(x)),
        |x| {
            let (_, g, h) = membrane::eval(model, lame, &rest, &tri(x), Filter::Exact);
            (DVector::from_column_slice(g.as_slice()), DMatrix::from_column_slice(9, 9, h.as_slice()))
        },
    )
}

fn tet_case(model: M, rest_x: [DVec3; 4], x: [DVec3; 4]) -> (f64, f64) {
    let lame = Lame::solid(1.0e4, 0.45);
    let rest = TetRest::from_rest(rest_x, DMat3::IDENTITY).unwrap();
    let flat: Vec<f64> = x.iter().flat_map(|v| v.to_array()).collect();
    let tet4 = |x: &[f64]| [v3(x, 0), v3(x, 1), v3(x, 2), v3(x, 3)];
    fd_errors(
        &flat,
        |x| tet::energy(model, lame, &rest, &tet4(x)),
        |x| {
            let (_, g, h) = tet::eval(model, lame, &rest, &tet4(x), Filter::Exact);
            (DVector::from_column_slice(g.as_slice()), DMatrix::from_column_slice(12, 12, h.as_slice()))
        },
    )
}

fn hinge_case(model: HingeModel, rest_x: [DVec3; 4], x: [DVec3; 4]) -> (f64, f64) {
    let rest = HingeRest::from_rest(model, 1e-6, rest_x);
    let flat: Vec<f64> = x.iter().flat_map(|v| v.to_array()).collect();
    let h4 = |x: &[f64]| [v3(x, 0), v3(x, 1), v3(x, 2), v3(x, 3)];
    fd_errors(
        &flat,
        |x| hinge::energy(model, &rest, &h4(x)),
        |x| {
            let (_, g, h) = hinge::eval(model, &rest, &h4(x), Filter::Exact);
            (DVector::from_column_slice(g.as_slice()), DMatrix::from_column_slice(12, 12, h.as_slice()))
        },
    )
}

fn vec3() -> impl Strategy<Value = DVec3> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_map(|(a, b, c)| DVec3::new(a, b, c))
}

/// A rest triangle in mm: well shaped, or a sliver (aspect down to 1e-3).
fn rest_triangle() -> impl Strategy<Value = [DVec3; 3]> {
    (prop_oneof![Just(1.0), Just(1e-3)], 0.2f64..0.8)
        .prop_map(|(aspect, s)| [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(s * 1e-3, aspect * 1e-3, 0.0)])
}

/// Deformed configuration: the rest shape stretched or compressed (to 30 %), sheared and moved.
fn deform<const N: usize>(rest: [DVec3; N], sx: f64, sy: f64, noise: [DVec3; N]) -> [DVec3; N] {
    let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
    std::array::from_fn(|i| {
        let p = rest[i];
        q * DVec3::new(p.x * sx, p.y * sy + 0.2 * p.x, p.z) + noise[i] * 2e-5 + DVec3::splat(1e-3)
    })
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn a1_membrane_derivatives(rest in rest_triangle(), sx in 0.3f64..1.6, sy in 0.3f64..1.6,
                               n in proptest::array::uniform3(vec3()), zlift in -0.3f64..0.3) {
        let mut x = deform(rest, sx, sy, n);
        x[2].z += zlift * 1e-3;
        for model in MEMBRANE_MODELS {
            let (eg, eh) = membrane_case(model, rest, x);
            prop_assert!(eg < 1e-6 && eh < 1e-6, "{model:?}: gradient {eg:e}, Hessian {eh:e}");
        }
    }

    #[test]
    fn a1_tet_derivatives(sx in 0.3f64..1.6, sz in 0.3f64..1.6, n in proptest::array::uniform4(vec3()),
                          invert in proptest::bool::ANY) {
        let rest = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 1e-3, 0.0), DVec3::new(0.2e-3, 0.3e-3, 1e-3)];
        let mut x = deform(rest, sx, 1.0, n);
        for (i, p) in x.iter_mut().enumerate() { p.z += (rest[i].z) * (sz - 1.0); }
        for model in SOLID_MODELS {
            let mut x = x;
            // Inversion only where the model is defined there (Stable Neo-Hookean).
            if invert && model == M::StableNeoHookean { x[3] = x[0] + (x[0] - x[3]) * 0.3; }
            let (eg, eh) = tet_case(model, rest, x);
            prop_assert!(eg < 1e-6 && eh < 1e-6, "{model:?}: gradient {eg:e}, Hessian {eh:e}");
        }
    }

    #[test]
    fn a1_hinge_derivatives(bend in -2.5f64..2.5, n in proptest::array::uniform4(vec3()), sliver in proptest::bool::ANY) {
        let h = if sliver { 1e-3 } else { 1.0 };
        let rest = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.4e-3, h * 1e-3, 0.0), DVec3::new(0.6e-3, -1e-3, 0.0)];
        let (s, c) = bend.sin_cos();
        let mut x = rest;
        x[3] = DVec3::new(0.6e-3, -1e-3 * c, -1e-3 * s);
        for (p, d) in x.iter_mut().zip(n) { *p += d * 2e-5 * h; }
        for model in HINGE_MODELS {
            let (eg, eh) = hinge_case(model, rest, x);
            prop_assert!(eg < 1e-6 && eh < 1e-6, "{model:?}: gradient {eg:e}, Hessian {eh:e}");
        }
    }
}

fn random_rigid(seed: u64) -> (DQuat, DVec3) {
    let a = (seed as f64 * 0.37).sin() * 3.0;
    (DQuat::from_euler(glam::EulerRot::ZYX, a, 1.3 - a, 0.4 * a), DVec3::new(a, -2.0 * a, 0.5))
}

/// A2: rigid motions of the rest shape carry no energy and no force; the rest state no force.
#[test]
fn a2_rigid_invariance() {
    let lame_m = Lame::plane_stress(1e6, 0.3);
    let lame_s = Lame::solid(1e6, 0.3);
    let tri = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 0.8e-3, 0.0)];
    let tet4 =
        [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 1e-3, 0.0), DVec3::new(0.2e-3, 0.3e-3, 1e-3)];
    let quad = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.4e-3, 1e-3, 0.0), DVec3::new(0.6e-3, -1e-3, 0.0)];
    for seed in 0..8 {
        let (q, t) = random_rigid(seed);
        let mv = |p: DVec3| q * p + t;
        let mrest = MembraneRest::from_rest_triangle(tri, 1e-4, DMat2::IDENTITY).unwrap();
        let force_scale = lame_m.mu * mrest.volume / 1e-3;
        for model in MEMBRANE_MODELS {
            let (e, g, _) = membrane::eval(model, lame_m, &mrest, &tri.map(mv), Filter::Exact);
            assert!(e.abs() < 1e-10 * force_scale * 1e-3, "{model:?} energy {e:e}");
            assert!(g.norm() < 1e-8 * force_scale, "{model:?} force {:e}", g.norm());
        }
        let trest = TetRest::from_rest(tet4, DMat3::IDENTITY).unwrap();
        let force_scale = lame_s.mu * trest.volume / 1e-3;
        for model in SOLID_MODELS {
            let (e, g, _) = tet::eval(model, lame_s, &trest, &tet4.map(mv), Filter::Exact);
            assert!(e.abs() < 1e-10 * force_scale * 1e-3, "{model:?} energy {e:e}");
            assert!(g.norm() < 1e-8 * force_scale, "{model:?} force {:e}", g.norm());
        }
        for model in HINGE_MODELS {
            let hrest = HingeRest::from_rest(model, 1e-6, quad);
            let (e, g, _) = hinge::eval(model, &hrest, &quad.map(mv), Filter::Exact);
            assert!(e.abs() < 1e-20 && g.norm() < 1e-14, "{model:?} {e:e} {:e}", g.norm());
            // A bent rest state stays force free under rigid motion too.
            let mut bent = quad;
            bent[3].z = 0.4e-3;
            let hrest = HingeRest::from_rest(model, 1e-6, bent);
            let (e, g, _) = hinge::eval(model, &hrest, &bent.map(mv), Filter::Exact);
            assert!(e.abs() < 1e-18 && g.norm() < 1e-12, "{model:?} bent {e:e} {:e}", g.norm());
        }
    }
}

/// A3: at F = I the Hessian in F equals linear elasticity mu (I + T) + lambda vec(I) vec(I)^T.
#[test]
fn a3_linearization_matches_linear_elasticity() {
    let lame = Lame { mu: 3.0e5, lambda: 7.0e5 };
    // Membrane: F is 3x2; in-plane entries (F11, F21, F12, F22) are indices 0, 1, 3, 4.
    for model in MEMBRANE_MODELS {
        let f: [f64; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let fd: [Dual2SVec64<6>; 6] = std::array::from_fn(|i| Dual2SVec64::from_re(f[i]).derivative(i));
        let psi = membrane_psi(model, lame, &fd);
        let h = psi.v2.unwrap_generic(nalgebra::Const::<6>, nalgebra::Const::<6>);
        let g = psi.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<6>);
        assert!(g.norm() < 1e-6, "{model:?}: rest stress {g}");
        let idx = [(0usize, 0usize, 0usize), (1, 1, 0), (3, 0, 1), (4, 1, 1)]; // (flat, row, col)
        for &(a, ia, ja) in &idx {
            for &(b, ib, jb) in &idx {
                let lin = lame.mu * (((ia == ib) && (ja == jb)) as u8 as f64 + ((ia == jb) && (ja == ib)) as u8 as f64)
                    + lame.lambda * ((ia == ja) && (ib == jb)) as u8 as f64;
                assert!((h[(a, b)] - lin).abs() < 1e-6 * lame.lambda, "{model:?} ({a},{b}): {} vs {lin}", h[(a, b)]);
            }
        }
    }
    for model in [M::BazantHencky, M::StableNeoHookean, M::StVenantKirchhoff] {
        let f: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let fd: [Dual2SVec64<9>; 9] = std::array::from_fn(|i| Dual2SVec64::from_re(f[i]).derivative(i));
        let psi = solid_psi(model, lame, &fd);
        let h = psi.v2.unwrap_generic(nalgebra::Const::<9>, nalgebra::Const::<9>);
        for a in 0..9 {
            for b in 0..9 {
                let (ia, ja, ib, jb) = (a % 3, a / 3, b % 3, b / 3);
                let lin = lame.mu * (((ia == ib) && (ja == jb)) as u8 as f64 + ((ia == jb) && (ja == ib)) as u8 as f64)
                    + lame.lambda * ((ia == ja) && (ib == jb)) as u8 as f64;
                assert!((h[(a, b)] - lin).abs() < 1e-6 * lame.lambda, "{model:?} ({a},{b}): {} vs {lin}", h[(a, b)]);
            }
        }
    }
    // Corotational solid: through the element (its F-Hessian is closed form).
    let rest = TetRest::from_rest([DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z], DMat3::IDENTITY).unwrap();
    let (_, _, h) =
        tet::eval(M::Corotational, lame, &rest, &[DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z], Filter::Exact);
    let (_, _, h_bh) =
        tet::eval(M::BazantHencky, lame, &rest, &[DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z], Filter::Exact);
    assert!((h - h_bh).norm() < 1e-6 * h.norm(), "corotational linearization differs");
}

/// A4: projected element Hessians have no eigenvalue below the floor (up to round-off).
#[test]
fn a4_projected_element_hessians_are_psd() {
    let lame = Lame::plane_stress(1e6, 0.45);
    let tri = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 0.8e-3, 0.0)];
    let rest = MembraneRest::from_rest_triangle(tri, 1e-4, DMat2::IDENTITY).unwrap();
    let squashed = [tri[0], DVec3::new(0.4e-3, 0.0, 0.0), DVec3::new(0.1e-3, 0.3e-3, 0.05e-3)];
    let min_eig = |h: DMatrix<f64>| {
        let e = SymmetricEigen::new(h.clone()).eigenvalues;
        (e.min(), e.amax())
    };
    for model in MEMBRANE_MODELS {
        let (_, _, exact) = membrane::eval(model, lame, &rest, &squashed, Filter::Exact);
        let (lo, _) = min_eig(DMatrix::from_column_slice(9, 9, exact.as_slice()));
        for filter in [Filter::Clamp, Filter::Abs] {
            let (_, _, h) = membrane::eval(model, lame, &rest, &squashed, filter);
            let (lo_p, hi) = min_eig(DMatrix::from_column_slice(9, 9, h.as_slice()));
            assert!(lo_p >= -1e-10 * hi, "{model:?} {filter:?}: {lo_p:e} (exact {lo:e})");
        }
    }
    let quad = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.4e-3, 1e-3, 0.0), DVec3::new(0.6e-3, -1e-3, 0.0)];
    let mut bent = quad;
    bent[3].z = -0.9e-3;
    for model in HINGE_MODELS {
        let rest = HingeRest::from_rest(model, 1e-6, quad);
        let (_, _, h) = hinge::eval(model, &rest, &bent, Filter::Clamp);
        let (lo, hi) = min_eig(DMatrix::from_column_slice(12, 12, h.as_slice()));
        assert!(lo >= -1e-10 * hi, "{model:?}: {lo:e}");
    }
    let lame = Lame::solid(1e4, 0.45);
    let tet4 =
        [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 1e-3, 0.0), DVec3::new(0.2e-3, 0.3e-3, 1e-3)];
    let rest = TetRest::from_rest(tet4, DMat3::IDENTITY).unwrap();
    let mut squashed = tet4;
    squashed[3] = DVec3::new(0.2e-3, 0.3e-3, 0.2e-3);
    for model in SOLID_MODELS {
        for filter in [Filter::Clamp, Filter::Abs] {
            let (_, _, h) = tet::eval(model, lame, &rest, &squashed, filter);
            let (lo, hi) = min_eig(DMatrix::from_column_slice(12, 12, h.as_slice()));
            assert!(lo >= -1e-10 * hi, "{model:?} {filter:?}: {lo:e}");
        }
    }
}

/// The in-plane / normal split of the membrane projection equals a full 6x6 projection.
#[test]
fn a4_membrane_block_projection_matches_full_projection() {
    use super::psd::project;
    let lame = Lame::plane_stress(1e6, 0.45);
    let tri = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 0.8e-3, 0.0)];
    let rest = MembraneRest::from_rest_triangle(tri, 1e-4, DMat2::IDENTITY).unwrap();
    let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.4, 0.2, -0.9);
    for (sx, sy) in [(0.5, 0.9), (0.7, 1.2), (1.1, 0.6), (0.4, 0.4)] {
        let x = tri.map(|p| q * DVec3::new(p.x * sx, p.y * sy + 0.1 * p.x, 0.0));
        for model in MEMBRANE_MODELS {
            for filter in [Filter::Clamp, Filter::Abs] {
                let (_, _, h) = membrane::eval(model, lame, &rest, &x, filter);
                // Reference: project the exact element Hessian's F-level matrix in full.
                let (_, _, exact) = membrane::eval(model, lame, &rest, &x, Filter::Exact);
                let mut full = exact;
                project(&mut full, filter);
                let (lo, hi) = {
                    let e = SymmetricEigen::new(DMatrix::from_column_slice(9, 9, h.as_slice())).eigenvalues;
                    (e.min(), e.amax())
                };
                assert!(lo >= -1e-10 * hi, "{model:?} {filter:?}: {lo:e}");
                // Same spectrum magnitude as projecting the exact Hessian directly.
                assert!((h.norm() - full.norm()).abs() < 0.5 * full.norm(), "{model:?} {filter:?}");
            }
        }
    }
}

/// A1 and A2 for zero-length springs: gradient against central differences of the energy,
/// rigid invariance and no force at rest.
#[test]
fn a1_a2_springs() {
    use super::spring;
    let k = 3.7e2;
    let (a, b) = (DVec3::new(1e-3, -2e-3, 0.5e-3), DVec3::new(-0.4e-3, 1e-3, 2e-3));
    let g = spring::gradient(k, a, b);
    for i in 0..3 {
        let mut best = f64::INFINITY;
        for p in 4..=8 {
            let h = 10f64.powi(-p) * 1e-3;
            let (mut ap, mut am) = (a, a);
            ap[i] += h;
            am[i] -= h;
            let fd = (spring::energy(k, ap, b) - spring::energy(k, am, b)) / (2.0 * h);
            best = best.min((fd - g[i]).abs() / g.length());
        }
        assert!(best < 1e-6, "component {i}: {best:e}");
    }
    let (q, t) = random_rigid(3);
    let e0 = spring::energy(k, a, b);
    assert!((spring::energy(k, q * a + t, q * b + t) - e0).abs() < 1e-12 * e0);
    assert_eq!(spring::gradient(k, a, a), DVec3::ZERO);
}

/// A1 for anchor springs at a face barycentre: gradient and Hessian against central differences,
/// no force when the skin point sits on its anchor.
#[test]
fn a1_anchor_springs() {
    use super::spring::anchor_eval;
    let (k, w) = (2.5e3, [0.2, 0.3, 0.5]);
    let x = [DVec3::new(1e-3, -2e-3, 0.5e-3), DVec3::new(-0.4e-3, 1e-3, 2e-3), DVec3::new(0.3e-3, 0.1e-3, -1e-3)];
    let target = DVec3::new(0.2e-3, 0.4e-3, 0.1e-3);
    let (_, g, hess) = anchor_eval::<3, 9>(k, &w, &x, target);
    for p in 0..9 {
        let h = 1e-7;
        let (mut xp, mut xm) = (x, x);
        xp[p / 3][p % 3] += h;
        xm[p / 3][p % 3] -= h;
        let (ep, gp, _) = anchor_eval::<3, 9>(k, &w, &xp, target);
        let (em, gm, _) = anchor_eval::<3, 9>(k, &w, &xm, target);
        assert!(((ep - em) / (2.0 * h) - g[p]).abs() < 1e-6 * g.norm(), "gradient {p}");
        for q in 0..9 {
            assert!(((gp[q] - gm[q]) / (2.0 * h) - hess[(q, p)]).abs() < 1e-6 * hess.norm(), "Hessian {q} {p}");
        }
    }
    let on = w[0] * x[0] + w[1] * x[1] + w[2] * x[2];
    assert_eq!(anchor_eval::<3, 9>(k, &w, &x, on).1.norm(), 0.0);
}
