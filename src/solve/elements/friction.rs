//! Lagged friction (`crate::contact::friction`): the pairs touching at the frame's start, each
//! resisting the slip of its closest points over the frame. Fixed through a frame (the solve
//! with contact sets them at its start: `solve::contact`), so the kind is a `Term` of its own.

use glam::{DMat3, DVec3};

use crate::contact::FrictionPairs;
use crate::physics::psd::Filter;
use crate::solve::element::{add_local_gradient, local_block, sum_chunks, Part, Term, TermList};
use crate::solve::scatter::{Derivatives, Scatter};

impl FrictionPairs {
    fn eval(&self, i: usize, x: &[DVec3]) -> Derivatives<12> {
        self.pairs[i].derivatives(x, self.eps)
    }
}

impl Term for FrictionPairs {
    fn part(&self) -> Part {
        Part::Contact
    }
    fn stencils(&self, each: &mut dyn FnMut(&[u32])) {
        self.pairs.iter().for_each(|p| each(&p.v));
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        sum_chunks(&self.pairs, |p| p.energy(x, self.eps))
    }
    /// (the Hessian is PSD as it stands: no filter)
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], _filter: Filter) -> f64 {
        let index: Vec<usize> = (0..self.pairs.len()).collect();
        acc.class(&index, map, |&i| self.pairs[i].v, |&i| self.eval(i, x))
    }
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]) {
        for (i, p) in self.pairs.iter().enumerate() {
            add_local_gradient(&p.v, &self.eval(i, x).1, g);
        }
    }
    /// (no share in the energy's round-off scale: it is a load, not a material)
    fn unit_energy(&self, _length: f64) -> f64 {
        0.0
    }
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize> {
        (0..self.pairs.len()).filter(|&i| keep(&self.pairs[i].v)).collect()
    }
    fn settle_slots(&self, _slot: &mut dyn FnMut(u32, usize, u32)) {}
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        self.pairs[i].energy(x, self.eps)
    }
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3) {
        local_block(&self.eval(i, x), k)
    }
}

impl TermList for FrictionPairs {
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self {
        let pairs = which
            .iter()
            .map(|&i| self.pairs[i])
            .map(|p| crate::contact::FrictionPair { v: p.v.map(to), ..p })
            .collect();
        FrictionPairs { pairs, eps: self.eps }
    }
}
