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

use std::collections::{HashMap, HashSet};

use bevy_ecs::prelude::*;
use glam::{DMat2, DMat3, DVec2, DVec3};
use serde::{Deserialize, Serialize};
use skinsim::coupling::kernels::Adjusted;
use skinsim::coupling::walk::SurfacePoint;
use skinsim::model::*;
use skinsim::physics::hinge::HingeRest;
use skinsim::physics::membrane::MembraneRest;
use skinsim::physics::tet::TetRest;
use skinsim::solve::{Carry, PackedPatch};

/// The state after `frame`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    pub frame: u32,
    pub time: f64,
    /// Every layer (patches' and bodies'), in entity order.
    pub layers: Vec<LayerState>,
    /// Every patch, in entity order.
    pub patches: Vec<PatchState>,
    /// `log::LogState`: frame 0 written, and the layers' colour scales.
    pub log: (bool, Vec<(u64, f64)>),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerState {
    pub id: u64,
    pub name: String,
    pub epoch: u64,
    pub remesh: Option<RemeshReport>,
    pub vertices: Vec<VertexState>,
    pub faces: Vec<FaceState>,
    pub edges: Vec<EdgeState>,
    pub tets: Vec<TetState>,
    pub springs: Vec<SpringState>,
    pub anchors: Vec<AnchorSaved>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VertexState {
    pub id: u64,
    pub uv: DVec2,
    pub rest: DVec3,
    pub x: DVec3,
    pub v: DVec3,
    pub mass: f64,
    pub fixed: [bool; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceState {
    pub id: u64,
    pub verts: [u64; 3],
    /// `MembraneRest`'s b and volume.
    pub rest: Option<(DMat2, f64)>,
    pub prestrain: Option<DMat2>,
    pub scale: Option<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EdgeState {
    pub id: u64,
    pub verts: [u64; 2],
    pub opposite: Option<[u64; 2]>,
    pub hinge: Option<HingeState>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HingeState {
    pub opposite: [u64; 2],
    pub weight: f64,
    pub rest_phi: f64,
    pub image: Option<[u64; 2]>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TetState {
    pub rest: (DMat3, f64),
    pub prestrain: Option<DMat3>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SpringState {
    Point { id: u64, a: u64, b: u64, stiffness: f64 },
    Face { id: u64, a: u64, b: [u64; 3], w: [f64; 3], stiffness: f64 },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnchorSaved {
    /// The skin point: one vertex, or a face's three.
    pub skin: Vec<u64>,
    pub face: u32,
    pub st: DVec2,
    pub stiffness: f64,
    /// `AnchorState`: position, step, walked, jump.
    pub state: (DVec3, f64, f64, f64),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatchState {
    pub id: u64,
    pub name: String,
    pub carry: Carry,
    pub kernels: Vec<KernelState>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KernelState {
    pub samples: [Vec<(u64, f64)>; 2],
    pub chart: [Vec<DVec2>; 2],
    pub weights: [Vec<(u64, f64)>; 2],
    pub adjusted: [Option<Adjusted>; 2],
}

/// Why a checkpoint does not fit the World it is restored into.
#[derive(Debug, thiserror::Error)]
pub enum RestoreError {
    #[error("the checkpoint has {saved} {what}, the scene {scene}")]
    Count { what: &'static str, saved: usize, scene: usize },
    #[error("the checkpoint's {what} \"{saved}\" is \"{scene}\" in the scene")]
    Name { what: &'static str, saved: String, scene: String },
    #[error("the checkpoint names an entity the scene does not make ({0:#x})")]
    Entity(u64),
    #[error("layer \"{0}\": its {1} could not be put back in the saved order")]
    Order(String, &'static str),
}

impl Checkpoint {
    /// The checkpoint as CBOR (every f64 bit-exact).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        ciborium::into_writer(self, &mut out).expect("a checkpoint encodes");
        out
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, String> {
        ciborium::from_reader(bytes).map_err(|e| e.to_string())
    }
}

fn bits(e: Entity) -> u64 {
    e.to_bits()
}

fn list<C: Component>(world: &World, e: Entity, get: impl Fn(&C) -> &[Entity]) -> Vec<Entity> {
    world.get::<C>(e).map_or(Vec::new(), |c| get(c).to_vec())
}

/// The entities with `C`, in entity order (the same in a fresh World of the same scene).
fn sorted_with<C: Component>(world: &mut World) -> Vec<Entity> {
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
        .get_resource::<crate::log::LogState>()
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

/// Saved entity bits -> the restored World's entity: the scene's own keep theirs, what a
/// remesh made is spawned again.
#[derive(Default)]
struct Remap(HashMap<u64, Entity>);

impl Remap {
    fn get(&self, world: &World, b: u64) -> Result<Entity, RestoreError> {
        if let Some(&e) = self.0.get(&b) {
            return Ok(e);
        }
        let e = Entity::try_from_bits(b).ok_or(RestoreError::Entity(b))?;
        world.get_entity(e).map(|_| e).map_err(|_| RestoreError::Entity(b))
    }

    fn all<const N: usize>(&self, world: &World, b: [u64; N]) -> Result<[Entity; N], RestoreError> {
        let mut out = [Entity::PLACEHOLDER; N];
        for (o, b) in out.iter_mut().zip(b) {
            *o = self.get(world, b)?;
        }
        Ok(out)
    }
}

/// Puts `cp` into `world`, a World freshly spawned from the scene `cp` was saved from.
pub fn restore(world: &mut World, cp: &Checkpoint) -> Result<(), RestoreError> {
    let layers = sorted_with::<Layer>(world);
    let patches = sorted_with::<Patch>(world);
    count("layers", cp.layers.len(), layers.len())?;
    count("patches", cp.patches.len(), patches.len())?;
    let mut remap = Remap::default();
    // Vertices first, everything else refers to them.
    for (&l, saved) in layers.iter().zip(&cp.layers) {
        let name = &world.get::<Layer>(l).expect("layer").name;
        if bits(l) != saved.id || *name != saved.name {
            return Err(RestoreError::Name { what: "layer", saved: saved.name.clone(), scene: name.clone() });
        }
        restore_vertices(world, l, saved, &mut remap)?;
    }
    for (&l, saved) in layers.iter().zip(&cp.layers) {
        restore_faces(world, l, saved, &mut remap)?;
        restore_edges(world, l, saved, &mut remap)?;
        restore_tets(world, l, saved)?;
        restore_springs(world, l, saved, &mut remap)?;
        restore_anchors(world, l, saved, &remap)?;
        world.get_mut::<TopologyEpoch>(l).expect("layer").0 = saved.epoch;
        match saved.remesh {
            Some(r) => world.entity_mut(l).insert(r),
            None => world.entity_mut(l).remove::<RemeshReport>(),
        };
    }
    for (&p, saved) in patches.iter().zip(&cp.patches) {
        let name = &world.get::<Patch>(p).expect("patch").name;
        if bits(p) != saved.id || *name != saved.name {
            return Err(RestoreError::Name { what: "patch", saved: saved.name.clone(), scene: name.clone() });
        }
        let kernels = list::<PatchKernels>(world, p, |k| k.entities());
        count("kernels", saved.kernels.len(), kernels.len())?;
        for (&k, s) in kernels.iter().zip(&saved.kernels) {
            let side = |w: &[(u64, f64)]| -> Result<LayerWeights, RestoreError> {
                w.iter().map(|&(b, x)| Ok((remap.get(world, b)?, x))).collect()
            };
            let samples =
                KernelSamples { upper: side(&s.samples[0])?, lower: side(&s.samples[1])?, chart: s.chart.clone() };
            let weights =
                KernelWeights { upper: side(&s.weights[0])?, lower: side(&s.weights[1])?, adjusted: s.adjusted };
            world.entity_mut(k).insert((samples, weights));
        }
        if let Some(mut packed) = world.get_mut::<PackedPatch>(p) {
            packed.carry = Some(saved.carry.clone());
        }
    }
    let colour_scales = cp.log.1.iter().map(|&(l, x)| Ok((remap.get(world, l)?, x))).collect::<Result<_, _>>()?;
    world.insert_resource(crate::log::LogState { rest_logged: cp.log.0, colour_scales });
    let mut clock = world.resource_mut::<SimClock>();
    (clock.frame, clock.time) = (cp.frame, cp.time);
    Ok(())
}

fn count(what: &'static str, saved: usize, scene: usize) -> Result<(), RestoreError> {
    (saved == scene).then_some(()).ok_or(RestoreError::Count { what, saved, scene })
}

/// A layer's list made the saved one: entities the saved run no longer had are despawned, the
/// ones it made are spawned (`spawn`) and mapped. Returns the list's entities, in saved order.
fn relist(
    world: &mut World,
    current: Vec<Entity>,
    saved: &[u64],
    remap: &mut Remap,
    mut spawn: impl FnMut(&mut World, usize) -> Result<Entity, RestoreError>,
) -> Result<Vec<Entity>, RestoreError> {
    if current.iter().map(|&e| bits(e)).eq(saved.iter().copied()) {
        return Ok(current);
    }
    let keep: HashSet<u64> = saved.iter().copied().collect();
    for &e in current.iter().filter(|e| !keep.contains(&bits(**e))) {
        world.despawn(e);
    }
    let alive: HashSet<u64> = current.iter().map(|&e| bits(e)).filter(|b| keep.contains(b)).collect();
    let mut out = Vec::with_capacity(saved.len());
    for (i, &b) in saved.iter().enumerate() {
        if alive.contains(&b) {
            out.push(Entity::from_bits(b));
        } else {
            let e = spawn(world, i)?;
            remap.0.insert(b, e);
            out.push(e);
        }
    }
    Ok(out)
}

fn check_order<C: Component>(
    world: &World,
    l: Entity,
    get: impl Fn(&C) -> &[Entity],
    want: &[Entity],
    what: &'static str,
) -> Result<(), RestoreError> {
    let now = list::<C>(world, l, get);
    if now != want {
        return Err(RestoreError::Order(world.get::<Layer>(l).expect("layer").name.clone(), what));
    }
    Ok(())
}

fn restore_vertices(world: &mut World, l: Entity, saved: &LayerState, remap: &mut Remap) -> Result<(), RestoreError> {
    let current = list::<LayerVertices>(world, l, |c| c.entities());
    let ids: Vec<u64> = saved.vertices.iter().map(|v| v.id).collect();
    let spawn = |world: &mut World, i: usize| {
        let v = &saved.vertices[i];
        Ok(world.spawn((VertexOf(l), MaterialPos(v.uv), RestPos(v.rest), Position(v.x))).id())
    };
    let ents = relist(world, current, &ids, remap, spawn)?;
    check_order::<LayerVertices>(world, l, |c| c.entities(), &ents, "vertices")?;
    for (&e, v) in ents.iter().zip(&saved.vertices) {
        let mut e = world.entity_mut(e);
        e.insert((MaterialPos(v.uv), RestPos(v.rest), Position(v.x), Velocity(v.v), Mass(v.mass), Prescribed(v.fixed)));
    }
    Ok(())
}

fn restore_faces(world: &mut World, l: Entity, saved: &LayerState, remap: &mut Remap) -> Result<(), RestoreError> {
    let current = list::<LayerFaces>(world, l, |c| c.entities());
    let ids: Vec<u64> = saved.faces.iter().map(|f| f.id).collect();
    let spawn = |world: &mut World, i: usize| {
        let verts = remap.all(world, saved.faces[i].verts)?;
        Ok(world.spawn((FaceVerts(verts), FaceOf(l))).id())
    };
    // (the closure borrows remap immutably; new faces are mapped after)
    let mut fresh = Remap::default();
    let ents = relist(world, current, &ids, &mut fresh, spawn)?;
    remap.0.extend(fresh.0);
    check_order::<LayerFaces>(world, l, |c| c.entities(), &ents, "faces")?;
    for (&e, f) in ents.iter().zip(&saved.faces) {
        let verts = remap.all(world, f.verts)?;
        let mut e = world.entity_mut(e);
        e.insert(FaceVerts(verts));
        match f.rest {
            Some((b, volume)) => e.insert(FaceRest(MembraneRest { b, volume })),
            None => e.remove::<FaceRest>(),
        };
        match f.prestrain {
            Some(p) => e.insert(FacePrestrain(p)),
            None => e.remove::<FacePrestrain>(),
        };
        match f.scale {
            Some(s) => e.insert(ModulusScale(s)),
            None => e.remove::<ModulusScale>(),
        };
    }
    Ok(())
}

fn restore_edges(world: &mut World, l: Entity, saved: &LayerState, remap: &mut Remap) -> Result<(), RestoreError> {
    let current = list::<LayerEdges>(world, l, |c| c.entities());
    let ids: Vec<u64> = saved.edges.iter().map(|d| d.id).collect();
    let spawn = |world: &mut World, i: usize| {
        let verts = remap.all(world, saved.edges[i].verts)?;
        Ok(world.spawn((EdgeVerts(verts), EdgeOf(l))).id())
    };
    let mut fresh = Remap::default();
    let ents = relist(world, current, &ids, &mut fresh, spawn)?;
    remap.0.extend(fresh.0);
    check_order::<LayerEdges>(world, l, |c| c.entities(), &ents, "edges")?;
    for (&e, d) in ents.iter().zip(&saved.edges) {
        let verts = remap.all(world, d.verts)?;
        let opposite = d.opposite.map(|o| remap.all(world, o)).transpose()?;
        let hinge = match &d.hinge {
            Some(h) => Some(Hinge {
                opposite: remap.all(world, h.opposite)?,
                rest: HingeRest { weight: h.weight, rest_phi: h.rest_phi },
                image: h.image.map(|i| remap.all(world, i)).transpose()?,
            }),
            None => None,
        };
        let mut e = world.entity_mut(e);
        e.insert(EdgeVerts(verts));
        match opposite {
            Some(o) => e.insert(EdgeOpposite(o)),
            None => e.remove::<EdgeOpposite>(),
        };
        match hinge {
            Some(h) => e.insert(h),
            None => e.remove::<Hinge>(),
        };
    }
    Ok(())
}

fn restore_tets(world: &mut World, l: Entity, saved: &LayerState) -> Result<(), RestoreError> {
    let tets = list::<LayerTets>(world, l, |c| c.entities());
    count("tetrahedra", saved.tets.len(), tets.len())?;
    for (&t, s) in tets.iter().zip(&saved.tets) {
        let mut e = world.entity_mut(t);
        e.insert(TetRestShape(TetRest { b: s.rest.0, volume: s.rest.1 }));
        match s.prestrain {
            Some(p) => e.insert(TetPrestrain(p)),
            None => e.remove::<TetPrestrain>(),
        };
    }
    Ok(())
}

fn restore_springs(world: &mut World, l: Entity, saved: &LayerState, remap: &mut Remap) -> Result<(), RestoreError> {
    let current = list::<LayerSprings>(world, l, |c| c.entities());
    let id = |s: &SpringState| match s {
        SpringState::Point { id, .. } | SpringState::Face { id, .. } => *id,
    };
    let ids: Vec<u64> = saved.springs.iter().map(id).collect();
    let spawn = |world: &mut World, _: usize| Ok(world.spawn(SpringOf(l)).id());
    let mut fresh = Remap::default();
    let ents = relist(world, current, &ids, &mut fresh, spawn)?;
    remap.0.extend(fresh.0);
    check_order::<LayerSprings>(world, l, |c| c.entities(), &ents, "springs")?;
    for (&e, s) in ents.iter().zip(&saved.springs) {
        match *s {
            SpringState::Point { a, b, stiffness, .. } => {
                let spring = Spring { a: remap.get(world, a)?, b: remap.get(world, b)?, stiffness };
                world.entity_mut(e).remove::<FaceSpring>().insert(spring);
            }
            SpringState::Face { a, b, w, stiffness, .. } => {
                let spring = FaceSpring { a: remap.get(world, a)?, b: remap.all(world, b)?, w, stiffness };
                world.entity_mut(e).remove::<Spring>().insert(spring);
            }
        }
    }
    Ok(())
}

fn restore_anchors(world: &mut World, l: Entity, saved: &LayerState, remap: &Remap) -> Result<(), RestoreError> {
    let anchors = list::<LayerAnchors>(world, l, |c| c.entities());
    count("anchors", saved.anchors.len(), anchors.len())?;
    for (&a, s) in anchors.iter().zip(&saved.anchors) {
        let skin = match s.skin[..] {
            [v] => SkinPoint::Vertex(remap.get(world, v)?),
            [a, b, c] => SkinPoint::Face(remap.all(world, [a, b, c])?),
            _ => return Err(RestoreError::Count { what: "anchor skin vertices", saved: s.skin.len(), scene: 3 }),
        };
        let (position, step, walked, jump) = s.state;
        let anchor = Anchor { skin, body: SurfacePoint { face: s.face, st: s.st }, stiffness: s.stiffness };
        world.entity_mut(a).insert((anchor, AnchorState { position, step, walked, jump }));
    }
    Ok(())
}
