//! VALIDATION.md G: per-frame timings of scenes in the columns of LK14 table 6-1 (constraints
//! N_c, average vertices N_v, constraint build t_c, integration t_I, remesh t_R, sampling t_S,
//! total; and the KCK18 anchor walk t_W), beside the published figures where the scene stands
//! for one of LK14's or KCK18's examples. Runs without a viewer (their times are compute only).

use std::fmt::Write as _;
use std::path::Path;

use skinsim::model::Stage;
use skinsim::scene;
use skinsim_systems::Simulation;

/// One scene's averages over its frames, in seconds.
#[derive(Clone, Debug)]
pub struct TimingRow {
    pub scene: String,
    pub frames: u32,
    pub kernels: f64,
    pub vertices: f64,
    pub t_c: f64,
    pub t_i: f64,
    pub t_r: f64,
    pub t_s: f64,
    pub t_w: f64,
    pub total: f64,
    pub newton_iterations: f64,
}

/// LK14 table 6-1 (2.4 GHz Core i7, TAUCS): (their example, N_c, N_v, total s/frame) for the
/// scene of ours that stands for it.
pub fn lk14_figure(scene_name: &str) -> Option<(&'static str, u32, u32, f64)> {
    let table = [
        ("fig6_3_two_layers", ("Figure 6-3", 436, 7693, 109.082)),
        ("fig6_1_thickness", ("Figure 6-1 middle", 189, 3104, 76.891)),
        ("fig6_1_stiffness", ("Figure 6-1 top", 139, 2696, 72.496)),
        ("fig6_4_compress", ("Figure 6-4 top", 421, 11529, 273.871)),
        ("fig6_4_twist", ("Figure 6-4 middle", 421, 6770, 86.821)),
        ("fig6_4_pinch", ("Figure 6-4 bottom", 401, 5294, 82.878)),
    ];
    table.iter().find(|(k, _)| scene_name.contains(k)).map(|(_, v)| *v)
}

/// KCK18 section 3: the raccoon, 18,929 triangles at 78.63 s/frame (no kernels; N_v stands for
/// the triangle count), for the full-size creature scene.
pub fn kck18_figure(scene_name: &str) -> Option<(&'static str, u32, u32, f64)> {
    (scene_name == "creature").then_some(("KCK18 raccoon (N_v: triangles)", 0, 18929, 78.63))
}

/// The stages of t_R: the remesh and the settle of its new vertices.
pub const T_R: [Stage; 2] = [Stage::Remesh, Stage::Settle];
/// The stages of t_S: the property and kernel resampling, and the kernels' adjust.
pub const T_S: [Stage; 3] = [Stage::PropertyResample, Stage::ConstraintResample, Stage::ConstraintAdjust];

/// Runs `frames` frames (default: all) of a scene and averages the stage timings:
/// t_c = assemble (element and kernel rows packed), t_I = motion (blend shapes) + solve + write-back,
/// t_R = remesh + settle (the relaxation of its new vertices), t_S = property resample + kernel
/// resample + adjust.
pub fn time_scene(path: &Path, frames: Option<u32>) -> Result<TimingRow, String> {
    let built = scene::load(path).map_err(|e| e.to_string())?;
    let frames = frames.unwrap_or(built.scene.frames).min(built.scene.frames).max(1);
    let mut sim = Simulation::new(&built);
    let mut row = TimingRow {
        scene: path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned()),
        frames,
        kernels: 0.0,
        vertices: 0.0,
        t_c: 0.0,
        t_i: 0.0,
        t_r: 0.0,
        t_s: 0.0,
        t_w: 0.0,
        total: 0.0,
        newton_iterations: 0.0,
    };
    for _ in 0..frames {
        let s = sim.step();
        if let Some(reason) = sim.failure() {
            return Err(format!("{}: {reason}", path.display()));
        }
        let ms = |stage: Stage| s.timing(stage) / 1e3;
        row.kernels += s.patches.iter().map(|p| p.constraints as f64 / 3.0).sum::<f64>();
        row.vertices += s.patches.iter().map(|p| p.vertices as f64).sum::<f64>();
        row.newton_iterations += s.patches.iter().map(|p| p.newton_iterations as f64).sum::<f64>();
        row.t_c += ms(Stage::Assemble);
        row.t_i += ms(Stage::Motion) + ms(Stage::Solve) + ms(Stage::Writeback);
        row.t_r += T_R.iter().map(|&k| ms(k)).sum::<f64>();
        row.t_s += T_S.iter().map(|&k| ms(k)).sum::<f64>();
        row.t_w += ms(Stage::AnchorWalk);
        row.total += s.total_ms() / 1e3;
    }
    let n = frames as f64;
    for v in [
        &mut row.kernels,
        &mut row.vertices,
        &mut row.t_c,
        &mut row.t_i,
        &mut row.t_r,
        &mut row.t_s,
        &mut row.t_w,
        &mut row.total,
        &mut row.newton_iterations,
    ] {
        *v /= n;
    }
    Ok(row)
}

/// The markdown table, ours beside LK14's.
pub fn markdown(rows: &[TimingRow]) -> String {
    let mut out = String::from(
        "| scene | frames | N_c | N_v | t_c (s) | t_I (s) | t_R (s) | t_S (s) | t_W (s) | total (s/frame) \
         | Newton its/frame | published example | its N_c | its N_v | its total (s/frame) | speed-up |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let lk = lk14_figure(&r.scene).or_else(|| kck18_figure(&r.scene));
        let _ = writeln!(
            out,
            "| {} | {} | {:.0} | {:.0} | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} | {:.3} | {:.1} | {} | {} | {} | {} | {} |",
            r.scene,
            r.frames,
            r.kernels,
            r.vertices,
            r.t_c,
            r.t_i,
            r.t_r,
            r.t_s,
            r.t_w,
            r.total,
            r.newton_iterations,
            lk.map_or("-".into(), |l| l.0.to_string()),
            lk.map_or("-".into(), |l| l.1.to_string()),
            lk.map_or("-".into(), |l| l.2.to_string()),
            lk.map_or("-".into(), |l| format!("{:.1}", l.3)),
            lk.map_or("-".into(), |l| format!("{:.0}x", l.3 / r.total.max(1e-9))),
        );
    }
    out
}
