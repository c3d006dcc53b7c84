//! Spawning a built scene into a World: one entity per patch, layer, vertex, edge, face, tet
//! and spring, with their relationships.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use rand::{Rng, SeedableRng};

use super::built::{BuiltDriver, BuiltLayer, BuiltPatch, BuiltScene, ContactWith, LayerMesh};
use super::geometry::{final_layers, lumped_mass, prescribed, shell_rest, tet_rest};
use crate::mesh;
use crate::mesh::imperfection::Imperfection;
use crate::model::*;
use crate::physics::hinge::HingeRest;

/// Spawns the shared bodies, then every patch of the scene, and inserts the clock. Returns the
/// patch entities.
pub fn spawn(world: &mut World, scene: &BuiltScene) -> Vec<Entity> {
    world.insert_resource(SimClock { frame: 0, time: 0.0, dt: scene.scene.frame_time });
    world.init_resource::<Timings>();
    world.init_resource::<FrameReport>();
    world.init_resource::<SimFailure>();
    // A body is an owner of one layer, moved and logged like a patch's, and never solved.
    let bodies: Vec<SharedBody> = scene
        .bodies
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let (_, mut layers, mut vertices) = spawn_patch(world, b, i as u32, Role::Body);
            (layers.remove(0), vertices.remove(0))
        })
        .collect();
    let first = bodies.len() as u32;
    let spawned: Vec<(Entity, Vec<Entity>)> = scene
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (patch, layers, _) = spawn_patch(world, p, first + i as u32, Role::Patch(p.body.map(|b| &bodies[b])));
            (patch, layers)
        })
        .collect();
    // What else each patch's skin touches: a body's layer, another patch's skin layers.
    for (p, (patch, _)) in scene.patches.iter().zip(&spawned) {
        let layers: Vec<Entity> = p
            .contact_with
            .iter()
            .flat_map(|w| match *w {
                ContactWith::Body(b) => vec![bodies[b].0],
                ContactWith::Patch(q) => {
                    let other = &scene.patches[q].layers;
                    (0..other.len()).filter(|&l| other[l].kind == LayerKind::Shell).map(|l| spawned[q].1[l]).collect()
                }
            })
            .collect();
        if !layers.is_empty() {
            world.entity_mut(*patch).insert(ContactObstacles(layers));
        }
    }
    spawned.into_iter().map(|(patch, _)| patch).collect()
}

/// A spawned body's layer and the entities of its mesh vertices.
type SharedBody = (Entity, Vec<Entity>);

/// What `spawn_patch` spawns: a shared body (no solver), or a patch, on the spawned body that is
/// its layer 0 if it has one.
enum Role<'a> {
    Body,
    Patch(Option<&'a SharedBody>),
}

/// Spawns a patch or a body (`Role`). Returns the patch, its layers and their vertices.
fn spawn_patch(world: &mut World, p: &BuiltPatch, index: u32, role: Role) -> (Entity, Vec<Entity>, Vec<Vec<Entity>>) {
    let patch = world.spawn(Patch { name: p.name.clone(), index }).id();
    let (solved, body) = match role {
        Role::Body => (false, None),
        Role::Patch(body) => (true, body),
    };
    if solved {
        world.entity_mut(patch).insert(p.solver.clone());
    }
    let mut layer_vertices: Vec<Vec<Entity>> = Vec::new();
    let mut layers = Vec::new();
    let mut fixed = prescribed(p);
    // Shared vertices belong to an earlier layer: their pins and masses go to the owner.
    let mut mass: Vec<Vec<f64>> = p.layers.iter().map(lumped_mass).collect();
    for li in (0..p.layers.len()).rev() {
        for (v, s) in p.layers[li].shared.iter().enumerate() {
            if let Some((owner, ov)) = *s {
                let f = fixed[li][v];
                let m = mass[li][v];
                for k in 0..3 {
                    fixed[owner][ov as usize][k] |= f[k];
                }
                mass[owner][ov as usize] += m;
            }
        }
    }
    let mut all_rest = Vec::new();
    for (li, l) in final_layers(p, &fixed).into_iter().enumerate() {
        if let (0, Some((layer, verts))) = (li, body) {
            all_rest.extend_from_slice(l.mesh.rest());
            layers.push(*layer);
            layer_vertices.push(verts.clone());
            continue;
        }
        let owners: Vec<Option<Entity>> =
            l.shared.iter().map(|s| s.map(|(ol, ov)| layer_vertices[ol][ov as usize])).collect();
        let (layer, verts) = spawn_layer(world, patch, &l, li as u32, &fixed[li], &mass[li], &owners);
        // A remesh gives its new vertices the same smooth imperfection.
        if let (Some(q), Some(_)) = (&p.perturbation, l.remesh) {
            if let Some(cell) = q.cell {
                let imperfection = Imperfection::new(q.amplitude, cell, q.seed).with_waves(super::geometry::waves(q));
                world.entity_mut(layer).insert(LayerImperfection(imperfection));
            }
        }
        all_rest.extend_from_slice(l.mesh.rest());
        layers.push(layer);
        layer_vertices.push(verts);
    }
    let (lo, hi) = mesh::bounds(&all_rest);
    let (mut motion, captures) = spawn_drivers(world, p, &layers, &layer_vertices, 0.5 * (lo + hi));
    for (li, l) in p.layers.iter().enumerate() {
        if let Some(e) = &l.embedding {
            motion.motions.push(embedded_motion(world, &motion, p, li, layers[e.base], &layers));
        }
    }
    for c in &p.couplings {
        let batch: Vec<_> = c
            .kernels
            .iter()
            .map(|&shape| {
                let (upper, lower) = (layers[c.upper], layers[c.lower]);
                let kernel = Kernel { upper, lower, shape, adjust: c.adjust, distance: c.distance };
                (kernel, KernelOf(patch), KernelSamples::default(), KernelWeights::default())
            })
            .collect();
        world.spawn_batch(batch);
    }
    if let Some(a) = &p.anchors {
        spawn_anchors(world, p, a, &layers, &layer_vertices);
        world.entity_mut(patch).insert(AnchorReport::default());
    }
    if !motion.motions.is_empty() {
        world.entity_mut(patch).insert((motion, LoadHeld::default()));
    }
    if let Some(c) = p.contact {
        world.entity_mut(patch).insert(c);
    }
    if !captures.is_empty() {
        world.entity_mut(patch).insert(PatchCaptures(captures));
    }
    // The solve packs the body only where kernels hold the patch to it (anchors hold targets).
    if body.is_some() && p.couplings.iter().any(|c| c.lower == 0 || c.upper == 0) {
        world.entity_mut(patch).insert(PatchBodies(vec![layers[0]]));
    }
    if solved {
        world.entity_mut(patch).insert((crate::solve::PackedPatch::default(), PackedIndex::default()));
    }
    (patch, layers, layer_vertices)
}

/// The patch's drivers (scene `drivers`): motions (about `centre`, the rest bounding box's) and
/// captures returned for the patch entity, attachment springs, plane-strain and periodic ties
/// and seam hinges spawned.
fn spawn_drivers(
    world: &mut World,
    p: &BuiltPatch,
    layers: &[Entity],
    layer_vertices: &[Vec<Entity>],
    centre: glam::DVec3,
) -> (PatchMotion, Vec<Capture>) {
    let mut motion = PatchMotion { centre, ..Default::default() };
    let mut captures = Vec::new();
    for d in &p.drivers {
        match d {
            BuiltDriver::Compress { layers: ls, axis, keyframes, predict } => motion.motions.push(Motion {
                layers: ls.iter().map(|&i| layers[i]).collect(),
                // Implicit Euler's own predictor x_n + h v_n already carries the compression
                // (LK14 eq. 5.2): moving x_n too would count the increment twice in x_hat.
                kind: MotionKind::Compress { axis: *axis, predict: *predict && !p.solver.mode.is_dynamic() },
                keyframes: Keyframes(keyframes.clone()),
            }),
            BuiltDriver::Joint { layers: ls, joint, keyframes } => motion.motions.push(Motion {
                layers: ls.iter().map(|&i| layers[i]).collect(),
                kind: MotionKind::Joint(*joint),
                keyframes: Keyframes(keyframes.clone()),
            }),
            BuiltDriver::Bend { layers: ls, axis, keyframes } => motion.motions.push(Motion {
                layers: ls.iter().map(|&i| layers[i]).collect(),
                kind: MotionKind::Bend { axis: *axis },
                keyframes: Keyframes(keyframes.clone()),
            }),
            BuiltDriver::BlendShape { layer, targets, interpolation } => motion.motions.push(Motion {
                layers: vec![layers[*layer]],
                kind: MotionKind::Blend(BlendShape {
                    targets: targets.iter().map(|(d, k)| (d.clone(), Keyframes(k.clone()))).collect(),
                    interpolation: *interpolation,
                }),
                keyframes: Keyframes(Vec::new()),
            }),
            BuiltDriver::Rig { layer, rig } => motion.motions.push(Motion {
                layers: vec![layers[*layer]],
                kind: MotionKind::Rig(rig.clone()),
                keyframes: Keyframes(Vec::new()),
            }),
            BuiltDriver::Sequence { layer, frames, start } => motion.motions.push(Motion {
                layers: vec![layers[*layer]],
                kind: MotionKind::Sequence { frames: frames.clone(), start: *start },
                keyframes: Keyframes(Vec::new()),
            }),
            BuiltDriver::Attach { layer, to, springs, k_area } => {
                let mut attached = world.entity_mut(layers[*layer]);
                let mut list = attached.get::<Attachments>().cloned().unwrap_or_default();
                list.0.push((layers[*to], *k_area));
                attached.insert(list);
                let batch: Vec<_> = springs
                    .iter()
                    .map(|&(a, b, k)| {
                        (
                            Spring {
                                a: layer_vertices[*layer][a as usize],
                                b: layer_vertices[*to][b as usize],
                                stiffness: k,
                            },
                            SpringOf(layers[*layer]),
                        )
                    })
                    .collect();
                world.spawn_batch(batch);
            }
            BuiltDriver::PlaneStrain { layers: ls, axis, ties } => {
                for (&l, pairs) in ls.iter().zip(ties) {
                    let mut dofs = [true; 3];
                    dofs[*axis] = false;
                    for &(v, m) in pairs {
                        let master = layer_vertices[l][m as usize];
                        world.entity_mut(layer_vertices[l][v as usize]).insert(Tied { master, dofs });
                    }
                }
            }
            BuiltDriver::Periodic { layers: ls, axis, ties, seams } => {
                for (&l, seam) in ls.iter().zip(seams) {
                    let Some(b) = p.layers[l].bending else { continue };
                    let rest = p.layers[l].mesh.rest();
                    let vs = &layer_vertices[l];
                    for s in seam {
                        let shift = rest[s.image.0 as usize] - rest[s.image.1 as usize];
                        let mut x = s.v.map(|i| rest[i as usize]);
                        x[3] += shift;
                        let hinge = Hinge {
                            opposite: [vs[s.v[2] as usize], vs[s.v[3] as usize]],
                            rest: HingeRest::from_rest(b.model, b.stiffness, x),
                            image: Some([vs[s.image.0 as usize], vs[s.image.1 as usize]]),
                        };
                        world.spawn((EdgeVerts([vs[s.v[0] as usize], vs[s.v[1] as usize]]), EdgeOf(layers[l]), hinge));
                    }
                }
                // Vertices already tied (by PlaneStrain) follow their master, which is tied here.
                for (&l, pairs) in ls.iter().zip(ties) {
                    let mut dofs = [true; 3];
                    dofs[*axis] = false;
                    for &(v, m) in pairs {
                        let (slave, master) = (layer_vertices[l][v as usize], layer_vertices[l][m as usize]);
                        if world.get::<Tied>(slave).is_none() {
                            world.entity_mut(slave).insert(Tied { master, dofs });
                        }
                    }
                }
            }
            BuiltDriver::Capture { layers: ls, frame, fraction, maps } => {
                for (&l, map) in ls.iter().zip(maps) {
                    captures.push(Capture {
                        layers: vec![layers[l]],
                        frame: *frame,
                        fraction: *fraction,
                        map: map.clone(),
                    });
                }
            }
            BuiltDriver::Pin { .. } => {}
        }
    }
    (motion, captures)
}

/// KCK18: the body's walking surface on the body layer, the method on the skin layer, and one
/// anchor entity per skin vertex and face barycentre.
fn spawn_anchors(
    world: &mut World,
    p: &BuiltPatch,
    a: &super::built::BuiltAnchors,
    layers: &[Entity],
    layer_vertices: &[Vec<Entity>],
) {
    let rest = p.layers[a.body].mesh.rest().to_vec();
    let state = |point| AnchorState { position: a.surface.position(&rest, point), ..Default::default() };
    let skin = layers[a.skin];
    let verts = &layer_vertices[a.skin];
    let mut batch: Vec<_> = a
        .vertex
        .iter()
        .map(|&(v, body, stiffness)| {
            let anchor = Anchor { skin: SkinPoint::Vertex(verts[v as usize]), body, stiffness };
            (anchor, state(body), AnchorOf(skin))
        })
        .collect();
    if let LayerMesh::Surface(m) = &p.layers[a.skin].mesh {
        batch.extend(a.face.iter().map(|&(f, body, stiffness)| {
            let face = m.faces[f as usize].map(|i| verts[i as usize]);
            (Anchor { skin: SkinPoint::Face(face), body, stiffness }, state(body), AnchorOf(skin))
        }));
    }
    world.spawn_batch(batch);
    let vertex_faces = a.surface.vertex_faces(rest.len());
    world.entity_mut(layers[a.body]).insert(AnchorBody { surface: a.surface.clone(), rest, vertex_faces });
    world.entity_mut(skin).insert(Anchoring { body: layers[a.body], method: a.method, slide: a.slide });
}

/// Spawns a layer and its own vertices; `owners[v]` is the entity of a vertex shared with an
/// earlier layer. Returns the layer and the entity of every mesh vertex.
fn spawn_layer(
    world: &mut World,
    patch: Entity,
    l: &BuiltLayer,
    index: u32,
    fixed: &[[bool; 3]],
    mass: &[f64],
    owners: &[Option<Entity>],
) -> (Entity, Vec<Entity>) {
    let mut e = world.spawn((Layer { name: l.name.clone(), kind: l.kind, index }, LayerOf(patch), TopologyEpoch(0)));
    if let Some(m) = l.material {
        e.insert(m);
    }
    if let Some(h) = l.thickness {
        e.insert(Thickness(h));
    }
    if let Some(b) = l.bending {
        e.insert(b);
    }
    if let Some(p) = &l.properties {
        e.insert(p.clone());
    }
    if let Some(r) = l.remesh {
        e.insert((r, RemeshReport::default()));
        if let Some(p) = &l.prestrain {
            e.insert(p.clone());
        }
    }
    let layer = e.id();
    let rest = l.mesh.rest();
    let uv = l.mesh.material_positions();
    let own: Vec<usize> = (0..rest.len()).filter(|&i| owners[i].is_none()).collect();
    let spawned: Vec<Entity> = world
        .spawn_batch(own.iter().map(|&i| {
            (
                VertexOf(layer),
                MaterialPos(uv[i]),
                RestPos(rest[i]),
                Position(rest[i]),
                Velocity::default(),
                Mass(mass[i]),
                Prescribed(fixed[i]),
            )
        }))
        .collect();
    let mut next = spawned.into_iter();
    let verts: Vec<Entity> =
        owners.iter().map(|o| o.unwrap_or_else(|| next.next().expect("one per own vertex"))).collect();
    if let Some(uv) = &l.asset_uv {
        own.iter().for_each(|&i| {
            world.entity_mut(verts[i]).insert(AssetUv(uv[i]));
        });
    }
    let mut rng = l.randomize.map(|(a, seed)| (a, rand_pcg::Pcg64::seed_from_u64(seed)));
    let mut modulus = |n: usize| -> Option<Vec<f64>> {
        let (a, rng) = rng.as_mut()?;
        Some((0..n).map(|_| 1.0 + *a * rng.random_range(-1.0..=1.0)).collect())
    };
    match &l.mesh {
        LayerMesh::Surface(m) => {
            let shell = l.kind == LayerKind::Shell;
            let layer_rest = shell_rest(l);
            let scale = modulus(if shell { m.faces.len() } else { 0 });
            for (fi, f) in m.faces.iter().enumerate() {
                let mut e = world.spawn((FaceVerts(f.map(|i| verts[i as usize])), FaceOf(layer)));
                if !shell {
                    continue;
                }
                let data =
                    layer_rest.face(f.map(|i| m.rest[i as usize]), f.map(|i| uv[i as usize])).expect("checked mesh");
                e.insert(FaceRest(data.rest));
                if let Some(f0) = data.prestrain {
                    e.insert(FacePrestrain(f0));
                }
                if scale.is_some() || l.properties.is_some() {
                    e.insert(ModulusScale(scale.as_ref().map_or(1.0, |s| s[fi]) * data.young));
                }
            }
            // A hinge's stiffness follows its faces' moduli (mean of the two).
            let sorted = |mut k: [u32; 3]| {
                k.sort_unstable();
                k
            };
            let face_index: HashMap<[u32; 3], usize> = match scale {
                Some(_) => m.faces.iter().enumerate().map(|(i, f)| (sorted(*f), i)).collect(),
                None => HashMap::new(),
            };
            let hinge_scale = |q: [u32; 4]| -> f64 {
                let Some(s) = &scale else { return 1.0 };
                let face = |a: u32, b: u32, c: u32| face_index.get(&sorted([a, b, c])).map_or(1.0, |&i| s[i]);
                0.5 * (face(q[0], q[1], q[2]) + face(q[0], q[1], q[3]))
            };
            if shell {
                let bending = l.bending;
                let batch: Vec<_> = mesh::edges(&m.faces)
                    .into_iter()
                    .map(|e| {
                        let hinge = match (bending, e.is_interior()) {
                            (Some(b), true) => {
                                let q = [e.v[0], e.v[1], e.opposite[0], e.opposite[1]];
                                let (x, ends) = (q.map(|i| m.rest[i as usize]), e.v.map(|i| uv[i as usize]));
                                Some(Hinge {
                                    opposite: [verts[q[2] as usize], verts[q[3] as usize]],
                                    rest: layer_rest.hinge(&b, hinge_scale(q), x, ends),
                                    image: None,
                                })
                            }
                            _ => None,
                        };
                        (EdgeVerts([verts[e.v[0] as usize], verts[e.v[1] as usize]]), EdgeOf(layer), hinge)
                    })
                    .collect();
                for (ev, of, hinge) in batch {
                    let mut e = world.spawn((ev, of));
                    if let Some(h) = hinge {
                        e.insert(h);
                    }
                }
            }
        }
        LayerMesh::Volume(m) => {
            let scale = modulus(m.tets.len());
            for (ti, t) in m.tets.iter().enumerate() {
                let (rest, f0) = tet_rest(l, &m.rest, &uv, t);
                let rest = rest.expect("checked tets");
                let mut e = world.spawn((
                    TetVerts(t.map(|i| verts[i as usize])),
                    TetOf(layer),
                    TetRestShape(rest),
                    TetCell(m.cells[ti]),
                ));
                if let Some(f0) = f0 {
                    e.insert(TetPrestrain(f0));
                }
                if let Some(s) = &scale {
                    e.insert(ModulusScale(s[ti]));
                }
            }
        }
    }
    (layer, verts)
}

/// The motion of a layer embedded in `base` (issue 62), with the motions that move the base
/// (the body's, or the patch's own), which say when its load holds.
fn embedded_motion(
    world: &World,
    own: &PatchMotion,
    p: &BuiltPatch,
    li: usize,
    base: Entity,
    layers: &[Entity],
) -> Motion {
    let (l, layer) = (&p.layers[li], layers[li]);
    let e = l.embedding.as_ref().expect("called for embedded layers");
    let owner = world.get::<LayerOf>(base).map(|o| o.0);
    let carriers: Vec<Motion> = match owner.and_then(|o| world.get::<PatchMotion>(o)) {
        Some(body) => body.motions.iter().filter(|m| m.layers.contains(&base)).cloned().collect(),
        None => own.motions.iter().filter(|m| m.layers.contains(&base)).cloned().collect(),
    };
    let LayerMesh::Surface(m) = &l.mesh else { unreachable!("an embedded layer is a surface") };
    let embedding = Embedding { base, stencils: e.stencils.clone(), faces: m.faces.clone(), distance: e.distance };
    Motion {
        layers: vec![layer],
        kind: MotionKind::Embed { embedding: std::sync::Arc::new(embedding), carriers },
        keyframes: Keyframes(Vec::new()),
    }
}
