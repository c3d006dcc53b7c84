//! The contact surface of a patch with `Contact`: its shell layers' faces in packed numbers,
//! rebuilt with the packed index (the barrier stiffness carries over).

use bevy_ecs::prelude::*;
use skinsim::contact::{ContactState, Surface, SurfaceLayer};
use skinsim::model::*;
use skinsim::solve::PackedPatch;

use super::{ElementItems, LayerItems};

/// What the patch's contact declares: the contact, its kernels (whose layers do not touch) and
/// the layers it touches besides its own (held).
pub(super) struct With<'a> {
    pub contact: Option<&'a Contact>,
    pub kernels: Option<&'a PatchKernels>,
    pub obstacles: &'a [Entity],
}

pub(super) fn rebuild(
    packed: &mut PackedPatch,
    index: &PackedIndex,
    patch_layers: &PatchLayers,
    with: With,
    layers: &Query<LayerItems>,
    items: &ElementItems,
) {
    let With { contact, kernels, obstacles } = with;
    let Some(c) = contact else {
        packed.contact = None;
        return;
    };
    // Shell layers (the skin, half its thickness on each side) and kinematic ones (bodies in
    // the patch: obstacles); then other patches' skins and scene bodies it touches (held).
    let own = patch_layers.entities().iter().map(|&l| (l, true));
    let (entities, surfaces): (Vec<Entity>, Vec<SurfaceLayer>) = own
        .chain(obstacles.iter().map(|&l| (l, false)))
        .filter_map(|(l, mine)| layers.get(l).ok().map(|item| (l, item, mine)))
        .filter(|(_, l, mine)| {
            matches!(l.layer.kind, LayerKind::Shell | LayerKind::Kinematic) && !(*mine && l.anchor_body)
        })
        .filter_map(|(e, l, mine)| l.faces.map(|f| (e, f, l.layer.kind == LayerKind::Shell, mine)))
        .map(|(e, faces, shell, mine)| {
            (
                e,
                SurfaceLayer {
                    half_thickness: if shell { 0.5 * c.thickness } else { 0.0 },
                    moving: shell && mine,
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
