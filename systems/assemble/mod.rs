//! Assemble (ARCHITECTURE.md 2): packs each patch out of the ECS into its `PackedPatch`. When a
//! layer's topology changes (its epoch or an element count) the packed index, the element
//! lists and the anchor springs are rebuilt (`rebuild`, `anchor_springs`); when the kernels
//! were resampled, the constraint rows (`kernel_rows`). Every frame the positions, velocities,
//! fixed coordinates and anchor targets are gathered.

mod anchor_springs;
mod contact_surface;
mod kernel_rows;
mod rebuild;

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use bevy_ecs::system::SystemParam;
use skinsim::model::*;
use skinsim::solve::PackedPatch;

/// What Assemble reads of a layer.
#[derive(QueryData)]
pub struct LayerItems {
    pub layer: &'static Layer,
    pub epoch: &'static TopologyEpoch,
    pub material: Option<&'static Material>,
    pub bending: Option<&'static Bending>,
    pub vertices: Option<&'static LayerVertices>,
    pub faces: Option<&'static LayerFaces>,
    pub edges: Option<&'static LayerEdges>,
    pub tets: Option<&'static LayerTets>,
    pub springs: Option<&'static LayerSprings>,
    pub anchors: Option<&'static LayerAnchors>,
    /// A body under KCK18 anchors is not solved for: the walk reads it, the springs hold targets.
    pub anchor_body: Has<AnchorBody>,
}

/// The element entities Assemble packs.
#[derive(SystemParam)]
pub struct ElementItems<'w, 's> {
    pub vertices: Query<'w, 's, (&'static Position, &'static Velocity, &'static Mass, &'static Prescribed)>,
    pub ties: Query<'w, 's, &'static Tied>,
    pub rest: Query<'w, 's, &'static RestPos>,
    pub faces: Query<'w, 's, (&'static FaceVerts, Option<&'static FaceRest>, Option<&'static ModulusScale>)>,
    pub hinges: Query<'w, 's, (&'static EdgeVerts, &'static Hinge)>,
    pub tets: Query<
        'w,
        's,
        (&'static TetVerts, &'static TetRestShape, Option<&'static ModulusScale>, Option<&'static TetCell>),
    >,
    pub springs: Query<'w, 's, &'static Spring>,
    pub face_springs: Query<'w, 's, &'static FaceSpring>,
    pub anchors: Query<'w, 's, (&'static Anchor, &'static AnchorState)>,
    pub kernels: Query<'w, 's, (&'static Kernel, Ref<'static, KernelWeights>)>,
    pub thickness: Query<'w, 's, (&'static Thickness, Option<&'static LayerProperties>)>,
}

/// What Assemble reads and writes of a patch.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct PatchItems {
    pub layers: &'static PatchLayers,
    /// Shared bodies its kernels hold it to (packed after its own vertices, held fixed).
    pub bodies: Option<&'static PatchBodies>,
    pub kernels: Option<&'static PatchKernels>,
    pub packed: &'static mut PackedPatch,
    pub index: &'static mut PackedIndex,
    pub contact: Option<&'static Contact>,
    pub obstacles: Option<&'static ContactObstacles>,
}

pub fn gather_packed(mut patches: Query<PatchItems>, layers: Query<LayerItems>, items: ElementItems) {
    for patch in &mut patches {
        let PatchItemsItem {
            layers: patch_layers,
            bodies,
            kernels: patch_kernels,
            mut packed,
            mut index,
            contact,
            obstacles,
        } = patch;
        let (packed, index) = (packed.as_mut(), index.as_mut());
        let bodies = bodies.map_or(&[][..], |b| &b.0);
        let obstacles = obstacles.map_or(&[][..], |o| &o.0);
        let key = topology_key(patch_layers.entities().iter().chain(bodies).chain(obstacles), &layers);
        let rebuilt = key != index.key;
        if rebuilt {
            // (where the last solve left each vertex, by entity: a remesh keeps its survivors')
            let last = packed.contact.as_ref().filter(|c| c.last.len() == index.vertices.len()).map(|c| {
                index.vertices.iter().copied().zip(c.last.iter().copied()).collect::<std::collections::HashMap<_, _>>()
            });
            rebuild::rebuild(packed, index, patch_layers, bodies, obstacles, &layers, &items);
            anchor_springs::rebuild(packed, index, patch_layers, &layers, &items.anchors);
            let with = contact_surface::With { contact, kernels: patch_kernels, obstacles, last };
            contact_surface::rebuild(packed, index, patch_layers, with, &layers, &items);
            index.key = key;
        }
        if let Some(pk) = patch_kernels {
            let resampled = pk.entities().iter().any(|&k| items.kernels.get(k).is_ok_and(|(_, w)| w.is_changed()));
            if rebuilt || resampled {
                packed.constraints = kernel_rows::kernel_rows(packed, index, pk, &layers, &items);
                packed.cache.invalidate(); // the pattern holds the kernels' J^T J couplings
            }
        }
        // A resumed run: the solver state the checkpoint saved replaces what the rebuild made.
        if let Some(carry) = packed.carry.take() {
            packed.take_up(carry, key);
        }
        let mut fixed_changed = false;
        let state = &mut packed.state;
        for (i, &e) in index.vertices.iter().enumerate() {
            let (p, v, _, f) = items.vertices.get(e).expect("vertex of a live layer");
            state.x[i] = p.0;
            state.v[i] = v.0;
            let f = if i < index.held { f.0 } else { [true; 3] };
            if state.fixed[i] != f {
                state.fixed[i] = f;
                fixed_changed = true;
            }
        }
        if fixed_changed {
            packed.cache.invalidate();
        }
        anchor_springs::update_targets(packed, index, &items.anchors);
    }
}

/// A cheap fingerprint of a patch's topology: epochs and element counts of every layer (its
/// own, then shared bodies'), in order.
fn topology_key<'a>(patch_layers: impl Iterator<Item = &'a Entity>, layers: &Query<LayerItems>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |v: u64| {
        h ^= v;
        h = h.wrapping_mul(0x100_0000_01b3);
    };
    let count = |list: Option<&[Entity]>| list.map_or(0, |x| x.len()) as u64;
    for &l in patch_layers {
        if let Ok(item) = layers.get(l) {
            mix(l.to_bits());
            mix(item.epoch.0);
            mix(count(item.vertices.map(|x| x.entities())));
            mix(count(item.faces.map(|x| x.entities())));
            mix(count(item.edges.map(|x| x.entities())));
            mix(count(item.tets.map(|x| x.entities())));
            mix(count(item.springs.map(|x| x.entities())));
            mix(count(item.anchors.map(|x| x.entities())));
        }
    }
    h
}
