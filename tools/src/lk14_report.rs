//! `skinsim report`, LK14 part (VALIDATION.md F, issue 5): uniform meshes at several
//! resolutions against adaptive meshes at several refinement settings, for the wavelength case
//! (case 10, the fig. 3-3 strip), the two-layer case (case 11, fig. 6-3) and the localized
//! fig. 6-4 pinch. Each run records
//! the wall time per frame, the mean vertex count, the wavelength error against the kernels, and
//! the final shape's and energy's errors against the finest uniform run. Every run of a case
//! gets the same smooth imperfection (a Perlin perturbation in material space): with the
//! default vertex-random one each mesh draws its own, and the wrinkle mode it seeds (measured
//! on case 10: 14 or 16 waves by seed, at any resolution) would swamp the discretization
//! error. Writes speed_error_lk14.md, .csv, .svg and .png (time per frame against shape error), and
//! speed_error_lk14_map.* and _height.* (against the wrinkle-map and height-field errors).
//!
//! Case 10's reference is 512 x 72 (32 elements per wavelength). Before the constrained
//! stability test (issue 26 item 5) that run stopped at a saddle in its first frame and wrinkled
//! 17 % short of the kernels' wavelength, with 0.9 % more energy than 384 x 54; it now lands on
//! the coarser meshes' mode.

use std::fmt::Write as _;
use std::path::Path;

use skinsim::physics::BendingElement;
use skinsim::scene;
use skinsim_systems::{FrameStats, Simulation};

use crate::field_error;
use crate::plot::{LogLog, Point};
use crate::report::csv_text;
use crate::timing::{least_most, median, T_R, T_S};
use crate::wrinkles::{resample_on_grid, row_peaks};

/// One run of the sweep.
#[derive(Clone, Debug)]
pub struct Lk14Row {
    pub series: String,
    pub setting: String,
    pub mean_vertices: f64,
    /// The median of `times`.
    pub ms_per_frame: f64,
    /// Wall time per frame (ms), one per round.
    pub times: Vec<f64>,
    pub newton_iterations: u32,
    /// Frames whose Newton solve stopped at its iteration limit (their state is kept).
    pub unconverged_frames: u32,
    /// Dominant (case 10) or nearest-to-lambda_2 (case 11) wavelength against the kernels'.
    pub wavelength_error: f64,
    /// Final energy against the series' reference (the finest uniform run).
    pub energy_error: f64,
    /// Final shape against the reference's: RMS distance over a grid in material space, over
    /// the reference's RMS wrinkle height.
    pub shape_error: f64,
    /// Adaptive runs: this run's time over the uniform time at the same shape error
    /// (`time_at_error`); `upper` when no uniform run but the reference is as accurate (the ratio
    /// is then at most this).
    pub time_ratio: Option<(f64, bool)>,
    /// The same at the same |energy error|.
    pub time_ratio_energy: Option<(f64, bool)>,
    /// Wrinkle-map error against the reference: the mean angle (radians) between the normals
    /// of the two baked maps (`field_error::map_error`).
    pub map_error: f64,
    /// The time ratio at the same wrinkle-map error.
    pub time_ratio_map: Option<(f64, bool)>,
    /// Height-field error against the reference, without the affine part
    /// (`field_error::height_error`); NaN when the run's material grid is not the reference's.
    pub height_error: f64,
    /// The time ratio at the same height-field error.
    pub time_ratio_height: Option<(f64, bool)>,
    /// Frames whose remesh changed the swept layer's topology.
    pub remeshes: u32,
    /// Remesh, settle and resampling (property, kernel, adjust) over the timed frames' wall
    /// time, the run's and its largest frame's (issue 26's target: under 15 % of a frame).
    pub remesh_share: RemeshShare,
    /// Adaptive runs: the remeshes at a held load (past the last keyframe, remeshing every frame
    /// for `HELD_FRAMES`) and what they added.
    pub held: Option<HeldRemeshes>,
    /// The series' reference run (the finest uniform one).
    pub reference: bool,
    energy: f64,
    grid: Vec<glam::DVec3>,
    grid_uv: Vec<glam::DVec2>,
    /// The wrinkle map baked (`maps/`), and its normals before the encoding.
    map: image::RgbImage,
    normals: Vec<glam::DVec3>,
}

/// Wrinkle maps baked for the map error: pixels over the material rectangle's longer side.
const MAP_SIZE: u32 = 512;

/// A case: its scene, the layer whose mesh is swept, the mesh line to replace, the kernel
/// wavelength (mm) the analysis compares with (none for the pinch, whose spectrum its own
/// shape dominates), and the settings.
struct Case {
    name: &'static str,
    scene: &'static str,
    layer: &'static str,
    mesh: &'static str,
    lambda_mm: Option<f64>,
    /// The imperfection's Perlin cell (mm): half the wrinkle wavelength, or the whole one where
    /// that made the uniform meshes agree on the wrinkles' phase (the localized case).
    cell_mm: f64,
    /// Waves added to the imperfection (wavelength, amplitude; mm) along x, and then the noise's
    /// amplitude (mm; None: the scene's).
    waves: &'static [(f64, f64)],
    noise_mm: Option<f64>,
    /// Uniform meshes, coarsest first: (cells x, cells y).
    uniform: &'static [(u32, u32)],
    /// Adaptive: the starting cells and (size_min, size_max in mm, refine_angle, and
    /// refine_compression in mm); the refinement is swept by the angle (the wrinkles' curvature
    /// sets the edge length, not size_min). Remeshed every `every` frames.
    start: (u32, u32),
    adaptive: &'static [(f64, f64, f64, f64)],
    every: u32,
    /// With the wavelength term: refined ahead of the load and held (`Ahead`); None: across
    /// this frame's compression, every setting at `PER_WAVELENGTH`.
    ahead: Option<Ahead>,
    /// Runs of each series that `--quick` keeps (the first: the coarsest uniform meshes, the first
    /// adaptive settings).
    quick: usize,
}

/// Adaptive runs with the wavelength term refined ahead of the load (`lookahead`), before the
/// first solve, and held there after (`hold`): a run of the first setting for each margin and
/// each number of elements per wavelength.
struct Ahead {
    /// Every edge bounded (`isotropic`), not only those across the compression.
    isotropic: bool,
    /// Grown this many mm around where the base will compress (`margin`).
    margins_mm: &'static [f64],
    per_wavelength: &'static [u32],
    /// Remeshed every this many frames (the case's `every` is that of the runs without).
    every: u32,
}

const CASES: [Case; 4] = [
    Case {
        name: "case 10 (fig. 3-3 strip, lambda 6 mm)",
        scene: "fig3_3_e1_h1_quick.ron",
        layer: "skin",
        mesh: "cells: (128, 18), pattern: Equilateral, z: 0.01875",
        lambda_mm: Some(6.0),
        cell_mm: 3.0,
        waves: &[],
        noise_mm: None,
        uniform: &[(64, 9), (96, 13), (128, 18), (192, 27), (256, 36), (384, 54), (512, 72)],
        start: (64, 9),
        every: 3,
        // The whole strip compresses, across its length: refined across it before the first
        // solve and held, each run's one remesh (held, the angle sets nothing). Measured against
        // the term on this frame's compression at lambda / 8 and the four angles 0.4-0.2, one
        // run each: map ratios 0.43-0.52 against 0.72-1.89, shape 0.54-0.65 against 1.01-3.45
        // (src/mesh/remesh/README.md, "Cases 10 and 11 read at the last frame").
        ahead: Some(Ahead { isotropic: false, margins_mm: &[0.0], per_wavelength: &[6, 8, 12], every: 3 }),
        adaptive: &[(0.25, 3.0, 0.4, 0.05), (0.25, 3.0, 0.3, 0.03), (0.25, 3.0, 0.2, 0.02), (0.25, 3.0, 0.2, 0.01)],
        quick: 2,
    },
    Case {
        name: "case 11 (fig. 6-3 two layers, lambda_2 2 mm)",
        scene: "fig6_3_two_layers_quick.ron",
        layer: "epidermis",
        mesh: "cells: (96, 55), pattern: Equilateral, z: 1.0125",
        lambda_mm: Some(2.0),
        cell_mm: 1.0,
        // Sinusoids along the compression at lambda_1 and lambda_2, which set both wrinkle modes'
        // phase and sign, and a quarter of the noise: with the noise alone (0.002 mm, or 0.01,
        // or a cell of lambda_1) the meshes picked modes apart, the map error was not monotone
        // in the resolution and no adaptive run was within 1.2x (src/mesh/remesh/README.md,
        // "Case 11's modes pinned by waves").
        waves: &[(8.0, 0.001), (2.0, 0.001)],
        noise_mm: Some(0.0005),
        uniform: &[(48, 28), (64, 37), (96, 55), (128, 74)],
        start: (48, 28),
        every: 3,
        // Every edge bounded: across the compression only, the first remesh also flipped 3874
        // edges of the split start and lost 3 degrees of map error to the uniform 96 x 56 that
        // lambda_2 / 8 otherwise makes; lambda_2 / 12 (21865 vertices) was less accurate than
        // either (src/mesh/remesh/README.md, "Case 11's modes pinned by waves").
        ahead: Some(Ahead { isotropic: true, margins_mm: &[0.0], per_wavelength: &[6, 8], every: 3 }),
        adaptive: &[(0.1, 1.0, 0.6, 0.05), (0.1, 1.0, 0.4, 0.02), (0.1, 1.0, 0.3, 0.01), (0.1, 1.0, 0.2, 0.01)],
        quick: 2,
    },
    // Wrinkles in a disc rather than over the whole patch: where adaptivity can pay.
    Case {
        name: "fig. 6-4 pinch (two layers, lambda_2 2 mm)",
        scene: "fig6_4_pinch.ron",
        layer: "epidermis",
        mesh: "cells: (128, 74), pattern: Equilateral, z: 1.0125",
        lambda_mm: None,
        cell_mm: 1.0,
        waves: &[],
        noise_mm: None,
        uniform: &[(64, 37), (96, 55), (128, 74)],
        start: (64, 37),
        every: 1,
        // Refined ahead over the disc and 2 or 4 mm around, held, one remesh before the first
        // solve (with no margin the wrinkles form on the start mesh at the disc's rim). Map error
        // 0.56-0.77 degrees against 1.24-1.41 with the angle sweep, at fewer iterations while
        // loading; lambda_2 / 8 was no more accurate than / 6 and cost 14.7 iterations per held
        // remesh (src/mesh/remesh/README.md, "The fig. 6-4 pinch refined ahead in the report",
        // "Margins for the fig. 6-4 pinch").
        ahead: Some(Ahead { isotropic: true, margins_mm: &[2.0, 4.0], per_wavelength: &[6], every: 10 }),
        adaptive: &[(0.1, 1.0, 0.4, 0.02), (0.1, 1.0, 0.3, 0.02), (0.1, 1.0, 0.2, 0.02)],
        quick: 2,
    },
    // Issue 26 item 6: a pinch of radius 6 mm on a 64 x 48 mm patch, wrinkles on under a
    // quarter of it; adaptive runs refine by the wavelength term (`WAVELENGTH_CASES`).
    Case {
        name: "localized pinch (64 x 48 mm, lambda_2 2 mm)",
        scene: "pinch_localized.ron",
        layer: "epidermis",
        mesh: "cells: (128, 111), pattern: Equilateral, z: 1.0125",
        lambda_mm: None,
        // (with a cell of lambda_2 / 2 the uniform meshes up to 384 x 333 took one phase or the
        // other in patches of the ring, and no reference converged)
        cell_mm: 2.0,
        waves: &[],
        noise_mm: None,
        // (the reference 384 x 333: a 256 x 222 run differed from it by 0.2 degrees)
        uniform: &[(96, 83), (128, 111), (192, 166), (256, 222), (384, 333)],
        // (edges at most half the kernel radius, 0.5 mm: from a coarser start the first remesh
        // splits every edge)
        start: (128, 111),
        // One remesh, before the first solve, for every wrinkle to come: the base compresses
        // only inside the 6 mm disc and the ring forms out to about 14 mm, so refined 6 or 9 mm
        // around where the base will compress; later remeshes of the wrinkled ring moved its
        // phase off the reference's (src/mesh/remesh/README.md, "Refining ahead of the load").
        every: 8,
        ahead: Some(Ahead { isotropic: true, margins_mm: &[6.0, 9.0], per_wavelength: &[PER_WAVELENGTH], every: 8 }),
        adaptive: &[(0.1, 1.0, 0.6, 0.05)],
        // (its runs are the sweep's largest: one of each keeps the quick test short)
        quick: 1,
    },
];

/// Each case's name in the maps' file names.
const CASE_KEYS: [&str; 4] = ["case10", "case11", "pinch", "localized"];
/// And in the report's `--cases` option.
const CASE_FLAGS: [&str; 4] = ["10", "11", "pinch", "localized"];

/// Adaptive runs of a case whose index is here refine by the wavelength term too
/// (`PER_WAVELENGTH` elements per kernel wavelength across the compression, or those of the
/// case's `Ahead`, from half the critical strain) by default.
const WAVELENGTH_CASES: [usize; 4] = [0, 1, 2, 3];
const PER_WAVELENGTH: u32 = 8;

/// Which cases' adaptive runs refine by the wavelength term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WavelengthTerm {
    /// Those where it was measured to pay (`WAVELENGTH_CASES`).
    #[default]
    Default,
    All,
    Off,
}

impl WavelengthTerm {
    fn applies(self, case: usize) -> bool {
        match self {
            WavelengthTerm::Default => WAVELENGTH_CASES.contains(&case),
            WavelengthTerm::All => true,
            WavelengthTerm::Off => false,
        }
    }

    /// The report's command-line option that selects it.
    fn flag(self) -> &'static str {
        match self {
            WavelengthTerm::Default => "",
            WavelengthTerm::All => " --wavelength-term all",
            WavelengthTerm::Off => " --wavelength-term off",
        }
    }
}

/// What `speed_error` sweeps.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The coarsest settings of each series (`Case::quick`) and two frames.
    pub quick: bool,
    /// Every shell's bending element.
    pub element: BendingElement,
    /// Indices into `CASES` (case 10, case 11, pinch, localized); empty: all.
    pub cases: Vec<usize>,
    pub wavelength_term: WavelengthTerm,
    /// Rounds of each case's runs, every run once per round in turn, so that uniform and
    /// adaptive runs alternate in one window (the machine drifts between hours); each run's time
    /// is its median over the rounds. At least 1.
    pub rounds: u32,
}

/// Runs the sweeps of `sweep.cases`.
pub fn speed_error(out: &Path, sweep: &Sweep) -> Result<Vec<Lk14Row>, Box<dyn std::error::Error>> {
    let Sweep { quick, element, ref cases, wavelength_term, rounds } = *sweep;
    std::fs::create_dir_all(out)?;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/lk14");
    let mut rows = Vec::new();
    for (ci, case) in CASES.iter().enumerate().filter(|(i, _)| cases.is_empty() || cases.contains(i)) {
        let text = smooth_perturbation(&std::fs::read_to_string(dir.join(case.scene))?, case);
        let text = with_iteration_cap(&with_element(&text, element), ITERATION_CAP);
        let take = |n: usize| if quick { n.min(case.quick) } else { n };
        let (mut series, mut texts): (Vec<Lk14Row>, Vec<String>) = (Vec::new(), Vec::new());
        for &(nx, ny) in case.uniform.iter().take(take(case.uniform.len())) {
            let scene_text = mesh_line(&text, case.mesh, nx, ny, "");
            keep_scene(out, CASE_KEYS[ci], series.len(), "uniform", &scene_text)?;
            series.push(run(case, &scene_text, &dir, "uniform", format!("{nx} x {ny} cells"), quick)?);
            texts.push(scene_text);
        }
        let term = wavelength_term.applies(ci);
        // (every setting without the term or without `ahead`; with both, the first setting at each
        // margin and number of elements per wavelength)
        let runs: Vec<_> = match (&case.ahead, term) {
            (Some(a), true) => a
                .margins_mm
                .iter()
                .flat_map(|&m| a.per_wavelength.iter().map(move |&n| (&case.adaptive[0], Some((m, a)), n)))
                .collect(),
            _ => case.adaptive.iter().map(|s| (s, None, PER_WAVELENGTH)).collect(),
        };
        let count = take(runs.len());
        for (&(lo, hi, angle, c), ahead, n) in runs.into_iter().take(count) {
            let lookahead = match ahead {
                Some((m, a)) => format!(", isotropic: {}, lookahead: true, margin: {m}, hold: true", a.isotropic),
                None => String::new(),
            };
            let wavelength = if term {
                format!(", wavelength: Some((per_wavelength: {n}, onset: 0.5{lookahead}))")
            } else {
                String::new()
            };
            let every = ahead.map_or(case.every, |(_, a)| a.every);
            let remesh = format!(
                ", remesh: Some((size_min: {lo}, size_max: {hi}, refine_angle: {angle}, refine_compression: {c}, \
                 every: {every}{wavelength}))"
            );
            let scene_text = mesh_line(&text, case.mesh, case.start.0, case.start.1, &remesh);
            let by_wavelength = match (term, ahead) {
                (true, Some((0.0, _))) => format!(", lambda / {n} ahead, held"),
                (true, Some((m, _))) => format!(", lambda / {n} ahead, {m} mm around, held"),
                (true, None) => format!(", lambda / {n}"),
                (false, _) => String::new(),
            };
            let setting = format!("angle {angle}, size {lo} .. {hi} mm, c {c} mm, every {every}{by_wavelength}");
            keep_scene(out, CASE_KEYS[ci], series.len(), "adaptive", &scene_text)?;
            series.push(run(case, &scene_text, &dir, "adaptive", setting, quick)?);
            texts.push(scene_text);
        }
        // Later rounds: every run of the case again, in the same order, timed only.
        for _ in 1..rounds.max(1) {
            for (r, t) in series.iter_mut().zip(&texts) {
                r.times.push(time_run(case, t, &dir, quick)?);
                eprintln!(
                    "{}: {}: {:.0} ms/frame (round {})",
                    r.series,
                    r.setting,
                    r.times.last().unwrap_or(&0.0),
                    r.times.len()
                );
            }
        }
        series.iter_mut().for_each(|r| r.ms_per_frame = median(&r.times));
        // The reference: the finest uniform run.
        let finest = take(case.uniform.len()) - 1;
        series[finest].reference = true;
        let (reference, shape) = (series[finest].energy, series[finest].grid.clone());
        let mean = shape.iter().map(|x| x.z).sum::<f64>() / shape.len() as f64;
        let height = (shape.iter().map(|x| (x.z - mean).powi(2)).sum::<f64>() / shape.len() as f64).sqrt();
        let (normals, grid_uv) = (series[finest].normals.clone(), series[finest].grid_uv.clone());
        std::fs::create_dir_all(out.join("maps"))?;
        for (k, r) in series.iter().enumerate() {
            let kind = if r.series.ends_with("adaptive") { "adaptive" } else { "uniform" };
            r.map.save(out.join("maps").join(format!("{}_{k}_{kind}.png", CASE_KEYS[ci])))?;
        }
        for r in &mut series {
            r.energy_error = r.energy / reference - 1.0;
            let d2 = r.grid.iter().zip(&shape).map(|(a, b)| a.distance_squared(*b)).sum::<f64>();
            r.shape_error = (d2 / shape.len() as f64).sqrt() / height;
            r.map_error = field_error::sample_error(&normals, &r.normals);
            r.height_error =
                if r.grid_uv == grid_uv { field_error::height_error(&grid_uv, &shape, &r.grid) } else { f64::NAN };
        }
        // (a run without the error, a NaN height, is left off the front)
        let front = |f: fn(&Lk14Row) -> f64| -> Vec<(f64, f64)> {
            series[..finest].iter().map(|r| (f(r), r.ms_per_frame)).filter(|(e, _)| !e.is_nan()).collect()
        };
        let (uniform, energy, maps, heights) = (
            front(|r| r.shape_error),
            front(|r| r.energy_error.abs()),
            front(|r| r.map_error),
            front(|r| r.height_error),
        );
        for r in &mut series[finest + 1..] {
            let ratio =
                |front: &[(f64, f64)], e: f64| time_at_error(front, e).map(|(t, upper)| (r.ms_per_frame / t, upper));
            r.time_ratio = ratio(&uniform, r.shape_error);
            r.time_ratio_energy = ratio(&energy, r.energy_error.abs());
            r.time_ratio_map = ratio(&maps, r.map_error);
            r.time_ratio_height = ratio(&heights, r.height_error);
        }
        rows.extend(series);
    }
    write(out, &rows, element, wavelength_term, cases, rounds.max(1))?;
    plots(&out.join("speed_error_lk14"), &rows)?;
    Ok(rows)
}

/// The uniform runs' time at `error`, along their Pareto front (each run kept only if it is
/// more accurate than every cheaper one): log-log interpolation between the two front runs
/// around `error`, or, when `error` is below them all, the most accurate one's time (flagged:
/// the uniform mesh that reaches `error` costs more). None when every uniform run is more
/// accurate.
fn time_at_error(uniform: &[(f64, f64)], error: f64) -> Option<(f64, bool)> {
    let mut runs = uniform.to_vec();
    runs.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for r in runs {
        if front.last().is_none_or(|f| r.0 < f.0) {
            front.push(r);
        }
    }
    let best = *front.last()?;
    if error < best.0 {
        return Some((best.1, true));
    }
    front.windows(2).find_map(|w| {
        let ((e0, t0), (e1, t1)) = (w[0], w[1]);
        let s = (error / e0).ln() / (e1 / e0).ln();
        (e0 >= error && error >= e1).then(|| ((t0.ln() + s * (t1 / t0).ln()).exp(), false))
    })
}

/// The scene text with every shell bending with `element`.
/// Newton's iteration cap in every run: a frame stopped at the scenes' 200 would carry the
/// solver's error into the comparison (measured: a quadratic adaptive case-10 frame at the
/// onset of wrinkling stopped at 200 with 1.3 % too much energy and converged at 218).
const ITERATION_CAP: u32 = 1000;

/// The scene text with its solver's `max_iterations` set to `cap`.
fn with_iteration_cap(text: &str, cap: u32) -> String {
    let key = "max_iterations: ";
    let start = text.find(key).expect("a solver with an iteration cap") + key.len();
    let end = start + text[start..].find(|c: char| !c.is_ascii_digit()).expect("the cap's end");
    format!("{}{cap}{}", &text[..start], &text[end..])
}

fn with_element(text: &str, element: BendingElement) -> String {
    let hinge = "bending: Some((model: Tan))";
    assert!(text.contains(hinge), "the LK14 scenes bend with Tan hinges");
    text.replace(hinge, &format!("bending: Some((model: Tan, element: {element:?}))"))
}

/// The scene text with its perturbation made the case's smooth field: Perlin noise of its cell,
/// at its noise amplitude, plus its waves.
fn smooth_perturbation(text: &str, case: &Case) -> String {
    let start = text.find("perturbation: Some((").expect("a perturbed scene");
    let end = start + text[start..].find("))").expect("perturbation end");
    let mut fields = format!("{}, cell: {}", &text[start..end], case.cell_mm);
    if let Some(a) = case.noise_mm {
        let at = fields.find("amplitude: ").expect("an amplitude") + "amplitude: ".len();
        let to = at + fields[at..].find(',').expect("more fields");
        fields.replace_range(at..to, &a.to_string());
    }
    if !case.waves.is_empty() {
        let waves: Vec<String> =
            case.waves.iter().map(|(l, a)| format!("(wavelength: {l}, amplitude: {a}, axis: X)")).collect();
        fields.push_str(&format!(", waves: [{}]", waves.join(", ")));
    }
    format!("{}{fields}{}", &text[..start], &text[end..])
}

/// The scene text with the swept layer's cells replaced and `extra` fields added to it.
fn mesh_line(text: &str, mesh: &str, nx: u32, ny: u32, extra: &str) -> String {
    let rest = &mesh[mesh.find(')').expect("cells (x, y)") + 1..];
    let line_end = text.find(mesh).expect("the swept mesh") + mesh.len();
    // The layer's closing parenthesis: the last of the first "))," after the mesh (the end of
    // `bending: Some((..))`, then the layer's own).
    let close = line_end + text[line_end..].find(")),\n").expect("layer end") + 1;
    let mut out = text[..close].replace(mesh, &format!("cells: ({nx}, {ny}){rest}"));
    out.push_str(extra);
    out.push_str(&text[close..]);
    out
}

/// Writes a run's scene as `scenes/<case>_<row>_<kind>.ron` in `out`, beside its map: `skinsim
/// run` on it repeats the run's timed frames (the held remeshes after them are the report's).
fn keep_scene(out: &Path, case: &str, row: usize, kind: &str, text: &str) -> std::io::Result<()> {
    std::fs::create_dir_all(out.join("scenes"))?;
    std::fs::write(out.join("scenes").join(format!("{case}_{row}_{kind}.ron")), text)
}

fn run(
    case: &Case,
    text: &str,
    dir: &Path,
    kind: &str,
    setting: String,
    quick: bool,
) -> Result<Lk14Row, Box<dyn std::error::Error>> {
    let mut built = scene::load_str(text, &dir.join(case.scene))?;
    if quick {
        built.scene.frames = 2;
    }
    let mut sim = Simulation::new(&built);
    let (mut vertices, mut iterations, mut seconds, mut energy, mut unconverged) = (0.0, 0, 0.0, 0.0, 0);
    let mut remeshes = 0;
    let mut share = RemeshShare::default();
    for _ in 0..built.scene.frames {
        let clock = std::time::Instant::now();
        let s = sim.step();
        seconds += clock.elapsed().as_secs_f64();
        if let Some(f) = sim.failure() {
            return Err(f.into());
        }
        share.add(&s);
        // (the swept layer's own vertices, counted outside the timed step)
        vertices += sim.layer_mesh("skin", case.layer).0.len() as f64;
        iterations += s.patches[0].outcome.iterations;
        unconverged += u32::from(!s.patches[0].outcome.converged);
        energy = s.patches[0].outcome.energy;
        remeshes += remeshed(&mut sim, case.layer, s.frame);
    }
    let frames = built.scene.frames as f64;
    let ms_per_frame = 1e3 * seconds / frames;
    let (uv, x, faces) = sim.layer_mesh("skin", case.layer);
    // (measured after the timed frames and the last frame's shape, so they change neither)
    let held = if kind == "adaptive" && !quick { Some(held_remeshes(&mut sim, case.layer)?) } else { None };
    let size = uv.iter().fold(glam::DVec2::ZERO, |m, u| m.max(*u));
    let cells = ((size.x / 0.1e-3).round() as usize, ((size.y / 0.5e-3).round() as usize).max(2));
    let (guv, gx) = resample_on_grid(&uv, &x, &faces, cells);
    let normals = skinsim::mesh::shading::vertex_normals(&x, &faces);
    let lo = uv.iter().fold(glam::DVec2::INFINITY, |m, u| m.min(*u));
    let map = skinsim::mesh::wrinkle_map::normal_map(&uv, &faces, &normals, MAP_SIZE, lo, size);
    let normals = skinsim::mesh::wrinkle_map::normal_samples(&uv, &faces, &normals, MAP_SIZE, lo, size);
    let peaks = row_peaks(&gx, &guv, 0, 0.05);
    let wavelength_error = case.lambda_mm.map_or(f64::NAN, |lambda| {
        let mut errors = peaks.iter().map(|p| 1e3 * p.wavelength / lambda - 1.0);
        if case.layer == "skin" {
            errors.next().unwrap_or(f64::NAN)
        } else {
            errors.min_by(|a, b| a.abs().total_cmp(&b.abs())).unwrap_or(f64::NAN)
        }
    });
    let row = Lk14Row {
        series: format!("{}, {kind}", case.name),
        setting,
        mean_vertices: vertices / frames,
        ms_per_frame,
        times: vec![ms_per_frame],
        newton_iterations: iterations,
        unconverged_frames: unconverged,
        wavelength_error,
        energy_error: 0.0,
        shape_error: 0.0,
        time_ratio: None,
        time_ratio_energy: None,
        map_error: 0.0,
        time_ratio_map: None,
        time_ratio_height: None,
        height_error: 0.0,
        remeshes,
        remesh_share: share,
        held,
        reference: false,
        energy,
        grid: gx,
        grid_uv: guv,
        map,
        normals,
    };
    eprintln!("{}: {}: {:.0} ms/frame, {:.0} vertices", row.series, row.setting, row.ms_per_frame, row.mean_vertices);
    Ok(row)
}

/// A later round's run: its frames as `run` steps them, timed the same way, nothing else
/// measured (ms per frame).
fn time_run(case: &Case, text: &str, dir: &Path, quick: bool) -> Result<f64, Box<dyn std::error::Error>> {
    let mut built = scene::load_str(text, &dir.join(case.scene))?;
    if quick {
        built.scene.frames = 2;
    }
    let mut sim = Simulation::new(&built);
    let mut seconds = 0.0;
    for _ in 0..built.scene.frames {
        let clock = std::time::Instant::now();
        sim.step();
        seconds += clock.elapsed().as_secs_f64();
        if let Some(f) = sim.failure() {
            return Err(f.into());
        }
    }
    Ok(1e3 * seconds / f64::from(built.scene.frames))
}

/// Remesh, settle and resampling time against the frames' (`FrameStats` timings).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RemeshShare {
    remesh_ms: f64,
    total_ms: f64,
    /// The largest one frame's share.
    pub largest: f64,
}

impl RemeshShare {
    /// Adds a frame: the stages a remesh brings are VALIDATION.md G's t_R + t_S.
    pub fn add(&mut self, s: &FrameStats) {
        let remesh = T_R.iter().chain(&T_S).map(|&k| s.timing(k)).sum::<f64>();
        let total = s.total_ms();
        self.remesh_ms += remesh;
        self.total_ms += total;
        if total > 0.0 {
            self.largest = self.largest.max(remesh / total);
        }
    }

    /// Over all the frames added.
    pub fn mean(&self) -> f64 {
        if self.total_ms > 0.0 {
            self.remesh_ms / self.total_ms
        } else {
            0.0
        }
    }
}

/// What the remeshes of `HELD_FRAMES` frames at a held load did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeldRemeshes {
    /// Those that changed the layer's topology.
    pub changed: u32,
    /// The Newton iterations of their frames, frame by frame (the first `changed`).
    pub each: [u32; HELD_FRAMES as usize],
    /// The Newton iterations of the last held frame before them, without a remesh: 0 once the
    /// patch is settled (`SETTLE_FRAMES`), else what a remesh's frame would take anyway.
    pub baseline: u32,
    /// Then the frames without a remesh until one takes no Newton iteration (at most
    /// `SETTLE_FRAMES`), and their iterations: what the remeshes leave to later frames (a frame
    /// that starts where the last one was accepted takes none: `solve::constrained`; kept as a
    /// check).
    pub after_frames: u32,
    pub after: u32,
}

impl HeldRemeshes {
    /// The Newton iterations a remesh that changed the mesh added, on average, beyond a held
    /// frame without one (None: none changed it).
    pub fn per_remesh(&self) -> Option<f64> {
        (self.changed > 0).then(|| f64::from(self.iterations()) / f64::from(self.changed) - f64::from(self.baseline))
    }

    /// The Newton iterations of the frames whose remesh changed the mesh.
    pub fn iterations(&self) -> u32 {
        self.each[..self.changed as usize].iter().sum()
    }

    /// The Newton iterations of each remesh's frame that changed the mesh, as "5, 1, 1".
    pub fn listed(&self) -> String {
        let each: Vec<String> = self.each[..self.changed as usize].iter().map(u32::to_string).collect();
        each.join(", ")
    }

    /// The same with the frames after them counted too: the Newton iterations a remesh costs
    /// until the patch is settled again.
    pub fn per_remesh_settled(&self) -> Option<f64> {
        (self.changed > 0).then(|| {
            let frames = f64::from(self.changed + self.after_frames);
            (f64::from(self.iterations() + self.after) - frames * f64::from(self.baseline)) / f64::from(self.changed)
        })
    }
}

/// The held remeshes of a report's adaptive runs together (issue 26's target: the mean over the
/// sweep).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldSummary {
    pub scheduled: u32,
    pub changed: u32,
    /// Newton iterations of the frames whose remesh changed the mesh, beyond each run's held
    /// frame without a remesh.
    pub extra: i64,
}

impl HeldSummary {
    /// None: no run measured its held remeshes (`--quick`, or no adaptive run).
    pub fn over<'a>(runs: impl IntoIterator<Item = &'a HeldRemeshes>) -> Option<Self> {
        let held: Vec<&HeldRemeshes> = runs.into_iter().collect();
        (!held.is_empty()).then(|| HeldSummary {
            scheduled: HELD_FRAMES * held.len() as u32,
            changed: held.iter().map(|h| h.changed).sum(),
            extra: held.iter().map(|h| i64::from(h.iterations()) - i64::from(h.changed * h.baseline)).sum(),
        })
    }

    /// The summary as the report prints it below its table.
    pub fn sentence(&self) -> String {
        match self.changed {
            0 => format!("none of {} scheduled changed the mesh.", self.scheduled),
            changed => format!(
                "{changed} of {} scheduled changed the mesh, and their frames took {} Newton iterations beyond a \
                 held frame without a remesh: {:.1} per remesh that changed it, {:.1} per scheduled remesh.",
                self.scheduled,
                self.extra,
                self.extra as f64 / f64::from(changed),
                self.extra as f64 / f64::from(self.scheduled),
            ),
        }
    }
}

/// Frames run past the last keyframe, remeshing every frame, to count what a remesh adds.
const HELD_FRAMES: u32 = 3;

/// Held frames without a remesh before those, at most: until one takes no Newton iteration. A
/// loading frame may end on the solver's stall test; the held frame after it accepts that state
/// as it stands (`solve::constrained`), where it once crept on for a frame or two (the localized
/// pinch's 9 mm run: 6 and 8 iterations, then 0) that a remesh's frame would have counted.
const SETTLE_FRAMES: u32 = 4;

/// The remeshes of `layer` in `HELD_FRAMES` frames with the load held (the run past its last
/// keyframe), remeshing every frame, after up to `SETTLE_FRAMES` without a remesh.
fn held_remeshes(sim: &mut Simulation, layer: &str) -> Result<HeldRemeshes, Box<dyn std::error::Error>> {
    let mut held = HeldRemeshes::default();
    let every = |sim: &mut Simulation, every: u32| {
        let mut q = sim.world.query::<(&skinsim::model::Layer, &mut skinsim::model::RemeshSettings)>();
        q.iter_mut(&mut sim.world).filter(|(l, _)| l.name == layer).for_each(|(_, mut r)| r.every = every);
    };
    every(sim, u32::MAX);
    held.baseline = settle(sim)?.last().copied().unwrap_or(0);
    every(sim, 1);
    for _ in 0..HELD_FRAMES {
        let s = sim.step();
        if let Some(f) = sim.failure() {
            return Err(f.into());
        }
        if remeshed(sim, layer, s.frame) == 1 {
            held.each[held.changed as usize] = s.patches[0].outcome.iterations;
            held.changed += 1;
        }
    }
    if held.changed > 0 {
        every(sim, u32::MAX);
        let after = settle(sim)?;
        held.after_frames = after.iter().filter(|&&n| n > 0).count() as u32;
        held.after = after.iter().sum();
    }
    Ok(held)
}

/// The Newton iterations of frames run until one takes none, at most `SETTLE_FRAMES`.
fn settle(sim: &mut Simulation) -> Result<Vec<u32>, Box<dyn std::error::Error>> {
    let mut iterations = Vec::new();
    while iterations.len() < SETTLE_FRAMES as usize && iterations.last() != Some(&0) {
        iterations.push(sim.step().patches[0].outcome.iterations);
        if let Some(f) = sim.failure() {
            return Err(f.into());
        }
    }
    Ok(iterations)
}

/// 1 when the last step's remesh of `layer` changed its topology.
fn remeshed(sim: &mut Simulation, layer: &str, frame: u32) -> u32 {
    let mut q = sim.world.query::<(&skinsim::model::Layer, &skinsim::model::RemeshReport)>();
    let changed = q.iter(&sim.world).any(|(l, r)| {
        l.name == layer && r.frame == u64::from(frame) && r.stats.splits + r.stats.collapses + r.stats.flips > 0
    });
    u32::from(changed)
}

fn write(
    out: &Path,
    rows: &[Lk14Row],
    element: BendingElement,
    term: WavelengthTerm,
    cases: &[usize],
    rounds: u32,
) -> std::io::Result<()> {
    let flag = if element == BendingElement::Hinge { "hinge" } else { "quadratic" };
    let mut without = term.flag().to_string();
    if !cases.is_empty() {
        let names: Vec<&str> = cases.iter().map(|&c| CASE_FLAGS[c]).collect();
        without.push_str(&format!(" --cases {}", names.join(",")));
    }
    let timed = if rounds > 1 {
        without.push_str(&format!(" --rounds {rounds}"));
        format!(
            "the median of {rounds} rounds, each running every run of the case once in turn (so that \
             uniform and adaptive runs alternate in one window), the rounds' least and most in brackets"
        )
    } else {
        "one run (`--rounds N`: the median of N rounds that alternate the runs)".to_string()
    };
    let mut md = format!(
        "# Speed against error, LK14 (VALIDATION.md F, issue 5)\n\n\
         Regenerate: `cargo run --release --bin skinsim -- report --only lk14 --bending {flag}{without} --out \
         report`. \
         Every shell bends with the {element:?} element.\n\
         Uniform meshes of the swept layer against adaptive ones (REMESH.md) started from the coarsest uniform \
         mesh; the first frame is solved on that mesh, then it is remeshed every few frames. Every run of a case \
         has the same imperfection, a Perlin field of half the wavelength in material space (the whole wavelength \
         on the localized pinch; case 11: a quarter of the noise, plus sinusoids along x at lambda_1 and \
         lambda_2, 1 um each, which fix both modes' phase and sign), meant to make every mesh select the same wrinkle mode (the shape and \
         wavelength columns show where it does not). Shape error: RMS distance between the final layer and the finest uniform \
         run's, on a grid in material space, over the reference's RMS wrinkle height. Time ratios (adaptive): \
         time per frame over the uniform time at the same map, height, shape or |energy| error, interpolated log-log along \
         the uniform runs' Pareto front, each kept only if more accurate than every cheaper one (`<`: no \
         uniform run but the reference is as accurate, so the ratio is at most this; blank: every uniform run is \
         more accurate). Wavelength error: the dominant peak (case 10) or the peak nearest lambda_2 (case 11) \
         against the kernel wavelength. Energy error: the final total energy against the reference's. With the \
         Hinge element it carries the hinge's mesh dependence on remeshed (irregular, anisotropic) meshes: \
         calibrated on equilateral triangles, it holds 46 % too little energy on a 4:1 mesh bent across its short \
         edges (VALIDATION.md case 5), and the adaptive case-10 runs 11-13 % too little bending energy; the \
         Quadratic element is within 1 % on that mesh. Newton iterations: the run's total, its cap raised to \
         {ITERATION_CAP} per frame so that every frame converges. Vertices: the swept layer's, mean over the \
         frames. Time: wall per frame on this machine, {timed}. Map error (issue 26): the mean angle between \
         the normals of the run's and the reference's wrinkle maps ({MAP_SIZE} pixels square over the material \
         rectangle), pixel by pixel, before the maps' 8-bit encoding (its steps, up to half a degree, would \
         hide finer differences). Height error: the RMS of the height difference to the reference on the \
         material grid, without its best affine fit (a rigid or affine drift of the sheet), over the reference's \
         RMS wrinkle height. Remeshes: frames whose remesh changed the layer's topology. Remesh share: \
         the remesh, the settle of its new vertices and the property and kernel resampling (with the \
         kernels' adjust) over the timed frames' wall time (the first round's), over the run and in its largest \
         frame. \
         Iterations per remesh: \
         after the run, frames with the load held (past the last keyframe) and no remesh until one takes no \
         Newton iteration (at most {SETTLE_FRAMES}; a frame that starts where the last one was accepted \
         takes none), then {HELD_FRAMES} with a remesh every frame (the load held, a remesh's frame is \
         converged once its residual is back within the one the load was accepted at, the tolerance, \
         or twice the stall test's floor when the load ended on it (that test's own band), and a full \
         step whose energy change is far off its quadratic model is taken back, counted, and tried \
         stiffer); the mean Newton iterations \
         of those whose remesh changed the topology, less those of the last frame without one (shown after \
         `without`, 0 once settled), and how many of them did; then, with the frames after them without a \
         remesh until one takes no iteration (at most {SETTLE_FRAMES}) counted too: a remesh's frame may end \
         on the solver's stall test within 1000 times its tolerance, and the next frame at the same load \
         accepts that state as it stands. Each run's wrinkle map is in maps/ (case, row of the case from 0, \
         kind), and its scene in scenes/, named alike: `skinsim run` on it repeats the run's frames (`--quick` \
         runs 2 of them). Adaptive runs whose setting ends in lambda / N add the wavelength term (edges across the \
         compression at most the kernels' wavelength over N where the compression passes half the critical \
         strain; their first remesh comes before the first solve, and leaves the layer at rest: each new \
         vertex at its rest position, imperfection included): by default those of every case, \
         `--wavelength-term all` or `off` for every case or none (without it each case's \
         settings sweep the angle, remeshed on the frame's compression and curvature). Those ending in `ahead, held` (cases 10 and 11) bound the edges where the kinematic base will be \
         compressed at its last keyframe (case 10: those across the compression; case 11: every edge), from the \
         first remesh on, and no later remesh changes a face there whose edges meet the bound (`hold`); those \
         ending in `ahead, M mm around, held` (the two pinches) bound every edge there and M mm around. A held face is released where a free face meets it across an edge the sizing field \
         wants split. Under `lookahead` the term reads the kinematic base only, not the dermis.\n\n\
         | series | setting | vertices | ms / frame | Newton iterations | remeshes | remesh share (run; largest frame) \
         | iterations per remesh (held load) | \
         map error (deg) | time ratio (map) | height error | time ratio (height) | shape error | \
         time ratio (shape) | wavelength error | energy error | time ratio (energy) |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let mut csv = String::from(
        "series,setting,mean_vertices,ms_per_frame,newton_iterations,shape_error,time_ratio,ratio_is_upper_bound,\
         wavelength_error,energy_error,time_ratio_energy,energy_ratio_is_upper_bound,remeshes,\
         iterations_per_remesh_held,held_remeshes_changed,held_iterations_without_remesh,\
         iterations_per_remesh_settled,held_frames_after,held_iterations_after,map_error_deg,time_ratio_map,map_ratio_is_upper_bound,height_error,\
         held_iterations_each,time_ratio_height,height_ratio_is_upper_bound,remesh_share,remesh_share_largest_frame,\
         rounds,ms_per_frame_least,ms_per_frame_most\n",
    );
    for r in rows {
        let show = |t: Option<(f64, bool)>| match t {
            Some((q, true)) => format!("< {q:.2}"),
            Some((q, false)) => format!("{q:.2}"),
            None => String::new(),
        };
        let (ratio, ratio_energy, ratio_map, ratio_height) =
            (show(r.time_ratio), show(r.time_ratio_energy), show(r.time_ratio_map), show(r.time_ratio_height));
        let per_remesh = r.held.map_or(String::new(), |h| match h.per_remesh() {
            Some(n) => format!(
                "{n:.1} ({} of {HELD_FRAMES} changed it: {}; {} without); {:.1} with the {} frame(s) after",
                h.changed,
                h.listed(),
                h.baseline,
                h.per_remesh_settled().unwrap_or(n),
                h.after_frames
            ),
            None => format!("none of {HELD_FRAMES} changed it"),
        });
        let wavelength = if r.wavelength_error.is_nan() {
            "n/a".to_string()
        } else {
            format!("{:+.2} %", 100.0 * r.wavelength_error)
        };
        let (least, most) = least_most(&r.times);
        let time = if r.times.len() > 1 {
            format!("{:.0} ({least:.0}-{most:.0})", r.ms_per_frame)
        } else {
            format!("{:.0}", r.ms_per_frame)
        };
        let iterations = match r.unconverged_frames {
            0 => r.newton_iterations.to_string(),
            n => format!("{} ({n} frame(s) at the iteration limit)", r.newton_iterations),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {:.0} | {time} | {iterations} | {} | {:.1} %; {:.1} % | {per_remesh} | {:.2} | {ratio_map} | {:.3} \
             | {ratio_height} \
             | {:.3} | {ratio} \
             | {wavelength} | {:+.3} % | {ratio_energy} |",
            r.series,
            r.setting,
            r.mean_vertices,
            r.remeshes,
            100.0 * r.remesh_share.mean(),
            100.0 * r.remesh_share.largest,
            r.map_error.to_degrees(),
            r.height_error,
            r.shape_error,
            100.0 * r.energy_error
        );
        let _ = writeln!(
            csv,
            "{},{},{:.1},{:.3},{},{:.6},{},{},{:.6},{:.6},{},{},{},{},{},{},{},{},{},{:.4},{},{},{:.6},{},{},{},{:.5},{:.5},{},{:.3},{:.3}",
            csv_text(&r.series),
            csv_text(&r.setting),
            r.mean_vertices,
            r.ms_per_frame,
            r.newton_iterations,
            r.shape_error,
            r.time_ratio.map_or(f64::NAN, |t| t.0),
            r.time_ratio.is_some_and(|t| t.1),
            r.wavelength_error,
            r.energy_error,
            r.time_ratio_energy.map_or(f64::NAN, |t| t.0),
            r.time_ratio_energy.is_some_and(|t| t.1),
            r.remeshes,
            r.held.and_then(|h| h.per_remesh()).map_or(f64::NAN, |n| n),
            r.held.map_or(String::new(), |h| h.changed.to_string()),
            r.held.map_or(String::new(), |h| h.baseline.to_string()),
            r.held.and_then(|h| h.per_remesh_settled()).map_or(f64::NAN, |n| n),
            r.held.map_or(String::new(), |h| h.after_frames.to_string()),
            r.held.map_or(String::new(), |h| h.after.to_string()),
            r.map_error.to_degrees(),
            r.time_ratio_map.map_or(f64::NAN, |t| t.0),
            r.time_ratio_map.is_some_and(|t| t.1),
            r.height_error,
            r.held.map_or(String::new(), |h| h.listed().replace(", ", ";")),
            r.time_ratio_height.map_or(f64::NAN, |t| t.0),
            r.time_ratio_height.is_some_and(|t| t.1),
            r.remesh_share.mean(),
            r.remesh_share.largest,
            r.times.len(),
            least,
            most,
        );
    }
    if let Some(s) = HeldSummary::over(rows.iter().filter_map(|r| r.held.as_ref())) {
        let _ = writeln!(md, "\nHeld remeshes over these runs: {}", s.sentence());
    }
    let adaptive: Vec<&RemeshShare> =
        rows.iter().filter(|r| r.series.ends_with("adaptive")).map(|r| &r.remesh_share).collect();
    if !adaptive.is_empty() {
        let range = |f: &dyn Fn(&RemeshShare) -> f64| {
            let v: Vec<f64> = adaptive.iter().map(|s| 100.0 * f(s)).collect();
            (v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(0.0, f64::max))
        };
        let ((lo, hi), (_, top)) = (range(&|s| s.mean()), range(&|s| s.largest));
        let _ = writeln!(
            md,
            "\nRemesh and resampling in the adaptive runs: {lo:.1}-{hi:.1} % of a run's time, at most {top:.1} % of \
             one frame's."
        );
    }
    std::fs::write(out.join("speed_error_lk14.md"), md)?;
    std::fs::write(out.join("speed_error_lk14.csv"), csv)
}

/// The three plots of time per frame against an error: `<stem>.*` (shape), `<stem>_map.*` and
/// `<stem>_height.*` (issue 26's errors a user can see).
fn plots(stem: &Path, rows: &[Lk14Row]) -> Result<(), Box<dyn std::error::Error>> {
    let name = |suffix: &str| {
        stem.with_file_name(format!("{}{suffix}", stem.file_name().unwrap_or_default().to_string_lossy()))
    };
    plot(
        &name(""),
        rows,
        |r| 100.0 * r.shape_error,
        "LK14: time per frame against shape error",
        "shape error against the finest uniform run (RMS distance / RMS wrinkle height, %)",
    )?;
    plot(
        &name("_map"),
        rows,
        |r| r.map_error.to_degrees(),
        "LK14: time per frame against wrinkle-map error",
        "wrinkle-map error against the finest uniform run (mean angle between the maps' normals, degrees)",
    )?;
    plot(
        &name("_height"),
        rows,
        |r| 100.0 * r.height_error,
        "LK14: time per frame against height-field error",
        "height-field error against the finest uniform run (RMS without the affine part / RMS wrinkle height, %)",
    )
}

fn plot(
    stem: &Path,
    rows: &[Lk14Row],
    error: impl Fn(&Lk14Row) -> f64,
    caption: &str,
    x_label: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    // The reference runs have no error: drawn left of every other point.
    let floor = rows.iter().map(&error).filter(|e| *e > 0.0).fold(100.0f64, f64::min) / 2.0;
    let points = rows
        .iter()
        .filter(|r| r.reference || error(r).is_finite())
        .map(|r| Point {
            series: r.series.clone(),
            x: if r.reference { floor } else { error(r).max(floor) },
            y: r.ms_per_frame,
            reference: r.reference,
        })
        .collect();
    let plot = LogLog {
        caption,
        x_label,
        y_label: "time per frame (ms)",
        points,
        reference_label: Some("reference (finest uniform run): no error, drawn at half the smallest"),
    };
    plot.write(stem)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skinsim::model::Stage;

    #[test]
    fn a_runs_time_is_the_median_of_its_rounds() {
        assert_eq!(median(&[3.0]), 3.0);
        assert_eq!(median(&[5.0, 1.0, 4.0]), 4.0);
        assert_eq!(median(&[5.0, 1.0, 4.0, 2.0]), 3.0);
    }

    #[test]
    fn the_remesh_share_sums_the_remesh_stages_over_the_frames_and_keeps_the_largest_frame() {
        let frame = |stages: &[(Stage, f64)], total: f64| {
            let mut timings_ms = serde_json::Map::new();
            for k in Stage::ALL {
                let ms = stages.iter().find(|(s, _)| *s == k).map_or(0.0, |s| s.1);
                timings_ms.insert(k.key().into(), ms.into());
            }
            timings_ms.insert("total".into(), total.into());
            FrameStats { frame: 0, time: 0.0, patches: Vec::new(), timings_ms }
        };
        let mut share = RemeshShare::default();
        share.add(&frame(
            &[(Stage::Remesh, 10.0), (Stage::Settle, 5.0), (Stage::ConstraintAdjust, 5.0), (Stage::Solve, 80.0)],
            100.0,
        ));
        share.add(&frame(&[(Stage::PropertyResample, 1.0), (Stage::Solve, 299.0)], 300.0));
        assert!((share.mean() - 21.0 / 400.0).abs() < 1e-15, "{share:?}");
        assert!((share.largest - 0.2).abs() < 1e-15, "{share:?}");
        assert_eq!(RemeshShare::default().mean(), 0.0);
    }

    #[test]
    fn the_swept_mesh_line_is_edited_and_remesh_added_to_its_layer() {
        let text = "layers: [\n    Layer(name: \"a\", mesh: Grid(cells: (9, 9), z: 0.0)),\n    Layer(name: \"s\", \
                    mesh: Grid(cells: (128, 18), pattern: Equilateral, z: 0.5),\n        bending: Some((model: Tan))),\n]";
        let out = mesh_line(text, "cells: (128, 18), pattern: Equilateral, z: 0.5", 64, 9, ", remesh: X");
        assert!(out.contains("cells: (64, 9), pattern: Equilateral, z: 0.5"), "{out}");
        assert!(out.contains("bending: Some((model: Tan)), remesh: X),\n]"), "{out}");
        assert!(out.contains("cells: (9, 9)"));
    }

    #[test]
    fn the_iteration_cap_is_raised() {
        let text = "solver: (tolerance: 1e-8, max_iterations: 200, projection: None),";
        assert_eq!(
            with_iteration_cap(text, 1000),
            "solver: (tolerance: 1e-8, max_iterations: 1000, projection: None),"
        );
    }

    #[test]
    fn the_perturbation_becomes_the_cases_smooth_field() {
        let text = "solver: (perturbation: Some((amplitude: 0.002, seed: 3))),";
        assert_eq!(
            smooth_perturbation(text, &CASES[0]),
            "solver: (perturbation: Some((amplitude: 0.002, seed: 3, cell: 3))),"
        );
        assert_eq!(
            smooth_perturbation(text, &CASES[1]),
            "solver: (perturbation: Some((amplitude: 0.0005, seed: 3, cell: 1, waves: [(wavelength: 8, amplitude: \
             0.001, axis: X), (wavelength: 2, amplitude: 0.001, axis: X)]))),"
        );
    }

    #[test]
    fn held_remeshes_are_listed_and_summed_beyond_each_runs_frame_without_one() {
        let a = HeldRemeshes { changed: 3, each: [5, 1, 1], ..Default::default() };
        let b = HeldRemeshes { changed: 1, each: [9, 0, 0], baseline: 2, ..Default::default() };
        let none = HeldRemeshes::default();
        assert_eq!((a.listed(), b.listed(), none.listed()), ("5, 1, 1".into(), "9".into(), String::new()));
        assert_eq!(b.per_remesh(), Some(7.0));
        let s = HeldSummary::over([&a, &b, &none]).unwrap();
        assert_eq!(s, HeldSummary { scheduled: 9, changed: 4, extra: 14 });
        assert_eq!(HeldSummary::over([]), None);
        assert!(
            s.sentence().contains("14 Newton iterations")
                && s.sentence().contains("3.5 per remesh that changed it, 1.6 per scheduled"),
            "{}",
            s.sentence()
        );
        let unchanged = HeldSummary::over([&none, &none]).unwrap();
        assert_eq!(unchanged.sentence(), "none of 6 scheduled changed the mesh.");
    }

    #[test]
    fn the_uniform_time_at_an_error_is_interpolated_log_log_on_the_pareto_front() {
        // (the second run is less accurate than the cheaper first: off the front)
        let uniform = [(1.0, 100.0), (1.5, 400.0), (0.1, 1000.0), (0.01, 10000.0)];
        let (t, upper) = time_at_error(&uniform, 0.1f64.sqrt()).unwrap();
        assert!((t / 1000f64.sqrt() / 10.0 - 1.0).abs() < 1e-12 && !upper, "{t}");
        assert_eq!(time_at_error(&uniform, 0.001), Some((10000.0, true)));
        assert_eq!(time_at_error(&uniform, 1.2), None);
        // (a NaN error, a run on another material grid, has no ratio)
        assert_eq!(time_at_error(&uniform, f64::NAN), None);
    }
}
