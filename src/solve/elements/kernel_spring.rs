//! Released LK14 kernels held by soft springs (issue 64, scope 3): W_k = k_k / 2 |c_k(x)|^2,
//! c_k the kernel's value (LK14 eq. 4.1), k_k = stiffness / sum_j w_j^2.
//!
//! A kernel whose skin touches, or whose body point lies where the body folds through itself,
//! leaves the frame's hard rows (`solve::release`). Left free, its skin wandered (the bent
//! elbow's compressed skin bulged 19 mm off its body points) and the solve crawled over the
//! flat energy of the freed region. A spring much softer than the skin keeps the region near
//! its body and gives that energy curvature; the barrier outweighs it where the body folds
//! through itself. The body's side of a released kernel is prescribed (only kernels binding
//! skin to a kinematic layer are released), so the Hessian is exactly k w_a w_b I3.

use glam::{DMat3, DVec3};

use crate::physics::psd::Filter;
use crate::solve::constraints::KernelRows;
use crate::solve::element::{Coupling, Part, Term, TermList};
use crate::solve::scatter::{Scatter, WeightedSums};

/// The released kernels' springs: each kernel's skin stencil and weights, and its rows for the
/// body's point (prescribed: a constant of each solve).
#[derive(Clone, Debug, Default)]
pub struct KernelSprings {
    kernels: Vec<KernelRows>,
    start: Vec<u32>,
    v: Vec<u32>,
    w: Vec<f64>,
    /// sum_j w_j^2 per kernel.
    norm: Vec<f64>,
    /// The scale of k (N/m); 0 until the patch's first assembly with springs sets it
    /// (`solve::contact::stiffen`).
    pub stiffness: f64,
}

impl KernelSprings {
    pub fn new(kernels: Vec<KernelRows>, stiffness: f64) -> KernelSprings {
        let mut s = KernelSprings { start: vec![0], stiffness, ..Default::default() };
        for k in &kernels {
            s.v.extend(k.upper.iter().map(|&(v, _)| v));
            s.w.extend(k.upper.iter().map(|&(_, w)| w));
            s.start.push(s.v.len() as u32);
            s.norm.push(k.upper.iter().map(|&(_, w)| w * w).sum());
        }
        s.kernels = kernels;
        s
    }

    pub fn is_empty(&self) -> bool {
        self.norm.is_empty()
    }

    fn element_energy_at(&self, i: usize, x: &[DVec3]) -> f64 {
        0.5 * WeightedSums::stiffness(self, i) * self.residual(i, x).length_squared()
    }
}

impl WeightedSums for KernelSprings {
    fn count(&self) -> usize {
        self.norm.len()
    }
    fn weights(&self, i: usize) -> (&[u32], &[f64]) {
        let (s, e) = (self.start[i] as usize, self.start[i + 1] as usize);
        (&self.v[s..e], &self.w[s..e])
    }
    fn stiffness(&self, i: usize) -> f64 {
        self.stiffness / self.norm[i]
    }
    fn residual(&self, i: usize, x: &[DVec3]) -> DVec3 {
        self.kernels[i].value(x)
    }
}

impl Term for KernelSprings {
    fn part(&self) -> Part {
        Part::Springs
    }
    fn stencils(&self, each: &mut dyn FnMut(&[u32])) {
        (0..self.count()).for_each(|i| each(self.weights(i).0));
    }
    /// (a Hessian k w_a w_b I3 per stencil pair)
    fn coupling(&self) -> Coupling {
        Coupling::PerCoordinate
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        (0..self.count()).map(|i| self.element_energy_at(i, x)).sum()
    }
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], _filter: Filter) -> f64 {
        acc.weighted_sums(self, map, x)
    }
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]) {
        for i in 0..self.count() {
            let r = WeightedSums::stiffness(self, i) * self.residual(i, x);
            let (vs, ws) = self.weights(i);
            for (&v, &w) in vs.iter().zip(ws) {
                g[v as usize] += w * r;
            }
        }
    }
    /// (a stand-in for constraints, not a material: no share in the round-off scale)
    fn unit_energy(&self, _length: f64) -> f64 {
        0.0
    }
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize> {
        (0..self.count()).filter(|&i| keep(self.weights(i).0)).collect()
    }
    /// (never settled: Settle runs without contact)
    fn settle_slots(&self, _slot: &mut dyn FnMut(u32, usize, u32)) {}
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        self.element_energy_at(i, x)
    }
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3) {
        let w = self.weights(i).1[k];
        let kw = WeightedSums::stiffness(self, i) * w;
        (kw * self.residual(i, x), DMat3::from_diagonal(DVec3::splat(kw * w)))
    }
}

impl TermList for KernelSprings {
    /// (Settle's region solve, which never runs with contact: a spring whose body side lies
    /// outside the region is left out)
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self {
        let mapped = |v: u32| to(v) != u32::MAX;
        let kernels = which
            .iter()
            .map(|&i| &self.kernels[i])
            .filter(|k| k.lower.iter().all(|t| mapped(t.v) && t.ring.iter().flatten().all(|&v| mapped(v))))
            .map(|k| {
                let mut k = k.clone();
                k.upper.iter_mut().for_each(|(v, _)| *v = to(*v));
                k.lower.iter_mut().for_each(|t| {
                    t.v = to(t.v);
                    t.ring.iter_mut().flatten().for_each(|v| *v = to(*v));
                });
                k
            })
            .collect();
        KernelSprings::new(kernels, self.stiffness)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::constraints::LowerTerm;

    /// A kernel of two skin vertices over one body vertex, pulled 1 mm off its body point.
    #[test]
    fn energy_gradient_and_hessian_agree_with_differences() {
        let k = KernelRows {
            upper: vec![(0, 0.25), (1, 0.75)],
            lower: vec![LowerTerm { v: 2, w: 1.0, offset: 0.0, ring: Vec::new() }],
            lower_moves: false,
        };
        let s = KernelSprings::new(vec![k], 3.0);
        let x = vec![DVec3::new(0.0, 0.0, 1e-3), DVec3::new(1e-3, 0.0, 2e-3), DVec3::new(0.5e-3, 0.0, 0.0)];
        let mut g = vec![DVec3::ZERO; 3];
        s.add_gradient(&x, &mut g);
        let h = 1e-7;
        for v in 0..2 {
            for c in 0..3 {
                let (mut a, mut b) = (x.clone(), x.clone());
                a[v][c] += h;
                b[v][c] -= h;
                let fd = (s.energy(&a) - s.energy(&b)) / (2.0 * h);
                assert!((fd - g[v][c]).abs() <= 1e-6 * g[v][c].abs().max(1e-9), "{v} {c}: {fd} {}", g[v][c]);
                let (gv, hv) = s.block(0, v, &x);
                assert!((gv[c] - g[v][c]).abs() <= 1e-12);
                assert_eq!(hv.col(c)[c], 3.0 / (0.25f64.powi(2) + 0.75f64.powi(2)) * [0.25f64, 0.75][v].powi(2));
            }
        }
    }
}
