//! `skinsim`: run and check skin scenes.
//!
//! Exit status: 0 success, 1 simulation failure (NaN, no convergence), 2 bad input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use skinsim::mesh::shading::ColourBy;
use skinsim::mesh::usd::{UsdFormat, UsdOptions, UsdStage};
use skinsim::scene::{self, BuiltScene};
use skinsim_systems::log::{Colouring, ObjExport, RerunSink, UsdExport};
use skinsim_systems::Simulation;
use skinsim_tools::bake::{BakeRequest, MapLayout};

#[derive(Parser)]
#[command(name = "skinsim", version, about = "Physically based wrinkling of multi-layer skin")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene: writes stats.jsonl, a Rerun recording and requested exports under --out.
    Run(RunArgs),
    /// Validate a scene (schema, values, meshes, assets) without running it, and estimate what
    /// running it costs (vertices, DOFs, the Newton factor's memory, a frame's time).
    Check {
        scene: PathBuf,
        /// The memory a run may take (GB; default: the scene's `memory`, else this machine's).
        #[arg(long, value_parser = budget_gb)]
        budget: Option<f64>,
    },
    /// Wrinkles of a layer from its exported frames (`run --export obj`): per frame the
    /// compression, the dominant wavelengths and the amplitude; then the onset strain.
    Analyze {
        /// A folder of frames: <out>/obj/<patch>/<layer>
        dir: PathBuf,
        /// The compression axis in material space.
        #[arg(long, value_enum, default_value = "x")]
        axis: AxisArg,
        /// The domain is periodic along the axis (whole waves only).
        #[arg(long)]
        periodic: bool,
    },
    /// Wrinkle maps (LK14 5.4): runs the scene and writes per chosen frame an 8-bit RGB normal
    /// map of a shell layer in material space, or with --layout asset 16-bit normal and height
    /// maps in the body's UVs (padded, faded at the patches' edges; maps.json says how to read
    /// them); blends of the first two; and bake.rrd.
    Bake {
        scene: PathBuf,
        /// Frames to bake, e.g. 5,10.
        #[arg(long, value_delimiter = ',')]
        frames: Vec<u32>,
        /// Blend-shape weights to bake: the frames where the first target's weight comes closest.
        #[arg(long, value_delimiter = ',')]
        weights: Vec<f64>,
        /// Joint angles (degrees) to bake: the frames where the first Joint's angle comes
        /// closest (LK14 5.4: the joint angle is the blend parameter).
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        angles: Vec<f64>,
        /// Map size in pixels (square).
        #[arg(long, default_value_t = 1024)]
        size: u32,
        /// Output folder (default: out/<scene name>/wrinkle_maps).
        #[arg(long)]
        out: Option<PathBuf>,
        /// The layer to bake (default: the top shell layer of each patch).
        #[arg(long)]
        layer: Option<String>,
        /// Also write blends of the first two maps at these weights, e.g. 0.5.
        #[arg(long, value_delimiter = ',')]
        blend: Vec<f64>,
        /// material: a map per layer over its material rectangle, world-space normals. asset:
        /// a map per shared body over its UV layout (the patches on it at their UVs), normals
        /// in the body's tangent space.
        #[arg(long, value_enum, default_value = "material")]
        layout: LayoutArg,
        /// Asset maps: pixels of padding around each patch's region.
        #[arg(long, default_value_t = 8)]
        padding: u32,
        /// Asset maps: the width (mm) over which a patch fades into its body's unwrinkled surface.
        #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
        edge_blend: f64,
        /// Asset maps: bits per channel of the normal map, 8 or 16 (the height map is 16-bit).
        #[arg(long, default_value_t = 16)]
        bits: u8,
        /// Asset maps: the height (mm) the height map's white stands for (black: minus it).
        #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
        height_range: f64,
        /// Asset maps: Loop subdivision levels the skin is drawn at (0: its triangles).
        #[arg(long, default_value_t = 2)]
        smooth: u32,
    },
    /// Timing table (VALIDATION.md G): per-frame stage times of scenes in the columns of LK14
    /// table 6-1, beside LK14's figures; writes <out>/timing.md.
    Timing {
        scenes: Vec<PathBuf>,
        /// Frames per scene (default: all of each scene's).
        #[arg(long)]
        frames: Option<u32>,
        /// Rounds, every scene once per round in turn (scenes compared in one window
        /// alternate); each figure is the median over the rounds, and the table adds each
        /// scene's least and most total and its median over the first scene's.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        rounds: u32,
        #[arg(long, default_value = "report")]
        out: PathBuf,
    },
    /// Speed against error (VALIDATION.md F): sweeps the resolution of the wrinkling cases and
    /// writes speed_error.md, .csv, .svg and .png (H15 cases 7 and 9: time per increment against
    /// error, log-log) and speed_error_lk14.* (LK14 cases 10 and 11 and two pinches: uniform
    /// against adaptive meshes, time per frame against the wrinkle-map, height, shape and energy
    /// errors; plots speed_error_lk14_map.*, _height.* and speed_error_lk14.*, against shape).
    Report {
        /// Output folder.
        #[arg(long, default_value = "report")]
        out: PathBuf,
        /// Only the two coarsest resolutions of each sweep (two frames for LK14).
        #[arg(long)]
        quick: bool,
        /// Which sweeps.
        #[arg(long, value_enum, default_value = "all")]
        only: Sweeps,
        /// LK14 sweeps: the bending element of every shell (hinge: the scenes' own).
        #[arg(long, value_enum, default_value = "hinge")]
        bending: BendingArg,
        /// LK14 sweeps: only these cases (default: all four).
        #[arg(long, value_enum, value_delimiter = ',')]
        cases: Vec<Lk14Case>,
        /// LK14 sweeps: which cases' adaptive runs refine by the wavelength term (issue 26):
        /// default, those where it was measured to pay (now all four); all; off (curvature and
        /// compression only, as before).
        #[arg(long, value_enum, default_value = "default")]
        wavelength_term: WavelengthTermArg,
        /// LK14 sweeps: rounds of each case's runs, every run once per round in turn (uniform
        /// and adaptive alternate in one window); each run's time is its median.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        rounds: u32,
    },
    /// Write a procedural asset of the character scenes (scenes/character): `hand`, a hand-like
    /// body (arm, palm, two fingers) as an OBJ with UVs, lengths in mm.
    Asset {
        #[arg(value_enum)]
        kind: AssetKind,
        /// Output folder.
        #[arg(long, default_value = "scenes/character/assets")]
        out: PathBuf,
        /// File name without .obj.
        #[arg(long, default_value = "hand")]
        name: String,
        /// Vertices around and cells along each finger.
        #[arg(long, value_delimiter = ',', default_values_t = [72, 128])]
        finger_cells: Vec<u32>,
        /// Vertices around and cells along the arm and palm.
        #[arg(long, value_delimiter = ',', default_values_t = [48, 45])]
        arm_cells: Vec<u32>,
    },
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum LayoutArg {
    Material,
    Asset,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum AssetKind {
    Hand,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Sweeps {
    All,
    H15,
    Lk14,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum BendingArg {
    Hinge,
    Quadratic,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Lk14Case {
    #[value(name = "10")]
    Case10,
    #[value(name = "11")]
    Case11,
    Pinch,
    /// The localized pinch (issue 26): wrinkles on about a tenth of a large patch.
    Localized,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum WavelengthTermArg {
    Default,
    All,
    Off,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum AxisArg {
    X,
    Y,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum, serde::Serialize, serde::Deserialize)]
enum ColourArg {
    Strain,
    Curvature,
    Height,
    Layer,
}

impl From<ColourArg> for ColourBy {
    fn from(c: ColourArg) -> Self {
        match c {
            ColourArg::Strain => ColourBy::Strain,
            ColourArg::Curvature => ColourBy::Curvature,
            ColourArg::Height => ColourBy::Height,
            ColourArg::Layer => ColourBy::Layer,
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum, serde::Serialize, serde::Deserialize)]
enum Export {
    /// obj/<patch>/<layer>/<frame>.obj
    Obj,
    /// skinsim.usdc: one USD stage (Pixar's binary crate format), each layer a time-sampled mesh
    Usd,
    /// skinsim.usda: the same stage as text
    Usda,
}

#[derive(clap::Args, Clone, serde::Serialize, serde::Deserialize)]
struct RunArgs {
    /// The scene file (not with --resume: the checkpoint names it).
    #[arg(required_unless_present = "resume")]
    scene: Option<PathBuf>,
    /// Write the whole state every N frames to <out>/checkpoint.cbor (the last one kept), so
    /// that `run --resume <out>` can continue the run after it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    checkpoint_every: Option<u32>,
    /// Continue the run whose outputs are in this folder after its last checkpoint, with its
    /// scene and options, appending to its outputs. The frames after it are bit-identical to
    /// an uninterrupted run's at the same thread count. Refused when the scene file or the
    /// program changed since.
    #[arg(
        long,
        value_name = "OUT",
        conflicts_with_all = ["scene", "checkpoint_every", "out", "rrd", "spawn", "connect", "no_rerun",
                              "recording_id", "colour", "colour_scale", "export", "double_sided"]
    )]
    #[serde(skip)]
    resume: Option<PathBuf>,
    /// Output folder (default: out/<scene name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// The memory the run may take (GB; default: the scene's `memory`, else this machine's).
    #[arg(long, value_parser = budget_gb)]
    budget: Option<f64>,
    /// Number of frames (default: the scene's).
    #[arg(long)]
    frames: Option<u32>,
    /// Write the Rerun recording to this file (default: <out>/recording.rrd).
    #[arg(long, conflicts_with_all = ["spawn", "connect", "no_rerun"])]
    rrd: Option<PathBuf>,
    /// Stream to a newly spawned Rerun viewer (needs `rerun` on PATH).
    #[arg(long, conflicts_with_all = ["connect", "no_rerun"])]
    spawn: bool,
    /// Stream to a running viewer, e.g. rerun+http://127.0.0.1:9876/proxy.
    #[arg(long, conflicts_with = "no_rerun")]
    connect: Option<String>,
    /// No Rerun output at all.
    #[arg(long)]
    no_rerun: bool,
    /// The Rerun recording id (default: a fresh one per run, so runs never merge in a viewer;
    /// give one to log several runs into one recording, or for a known id).
    #[arg(long, conflicts_with = "no_rerun", value_parser = recording_id)]
    recording_id: Option<String>,
    /// What the viewer's colours show: the elastic area strain (blue stretch, red compression),
    /// the mean curvature (blue crests, red troughs), the height over the layer's best-fit plane
    /// (blue up, red down), or one colour per layer. The legend is logged as text.
    #[arg(long = "color", value_enum, default_value = "strain", conflicts_with = "no_rerun")]
    colour: ColourArg,
    /// The value that saturates the curvature (1/m) or height (mm) colours, for the whole run
    /// (default: each layer's 98th percentile at the first solved frame, then fixed).
    #[arg(
        long = "colour-scale",
        alias = "color-scale",
        conflicts_with = "no_rerun",
        value_parser = positive_scale,
        allow_negative_numbers = true
    )]
    colour_scale: Option<f64>,
    /// Extra exports.
    #[arg(long, value_enum)]
    export: Vec<Export>,
    /// The USD meshes double-sided (`doubleSided`: a DCC draws the skin's back faces too).
    #[arg(long)]
    double_sided: bool,
    /// Worker threads (default: all cores). Results are identical for a fixed count.
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar or summary.
    #[arg(long)]
    quiet: bool,
}

/// `--colour-scale`: a positive finite number.
fn positive_scale(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("must be a positive number (got {s})")),
    }
}

fn main() -> ExitCode {
    // Before any thread starts: every thread inherits the blocked signals.
    if let Err(e) = skinsim_tools::signals::take_over() {
        eprintln!("error: cannot set up the handling of Ctrl-C and SIGTERM: {e}");
        return ExitCode::from(1);
    }
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    // A bug must not greet the user with a Rust backtrace: one line, and the status says so.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("error: internal error in skinsim (please report it): {info}");
    }));
    let result = std::panic::catch_unwind(|| match cli.command {
        Command::Check { scene, budget } => check(&scene, budget),
        Command::Run(args) => run(args),
        Command::Analyze { dir, axis, periodic } => analyze(&dir, axis as usize, periodic),
        Command::Report { out, quick, only, bending, cases, wavelength_term, rounds } => {
            let element = match bending {
                BendingArg::Hinge => skinsim::physics::BendingElement::Hinge,
                BendingArg::Quadratic => skinsim::physics::BendingElement::Quadratic,
            };
            let cases: Vec<usize> = cases.iter().map(|c| *c as usize).collect();
            let term = match wavelength_term {
                WavelengthTermArg::Default => skinsim_tools::lk14_report::WavelengthTerm::Default,
                WavelengthTermArg::All => skinsim_tools::lk14_report::WavelengthTerm::All,
                WavelengthTermArg::Off => skinsim_tools::lk14_report::WavelengthTerm::Off,
            };
            let sweep = skinsim_tools::lk14_report::Sweep { quick, element, cases, wavelength_term: term, rounds };
            report(&out, only, &sweep)
        }
        Command::Timing { scenes, frames, rounds, out } => timing(&scenes, frames, rounds, &out),
        Command::Bake {
            scene,
            frames,
            weights,
            angles,
            size,
            out,
            layer,
            blend,
            layout,
            padding,
            edge_blend,
            bits,
            height_range,
            smooth,
        } => {
            let layout = match layout {
                LayoutArg::Material => MapLayout::Material,
                LayoutArg::Asset => MapLayout::Asset,
            };
            let (edge_blend, height_range) = (edge_blend * 1e-3, height_range * 1e-3);
            let req = BakeRequest {
                frames,
                weights,
                angles,
                size,
                layer,
                blends: blend,
                layout,
                padding,
                edge_blend,
                bits,
                height_range,
                smooth,
            };
            bake(&scene, req, out)
        }
        Command::Asset { kind: AssetKind::Hand, out, name, finger_cells, arm_cells } => {
            asset_hand(&out, &name, &finger_cells, &arm_cells)
        }
    });
    match result {
        Ok(code) => code,
        Err(_) => ExitCode::from(70),
    }
}

fn asset_hand(out: &Path, name: &str, finger: &[u32], arm: &[u32]) -> ExitCode {
    let cells = |c: &[u32]| (c[0], c[1]);
    if finger.len() != 2 || arm.len() != 2 || finger.iter().chain(arm).any(|&c| c < 3) {
        eprintln!("error: --finger-cells and --arm-cells take two numbers, around,along, each at least 3");
        return ExitCode::from(2);
    }
    let vertices = |c: &[u32]| c[0] as u64 * (c[1] as u64 + 1);
    let limit = skinsim::scene::MAX_GENERATED_VERTICES;
    if 2 * vertices(finger) + vertices(arm) > limit {
        eprintln!("error: --finger-cells and --arm-cells would make more than {limit} vertices");
        return ExitCode::from(2);
    }
    if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
        eprintln!("error: --name \"{name}\" must be a plain file name");
        return ExitCode::from(2);
    }
    let shape = skinsim::mesh::hand::HandShape { finger_cells: cells(finger), arm_cells: cells(arm) };
    match skinsim_tools::asset::write_hand(out, name, shape) {
        Ok((v, f)) => {
            println!("wrote {} ({v} vertices, {f} triangles)", out.join(format!("{name}.obj")).display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: cannot write {}: {e}", out.join(format!("{name}.obj")).display());
            ExitCode::from(1)
        }
    }
}

/// Creates `out` and holds it for this command (one writer per output folder), or exits 2.
fn hold(out: &Path, command: String) -> Result<skinsim_tools::out_lock::OutLock, ExitCode> {
    if let Err(e) = std::fs::create_dir_all(out) {
        eprintln!("error: cannot create the output folder {}: {e}", out.display());
        return Err(ExitCode::from(2));
    }
    skinsim_tools::out_lock::lock(out, &command).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

/// A memory budget on the command line: a positive number of GB.
fn budget_gb(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(gb) if gb > 0.0 && gb <= 1e6 => Ok(gb),
        _ => Err("a number of GB in (0, 1e6]".into()),
    }
}

fn load(path: &Path) -> Result<BuiltScene, ExitCode> {
    load_within(path, None)
}

/// `load` within a budget (GB).
fn load_within(path: &Path, budget_gb: Option<f64>) -> Result<BuiltScene, ExitCode> {
    scene::load_within(path, budget_gb.map(|gb| gb * 1e9)).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

fn check(path: &Path, budget: Option<f64>) -> ExitCode {
    match load_within(path, budget) {
        Ok(s) => {
            // A shared body counts once (a patch on it holds a copy as its layer 0).
            let own = s.patches.iter().flat_map(|p| &p.layers[p.body.map_or(0, |_| 1)..]);
            let verts: usize = own.chain(s.bodies.iter().flat_map(|b| &b.layers)).map(|l| l.mesh.rest().len()).sum();
            let bodies = match s.bodies.len() {
                0 => String::new(),
                1 => "1 body, ".into(),
                n => format!("{n} bodies, "),
            };
            println!(
                "{}: ok ({bodies}{} patches, {} vertices, {} frames; about {:.0} MB to run)",
                path.display(),
                s.patches.len(),
                verts,
                s.scene.frames,
                s.memory / 1e6
            );
            for note in &s.notes {
                println!("  {note}");
            }
            // What a run costs, per patch (issue 66; orders of magnitude: scene::estimate).
            use skinsim::scene::estimate::{costs, duration, ITERATIONS};
            for c in costs(&s) {
                println!(
                    "  {}: {} vertices, {} DOFs; Newton factor about {:.0} MB; a frame about {} smooth ({} Newton iterations) to {} buckling ({})",
                    c.name,
                    c.vertices,
                    c.dofs,
                    c.factor_bytes / 1e6,
                    duration(c.frame_seconds[0]),
                    ITERATIONS[0],
                    duration(c.frame_seconds[1]),
                    ITERATIONS[1],
                );
            }
            ExitCode::SUCCESS
        }
        Err(code) => code,
    }
}

/// The largest `--threads`, as a multiple of the machine's cores (more only costs memory).
const MAX_THREADS_PER_CORE: usize = 16;
/// Exit status of an interrupted run (128 + SIGINT, as shells report it).
const INTERRUPTED: u8 = 130;

/// A checkpoint file of `run` (`skinsim_tools::resume`).
type Saved = skinsim_tools::resume::Saved<RunArgs>;

/// `run --resume OUT`: the checkpoint, and the options to run with: the saved run's, with this
/// command's `--frames`, `--threads`, `--budget` and `--quiet`.
fn resume_args(out: &Path, given: &RunArgs) -> Result<(Saved, RunArgs), ExitCode> {
    let saved: Saved = skinsim_tools::resume::read(out).map_err(|e| {
        eprintln!("error: cannot resume: {e}");
        ExitCode::from(2)
    })?;
    if let Some(n) = given.threads.filter(|&n| n != saved.threads) {
        eprintln!(
            "error: cannot resume: the run used {} threads, and only the same count repeats its frames \
             bit for bit (give --threads {} or leave it out; got {n})",
            saved.threads, saved.threads
        );
        return Err(ExitCode::from(2));
    }
    let mut args = saved.args.clone();
    args.threads = Some(saved.threads);
    args.frames = given.frames.or(Some(saved.frames));
    (args.budget, args.quiet) = (given.budget, given.quiet);
    Ok((saved, args))
}

/// `path` made absolute (a resumed run may start in another folder).
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

fn run(args: RunArgs) -> ExitCode {
    let (resume, args) = match args.resume.clone() {
        Some(out) => match resume_args(&out, &args) {
            Ok((saved, merged)) => (Some(saved), merged),
            Err(code) => return code,
        },
        None => (None, args),
    };
    // (before the scene loads: building it runs on rayon's pool, which then exists with a
    // thread per core and cannot be resized)
    if let Some(n) = args.threads {
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        let max = MAX_THREADS_PER_CORE * cores;
        if n == 0 || n > max {
            eprintln!("error: --threads must be in 1..={max} ({MAX_THREADS_PER_CORE} per core; got {n})");
            return ExitCode::from(2);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("error: cannot start {n} worker threads: {e}");
            return ExitCode::from(1);
        }
    }
    let scene_path = args.scene.clone().expect("a scene: clap requires one without --resume");
    if let Some(saved) = &resume {
        let differs =
            skinsim_tools::resume::differences(saved, skinsim_tools::resume::file_sha256(&scene_path).ok().as_deref());
        if !differs.is_empty() {
            eprintln!("error: cannot resume from {}: {}", skinsim_tools::resume::FILE, differs.join("; "));
            return ExitCode::from(2);
        }
    }
    let scene = match load_within(&scene_path, args.budget) {
        Ok(s) => s,
        Err(code) => return code,
    };
    if !args.quiet {
        scene.notes.iter().filter(|n| n.starts_with("warning")).for_each(|n| eprintln!("{n}"));
    }
    if args.frames == Some(0) {
        eprintln!("error: --frames must be at least 1");
        return ExitCode::from(2);
    }
    let frames = args.frames.unwrap_or(scene.scene.frames);
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.scene.name));
    let _held = match hold(&out, format!("run {}", scene_path.display())) {
        Ok(l) => l,
        Err(code) => return code,
    };
    let (mut sim, done) = match &resume {
        None => {
            if let Err(e) = clear_earlier_outputs(&args, &scene, &out) {
                eprintln!("error: cannot clear an earlier run's outputs in {}: {e}", out.display());
                return ExitCode::from(2);
            }
            (Simulation::new(&scene), 0)
        }
        Some(saved) => {
            let done = saved.state.frame;
            if done >= frames {
                eprintln!(
                    "error: nothing to resume: the checkpoint is of frame {done}, and the run ends at frame \
                     {frames} (--frames N goes further)"
                );
                return ExitCode::from(2);
            }
            match Simulation::resume(&scene, &saved.state) {
                Ok(sim) => (sim, done),
                Err(e) => {
                    eprintln!("error: cannot resume: {e}");
                    return ExitCode::from(2);
                }
            }
        }
    };
    if resume.is_some() {
        if let Err(e) = skinsim::mesh::obj::clear_frames_after(&out, done) {
            eprintln!("error: cannot clear the frames after the checkpoint in {}: {e}", out.display());
            return ExitCode::from(2);
        }
    }
    // Ctrl-C (or SIGTERM) ends the run after the frame being computed, with every output
    // closed; a second one ends it at once.
    let interrupted = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        skinsim_tools::signals::on_signal(move || {
            if flag.swap(true, std::sync::atomic::Ordering::SeqCst) {
                eprintln!("\nerror: interrupted again: stopping now");
                std::process::exit(INTERRUPTED as i32);
            }
            eprintln!("\ninterrupted: finishing the current frame (Ctrl-C again to stop now)");
        });
    }
    let mark = resume.as_ref().and_then(|s| s.recording.as_ref());
    let (rec, rrd_file) = match recording(&args, &scene, &out, mark) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot open the Rerun output: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(rec) = &rec {
        sim.world.insert_resource(RerunSink(rec.clone()));
        let by: ColourBy = args.colour.into();
        let scale = args.colour_scale.map(|s| if by == ColourBy::Height { s * 1e-3 } else { s });
        sim.world.insert_resource(Colouring(by, scale));
    }
    if args.export.contains(&Export::Obj) || scene.scene.output.obj {
        sim.world.insert_resource(ObjExport(out.clone()));
    }
    let text = args.export.contains(&Export::Usda) || scene.scene.output.usd_text;
    if args.export.contains(&Export::Usd) || scene.scene.output.usd || text {
        let doc =
            format!("skinsim {}: scene {} ({})", env!("CARGO_PKG_VERSION"), scene.scene.name, scene_path.display());
        let options = UsdOptions {
            format: if text { UsdFormat::Text } else { UsdFormat::Crate },
            double_sided: args.double_sided || scene.scene.output.double_sided,
            st_unit: scene.scene.units.length.to_si(),
        };
        let fps = 1.0 / scene.scene.frame_time;
        let stage = match resume.as_ref().and_then(|s| s.usd.as_ref()) {
            Some(mark) => UsdStage::reopen(&out, &doc, fps, options, mark),
            None => UsdStage::new(&out, &doc, fps, options),
        };
        match stage {
            Ok(stage) => {
                sim.world.insert_resource(UsdExport(stage));
            }
            Err(e) => {
                eprintln!("error: cannot start the USD cache in {}: {e}", out.display());
                return ExitCode::from(2);
            }
        }
    }
    let stats_path = out.join("stats.jsonl");
    let mut stats = if scene.scene.output.stats {
        let file = match resume.as_ref().and_then(|s| s.stats_len) {
            Some(len) => skinsim_tools::resume::reopen_stats(&stats_path, len),
            None => std::fs::File::create(&stats_path).map_err(|e| format!("{}: {e}", stats_path.display())),
        };
        match file {
            Ok(f) => Some(std::io::BufWriter::new(f)),
            Err(e) => {
                eprintln!("error: cannot write {e}");
                return ExitCode::from(2);
            }
        }
    } else {
        None
    };
    // What a checkpoint records of this run besides the state.
    let mut saved_args = args.clone();
    (saved_args.scene, saved_args.out) = (Some(absolute(&scene_path)), Some(absolute(&out)));
    saved_args.rrd = saved_args.rrd.as_deref().map(absolute);
    let scene_sha256 = scene_hash(&scene_path);
    let recording_id = rec.as_ref().and_then(|r| r.store_info()).map(|i| i.store_id.recording_id().to_string());
    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(frames as u64) };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {elapsed} (eta {eta})  {msg}").unwrap());
    bar.set_position(done as u64);
    let start = std::time::Instant::now();
    let mut unconverged = Vec::new();
    let mut status = ExitCode::SUCCESS;
    let mut last = done;
    // Tests kill a run at a known frame (`tests/resume.rs`): as SIGKILL would, after the frame's
    // outputs, with nothing closed.
    let kill_after: Option<u32> = std::env::var("SKINSIM_TEST_KILL_AFTER_FRAME").ok().and_then(|v| v.parse().ok());
    for _ in done..frames {
        let frame = sim.step();
        last = frame.frame;
        // The layout, once the first frame says which stages run (a resumed recording file
        // has it from before the checkpoint; a viewer gets it again).
        let first = frame.frame == done + 1 && (done == 0 || rrd_file.is_none());
        if let (Some(rec), true) = (&rec, first) {
            let ran = frame
                .timings_ms
                .iter()
                .filter(|(k, v)| !["total", "log"].contains(&k.as_str()) && v.as_f64() > Some(0.0));
            let stages: Vec<String> = ran.map(|(k, _)| k.clone()).collect();
            let _ = skinsim_tools::layout::layout(&scene, &stages).send(rec);
            let _ = skinsim_tools::layout::log_stage_colours(rec, &stages);
        }
        // The recording first, then the stats line: a killed run's stats.jsonl never names a
        // frame its recording lacks.
        if let Some(rec) = &rec {
            rec.flush_blocking().ok();
        }
        if let Some(e) = rrd_file.as_ref().and_then(|f| f.error()) {
            bar.abandon();
            eprintln!(
                "error: cannot write the recording {e}; frames 1-{} are complete in the other outputs",
                frame.frame
            );
            status = ExitCode::from(1);
            break;
        }
        if let Some(w) = stats.as_mut() {
            let line = serde_json::to_string(&frame).expect("stats serialize");
            if let Err(e) = writeln!(w, "{line}").and_then(|_| w.flush()) {
                bar.abandon();
                eprintln!("error: cannot write {}: {e}", stats_path.display());
                status = ExitCode::from(1);
                break;
            }
        }
        let iters: u32 = frame.patches.iter().map(|p| p.outcome.iterations).sum();
        bar.set_message(format!("{iters} Newton its, {:.0} ms/frame", frame.total_ms()));
        bar.inc(1);
        if let Some(reason) = sim.failure() {
            bar.abandon();
            eprintln!("error: simulation failed at {reason}; frames before it are complete in {}", out.display());
            status = ExitCode::from(1);
            break;
        }
        // Every N frames, and at an interruption (a farm's preemption sends SIGTERM): the resume
        // then loses no finished frame.
        let stopping = interrupted.load(std::sync::atomic::Ordering::SeqCst);
        if args.checkpoint_every.is_some_and(|n| frame.frame % n == 0 || stopping) {
            let written = Written { stats: &stats_path, stats_on: stats.is_some(), rrd: rrd_file.as_ref() };
            let ids = (&saved_args, scene_sha256.as_str(), scene.scene.name.as_str(), recording_id.as_deref(), frames);
            if let Err(e) = write_checkpoint(&mut sim, &out, ids, written) {
                bar.abandon();
                eprintln!(
                    "error: cannot write the checkpoint {e}; frames 1-{} are complete in {}",
                    frame.frame,
                    out.display()
                );
                status = ExitCode::from(1);
                break;
            }
        }
        if kill_after == Some(frame.frame) {
            let _ = std::process::Command::new("kill").args(["-KILL", &std::process::id().to_string()]).status();
            std::process::exit(137);
        }
        for p in frame.patches.iter().filter(|p| !p.outcome.converged) {
            unconverged
                .push(format!("frame {} patch \"{}\" (residual {:.2e})", frame.frame, p.name, p.outcome.residual));
        }
        if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
            bar.abandon();
            eprintln!(
                "error: interrupted after frame {}; frames 1-{} are complete in {}",
                frame.frame,
                frame.frame,
                out.display()
            );
            status = ExitCode::from(INTERRUPTED);
            break;
        }
    }
    bar.finish_and_clear();
    if let Some(rec) = &rec {
        let _ = rec.flush_blocking();
    }
    if let Some(Err(e)) = rrd_file.as_ref().map(|f| f.finish()) {
        if status == ExitCode::SUCCESS {
            eprintln!("error: cannot write the recording {e}");
        }
        status = ExitCode::from(1);
    }
    // The USD stage holds every frame that completed, whatever ended the run; a run that may
    // be resumed keeps its spool for the resume to append to.
    if let Some(UsdExport(stage)) = sim.world.remove_resource::<UsdExport>() {
        let path = stage.path().to_path_buf();
        let resumable = args.checkpoint_every.is_some() && last < frames;
        let written = if resumable { stage.finish_keeping() } else { stage.finish() };
        if let Err(e) = written {
            eprintln!("error: cannot write {}: {e}", path.display());
            status = ExitCode::from(1);
        }
    }
    if !unconverged.is_empty() && status == ExitCode::SUCCESS {
        eprintln!("error: Newton did not converge in {} frame(s): {}", unconverged.len(), unconverged.join("; "));
        status = ExitCode::from(1);
    }
    if !args.quiet {
        let resumed = if done > 0 { format!(" (resumed after frame {done})") } else { String::new() };
        eprintln!(
            "{} frames{resumed} in {:.2} s; outputs in {}",
            last - done,
            start.elapsed().as_secs_f64(),
            out.display()
        );
    }
    status
}

/// The outputs a checkpoint marks how far they got.
struct Written<'a> {
    stats: &'a Path,
    stats_on: bool,
    rrd: Option<&'a skinsim_tools::rrd_sink::RrdFile>,
}

/// Saves the state after the frame just written, with the run's options and its outputs' marks
/// (every output is flushed by now: the recording and stats.jsonl by the frame loop).
fn write_checkpoint(
    sim: &mut Simulation,
    out: &Path,
    (args, scene_sha256, name, recording_id, frames): (&RunArgs, &str, &str, Option<&str>, u32),
    written: Written,
) -> Result<(), String> {
    let len = |p: &Path| std::fs::metadata(p).map(|m| m.len()).map_err(|e| format!("{}: {e}", p.display()));
    let usd = match sim.world.get_resource_mut::<UsdExport>() {
        Some(mut stage) => {
            let path = stage.0.path().to_path_buf();
            Some(stage.0.mark().map_err(|e| format!("(USD spool of {}): {e}", path.display()))?)
        }
        None => None,
    };
    let recording = match recording_id {
        Some(id) => Some(skinsim_tools::resume::RecordingMark {
            file: written.rrd.map(|f| f.path().to_path_buf()),
            len: written.rrd.map(|f| len(f.path())).transpose()?.unwrap_or(0),
            recording_id: id.to_string(),
        }),
        None => None,
    };
    let saved = Saved {
        format: skinsim_tools::resume::FORMAT,
        version: env!("CARGO_PKG_VERSION").into(),
        build: skinsim_tools::resume::build_id(),
        scene_file: args.scene.clone().expect("a scene"),
        scene_sha256: scene_sha256.into(),
        scene_name: name.into(),
        args: args.clone(),
        threads: rayon::current_num_threads(),
        frames,
        stats_len: written.stats_on.then(|| len(written.stats)).transpose()?,
        recording,
        usd,
        state: sim.checkpoint(),
    };
    skinsim_tools::resume::write(out, &saved)
}

/// What an earlier run into `out` left that this one would not overwrite: its OBJ frames, and
/// its stats.jsonl and recording.rrd when this run writes none there. Nothing else is touched.
fn clear_earlier_outputs(args: &RunArgs, scene: &BuiltScene, out: &Path) -> std::io::Result<()> {
    skinsim::mesh::obj::clear_frames(out)?;
    let records_here = !args.no_rerun && !args.spawn && args.connect.is_none() && args.rrd.is_none();
    // An earlier stage goes in any case: this run's is written when it ends.
    let stale = [
        ("stats.jsonl", !scene.scene.output.stats),
        ("recording.rrd", !(records_here && scene.scene.output.rerun)),
        (UsdFormat::Crate.file_name(), true),
        (UsdFormat::Text.file_name(), true),
    ];
    for (name, stale) in stale {
        let path = out.join(name);
        if stale && path.is_file() {
            std::fs::remove_file(path)?;
        }
    }
    Ok(())
}

fn analyze(dir: &Path, axis: usize, periodic: bool) -> ExitCode {
    use skinsim_tools::wrinkles;
    let mut files: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(d) => {
            d.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|x| x == "obj")).collect()
        }
        Err(e) => {
            eprintln!("error: {}: {e}", dir.display());
            return ExitCode::from(2);
        }
    };
    files.sort();
    if files.is_empty() {
        eprintln!("error: {}: no .obj frames (run with --export obj)", dir.display());
        return ExitCode::from(2);
    }
    // (a FIFO would block the read for ever, a link to /dev/zero fill the memory)
    if let Some(f) = files.iter().find(|f| !std::fs::metadata(f).is_ok_and(|m| m.is_file())) {
        eprintln!("error: {}: not a regular file (analyze reads regular .obj files only)", f.display());
        return ExitCode::from(2);
    }
    println!("{:>8} {:>12} {:>14} {:>14} {:>14}", "frame", "compression", "wavelength_mm", "second_mm", "amplitude_mm");
    let mut series = Vec::new();
    for f in &files {
        let m = match skinsim::mesh::obj::load(f, 1.0) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: {}: {e}", f.display());
                return ExitCode::from(2);
            }
        };
        let p = wrinkles::profile(&m.rest, &m.uv, axis);
        let eps = wrinkles::compression(&m.rest, &m.uv, axis);
        let a = wrinkles::amplitude(&p);
        let pk = wrinkles::peaks(&p, periodic, 0.25);
        let w = |i: usize| pk.get(i).map_or("-".to_string(), |q| format!("{:.4}", q.wavelength * 1e3));
        let name = f.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        println!("{:>8} {:>12.6} {:>14} {:>14} {:>14.6}", name, eps, w(0), w(1), a * 1e3);
        series.push((eps, a));
    }
    let top = series.iter().fold(0.0f64, |m, s| m.max(s.1));
    match wrinkles::onset_strain(&series, 0.05 * top) {
        Some(e) => {
            println!("onset strain (fit of A^2 against strain over amplitudes above 5 % of the largest): {e:.6}")
        }
        None => println!("onset strain: not enough wrinkled frames"),
    }
    ExitCode::SUCCESS
}

/// The run's recording, and when it goes to a file, the file (its write errors end the run).
type Recording = (Option<rerun::RecordingStream>, Option<skinsim_tools::rrd_sink::RrdFile>);

/// The Rerun output; `resumed`: an interrupted run's recording, continued under its id (its
/// file cut back to the checkpoint's mark).
fn recording(
    args: &RunArgs,
    scene: &BuiltScene,
    out: &Path,
    resumed: Option<&skinsim_tools::resume::RecordingMark>,
) -> Result<Recording, String> {
    if args.no_rerun || (!scene.scene.output.rerun && args.rrd.is_none() && !args.spawn && args.connect.is_none()) {
        return Ok((None, None));
    }
    let mut builder = rerun::RecordingStreamBuilder::new("skinsim").recording_name(scene.scene.name.clone());
    if let Some(id) = &args.recording_id {
        // (an explicit id would otherwise drop the recording's name and start time)
        builder = builder.recording_id(id.clone()).send_properties(true);
    }
    if let Some(mark) = resumed {
        // (its name and start time are in the stream before the mark)
        builder = builder.recording_id(mark.recording_id.clone()).send_properties(false);
    }
    let mut file = None;
    let rec = if args.spawn {
        builder.spawn()
    } else if let Some(url) = &args.connect {
        viewer_listening(url)?;
        builder.connect_grpc_opts(url.clone())
    } else {
        let path = args.rrd.clone().unwrap_or_else(|| out.join("recording.rrd"));
        let (f, sink) = match resumed.map(|m| m.len) {
            Some(len) => skinsim_tools::rrd_sink::RrdFile::append(&path, len)?,
            None => skinsim_tools::rrd_sink::RrdFile::create(&path)?,
        };
        file = Some(f);
        builder.set_sinks(vec![Box::new(sink) as Box<dyn rerun::sink::LogSink>])
    }
    .map_err(|e| e.to_string())?;
    rec.set_log_time_enabled(false);
    // Shown in the viewer's recording properties beside the name and start time.
    let text = |v: String| [rerun::components::Text(v.into())];
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    let scene_file = args.scene.clone().unwrap_or_default();
    let about = rerun::AnyValues::default()
        .with_component::<rerun::components::Text>("scene", text(scene.scene.name.clone()))
        .with_component::<rerun::components::Text>("scene_file", text(scene_file.display().to_string()))
        .with_component::<rerun::components::Text>("scene_sha256", text(scene_hash(&scene_file)))
        .with_component::<rerun::components::Text>("skinsim_version", text(env!("CARGO_PKG_VERSION").to_string()))
        .with_component::<rerun::components::Text>("threads", text(threads.to_string()));
    if resumed.is_none() {
        rec.send_property("skinsim", &about).map_err(|e| e.to_string())?;
    }
    Ok((Some(rec), file))
}

/// The SHA-256 of a scene file's bytes, in hex (which scene text a recording came from).
fn scene_hash(path: &Path) -> String {
    use sha2::Digest;
    let bytes = std::fs::read(path).unwrap_or_default();
    sha2::Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// A recording id: 1-128 printable characters, no spaces.
fn recording_id(s: &str) -> Result<String, String> {
    if !s.is_empty() && s.len() <= 128 && s.chars().all(|c| c.is_ascii_graphic()) {
        Ok(s.to_string())
    } else {
        Err("1 to 128 printable ASCII characters without spaces".into())
    }
}

/// The Rerun SDK connects lazily and drops what it cannot send: check that a viewer answers at
/// `url` (e.g. rerun+http://127.0.0.1:9876/proxy) before the run starts.
fn viewer_listening(url: &str) -> Result<(), String> {
    use std::net::ToSocketAddrs;
    let authority = url.split_once("://").map_or(url, |(_, rest)| rest).split('/').next().unwrap_or("");
    let addresses: Vec<_> = authority.to_socket_addrs().map_err(|e| format!("{url}: {e}"))?.collect();
    let timeout = std::time::Duration::from_secs(2);
    let Some(stream) = addresses.iter().find_map(|a| std::net::TcpStream::connect_timeout(a, timeout).ok()) else {
        return Err(format!("no viewer is listening at {url} (start one with `rerun`, or use --spawn)"));
    };
    skinsim_tools::handshake::speaks_grpc(stream, timeout)
        .map_err(|why| format!("{url} is not a Rerun viewer: {why} (start one with `rerun`, or use --spawn)"))
}

fn bake(path: &Path, req: BakeRequest, out: Option<PathBuf>) -> ExitCode {
    let scene = match load(path) {
        Ok(s) => s,
        Err(code) => return code,
    };
    if !(16..=8192).contains(&req.size) {
        eprintln!("error: --size must be in 16..=8192 (got {})", req.size);
        return ExitCode::from(2);
    }
    if let Err(e) = skinsim_tools::bake::frames_for(&scene, &req) {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(&scene.scene.name).join("wrinkle_maps"));
    let _held = match hold(&out, format!("bake {}", path.display())) {
        Ok(l) => l,
        Err(code) => return code,
    };
    let opened = skinsim_tools::rrd_sink::RrdFile::create(&out.join("bake.rrd"));
    let started = opened.map_err(|e| e.to_string()).and_then(|(file, sink)| {
        let rec = rerun::RecordingStreamBuilder::new("skinsim-bake")
            .set_sinks(vec![Box::new(sink) as Box<dyn rerun::sink::LogSink>]);
        rec.map(|r| (file, r)).map_err(|e| e.to_string())
    });
    let (file, rec) = match started {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot write the bake's recording {e}");
            return ExitCode::from(1);
        }
    };
    let result = skinsim_tools::bake::bake(&scene, &req, &out, Some(&rec));
    let _ = rec.flush_blocking();
    let result =
        result.and_then(|b| file.finish().map(|_| b).map_err(|e| format!("cannot write the bake's recording {e}")));
    match result {
        Ok(baked) => {
            for w in &baked.warnings {
                eprintln!("warning: {w}");
            }
            for (body, lo, hi) in &baked.rectangles {
                // (in the asset's own UVs: a character's atlas, an OBJ body's vt)
                let vt = |v: glam::DVec2| v.to_array().map(|x| format!("{x:.4}")).join(", ");
                println!("{body}: the map spans the body's UVs from ({}) to ({})", vt(*lo), vt(*hi));
            }
            for m in &baked.maps {
                println!("frame {:>5}  {}/{}  {}", m.frame, m.patch, m.layer, m.path.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

fn timing(scenes: &[PathBuf], frames: Option<u32>, rounds: u32, out: &Path) -> ExitCode {
    use skinsim_tools::timing;
    if scenes.is_empty() || frames == Some(0) {
        eprintln!("error: timing needs at least one scene and --frames of at least 1");
        return ExitCode::from(2);
    }
    // Every scene is checked before any runs: a typo in the last one must not waste the rounds.
    for path in scenes {
        if let Err(code) = load(path) {
            return code;
        }
    }
    let _held = match hold(out, "timing".to_string()) {
        Ok(l) => l,
        Err(code) => return code,
    };
    let paths: Vec<&Path> = scenes.iter().map(PathBuf::as_path).collect();
    let rows = match timing::time_rounds(&paths, frames, rounds) {
        Ok(rows) => rows,
        Err(e) => {
            // (every scene loaded above: what is left is a frame that failed)
            eprintln!("error: {e}");
            return ExitCode::from(1);
        }
    };
    let table = timing::markdown(&rows);
    print!("{table}");
    if std::fs::create_dir_all(out).and_then(|_| std::fs::write(out.join("timing.md"), &table)).is_err() {
        eprintln!("error: cannot write {}", out.join("timing.md").display());
        return ExitCode::from(1);
    }
    ExitCode::SUCCESS
}

fn report(out: &Path, only: Sweeps, sweep: &skinsim_tools::lk14_report::Sweep) -> ExitCode {
    let _held = match hold(out, "report".to_string()) {
        Ok(l) => l,
        Err(code) => return code,
    };
    let result = (|| -> Result<(), Box<dyn std::error::Error>> {
        if only != Sweeps::Lk14 {
            let rows = skinsim_tools::report::speed_error(out, sweep.quick)?;
            println!("{} runs; wrote {}", rows.len(), out.join("speed_error.md").display());
        }
        if only != Sweeps::H15 {
            let rows = skinsim_tools::lk14_report::speed_error(out, sweep)?;
            println!("{} runs; wrote {}", rows.len(), out.join("speed_error_lk14.md").display());
        }
        Ok(())
    })();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
