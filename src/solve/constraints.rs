//! LK14 kernel constraints in packed form (eq. 4.1): for each kernel three rows
//! c_k(x) = sum_i w_i x_i(upper) - sum_j w_j (x_j(lower) + t_j n_j(lower)) = 0,
//! n_j the area-weighted vertex normal of the lower layer. The Jacobian is exact: it includes
//! the derivative of the normals when the lower layer moves (its curvature term, lambda^T
//! d2c/dx2, is left out of the Newton matrix: a Gauss-Newton SQP step; with it, more iterations
//! and factorizations: `README.md`).

use std::collections::HashMap;

use glam::{DMat3, DVec3};

/// A lower-layer term of a kernel: packed vertex, weight, normal offset t_j (m) and the faces
/// around the vertex (packed, oriented) that define its normal.
#[derive(Clone, Debug, PartialEq)]
pub struct LowerTerm {
    pub v: u32,
    pub w: f64,
    pub offset: f64,
    pub ring: Vec<[u32; 3]>,
}

/// One kernel's three rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KernelRows {
    pub upper: Vec<(u32, f64)>,
    pub lower: Vec<LowerTerm>,
    /// Whether a lower vertex or a vertex of its rings has a free coordinate (else the lower
    /// side is a constant of the solve, as over a kinematic blend shape).
    pub lower_moves: bool,
}

/// The faces around each vertex of a surface (packed indices, as oriented): what defines the
/// lower layer's area-weighted vertex normals.
pub fn vertex_rings(faces: &[[u32; 3]]) -> HashMap<u32, Vec<[u32; 3]>> {
    let mut map: HashMap<u32, Vec<[u32; 3]>> = HashMap::new();
    for tri in faces {
        for &v in tri {
            map.entry(v).or_default().push(*tri);
        }
    }
    map
}

impl KernelRows {
    /// The body's side: sum_j w_j (x_j + t_j n_j).
    pub fn lower_point(&self, x: &[DVec3]) -> DVec3 {
        self.lower
            .iter()
            .map(|t| {
                let n = ring_normal(&t.ring, x).normalize_or_zero();
                (x[t.v as usize] + n * t.offset) * t.w
            })
            .sum()
    }

    /// The kernel's value c_k (its three rows): the skin's side minus the body's.
    pub fn value(&self, x: &[DVec3]) -> DVec3 {
        self.upper.iter().map(|&(v, w)| x[v as usize] * w).sum::<DVec3>() - self.lower_point(x)
    }

    /// A kernel's rows from its packed weights on both layers; `offset` is the normal offset of
    /// the lower layer, `fixed` the held coordinates of every packed vertex.
    pub fn new(
        upper: Vec<(u32, f64)>,
        lower: &[(u32, f64)],
        offset: f64,
        rings: &HashMap<u32, Vec<[u32; 3]>>,
        fixed: &[[bool; 3]],
    ) -> KernelRows {
        let lower: Vec<LowerTerm> = lower
            .iter()
            .map(|&(v, w)| LowerTerm { v, w, offset, ring: rings.get(&v).cloned().unwrap_or_default() })
            .collect();
        let lower_moves = lower.iter().any(|t| {
            std::iter::once(t.v).chain(t.ring.iter().flatten().copied()).any(|v| fixed[v as usize] != [true; 3])
        });
        KernelRows { upper, lower, lower_moves }
    }
}

/// Every kernel row of a patch, and the Jacobian's sparsity (rows 3 k + a, vertex, coordinate):
/// the solver's equality constraints, the J of its KKT system (`kkt`). They stay the only
/// constraint kind: contact enters beside them as an energy term (an IPC barrier is a registered
/// `element::Term` whose elements the broad phase rebuilds), with its step bound in the line
/// search.
#[derive(Clone, Debug, Default)]
pub struct Constraints {
    pub kernels: Vec<KernelRows>,
    /// Structural entries (row, packed vertex, coordinate), in first-visit order.
    pub entries: Vec<(u32, u32, u8)>,
    /// For each value produced while visiting the rows, the entry it adds into.
    slots: Vec<u32>,
}

/// The skew matrix [v]_x with [v]_x w = v x w.
fn skew(v: DVec3) -> DMat3 {
    DMat3::from_cols(DVec3::new(0.0, v.z, -v.y), DVec3::new(-v.z, 0.0, v.x), DVec3::new(v.y, -v.x, 0.0))
}

/// Sum of the (doubled-area) face normals around a vertex: the direction of the area-weighted
/// vertex normal.
fn ring_normal(ring: &[[u32; 3]], x: &[DVec3]) -> DVec3 {
    ring.iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| x[i as usize]);
            (b - a).cross(c - a)
        })
        .sum()
}

impl Constraints {
    pub fn new(kernels: Vec<KernelRows>, x: &[DVec3]) -> Constraints {
        let mut c = Constraints { kernels, entries: Vec::new(), slots: Vec::new() };
        let mut index: HashMap<(u32, u32, u8), u32> = HashMap::new();
        let (mut entries, mut slots) = (Vec::new(), Vec::new());
        c.visit(x, |row, v, coord, _| {
            let key = (row, v, coord);
            let e = *index.entry(key).or_insert_with(|| {
                entries.push(key);
                (entries.len() - 1) as u32
            });
            slots.push(e);
        });
        c.entries = entries;
        c.slots = slots;
        c
    }

    pub fn rows(&self) -> usize {
        3 * self.kernels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.kernels.is_empty()
    }

    /// The constraint values c_k (one vector per kernel).
    pub fn values(&self, x: &[DVec3]) -> Vec<DVec3> {
        self.kernels.iter().map(|k| k.value(x)).collect()
    }

    /// |c(x)|_1, the l1 merit function's penalty term.
    pub(crate) fn violation_l1(&self, x: &[DVec3]) -> f64 {
        self.values(x).iter().map(|c| c.x.abs() + c.y.abs() + c.z.abs()).sum()
    }

    /// Jacobian values, aligned with `entries` (duplicates summed).
    pub fn jacobian(&self, x: &[DVec3], out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.entries.len(), 0.0);
        let mut next = 0;
        self.visit(x, |_, _, _, value| {
            out[self.slots[next] as usize] += value;
            next += 1;
        });
    }

    /// Visits every Jacobian contribution (row, vertex, coordinate, value) in a fixed order.
    fn visit(&self, x: &[DVec3], mut emit: impl FnMut(u32, u32, u8, f64)) {
        for (k, rows) in self.kernels.iter().enumerate() {
            let r0 = 3 * k as u32;
            for &(v, w) in &rows.upper {
                for a in 0..3u8 {
                    emit(r0 + a as u32, v, a, w);
                }
            }
            for t in &rows.lower {
                for a in 0..3u8 {
                    emit(r0 + a as u32, t.v, a, -t.w);
                }
                if !rows.lower_moves || t.offset == 0.0 {
                    continue;
                }
                // d n = (I - n n^T) / |N| dN, N = sum over the ring of (b - a) x (c - a).
                let big_n = ring_normal(&t.ring, x);
                let len = big_n.length();
                if len == 0.0 {
                    continue;
                }
                let n = big_n / len;
                let proj = (DMat3::IDENTITY - DMat3::from_cols(n * n.x, n * n.y, n * n.z)) * (-t.w * t.offset / len);
                for f in &t.ring {
                    let [pa, pb, pc] = f.map(|i| x[i as usize]);
                    // dN_f / da = [c - b]_x, / db = [a - c]_x, / dc = [b - a]_x.
                    for (q, edge) in [(f[0], pc - pb), (f[1], pa - pc), (f[2], pb - pa)] {
                        let block = proj * skew(edge);
                        for a in 0..3u8 {
                            for b in 0..3u8 {
                                emit(r0 + a as u32, q, b, block.col(b as usize)[a as usize]);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upper: one vertex; lower: a fan of four triangles around a centre vertex, offset 0.3.
    fn fan() -> (Constraints, Vec<DVec3>) {
        let x = vec![
            DVec3::new(0.1, 0.2, 1.0),
            DVec3::new(0.0, 0.0, 0.1),
            DVec3::new(1.0, 0.0, 0.2),
            DVec3::new(0.0, 1.0, -0.1),
            DVec3::new(-1.0, 0.0, 0.3),
            DVec3::new(0.0, -1.0, 0.0),
        ];
        let ring = vec![[1, 2, 3], [1, 3, 4], [1, 4, 5], [1, 5, 2]];
        let k = KernelRows {
            upper: vec![(0, 1.0)],
            lower: vec![LowerTerm { v: 1, w: 1.0, offset: 0.3, ring }],
            lower_moves: true,
        };
        (Constraints::new(vec![k], &x), x)
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let (c, x) = fan();
        let mut jac = Vec::new();
        c.jacobian(&x, &mut jac);
        let h = 1e-6;
        let mut worst = 0.0f64;
        for v in 0..x.len() {
            for b in 0..3 {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[v][b] += h;
                xm[v][b] -= h;
                let fd = (c.values(&xp)[0] - c.values(&xm)[0]) / (2.0 * h);
                for a in 0..3 {
                    let exact: f64 = c
                        .entries
                        .iter()
                        .zip(&jac)
                        .filter(|(e, _)| **e == (a as u32, v as u32, b as u8))
                        .map(|(_, j)| *j)
                        .sum();
                    worst = worst.max((exact - fd[a]).abs());
                }
            }
        }
        assert!(worst < 1e-8, "worst Jacobian error {worst}");
    }

    #[test]
    fn value_is_upper_minus_offset_lower() {
        let (c, mut x) = fan();
        // Flatten the lower fan at z = 0: the normal is +z, the target 0.3 above the centre.
        for p in &mut x[1..] {
            p.z = 0.0;
        }
        x[0] = DVec3::new(0.0, 0.0, 0.3);
        assert!(c.values(&x)[0].length() < 1e-15);
    }
}
