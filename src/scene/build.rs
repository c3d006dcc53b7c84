//! Reading, validating and building a scene: everything `skinsim check` verifies. The parts of a
//! patch are built in `meshes`, `layers`, `drivers`, `couplings` and `anchors`.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::built::{BuiltDriver, BuiltLayer, BuiltPatch, BuiltScene};
use super::context::{Builder, PatchContext};
use super::error::SceneError;
use super::schema::*;

/// The largest scene file read (bytes): a scene is text; anything longer is not one (and a
/// device such as /dev/zero would be read until memory runs out).
pub(crate) const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Reads, validates and builds a scene file.
pub fn load(path: &Path) -> Result<BuiltScene, SceneError> {
    load_within(path, None)
}

/// `load` within a memory budget (bytes) that replaces the scene's own and the machine's
/// (`--budget`).
pub fn load_within(path: &Path, budget: Option<f64>) -> Result<BuiltScene, SceneError> {
    let text = read_text(path, MAX_SCENE_BYTES).map_err(|message| SceneError {
        file: path.to_path_buf(),
        position: None,
        field: None,
        message: format!("cannot read the scene file: {message}"),
    })?;
    load_str_within(&text, path, budget)
}

/// A text file of at most `limit` bytes; errors name what is wrong (a directory, too long, the
/// line of the first byte that is not UTF-8).
pub(crate) fn read_text(path: &Path, limit: u64) -> Result<String, String> {
    use std::io::Read;
    if path.is_dir() {
        return Err("it is a directory".into());
    }
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    if bytes.len() as u64 > limit {
        return Err(format!("longer than {} MiB", limit >> 20));
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = 1 + good.iter().filter(|&&b| b == b'\n').count();
        let column = 1 + good.iter().rev().take_while(|&&b| b != b'\n').count();
        format!("not UTF-8 text (line {line}, column {column})")
    })
}

/// Parses, validates and builds a scene given as text; `path` names it in errors and anchors
/// relative asset paths.
pub fn load_str(text: &str, path: &Path) -> Result<BuiltScene, SceneError> {
    load_str_within(text, path, None)
}

/// `load_str` within a memory budget (bytes; see `load_within`).
pub fn load_str_within(text: &str, path: &Path, budget: Option<f64>) -> Result<BuiltScene, SceneError> {
    // (a byte-order mark, as some Windows editors write)
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let options = ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    let scene: Scene = options.from_str(text).map_err(|e| {
        let (line, col) = (e.span.start.line, e.span.start.col);
        let message = match syntax_hint(text, line, col) {
            Some(hint) => format!("{}: {hint}", e.code),
            None => e.code.to_string(),
        };
        SceneError { file: path.to_path_buf(), position: Some((line, col)), field: None, message }
    })?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let builder = Builder {
        file: path.to_path_buf(),
        dir,
        memory: Default::default(),
        budget: std::cell::Cell::new(budget.map(|b| (b, "the --budget"))),
        notes: Default::default(),
    };
    // Every number bounded (issue 66): NaN and infinities before the build, magnitudes after
    // its own range checks (see `bounds`).
    let unbounded = |found: super::bounds::Unbounded| {
        let (line, col, token, key) = found;
        let key = key.map(|k| format!(" (`{k}`)")).unwrap_or_default();
        let message = format!(
            "`{token}`{key} is not a number a scene can hold: every number must be finite and at most {:e} in size, \
             in any unit (so that it stays finite in SI)",
            super::bounds::MAX_MAGNITUDE
        );
        SceneError { file: path.to_path_buf(), position: Some((line, col)), field: None, message }
    };
    if let Some(found) = super::bounds::non_finite_number(text) {
        return Err(unbounded(found));
    }
    let built = builder.build(scene)?;
    match super::bounds::unbounded_number(text) {
        Some(found) => Err(unbounded(found)),
        None => Ok(built),
    }
}

/// What a bare RON syntax error most likely means, from the text around its 1-based position:
/// a decimal point in a whole number (`frames: 30.0`), or a string left open earlier.
fn syntax_hint(text: &str, line: usize, col: usize) -> Option<String> {
    let offset = text.lines().take(line.saturating_sub(1)).map(|l| l.len() + 1).sum::<usize>() + col.saturating_sub(1);
    let (before, after) = text.split_at_checked(offset)?;
    if after.starts_with('.') && before.ends_with(|c: char| c.is_ascii_digit()) {
        return Some("this field takes a whole number (no decimal point)".into());
    }
    // A string that ends just before the error and spans lines was probably never closed.
    let body = before.strip_suffix('"')?;
    let open = body.rfind('"')?;
    let opened = 1 + before[..open].matches('\n').count();
    (opened < line).then(|| format!("the string opened at line {opened} runs to here: is its closing quote missing?"))
}

/// The perturbation's noise cell (m), at least and at most.
const MIN_CELL: f64 = 1e-9;
const MAX_CELL: f64 = 1e3;
/// The longest simulated time (s): a time written to the outputs stays a finite number.
const MAX_SCENE_TIME: f64 = 1e9;

impl Builder {
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
        if !(0.0..=MAX_SCENE_TIME).contains(&(scene.frame_time * scene.frames as f64)) {
            return Err(self.err(
                "frame_time",
                format!("frames x frame_time must be at most {MAX_SCENE_TIME:e} s (got {:e})", scene.frame_time),
            ));
        }
        self.check_name("name", &scene.name)?;
        if let Some(gb) = scene.memory {
            if !(gb > 0.0 && gb.is_finite()) {
                return Err(self.err("memory", format!("must be a positive number of GB (got {gb})")));
            }
            // (--budget, given, overrides the scene's)
            if self.budget.get().is_none() {
                self.budget.set(Some((gb * 1e9, "the scene's `memory` budget")));
            }
        }
        // Issue 66: a scene too big to run is refused from its declared sizes, before any mesh
        // is made.
        self.preflight(&scene)?;
        // Bodies and patches name output folders side by side: one name each.
        let mut names = HashMap::new();
        let mut bodies = Vec::new();
        for (bi, b) in scene.bodies.iter().enumerate() {
            let field = format!("bodies[{bi}].name");
            self.check_name(&field, &b.name)?;
            if let Some(prev) = names.insert(b.name.clone(), format!("bodies[{bi}]")) {
                return Err(self.err(field, format!("\"{}\" is also the name of {prev}", b.name)));
            }
            bodies.push(self.body(&scene, bi, b)?);
        }
        let mut patches = Vec::new();
        for (pi, p) in scene.patches.iter().enumerate() {
            self.check_name(format!("patches[{pi}].name"), &p.name)?;
            if let Some(prev) = names.insert(p.name.clone(), format!("patches[{pi}]")) {
                return Err(
                    self.err(format!("patches[{pi}].name"), format!("\"{}\" is also the name of {prev}", p.name))
                );
            }
            patches.push(self.patch(&scene, pi, p, &bodies)?);
        }
        for (pi, p) in scene.patches.iter().enumerate() {
            if let Some(c) = &p.contact {
                patches[pi].contact_with = self.contact_with(pi, &c.with, &scene, &patches)?;
                self.start_clearance(pi, &bodies, &mut patches)?;
            }
        }
        let (notes, memory) = (self.notes.take(), self.memory.get());
        Ok(BuiltScene { path: self.file.clone(), scene, bodies, patches, notes, memory })
    }

    /// A shared body: one kinematic layer named as the body, and the drivers that move it.
    fn body(&self, scene: &Scene, bi: usize, b: &BodySpec) -> Result<BuiltPatch, SceneError> {
        let at = format!("bodies[{bi}] (\"{}\")", b.name);
        let (len, stress) = (scene.units.length.to_si(), scene.units.stress.to_si());
        let offset = self.placement(&format!("{at}.offset"), b.offset, len)?;
        let spec = LayerSpec {
            name: b.name.clone(),
            kind: crate::model::LayerKind::Kinematic,
            mesh: b.mesh.clone(),
            material: None,
            bending: None,
            prestrain: None,
            randomize: None,
            properties: None,
            remesh: None,
        };
        let index = HashMap::from([(b.name.clone(), 0)]);
        let layers = vec![self.layer(&at, &spec, len, stress, offset, &[], &index, None)?];
        let cx = PatchContext { scene, layers: &layers, index: &index, len, stress, offset };
        let mut drivers = Vec::new();
        for (di, d) in b.drivers.iter().enumerate() {
            let dat = format!("{at}.drivers[{di}]");
            let built = self.driver(&dat, d, &cx)?;
            if !built.is_motion() {
                return Err(self.err(
                    dat,
                    "a body takes motions only (Rig, Joint, Bend, Compress, BlendShape, Sequence): the rest belongs to \
                     the patches on it",
                ));
            }
            drivers.push(built);
        }
        let body = BuiltPatch {
            name: b.name.clone(),
            body: None,
            solver: Default::default(),
            perturbation: None,
            layers,
            drivers,
            couplings: Vec::new(),
            anchors: None,
            contact: None,
            contact_with: Vec::new(),
        };
        if let Some((_, message)) = super::geometry::geometry_error(&body) {
            return Err(self.err(format!("{at}.mesh"), message));
        }
        Ok(body)
    }

    /// A patch's or body's offset in metres, finite and within the coordinate bound.
    fn placement(&self, field: &str, offset: (f64, f64, f64), len: f64) -> Result<DVec3, SceneError> {
        let placed = DVec3::new(offset.0, offset.1, offset.2) * len;
        // (checked here, not only on the final geometry: a non-finite offset would first make a
        // driver's selection come out empty and be blamed on it)
        if !(0.0..=super::geometry::MAX_COORDINATE).contains(&placed.abs().max_element()) {
            let message = format!(
                "must be finite and within +-{} m of the origin (got {offset:?})",
                super::geometry::MAX_COORDINATE
            );
            return Err(self.err(field, message));
        }
        Ok(placed)
    }

    /// Names become output folders and file names: a safe character set, no path separator,
    /// no `..`, no hidden file.
    fn patch(&self, scene: &Scene, pi: usize, p: &PatchSpec, bodies: &[BuiltPatch]) -> Result<BuiltPatch, SceneError> {
        let at = format!("patches[{pi}] (\"{}\")", p.name);
        let len = scene.units.length.to_si();
        let stress = scene.units.stress.to_si();
        if p.layers.is_empty() {
            return Err(self.err(format!("{at}.layers"), "a patch needs at least one layer"));
        }
        let s = &p.solver;
        if !(s.tolerance > 0.0 && s.tolerance < 1.0) {
            let message = format!("must be a relative residual in (0, 1) (got {:e})", s.tolerance);
            return Err(self.err(format!("{at}.solver.tolerance"), message));
        }
        if s.max_iterations == 0 {
            return Err(self.err(format!("{at}.solver.max_iterations"), "must be at least 1"));
        }
        let solver = s.settings();
        let mut perturbation = s.perturbation.clone();
        if let Some(pert) = &mut perturbation {
            if !(pert.amplitude >= 0.0 && pert.amplitude.is_finite()) {
                return Err(self.err(format!("{at}.solver.perturbation.amplitude"), "must be >= 0"));
            }
            pert.amplitude *= len;
            if let Some(cell) = &mut pert.cell {
                // (material coordinates over the cell stay finite numbers for the noise field)
                if !(*cell * len >= MIN_CELL && *cell * len <= MAX_CELL) {
                    let message = format!("must be > 0, from {MIN_CELL:e} to {MAX_CELL:e} m (got {})", *cell);
                    return Err(self.err(format!("{at}.solver.perturbation.cell"), message));
                }
                *cell *= len;
            }
            for (i, w) in pert.waves.iter_mut().enumerate() {
                let field = |f: &str| format!("{at}.solver.perturbation.waves[{i}].{f}");
                if pert.cell.is_none() {
                    return Err(
                        self.err(field("wavelength"), "waves add to the smooth field: give the perturbation a `cell`")
                    );
                }
                if !(w.wavelength * len >= MIN_CELL && w.wavelength * len <= MAX_CELL) {
                    let message = format!("must be > 0, from {MIN_CELL:e} to {MAX_CELL:e} m (got {})", w.wavelength);
                    return Err(self.err(field("wavelength"), message));
                }
                if !(w.amplitude >= 0.0 && w.amplitude.is_finite()) {
                    return Err(self.err(field("amplitude"), "must be >= 0"));
                }
                if w.axis == Axis::Z {
                    return Err(self.err(field("axis"), "must be X or Y (a material axis)"));
                }
                (w.wavelength, w.amplitude) = (w.wavelength * len, w.amplitude * len);
            }
        }
        let offset = self.placement(&format!("{at}.offset"), p.offset, len)?;
        let mut layers: Vec<BuiltLayer> = Vec::new();
        let mut index = HashMap::new();
        // The shared body, if any, is the patch's layer 0 (its layers are numbered from 1).
        let body = match &p.body {
            None => None,
            Some(name) => {
                let field = format!("{at}.body");
                let Some(bi) = bodies.iter().position(|b| &b.name == name) else {
                    let known: Vec<_> = bodies.iter().map(|b| format!("\"{}\"", b.name)).collect();
                    let known = if known.is_empty() { "the scene declares no body".into() } else { known.join(", ") };
                    return Err(self.err(field, format!("no body named \"{name}\" ({known})")));
                };
                if offset != DVec3::ZERO {
                    return Err(self.err(format!("{at}.offset"), "a patch on a body sits where the body is: no offset"));
                }
                layers.push(bodies[bi].layers[0].clone());
                index.insert(name.clone(), 0);
                Some(bi)
            }
        };
        let first = layers.len();
        let lambdas = self.refine_wavelengths(p, len, stress);
        for (li, l) in p.layers.iter().enumerate() {
            let lat = format!("{at}.layers[{li}] (\"{}\")", l.name);
            self.check_name(format!("{lat}.name"), &l.name)?;
            if let Some(prev) = index.insert(l.name.clone(), first + li) {
                let what = match prev.checked_sub(first) {
                    Some(prev) => format!("also the name of layers[{prev}]"),
                    None => "also the name of the patch's body".into(),
                };
                return Err(self.err(format!("{lat}.name"), what));
            }
            // KCK18 section 3: a skin under anchors is Stable Neo-Hookean unless stated.
            let mut l = l.clone();
            if let (Some(a), Some(m)) = (&p.anchors, &mut l.material) {
                if a.skin == l.name {
                    m.model.get_or_insert(crate::physics::ConstitutiveModel::StableNeoHookean);
                }
            }
            layers.push(self.layer(&lat, &l, len, stress, offset, &layers, &index, lambdas[li])?);
        }
        self.check_interfaces(&at, first, &layers)?;
        let cx = PatchContext { scene, layers: &layers, index: &index, len, stress, offset };
        let mut drivers = Vec::new();
        for (di, d) in p.drivers.iter().enumerate() {
            let dat = format!("{at}.drivers[{di}]");
            let built = self.driver(&dat, d, &cx)?;
            // (these move each vertex by its index in the layer as built: a remesh renumbers it)
            if let BuiltDriver::BlendShape { layer, .. }
            | BuiltDriver::Sequence { layer, .. }
            | BuiltDriver::Rig { layer, .. } = &built
            {
                if layers[*layer].remesh.is_some() {
                    let message = format!(
                        "\"{}\" is remeshed: a blend shape, sequence or rig moves each vertex of the mesh as \
                         given, and a remesh makes new ones (drive a layer below it instead)",
                        layers[*layer].name
                    );
                    return Err(self.err(format!("{dat}.layer"), message));
                }
            }
            if let (Some(bi), true) = (body, built.layers().contains(&0)) {
                let message =
                    format!("the body \"{}\" moves by its own drivers (bodies[{bi}].drivers)", layers[0].name);
                return Err(self.err(dat, message));
            }
            drivers.push(built);
        }
        let couplings: Vec<_> = p
            .couplings
            .iter()
            .enumerate()
            .map(|(ci, c)| self.coupling(&format!("{at}.couplings[{ci}]"), c, &cx))
            .collect::<Result<_, _>>()?;
        for (li, l) in layers.iter().enumerate().skip(first) {
            let wavelength = l.remesh.as_ref().is_some_and(|r| r.wavelength.is_some());
            if wavelength && !couplings.iter().any(|c| c.upper == li) {
                return Err(self.err(
                    format!("{at}.layers[{}].remesh.wavelength", li - first),
                    format!(
                        "needs a coupling with \"{}\" as its upper layer (lambda(x) is its kernels' wavelength)",
                        l.name
                    ),
                ));
            }
        }
        let anchors = p.anchors.as_ref().map(|a| self.anchors(&format!("{at}.anchors"), a, &cx)).transpose()?;
        let contact = p
            .contact
            .as_ref()
            .map(|c| self.contact(&format!("{at}.contact"), c, p, &layers[first..], len))
            .transpose()?;
        let patch = BuiltPatch {
            name: p.name.clone(),
            body,
            solver,
            perturbation,
            layers,
            drivers,
            couplings,
            anchors,
            contact,
            contact_with: Vec::new(),
        };
        if let Some((li, message)) = super::geometry::geometry_error(&patch) {
            let field = match li.checked_sub(first) {
                Some(own) => format!("{at}.layers[{own}] (\"{}\").mesh", patch.layers[li].name),
                None => format!("{at}.body"),
            };
            return Err(self.err(field, message));
        }
        Ok(patch)
    }
}
