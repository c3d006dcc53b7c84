//! Building a patch's drivers: layer names resolved to indices, values checked and converted to
//! SI, and the geometry each needs (selected vertices, ties, seams, attachment pairs, targets).

use glam::DVec3;

use super::built::{BuiltDriver, BuiltLayer, LayerMesh};
use super::context::{Builder, PatchContext};
use super::schema::*;
use super::SceneError;
use crate::mesh::{self, select::Region};
use crate::model::LayerKind;
use crate::physics::BendingElement;

impl Builder {
    /// One driver, `dat` its field path.
    pub(super) fn driver(&self, dat: &str, d: &DriverSpec, cx: &PatchContext) -> Result<BuiltDriver, SceneError> {
        let PatchContext { scene, layers, len, stress, offset, .. } = *cx;
        let find = |field: String, name: &str| cx.find(self, field, name);
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
        Ok(match d {
            DriverSpec::Pin { layer, select, dofs } => {
                let li = find(format!("{dat}.layer"), layer)?;
                let vertices = mesh::select::select(layers[li].mesh.rest(), &region(select, len, offset));
                if vertices.is_empty() {
                    return Err(self.err(format!("{dat}.select"), "selects no vertex"));
                }
                BuiltDriver::Pin { layer: li, vertices, dofs: [dofs.x, dofs.y, dofs.z] }
            }
            DriverSpec::Compress { layers: ls, axis, keyframes, predict } => {
                keyframes_ok(keyframes, "strain")?;
                if let Some((i, _)) = keyframes.iter().enumerate().find(|(_, k)| k.1 >= 1.0) {
                    return Err(self.err(format!("{dat}.keyframes[{i}]"), "a strain of 1 or more collapses the patch"));
                }
                let layers = ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                BuiltDriver::Compress { layers, axis: axis.index(), keyframes: keyframes.clone(), predict: *predict }
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
            DriverSpec::Joint { layers: ls, pivot, axis, along, width, keyframes } => {
                keyframes_ok(keyframes, "angle")?;
                if axis == along {
                    return Err(self.err(format!("{dat}.along"), "the bone axis must differ from the hinge axis"));
                }
                if !(*width > 0.0 && width.is_finite()) {
                    return Err(self.err(format!("{dat}.width"), format!("must be > 0 (got {width})")));
                }
                let p = DVec3::new(pivot.0, pivot.1, pivot.2);
                if !p.is_finite() {
                    return Err(self.err(format!("{dat}.pivot"), "must be finite"));
                }
                let layers = ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                let unit = |a: &Axis| {
                    let mut v = DVec3::ZERO;
                    v[a.index()] = 1.0;
                    v
                };
                let joint = crate::model::Joint {
                    pivot: p * len + offset,
                    axis: unit(axis),
                    along: unit(along),
                    width: width * len,
                };
                let keyframes = keyframes.iter().map(|&(f, a)| (f, a.to_radians())).collect();
                BuiltDriver::Joint { layers, joint, keyframes }
            }
            DriverSpec::PlaneStrain { layers: ls, axis } => {
                let layers_i: Vec<usize> =
                    ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                let ties = layers_i
                    .iter()
                    .map(|&li| mesh::select::plane_strain_ties(layers[li].mesh.rest(), axis.index()))
                    .collect();
                BuiltDriver::PlaneStrain { layers: layers_i, axis: axis.index(), ties }
            }
            DriverSpec::Periodic { layers: ls, axis } => {
                let layers_i: Vec<usize> =
                    ls.iter().map(|n| find(format!("{dat}.layers"), n)).collect::<Result<_, _>>()?;
                let ties: Vec<Vec<(u32, u32)>> = layers_i
                    .iter()
                    .map(|&li| mesh::select::periodic_ties(layers[li].mesh.rest(), axis.index()))
                    .collect();
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
                        (LayerMesh::Surface(m), LayerKind::Shell) => mesh::select::periodic_seams(m, axis.index()),
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
                        format!(
                            "\"{}\" bends with the quadratic element, which has no rest curvature to capture into",
                            layers[li].name
                        ),
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
                let targets = self.blend_targets(dat, targets, *range, &layers[li].mesh, len, offset)?;
                BuiltDriver::BlendShape { layer: li, targets, interpolation: *interpolation }
            }
            DriverSpec::Articulate { layer, pose, weights, interpolation } => {
                let li = find(format!("{dat}.layer"), layer)?;
                let frames = self.articulate(dat, pose, weights, *interpolation, &layers[li], len, scene.frames)?;
                BuiltDriver::Sequence { layer: li, frames, start: 0 }
            }
            DriverSpec::Rig { layer, clip, start, speed, joints, morphs, skinning, interpolation } => {
                let li = find(format!("{dat}.layer"), layer)?;
                let rig = self.rig_motion(
                    dat,
                    &layers[li],
                    clip.as_deref(),
                    *start,
                    *speed,
                    joints,
                    morphs,
                    *skinning,
                    *interpolation,
                    scene.frame_time,
                    scene.frames,
                    offset,
                )?;
                BuiltDriver::Rig { layer: li, rig: std::sync::Arc::new(rig) }
            }
            DriverSpec::ObjSequence { layer, files, start } => {
                let li = find(format!("{dat}.layer"), layer)?;
                let frames = self.obj_sequence(dat, files, &layers[li], len, offset)?;
                BuiltDriver::Sequence { layer: li, frames, start: *start }
            }
            DriverSpec::Attach { layer, to, stiffness } => {
                let a = find(format!("{dat}.layer"), layer)?;
                let b = find(format!("{dat}.to"), to)?;
                if !(*stiffness > 0.0 && stiffness.is_finite()) {
                    return Err(self.err(format!("{dat}.stiffness"), format!("must be > 0 (got {stiffness})")));
                }
                let k_area = stiffness * stress / len;
                let springs = self.attach_springs(dat, &layers[a], &layers[b], k_area)?;
                BuiltDriver::Attach { layer: a, to: b, springs, k_area }
            }
        })
    }

    /// Pairs every vertex of `a` with the vertex of `b` at the same rest position in the plane
    /// (x, y), for attachment springs; stiffness per vertex = k_area x vertex area of `a`.
    fn attach_springs(
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
            LayerMesh::Volume(m) => mesh::select::bottom_faces(ra, &m.tets),
        };
        let below = mesh::select::match_xy(ra, b.mesh.rest());
        let area = mesh::select::vertex_areas(ra, &faces);
        let mut out = Vec::with_capacity(ra.len());
        for i in (0..ra.len()).filter(|&i| attached[i]) {
            let j = below[i].ok_or_else(|| {
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

/// A selection in SI, about the placed patch.
fn region(select: &Select, len: f64, offset: DVec3) -> Region {
    match select {
        Select::All => Region::All,
        Select::Sides(sides) => Region::Sides(
            sides
                .iter()
                .map(|s| match s {
                    Side::XMin => (0, false),
                    Side::XMax => (0, true),
                    Side::YMin => (1, false),
                    Side::YMax => (1, true),
                    Side::ZMin => (2, false),
                    Side::ZMax => (2, true),
                })
                .collect(),
        ),
        Select::Box { min, max } => Region::Box {
            min: DVec3::new(min.0, min.1, min.2) * len + offset,
            max: DVec3::new(max.0, max.1, max.2) * len + offset,
        },
    }
}

/// Whether a layer bends with the quadratic element (flat rest only).
fn quadratic(layer: &BuiltLayer) -> bool {
    layer.bending.is_some_and(|b| b.element == BendingElement::Quadratic)
}
