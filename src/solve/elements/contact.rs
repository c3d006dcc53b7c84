//! Barrier contact (`crate::contact`): the pairs near the state, each a point and a triangle or
//! two edges, their energy scaled by the barrier stiffness. The list changes as the state
//! moves (the Newton loop refreshes it: `solve::newton`), so the kind is a `Term` of its own.

use glam::{DMat3, DVec3};

use crate::contact::{gather, ContactPairs};
use crate::physics::psd::Filter;
use crate::solve::element::{add_local_gradient, local_block, sum_chunks, Part, Term, TermList};
use crate::solve::scatter::{Derivatives, Scatter};

impl ContactPairs {
    fn eval(&self, i: usize, x: &[DVec3], filter: Filter) -> Derivatives<12> {
        let (p, k) = (&self.pairs[i], self.stiffness);
        if k == 0.0 {
            // (before the stiffness is set: no barrier, not 0 x infinity)
            return (0.0, nalgebra::SVector::zeros(), nalgebra::SMatrix::zeros());
        }
        let (e, g, h) = p.derivatives(&gather(x, &p.v), filter);
        (k * e, k * g, k * h)
    }
}

impl Term for ContactPairs {
    fn part(&self) -> Part {
        Part::Contact
    }
    fn stencils(&self, each: &mut dyn FnMut(&[u32])) {
        self.pairs.iter().for_each(|p| each(&p.v));
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        if self.stiffness == 0.0 {
            return 0.0;
        }
        self.stiffness * sum_chunks(&self.pairs, |p| p.energy(&gather(x, &p.v)))
    }
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], filter: Filter) -> f64 {
        let index: Vec<usize> = (0..self.pairs.len()).collect();
        acc.class(&index, map, |&i| self.pairs[i].v, |&i| self.eval(i, x, filter))
    }
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]) {
        for (i, p) in self.pairs.iter().enumerate() {
            add_local_gradient(&p.v, &self.eval(i, x, Filter::Exact).1, g);
        }
    }
    /// (no share in the energy's round-off scale: the barrier vanishes at rest)
    fn unit_energy(&self, _length: f64) -> f64 {
        0.0
    }
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize> {
        (0..self.pairs.len()).filter(|&i| keep(&self.pairs[i].v)).collect()
    }
    fn settle_slots(&self, _slot: &mut dyn FnMut(u32, usize, u32)) {}
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        let p = &self.pairs[i];
        if self.stiffness == 0.0 {
            return 0.0;
        }
        self.stiffness * p.energy(&gather(x, &p.v))
    }
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3) {
        local_block(&self.eval(i, x, Filter::Exact), k)
    }
}

impl TermList for ContactPairs {
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self {
        let pairs =
            which.iter().map(|&i| self.pairs[i]).map(|p| crate::contact::Pair { v: p.v.map(to), ..p }).collect();
        ContactPairs { pairs, stiffness: self.stiffness }
    }
}
