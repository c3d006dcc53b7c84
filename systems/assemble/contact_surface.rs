//! The contact surface of a patch with `Contact`: its shell layers' faces in packed numbers,
//! rebuilt with the packed index (the barrier stiffness carries over).

use bevy_ecs::prelude::*;
use skinsim::contact::{ContactState, Surface, SurfaceLayer};
use skinsim::model::*;
use skinsim::solve::PackedPatch;

use super::{ElementItems, LayerItems};

pub(super) fn rebuild(
    packed: &mut PackedPatch,
    index: &PackedIndex,
    patch_layers: &PatchLayers,
    contact: Option<&Contact>,
    kernels: Option<&PatchKernels>,
    layers: &Query<LayerItems>,
    items: &ElementItems,
) {
    let Some(c) = contact else {
        packed.contact = None;
        return;
    };
    // Shell layers (the skin, half its thickness on each side) and kinematic ones (bodies in
    // the patch: obstacles).
    let (entities, surfaces): (Vec<Entity>, Vec<SurfaceLayer>) = patch_layers
        .entities()
        .iter()
        .filter_map(|&l| layers.get(l).ok().map(|item| (l, item)))
        .filter(|(_, l)| matches!(l.layer.kind, LayerKind::Shell | LayerKind::Kinematic) && !l.anchor_body)
        .filter_map(|(e, l)| l.faces.map(|f| (e, f, l.layer.kind == LayerKind::Shell)))
        .map(|(e, faces, shell)| {
            (
                e,
                SurfaceLayer {
                    half_thickness: if shell { 0.5 * c.thickness } else { 0.0 },
                    moving: shell,
                    triangles: faces
                        .entities()
                        .iter()
                        .filter_map(|&f| items.faces.get(f).ok())
                        .filter_map(|(fv, _, _)| {
                            let v = fv.0.map(|e| index.index.get(&e).copied());
                            v.iter().all(Option::is_some).then(|| v.map(Option::unwrap))
                        })
                        .collect(),
                },
            )
        })
        .unzip();
    // Layers a kernel binds do not touch (LK14: the skin oscillates about what it is bound to).
    let at = |e: Entity| entities.iter().position(|&l| l == e).map(|i| i as u32);
    let bound: Vec<(u32, u32)> = kernels
        .map_or(&[][..], |k| k.entities())
        .iter()
        .filter_map(|&k| items.kernels.get(k).ok())
        .filter_map(|(k, _)| Some((at(k.upper)?, at(k.lower)?)))
        .collect();
    let rest = index.vertices.iter().map(|&v| items.rest.get(v).expect("vertex").0).collect();
    let surface = Surface::new(&surfaces, rest, c.reach, &bound);
    // (the list's margin: a step of up to half of it needs no new broad phase)
    let mut state = ContactState::new(surface, c.reach);
    (state.friction, state.sticking) = (c.friction, c.sticking);
    if let Some(old) = packed.contact.take() {
        (state.stiffness, state.stiffness_min, state.stiffness_max) =
            (old.stiffness, old.stiffness_min, old.stiffness_max);
    }
    packed.contact = Some(state);
}
