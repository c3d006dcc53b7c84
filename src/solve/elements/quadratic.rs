//! Quadratic bending (`physics::quadratic_bending`): one element per interior vertex, its
//! stencil of variable length, so the kind is a `Term` of its own rather than a list of fixed
//! `Element`s.

use glam::{DMat3, DVec3};

use crate::physics::psd::Filter;
use crate::physics::QuadraticBending;
use crate::solve::element::{Coupling, Part, Term, TermList};
use crate::solve::scatter::{Scatter, WeightedSums};

impl Term for QuadraticBending {
    fn part(&self) -> Part {
        Part::Bending
    }
    fn stencils(&self, each: &mut dyn FnMut(&[u32])) {
        (0..QuadraticBending::len(self)).for_each(|i| each(self.stencil(i).0));
    }
    /// (a Hessian k w_a w_b I3 per stencil pair)
    fn coupling(&self) -> Coupling {
        Coupling::PerCoordinate
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        QuadraticBending::energy(self, x)
    }
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], _filter: Filter) -> f64 {
        acc.weighted_sums(self, map, x)
    }
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]) {
        for i in 0..QuadraticBending::len(self) {
            let (vs, ws) = self.stencil(i);
            let r = self.k[i] * self.laplacian(i, x);
            for (&v, &w) in vs.iter().zip(ws) {
                g[v as usize] += w * r;
            }
        }
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        self.rigidity_sum()
    }
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize> {
        (0..QuadraticBending::len(self)).filter(|&i| keep(self.stencil(i).0)).collect()
    }
    fn settle_slots(&self, slot: &mut dyn FnMut(u32, usize, u32)) {
        for i in 0..QuadraticBending::len(self) {
            for (k, &v) in self.stencil(i).0.iter().enumerate() {
                slot(i as u32, k, v);
            }
        }
    }
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        QuadraticBending::element_energy(self, i, x)
    }
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3) {
        let w = self.stencil(i).1[k];
        let kw = self.k[i] * w;
        (kw * self.laplacian(i, x), DMat3::from_diagonal(DVec3::splat(kw * w)))
    }
}

impl WeightedSums for QuadraticBending {
    fn count(&self) -> usize {
        self.len()
    }
    fn weights(&self, i: usize) -> (&[u32], &[f64]) {
        self.stencil(i)
    }
    fn stiffness(&self, i: usize) -> f64 {
        self.k[i]
    }
    fn residual(&self, i: usize, x: &[DVec3]) -> DVec3 {
        self.laplacian(i, x)
    }
}

impl TermList for QuadraticBending {
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self {
        let mut out = QuadraticBending::default();
        if !which.is_empty() {
            out.start.push(0);
        }
        for &i in which {
            let (vs, ws) = self.stencil(i);
            out.v.extend(vs.iter().map(|&v| to(v)));
            out.w.extend_from_slice(ws);
            out.start.push(out.v.len() as u32);
            out.k.push(self.k[i]);
            out.area.push(self.area[i]);
        }
        out
    }
}
