//! Reading, validating and building a scene: everything `skinsim check` verifies.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

use super::error::SceneError;
use super::schema::*;
use crate::mesh::{self, SurfaceMesh, TetMesh};
use crate::model::{LayerKind, WeightMap};
use crate::physics::{BendingElement, Lame};

/// A validated scene with its meshes built, in SI units.
#[derive(Clone, Debug)]
pub struct BuiltScene {
    pub path: PathBuf,
    pub scene: Scene,
    pub patches: Vec<BuiltPatch>,
}

#[derive(Clone, Debug)]
pub struct BuiltPatch {
    pub name: String,
    pub solver: crate::solve::SolverSettings,
    /// The imperfection spawn applies to free shell vertices (SI lengths).
    pub perturbation: Option<Perturbation>,
    pub layers: Vec<BuiltLayer>,
    pub drivers: Vec<BuiltDriver>,
    pub couplings: Vec<BuiltCoupling>,
    pub anchors: Option<super::anchors::BuiltAnchors>,
}

/// A coupling's kernels, clustered at load (SI units).
#[derive(Clone, Debug)]
pub struct BuiltCoupling {
    pub upper: usize,
    pub lower: usize,
    pub kernels: Vec<crate::coupling::kernels::KernelShape>,
    pub adjust: bool,
}

#[derive(Clone, Debug)]
pub enum LayerMesh {
    Surface(SurfaceMesh),
    Volume(TetMesh),
}

impl LayerMesh {
    pub fn rest(&self) -> &[DVec3] {
        match self {
            LayerMesh::Surface(m) => &m.rest,
            LayerMesh::Volume(m) => &m.rest,
        }
    }
}

#[derive(Clone, Debug)]
pub struct BuiltLayer {
    pub name: String,
    pub kind: LayerKind,
    pub mesh: LayerMesh,
    /// Per mesh vertex: Some((layer, vertex)) when the vertex is another (earlier) layer's.
    pub shared: Vec<Option<(usize, u32)>>,
    /// The prism grid of a volume slab, for layers stacked on it.
    pub slab: Option<SlabGrid>,
    pub material: Option<crate::model::Material>,
    pub thickness: Option<f64>,
    pub bending: Option<crate::model::Bending>,
    pub prestrain: Option<crate::model::LayerPrestrain>,
    /// (relative amplitude, seed) of the per-element modulus randomization.
    pub randomize: Option<(f64, u64)>,
    pub properties: Option<crate::model::LayerProperties>,
    pub remesh: Option<crate::model::RemeshSettings>,
}

impl LayerMesh {
    /// Material (2D) positions of the mesh's vertices, as spawned into `MaterialPos`.
    pub fn material_positions(&self) -> Vec<DVec2> {
        match self {
            LayerMesh::Surface(m) => m.uv.clone(),
            LayerMesh::Volume(m) => m.rest.iter().map(|p| p.truncate()).collect(),
        }
    }
}

/// The structured grid of a tetrahedral slab (SI, offset included).
#[derive(Clone, Copy, Debug)]
pub struct SlabGrid {
    pub size: DVec2,
    pub cells: (u32, u32),
    pub origin: DVec3,
    /// z of the top plane.
    pub top: f64,
    /// Number of vertex planes.
    pub planes: usize,
}

impl SlabGrid {
    fn plane_len(&self) -> usize {
        (self.cells.0 as usize + 1) * (self.cells.1 as usize + 1)
    }
    fn top_offset(&self) -> usize {
        (self.planes - 1) * self.plane_len()
    }
}

/// A hinge across a periodic seam: `v` in hinge order (edge on the max side, its face's
/// opposite vertex, the min-side face's opposite vertex), and the (max, min) pair of vertices
/// whose difference is the period.
#[derive(Clone, Copy, Debug)]
pub struct SeamHinge {
    pub v: [u32; 4],
    pub image: (u32, u32),
}

/// A blend-shape target: displacements of the layer's vertices (m) and weight keyframes.
pub type BuiltTarget = (Vec<DVec3>, Vec<(u32, f64)>);

/// Drivers with layer names resolved to indices and values in SI units.
#[derive(Clone, Debug)]
pub enum BuiltDriver {
    Pin {
        layer: usize,
        vertices: Vec<u32>,
        dofs: [bool; 3],
    },
    Compress {
        layers: Vec<usize>,
        axis: usize,
        keyframes: Vec<(u32, f64)>,
        predict: bool,
    },
    Bend {
        layers: Vec<usize>,
        axis: usize,
        keyframes: Vec<(u32, f64)>,
    },
    /// Springs (vertex of `layer`, vertex of `to`, stiffness N/m).
    Attach {
        layer: usize,
        to: usize,
        springs: Vec<(u32, u32, f64)>,
    },
    /// Per layer: (vertex, master vertex) pairs whose in-plane coordinates are shared.
    PlaneStrain {
        layers: Vec<usize>,
        axis: usize,
        ties: Vec<Vec<(u32, u32)>>,
    },
    /// Per layer: (max-side vertex, min-side vertex) pairs sharing the non-axis coordinates,
    /// and for shells the hinges across the seam.
    Periodic {
        layers: Vec<usize>,
        axis: usize,
        ties: Vec<Vec<(u32, u32)>>,
        seams: Vec<Vec<SeamHinge>>,
    },
    /// Per target: displacements of the layer's vertices (m) and weight keyframes.
    BlendShape {
        layer: usize,
        targets: Vec<BuiltTarget>,
        interpolation: crate::model::Interpolation,
    },
    /// Per frame from `start`: displacements of the layer's vertices from rest (m).
    Sequence {
        layer: usize,
        frames: Vec<Vec<DVec3>>,
        start: u32,
    },
    Capture {
        layers: Vec<usize>,
        frame: u32,
        fraction: f64,
        /// Per listed layer: the painted fraction over its rectangle.
        maps: Vec<Option<WeightMap>>,
    },
}

/// Reads, validates and builds a scene file.
pub fn load(path: &Path) -> Result<BuiltScene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError {
        file: path.to_path_buf(),
        position: None,
        field: None,
        message: format!("cannot read the scene file: {e}"),
    })?;
    load_str(&text, path)
}

/// Parses, validates and builds a scene given as text; `path` names it in errors and anchors
/// relative asset paths.
pub fn load_str(text: &str, path: &Path) -> Result<BuiltScene, SceneError> {
    let options = ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    let scene: Scene = options.from_str(text).map_err(|e| SceneError {
        file: path.to_path_buf(),
        position: Some((e.span.start.line, e.span.start.col)),
        field: None,
        message: e.code.to_string(),
    })?;
    Builder { file: path.to_path_buf(), dir: path.parent().map(Path::to_path_buf).unwrap_or_default() }.build(scene)
}

/// A layer's material as stated or taken from its preset (scene units).
struct Resolved {
    model: crate::physics::ConstitutiveModel,
    young: f64,
    poisson: f64,
    density: f64,
    thickness: Option<f64>,
}

pub(super) struct Builder {
    pub(super) file: PathBuf,
    pub(super) dir: PathBuf,
}

impl Builder {
    pub(super) fn err(&self, field: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError::at_field(&self.file, field, message)
    }

    fn build(&self, scene: Scene) -> Result<BuiltScene, SceneError> {
        if scene.patches.is_empty() {
            return Err(self.err("patches", "the scene is empty: it declares no patch"));
        }
        if scene.frames == 0 {
            return Err(self.err("frames", "must be at least 1"));
        }
        if !(scene.frame_time > 0.0 && scene.frame_time.is_finite()) {
            return Err(
                self.err("frame_time", format!("must be a positive number of seconds (got {})", scene.frame_time))
            );
        }
        let mut names = HashMap::new();
        let mut patches = Vec::new();
        for (pi, p) in scene.patches.iter().enumerate() {
            if let Some(prev) = names.insert(p.name.clone(), pi) {
                return Err(self.err(
                    format!("patches[{pi}].name"),
                    format!("\"{}\" is also the name of patches[{prev}]", p.name),
                ));
            }
            patches.push(self.patch(&scene, pi, p)?);
        }
        Ok(BuiltScene { path: self.file.clone(), scene, patches })
    }

    fn patch(&self, scene: &Scene, pi: usize, p: &PatchSpec) -> Result<BuiltPatch, SceneError> {
        let at = format!("patches[{pi}] (\"{}\")", p.name);
        let len = scene.units.length.to_si();
        let stress = scene.units.stress.to_si();
        if p.layers.is_empty() {
            return Err(self.err(format!("{at}.layers"), "a patch needs at least one layer"));
        }
        let s = &p.solver;
        if s.tolerance.is_nan() || s.tolerance <= 0.0 {
            return Err(self.err(format!("{at}.solver.tolerance"), format!("must be > 0 (got {})", s.tolerance)));
        }
        if s.max_iterations == 0 {
            return Err(self.err(format!("{at}.solver.max_iterations"), "must be at least 1"));
        }
        let solver = s.settings();
        let mut perturbation = s.perturbation;
        if let Some(pert) = &mut perturbation {
            if !(pert.amplitude >= 0.0 && pert.amplitude.is_finite()) {
                return Err(self.err(format!("{at}.solver.perturbation.amplitude"), "must be >= 0"));
            }
            pert.amplitude *= len;
            if let Some(cell) = &mut pert.cell {
                if !(*cell > 0.0 && cell.is_finite()) {
                    return Err(self.err(format!("{at}.solver.perturbation.cell"), "must be > 0"));
                }
                *cell *= len;
            }
        }
        let offset = DVec3::new(p.offset.0, p.offset.1, p.offset.2) * len;
        let mut layers: Vec<BuiltLayer> = Vec::new();
        let mut index = HashMap::new();
        for (li, l) in p.layers.iter().enumerate() {
            let lat = format!("{at}.layers[{li}] (\"{}\")", l.name);
            if let Some(prev) = index.insert(l.name.clone(), li) {
                return Err(self.err(format!("{lat}.name"), format!("also the name of layers[{prev}]")));
            }
            // KCK18 section 3: a skin under anchors is Stable Neo-Hookean unless stated.
            let mut l = l.clone();
            if let (Some(a), Some(m)) = (&p.anchors, &mut l.material) {
                if a.skin == l.name {
                    m.model.get_or_insert(crate::physics::ConstitutiveModel::StableNeoHookean);
                }
            }
            layers.push(self.layer(&lat, &l, len, stress, offset, &layers, &index)?);
        }
        self.check_interfaces(&at, p, &layers)?;
        let find = |field: String, name: &str| -> Result<usize, SceneError> {
            index.get(name).copied().ok_or_else(|| self.err(field, format!("no layer named \"{name}\" in this patch")))
        };
        let mut drivers = Vec::new();
        for (di, d) in p.drivers.iter().enumerate() {
            let dat = format!("{at}.drivers[{di}]");
            let keyframes_ok = |k: &Vec<(u32, f64)>, what: &str| -> Result<(), SceneError> {
                if k.is_empty() {
                    return Err(self.err(format!("{dat}.keyframes"), "needs at least one keyframe"));
                }
                for (i, w) in k.windows(2).enumerate() {
                    if w[1].0 <= w[0].0 {
                        return Err(self.err(
                            format!("{dat}.keyframes[{}]", i + 1),
                            format!("keyframes out of order: frame {} comes after frame {}", w[1].0, w[0].0),
                        ));
                    }
                }
                if let Some((i, _)) = k.iter().enumerate().find(|(_, kv)| !kv.1.is_finite()) {
                    return Err(self.err(format!("{dat}.keyframes[{i}]"), format!("{what} must be finite")));
                }
                Ok(())
            };
            drivers.push(match d {
                DriverSpec::Pin { layer, select, dofs } => {
                    let li = find(format!("{dat}.layer"), layer)?;
                    let vertices = select_vertices(layers[li].mesh.rest(), select, len, offset);
                    if vertices.is_empty() {
                        return Err(self.err(format!("{dat}.select"), "selects no vertex"));
                    }
                    BuiltDriver::Pin { layer: li, vertices, dofs: [dofs.x, dofs.y, dofs.z] }
                }
                DriverSpec::Compress { layers: ls, axis, keyframes, predict } => {
                    keyframes_ok(keyframes, "strain")?;
                    if let Some((i, _)) = keyframes.iter().enumerate().find(|(_, k)| k.1 >= 1.0) {
                        return Err(
                            self.err(format!("{dat}.keyframes[{i}]"), "a strain of 1 or more collapses the patch")
                        );
                    }
                    let layers = ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                    BuiltDriver::Compress {
                        layers,
                        axis: axis.index(),
                        keyframes: keyframes.clone(),
                        predict: *predict,
                    }
                }
                DriverSpec::Bend { layers: ls, axis, keyframes } => {
                    keyframes_ok(keyframes, "curvature")?;
                    if *axis == Axis::Z {
                        return Err(self.err(format!("{dat}.axis"), "the cylinder axis must lie in the plane (X or Y)"));
                    }
                    let layers = ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                    let keyframes = keyframes.iter().map(|&(f, k)| (f, k / len)).collect();
                    BuiltDriver::Bend { layers, axis: axis.index(), keyframes }
                }
                DriverSpec::PlaneStrain { layers: ls, axis } => {
                    let layers_i: Vec<usize> =
                        ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                    let ties =
                        layers_i.iter().map(|&li| plane_strain_ties(layers[li].mesh.rest(), axis.index())).collect();
                    BuiltDriver::PlaneStrain { layers: layers_i, axis: axis.index(), ties }
                }
                DriverSpec::Periodic { layers: ls, axis } => {
                    let layers_i: Vec<usize> =
                        ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                    let ties: Vec<Vec<(u32, u32)>> =
                        layers_i.iter().map(|&li| periodic_ties(layers[li].mesh.rest(), axis.index())).collect();
                    if ties.iter().all(|t| t.is_empty()) {
                        return Err(
                            self.err(format!("{dat}.layers"), "no vertex on the max side matches one on the min side")
                        );
                    }
                    if let Some(&li) = layers_i.iter().find(|&&li| quadratic(&layers[li])) {
                        return Err(self.err(
                            format!("{dat}.layers"),
                            format!("\"{}\" bends with the quadratic element, which does not cross a periodic seam (use element: Hinge)", layers[li].name),
                        ));
                    }
                    let seams = layers_i
                        .iter()
                        .map(|&li| match (&layers[li].mesh, layers[li].kind) {
                            (LayerMesh::Surface(m), LayerKind::Shell) => periodic_seams(m, axis.index()),
                            _ => Vec::new(),
                        })
                        .collect();
                    BuiltDriver::Periodic { layers: layers_i, axis: axis.index(), ties, seams }
                }
                DriverSpec::Capture { layers: ls, frame, fraction, map } => {
                    if !(*fraction >= 0.0 && *fraction <= 1.0) {
                        return Err(self.err(format!("{dat}.fraction"), format!("must be in [0, 1] (got {fraction})")));
                    }
                    if *frame == 0 || *frame > scene.frames {
                        return Err(self.err(
                            format!("{dat}.frame"),
                            format!("must be a computed frame, 1 to {} (got {frame})", scene.frames),
                        ));
                    }
                    let layers_i: Vec<usize> =
                        ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                    if let Some(&li) = layers_i.iter().find(|&&li| layers[li].kind == LayerKind::Kinematic) {
                        return Err(self.err(
                            format!("{dat}.layers"),
                            format!("\"{}\" is kinematic: it has no rest state to capture", layers[li].name),
                        ));
                    }
                    if let Some(&li) = layers_i.iter().find(|&&li| quadratic(&layers[li])) {
                        return Err(self.err(
                            format!("{dat}.layers"),
                            format!("\"{}\" bends with the quadratic element, which has no rest curvature to capture into", layers[li].name),
                        ));
                    }
                    if let Some(&li) = layers_i.iter().find(|&&li| layers[li].remesh.is_some()) {
                        return Err(self.err(
                            format!("{dat}.layers"),
                            format!(
                                "\"{}\" is remeshed: a captured rest state is per element and is not carried \
                                 across a remesh",
                                layers[li].name
                            ),
                        ));
                    }
                    let maps = layers_i
                        .iter()
                        .map(|&li| map.as_ref().map(|m| self.weight_map(&format!("{dat}.map"), m, &layers[li].mesh)))
                        .map(Option::transpose)
                        .collect::<Result<_, _>>()?;
                    BuiltDriver::Capture { layers: layers_i, frame: *frame, fraction: *fraction, maps }
                }
                DriverSpec::BlendShape { layer, targets, interpolation, range } => {
                    let li = find(format!("{dat}.layer"), layer)?;
                    let targets = self.blend_targets(&dat, targets, *range, &layers[li].mesh, len, offset)?;
                    BuiltDriver::BlendShape { layer: li, targets, interpolation: *interpolation }
                }
                DriverSpec::Articulate { layer, pose, weights, interpolation } => {
                    let li = find(format!("{dat}.layer"), layer)?;
                    let frames =
                        self.articulate(&dat, pose, weights, *interpolation, &layers[li], len, scene.frames)?;
                    BuiltDriver::Sequence { layer: li, frames, start: 0 }
                }
                DriverSpec::ObjSequence { layer, files, start } => {
                    let li = find(format!("{dat}.layer"), layer)?;
                    let frames = self.obj_sequence(&dat, files, &layers[li], len, offset)?;
                    BuiltDriver::Sequence { layer: li, frames, start: *start }
                }
                DriverSpec::Attach { layer, to, stiffness } => {
                    let a = find(format!("{dat}.layer"), layer)?;
                    let b = find(format!("{dat}.to"), to)?;
                    if !(*stiffness > 0.0 && stiffness.is_finite()) {
                        return Err(self.err(format!("{dat}.stiffness"), format!("must be > 0 (got {stiffness})")));
                    }
                    let springs = self.pair_layers(&dat, &layers[a], &layers[b], stiffness * stress / len)?;
                    BuiltDriver::Attach { layer: a, to: b, springs }
                }
            });
        }
        let couplings = p
            .couplings
            .iter()
            .enumerate()
            .map(|(ci, c)| self.coupling(&format!("{at}.couplings[{ci}]"), c, &layers, &index, len, stress))
            .collect::<Result<_, _>>()?;
        let anchors =
            p.anchors.as_ref().map(|a| self.anchors(&format!("{at}.anchors"), a, &layers, &index, len, stress));
        let anchors = anchors.transpose()?;
        Ok(BuiltPatch { name: p.name.clone(), solver, perturbation, layers, drivers, couplings, anchors })
    }

    /// Validates a coupling and clusters its kernels (LK14 4.1) on a fine grid of the upper
    /// layer's material rectangle, 10 grid cells per smallest wavelength.
    fn coupling(
        &self,
        at: &str,
        c: &CouplingSpec,
        layers: &[BuiltLayer],
        index: &HashMap<String, usize>,
        len: f64,
        stress: f64,
    ) -> Result<BuiltCoupling, SceneError> {
        let find = |field: &str, name: &str| {
            index
                .get(name)
                .copied()
                .ok_or_else(|| self.err(format!("{at}.{field}"), format!("no layer named \"{name}\"")))
        };
        let (ui, li) = (find("upper", &c.upper)?, find("lower", &c.lower)?);
        let (upper, lower) = (&layers[ui], &layers[li]);
        if upper.kind != LayerKind::Shell {
            return Err(self.err(format!("{at}.upper"), format!("\"{}\" is not a shell layer", upper.name)));
        }
        if ui == li {
            return Err(self.err(format!("{at}.lower"), "a layer cannot be coupled to itself"));
        }
        let LayerMesh::Surface(lower_mesh) = &lower.mesh else {
            return Err(
                self.err(format!("{at}.lower"), format!("\"{}\" is a volume: kernels need a surface", lower.name))
            );
        };
        let LayerMesh::Surface(upper_mesh) = &upper.mesh else { unreachable!("shells are surfaces") };
        let positive = |field: &str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(v)
            } else {
                Err(self.err(format!("{at}.wavelength.{field}"), format!("must be > 0 (got {v})")))
            }
        };
        let upper_e = upper.material.map_or(0.0, |m| m.young);
        let upper_h = upper.thickness.unwrap_or(0.0);
        let lambda = match &c.wavelength {
            WavelengthSpec::Constant(l) => positive("0", *l)? * len,
            WavelengthSpec::Eq31 { constant, lower: given } => {
                let (e, h) = match (given, lower.material, lower.thickness) {
                    (Some((e, h)), ..) => (positive("lower.0", *e)? * stress, positive("lower.1", *h)? * len),
                    (None, Some(m), Some(h)) => (m.young, h),
                    _ => {
                        return Err(self.err(
                            format!("{at}.wavelength.lower"),
                            format!("\"{}\" has no shell material: state (young, thickness)", lower.name),
                        ))
                    }
                };
                crate::coupling::kernels::wavelength_two_layer(positive("constant", *constant)?, upper_h, h, upper_e, e)
            }
            WavelengthSpec::Film { substrate: (e, nu) } => {
                let e = positive("substrate.0", *e)? * stress;
                if !(*nu > -1.0 && *nu < 0.5) {
                    return Err(
                        self.err(format!("{at}.wavelength.substrate.1"), format!("must be in (-1, 0.5) (got {nu})"))
                    );
                }
                let nu_f = upper.material.map_or(0.0, |m| m.poisson);
                crate::coupling::kernels::wavelength_film(upper_h, upper_e / (1.0 - nu_f * nu_f), e / (1.0 - nu * nu))
            }
        };
        // The upper layer's property map: red scales the wavelength; green and blue scale it
        // through the formula's powers of E and h (eq. 3.1: E^1/6 h^1/2; film: E^1/3 h).
        let (e_power, h_power) = match &c.wavelength {
            WavelengthSpec::Constant(_) => (0.0, 0.0),
            WavelengthSpec::Eq31 { .. } => (1.0 / 6.0, 0.5),
            WavelengthSpec::Film { .. } => (1.0 / 3.0, 1.0),
        };
        let local = |uv: DVec2| {
            let f = crate::model::factors_at(upper.properties.as_ref(), uv);
            lambda * f.wavelength * f.young.powf(e_power) * f.thickness.powf(h_power)
        };
        let (lo, hi) = mesh::bounds(&upper_mesh.uv);
        let (lambda_min, lambda_max) = upper_mesh
            .uv
            .iter()
            .map(|u| local(*u))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), l| (a.min(l), b.max(l)));
        // Refused: a wavelength the patch cannot hold, or supports too small to hold a vertex.
        let extent = (hi - lo).max_element();
        if lambda_max > extent {
            return Err(self.err(
                format!("{at}.wavelength"),
                format!("the wavelength {:.4} m is larger than the patch ({:.4} m)", lambda_max, extent),
            ));
        }
        for (name, m) in [(&upper.name, upper_mesh), (&lower.name, lower_mesh)] {
            let spacing = mean_edge(m);
            if 0.5 * lambda_min < spacing {
                return Err(self.err(
                    format!("{at}.wavelength"),
                    format!(
                        "the kernel radius (half the wavelength, {:.3e} m) is below the mesh spacing of \"{name}\" \
                         ({spacing:.3e} m): refine the mesh or raise the wavelength",
                        0.5 * lambda_min
                    ),
                ));
            }
        }
        let cell = DVec2::new(lambda_min / 10.0, lambda_min / 10.0 * 0.75f64.sqrt());
        let cells = ((hi - lo) / cell).ceil().max(DVec2::ONE);
        let fine =
            crate::mesh::grid(hi - lo, (cells.x as u32, cells.y as u32), crate::mesh::GridPattern::Equilateral, 0.0);
        let points: Vec<DVec2> = fine.uv.iter().map(|u| *u + lo).collect();
        let layout = crate::coupling::kernels::KERNEL_SCALE;
        let wavelength: Vec<f64> = points.iter().map(|p| layout * local(*p)).collect();
        let kernels = crate::coupling::kernels::build_kernels(&points, &fine.faces, &wavelength, c.seed);
        Ok(BuiltCoupling { upper: ui, lower: li, kernels, adjust: c.adjust })
    }

    #[allow(clippy::too_many_arguments)]
    fn layer(
        &self,
        at: &str,
        l: &LayerSpec,
        len: f64,
        stress: f64,
        offset: DVec3,
        earlier: &[BuiltLayer],
        index: &HashMap<String, usize>,
    ) -> Result<BuiltLayer, SceneError> {
        let (mesh, shared, slab) = self.mesh(at, l, len, offset, earlier, index)?;
        let needs_material = l.kind != LayerKind::Kinematic;
        let (mut material, mut thickness) = (None, None);
        match (&l.material, needs_material) {
            (None, true) => {
                return Err(self.err(format!("{at}.material"), format!("a {:?} layer needs a material", l.kind)))
            }
            (Some(spec), true) => {
                let m = self.resolve_material(&format!("{at}.material"), spec, len, stress)?;
                if !(m.young > 0.0 && m.young.is_finite()) {
                    return Err(self.err(
                        format!("{at}.material.young"),
                        format!("Young's modulus must be > 0 (got {})", m.young),
                    ));
                }
                if !(m.poisson > -1.0 && m.poisson < 0.5) {
                    return Err(self.err(
                        format!("{at}.material.poisson"),
                        format!("Poisson's ratio must be in (-1, 0.5) (got {})", m.poisson),
                    ));
                }
                if !(m.density > 0.0 && m.density.is_finite()) {
                    return Err(
                        self.err(format!("{at}.material.density"), format!("must be > 0 kg/m^3 (got {})", m.density))
                    );
                }
                let young = m.young * stress;
                let lame = match l.kind {
                    LayerKind::Shell => Lame::plane_stress(young, m.poisson),
                    _ => Lame::solid(young, m.poisson),
                };
                material = Some(crate::model::Material {
                    model: m.model,
                    young,
                    poisson: m.poisson,
                    density: m.density,
                    lame,
                });
                match (l.kind, m.thickness) {
                    (LayerKind::Shell, None) => {
                        return Err(self.err(format!("{at}.material.thickness"), "a shell needs a thickness"))
                    }
                    (LayerKind::Shell, Some(h)) if !(h > 0.0 && h.is_finite()) => {
                        return Err(self.err(format!("{at}.material.thickness"), format!("must be > 0 (got {h})")))
                    }
                    (LayerKind::Shell, Some(h)) => thickness = Some(h * len),
                    (_, Some(_)) => {
                        return Err(self.err(format!("{at}.material.thickness"), "only shells have a thickness"))
                    }
                    _ => {}
                }
            }
            (Some(_), false) => return Err(self.err(format!("{at}.material"), "a kinematic layer has no material")),
            (None, false) => {}
        }
        let bending = match (&l.bending, l.kind) {
            (None, _) => None,
            (Some(b), LayerKind::Shell) => {
                if !(b.scale > 0.0 && b.scale.is_finite()) {
                    return Err(self.err(format!("{at}.bending.scale"), format!("must be > 0 (got {})", b.scale)));
                }
                let m = material.unwrap();
                let h = thickness.unwrap();
                let d = m.young * h.powi(3) / (12.0 * (1.0 - m.poisson * m.poisson));
                Some(crate::model::Bending { model: b.model, element: b.element, stiffness: b.scale * d / 6.0 })
            }
            (Some(_), kind) => {
                return Err(self.err(format!("{at}.bending"), format!("only shells bend ({kind:?} layer)")))
            }
        };
        let prestrain = match &l.prestrain {
            None => None,
            Some(_) if l.kind == LayerKind::Kinematic => {
                return Err(self.err(format!("{at}.prestrain"), "a kinematic layer has no rest state to prestrain"))
            }
            Some(p) => Some(self.prestrain(&format!("{at}.prestrain"), p, l.kind, bending.is_some(), len, &mesh)?),
        };
        if bending.is_some_and(|b| b.element == BendingElement::Quadratic) {
            self.quadratic_bending_ok(at, &mesh, prestrain.as_ref(), len)?;
        }
        let randomize = match &l.randomize {
            None => None,
            Some(_) if l.kind == LayerKind::Kinematic => {
                return Err(self.err(format!("{at}.randomize"), "a kinematic layer has no material to randomize"))
            }
            Some(r) if !(r.amplitude >= 0.0 && r.amplitude < 1.0) => {
                return Err(self.err(
                    format!("{at}.randomize.amplitude"),
                    format!(
                        "E (1 + amplitude u) with u in [-1, 1] must stay positive: the amplitude must be in [0, 1) \
                         (got {}, which makes the Young's modulus of \"{}\" reach {:.4})",
                        r.amplitude,
                        l.name,
                        material.map_or(0.0, |m| m.young / stress) * (1.0 - r.amplitude)
                    ),
                ))
            }
            Some(r) => Some((r.amplitude, r.seed)),
        };
        let properties = match (&l.properties, l.kind) {
            (None, _) => None,
            (Some(p), LayerKind::Shell) => Some(self.properties(&format!("{at}.properties"), p, &mesh)?),
            (Some(_), kind) => {
                return Err(
                    self.err(format!("{at}.properties"), format!("property maps are for shells ({kind:?} layer)"))
                )
            }
        };
        let remesh = match &l.remesh {
            None => None,
            Some(r) => Some(self.remesh(&format!("{at}.remesh"), r, l, len, &mesh, &shared)?),
        };
        Ok(BuiltLayer {
            name: l.name.clone(),
            kind: l.kind,
            remesh,
            mesh,
            shared,
            slab,
            material,
            thickness,
            bending,
            prestrain,
            randomize,
            properties,
        })
    }

    /// Remeshing of a shell with a usable material space: thresholds in SI units, checked.
    fn remesh(
        &self,
        at: &str,
        r: &RemeshSpec,
        l: &LayerSpec,
        len: f64,
        mesh: &LayerMesh,
        shared: &[Option<(usize, u32)>],
    ) -> Result<crate::model::RemeshSettings, SceneError> {
        if l.kind != LayerKind::Shell {
            return Err(self.err(at.to_string(), format!("remeshing is for shell layers ({:?} layer)", l.kind)));
        }
        let unsupported = [
            (l.randomize.is_some(), "randomize"),
            (shared.iter().any(|s| s.is_some()), "vertices shared with another layer"),
        ];
        if let Some((_, what)) = unsupported.iter().find(|u| u.0) {
            return Err(self.err(at.to_string(), format!("remeshing a layer with {what} is not supported")));
        }
        // Remeshing works in material space: every face needs a positive material area.
        if let LayerMesh::Surface(m) = mesh {
            let flat = m.faces.iter().position(|f| {
                let u = f.map(|i| m.uv[i as usize]);
                (u[1] - u[0]).perp_dot(u[2] - u[0]) <= 0.0
            });
            if let Some(face) = flat {
                return Err(self.err(
                    at.to_string(),
                    format!("the layer has no usable material space (face {face} has no positive material area)"),
                ));
            }
        }
        if r.every == 0 {
            return Err(self.err(format!("{at}.every"), "must be at least 1"));
        }
        // Checked in the scene's units (the messages quote the file's values), then converted.
        let stated = crate::mesh::remesh::RemeshParams {
            size_min: r.size_min,
            size_max: r.size_max,
            aspect_min: r.aspect_min,
            refine_angle: r.refine_angle,
            refine_compression: r.refine_compression,
            refine_velocity: r.refine_velocity,
            curved_splits: r.curved_splits,
        };
        stated.check().map_err(|(field, message)| self.err(format!("{at}.{field}"), message))?;
        let params = crate::mesh::remesh::RemeshParams {
            size_min: r.size_min * len,
            size_max: r.size_max * len,
            refine_compression: r.refine_compression * len,
            refine_velocity: r.refine_velocity.map(|v| v * len),
            ..stated
        };
        Ok(crate::model::RemeshSettings { params, every: r.every, settle: r.settle })
    }

    /// A material with its preset's values filled in where the scene states none (in the
    /// scene's units).
    fn resolve_material(&self, at: &str, m: &MaterialSpec, len: f64, stress: f64) -> Result<Resolved, SceneError> {
        let preset = m.preset.map(|p| {
            let (e, nu, h) = p.si();
            (e / stress, nu, h / len)
        });
        let young = m.young.or(preset.map(|p| p.0));
        let poisson = m.poisson.or(preset.map(|p| p.1));
        let (Some(young), Some(poisson)) = (young, poisson) else {
            let missing = if young.is_none() { "young" } else { "poisson" };
            return Err(self.err(format!("{at}.{missing}"), "state it, or name a preset"));
        };
        let thickness = m.thickness.or(preset.map(|p| p.2));
        Ok(Resolved { model: m.model.unwrap_or_default(), young, poisson, density: m.density, thickness })
    }

    /// The quadratic bending element measures curvature from a flat rest state.
    fn quadratic_bending_ok(
        &self,
        at: &str,
        mesh: &LayerMesh,
        prestrain: Option<&crate::model::LayerPrestrain>,
        len: f64,
    ) -> Result<(), SceneError> {
        let flat_rest = "the quadratic bending element needs a flat rest state (use element: Hinge)";
        if prestrain.is_some_and(|p| p.curvature != 0.0) {
            return Err(self.err(format!("{at}.prestrain.curvature"), flat_rest));
        }
        if let LayerMesh::Surface(m) = mesh {
            let p = &m.rest;
            let normal = m
                .faces
                .iter()
                .map(|f| (p[f[1] as usize] - p[f[0] as usize]).cross(p[f[2] as usize] - p[f[0] as usize]))
                .fold(DVec3::ZERO, |a, n| a + n)
                .normalize_or_zero();
            let off = p.iter().map(|q| (*q - p[0]).dot(normal).abs()).fold(0.0, f64::max);
            if normal == DVec3::ZERO || off > 1e-6 * len {
                return Err(self
                    .err(format!("{at}.mesh"), format!("{flat_rest}: the rest mesh leaves its plane by {off:.3e} m")));
            }
        }
        Ok(())
    }

    fn prestrain(
        &self,
        at: &str,
        p: &PrestrainSpec,
        kind: LayerKind,
        bends: bool,
        len: f64,
        mesh: &LayerMesh,
    ) -> Result<crate::model::LayerPrestrain, SceneError> {
        let stretch = DVec3::new(p.stretch.0, p.stretch.1, p.stretch.2);
        let det = stretch.x * stretch.y * if kind == LayerKind::Shell { 1.0 } else { stretch.z };
        if !stretch.is_finite() || stretch.min_element() <= 0.0 {
            return Err(self.err(
                format!("{at}.stretch"),
                format!(
                    "F0 = diag{:?} has determinant {det}: a prestrain must keep every stretch (and volume) positive",
                    p.stretch
                ),
            ));
        }
        if !p.curvature.is_finite() {
            return Err(self.err(format!("{at}.curvature"), "must be finite"));
        }
        if p.curvature != 0.0 && !(kind == LayerKind::Shell && bends) {
            return Err(self.err(format!("{at}.curvature"), "a rest curvature needs a shell layer with bending"));
        }
        if p.curvature_along == Axis::Z {
            return Err(self.err(format!("{at}.curvature_along"), "the curvature runs along X or Y"));
        }
        let map = p.map.as_ref().map(|m| self.weight_map(&format!("{at}.map"), m, mesh)).transpose()?;
        Ok(crate::model::LayerPrestrain {
            stretch,
            map,
            curvature: p.curvature / len,
            along: p.curvature_along.index(),
        })
    }

    /// Volume layers that touch (one's bottom on another's top) must share their interface
    /// vertices (TetOn): two unconnected slabs would slide through each other.
    fn check_interfaces(&self, at: &str, p: &PatchSpec, layers: &[BuiltLayer]) -> Result<(), SceneError> {
        let volumes: Vec<(usize, DVec3, DVec3)> = layers
            .iter()
            .enumerate()
            .filter(|(_, l)| l.kind == LayerKind::Volume)
            .map(|(i, l)| {
                let (lo, hi) = mesh::bounds(l.mesh.rest());
                (i, lo, hi)
            })
            .collect();
        for &(b, blo, bhi) in &volumes {
            for &(a, alo, ahi) in volumes.iter().filter(|v| v.0 < b) {
                let tol = 1e-9 * (bhi - blo).length().max((ahi - alo).length());
                let overlap = (bhi.x.min(ahi.x) - blo.x.max(alo.x)).min(bhi.y.min(ahi.y) - blo.y.max(alo.y));
                let touch = (blo.z - ahi.z).abs() <= tol || (bhi.z - alo.z).abs() <= tol;
                let shares = layers[b].shared.iter().flatten().any(|s| s.0 == a)
                    || layers[a].shared.iter().flatten().any(|s| s.0 == b);
                if touch && overlap > tol && !shares {
                    let (na, nb) = (&layers[a].name, &layers[b].name);
                    let cells = |i: usize| layers[i].slab.map(|s| format!("{:?} cells", s.cells)).unwrap_or_default();
                    return Err(self.err(
                        format!("{at}.layers[{b}] (\"{}\").mesh", p.layers[b].name),
                        format!(
                            "the interface between \"{nb}\" ({}) and \"{na}\" ({}) does not match: the two \
                             volumes touch at z = {:.6} m without sharing vertices; stack \"{nb}\" with \
                             TetOn(layer: \"{na}\", ...) so that they share the interface",
                            cells(b),
                            cells(a),
                            if (blo.z - ahi.z).abs() <= tol { blo.z } else { bhi.z },
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Loads a greyscale map (relative to the scene file) spanning the mesh's material rectangle.
    fn weight_map(&self, field: &str, path: &str, mesh: &LayerMesh) -> Result<WeightMap, SceneError> {
        let full = self.dir.join(path);
        let img = image::open(&full)
            .map_err(|e| SceneError::at_field(&full, field, format!("cannot read the map image: {e}")))?
            .to_luma16();
        let (width, height) = (img.width() as usize, img.height() as usize);
        let values = img.pixels().map(|p| p.0[0] as f32 / 65535.0).collect();
        let uv = mesh.material_positions();
        let (lo, hi) = mesh::bounds(&uv);
        Ok(WeightMap { width, height, values, lo, hi })
    }

    #[allow(clippy::type_complexity)]
    fn mesh(
        &self,
        at: &str,
        l: &LayerSpec,
        len: f64,
        offset: DVec3,
        earlier: &[BuiltLayer],
        index: &HashMap<String, usize>,
    ) -> Result<(LayerMesh, Vec<Option<(usize, u32)>>, Option<SlabGrid>), SceneError> {
        let field = format!("{at}.mesh");
        let base_slab = |name: &str| -> Result<(usize, SlabGrid), SceneError> {
            let i = *index.get(name).ok_or_else(|| {
                self.err(
                    format!("{field}.layer"),
                    format!("no earlier layer named \"{name}\" (layers are listed bottom to top)"),
                )
            })?;
            let slab = earlier.get(i).and_then(|b| b.slab).ok_or_else(|| {
                self.err(format!("{field}.layer"), format!("\"{name}\" is not a TetSlab or TetOn volume layer"))
            })?;
            Ok((i, slab))
        };
        let mut shared = Vec::new();
        let mut slab = None;
        let positive = |v: f64, what: &str| -> Result<(), SceneError> {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(self.err(format!("{field}.{what}"), format!("must be > 0 (got {v})")))
            }
        };
        let mut mesh = match &l.mesh {
            MeshSpec::Grid { size, cells, pattern, z } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "a volume layer needs a TetSlab mesh"));
                }
                positive(size.0, "size")?;
                positive(size.1, "size")?;
                if cells.0 == 0 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least one cell in each direction"));
                }
                LayerMesh::Surface(mesh::grid(DVec2::new(size.0, size.1) * len, *cells, *pattern, z * len))
            }
            MeshSpec::TetSlab { size, cells, depth, elements, top, grading } => {
                if l.kind != LayerKind::Volume {
                    return Err(self.err(&field, "a TetSlab mesh belongs to a volume layer"));
                }
                positive(size.0, "size")?;
                positive(size.1, "size")?;
                positive(*depth, "depth")?;
                if cells.0 == 0 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least one cell in each direction"));
                }
                if *elements == 0 {
                    return Err(self.err(format!("{field}.elements"), "zero elements through the thickness"));
                }
                let size = DVec2::new(size.0, size.1) * len;
                positive(*grading, "grading")?;
                let (m, _) = mesh::tet_slab(size, *cells, top * len, &[(depth * len, *elements, *grading)]);
                slab = Some(SlabGrid {
                    size,
                    cells: *cells,
                    origin: offset,
                    top: top * len + offset.z,
                    planes: *elements as usize + 1,
                });
                LayerMesh::Volume(m)
            }
            MeshSpec::Obj { path } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "OBJ meshes are surfaces: use them for shell or kinematic layers"));
                }
                let full = self.dir.join(path);
                if !full.is_file() {
                    return Err(SceneError::at_field(
                        &full,
                        &field,
                        format!("mesh file not found: {}", full.display()),
                    ));
                }
                let m = mesh::obj::load(&full, len).map_err(|e| SceneError::at_field(&full, &field, e))?;
                mesh::check_surface(&m).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
                LayerMesh::Surface(m)
            }
            MeshSpec::TetOn { layer, depth, elements, grading } => {
                if l.kind != LayerKind::Volume {
                    return Err(self.err(&field, "a TetOn mesh belongs to a volume layer"));
                }
                positive(*depth, "depth")?;
                if *elements == 0 {
                    return Err(self.err(format!("{field}.elements"), "zero elements through the thickness"));
                }
                let (bi, base) = base_slab(layer)?;
                let new_top = base.top - base.origin.z + depth * len;
                positive(*grading, "grading")?;
                let (m, _) = mesh::tet_slab(base.size, base.cells, new_top, &[(depth * len, *elements, *grading)]);
                slab = Some(SlabGrid { top: new_top + base.origin.z, planes: *elements as usize + 1, ..base });
                // The bottom plane is the base's top plane.
                let plane = base.plane_len();
                shared = (0..m.rest.len()).map(|v| (v < plane).then(|| (bi, (base.top_offset() + v) as u32))).collect();
                LayerMesh::Volume(m)
            }
            MeshSpec::SurfaceOf { layer } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "SurfaceOf makes a surface: use it for shell or kinematic layers"));
                }
                let (bi, base) = base_slab(layer)?;
                let top_local = base.top - base.origin.z;
                let mut m = mesh::grid(base.size, base.cells, mesh::GridPattern::RightTriangle, top_local);
                // The slab's prisms split each cell along the same diagonal as RightTriangle.
                shared = (0..m.rest.len()).map(|v| Some((bi, (base.top_offset() + v) as u32))).collect();
                m.uv.iter_mut().for_each(|u| *u += base.origin.truncate() - offset.truncate());
                LayerMesh::Surface(m)
            }
            MeshSpec::Tube { radius, length, cells } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                positive(*length, "length")?;
                if cells.0 < 3 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least 3 cells around and 1 along"));
                }
                LayerMesh::Surface(mesh::bodies::tube(radius * len, length * len, cells.0, cells.1))
            }
            MeshSpec::Creature { radius, subdivisions } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                if *subdivisions > 7 {
                    return Err(self.err(format!("{field}.subdivisions"), "at most 7 (327,680 triangles)"));
                }
                LayerMesh::Surface(mesh::bodies::creature(radius * len, *subdivisions))
            }
            MeshSpec::Offset { layer, distance } => {
                self.surface_only(&field, l.kind)?;
                if !distance.is_finite() {
                    return Err(self.err(format!("{field}.distance"), "must be finite"));
                }
                let base = index
                    .get(layer)
                    .and_then(|&i| earlier.get(i))
                    .ok_or_else(|| self.err(format!("{field}.layer"), format!("no earlier layer named \"{layer}\"")))?;
                let LayerMesh::Surface(m) = &base.mesh else {
                    return Err(self.err(format!("{field}.layer"), format!("\"{layer}\" is not a surface")));
                };
                let mut m = mesh::bodies::offset(m, distance * len);
                m.rest.iter_mut().for_each(|p| *p -= offset); // the base is already placed
                LayerMesh::Surface(m)
            }
        };
        if shared.is_empty() {
            shared = vec![None; mesh.rest().len()];
        }
        if let LayerMesh::Surface(m) = &mesh {
            mesh::check_surface(m).map_err(|e| self.err(&field, e.to_string()))?;
        }
        match &mut mesh {
            LayerMesh::Surface(m) => m.rest.iter_mut().for_each(|p| *p += offset),
            LayerMesh::Volume(m) => m.rest.iter_mut().for_each(|p| *p += offset),
        }
        // Shared vertices resolve to their owner (a stacked layer's owner may itself share).
        for s in shared.iter_mut().flatten() {
            while let Some(owner) = earlier[s.0].shared[s.1 as usize] {
                *s = owner;
            }
        }
        Ok((mesh, shared, slab))
    }

    fn surface_only(&self, field: &str, kind: LayerKind) -> Result<(), SceneError> {
        if kind == LayerKind::Volume {
            return Err(self.err(field, "this mesh is a surface: use it for shell or kinematic layers"));
        }
        Ok(())
    }

    /// Pairs every vertex of `a` with the vertex of `b` at the same rest position in the plane
    /// (x, y), for attachment springs; stiffness per vertex = k_area x vertex area of `a`.
    fn pair_layers(
        &self,
        at: &str,
        a: &BuiltLayer,
        b: &BuiltLayer,
        k_area: f64,
    ) -> Result<Vec<(u32, u32, f64)>, SceneError> {
        // The attached vertices and their faces: a surface's own, or a solid's bottom faces.
        let ra = a.mesh.rest();
        let (faces, attached): (Vec<[u32; 3]>, Vec<bool>) = match &a.mesh {
            LayerMesh::Surface(m) => (m.faces.clone(), vec![true; ra.len()]),
            LayerMesh::Volume(m) => {
                let zmin = ra.iter().fold(f64::INFINITY, |z, p| z.min(p.z));
                let tol = 1e-9 * mesh::bounds::diagonal(ra).max(1e-300);
                let bottom: Vec<bool> = ra.iter().map(|p| p.z <= zmin + tol).collect();
                let faces = mesh::surface_of_tets(&m.tets)
                    .into_iter()
                    .filter(|f| f.iter().all(|&v| bottom[v as usize]))
                    .collect();
                (faces, bottom)
            }
        };
        let rb = b.mesh.rest();
        let size = mesh::bounds::diagonal(ra).max(1e-300);
        let tol = 1e-9 * size;
        let key = |p: DVec3| ((p.x / tol).round() as i64, (p.y / tol).round() as i64);
        let mut lookup: HashMap<(i64, i64), u32> = HashMap::new();
        // Several vertices of b may share (x, y) (a slab): keep the topmost.
        for (i, p) in rb.iter().enumerate() {
            let e = lookup.entry(key(*p)).or_insert(i as u32);
            if rb[*e as usize].z < p.z {
                *e = i as u32;
            }
        }
        let mut area = vec![0.0; ra.len()];
        for f in &faces {
            let p = |i: usize| ra[f[i] as usize];
            let ar = 0.5 * (p(1) - p(0)).cross(p(2) - p(0)).length();
            for &v in f {
                area[v as usize] += ar / 3.0;
            }
        }
        let mut out = Vec::with_capacity(ra.len());
        for (i, p) in ra.iter().enumerate().filter(|(i, _)| attached[*i]) {
            let j = lookup.get(&key(*p)).copied().ok_or_else(|| {
                self.err(
                    format!("{at}.to"),
                    format!("vertex {i} of \"{}\" has no vertex of \"{}\" at the same (x, y)", a.name, b.name),
                )
            })?;
            out.push((i as u32, j, k_area * area[i]));
        }
        Ok(out)
    }
}

/// Vertices that differ only along `axis` form a group; each is tied to the group's first.
fn plane_strain_ties(rest: &[DVec3], axis: usize) -> Vec<(u32, u32)> {
    let tol = 1e-9 * mesh::bounds::diagonal(rest).max(1e-300);
    let (a, b) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let key = |p: &DVec3| ((p[a] / tol).round() as i64, (p[b] / tol).round() as i64);
    let mut first: HashMap<(i64, i64), u32> = HashMap::new();
    let mut ties = Vec::new();
    for (i, p) in rest.iter().enumerate() {
        match first.get(&key(p)) {
            Some(&m) => ties.push((i as u32, m)),
            None => {
                first.insert(key(p), i as u32);
            }
        }
    }
    ties
}

/// Whether a layer bends with the quadratic element (flat rest only).
fn quadratic(layer: &BuiltLayer) -> bool {
    layer.bending.is_some_and(|b| b.element == BendingElement::Quadratic)
}

/// Pairs each vertex on the max side along `axis` with the min-side vertex at the same other
/// coordinates.
fn periodic_ties(rest: &[DVec3], axis: usize) -> Vec<(u32, u32)> {
    let (lo, hi) = mesh::bounds(rest);
    let tol = 1e-9 * (hi - lo).length().max(1e-300);
    let key = |p: &DVec3| {
        let mut q = *p;
        q[axis] = 0.0;
        ((q.x / tol).round() as i64, (q.y / tol).round() as i64, (q.z / tol).round() as i64)
    };
    let min_side: HashMap<_, u32> =
        rest.iter().enumerate().filter(|(_, p)| p[axis] <= lo[axis] + tol).map(|(i, p)| (key(p), i as u32)).collect();
    rest.iter()
        .enumerate()
        .filter(|(_, p)| p[axis] >= hi[axis] - tol)
        .filter_map(|(i, p)| min_side.get(&key(p)).map(|&m| (i as u32, m)))
        .collect()
}

/// Hinges joining a shell's boundary edges on the max side to the matching ones on the min side.
fn periodic_seams(m: &SurfaceMesh, axis: usize) -> Vec<SeamHinge> {
    let (lo, hi) = mesh::bounds(&m.rest);
    let tol = 1e-9 * (hi - lo).length().max(1e-300);
    let key = |v: u32| {
        let mut q = m.rest[v as usize];
        q[axis] = 0.0;
        ((q.x / tol).round() as i64, (q.y / tol).round() as i64, (q.z / tol).round() as i64)
    };
    let on = |v: u32, side: f64| (m.rest[v as usize][axis] - side).abs() <= tol;
    let boundary: Vec<_> = mesh::edges(&m.faces).into_iter().filter(|e| !e.is_interior()).collect();
    let min_side: HashMap<_, (u32, u32, u32)> = boundary
        .iter()
        .filter(|e| on(e.v[0], lo[axis]) && on(e.v[1], lo[axis]))
        .map(|e| ((key(e.v[0]), key(e.v[1])), (e.v[0], e.v[1], e.opposite[0])))
        .collect();
    let mut out = Vec::new();
    for e in boundary.iter().filter(|e| on(e.v[0], hi[axis]) && on(e.v[1], hi[axis])) {
        let (a, b) = (e.v[0], e.v[1]);
        // The matching min-side edge runs the other way in its face.
        let found = min_side
            .get(&(key(b), key(a)))
            .map(|&(_, a0, o)| (a0, o))
            .or_else(|| min_side.get(&(key(a), key(b))).map(|&(a0, _, o)| (a0, o)));
        if let Some((a0, o2)) = found {
            out.push(SeamHinge { v: [a, b, e.opposite[0], o2], image: (a, a0) });
        }
    }
    out
}

/// Mean edge length of a surface mesh in material space.
fn mean_edge(m: &SurfaceMesh) -> f64 {
    let total: f64 = m
        .faces
        .iter()
        .map(|f| (0..3).map(|k| (m.uv[f[k] as usize] - m.uv[f[(k + 1) % 3] as usize]).length()).sum::<f64>())
        .sum();
    total / (3 * m.faces.len()).max(1) as f64
}


fn select_vertices(rest: &[DVec3], select: &Select, len: f64, offset: DVec3) -> Vec<u32> {
    let (lo, hi) = mesh::bounds(rest);
    let tol = 1e-9 * (hi - lo).length();
    rest.iter()
        .enumerate()
        .filter(|(_, p)| match select {
            Select::All => true,
            Select::Sides(sides) => sides.iter().any(|s| match s {
                Side::XMin => p.x <= lo.x + tol,
                Side::XMax => p.x >= hi.x - tol,
                Side::YMin => p.y <= lo.y + tol,
                Side::YMax => p.y >= hi.y - tol,
                Side::ZMin => p.z <= lo.z + tol,
                Side::ZMax => p.z >= hi.z - tol,
            }),
            Select::Box { min, max } => {
                let (a, b) =
                    (DVec3::new(min.0, min.1, min.2) * len + offset, DVec3::new(max.0, max.1, max.2) * len + offset);
                p.cmpge(a - tol).all() && p.cmple(b + tol).all()
            }
        })
        .map(|(i, _)| i as u32)
        .collect()
}
