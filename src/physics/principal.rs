//! Bazant-Hencky solids in principal stretches, with the Hessian's analytic eigensystem
//! (Smith, de Goes, Kim 2019: isotropic energies; H15 eq. 4.5 / 5.21).
//!
//! With F = U diag(s) V^T, Psi(s) = mu/4 sum(s_i^2 + s_i^-2 - 2) + lambda/2 ln^2 J, J = s1 s2 s3.
//! The 9x9 Hessian has nine known eigenvectors: three scalings U diag(e_k) V^T (e_k the
//! eigenvectors of d2Psi/ds2), and per pair (i, j) a twist (u_i v_j^T - u_j v_i^T) / sqrt 2 with
//! eigenvalue (Psi_i + Psi_j) / (s_i + s_j) and a flip (u_i v_j^T + u_j v_i^T) / sqrt 2 with
//! eigenvalue (Psi_i - Psi_j) / (s_i - s_j), written below without the division. Projecting
//! (clamping eigenvalues) is then free: no 9x9 eigendecomposition, no AD.
//! Like the C-based energy, this sees |J|: the unsigned SVD is used.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::material::Lame;
use super::psd::{Filter, CLAMP_FLOOR};

/// Energy density, dPsi/dF and d2Psi/dF2 (vec = column-major 9), filtered.
pub(crate) fn bazant_hencky(lame: Lame, f: &[f64; 9], filter: Filter) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let fm = Matrix3::from_column_slice(f);
    let svd = fm.svd(true, true);
    let (u, v) = (svd.u.unwrap(), svd.v_t.unwrap().transpose());
    let s = svd.singular_values;
    let (mu, la) = (lame.mu, lame.lambda);
    let ln_j = s.iter().map(|x| x.ln()).sum::<f64>();
    let psi = 0.25 * mu * s.iter().map(|x| x * x + 1.0 / (x * x) - 2.0).sum::<f64>() + 0.5 * la * ln_j * ln_j;
    // dPsi/ds_i and d2Psi/ds_i ds_j.
    let d1 = s.map(|x| 0.5 * mu * (x - 1.0 / (x * x * x)) + la * ln_j / x);
    let mut d2 = Matrix3::from_fn(|i, j| la / (s[i] * s[j]));
    for i in 0..3 {
        d2[(i, i)] = 0.5 * mu * (1.0 + 3.0 / s[i].powi(4)) + la * (1.0 - ln_j) / (s[i] * s[i]);
    }
    let p = u * Matrix3::from_diagonal(&d1) * v.transpose();
    // Outer product u_a v_b^T as a vec(9).
    let outer =
        |a: usize, b: usize| -> SVector<f64, 9> { SVector::<f64, 9>::from_fn(|r, _| u[(r % 3, a)] * v[(r / 3, b)]) };
    let mut modes: [(f64, SVector<f64, 9>); 9] = [(0.0, SVector::zeros()); 9];
    let scaling = d2.symmetric_eigen();
    for (k, mode) in modes.iter_mut().take(3).enumerate() {
        let e: Vector3<f64> = scaling.eigenvectors.column(k).into();
        *mode = (scaling.eigenvalues[k], outer(0, 0) * e[0] + outer(1, 1) * e[1] + outer(2, 2) * e[2]);
    }
    let r2 = std::f64::consts::FRAC_1_SQRT_2;
    for (n, (i, j)) in [(0usize, 1usize), (0, 2), (1, 2)].into_iter().enumerate() {
        let (si, sj) = (s[i], s[j]);
        let cube = (si * sj).powi(3);
        let twist = 0.5 * mu * (1.0 - (si * si - si * sj + sj * sj) / cube) + la * ln_j / (si * sj);
        let flip = 0.5 * mu * (1.0 + (si * si + si * sj + sj * sj) / cube) - la * ln_j / (si * sj);
        let (a, b) = (outer(i, j), outer(j, i));
        modes[3 + 2 * n] = (twist, (a - b) * r2);
        modes[4 + 2 * n] = (flip, (a + b) * r2);
    }
    let max_abs = modes.iter().fold(0.0f64, |m, (l, _)| m.max(l.abs()));
    let floor = CLAMP_FLOOR * max_abs;
    let mut h = SMatrix::<f64, 9, 9>::zeros();
    for (l, q) in &modes {
        let l = match filter {
            Filter::Exact => *l,
            Filter::Clamp => l.max(floor),
            Filter::Abs => l.abs().max(floor),
        };
        h.ger(l, q, q, 1.0);
    }
    (psi, SVector::<f64, 9>::from_column_slice(p.as_slice()), h)
}
