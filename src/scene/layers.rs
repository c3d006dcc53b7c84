//! Building a patch's layers: materials (presets resolved, checked, in SI), bending, prestrain,
//! randomized moduli, property maps and remeshing, and the checks between layers.

use std::collections::HashMap;

use glam::DVec3;

use super::built::{BuiltLayer, LayerMesh};
use super::context::Builder;
use super::schema::*;
use super::SceneError;
use crate::mesh;
use crate::model::{LayerKind, WeightMap};
use crate::physics::cell::VolumeElement;
use crate::physics::{plate_rigidity, BendingElement, Lame};

/// A layer's material as stated or taken from its preset (scene units).
pub(super) struct Resolved {
    pub(super) model: crate::physics::ConstitutiveModel,
    pub(super) young: f64,
    pub(super) poisson: f64,
    pub(super) density: f64,
    pub(super) thickness: Option<f64>,
}

impl Builder {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn layer(
        &self,
        at: &str,
        l: &LayerSpec,
        len: f64,
        stress: f64,
        offset: DVec3,
        earlier: &[BuiltLayer],
        index: &HashMap<String, usize>,
        lambda: Option<f64>,
    ) -> Result<BuiltLayer, SceneError> {
        let super::meshes::BuiltMesh { mesh, shared, slab, groups, asset, embedding, parents, asset_uv } =
            self.mesh(at, l, len, offset, earlier, index, lambda)?;
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
                let volume_element = match (l.kind, spec.volume_element) {
                    (LayerKind::Volume, Some(v)) => v,
                    (LayerKind::Volume, None) => VolumeElement::default_for(m.poisson),
                    (_, None) => VolumeElement::Tet,
                    (_, Some(_)) => {
                        return Err(self.err(format!("{at}.material.volume_element"), "only volume layers have one"))
                    }
                };
                if volume_element == VolumeElement::Cell && has_transition_cells(&mesh) {
                    return Err(self.err(
                        format!("{at}.material.volume_element"),
                        "the cell element needs hexahedral cells, and this slab coarsens (its transition cells \
                         are not hexahedra): set `volume_element: Tet` or drop `coarsen`",
                    ));
                }
                material = Some(crate::model::Material {
                    model: m.model,
                    young,
                    poisson: m.poisson,
                    density: m.density,
                    lame,
                    volume_element,
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
                let d = plate_rigidity(m.young, thickness.unwrap(), m.poisson);
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
            groups,
            material,
            thickness,
            bending,
            prestrain,
            randomize,
            properties,
            asset,
            embedding,
            parents,
            asset_uv,
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
        if !(r.min_change >= 0.0 && r.min_change.is_finite()) {
            return Err(
                self.err(format!("{at}.min_change"), format!("must be a non-negative number (got {})", r.min_change))
            );
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
        let wavelength = r
            .wavelength
            .map(|w| {
                if !(w.per_wavelength >= 1.0 && w.per_wavelength.is_finite()) {
                    return Err(self.err(
                        format!("{at}.wavelength.per_wavelength"),
                        format!("must be a number of at least 1 (got {})", w.per_wavelength),
                    ));
                }
                for (field, value) in [("onset", w.onset), ("margin", w.margin)] {
                    if !(value >= 0.0 && value.is_finite()) {
                        return Err(self.err(
                            format!("{at}.wavelength.{field}"),
                            format!("must be a non-negative number (got {value})"),
                        ));
                    }
                }
                Ok(crate::mesh::remesh::sizing::WavelengthSizing {
                    per_wavelength: w.per_wavelength,
                    onset: w.onset,
                    isotropic: w.isotropic,
                    lookahead: w.lookahead,
                    margin: w.margin * len,
                    hold: w.hold,
                })
            })
            .transpose()?;
        Ok(crate::model::RemeshSettings {
            params,
            every: r.every,
            settle: r.settle,
            settle_rings: r.settle_rings,
            local_solve: r.local_solve,
            min_change: r.min_change,
            wavelength,
        })
    }

    /// A material with its preset's values filled in where the scene states none (in the
    /// scene's units).
    pub(super) fn resolve_material(
        &self,
        at: &str,
        m: &MaterialSpec,
        len: f64,
        stress: f64,
    ) -> Result<Resolved, SceneError> {
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
    /// `first`: the index in `layers` of the patch's first own layer (1 on a shared body).
    pub(super) fn check_interfaces(&self, at: &str, first: usize, layers: &[BuiltLayer]) -> Result<(), SceneError> {
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
                        format!("{at}.layers[{}] (\"{}\").mesh", b - first, layers[b].name),
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
    pub(super) fn weight_map(&self, field: &str, path: &str, mesh: &LayerMesh) -> Result<WeightMap, SceneError> {
        let full = self.dir.join(path);
        if let Some(problem) = super::context::not_a_file(&full) {
            return Err(SceneError::at_field(&full, field, format!("cannot read the map image: {problem}")));
        }
        let img = image::open(&full)
            .map_err(|e| SceneError::at_field(&full, field, format!("cannot read the map image: {e}")))?
            .to_luma16();
        let (width, height) = (img.width() as usize, img.height() as usize);
        let values = img.pixels().map(|p| p.0[0] as f32 / 65535.0).collect();
        let uv = mesh.material_positions();
        let (lo, hi) = mesh::bounds(&uv);
        Ok(WeightMap { width, height, values, lo, hi })
    }
}

/// Whether a volume mesh has cells other than the six-tet hexahedra (a coarsening slab's
/// transition cells; `tet_slab` emits each cell's tets together).
fn has_transition_cells(mesh: &LayerMesh) -> bool {
    let LayerMesh::Volume(m) = mesh else { return false };
    m.cells.chunk_by(|a, b| a == b).any(|cell| cell.len() != 6)
}
