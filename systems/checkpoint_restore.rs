//! Restoring a checkpoint (`checkpoint`) into a World freshly spawned from its scene: the
//! scene's own entities keep theirs, what a remesh made is spawned again in saved order, and
//! every saved reference is mapped.

use std::collections::{HashMap, HashSet};

use bevy_ecs::prelude::*;
use skinsim::coupling::walk::SurfacePoint;
use skinsim::model::checkpoint::*;
use skinsim::model::*;
use skinsim::physics::hinge::HingeRest;
use skinsim::physics::membrane::MembraneRest;
use skinsim::physics::tet::TetRest;
use skinsim::solve::PackedPatch;

use crate::checkpoint::{bits, list, sorted_with};

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
    world.insert_resource(LogState { rest_logged: cp.log.0, colour_scales });
    let mut clock = world.resource_mut::<SimClock>();
    (clock.frame, clock.time) = (cp.frame, cp.time);
    Ok(())
}

fn count(what: &'static str, saved: usize, scene: usize) -> Result<(), RestoreError> {
    (saved == scene).then_some(()).ok_or(RestoreError::Count { what, saved, scene })
}

/// A layer's list made the saved one: entities the saved run no longer had are despawned, the
/// ones it made are spawned (`spawn`, given the mapping so far) and mapped after. Returns the
/// list's entities, in saved order.
fn relist(
    world: &mut World,
    current: Vec<Entity>,
    saved: &[u64],
    remap: &mut Remap,
    mut spawn: impl FnMut(&mut World, &Remap, usize) -> Result<Entity, RestoreError>,
) -> Result<Vec<Entity>, RestoreError> {
    if current.iter().map(|&e| bits(e)).eq(saved.iter().copied()) {
        return Ok(current);
    }
    let keep: HashSet<u64> = saved.iter().copied().collect();
    for &e in current.iter().filter(|e| !keep.contains(&bits(**e))) {
        world.despawn(e);
    }
    let alive: HashSet<u64> = current.iter().map(|&e| bits(e)).filter(|b| keep.contains(b)).collect();
    let (mut out, mut made) = (Vec::with_capacity(saved.len()), Vec::new());
    for (i, &b) in saved.iter().enumerate() {
        if alive.contains(&b) {
            out.push(Entity::from_bits(b));
        } else {
            let e = spawn(world, remap, i)?;
            made.push((b, e));
            out.push(e);
        }
    }
    remap.0.extend(made);
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
    let spawn = |world: &mut World, _: &Remap, i: usize| {
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
    let spawn = |world: &mut World, remap: &Remap, i: usize| {
        let verts = remap.all(world, saved.faces[i].verts)?;
        Ok(world.spawn((FaceVerts(verts), FaceOf(l))).id())
    };
    let ents = relist(world, current, &ids, remap, spawn)?;
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
    let spawn = |world: &mut World, remap: &Remap, i: usize| {
        let verts = remap.all(world, saved.edges[i].verts)?;
        Ok(world.spawn((EdgeVerts(verts), EdgeOf(l))).id())
    };
    let ents = relist(world, current, &ids, remap, spawn)?;
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
    let spawn = |world: &mut World, _: &Remap, _: usize| Ok(world.spawn(SpringOf(l)).id());
    let ents = relist(world, current, &ids, remap, spawn)?;
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
