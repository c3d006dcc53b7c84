//! Assemble: copies each patch out of the ECS into its packed `SolverBody`. Element lists are
//! rebuilt only when a layer's topology epoch (or element count) changes; positions,
//! velocities and fixed coordinates are gathered every frame. The rebuild itself is
//! `assemble_rebuild`.

use bevy_ecs::prelude::*;
use skinsim::model::*;
use skinsim::solve::SolverBody;

use crate::assemble_rebuild::rebuild;

pub(crate) type LayerItems<'a> = (
    &'a Layer,
    &'a TopologyEpoch,
    Option<&'a Material>,
    Option<&'a Bending>,
    Option<&'a LayerVertices>,
    Option<&'a LayerFaces>,
    Option<&'a LayerEdges>,
    Option<&'a LayerTets>,
    Option<&'a LayerSprings>,
    Option<&'a LayerAnchors>,
    Has<AnchorBody>,
);

#[allow(clippy::too_many_arguments)]
pub fn gather_bodies(
    mut patches: Query<(&PatchLayers, Option<&PatchKernels>, &mut SolverBody)>,
    kernels: Query<crate::kernels::KernelItems>,
    thickness: Query<(&Thickness, Option<&LayerProperties>)>,
    layers: Query<LayerItems>,
    vertices: Query<(&Position, &Velocity, &Mass, &Prescribed)>,
    ties: Query<&Tied>,
    rest: Query<&RestPos>,
    faces: Query<(&FaceVerts, Option<&FaceRest>, Option<&ModulusScale>)>,
    hinges: Query<(&EdgeVerts, &Hinge)>,
    tets: Query<(&TetVerts, &TetRestShape, Option<&ModulusScale>)>,
    springs: Query<&Spring>,
    anchors: Query<(&Anchor, &AnchorState)>,
) {
    for (patch_layers, patch_kernels, mut body) in &mut patches {
        let key = topology_key(patch_layers, &layers);
        let rebuilt = key != body.topology_key;
        if rebuilt {
            rebuild(&mut body, patch_layers, &layers, &vertices, &ties, &faces, &hinges, &tets, &springs, &rest);
            crate::anchors::rebuild_anchor_springs(&mut body, patch_layers, &layers, &anchors);
            body.topology_key = key;
        }
        if let Some(pk) = patch_kernels {
            let resampled = pk.entities().iter().any(|&k| kernels.get(k).is_ok_and(|(_, w)| w.is_changed()));
            if rebuilt || resampled {
                let (items, faces) = (&kernels, &faces);
                body.constraints = crate::kernels::kernel_rows(&body, pk, items, &layers, faces, &thickness);
                body.invalidate_pattern(); // the pattern holds the kernels' J^T J couplings
            }
        }
        let body = body.as_mut();
        let mut fixed_changed = false;
        for (i, &e) in body.vertices.iter().enumerate() {
            let (p, v, _, f) = vertices.get(e).expect("vertex of a live layer");
            body.x[i] = p.0;
            body.v[i] = v.0;
            if body.fixed[i] != f.0 {
                body.fixed[i] = f.0;
                fixed_changed = true;
            }
        }
        if fixed_changed {
            body.invalidate_pattern();
        }
        crate::anchors::update_anchor_targets(body, &anchors);
    }
}

fn topology_key(patch_layers: &PatchLayers, layers: &Query<LayerItems>) -> u64 {
    // A cheap fingerprint: epochs and element counts of every layer, in order.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |v: u64| {
        h ^= v;
        h = h.wrapping_mul(0x100_0000_01b3);
    };
    for &l in patch_layers.entities() {
        if let Ok((_, epoch, _, _, v, f, e, t, s, a, _)) = layers.get(l) {
            mix(l.to_bits());
            mix(epoch.0);
            mix(v.map_or(0, |x| x.entities().len()) as u64);
            mix(f.map_or(0, |x| x.entities().len()) as u64);
            mix(e.map_or(0, |x| x.entities().len()) as u64);
            mix(t.map_or(0, |x| x.entities().len()) as u64);
            mix(s.map_or(0, |x| x.entities().len()) as u64);
            mix(a.map_or(0, |x| x.entities().len()) as u64);
        }
    }
    h
}
