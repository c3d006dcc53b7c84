//! KCK18 anchors packed as springs (KCK18 section 3): one per skin vertex and per skin face
//! barycentre, towards the anchor's point on the body.

use bevy_ecs::prelude::*;
use skinsim::model::*;
use skinsim::solve::{AnchorElem, PackedPatch};

use super::{LayerItems, LayerItemsItem};

/// Anchor springs in element order (vertex anchors, then face anchors), with their entities.
pub(super) fn rebuild(
    packed: &mut PackedPatch,
    index: &mut PackedIndex,
    patch_layers: &PatchLayers,
    layers: &Query<LayerItems>,
    anchors: &Query<(&Anchor, &AnchorState)>,
) {
    let at = |v: &Entity| index.index[v];
    let (mut at_vertices, mut at_faces) = (Vec::new(), Vec::new());
    for &l in patch_layers.entities() {
        let Ok(LayerItemsItem { anchors: Some(list), .. }) = layers.get(l) else { continue };
        for &a in list.entities() {
            let Ok((anchor, state)) = anchors.get(a) else { continue };
            let (k, target) = (anchor.stiffness, state.position);
            match anchor.skin {
                SkinPoint::Vertex(v) => at_vertices.push((a, AnchorElem { v: [at(&v)], w: [1.0], k, target })),
                SkinPoint::Face(f) => {
                    at_faces.push((a, AnchorElem { v: f.map(|v| at(&v)), w: [1.0 / 3.0; 3], k, target }))
                }
            }
        }
    }
    index.anchors = at_vertices.iter().map(|a| a.0).chain(at_faces.iter().map(|a| a.0)).collect();
    packed.elements.vertex_anchors = at_vertices.into_iter().map(|a| a.1).collect();
    packed.elements.face_anchors = at_faces.into_iter().map(|a| a.1).collect();
}

/// The walk moved the anchors: new spring targets, the same pattern (every frame).
pub(super) fn update_targets(packed: &mut PackedPatch, index: &PackedIndex, anchors: &Query<(&Anchor, &AnchorState)>) {
    let nv = packed.elements.vertex_anchors.len();
    for (i, &a) in index.anchors.iter().enumerate() {
        let target = anchors.get(a).expect("anchor of a live layer").1.position;
        match packed.elements.vertex_anchors.get_mut(i) {
            Some(e) => e.target = target,
            None => packed.elements.face_anchors[i - nv].target = target,
        }
    }
}
