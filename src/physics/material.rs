//! Constitutive models: energy densities Psi(F) for membranes (F is 3x2) and solids (F is 3x3).

use num_dual::DualNum;
use serde::{Deserialize, Serialize};

/// Lame parameters (Pa) of linear elasticity that a model must reproduce at the rest state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    pub mu: f64,
    pub lambda: f64,
}

impl Lame {
    /// Both parameters times a factor (they scale with Young's modulus).
    pub fn scaled(self, factor: f64) -> Self {
        Lame { mu: self.mu * factor, lambda: self.lambda * factor }
    }

    /// Plane-stress parameters of a thin membrane (PHYSICS.md 1.1): the 3D lambda would lock.
    pub fn plane_stress(young: f64, poisson: f64) -> Self {
        Lame { mu: young / (2.0 * (1.0 + poisson)), lambda: young * poisson / (1.0 - poisson * poisson) }
    }
    /// Three-dimensional parameters of a solid.
    pub fn solid(young: f64, poisson: f64) -> Self {
        Lame {
            mu: young / (2.0 * (1.0 + poisson)),
            lambda: young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)),
        }
    }
}

/// Kirchhoff's plate rigidity D = E h^3 / (12 (1 - nu^2)) (N m) of a shell of thickness h.
pub fn plate_rigidity(young: f64, thickness: f64, poisson: f64) -> f64 {
    young * thickness.powi(3) / (12.0 * (1.0 - poisson * poisson))
}

/// Which energy density a layer uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum ConstitutiveModel {
    /// H15 eq. 4.5 / 5.21: Psi = mu/4 tr(C + C^-1 - 2I) + lambda/8 ln^2(det C).
    #[default]
    BazantHencky,
    /// Smith, de Goes, Kim 2018, with the log term and its Lame reparameterization.
    StableNeoHookean,
    /// St. Venant-Kirchhoff: Psi = mu tr(E^2) + lambda/2 tr(E)^2, E = (C - I)/2.
    StVenantKirchhoff,
    /// Corotational linear: Psi = mu |F - R|^2 + lambda/2 tr(S - I)^2, F = R S (polar).
    Corotational,
}

impl ConstitutiveModel {
    pub fn name(self) -> &'static str {
        match self {
            ConstitutiveModel::BazantHencky => "bazant_hencky",
            ConstitutiveModel::StableNeoHookean => "stable_neo_hookean",
            ConstitutiveModel::StVenantKirchhoff => "st_venant_kirchhoff",
            ConstitutiveModel::Corotational => "corotational",
        }
    }
}

/// Energy density of a membrane. `f` is the 3x2 deformation gradient, column-major:
/// f[0..3] is the first column, f[3..6] the second. `lame` are the plane-stress parameters.
pub(crate) fn membrane_psi<D: DualNum<Primitive = f64> + Copy>(model: ConstitutiveModel, lame: Lame, f: &[D; 6]) -> D {
    let c11 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let c22 = f[3] * f[3] + f[4] * f[4] + f[5] * f[5];
    let c12 = f[0] * f[3] + f[1] * f[4] + f[2] * f[5];
    membrane_psi_of_c(model, lame, [c11, c22, c12])
}

/// The same energy density as a function of C = F^T F: [C11, C22, C12].
pub(crate) fn membrane_psi_of_c<D: DualNum<Primitive = f64> + Copy>(
    model: ConstitutiveModel,
    lame: Lame,
    c: [D; 3],
) -> D {
    let [c11, c22, c12] = c;
    let det_c = c11 * c22 - c12 * c12;
    let tr_c = c11 + c22;
    let (mu, la) = (lame.mu, lame.lambda);
    match model {
        ConstitutiveModel::BazantHencky => {
            let tr_c_inv = tr_c / det_c;
            let ln_det = det_c.ln();
            (tr_c + tr_c_inv - 4.0) * (mu / 4.0) + ln_det * ln_det * (la / 8.0)
        }
        ConstitutiveModel::StableNeoHookean => {
            // 2D reparameterization (PHYSICS.md 1.1): rest state is stress free and the
            // Hessian at F = I is linear elasticity with (mu_L, lambda_L).
            let mu_s = 1.5 * mu;
            let la_s = la + 2.0 / 3.0 * mu;
            let alpha = 1.0 + 2.0 * mu_s / (3.0 * la_s);
            let j = det_c.sqrt();
            let jm = j - alpha;
            // Minus the constant energy of the rest state, so that it is zero there.
            let rest = la_s / 2.0 * (1.0 - alpha) * (1.0 - alpha) - mu_s / 2.0 * 3f64.ln();
            (tr_c - 2.0) * (mu_s / 2.0) + jm * jm * (la_s / 2.0) - (tr_c + 1.0).ln() * (mu_s / 2.0) - rest
        }
        ConstitutiveModel::StVenantKirchhoff => {
            let e11 = (c11 - 1.0) * 0.5;
            let e22 = (c22 - 1.0) * 0.5;
            let e12 = c12 * 0.5;
            let tr_e = e11 + e22;
            (e11 * e11 + e22 * e22 + e12 * e12 * 2.0) * mu + tr_e * tr_e * (la / 2.0)
        }
        ConstitutiveModel::Corotational => {
            // In 2D, tr sqrt(C) = sqrt(tr C + 2 sqrt(det C)); |F - R|^2 = tr C - 2 tr S + 2.
            let tr_s = (tr_c + det_c.sqrt() * 2.0).sqrt();
            let ts = tr_s - 2.0;
            (tr_c - tr_s * 2.0 + 2.0) * mu + ts * ts * (la / 2.0)
        }
    }
}

/// Energy density of a solid. `f` is the 3x3 deformation gradient, column-major.
/// The corotational model is handled in closed form by `tet.rs` (it needs an SVD).
pub(crate) fn solid_psi<D: DualNum<Primitive = f64> + Copy>(model: ConstitutiveModel, lame: Lame, f: &[D; 9]) -> D {
    let col = |j: usize| [f[3 * j], f[3 * j + 1], f[3 * j + 2]];
    let (a, b, c) = (col(0), col(1), col(2));
    let dot = |u: &[D; 3], v: &[D; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let c11 = dot(&a, &a);
    let c22 = dot(&b, &b);
    let c33 = dot(&c, &c);
    let c12 = dot(&a, &b);
    let c13 = dot(&a, &c);
    let c23 = dot(&b, &c);
    let tr_c = c11 + c22 + c33;
    // det F = a . (b x c)
    let j =
        a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
    let (mu, la) = (lame.mu, lame.lambda);
    match model {
        ConstitutiveModel::BazantHencky => {
            let det_c = j * j;
            let tr_c2 = c11 * c11 + c22 * c22 + c33 * c33 + (c12 * c12 + c13 * c13 + c23 * c23) * 2.0;
            let tr_c_inv = (tr_c * tr_c - tr_c2) / (det_c * 2.0);
            let ln_det = det_c.ln();
            (tr_c + tr_c_inv - 6.0) * (mu / 4.0) + ln_det * ln_det * (la / 8.0)
        }
        ConstitutiveModel::StableNeoHookean => {
            let mu_s = 4.0 / 3.0 * mu;
            let la_s = la + 5.0 / 6.0 * mu;
            let alpha = 1.0 + 3.0 * mu_s / (4.0 * la_s);
            let jm = j - alpha;
            let rest = la_s / 2.0 * (1.0 - alpha) * (1.0 - alpha) - mu_s / 2.0 * 4f64.ln();
            (tr_c - 3.0) * (mu_s / 2.0) + jm * jm * (la_s / 2.0) - (tr_c + 1.0).ln() * (mu_s / 2.0) - rest
        }
        ConstitutiveModel::StVenantKirchhoff => {
            let e11 = (c11 - 1.0) * 0.5;
            let e22 = (c22 - 1.0) * 0.5;
            let e33 = (c33 - 1.0) * 0.5;
            let tr_e = e11 + e22 + e33;
            let off = (c12 * c12 + c13 * c13 + c23 * c23) * 0.25;
            (e11 * e11 + e22 * e22 + e33 * e33 + off * 2.0) * mu + tr_e * tr_e * (la / 2.0)
        }
        ConstitutiveModel::Corotational => {
            unreachable!("corotational solids are evaluated in closed form (physics::tet)")
        }
    }
}
