//! What a built scene will cost to run, as `check` prints it (issue 66): per patch its vertices,
//! its degrees of freedom, the memory of its Newton factor and the time of a frame, for a smooth
//! frame and a buckling one. The factor and its time follow nested dissection's growth (a
//! surface: n log n fill, n^1.5 work; a volume: n^(4/3) fill, n^2 work) with constants from
//! measured factorizations (ENGINEERING-NOTES.md, src/solve/README.md): a 61k-DOF shell KKT
//! system, 35.5M factor values; a 21k-DOF shell, 0.18 s a factorization; a 470k-DOF tet slab,
//! 360M values and 21.9 s; plus an assembly per vertex. They are orders of magnitude, not
//! promises: a frame's Newton iterations depend on the physics (a character's kernels can take
//! 100 in a frame).

use crate::model::LayerKind;

use super::BuiltScene;

/// Factor values per DOF and log2(DOF) of a surface's system (35.5M / (61k x 15.9)).
const SHELL_FILL: f64 = 37.0;
/// Factor values per DOF^(4/3) of a volume's system (360M / 470k^(4/3)).
const VOLUME_FILL: f64 = 10.0;
/// Seconds per DOF^1.5 of a surface's factorization (0.18 s / 21k^1.5).
const SHELL_WORK: f64 = 5.9e-8;
/// Seconds per DOF^2 of a volume's factorization (21.9 s / 470k^2).
const VOLUME_WORK: f64 = 1.0e-10;
/// Seconds per vertex of a Newton iteration's assembly, besides the factorization: a volume's
/// projected tet Hessians (h15/patch_3d_small: 0.35 s of 0.4 s an iteration at 10k vertices),
/// a shell's triangles and hinges (kck18/creature_contact_quick: 3-4 ms at 1.3k).
const VOLUME_ASSEMBLY: f64 = 35e-6;
const SHELL_ASSEMBLY: f64 = 2e-6;
/// Newton iterations (one factorization and one assembly each) in a frame that stays smooth,
/// and in one that buckles (src/solve/README.md: 187-247 factorizations over fig. 6-3's 10
/// frames, most in its buckling frames; fig. 6-4's pinch buckles in 44).
pub const ITERATIONS: [f64; 2] = [3.0, 40.0];

/// One patch's estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchCost {
    pub name: String,
    /// The patch's own vertices (a shared body's copy left out).
    pub vertices: u64,
    /// 3 per vertex of its shell and volume layers (a vertex two layers share counted once).
    pub dofs: u64,
    /// The Newton factor's values (8 bytes each).
    pub factor_bytes: f64,
    /// A frame's time (s): [smooth, buckling].
    pub frame_seconds: [f64; 2],
}

/// Every patch's estimate.
pub fn costs(scene: &BuiltScene) -> Vec<PatchCost> {
    scene
        .patches
        .iter()
        .map(|p| {
            let own = &p.layers[p.body.map_or(0, |_| 1)..];
            let vertices: u64 = own.iter().map(|l| l.mesh.rest().len() as u64).sum();
            let solved = own.iter().filter(|l| l.kind != LayerKind::Kinematic);
            let free: u64 = solved.clone().map(|l| l.shared.iter().filter(|s| s.is_none()).count() as u64).sum();
            let volume = solved.clone().any(|l| l.kind == LayerKind::Volume);
            let n = 3.0 * free as f64;
            let (values, iteration) = if n == 0.0 {
                (0.0, 0.0)
            } else if volume {
                (VOLUME_FILL * n.powf(4.0 / 3.0), VOLUME_WORK * n * n + VOLUME_ASSEMBLY * vertices as f64)
            } else {
                (SHELL_FILL * n * n.log2().max(1.0), SHELL_WORK * n.powf(1.5) + SHELL_ASSEMBLY * vertices as f64)
            };
            PatchCost {
                name: p.name.clone(),
                vertices,
                dofs: 3 * free,
                factor_bytes: 8.0 * values,
                frame_seconds: ITERATIONS.map(|i| i * iteration),
            }
        })
        .collect()
}

/// A duration for a message: ms below a second, s below ten minutes, else min or h.
pub fn duration(s: f64) -> String {
    if s < 1.0 {
        format!("{:.0} ms", (s * 1e3).max(1.0))
    } else if s < 600.0 {
        format!("{s:.1} s")
    } else if s < 36_000.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.0} h", s / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_constants_give_back_their_measurements() {
        let n: f64 = 61e3;
        assert!((SHELL_FILL * n * n.log2() / 35.5e6 - 1.0).abs() < 0.05);
        assert!((SHELL_WORK * 21e3f64.powf(1.5) / 0.18 - 1.0).abs() < 0.05);
        let n: f64 = 470e3;
        assert!((VOLUME_FILL * n.powf(4.0 / 3.0) / 360e6 - 1.0).abs() < 0.05);
        assert!((VOLUME_WORK * n * n / 21.9 - 1.0).abs() < 0.05);
        assert_eq!(duration(0.0123), "12 ms");
        assert_eq!(duration(42.0), "42.0 s");
        assert_eq!(duration(7200.0), "120 min");
    }
}
