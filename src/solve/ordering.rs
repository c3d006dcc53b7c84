//! Fill-reducing elimination order for the sparse Cholesky: geometric nested dissection.
//!
//! On 2D and 3D meshes, splitting the vertices at the median of their widest axis and
//! eliminating each half before the separator between them gives far less fill than minimum
//! degree when hinges couple second neighbours (measured in benches/solver.rs).

use glam::DVec3;

/// Parts of at most this many vertices are not split further.
const LEAF: usize = 48;

/// Vertex elimination order. `adjacency` must be symmetric (both directions listed).
pub fn nested_dissection(points: &[DVec3], adjacency: &[Vec<u32>]) -> Vec<u32> {
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
        let mut vs = match task {
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
        let (lo, hi) = vs.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &v| {
            (a.min(points[v as usize]), b.max(points[v as usize]))
        });
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = vs.len() / 2;
        vs.select_nth_unstable_by(mid, |a, b| {
            points[*a as usize][axis].total_cmp(&points[*b as usize][axis]).then(a.cmp(b))
        });
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
        sep.sort_unstable();
        // Pushed in reverse: left is processed first, the separator last.
        stack.push(Task::Emit(sep));
        stack.push(Task::Split(rest));
        stack.push(Task::Split(left));
    }
    order
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
}
