//! A checkpoint (issue 66): the state a frame leaves behind, captured from a World and restored
//! into a fresh World spawned from the same scene, so that the frames after it repeat the
//! uninterrupted run bit for bit.
//!
//! What is saved is what the frames change: positions, velocities and masses; the rest and
//! prestrain data captures and PropertyResample write; a remeshed layer's topology (its
//! vertices, faces, edges and attachment springs, in the layer's order); the kernels' samples
//! and weights; the anchors; each layer's last remesh report; each patch's solver carry
//! (`skinsim::solve::Carry`); the clock. The rest is the scene's and is spawned again.
//!
//! Entities are saved by their bits in the saved run. A fresh World spawned from the same scene
//! gives the scene's own entities the same bits (spawning is deterministic), so those are kept;
//! an entity a remesh made is spawned again and every saved reference is mapped to it. A layer's
//! list stays in the saved order: survivors keep their relative order in bevy's relationship
//! lists (a removal shifts, never swaps) and new entities are appended, in both runs.

use bevy_ecs::prelude::*;
use glam::{DVec2, DVec3};
pub use skinsim::model::checkpoint::*;
use skinsim::model::*;
use skinsim::solve::{Carry, PackedPatch};

pub use crate::checkpoint_restore::restore;

pub(crate) fn bits(e: Entity) -> u64 {
    e.to_bits()
}

pub(crate) fn list<C: Component>(world: &World, e: Entity, get: impl Fn(&C) -> &[Entity]) -> Vec<Entity> {
    world.get::<C>(e).map_or(Vec::new(), |c| get(c).to_vec())
}

/// The entities with `C`, in entity order (the same in a fresh World of the same scene).
pub(crate) fn sorted_with<C: Component>(world: &mut World) -> Vec<Entity> {
    let mut v: Vec<Entity> = world.query_filtered::<Entity, With<C>>().iter(world).collect();
    v.sort_by_key(|e| e.to_bits());
    v
}

/// The state `world` is in after its last frame.
pub fn capture(world: &mut World) -> Checkpoint {
    let clock = *world.resource::<SimClock>();
    let layers = sorted_with::<Layer>(world).into_iter().map(|l| capture_layer(world, l)).collect();
    let patches = sorted_with::<Patch>(world)
        .into_iter()
        .map(|p| {
            let kernels = list::<PatchKernels>(world, p, |k| k.entities());
            PatchState {
                id: bits(p),
                name: world.get::<Patch>(p).expect("patch").name.clone(),
                carry: match (world.get::<PackedPatch>(p), world.get::<PackedIndex>(p)) {
                    (Some(pp), Some(index)) => pp.carry(index.key),
                    _ => Carry::default(),
                },
                kernels: kernels.iter().map(|&k| capture_kernel(world, k)).collect(),
            }
        })
        .collect();
    let log = world
        .get_resource::<LogState>()
        .map_or((false, Vec::new()), |s| (s.rest_logged, s.colour_scales.iter().map(|&(l, x)| (bits(l), x)).collect()));
    Checkpoint { frame: clock.frame, time: clock.time, layers, patches, log }
}

fn capture_layer(world: &World, l: Entity) -> LayerState {
    let ids = |v: &[Entity]| v.iter().map(|&e| bits(e)).collect::<Vec<_>>();
    let vertices = list::<LayerVertices>(world, l, |c| c.entities())
        .into_iter()
        .map(|v| {
            let e = world.entity(v);
            VertexState {
                id: bits(v),
                uv: e.get::<MaterialPos>().map_or(DVec2::ZERO, |p| p.0),
                rest: e.get::<RestPos>().map_or(DVec3::ZERO, |p| p.0),
                x: e.get::<Position>().map_or(DVec3::ZERO, |p| p.0),
                v: e.get::<Velocity>().map_or(DVec3::ZERO, |p| p.0),
                mass: e.get::<Mass>().map_or(0.0, |m| m.0),
                fixed: e.get::<Prescribed>().map_or([false; 3], |p| p.0),
            }
        })
        .collect();
    let faces = list::<LayerFaces>(world, l, |c| c.entities())
        .into_iter()
        .map(|f| {
            let e = world.entity(f);
            FaceState {
                id: bits(f),
                verts: e.get::<FaceVerts>().expect("face").0.map(bits),
                rest: e.get::<FaceRest>().map(|r| (r.0.b, r.0.volume)),
                prestrain: e.get::<FacePrestrain>().map(|p| p.0),
                scale: e.get::<ModulusScale>().map(|s| s.0),
            }
        })
        .collect();
    let edges = list::<LayerEdges>(world, l, |c| c.entities())
        .into_iter()
        .map(|d| {
            let e = world.entity(d);
            EdgeState {
                id: bits(d),
                verts: e.get::<EdgeVerts>().expect("edge").0.map(bits),
                opposite: e.get::<EdgeOpposite>().map(|o| o.0.map(bits)),
                hinge: e.get::<Hinge>().map(|h| HingeState {
                    opposite: h.opposite.map(bits),
                    weight: h.rest.weight,
                    rest_phi: h.rest.rest_phi,
                    image: h.image.map(|i| i.map(bits)),
                }),
            }
        })
        .collect();
    let tets = list::<LayerTets>(world, l, |c| c.entities())
        .into_iter()
        .map(|t| {
            let e = world.entity(t);
            let rest = e.get::<TetRestShape>().expect("tet").0;
            TetState { rest: (rest.b, rest.volume), prestrain: e.get::<TetPrestrain>().map(|p| p.0) }
        })
        .collect();
    let springs = list::<LayerSprings>(world, l, |c| c.entities())
        .into_iter()
        .filter_map(|s| {
            let e = world.entity(s);
            if let Some(sp) = e.get::<Spring>() {
                return Some(SpringState::Point { id: bits(s), a: bits(sp.a), b: bits(sp.b), stiffness: sp.stiffness });
            }
            let sp = e.get::<FaceSpring>()?;
            Some(SpringState::Face { id: bits(s), a: bits(sp.a), b: sp.b.map(bits), w: sp.w, stiffness: sp.stiffness })
        })
        .collect();
    let anchors = list::<LayerAnchors>(world, l, |c| c.entities())
        .into_iter()
        .map(|a| {
            let e = world.entity(a);
            let anchor = e.get::<Anchor>().expect("anchor");
            let s = e.get::<AnchorState>().copied().unwrap_or_default();
            AnchorSaved {
                skin: match anchor.skin {
                    SkinPoint::Vertex(v) => vec![bits(v)],
                    SkinPoint::Face(f) => ids(&f),
                },
                face: anchor.body.face,
                st: anchor.body.st,
                stiffness: anchor.stiffness,
                state: (s.position, s.step, s.walked, s.jump),
            }
        })
        .collect();
    LayerState {
        id: bits(l),
        name: world.get::<Layer>(l).expect("layer").name.clone(),
        epoch: world.get::<TopologyEpoch>(l).map_or(0, |e| e.0),
        remesh: world.get::<RemeshReport>(l).copied(),
        vertices,
        faces,
        edges,
        tets,
        springs,
        anchors,
    }
}

fn capture_kernel(world: &World, k: Entity) -> KernelState {
    let side = |w: &LayerWeights| w.iter().map(|&(v, x)| (bits(v), x)).collect::<Vec<_>>();
    let samples = world.get::<KernelSamples>(k).cloned().unwrap_or_default();
    let weights = world.get::<KernelWeights>(k).cloned().unwrap_or_default();
    KernelState {
        samples: [side(&samples.upper), side(&samples.lower)],
        chart: samples.chart,
        weights: [side(&weights.upper), side(&weights.lower)],
        adjusted: weights.adjusted,
    }
}
