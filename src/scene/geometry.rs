//! The layers as `spawn` builds them, shared with `check`: which coordinates are prescribed,
//! the shells' rest shapes with the patch's perturbation, their rest data and lumped masses, and
//! the validation of that final geometry (everything `run` builds, `check` checks).

use glam::{DMat3, DVec2, DVec3};
use rand::{Rng, SeedableRng};

use super::built::{BuiltDriver, BuiltLayer, BuiltPatch, LayerMesh};
use super::schema::Perturbation;
use crate::mesh;
use crate::mesh::imperfection::{Imperfection, Wave};
use crate::model::{volume_masses, LayerKind, ShellRest};
use crate::physics::tet::TetRest;

/// Which coordinates of each layer's vertices are prescribed: kinematic layers, pins, plane strain.
pub(super) fn prescribed(p: &BuiltPatch) -> Vec<Vec<[bool; 3]>> {
    let mut fixed: Vec<Vec<[bool; 3]>> =
        p.layers.iter().map(|l| vec![[l.kind == LayerKind::Kinematic; 3]; l.mesh.rest().len()]).collect();
    for d in &p.drivers {
        match d {
            BuiltDriver::Pin { layer, vertices, dofs } => {
                for &v in vertices {
                    let f = &mut fixed[*layer][v as usize];
                    for k in 0..3 {
                        f[k] |= dofs[k];
                    }
                }
            }
            BuiltDriver::PlaneStrain { layers, axis, .. } => {
                for &l in layers {
                    fixed[l].iter_mut().for_each(|f| f[*axis] = true);
                }
            }
            _ => {}
        }
    }
    fixed
}

/// The layers as spawned: the shells' rest shapes with the patch's perturbation.
pub(super) fn final_layers(p: &BuiltPatch, fixed: &[Vec<[bool; 3]>]) -> Vec<BuiltLayer> {
    let mut rng = p.perturbation.as_ref().map(|q| (q, rand_pcg::Pcg64::seed_from_u64(q.seed)));
    let mut layers = p.layers.clone();
    for (li, l) in layers.iter_mut().enumerate() {
        if let (Some((q, rng)), LayerMesh::Surface(m), LayerKind::Shell) = (rng.as_mut(), &mut l.mesh, l.kind) {
            perturb(m, &fixed[li], q, rng);
        }
    }
    layers
}

/// The largest coordinate of a rest position (m): beyond it differences of positions lose the
/// digits a patch's elements need.
pub(super) const MAX_COORDINATE: f64 = 1e3;

/// `check` on the geometry `spawn` builds (after the offset and the perturbation): every rest
/// position finite and within MAX_COORDINATE, every shell face and every tet with a valid rest
/// shape. Returns the layer index and what is wrong.
pub(super) fn geometry_error(p: &BuiltPatch) -> Option<(usize, String)> {
    let layers = final_layers(p, &prescribed(p));
    for (li, l) in layers.iter().enumerate() {
        let rest = l.mesh.rest();
        if let Some(v) = rest.iter().position(|x| !(0.0..=MAX_COORDINATE).contains(&x.abs().max_element())) {
            let message = format!(
                "vertex {v} lies at {:?} m, outside +-{MAX_COORDINATE} m or not finite (with the patch's \
                 offset and perturbation applied)",
                rest[v]
            );
            return Some((li, message));
        }
        let uv = l.mesh.material_positions();
        match &l.mesh {
            LayerMesh::Surface(m) if l.kind == LayerKind::Shell => {
                let layer_rest = shell_rest(l);
                let bad = m
                    .faces
                    .iter()
                    .position(|f| layer_rest.face(f.map(|i| m.rest[i as usize]), f.map(|i| uv[i as usize])).is_none());
                if let Some(fi) = bad {
                    let message = format!(
                        "face {fi} is degenerate once the patch's offset and perturbation are applied \
                         (a perturbation amplitude or offset too large for the mesh?)"
                    );
                    return Some((li, message));
                }
            }
            LayerMesh::Volume(m) => {
                if let Some(ti) = m.tets.iter().position(|t| tet_rest(l, &m.rest, &uv, t).0.is_none()) {
                    let message = format!(
                        "tet {ti} is degenerate or inverted (a depth, size or grading too small or too large?)"
                    );
                    return Some((li, message));
                }
            }
            LayerMesh::Surface(_) => {}
        }
    }
    None
}

/// A tet's rest shape, with the layer's prestrain F0 at its centre when it has one.
pub(super) fn tet_rest(l: &BuiltLayer, rest: &[DVec3], uv: &[DVec2], t: &[u32; 4]) -> (Option<TetRest>, Option<DMat3>) {
    let centre = t.iter().map(|&i| uv[i as usize]).sum::<DVec2>() / 4.0;
    let f0 = l.prestrain.as_ref().map(|p| DMat3::from_diagonal(p.stretch_at(centre)));
    (TetRest::from_rest(t.map(|i| rest[i as usize]), f0.unwrap_or(DMat3::IDENTITY)), f0)
}

/// What a shell layer's face and hinge rest data depend on.
pub(super) fn shell_rest(l: &BuiltLayer) -> ShellRest<'_> {
    ShellRest {
        thickness: l.thickness.unwrap_or(0.0),
        prestrain: l.prestrain.as_ref(),
        properties: l.properties.as_ref(),
    }
}

/// Lumped masses (`ShellRest::masses`, `volume_masses`); kinematic vertices carry none.
pub(super) fn lumped_mass(l: &BuiltLayer) -> Vec<f64> {
    let Some(mat) = l.material else { return vec![0.0; l.mesh.rest().len()] };
    match &l.mesh {
        LayerMesh::Surface(m) => shell_rest(l).masses(mat.density, &m.rest, &m.uv, &m.faces),
        LayerMesh::Volume(m) => volume_masses(mat.density, &m.rest, &m.tets),
    }
}

/// The perturbation's waves as the imperfection takes them (SI lengths already).
pub(super) fn waves(q: &Perturbation) -> Vec<Wave> {
    q.waves.iter().map(|w| Wave { wavelength: w.wavelength, amplitude: w.amplitude, axis: w.axis.index() }).collect()
}

/// A geometric imperfection: free shell vertices moved along their rest normal by a seeded
/// uniform amount in [-a, a] (or, with a `cell`, by the smooth field of `Imperfection`), in the
/// rest shape itself, so the structure keeps it in equilibrium
/// (a perturbation of the initial positions alone is solved away at the first frame).
fn perturb(m: &mut mesh::SurfaceMesh, fixed: &[[bool; 3]], q: &Perturbation, rng: &mut rand_pcg::Pcg64) {
    if let Some(cell) = q.cell {
        let smooth = Imperfection::new(q.amplitude, cell, q.seed).with_waves(waves(q));
        return smooth.apply(1.0, &mut m.rest, &m.uv, &m.faces, fixed, |_| true);
    }
    let normal = mesh::shading::vertex_normals(&m.rest, &m.faces);
    for (i, p) in m.rest.iter_mut().enumerate() {
        let u: f64 = rng.random_range(-1.0..=1.0);
        let mut d = normal[i] * (u * q.amplitude);
        for k in 0..3 {
            if fixed[i][k] {
                d[k] = 0.0;
            }
        }
        *p += d;
    }
}
