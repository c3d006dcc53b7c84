//! Solving one region of a patch with the rest held (issue 26 item 2): after a remesh, the
//! vertices it touched (plus rings) are brought to equilibrium by the patch's own Newton on a
//! small problem, so that the frame's global solve starts with a residual only on the region's
//! rim instead of a disturbance that needs an inertia shift and many damped steps.
//!
//! The small problem is a `PackedPatch` of its own: the region's vertices free, every other
//! vertex of an element or a kernel row kept held, and the kernel rows (LK14 eq. 4.1) of the
//! kernels with at least `MIN_SHARE` of their weight on free vertices. A kernel that only
//! grazes the region would leave rows over one or two free vertices, several of them alike (a
//! singular KKT matrix): its rows are left to the frame's solve. (Other rules measured:
//! `src/mesh/remesh/README.md`, "Iterations a remesh adds".)

use super::constraints::{Constraints, KernelRows};
use super::frame::solve_frame;
use super::iteration::FrameOutcome;
use super::packed::{LocalReport, PackedPatch, PackedState};
use super::settings::{SolveMode, SolverSettings};
use super::SolveError;

/// A kernel's rows are kept in the region's problem only with at least this fraction of their
/// weight on free vertices.
const MIN_SHARE: f64 = 0.5;
/// Newton iterations at most in the region's solve: a settle, not the frame's solve.
const MAX_ITERATIONS: u32 = 50;

/// Solves the region `which` (packed vertices) of `packed` to equilibrium, the rest held. The
/// positions of the region's free vertices are written back only when the solve succeeds; no
/// other vertex moves. Quasistatic whatever the patch's mode (a settle of the new mesh's
/// vertices at the frame's start, as `settle::settle`).
pub fn solve_region(packed: &mut PackedPatch, settings: &SolverSettings, which: &[u32]) -> LocalReport {
    let clock = std::time::Instant::now();
    let free = region(packed, which);
    let (mut sub, map) = sub_patch(packed, &free);
    let mut report = LocalReport {
        vertices: free.iter().filter(|f| **f).count(),
        held: map.len() - free.iter().filter(|f| **f).count(),
        kernels: sub.constraints.kernels.len(),
        ..Default::default()
    };
    if report.vertices > 0 {
        let local = SolverSettings {
            mode: SolveMode::Quasistatic,
            max_iterations: settings.max_iterations.min(MAX_ITERATIONS),
            stability_check: false,
            ..settings.clone()
        };
        let out: Result<FrameOutcome, SolveError> = solve_frame(&mut sub, &local, 1.0);
        if let Ok(out) = out {
            (report.iterations, report.factorizations, report.converged) =
                (out.iterations, out.factorizations, out.converged);
            for (l, &g) in map.iter().enumerate().filter(|(_, &g)| free[g as usize]) {
                packed.state.x[g as usize] = sub.state.x[l];
            }
        }
    }
    report.ms = clock.elapsed().as_secs_f64() * 1e3;
    report
}

/// The free vertices of the region: `which` less the held and tied vertices.
fn region(packed: &PackedPatch, which: &[u32]) -> Vec<bool> {
    let state = &packed.state;
    let n = state.x.len();
    let mut tied = vec![false; n];
    for (v, &(m, dofs)) in state.tie.iter().enumerate() {
        if m as usize != v || dofs.iter().any(|&t| t) {
            tied[v] = true;
            tied[m as usize] = true;
        }
    }
    let mut free = vec![false; n];
    for &v in which {
        free[v as usize] = state.fixed[v as usize] != [true; 3] && !tied[v as usize];
    }
    free
}

/// Whether a kernel's rows belong to the region's problem: a free vertex among its terms, and on
/// each side with one, at least `MIN_SHARE` of the weight on free vertices. (A kernel reached
/// only through the faces around its lower vertices, whose normals move with the region, is
/// left to the frame's solve.)
fn kept(k: &KernelRows, free: &[bool]) -> bool {
    let share = |side: &mut dyn Iterator<Item = (u32, f64)>| {
        let (mut on, mut total) = (0.0, 0.0);
        for (v, w) in side {
            total += w.abs();
            on += if free[v as usize] { w.abs() } else { 0.0 };
        }
        if total > 0.0 {
            on / total
        } else {
            0.0
        }
    };
    let upper = share(&mut k.upper.iter().copied());
    let lower = share(&mut k.lower.iter().map(|t| (t.v, t.w)));
    let enough = |s: f64| s == 0.0 || s >= MIN_SHARE;
    (upper > 0.0 || lower > 0.0) && enough(upper) && enough(lower)
}

/// The small problem over the free vertices and everything their elements and kernels touch
/// (held), and each of its vertices' packed index in `packed` (increasing).
fn sub_patch(packed: &PackedPatch, free: &[bool]) -> (PackedPatch, Vec<u32>) {
    let el = &packed.elements;
    let mut used = free.to_vec();
    // Whether an element over `v` touches the region; if so its vertices join the problem.
    let mut keep = |v: &[u32]| {
        let touches = v.iter().any(|&i| free[i as usize]);
        if touches {
            v.iter().for_each(|&i| used[i as usize] = true);
        }
        touches
    };
    let picked: Vec<Vec<usize>> = el.terms().iter().map(|t| t.select(&mut keep)).collect();
    let kernels: Vec<usize> = (0..packed.constraints.kernels.len())
        .filter(|&i| {
            let k = &packed.constraints.kernels[i];
            if !kept(k, free) {
                return false;
            }
            let lower = k.lower.iter().flat_map(|t| std::iter::once(t.v).chain(t.ring.iter().flatten().copied()));
            let all: Vec<u32> = k.upper.iter().map(|(v, _)| *v).chain(lower).collect();
            keep(&all)
        })
        .collect();
    let map: Vec<u32> = (0..used.len() as u32).filter(|&v| used[v as usize]).collect();
    let mut local = vec![u32::MAX; used.len()];
    map.iter().enumerate().for_each(|(l, &g)| local[g as usize] = l as u32);
    let to = |v: u32| local[v as usize];
    let arr = |v: &[u32; 3]| v.map(to);

    let sub = el.pick(&picked, &to);

    let s = &packed.state;
    let mut state = PackedState {
        x: map.iter().map(|&g| s.x[g as usize]).collect(),
        v: map.iter().map(|&g| s.v[g as usize]).collect(),
        mass: map.iter().map(|&g| s.mass[g as usize]).collect(),
        fixed: map.iter().map(|&g| if free[g as usize] { s.fixed[g as usize] } else { [true; 3] }).collect(),
        tie: (0..map.len() as u32).map(|i| (i, [false; 3])).collect(),
    };
    state.v.iter_mut().for_each(|v| *v = glam::DVec3::ZERO);
    let rings = |t: &super::constraints::LowerTerm| t.ring.iter().map(arr).collect::<Vec<[u32; 3]>>();
    let rows: Vec<KernelRows> = kernels
        .iter()
        .map(|&i| {
            let k = &packed.constraints.kernels[i];
            let upper = k.upper.iter().map(|&(v, w)| (to(v), w)).collect();
            let lower = k
                .lower
                .iter()
                .map(|t| super::constraints::LowerTerm { v: to(t.v), w: t.w, offset: t.offset, ring: rings(t) })
                .collect::<Vec<_>>();
            let lower_moves = lower.iter().any(|t| {
                std::iter::once(t.v)
                    .chain(t.ring.iter().flatten().copied())
                    .any(|v| state.fixed[v as usize] != [true; 3])
            });
            KernelRows { upper, lower, lower_moves }
        })
        .collect();
    let constraints = Constraints::new(rows, &state.x);
    let sub = PackedPatch {
        state,
        elements: sub,
        constraints,
        length_scale: packed.length_scale,
        cache: Default::default(),
        local: None,
        load_held: false,
        // (a region is solved without contact: scenes with contact do not remesh)
        contact: None,
        carry: None,
    };
    (sub, map)
}

#[cfg(test)]
mod tests {
    use glam::{DVec2, DVec3};

    use super::*;
    use crate::mesh::{grid, GridPattern};
    use crate::physics::{ConstitutiveModel, HingeModel, Lame};

    /// A held flat sheet (the lower layer) under a free sheet 0.05 above it (skin-like: the
    /// membrane much stiffer than bending), their edges held, tied by kernels of radius 0.2 on a
    /// 0.25 grid of centres (LK14 eq. 4.1, offset 0.05), all satisfied at rest.
    fn two_sheets() -> PackedPatch {
        let cells = (10, 10);
        let lower = grid(DVec2::ONE, cells, GridPattern::Equilateral, 0.0);
        let upper = grid(DVec2::ONE, cells, GridPattern::Equilateral, 0.05);
        let n = lower.rest.len() as u32;
        let mut mesh = upper.clone();
        mesh.rest.extend(&lower.rest);
        mesh.faces.extend(lower.faces.iter().map(|f| f.map(|v| v + n)));
        let edge = |p: DVec3| p.x <= 1e-9 || p.x >= 1.0 - 1e-9 || p.y <= 1e-9 || p.y >= 1.0 - 1e-9;
        let lame = Lame::plane_stress(1.0, 0.3);
        let mut packed = PackedPatch::from_shell(
            &mesh,
            ConstitutiveModel::BazantHencky,
            lame,
            1e-2,
            Some((HingeModel::Tan, 1e-6)),
            |p| [edge(p) || p.z == 0.0; 3],
        );
        let rings = super::super::constraints::vertex_rings(&mesh.faces[upper.faces.len()..]);
        let mut rows = Vec::new();
        for i in 1..4 {
            for j in 1..4 {
                let c = DVec2::new(0.25 * i as f64, 0.25 * j as f64);
                let weights = |base: u32, m: &crate::mesh::SurfaceMesh| -> Vec<(u32, f64)> {
                    let w: Vec<(u32, f64)> = (0..m.rest.len() as u32)
                        .filter_map(|v| {
                            let d = m.rest[v as usize].truncate().distance(c);
                            (d < 0.2).then(|| (v + base, 1.0 - d / 0.2))
                        })
                        .collect();
                    let sum: f64 = w.iter().map(|(_, w)| w).sum();
                    w.into_iter().map(|(v, w)| (v, w / sum)).collect()
                };
                let (up, low) = (weights(0, &upper), weights(n, &lower));
                rows.push(KernelRows::new(up, &low, 0.05, &rings, &packed.state.fixed));
            }
        }
        packed.constraints = Constraints::new(rows, &packed.state.x);
        packed
    }

    #[test]
    fn a_region_solve_reaches_equilibrium_there_and_leaves_every_other_vertex_bitwise() {
        let mut packed = two_sheets();
        let rest = packed.state.x.clone();
        let centre = DVec3::new(0.5, 0.5, 0.05);
        // A pop in the middle of the upper sheet: what a bad split placement leaves.
        let which: Vec<u32> = (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z > 0.0 && rest[v as usize].distance(centre) < 0.3)
            .collect();
        for &v in &which {
            packed.state.x[v as usize].z += 0.01 * (1.0 - rest[v as usize].distance(centre) / 0.3);
        }
        let bumped = packed.state.x.clone();
        let settings = SolverSettings { tolerance: 1e-8, ..Default::default() };
        let report = solve_region(&mut packed, &settings, &which);
        println!("{report:?}");
        assert!(report.converged && report.iterations > 0, "{report:?}");
        assert_eq!(report.vertices, which.len(), "the whole region is free: {report:?}");
        // The kernels inside the region are kept (the central one's support lies within it).
        assert!(report.kernels >= 1 && report.kernels < 9, "{report:?}");
        for v in (0..rest.len() as u32).filter(|v| !which.contains(v)) {
            assert_eq!(packed.state.x[v as usize], bumped[v as usize], "vertex {v} moved");
        }
        // The pop is gone: the region is back near the flat sheet, its kernels satisfied.
        let lift = which.iter().map(|&v| (packed.state.x[v as usize].z - 0.05).abs()).fold(0.0, f64::max);
        assert!(lift < 1e-3, "largest lift left {lift}");
        let centre_row = &packed.constraints.values(&packed.state.x)[4];
        assert!(centre_row.length() < 1e-9, "the central kernel's rows: {centre_row}");
        // Deterministic.
        let mut again = two_sheets();
        again.state.x.copy_from_slice(&bumped);
        let _ = solve_region(&mut again, &settings, &which);
        assert_eq!(again.state.x, packed.state.x);
    }
}
