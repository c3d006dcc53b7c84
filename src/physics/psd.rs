//! Positive semi-definite projection of small symmetric matrices (H15 5.4).

use nalgebra::{SMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// The scene's projection policy for element Hessians.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Projection {
    /// Never project: the exact Hessian (may be indefinite).
    None,
    /// Clamp negative eigenvalues to a small positive floor.
    #[default]
    Clamp,
    /// Replace eigenvalues by their absolute values (Chen et al. 2024).
    Abs,
    /// H15: project far from the solution, stop as the gradient falls, project again when the
    /// unprojected direction is not a descent direction.
    Adaptive,
}

/// What one element evaluation applies to its Hessian.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Exact,
    Clamp,
    Abs,
}

/// Relative floor for clamped eigenvalues (of the largest eigenvalue magnitude).
pub(crate) const CLAMP_FLOOR: f64 = 1e-12;

/// Symmetric matrices that can be projected (the element sizes: 4, 6, 9, 12).
pub trait Project {
    /// Projects in place; a no-op for `Filter::Exact` or when already PSD.
    fn project(&mut self, filter: Filter);
}

macro_rules! impl_project {
    ($($n:literal),*) => {$(
        impl Project for SMatrix<f64, $n, $n> {
            fn project(&mut self, filter: Filter) {
                if filter == Filter::Exact {
                    return;
                }
                // Most element Hessians are already PSD: a 12x12 Cholesky is ~20x cheaper than an
                // eigendecomposition, so try it first (shifted by the floor, relative to the trace).
                let shift = CLAMP_FLOOR * self.trace().abs();
                let shifted = *self + SMatrix::<f64, $n, $n>::identity() * shift;
                if shift > 0.0 && shifted.cholesky().is_some() {
                    return;
                }
                let eig = SymmetricEigen::new(*self);
                let max_abs = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let floor = CLAMP_FLOOR * max_abs;
                if eig.eigenvalues.iter().all(|&v| v >= floor) {
                    return;
                }
                let vals = eig.eigenvalues.map(|v| match filter {
                    Filter::Clamp => v.max(floor),
                    Filter::Abs => v.abs().max(floor),
                    Filter::Exact => v,
                });
                *self = eig.eigenvectors * SMatrix::<f64, $n, $n>::from_diagonal(&vals) * eig.eigenvectors.transpose();
            }
        }
    )*};
}

impl_project!(2, 4, 6, 9, 12);

/// Projects `h` in place (see [`Project`]).
pub fn project<M: Project>(h: &mut M, filter: Filter) {
    h.project(filter);
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::SMatrix;

    fn indefinite() -> SMatrix<f64, 4, 4> {
        let q = SMatrix::<f64, 4, 4>::from_fn(|i, j| ((i * 7 + j * 3) as f64).sin());
        let q = q.qr().q();
        q * SMatrix::<f64, 4, 4>::from_diagonal(&nalgebra::vector![3.0, -2.0, 0.5, -1e-3]) * q.transpose()
    }

    #[test]
    fn clamp_leaves_no_eigenvalue_below_the_floor() {
        let mut h = indefinite();
        project(&mut h, Filter::Clamp);
        let e = SymmetricEigen::new(h).eigenvalues;
        let max = e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(e.iter().all(|&v| v >= CLAMP_FLOOR * max * 0.999 - 1e-14), "{e:?}");
    }

    #[test]
    fn abs_keeps_the_magnitudes() {
        let mut h = indefinite();
        project(&mut h, Filter::Abs);
        let mut e: Vec<f64> = SymmetricEigen::new(h).eigenvalues.iter().copied().collect();
        e.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let want = [1e-3, 0.5, 2.0, 3.0];
        for (a, b) in e.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{e:?}");
        }
    }
}
