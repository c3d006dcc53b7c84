//! The energy-term seam: what an element kind tells the solver. A kind is one file in
//! `elements/` (its struct and an `Element` impl over its physics) and one line in the
//! `elements!` registration list (`elements/mod.rs`); the pattern, the assembly, the energy,
//! the reaction forces, the region solve's subsetting and Settle then iterate over the
//! registered kinds (`Term`) without naming them.
//!
//! Every sum runs over the kinds in registration order and, within a kind, in element order,
//! so results do not depend on the thread count.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::scatter::{Local, Scatter, Vertices, CHUNK};
use crate::physics::psd::Filter;

/// The energy part a kind reports (`EnergyParts`, the stats' `energy_*` columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Membrane,
    /// Hinges, or the quadratic element and its Gaussian term.
    Bending,
    Volume,
    /// Attachment springs, KCK18 anchors and pins.
    Springs,
    /// Barrier contact.
    Contact,
}

/// How an element's coordinates couple: every pair of its 3 NV coordinates, or only the same
/// coordinate of each pair of vertices (a Hessian of the form K (x) I3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coupling {
    Full,
    PerCoordinate,
}

/// One element of a kind with a fixed number of vertices, its rest data inside it.
pub trait Element: Copy + Send + Sync {
    type Vertices: Vertices;
    type Local: Local;
    /// The energy part it reports.
    const PART: Part;
    /// Whether Settle relaxes its vertices: the shell's own membrane and bending energies
    /// (REMESH.md "Split").
    const SETTLES: bool = false;
    fn vertices(&self) -> Self::Vertices;
    fn energy(&self, x: &[DVec3]) -> f64;
    /// Energy, gradient and Hessian; `filter` chooses the exact or a projected Hessian.
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local;
    /// Its energy at unit strain (stiffness x volume; a spring's k times `length` squared):
    /// the scale of the round-off in an energy sum.
    fn unit_energy(&self, length: f64) -> f64;
    /// Whether an element reading these vertices is kept (`keep` also records them); an
    /// element that reads more than its own vertices passes them too.
    fn touches(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> bool {
        keep(self.vertices().as_ref())
    }
    /// The element on renumbered vertices.
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self;
    /// Whether Settle may move its vertices (a kind with `SETTLES` may refuse one element).
    fn settles(&self) -> bool {
        Self::SETTLES
    }
}

/// A registered kind's whole list, as the solver iterates over it (object safe: one `&dyn
/// Term` per kind).
pub(crate) trait Term: Sync {
    fn part(&self) -> Part;
    /// Calls `each` with each element's vertex list (the pattern's adjacency and scatter maps).
    fn stencils(&self, each: &mut dyn FnMut(&[u32]));
    /// How an element's vertices couple in the Hessian (its scatter map's layout).
    fn coupling(&self) -> Coupling {
        Coupling::Full
    }
    fn energy(&self, x: &[DVec3]) -> f64;
    /// Adds gradients and Hessians through `map`; returns the kind's energy.
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], filter: Filter) -> f64;
    /// Adds the exact gradient at every vertex.
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]);
    fn unit_energy(&self, length: f64) -> f64;
    /// The elements `keep` accepts (`Element::touches`), by index.
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize>;
    /// For Settle: calls `slot(element, slot, vertex)` for each vertex of each element it may
    /// move; none unless the kind settles.
    fn settle_slots(&self, slot: &mut dyn FnMut(u32, usize, u32));
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64;
    /// The exact gradient and Hessian block of element i's vertex slot k.
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3);
}

/// A kind's list built from chosen elements of another, renumbered (the region solve).
pub(crate) trait TermList: Term + Sized {
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self;
}

#[inline]
pub(crate) fn gather<const NV: usize>(x: &[DVec3], v: &[u32; NV]) -> [DVec3; NV] {
    std::array::from_fn(|i| x[v[i] as usize])
}

/// The gradient and Hessian block of vertex slot k of an element's local derivatives.
pub(crate) fn local_block<L: Local>(l: &L, k: usize) -> (DVec3, DMat3) {
    let (o, g) = (3 * k, l.gradient());
    let gv = DVec3::new(g[o], g[o + 1], g[o + 2]);
    let hv = DMat3::from_cols_array(&std::array::from_fn(|i| l.hessian(o + i % 3, o + i / 3)));
    (gv, hv)
}

/// Sum of `f` over the elements, in fixed chunks evaluated in parallel, summed in order.
pub(crate) fn sum_chunks<E: Sync>(elems: &[E], f: impl Fn(&E) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = elems.par_chunks(CHUNK).map(|c| c.iter().map(&f).sum::<f64>()).collect();
    partial.iter().sum()
}

impl<E: Element> Term for Vec<E> {
    fn part(&self) -> Part {
        E::PART
    }
    fn stencils(&self, each: &mut dyn FnMut(&[u32])) {
        self.iter().for_each(|e| each(e.vertices().as_ref()));
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        sum_chunks(self, |e| e.energy(x))
    }
    fn assemble(&self, acc: &mut Scatter<'_>, map: &[u32], x: &[DVec3], filter: Filter) -> f64 {
        acc.class(self, map, |e| e.vertices(), |e| e.eval(x, filter))
    }
    fn add_gradient(&self, x: &[DVec3], g: &mut [DVec3]) {
        for e in self {
            let l = e.eval(x, Filter::Exact);
            let gl = l.gradient();
            for (i, &v) in e.vertices().as_ref().iter().enumerate() {
                g[v as usize] += DVec3::new(gl[3 * i], gl[3 * i + 1], gl[3 * i + 2]);
            }
        }
    }
    fn unit_energy(&self, length: f64) -> f64 {
        self.iter().map(|e| e.unit_energy(length)).sum()
    }
    fn select(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> Vec<usize> {
        (0..self.as_slice().len()).filter(|&i| self[i].touches(keep)).collect()
    }
    fn settle_slots(&self, slot: &mut dyn FnMut(u32, usize, u32)) {
        if !E::SETTLES {
            return;
        }
        for (i, e) in self.iter().enumerate().filter(|(_, e)| e.settles()) {
            for (k, &v) in e.vertices().as_ref().iter().enumerate() {
                slot(i as u32, k, v);
            }
        }
    }
    fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        self[i].energy(x)
    }
    fn block(&self, i: usize, k: usize, x: &[DVec3]) -> (DVec3, DMat3) {
        local_block(&self[i].eval(x, Filter::Exact), k)
    }
}

impl<E: Element> TermList for Vec<E> {
    fn pick(&self, which: &[usize], to: &dyn Fn(u32) -> u32) -> Self {
        which.iter().map(|&i| self[i].reindexed(to)).collect()
    }
}

/// The element with its vertices renumbered (`Element::reindexed` for kinds whose vertices are
/// all they index).
#[inline]
pub(crate) fn renumbered<V: Vertices>(v: V, to: &dyn Fn(u32) -> u32) -> V {
    let mut out = v;
    out.as_mut().iter_mut().for_each(|i| *i = to(*i));
    out
}

/// Adds a 4-vertex element's local gradient (12 coordinates) into `g` (the pair kinds).
pub(crate) fn add_local_gradient(v: &[u32; 4], local: &nalgebra::SVector<f64, 12>, g: &mut [DVec3]) {
    for (k, &vk) in v.iter().enumerate() {
        g[vk as usize] += DVec3::new(local[3 * k], local[3 * k + 1], local[3 * k + 2]);
    }
}
