//! LK14 kernel constraints packed as rows (eq. 4.1) from the kernels' adjusted weights.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::DVec2;
use skinsim::model::*;
use skinsim::solve::constraints::{vertex_rings, Constraints, KernelRows};
use skinsim::solve::PackedPatch;

use super::{ElementItems, LayerItems, LayerItemsItem};

/// Packs the kernels' weights into constraint rows. A lower vertex's normal offset is the
/// distance between the layers' mid-surfaces, half the sum of their thicknesses (a kinematic
/// layer is a surface: thickness 0), each scaled by its property map at the kernel centre.
pub(super) fn kernel_rows(
    packed: &PackedPatch,
    index: &PackedIndex,
    patch_kernels: &PatchKernels,
    layers: &Query<LayerItems>,
    items: &ElementItems,
) -> Constraints {
    let at = |v: &Entity| index.index[v];
    let packed_faces = |layer: Entity| -> Vec<[u32; 3]> {
        let Ok(LayerItemsItem { faces: Some(lf), .. }) = layers.get(layer) else { return Vec::new() };
        lf.entities().iter().filter_map(|&f| items.faces.get(f).ok()).map(|(fv, ..)| fv.0.map(|e| at(&e))).collect()
    };
    let half =
        |l: Entity, c: DVec2| items.thickness.get(l).map_or(0.0, |(t, p)| 0.5 * t.0 * factors_at(p, c).thickness);
    let mut rings: HashMap<Entity, HashMap<u32, Vec<[u32; 3]>>> = HashMap::new();
    let mut rows = Vec::new();
    for &k in patch_kernels.entities() {
        let Ok((kernel, weights)) = items.kernels.get(k) else { continue };
        if weights.upper.is_empty() || weights.lower.is_empty() {
            continue; // a kernel with an empty support on either layer constrains nothing
        }
        let ring = rings.entry(kernel.lower).or_insert_with(|| vertex_rings(&packed_faces(kernel.lower)));
        let pack = |w: &LayerWeights| -> Vec<(u32, f64)> { w.iter().map(|(v, x)| (at(v), *x)).collect() };
        let offset = half(kernel.upper, kernel.shape.centre) + half(kernel.lower, kernel.shape.centre);
        rows.push(KernelRows::new(pack(&weights.upper), &pack(&weights.lower), offset, ring, &packed.state.fixed));
    }
    Constraints::new(rows, &packed.state.x)
}
