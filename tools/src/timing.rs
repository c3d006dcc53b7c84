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
    /// Each round's total (s/frame); `total` is their median (`rounds`).
    pub totals: Vec<f64>,
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
        totals: Vec::new(),
    };
    for _ in 0..frames {
        let s = sim.step();
        if let Some(reason) = sim.failure() {
            return Err(format!("{}: {reason}", path.display()));
        }
        let ms = |stage: Stage| s.timing(stage) / 1e3;
        row.kernels += s.patches.iter().map(|p| p.outcome.constraints as f64 / 3.0).sum::<f64>();
        row.vertices += s.patches.iter().map(|p| p.vertices as f64).sum::<f64>();
        row.newton_iterations += s.patches.iter().map(|p| p.outcome.iterations as f64).sum::<f64>();
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
    row.totals = vec![row.total];
    Ok(row)
}

/// `rounds` rounds of every scene in turn (A, B, A, B, ...: the machine's speed drifts by up to
/// 2x between hours, so runs compared in one window alternate); each scene's row is its rows'
/// median, field by field (`median_rows`).
pub fn time_rounds(paths: &[&Path], frames: Option<u32>, rounds: u32) -> Result<Vec<TimingRow>, String> {
    let mut runs: Vec<Vec<TimingRow>> = vec![Vec::new(); paths.len()];
    for round in 1..=rounds {
        for (path, rows) in paths.iter().zip(&mut runs) {
            if rounds > 1 {
                eprintln!("timing {} (round {round} of {rounds}) ...", path.display());
            } else {
                eprintln!("timing {} ...", path.display());
            }
            rows.push(time_scene(path, frames)?);
        }
    }
    Ok(runs.iter().map(|rows| median_rows(rows)).collect())
}

/// One scene's rounds as one row: every field the median over the rounds, and every round's
/// total kept in `totals`.
pub fn median_rows(rows: &[TimingRow]) -> TimingRow {
    let of = |field: fn(&TimingRow) -> f64| median(&rows.iter().map(field).collect::<Vec<_>>());
    TimingRow {
        scene: rows[0].scene.clone(),
        frames: rows[0].frames,
        kernels: of(|r| r.kernels),
        vertices: of(|r| r.vertices),
        t_c: of(|r| r.t_c),
        t_i: of(|r| r.t_i),
        t_r: of(|r| r.t_r),
        t_s: of(|r| r.t_s),
        t_w: of(|r| r.t_w),
        total: of(|r| r.total),
        newton_iterations: of(|r| r.newton_iterations),
        totals: rows.iter().map(|r| r.total).collect(),
    }
}

/// The median (the mean of the middle two of an even count).
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// The least and the most of `values` (times: never negative).
pub fn least_most(values: &[f64]) -> (f64, f64) {
    values.iter().fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(*v), b.max(*v)))
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
    let rounds = rows.first().map_or(0, |r| r.totals.len());
    if rounds > 1 {
        let _ = write!(
            out,
            "\nTotals over {rounds} rounds, every scene once per round in turn (each column above: the \
             median over the rounds), and each scene's median over the first's:\n\n\
             | scene | total (s/frame), median | least | most | over {} |\n|---|---|---|---|---|\n",
            rows[0].scene
        );
        for r in rows {
            let (least, most) = least_most(&r.totals);
            let _ = writeln!(
                out,
                "| {} | {:.3} | {least:.3} | {most:.3} | {:.3} |",
                r.scene,
                r.total,
                r.total / rows[0].total.max(1e-12),
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scene: &str, total: f64, t_i: f64) -> TimingRow {
        TimingRow {
            scene: scene.into(),
            frames: 2,
            kernels: 10.0,
            vertices: 100.0,
            t_c: 0.1,
            t_i,
            t_r: 0.0,
            t_s: 0.0,
            t_w: 0.0,
            total,
            newton_iterations: 3.0,
            totals: vec![total],
        }
    }

    #[test]
    fn a_scenes_rounds_give_their_medians_and_the_table_their_spread_and_ratio() {
        let a = median_rows(&[row("a", 4.0, 3.0), row("a", 2.0, 1.0), row("a", 3.0, 2.0)]);
        assert_eq!((a.total, a.t_i, a.totals.clone()), (3.0, 2.0, vec![4.0, 2.0, 3.0]));
        let b = median_rows(&[row("b", 1.0, 0.5), row("b", 2.0, 1.5), row("b", 1.5, 1.0)]);
        assert_eq!((b.total, b.t_i), (1.5, 1.0));
        let table = markdown(&[a.clone(), b]);
        assert!(table.contains("Totals over 3 rounds"), "{table}");
        assert!(table.contains("| a | 3.000 | 2.000 | 4.000 | 1.000 |"), "{table}");
        assert!(table.contains("| b | 1.500 | 1.000 | 2.000 | 0.500 |"), "{table}");
        let one = markdown(&[median_rows(&[row("a", 4.0, 3.0)])]);
        assert!(!one.contains("rounds"), "one round: the table alone\n{one}");
    }
}
