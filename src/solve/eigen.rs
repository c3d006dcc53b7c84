//! The smallest eigenpairs of a large symmetric matrix given only its product and a symmetric
//! positive definite preconditioner: block LOBPCG (Knyazev 2001), the Rayleigh-Ritz step on
//! [X, W, P] orthonormalized explicitly (the matrix is indefinite: no B-orthogonality tricks).
//! Used for the most negative curvature at an unstable equilibrium (`stability.rs`).

use faer::{Mat, Side};

/// The lowest Ritz pair found.
#[derive(Clone, Debug)]
pub struct Eigenpair {
    pub value: f64,
    /// Unit length.
    pub vector: Vec<f64>,
    /// Iterations taken, and the final |H x - value x| / |value| (x of unit length).
    pub iterations: u32,
    pub residual: f64,
}

/// Columns whose norm falls below this fraction of their original norm during the
/// orthonormalization are dropped (linearly dependent on the others).
const DEPENDENT: f64 = 1e-10;

/// The smallest eigenpair of the n x n symmetric matrix `apply` multiplies by (y = H x), from a
/// block of `block` vectors (more converge the lowest faster when its neighbours are close);
/// stops when the lowest pair's relative residual is below `tolerance` or after
/// `max_iterations`. `precondition` applies an SPD approximation of |H|^-1 in place. The start
/// block is `guess` (when given) and fixed pseudo-random vectors (deterministic).
#[allow(clippy::too_many_arguments)]
pub fn smallest(
    n: usize,
    block: usize,
    apply: &mut dyn FnMut(&[f64], &mut [f64]),
    precondition: &mut dyn FnMut(&mut [f64]),
    guess: Option<&[f64]>,
    max_iterations: u32,
    tolerance: f64,
) -> Eigenpair {
    let block = block.clamp(1, n.max(1));
    let mut start: Vec<Vec<f64>> = guess.map(|g| g.to_vec()).into_iter().collect();
    start.extend(
        (start.len()..block)
            .map(|b| (0..n).map(|i| ((i as f64 + 1.0) * (12.9898 + 7.233 * b as f64)).sin().fract() - 0.5).collect()),
    );
    let (mut x, mut ax) = orthonormal(start, apply);
    let mut p: Vec<Vec<f64>> = Vec::new();
    let mut iterations = 0;
    // The first Rayleigh-Ritz is on X alone.
    let mut basis = (x.clone(), ax.clone());
    loop {
        let (values, vectors) = ritz(&basis.0, &basis.1);
        let k = block.min(values.len());
        let combine = |cols: &[Vec<f64>], from: usize| -> Vec<Vec<f64>> {
            (0..k)
                .map(|j| {
                    let mut v = vec![0.0; n];
                    for (i, c) in cols.iter().enumerate().skip(from) {
                        axpy(&mut v, vectors[(i, j)], c);
                    }
                    v
                })
                .collect()
        };
        // X keeps the first `block` columns of the basis, so the new P is the rest's share.
        let had = x.len();
        x = combine(&basis.0, 0);
        ax = combine(&basis.1, 0);
        if iterations > 0 {
            p = combine(&basis.0, had);
        }
        let theta = &values[..k];
        let residuals: Vec<Vec<f64>> =
            (0..k).map(|j| ax[j].iter().zip(&x[j]).map(|(a, b)| a - theta[j] * b).collect()).collect();
        let lowest = norm(&residuals[0]) / theta[0].abs().max(f64::MIN_POSITIVE);
        tracing::trace!(iterations, value = theta[0], residual = lowest, "LOBPCG");
        if lowest <= tolerance || iterations >= max_iterations {
            return Eigenpair { value: theta[0], vector: x.swap_remove(0), iterations, residual: lowest };
        }
        iterations += 1;
        let w: Vec<Vec<f64>> = residuals
            .into_iter()
            .map(|mut r| {
                precondition(&mut r);
                r
            })
            .collect();
        let mut columns = x.clone();
        columns.extend(w);
        columns.extend(p.iter().cloned());
        basis = orthonormal(columns, apply);
        if basis.0.len() < x.len() {
            // (X itself became dependent: round-off; keep what was found)
            return Eigenpair { value: theta[0], vector: x.swap_remove(0), iterations, residual: lowest };
        }
    }
}

/// The lowest Rayleigh quotient over the span of `columns` (Rayleigh-Ritz): its value and unit
/// vector; None when the columns span nothing.
pub fn lowest_in_span(columns: Vec<Vec<f64>>, apply: &mut dyn FnMut(&[f64], &mut [f64])) -> Option<(f64, Vec<f64>)> {
    let (q, hq) = orthonormal(columns, apply);
    let n = q.first()?.len();
    let (values, vectors) = ritz(&q, &hq);
    let mut x = vec![0.0; n];
    for (j, qj) in q.iter().enumerate() {
        axpy(&mut x, vectors[(j, 0)], qj);
    }
    let length = norm(&x);
    x.iter_mut().for_each(|v| *v /= length);
    Some((values[0], x))
}

/// Modified Gram-Schmidt, twice, dropping dependent columns; returns the columns and H times them.
fn orthonormal(columns: Vec<Vec<f64>>, apply: &mut dyn FnMut(&[f64], &mut [f64])) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut kept: Vec<Vec<f64>> = Vec::with_capacity(columns.len());
    for mut c in columns {
        let original = norm(&c);
        if original.is_nan() || original <= 0.0 || original.is_infinite() {
            continue;
        }
        for _ in 0..2 {
            for q in &kept {
                let d = dot(q, &c);
                axpy(&mut c, -d, q);
            }
        }
        let length = norm(&c);
        if length > DEPENDENT * original {
            c.iter_mut().for_each(|v| *v /= length);
            kept.push(c);
        }
    }
    let products = kept
        .iter()
        .map(|q| {
            let mut y = vec![0.0; q.len()];
            apply(q, &mut y);
            y
        })
        .collect();
    (kept, products)
}

/// Rayleigh-Ritz on an orthonormal basis Q (with H Q): the eigenvalues of Q^T H Q in
/// nondecreasing order and their eigenvectors (columns).
fn ritz(q: &[Vec<f64>], hq: &[Vec<f64>]) -> (Vec<f64>, Mat<f64>) {
    let m = q.len();
    let g = Mat::from_fn(m, m, |i, j| 0.5 * (dot(&q[i], &hq[j]) + dot(&q[j], &hq[i])));
    match g.self_adjoint_eigen(Side::Lower) {
        Ok(e) => ((0..m).map(|i| e.S()[i]).collect(), e.U().to_owned()),
        // (a non-finite product: report the basis as it is)
        Err(_) => ((0..m).map(|i| g[(i, i)]).collect(), Mat::identity(m, m)),
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal matrix with one eigenvalue barely below zero among widely spread positive ones:
    /// the Jacobi-preconditioned LOBPCG finds it.
    #[test]
    fn finds_a_barely_negative_eigenvalue() {
        let n = 500;
        let diag: Vec<f64> = (0..n).map(|i| if i == 137 { -1e-9 } else { 1e-6 * (1.0 + i as f64).powi(3) }).collect();
        let mut apply = |x: &[f64], y: &mut [f64]| y.iter_mut().zip(x).zip(&diag).for_each(|((y, x), d)| *y = d * x);
        let mut precondition = |r: &mut [f64]| r.iter_mut().zip(&diag).for_each(|(r, d)| *r /= d.abs());
        let e = smallest(n, 2, &mut apply, &mut precondition, None, 50, 1e-8);
        assert!((e.value + 1e-9).abs() < 1e-15, "{e:?}");
        assert!(e.vector[137].abs() > 1.0 - 1e-8);
    }
}
