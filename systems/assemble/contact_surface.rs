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
    /// Where the last solve left each vertex of the patch before a topology change (none before
    /// the first solve).
    pub last: Option<std::collections::HashMap<Entity, glam::DVec3>>,
}

/// The kernels' median radius over the fold distance. Measured on the finger bent through itself
/// (`scenes/character/finger_fold_quick.ron`, radius 3.56 mm): at 0.09 mm frame 4 failed
/// (pinched); at 0.28 mm frames 6-8 did not converge; at 1.19 mm (a third) all 8 converged
/// (before the ring growth of `solve::release`: `src/solve/README.md`).
const RELEASE_FRACTION: f64 = 3.0;

pub(super) fn rebuild(
    packed: &mut PackedPatch,
    index: &PackedIndex,
    patch_layers: &PatchLayers,
    with: With,
    layers: &Query<LayerItems>,
    items: &ElementItems,
) {
    let With { contact, kernels, obstacles, last } = with;
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
    // A skin a kernel binds to a body does not touch it (LK14: the skin oscillates about its
    // body, up to 1.3 mm below the knuckle's). Two skins bound to each other do touch: tissue
    // layers never pass through each other, and on a pinch folded over itself (kernels of 2 mm,
    // `scenes/lk14/pinch_folded_quick.ron`) the dermis otherwise crossed its epidermis at frame 3.
    let at = |e: Entity| entities.iter().position(|&l| l == e).map(|i| i as u32);
    let bound: Vec<(u32, u32)> = kernels
        .map_or(&[][..], |k| k.entities())
        .iter()
        .filter_map(|&k| items.kernels.get(k).ok())
        .filter_map(|(k, _)| Some((at(k.upper)?, at(k.lower)?)))
        .filter(|&(a, b)| !(surfaces[a as usize].moving && surfaces[b as usize].moving))
        .collect();
    let rest: Vec<_> = index.vertices.iter().map(|&v| items.rest.get(v).expect("vertex").0).collect();
    // The kinematic layers kernels bind skin to (`solve::release`): where such a body comes
    // within a third of a kernel's radius (the median of those binding to it) of another part of
    // itself, its kernels are released.
    let is_body = |l: u32| !surfaces[l as usize].moving && surfaces[l as usize].half_thickness == 0.0;
    let mut radii: Vec<f64> = kernels
        .map_or(&[][..], |k| k.entities())
        .iter()
        .filter_map(|&k| items.kernels.get(k).ok())
        .filter(|(k, _)| at(k.lower).is_some_and(is_body))
        .map(|(k, _)| k.shape.radius)
        .collect();
    radii.sort_by(f64::total_cmp);
    let fold = radii.get(radii.len() / 2).copied().unwrap_or(0.0) / RELEASE_FRACTION;
    tracing::debug!(fold, kernels = radii.len(), "release distance");
    let bodies: Vec<SurfaceLayer> = bound
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .filter(|&l| is_body(l))
        .collect::<std::collections::BTreeSet<u32>>()
        .into_iter()
        .map(|l| SurfaceLayer {
            triangles: surfaces[l as usize].triangles.clone(),
            half_thickness: 0.5 * fold,
            moving: true,
        })
        .collect();
    let body = Surface::new(&bodies, rest.clone(), 0.0, &[]);
    let surface = Surface::new(&surfaces, rest, c.reach, &bound);
    // (the list's margin: a step of up to half of it needs no new broad phase)
    let mut state = ContactState::new(surface, c.reach);
    (state.body, state.fold) = (body, fold);
    (state.friction, state.sticking) = (c.friction, c.sticking);
    if let Some(old) = packed.contact.take() {
        (state.stiffness, state.stiffness_min, state.stiffness_max) =
            (old.stiffness, old.stiffness_min, old.stiffness_max);
        // (taken once, before any barrier: with the stiffness carried over it is not taken again)
        state.kernel_spring = old.kernel_spring;
    }
    // The next frame moves from where the last solve left the vertices (`solve::contact::
    // continuation`): after a remesh, the survivors from there and the new vertices from where
    // the remesh put them, on the straight edges near contact (`remesh::FaceRules::kept`).
    if let Some(last) = last {
        let position = |e: &Entity| items.vertices.get(*e).expect("vertex").0 .0;
        state.last = index.vertices.iter().map(|e| last.get(e).copied().unwrap_or_else(|| position(e))).collect();
    }
    packed.contact = Some(state);
}
