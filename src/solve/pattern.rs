//! DOF numbering, the lower-triangular CSC pattern over free DOFs, and per-element scatter maps
//! (computed once per topology so assembly is a plain indexed add).

use super::element::Coupling;
use super::elements::Elements;
pub use super::scatter::{pairs, DOUBLE, NONE};

#[derive(Clone, Debug)]
pub struct Pattern {
    /// Free DOF index of coordinate k of vertex v at [3 v + k], or NONE when fixed.
    pub dof: Vec<u32>,
    pub n: usize,
    pub col_ptr: Vec<u32>,
    pub row_idx: Vec<u32>,
    /// Position of each column's diagonal entry in `row_idx`.
    pub diag: Vec<u32>,
    /// Scatter maps, one per registered kind (`Elements::terms`): for element e with N local
    /// DOFs, N(N+1)/2 value positions (lower triangle of the local matrix, row-major: p >= q),
    /// NONE where a DOF is fixed; the quadratic kind per stencil pair (a, b <= a), per
    /// coordinate.
    pub maps: Vec<Vec<u32>>,
    /// Elimination order of the free DOFs (nested dissection of the vertices): order[k] is
    /// the DOF eliminated k-th.
    pub order: Vec<u32>,
    /// Which build this is (unique in the process): what the contact maps were made for
    /// (`solve::contact::fit`).
    pub stamp: u64,
}

/// The next `Pattern::stamp`.
static STAMP: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl Pattern {
    /// `tie[v] = (m, dofs)`: coordinates `dofs` of v share vertex m's DOFs (m < v; m = v
    /// when untied).
    pub fn build(
        points: &[glam::DVec3],
        fixed: &[[bool; 3]],
        tie: &[(u32, [bool; 3])],
        elements: &Elements,
    ) -> Pattern {
        let nv = fixed.len();
        let mut dof = vec![NONE; 3 * nv];
        let mut n = 0u32;
        for (v, f) in fixed.iter().enumerate() {
            let (m, tied) = tie.get(v).copied().unwrap_or((v as u32, [false; 3]));
            for k in 0..3 {
                if tied[k] && (m as usize) < v {
                    dof[3 * v + k] = dof[3 * m as usize + k];
                } else if !f[k] {
                    dof[3 * v + k] = n;
                    n += 1;
                }
            }
        }
        // Tied vertices couple wherever their masters do: link in the masters' adjacency.
        // A vertex's DOFs may belong to the vertices up its chain of ties: couple them all.
        let chain = |v: u32| -> Vec<u32> {
            let mut out = vec![v];
            let mut cur = v;
            loop {
                let (m, tied) = tie.get(cur as usize).copied().unwrap_or((cur, [false; 3]));
                if m == cur || !tied.iter().any(|t| *t) {
                    return out;
                }
                out.push(m);
                cur = m;
            }
        };
        // Vertex adjacency (upper: neighbours u >= v), sorted and unique.
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); nv];
        let mut link = |vs: &[u32]| {
            let all: Vec<u32> = vs.iter().flat_map(|&v| chain(v)).collect();
            for &a in &all {
                for &b in &all {
                    let (lo, hi) = (a.min(b), a.max(b));
                    adj[lo as usize].push(hi);
                }
            }
        };
        let terms = elements.terms();
        terms.iter().for_each(|t| t.stencils(&mut link));
        for (v, a) in adj.iter_mut().enumerate() {
            a.push(v as u32); // every free DOF has a diagonal entry
            a.sort_unstable();
            a.dedup();
        }
        let mut col_ptr = Vec::with_capacity(n as usize + 1);
        let mut row_idx = Vec::new();
        let mut diag = Vec::with_capacity(n as usize);
        col_ptr.push(0u32);
        let owned = |v: usize, k: usize| {
            let (m, tied) = tie.get(v).copied().unwrap_or((v as u32, [false; 3]));
            !(tied[k] && (m as usize) < v)
        };
        let mut rows = Vec::new();
        for v in 0..nv {
            for k in 0..3 {
                let c = dof[3 * v + k];
                if c == NONE || !owned(v, k) {
                    continue;
                }
                rows.clear();
                for &u in &adj[v] {
                    for m in 0..3 {
                        let r = dof[3 * u as usize + m];
                        if r != NONE && r >= c {
                            rows.push(r);
                        }
                    }
                }
                rows.sort_unstable();
                rows.dedup();
                diag.push((row_idx.len() + rows.iter().position(|&r| r == c).expect("diagonal")) as u32);
                row_idx.extend_from_slice(&rows);
                col_ptr.push(row_idx.len() as u32);
            }
        }
        // Symmetric vertex graph for the ordering.
        let mut sym: Vec<Vec<u32>> = adj.clone();
        for (v, a) in adj.iter().enumerate() {
            for &u in a {
                if u as usize != v {
                    sym[u as usize].push(v as u32);
                }
            }
        }
        let mut order = Vec::with_capacity(n as usize);
        for v in super::ordering::nested_dissection(points, &sym) {
            for k in 0..3 {
                let d = dof[3 * v as usize + k];
                if d != NONE && owned(v as usize, k) {
                    order.push(d);
                }
            }
        }
        let stamp = STAMP.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut p = Pattern { dof, n: n as usize, col_ptr, row_idx, diag, maps: Vec::new(), order, stamp };
        p.maps = terms
            .iter()
            .map(|t| {
                let (mut map, coupling) = (Vec::new(), t.coupling());
                t.stencils(&mut |v| match coupling {
                    Coupling::Full => map.extend(p.element_map(v)),
                    Coupling::PerCoordinate => map.extend(p.stencil_map(v)),
                });
                map
            })
            .collect();
        p
    }

    /// Whether every coupling of a stencil's vertices is an entry (its symbolic analysis holds).
    pub(crate) fn covers_stencil(&self, v: &[u32]) -> bool {
        // (the entries are symmetric: the lower triangle, diagonal included, settles it)
        let dof = |p: usize| self.dof[3 * v[p / 3] as usize + p % 3];
        (0..3 * v.len()).all(|p| {
            let dp = dof(p);
            dp == NONE || (0..=p).all(|q| dof(q) == NONE || self.position_of(dp, dof(q)).is_some())
        })
    }

    /// Position of the (symmetric) entry of DOFs a and b, None outside the pattern.
    pub(crate) fn position_of(&self, a: u32, b: u32) -> Option<u32> {
        let (r, c) = if a >= b { (a, b) } else { (b, a) };
        let (s, e) = (self.col_ptr[c as usize] as usize, self.col_ptr[c as usize + 1] as usize);
        self.row_idx[s..e].binary_search(&r).ok().map(|k| (s + k) as u32)
    }

    /// Position of the (symmetric) entry of DOFs a and b in the values.
    pub fn position(&self, a: u32, b: u32) -> u32 {
        self.position_of(a, b).expect("pattern holds every element pair")
    }

    pub(crate) fn element_map(&self, verts: &[u32]) -> Vec<u32> {
        let n = 3 * verts.len();
        let mut out = Vec::with_capacity(n * (n + 1) / 2);
        for p in 0..n {
            let dp = self.dof[3 * verts[p / 3] as usize + p % 3];
            for q in 0..=p {
                out.push(self.slot(dp, self.dof[3 * verts[q / 3] as usize + q % 3], p != q));
            }
        }
        out
    }

    /// Where the local entry of DOFs da, db lands: NONE if either is fixed, flagged DOUBLE when
    /// two distinct local DOFs share one global DOF.
    fn slot(&self, da: u32, db: u32, distinct: bool) -> u32 {
        if da == NONE || db == NONE {
            NONE
        } else if distinct && da == db {
            self.position(da, db) | DOUBLE
        } else {
            self.position(da, db)
        }
    }

    /// Scatter map of a stencil whose Hessian is (a scalar matrix) x I3: positions of the
    /// pairs (a, b <= a), coordinate by coordinate.
    fn stencil_map(&self, verts: &[u32]) -> Vec<u32> {
        let mut out = Vec::with_capacity(3 * verts.len() * (verts.len() + 1) / 2);
        for (a, &va) in verts.iter().enumerate() {
            for &vb in &verts[..=a] {
                for k in 0..3 {
                    out.push(self.slot(self.dof[3 * va as usize + k], self.dof[3 * vb as usize + k], va != vb));
                }
            }
        }
        out
    }

    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solve::{Elements, SpringElem};

    /// `covers_stencil` (the lower triangle of a stencil's DOF pairs) against every ordered
    /// pair of its free DOFs, on a chain of springs whose first four vertices are all coupled,
    /// with some coordinates held, for every four distinct vertices.
    #[test]
    fn a_stencil_is_covered_when_all_its_free_pairs_are_in_the_pattern() {
        let n = 7u32;
        let x: Vec<DVec3> = (0..n).map(|i| DVec3::new(f64::from(i), 0.0, 0.0)).collect();
        let springs = (0..n - 1)
            .map(|i| SpringElem { v: [i, i + 1], k: 1.0 })
            .chain([[0, 2], [0, 3], [1, 3]].map(|v| SpringElem { v, k: 1.0 }));
        let mut fixed = vec![[false; 3]; n as usize];
        fixed[2] = [true, false, true];
        fixed[5] = [true; 3];
        let p = Pattern::build(&x, &fixed, &[], &Elements { springs: springs.collect(), ..Default::default() });
        let (mut covered, mut not) = (0, 0);
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    for d in 0..n {
                        let v = [a, b, c, d];
                        if (0..4).any(|i| (0..i).any(|j| v[i] == v[j])) {
                            continue;
                        }
                        let dofs: Vec<u32> = v
                            .iter()
                            .flat_map(|&w| (0..3).map(move |k| 3 * w as usize + k))
                            .map(|i| p.dof[i])
                            .filter(|&d| d != NONE)
                            .collect();
                        let brute = dofs.iter().all(|&i| dofs.iter().all(|&j| p.position_of(i, j).is_some()));
                        assert_eq!(p.covers_stencil(&v), brute, "{v:?}");
                        if brute {
                            covered += 1;
                        } else {
                            not += 1;
                        }
                    }
                }
            }
        }
        assert!(covered > 0 && not > 0, "both outcomes met: {covered} covered, {not} not");
    }
}
