//! Prestrain (H15 4.3, eq. 4.8: F = dx/dX F0): building F0 from principal stretches, and
//! capturing part of a deformed state as the new rest state ("permanent wrinkles").
//!
//! Capture: with the current F = R U (polar), the new F0' = F0 U^-f gives F' = R U^(1-f) at the
//! current positions, so f = 1 makes the current state stress-free and f = 0 changes nothing.

use glam::{DMat2, DMat3, DVec3};
use nalgebra::{Matrix2, Matrix3};

use super::hinge::{dihedral_f64, HingeModel, HingeRest};
use super::membrane::MembraneRest;
use super::tet::TetRest;

/// F0 of a membrane triangle in its own rest frame (that of `membrane::rest_edge_matrix`) from
/// the stretch tensor diag(stretch) in world axes: F0_ij = a_i . S a_j, a = (t, s).
pub(crate) fn membrane_f0(x: [DVec3; 3], stretch: DVec3) -> DMat2 {
    let e1 = x[1] - x[0];
    let t = e1.normalize();
    let s = e1.cross(x[2] - x[0]).cross(t).normalize();
    let q = |a: DVec3, b: DVec3| a.dot(stretch * b);
    DMat2::from_cols_array(&[q(t, t), q(s, t), q(t, s), q(s, s)])
}

/// Stretch tensor of a map weight w: I + w (S - I).
pub(crate) fn weighted_stretch(stretch: DVec3, w: f64) -> DVec3 {
    DVec3::ONE + w * (stretch - DVec3::ONE)
}

/// C^(-f/2) = U^-f for a symmetric positive definite C.
fn sym_power2(c: Matrix2<f64>, p: f64) -> Matrix2<f64> {
    let e = c.symmetric_eigen();
    let d = Matrix2::from_diagonal(&e.eigenvalues.map(|l| l.max(f64::MIN_POSITIVE).powf(p)));
    e.eigenvectors * d * e.eigenvectors.transpose()
}

fn sym_power3(c: Matrix3<f64>, p: f64) -> Matrix3<f64> {
    let e = c.symmetric_eigen();
    let d = Matrix3::from_diagonal(&e.eigenvalues.map(|l| l.max(f64::MIN_POSITIVE).powf(p)));
    e.eigenvectors * d * e.eigenvectors.transpose()
}

/// The factor U^-f that a capture of fraction f right-multiplies into a membrane's B = Dm^-1 F0.
pub fn membrane_release(rest: &MembraneRest, x: &[DVec3; 3], f: f64) -> DMat2 {
    let (d1, d2) = (x[1] - x[0], x[2] - x[0]);
    let col = |j: usize| d1 * rest.b.col(j).x + d2 * rest.b.col(j).y;
    let (f0, f1) = (col(0), col(1));
    let c = Matrix2::new(f0.dot(f0), f0.dot(f1), f1.dot(f0), f1.dot(f1));
    let m = sym_power2(c, -0.5 * f);
    DMat2::from_cols_array(&[m[(0, 0)], m[(1, 0)], m[(0, 1)], m[(1, 1)]])
}

/// The factor U^-f for a tetrahedron (F = Ds B, B = Dm^-1 F0). Inverted tets are left alone
/// (identity): a rest state must have positive volume.
pub fn tet_release(rest: &TetRest, x: &[DVec3; 4], f: f64) -> DMat3 {
    let ds = DMat3::from_cols(x[1] - x[0], x[2] - x[0], x[3] - x[0]);
    let fm = ds * rest.b;
    if fm.determinant() <= 0.0 {
        return DMat3::IDENTITY;
    }
    let c = fm.transpose() * fm;
    let c = Matrix3::from_fn(|i, j| c.col(j)[i]);
    let m = sym_power3(c, -0.5 * f);
    DMat3::from_cols_array(&[
        m[(0, 0)],
        m[(1, 0)],
        m[(2, 0)],
        m[(0, 1)],
        m[(1, 1)],
        m[(2, 1)],
        m[(0, 2)],
        m[(1, 2)],
        m[(2, 2)],
    ])
}

/// A hinge's rest bend moved the fraction f towards its current bend.
pub fn hinge_capture(model: HingeModel, rest: &HingeRest, x: &[DVec3; 4], f: f64) -> HingeRest {
    let current = model.phi(dihedral_f64(x)).0;
    HingeRest { weight: rest.weight, rest_phi: (1.0 - f) * rest.rest_phi + f * current }
}

/// Maps a point of a flat sheet onto a cylinder of curvature kappa that curves along `axis`
/// (0 = x, 1 = y) towards +z, touching the sheet at `centre`; arc length along the axis and the
/// offset along z (the normal) are kept.
pub(crate) fn wrap_on_cylinder(p: DVec3, centre: DVec3, kappa: f64, axis: usize) -> DVec3 {
    if kappa == 0.0 {
        return p;
    }
    let r = 1.0 / kappa;
    let s = p[axis] - centre[axis];
    let h = p.z - centre.z;
    let (sn, cs) = (s / r).sin_cos();
    let mut q = p;
    q[axis] = centre[axis] + (r - h) * sn;
    q.z = centre.z + r - (r - h) * cs;
    q
}

/// A flat rest hinge given a rest curvature kappa along `axis` (0 = x, 1 = y): the rest bend is
/// that of the hinge wrapped on a cylinder of radius 1 / kappa, its weight that of the flat one.
pub fn hinge_with_curvature(model: HingeModel, k_b: f64, x: [DVec3; 4], kappa: f64, axis: usize) -> HingeRest {
    let flat = HingeRest::from_rest(model, k_b, x);
    if kappa == 0.0 {
        return flat;
    }
    let bent = HingeRest::from_rest(model, k_b, x.map(|p| wrap_on_cylinder(p, x[0], kappa, axis)));
    HingeRest { weight: flat.weight, rest_phi: bent.rest_phi }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::material::{ConstitutiveModel, Lame};
    use crate::physics::{hinge, membrane, tet};

    const LAME: Lame = Lame { mu: 1.0, lambda: 3.0 };

    fn tri() -> [DVec3; 3] {
        [DVec3::ZERO, DVec3::new(1.0, 0.2, 0.0), DVec3::new(0.3, 0.9, 0.0)]
    }

    #[test]
    fn uniform_prestretch_strains_the_rest_triangle() {
        let x = tri();
        let f0 = membrane_f0(x, DVec3::new(1.02, 1.02, 1.0));
        assert!(f0.abs_diff_eq(DMat2::from_diagonal(glam::DVec2::splat(1.02)), 1e-14));
        let rest = MembraneRest::from_rest_triangle(x, 0.1, f0).unwrap();
        // At the rest positions the element is stretched 2 %: it stores energy.
        assert!(membrane::energy(ConstitutiveModel::BazantHencky, LAME, &rest, &x) > 0.0);
        // Shrunk by 1 / 1.02 about x0 it is at rest.
        let shrunk = x.map(|p| p / 1.02);
        assert!(membrane::energy(ConstitutiveModel::BazantHencky, LAME, &rest, &shrunk).abs() < 1e-18);
    }

    #[test]
    fn full_capture_makes_the_current_state_stress_free() {
        let x = tri();
        for model in
            [ConstitutiveModel::BazantHencky, ConstitutiveModel::StableNeoHookean, ConstitutiveModel::StVenantKirchhoff]
        {
            let rest = MembraneRest::from_rest_triangle(x, 0.1, DMat2::IDENTITY).unwrap();
            let y = [DVec3::new(0.1, 0.0, 0.3), DVec3::new(0.8, 0.3, 0.1), DVec3::new(0.5, 1.1, 0.4)];
            let before = membrane::energy(model, LAME, &rest, &y);
            let half = MembraneRest { b: rest.b * membrane_release(&rest, &y, 0.5), ..rest };
            let full = MembraneRest { b: rest.b * membrane_release(&rest, &y, 1.0), ..rest };
            let (e_half, e_full) = (membrane::energy(model, LAME, &half, &y), membrane::energy(model, LAME, &full, &y));
            assert!(e_full.abs() < 1e-12 * before, "{model:?}: {e_full} vs {before}");
            assert!(e_half > e_full && e_half < before, "{model:?}: partial capture relaxes partly");
        }
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let rest = TetRest::from_rest(t, DMat3::IDENTITY).unwrap();
        let y = [DVec3::ZERO, DVec3::new(0.7, 0.1, 0.0), DVec3::new(0.2, 1.3, 0.1), DVec3::new(0.0, 0.1, 0.8)];
        let before = tet::energy(ConstitutiveModel::BazantHencky, LAME, &rest, &y);
        let full = TetRest { b: rest.b * tet_release(&rest, &y, 1.0), ..rest };
        assert!(tet::energy(ConstitutiveModel::BazantHencky, LAME, &full, &y).abs() < 1e-12 * before);
    }

    #[test]
    fn hinge_capture_and_rest_curvature() {
        let x = [DVec3::ZERO, DVec3::Y, DVec3::new(1.0, 0.5, 0.0), DVec3::new(-1.0, 0.5, 0.0)];
        let model = HingeModel::Tan;
        let rest = HingeRest::from_rest(model, 1.0, x);
        let bent = [x[0], x[1], DVec3::new(0.9, 0.5, 0.3), x[3]];
        let captured = hinge_capture(model, &rest, &bent, 1.0);
        assert!(hinge::energy(model, &captured, &bent).abs() < 1e-15);
        // A rest curvature: the hinge wrapped on that cylinder is at rest, the flat one is not.
        let curved = hinge_with_curvature(model, 1.0, x, 0.4, 0);
        assert!(hinge::energy(model, &curved, &x) > 0.0);
        let r = 1.0 / 0.4;
        let wrap = |p: DVec3| DVec3::new(r * (p.x / r).sin(), p.y, r - r * (p.x / r).cos());
        assert!(hinge::energy(model, &curved, &x.map(wrap)).abs() < 1e-15);
    }
}
