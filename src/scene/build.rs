//! Reading, validating and building a scene: everything `skinsim check` verifies. The parts of a
//! patch are built in `meshes`, `layers`, `drivers`, `couplings` and `anchors`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::built::{BuiltLayer, BuiltPatch, BuiltScene};
use super::drivers::PatchContext;
use super::error::SceneError;
use super::schema::*;

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
        let cx = PatchContext { scene, layers: &layers, index: &index, len, stress, offset };
        let drivers = p
            .drivers
            .iter()
            .enumerate()
            .map(|(di, d)| self.driver(&format!("{at}.drivers[{di}]"), d, &cx))
            .collect::<Result<Vec<_>, _>>()?;
        let couplings = p
            .couplings
            .iter()
            .enumerate()
            .map(|(ci, c)| self.coupling(&format!("{at}.couplings[{ci}]"), c, &cx))
            .collect::<Result<_, _>>()?;
        let anchors = p.anchors.as_ref().map(|a| self.anchors(&format!("{at}.anchors"), a, &cx)).transpose()?;
        Ok(BuiltPatch { name: p.name.clone(), solver, perturbation, layers, drivers, couplings, anchors })
    }
}
