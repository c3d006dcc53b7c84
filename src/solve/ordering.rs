//! Fill-reducing elimination order for the sparse Cholesky: geometric nested dissection.
//!
//! On 2D and 3D meshes, splitting the vertices at a median plane and eliminating each half
//! before the separator between them gives far less fill than minimum degree when hinges
//! couple second neighbours (measured in benches/solver.rs).

use glam::DVec3;

/// Parts of at most this many vertices are not split further.
const LEAF: usize = 48;

/// One METIS call at a time: METIS seeds its random generator at each call, but the generator's
/// state is a global of GKlib's (random.c), so two patches ordered at once on two threads
/// changed each other's orders, and so their round-off (`tests/bodies.rs`: a patch alone
/// against beside another).
static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// METIS nested dissection (METIS_NodeND with its default, fixed seed: deterministic) of the
/// graph of a symmetric matrix whose lower triangle is stored as CSC; an elimination order.
pub fn metis_nested_dissection(col_ptr: &[u32], row_idx: &[u32]) -> Option<Vec<u32>> {
    let n = col_ptr.len() - 1;
    let mut adjacency: Vec<Vec<i32>> = vec![Vec::new(); n];
    for c in 0..n {
        for &r in &row_idx[col_ptr[c] as usize..col_ptr[c + 1] as usize] {
            if r as usize != c {
                adjacency[c].push(r as i32);
                adjacency[r as usize].push(c as i32);
            }
        }
    }
    let mut xadj = Vec::with_capacity(n + 1);
    xadj.push(0i32);
    let mut adjncy = Vec::new();
    for a in &mut adjacency {
        a.sort_unstable();
        a.dedup();
        adjncy.extend_from_slice(a);
        xadj.push(i32::try_from(adjncy.len()).ok()?);
    }
    let mut nvtxs = i32::try_from(n).ok()?;
    let (mut perm, mut iperm) = (vec![0i32; n], vec![0i32; n]);
    let _one_at_a_time = METIS.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    // SAFETY: METIS reads the CSR graph (xadj of length n + 1, adjncy entries below n, no
    // self loops) and writes perm and iperm, each of length n; null weights and options select
    // its defaults.
    let status = unsafe {
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    // METIS's internal errors raise SIGTERM, which the command line keeps blocked
    // (skinsim_tools::signals), so METIS may go on after one: use only a true permutation.
    let mut seen = vec![false; n];
    for &v in &perm {
        let slot = seen.get_mut(usize::try_from(v).ok()?)?;
        if std::mem::replace(slot, true) {
            return None;
        }
    }
    // METIS: row i of the permuted matrix is row perm[i] of the original.
    Some(perm.into_iter().map(|v| v as u32).collect())
}

/// Vertex elimination order. `adjacency` must be symmetric (both directions listed).
pub(crate) fn nested_dissection(points: &[DVec3], adjacency: &[Vec<u32>]) -> Vec<u32> {
    let n = points.len();
    let mut order = Vec::with_capacity(n);
    let mut side = vec![0u8; n];
    // Explicit stack of tasks: Split(vertices) or Emit(vertices), processed depth first so the
    // order is left part, right part, separator.
    enum Task {
        Split(Vec<u32>),
        Emit(Vec<u32>),
    }
    let mut stack = vec![Task::Split((0..n as u32).collect())];
    while let Some(task) = stack.pop() {
        let vs = match task {
            Task::Emit(vs) => {
                order.extend_from_slice(&vs);
                continue;
            }
            Task::Split(vs) if vs.len() <= LEAF => {
                order.extend_from_slice(&vs);
                continue;
            }
            Task::Split(vs) => vs,
        };
        let (left, mut sep, rest) = best_cut(points, adjacency, vs, &mut side);
        sep.sort_unstable();
        // Pushed in reverse: left is processed first, the separator last.
        stack.push(Task::Emit(sep));
        stack.push(Task::Split(rest));
        stack.push(Task::Split(left));
    }
    order
}

/// Directions tried for a cut: the axes, the face diagonals and the body diagonals.
const DIRECTIONS: [[f64; 3]; 13] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, 1.0, -1.0],
    [1.0, 1.0, 1.0],
    [1.0, 1.0, -1.0],
    [1.0, -1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// Splits `vs` at the median along the direction whose separator (right-half vertices with a
/// left neighbour) is smallest: (left, separator, rest of the right half). With 13 directions
/// instead of only the widest axis, a closed surface is cut across its waist rather than along
/// its length (measured on the KCK18 creature, 30.7k DOFs: 1.0e9 against 1.44e9 flops per
/// Cholesky, 61-63 against 71-77 ms); on the flat LK14 sheets the flops stay within 2 %.
fn best_cut(points: &[DVec3], adjacency: &[Vec<u32>], vs: Vec<u32>, side: &mut [u8]) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let mut best: Option<(Vec<u32>, Vec<u32>, Vec<u32>)> = None;
    for d in &DIRECTIONS {
        let dir = DVec3::from_array(*d).normalize();
        let mut vs = vs.clone();
        let key = |v: u32| points[v as usize].dot(dir);
        let mid = vs.len() / 2;
        vs.select_nth_unstable_by(mid, |a, b| key(*a).total_cmp(&key(*b)).then(a.cmp(b)));
        let right = vs.split_off(mid);
        let left = vs;
        for &v in &left {
            side[v as usize] = 1;
        }
        let (mut sep, mut rest) = (Vec::new(), Vec::with_capacity(right.len()));
        for v in right {
            if adjacency[v as usize].iter().any(|&u| side[u as usize] == 1) {
                sep.push(v);
            } else {
                rest.push(v);
            }
        }
        for &v in &left {
            side[v as usize] = 0;
        }
        if best.as_ref().is_none_or(|b| sep.len() < b.1.len()) {
            best = Some((left, sep, rest));
        }
    }
    best.expect("at least one direction")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_split_with_its_middle_last() {
        let pts: Vec<DVec3> = (0..200).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
        let adj: Vec<Vec<u32>> =
            (0..200u32).map(|i| [i.wrapping_sub(1), i + 1].into_iter().filter(|&j| j < 200).collect()).collect();
        let order = nested_dissection(&pts, &adj);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..200).collect::<Vec<_>>(), "a permutation");
        assert_eq!(*order.last().unwrap(), 100, "the top separator is eliminated last");
    }

    #[test]
    fn a_tube_along_a_diagonal_is_cut_across_its_waist() {
        // 100 rings of 16 vertices along (1, 1, 0): the widest axis would cut it obliquely.
        let (rings, around) = (100u32, 16u32);
        let axis = DVec3::new(1.0, 1.0, 0.0).normalize();
        let (u, w) = (DVec3::new(1.0, -1.0, 0.0).normalize(), DVec3::Z);
        let id = |r: u32, a: u32| r * around + a % around;
        let mut pts = Vec::new();
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); (rings * around) as usize];
        for r in 0..rings {
            for a in 0..around {
                let t = std::f64::consts::TAU * a as f64 / around as f64;
                pts.push(axis * (0.4 * r as f64) + (u * t.cos() + w * t.sin()) * 1.0);
                let mut link = |p: u32, q: u32| {
                    adj[p as usize].push(q);
                    adj[q as usize].push(p);
                };
                link(id(r, a), id(r, a + 1));
                if r + 1 < rings {
                    link(id(r, a), id(r + 1, a));
                    link(id(r, a), id(r + 1, a + 1));
                }
            }
        }
        let (left, sep, rest) = best_cut(&pts, &adj, (0..rings * around).collect(), &mut vec![0u8; pts.len()]);
        assert_eq!(left.len() + sep.len() + rest.len(), pts.len());
        assert!(sep.len() <= around as usize, "separator of {} vertices, one ring is {around}", sep.len());
        let widest_x = {
            let key = |v: &u32| pts[*v as usize].x;
            let mut vs: Vec<u32> = (0..rings * around).collect();
            vs.sort_by(|a, b| key(a).total_cmp(&key(b)).then(a.cmp(b)));
            let left: std::collections::HashSet<u32> = vs[..vs.len() / 2].iter().copied().collect();
            vs[vs.len() / 2..].iter().filter(|v| adj[**v as usize].iter().any(|q| left.contains(q))).count()
        };
        assert!(widest_x > sep.len(), "an axis cut ({widest_x}) is larger than the best cut ({})", sep.len());
    }
}
