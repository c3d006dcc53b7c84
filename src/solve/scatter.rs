//! Scattering element derivatives into the cached pattern: a plain indexed add through each
//! kind's scatter map (`Pattern::maps`). Elements are evaluated in parallel in fixed chunks;
//! the scatter runs in element order, so results do not depend on the thread count.

use glam::DVec3;
use rayon::prelude::*;

use nalgebra::{SMatrix, SVector};

/// A kind whose elements are k_i / 2 |sum_j w_j x_j - o_i|^2 over a stencil of any length
/// (`Scatter::weighted_sums`): quadratic bending, released kernels' springs.
pub(crate) trait WeightedSums {
    fn count(&self) -> usize;
    /// Element i's stencil and weights.
    fn weights(&self, i: usize) -> (&[u32], &[f64]);
    fn stiffness(&self, i: usize) -> f64;
    /// r_i = sum_j w_j x_j - o_i.
    fn residual(&self, i: usize, x: &[DVec3]) -> DVec3;
}

/// Elements per parallel chunk: large enough to amortize the fork, small enough to stay in cache.
pub(crate) const CHUNK: usize = 1024;

/// A fixed coordinate: no free DOF, no scatter position.
pub const NONE: u32 = u32::MAX;
/// Set on a scatter position when two different local DOFs of an element are one shared
/// (tied) DOF: the off-diagonal local entry lands twice on the global diagonal.
pub const DOUBLE: u32 = 1 << 31;

/// Number of stored local pairs of an element with `nv` vertices.
pub const fn pairs(nv: usize) -> usize {
    let n = 3 * nv;
    n * (n + 1) / 2
}

/// An element's vertices: `[u32; NV]`.
pub trait Vertices: Copy + AsRef<[u32]> + AsMut<[u32]> + Send + Sync {
    const LEN: usize;
}

impl<const NV: usize> Vertices for [u32; NV] {
    const LEN: usize = NV;
}

/// Energy, gradient and Hessian of an element with N = 3 NV coordinates.
pub(crate) type Derivatives<const N: usize> = (f64, SVector<f64, N>, SMatrix<f64, N, N>);

/// An element's energy, gradient and Hessian over its 3 NV coordinates.
pub trait Local: Send + Sync {
    fn energy(&self) -> f64;
    fn gradient(&self) -> &[f64];
    fn gradient_norm(&self) -> f64;
    fn hessian(&self, p: usize, q: usize) -> f64;
}

impl<const N: usize> Local for Derivatives<N> {
    #[inline]
    fn energy(&self) -> f64 {
        self.0
    }
    #[inline]
    fn gradient(&self) -> &[f64] {
        self.1.as_slice()
    }
    #[inline]
    fn gradient_norm(&self) -> f64 {
        self.1.norm()
    }
    #[inline]
    fn hessian(&self, p: usize, q: usize) -> f64 {
        self.2[(p, q)]
    }
}

/// The gradient over free DOFs and the Hessian's lower-triangle values being assembled, and
/// the sum of element force magnitudes.
pub(crate) struct Scatter<'a> {
    pub(crate) dof: &'a [u32],
    pub(crate) grad: &'a mut [f64],
    pub(crate) values: &'a mut [f64],
    pub(crate) force: f64,
}

impl Scatter<'_> {
    /// Evaluates one element kind chunk by chunk (`eval`); the next chunk is evaluated in
    /// parallel while the previous one is scattered. Returns the kind's energy.
    pub(crate) fn class<E: Sync, V: Vertices, L: Local>(
        &mut self,
        elems: &[E],
        map: &[u32],
        verts: impl Fn(&E) -> V + Sync,
        eval: impl Fn(&E) -> L + Sync,
    ) -> f64 {
        let np = pairs(V::LEN);
        debug_assert_eq!(map.len(), elems.len() * np);
        let mut energy = 0.0;
        // Two result buffers, reused: one being filled while the other is scattered.
        let mut filling: Vec<L> = Vec::with_capacity(CHUNK.min(elems.len()));
        let mut ready: Vec<L> = Vec::with_capacity(CHUNK.min(elems.len()));
        let mut ready_start: Option<usize> = None;
        for (ci, chunk) in elems.chunks(CHUNK).enumerate() {
            rayon::join(
                || chunk.par_iter().map(&eval).collect_into_vec(&mut filling),
                || {
                    if let Some(start) = ready_start {
                        energy += self.scatter(&elems[start..], &map[start * np..], &verts, &ready);
                    }
                },
            );
            std::mem::swap(&mut filling, &mut ready);
            ready_start = Some(ci * CHUNK);
        }
        if let Some(start) = ready_start {
            energy += self.scatter(&elems[start..], &map[start * np..], &verts, &ready);
        }
        energy
    }

    fn scatter<E, V: Vertices, L: Local>(
        &mut self,
        elems: &[E],
        map: &[u32],
        verts: &impl Fn(&E) -> V,
        res: &[L],
    ) -> f64 {
        let nv = V::LEN;
        let (n, np) = (3 * nv, pairs(nv));
        let mut energy = 0.0;
        for (i, l) in res.iter().enumerate() {
            energy += l.energy();
            self.force += l.gradient_norm();
            let vs = verts(&elems[i]);
            let (vs, g) = (vs.as_ref(), l.gradient());
            for p in 0..n {
                let d = self.dof[3 * vs[p / 3] as usize + p % 3];
                if d != NONE {
                    self.grad[d as usize] += g[p];
                }
            }
            let m = &map[i * np..(i + 1) * np];
            let mut k = 0;
            for p in 0..n {
                for q in 0..=p {
                    self.add(m[k], l.hessian(p, q));
                    k += 1;
                }
            }
        }
        energy
    }

    #[inline]
    fn add(&mut self, pos: u32, h: f64) {
        if pos != NONE {
            if pos & DOUBLE != 0 {
                self.values[(pos & !DOUBLE) as usize] += 2.0 * h;
            } else {
                self.values[pos as usize] += h;
            }
        }
    }

    /// Weighted sums: W = k / 2 |r|^2 with r = sum_j w_j x_j - o, gradient k w_a r at vertex a,
    /// Hessian k w_a w_b I3 (constant). Serial: a few flops per stencil pair.
    pub(crate) fn weighted_sums(&mut self, q: &dyn WeightedSums, map: &[u32], x: &[DVec3]) -> f64 {
        let (mut energy, mut m) = (0.0, 0);
        for i in 0..q.count() {
            let (vs, ws) = q.weights(i);
            let k = q.stiffness(i);
            let r = q.residual(i, x);
            energy += 0.5 * k * r.length_squared();
            let mut g2 = 0.0;
            for (&v, &w) in vs.iter().zip(ws) {
                let g = k * w * r;
                g2 += g.length_squared();
                for (c, gc) in g.to_array().into_iter().enumerate() {
                    let d = self.dof[3 * v as usize + c];
                    if d != NONE {
                        self.grad[d as usize] += gc;
                    }
                }
            }
            self.force += g2.sqrt();
            for (a, &wa) in ws.iter().enumerate() {
                for &wb in &ws[..=a] {
                    let h = k * wa * wb;
                    for _ in 0..3 {
                        self.add(map[m], h);
                        m += 1;
                    }
                }
            }
        }
        energy
    }
}
