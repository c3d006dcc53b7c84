//! Evaluating a packed patch's elements: energies (line search), and energy + gradient + Hessian
//! assembled into the cached pattern. Elements run in parallel in fixed chunks; the scatter
//! and every sum run in element order, so results do not depend on the thread count.

use glam::DVec3;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use super::elements::{AnchorElem, Elements};
use super::pattern::{pairs, Pattern, DOUBLE, NONE};
use crate::physics::psd::Filter;
use crate::physics::{cell, gaussian_bending, hinge, membrane, spring, tet, QuadraticBending};

/// Elements per parallel chunk: large enough to amortize the fork, small enough to stay in cache.
const CHUNK: usize = 1024;

/// Energy by element kind (J).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnergyParts {
    pub membrane: f64,
    /// Hinges, or the quadratic element and its Gaussian term.
    pub bending: f64,
    pub volume: f64,
    /// Attachment springs and KCK18 anchors.
    pub springs: f64,
}

impl EnergyParts {
    /// The elastic energy: the parts summed in this order.
    pub fn total(&self) -> f64 {
        self.membrane + self.bending + self.volume + self.springs
    }
}

#[inline]
fn gather<const NV: usize>(x: &[DVec3], v: &[u32; NV]) -> [DVec3; NV] {
    std::array::from_fn(|i| x[v[i] as usize])
}

fn sum_chunks<E: Sync>(elems: &[E], f: impl Fn(&E) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = elems.par_chunks(CHUNK).map(|c| c.iter().map(&f).sum::<f64>()).collect();
    partial.iter().sum()
}

/// Energies only, by element kind.
pub fn energy(elements: &Elements, x: &[DVec3]) -> EnergyParts {
    EnergyParts {
        membrane: sum_chunks(&elements.membranes, |e| membrane::energy(e.model, e.lame, &e.rest, &gather(x, &e.v))),
        bending: sum_chunks(&elements.hinges, |e| hinge::energy(e.model, &e.rest, &e.positions(x)))
            + elements.quadratic.energy(x)
            + sum_chunks(&elements.gaussian, |e| gaussian_bending::energy(e, &gather(x, &e.v))),
        volume: sum_chunks(&elements.tets, |e| tet::energy(e.model, e.lame, &e.rest, &gather(x, &e.v)))
            + sum_chunks(&elements.cells, |e| cell::energy(&e.rest, &gather(x, &e.v))),
        springs: sum_chunks(&elements.springs, |e| spring::energy(e.k, x[e.v[0] as usize], x[e.v[1] as usize]))
            + sum_chunks(&elements.vertex_anchors, |e| anchor_energy(e, x))
            + sum_chunks(&elements.face_anchors, |e| anchor_energy(e, x))
            + sum_chunks(&elements.face_springs, |e| anchor_energy(e, x)),
    }
}

fn anchor_energy<const NV: usize>(e: &AnchorElem<NV>, x: &[DVec3]) -> f64 {
    let r = (0..NV).map(|i| e.w[i] * x[e.v[i] as usize]).sum::<DVec3>() - e.target;
    0.5 * e.k * r.length_squared()
}

/// The result of one assembly.
#[derive(Clone, Copy, Debug, Default)]
pub struct Assembly {
    pub parts: EnergyParts,
    /// Sum of element force magnitudes: the scale the residual is measured against.
    pub force_scale: f64,
}

/// Assembles energy, the gradient over free DOFs (`grad`, length pattern.n) and the lower
/// triangle of the Hessian (`values`, length pattern.nnz()). Both buffers are overwritten.
pub fn assemble(
    el: &Elements,
    pattern: &Pattern,
    x: &[DVec3],
    filter: Filter,
    grad: &mut [f64],
    values: &mut [f64],
) -> Assembly {
    grad.iter_mut().for_each(|g| *g = 0.0);
    values.iter_mut().for_each(|v| *v = 0.0);
    let mut out = Assembly::default();
    let mut acc = Scatter { dof: &pattern.dof, grad, values, force: 0.0 };
    out.parts.membrane = acc.class::<_, 3, 9>(
        &el.membranes,
        &pattern.membranes,
        |e| e.v,
        |e| membrane::eval(e.model, e.lame, &e.rest, &gather(x, &e.v), filter),
    );
    out.parts.bending = acc.class::<_, 4, 12>(
        &el.hinges,
        &pattern.hinges,
        |e| e.v,
        |e| hinge::eval(e.model, &e.rest, &e.positions(x), filter),
    );
    out.parts.bending += acc.quadratic(&el.quadratic, &pattern.quadratic, x);
    out.parts.bending += acc.class::<_, 3, 9>(
        &el.gaussian,
        &pattern.gaussian,
        |e| e.v,
        |e| gaussian_bending::eval(e, &gather(x, &e.v), filter),
    );
    out.parts.volume = acc.class::<_, 4, 12>(
        &el.tets,
        &pattern.tets,
        |e| e.v,
        |e| tet::eval(e.model, e.lame, &e.rest, &gather(x, &e.v), filter),
    );
    out.parts.volume +=
        acc.class::<_, 8, 24>(&el.cells, &pattern.cells, |e| e.v, |e| cell::eval(&e.rest, &gather(x, &e.v), filter));
    out.parts.springs = acc.class::<_, 2, 6>(
        &el.springs,
        &pattern.springs,
        |e| e.v,
        |e| {
            let (a, b) = (x[e.v[0] as usize], x[e.v[1] as usize]);
            let g = spring::gradient(e.k, a, b);
            let gv = SVector::<f64, 6>::from_column_slice(&[g.x, g.y, g.z, -g.x, -g.y, -g.z]);
            let mut h = SMatrix::<f64, 6, 6>::zeros();
            for k in 0..3 {
                h[(k, k)] = e.k;
                h[(k + 3, k + 3)] = e.k;
                h[(k, k + 3)] = -e.k;
                h[(k + 3, k)] = -e.k;
            }
            (spring::energy(e.k, a, b), gv, h)
        },
    );
    out.parts.springs += acc.class::<_, 1, 3>(
        &el.vertex_anchors,
        &pattern.vertex_anchors,
        |e| e.v,
        |e| spring::anchor_eval(e.k, &e.w, &gather(x, &e.v), e.target),
    );
    out.parts.springs += acc.class::<_, 3, 9>(
        &el.face_anchors,
        &pattern.face_anchors,
        |e| e.v,
        |e| spring::anchor_eval(e.k, &e.w, &gather(x, &e.v), e.target),
    );
    out.parts.springs += acc.class::<_, 4, 12>(
        &el.face_springs,
        &pattern.face_springs,
        |e| e.v,
        |e| spring::anchor_eval(e.k, &e.w, &gather(x, &e.v), e.target),
    );
    out.force_scale = acc.force;
    out
}

struct Scatter<'a> {
    dof: &'a [u32],
    grad: &'a mut [f64],
    values: &'a mut [f64],
    force: f64,
}

type Local<const N: usize> = (f64, SVector<f64, N>, SMatrix<f64, N, N>);

impl Scatter<'_> {
    /// Evaluates one element class chunk by chunk; the next chunk is evaluated in parallel
    /// while the previous one is scattered.
    fn class<E: Sync, const NV: usize, const N: usize>(
        &mut self,
        elems: &[E],
        map: &[u32],
        verts: impl Fn(&E) -> [u32; NV] + Sync,
        eval: impl Fn(&E) -> Local<N> + Sync + Send,
    ) -> f64 {
        let np = pairs(NV);
        debug_assert_eq!(map.len(), elems.len() * np);
        let mut energy = 0.0;
        // Two result buffers, reused: one being filled while the other is scattered.
        let mut filling: Vec<Local<N>> = Vec::with_capacity(CHUNK.min(elems.len()));
        let mut ready: Vec<Local<N>> = Vec::with_capacity(CHUNK.min(elems.len()));
        let mut ready_start: Option<usize> = None;
        for (ci, chunk) in elems.chunks(CHUNK).enumerate() {
            rayon::join(
                || chunk.par_iter().map(&eval).collect_into_vec(&mut filling),
                || {
                    if let Some(start) = ready_start {
                        energy += self.scatter::<E, NV, N>(&elems[start..], &map[start * np..], &verts, &ready);
                    }
                },
            );
            std::mem::swap(&mut filling, &mut ready);
            ready_start = Some(ci * CHUNK);
        }
        if let Some(start) = ready_start {
            energy += self.scatter::<E, NV, N>(&elems[start..], &map[start * np..], &verts, &ready);
        }
        energy
    }

    /// Quadratic bending: W = k / 2 |sum_j w_j x_j|^2, gradient k w_a r at vertex a, Hessian
    /// k w_a w_b I3 (constant). Serial: a few flops per stencil pair.
    fn quadratic(&mut self, q: &QuadraticBending, map: &[u32], x: &[DVec3]) -> f64 {
        let (mut energy, mut m) = (0.0, 0);
        for i in 0..q.len() {
            let (vs, ws) = q.stencil(i);
            let k = q.k[i];
            let r = q.laplacian(i, x);
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
                        let pos = map[m];
                        m += 1;
                        if pos != NONE {
                            if pos & DOUBLE != 0 {
                                self.values[(pos & !DOUBLE) as usize] += 2.0 * h;
                            } else {
                                self.values[pos as usize] += h;
                            }
                        }
                    }
                }
            }
        }
        energy
    }

    fn scatter<E, const NV: usize, const N: usize>(
        &mut self,
        elems: &[E],
        map: &[u32],
        verts: &impl Fn(&E) -> [u32; NV],
        res: &[Local<N>],
    ) -> f64 {
        let np = pairs(NV);
        let mut energy = 0.0;
        for (i, (e, g, h)) in res.iter().enumerate() {
            energy += e;
            self.force += g.norm();
            let vs = verts(&elems[i]);
            for p in 0..N {
                let d = self.dof[3 * vs[p / 3] as usize + p % 3];
                if d != NONE {
                    self.grad[d as usize] += g[p];
                }
            }
            let m = &map[i * np..(i + 1) * np];
            let mut k = 0;
            for p in 0..N {
                for q in 0..=p {
                    let pos = m[k];
                    if pos != NONE {
                        if pos & DOUBLE != 0 {
                            self.values[(pos & !DOUBLE) as usize] += 2.0 * h[(p, q)];
                        } else {
                            self.values[pos as usize] += h[(p, q)];
                        }
                    }
                    k += 1;
                }
            }
        }
        energy
    }
}

/// Gradient of the elastic energy (springs included) at every vertex, fixed ones too: at a
/// prescribed vertex it is the reaction force the support exerts (with the opposite sign).
pub fn vertex_gradient(el: &Elements, x: &[DVec3]) -> Vec<DVec3> {
    let mut g = vec![DVec3::ZERO; x.len()];
    let mut add = |vs: &[u32], gl: &[f64]| {
        for (i, &v) in vs.iter().enumerate() {
            g[v as usize] += DVec3::new(gl[3 * i], gl[3 * i + 1], gl[3 * i + 2]);
        }
    };
    for e in &el.membranes {
        add(&e.v, membrane::eval(e.model, e.lame, &e.rest, &gather(x, &e.v), Filter::Exact).1.as_slice());
    }
    for e in &el.hinges {
        add(&e.v, hinge::eval(e.model, &e.rest, &e.positions(x), Filter::Exact).1.as_slice());
    }
    for i in 0..el.quadratic.len() {
        let (vs, ws) = el.quadratic.stencil(i);
        let r = el.quadratic.k[i] * el.quadratic.laplacian(i, x);
        let gl: Vec<f64> = ws.iter().flat_map(|&w| (w * r).to_array()).collect();
        add(vs, &gl);
    }
    for e in &el.gaussian {
        add(&e.v, gaussian_bending::eval(e, &gather(x, &e.v), Filter::Exact).1.as_slice());
    }
    for e in &el.tets {
        add(&e.v, tet::eval(e.model, e.lame, &e.rest, &gather(x, &e.v), Filter::Exact).1.as_slice());
    }
    for e in &el.cells {
        add(&e.v, cell::eval(&e.rest, &gather(x, &e.v), Filter::Exact).1.as_slice());
    }
    for e in &el.springs {
        let d = spring::gradient(e.k, x[e.v[0] as usize], x[e.v[1] as usize]);
        add(&e.v, &[d.x, d.y, d.z, -d.x, -d.y, -d.z]);
    }
    for e in &el.vertex_anchors {
        add(&e.v, spring::anchor_eval::<1, 3>(e.k, &e.w, &gather(x, &e.v), e.target).1.as_slice());
    }
    for e in &el.face_anchors {
        add(&e.v, spring::anchor_eval::<3, 9>(e.k, &e.w, &gather(x, &e.v), e.target).1.as_slice());
    }
    for e in &el.face_springs {
        add(&e.v, spring::anchor_eval::<4, 12>(e.k, &e.w, &gather(x, &e.v), e.target).1.as_slice());
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{edges, grid, GridPattern};

    /// The assembled gradient and Hessian at x against central differences of `part` (the
    /// energy) and of the assembled gradient, over every free DOF.
    fn assert_derivatives(
        el: &Elements,
        pattern: &Pattern,
        x: &[DVec3],
        part: impl Fn(&[DVec3]) -> f64,
        grad: &[f64],
        values: &[f64],
    ) {
        let h = 1e-6;
        for v in 0..x.len() {
            for k in 0..3 {
                let d = pattern.dof[3 * v + k];
                if d == NONE {
                    continue;
                }
                let shifted = |s: f64| {
                    let mut y = x.to_vec();
                    y[v][k] += s;
                    y
                };
                let fd = (part(&shifted(h)) - part(&shifted(-h))) / (2.0 * h);
                assert!((fd - grad[d as usize]).abs() < 1e-6, "gradient at {v}.{k}: {fd} vs {}", grad[d as usize]);
                // Hessian column d against the central difference of gradients.
                let (mut gp, mut vp) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
                let (mut gm, mut vm) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
                assemble(el, pattern, &shifted(h), Filter::Exact, &mut gp, &mut vp);
                assemble(el, pattern, &shifted(-h), Filter::Exact, &mut gm, &mut vm);
                for r in 0..pattern.n as u32 {
                    let column = (gp[r as usize] - gm[r as usize]) / (2.0 * h);
                    let stored =
                        if pattern.position_of(r, d).is_some() { values[pattern.position(r, d) as usize] } else { 0.0 };
                    assert!((column - stored).abs() < 1e-5 * (1.0 + stored.abs()), "H[{r}, {d}]: {column} vs {stored}");
                }
            }
        }
    }

    /// The assembled quadratic bending gradient and Hessian, with its Gaussian term, against
    /// central differences of the energy, on a bent sheet with a held boundary (NONE entries
    /// in the maps).
    #[test]
    fn quadratic_bending_assembles_its_derivatives() {
        let m = grid(glam::DVec2::ONE, (5, 5), GridPattern::Equilateral, 0.0);
        let rigidity: Vec<_> = edges(&m.faces).iter().map(|e| (e.v, 2.0)).collect();
        let boundary = crate::mesh::boundary_vertices(&m.faces, m.rest.len());
        let quadratic = QuadraticBending::build(&m.faces, |i| m.rest[i as usize], &rigidity, &boundary);
        let gaussian = gaussian_bending::elements(&quadratic, &m.faces, |i| m.rest[i as usize], 0.3);
        assert!(!gaussian.is_empty());
        let el = Elements { quadratic, gaussian, ..Default::default() };
        let bending = |y: &[DVec3]| energy(&el, y).bending;
        let x: Vec<DVec3> = m
            .rest
            .iter()
            .enumerate()
            .map(|(i, p)| *p + DVec3::new(0.01 * (i as f64).sin(), 0.0, 0.1 * (3.0 * p.x).sin() * p.y))
            .collect();
        let fixed: Vec<[bool; 3]> = m.rest.iter().map(|p| [p.x == 0.0; 3]).collect();
        let tie: Vec<(u32, [bool; 3])> = (0..x.len() as u32).map(|i| (i, [false; 3])).collect();
        let pattern = Pattern::build(&x, &fixed, &tie, &el);
        let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
        let a = assemble(&el, &pattern, &x, Filter::Exact, &mut grad, &mut values);
        assert!((a.parts.bending - bending(&x)).abs() < 1e-15);
        assert_derivatives(&el, &pattern, &x, |y| energy(&el, y).bending, &grad, &values);
    }

    /// Issue 27: a slab whose tets share one dilatation per cell. The assembled gradient and
    /// Hessian (cells scattered through their 8-vertex maps, bottom held) against central
    /// differences of the energy, and the stability test's inertia against a dense eigen-solve,
    /// at a stretched state (stable) and a strongly compressed, sheared one.
    #[test]
    fn cells_assemble_their_derivatives_and_inertia() {
        use super::super::elements::{CellElem, TetElem};
        use crate::physics::tet::TetRest;
        use crate::physics::{ConstitutiveModel, Lame};
        let (m, _, _) = crate::mesh::tet_slab(glam::DVec2::new(2.0, 1.0), (2, 1), 0.0, &[(1.0, 2, 1.0)], None).unwrap();
        let lame = Lame::solid(1.0, 0.495);
        let tets: Vec<TetElem> = m
            .tets
            .iter()
            .map(|t| TetElem {
                v: *t,
                rest: TetRest::from_rest(t.map(|i| m.rest[i as usize]), glam::DMat3::IDENTITY).unwrap(),
                model: ConstitutiveModel::BazantHencky,
                lame,
            })
            .collect();
        let mut el = Elements::default();
        for c in 0..4u32 {
            let group: Vec<TetElem> = tets.iter().zip(&m.cells).filter(|(_, &k)| k == c).map(|(t, _)| *t).collect();
            el.cells.push(CellElem::from_tets(&group).expect("six tets over eight corners"));
        }
        el.tets = tets.into_iter().map(|t| TetElem { lame: Lame { lambda: 0.0, ..lame }, ..t }).collect();
        let fixed: Vec<[bool; 3]> = m.rest.iter().map(|p| [p.z < -0.99; 3]).collect();
        let tie: Vec<(u32, [bool; 3])> = (0..m.rest.len() as u32).map(|i| (i, [false; 3])).collect();
        let volume = |y: &[DVec3]| energy(&el, y).volume;
        for (stretch, shear) in [(1.05, 0.02), (0.55, 0.3)] {
            let x: Vec<DVec3> = m
                .rest
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let z = p.z + 1.0;
                    DVec3::new(p.x + shear * z * z, p.y + 0.01 * (i as f64).cos() * z, -1.0 + stretch * z)
                })
                .collect();
            let pattern = Pattern::build(&x, &fixed, &tie, &el);
            let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
            let a = assemble(&el, &pattern, &x, Filter::Exact, &mut grad, &mut values);
            assert!((a.parts.volume - volume(&x)).abs() < 1e-14);
            assert_derivatives(&el, &pattern, &x, volume, &grad, &values);
            // Inertia: the LDL^T's count against the dense spectrum.
            let mut dense = nalgebra::DMatrix::<f64>::zeros(pattern.n, pattern.n);
            for c in 0..pattern.n {
                let span = pattern.col_ptr[c] as usize..pattern.col_ptr[c + 1] as usize;
                for (&r, &v) in pattern.row_idx[span.clone()].iter().zip(&values[span]) {
                    dense[(r as usize, c)] = v;
                    dense[(c, r as usize)] = v;
                }
            }
            let negative = nalgebra::SymmetricEigen::new(dense).eigenvalues.iter().filter(|&&l| l < 0.0).count();
            let mut chol = super::super::linear::CholeskySolver::analyze(&pattern);
            let verdict = super::super::stability::test(&pattern, &mut chol, &values).expect("an LDL^T");
            match verdict {
                super::super::stability::Verdict::Stable => assert_eq!(negative, 0, "{stretch}"),
                super::super::stability::Verdict::Unstable { negative: k, .. } => assert_eq!(k, negative, "{stretch}"),
            }
            if stretch < 1.0 {
                assert!(negative > 0, "the compressed, sheared slab is unstable: {negative}");
            }
        }
    }
}
