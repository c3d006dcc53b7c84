//! A patch's `contact`: validated and converted to SI (`model::Contact`), with what it needs
//! of the rest of the patch, and a start state whose shell surfaces do not cross.

use super::built::{BuiltLayer, BuiltPatch, ContactWith, LayerMesh};
use super::context::Builder;
use super::error::SceneError;
use super::schema::{ContactSpec, PatchSpec, Scene};
use crate::contact::{Surface, SurfaceLayer};
use crate::model::{Contact, LayerKind};
use crate::solve::SolveMode;
use glam::DVec3;

impl Builder {
    /// `layers`: the patch's own layers (its body's excluded); `len`: metres per length unit.
    pub(super) fn contact(
        &self,
        at: &str,
        c: &ContactSpec,
        p: &PatchSpec,
        layers: &[BuiltLayer],
        len: f64,
    ) -> Result<Contact, SceneError> {
        let positive = |field: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v * len)
            } else {
                Err(self.err(format!("{at}.{field}"), format!("must be a positive length, not {v}")))
            }
        };
        let thickness = positive("thickness", c.thickness)?;
        let reach = match c.d_hat {
            Some(d) => positive("d_hat", d)?,
            None => 0.5 * thickness,
        };
        if !(c.friction.is_finite() && c.friction >= 0.0) {
            let message = format!("must be a friction coefficient (0 or more), not {}", c.friction);
            return Err(self.err(format!("{at}.friction"), message));
        }
        // (a thickness or reach beyond the patch's extent makes every pair of its surfaces
        // active: a d_hat of 1e300 held one frame of the pressed sheet for 430 s)
        let (lo, hi) = layers
            .iter()
            .filter(|l| matches!(l.kind, LayerKind::Shell | LayerKind::Kinematic))
            .flat_map(|l| l.mesh.rest())
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
        let extent = (hi - lo).length();
        for (field, v) in [("thickness", thickness), ("d_hat", reach)] {
            if extent.is_finite() && v > extent {
                let message = format!(
                    "{:.3e} m is more than the patch's extent ({extent:.3e} m): every pair of its surfaces would \
                     touch",
                    v
                );
                return Err(self.err(format!("{at}.{field}"), message));
            }
        }
        let sticking = match c.sticking {
            Some(s) => positive("sticking", s)?,
            None => 0.01 * thickness,
        };
        // What the contact solve does not combine with yet.
        let refuse = |why: &str| Err(self.err(at.to_string(), format!("contact {why} is not supported yet")));
        if p.solver.globalization == crate::solve::Globalization::TrustRegion {
            return refuse("with the TrustRegion globalization (its steps take no collision bound)");
        }
        // (a remeshed layer settles under the collision bound, `solve::settle`; the region solve
        // after it is a sub-problem without the patch's other surfaces)
        if layers.iter().any(|l| l.remesh.is_some_and(|r| r.local_solve)) {
            return refuse("on a remeshed layer with local_solve");
        }
        if p.solver.mode != SolveMode::Quasistatic {
            return refuse("with dynamics (solver mode other than Quasistatic)");
        }
        if !layers.iter().any(|l| l.kind == LayerKind::Shell) {
            return Err(self.err(at.to_string(), "acts between shell layers, and the patch has none"));
        }
        // A start state that already crosses cannot be made feasible: refuse it by name. (Its
        // shells and the kinematic bodies in the patch, as the contact surface holds them.)
        let (mut tris, mut x, mut owner) = (Vec::new(), Vec::new(), Vec::new());
        for (i, l) in layers.iter().enumerate() {
            let LayerMesh::Surface(m) = &l.mesh else { continue };
            if !matches!(l.kind, LayerKind::Shell | LayerKind::Kinematic) {
                continue;
            }
            let base = x.len() as u32;
            x.extend_from_slice(&m.rest);
            for (f, t) in m.faces.iter().enumerate() {
                tris.push(t.map(|v| v + base));
                owner.push((i, f));
            }
        }
        if let Some(&(a, b)) = crate::mesh::crossing::crossing_pairs(&tris, &x).first() {
            let name = |k: usize| format!("face {} of layer \"{}\"", owner[k].1, layers[owner[k].0].name);
            let message = format!("the start state already crosses: {} passes through {}", name(a), name(b));
            return Err(self.err(at.to_string(), message));
        }
        Ok(Contact { thickness, reach, friction: c.friction, sticking })
    }

    /// `patches[pi].contact.with`: each name a scene body or another patch with contact of its
    /// own (so that the two are solved in turn, each against the other's latest surface), whose
    /// surfaces are not remeshed.
    pub(super) fn contact_with(
        &self,
        pi: usize,
        names: &[String],
        scene: &Scene,
        patches: &[BuiltPatch],
    ) -> Result<Vec<ContactWith>, SceneError> {
        let at = |i: usize| format!("patches[{pi}] (\"{}\").contact.with[{i}]", scene.patches[pi].name);
        let mut out = Vec::new();
        for (i, name) in names.iter().enumerate() {
            let with = if let Some(b) = scene.bodies.iter().position(|b| &b.name == name) {
                if patches[pi].body == Some(b) {
                    return Err(self.err(at(i), format!("the patch sits on \"{name}\": name another body")));
                }
                ContactWith::Body(b)
            } else if let Some(q) = scene.patches.iter().position(|q| &q.name == name) {
                if q == pi {
                    return Err(self.err(at(i), "names the patch itself (its own layers touch already)"));
                }
                if patches[q].contact.is_none() {
                    let message = format!("the patch \"{name}\" has no contact of its own: give it one");
                    return Err(self.err(at(i), message));
                }
                ContactWith::Patch(q)
            } else {
                let known: Vec<String> = scene
                    .bodies
                    .iter()
                    .map(|b| &b.name)
                    .chain(scene.patches.iter().map(|q| &q.name))
                    .filter(|n| *n != &scene.patches[pi].name)
                    .map(|n| format!("\"{n}\""))
                    .collect();
                let message = format!("no body or patch is named \"{name}\" (known: {})", known.join(", "));
                return Err(self.err(at(i), message));
            };
            if out.contains(&with) {
                return Err(self.err(at(i), format!("names \"{name}\" twice")));
            }
            out.push(with);
        }
        Ok(out)
    }

    /// A start state with a pair of the contact surfaces (the patch's own, and what `with`
    /// names) closer than the barrier's offset, whose barrier would be infinite: the patch's own
    /// shells are pushed out of it, with a note, where that is a small move that crosses
    /// nothing; otherwise it is refused, naming the two layers.
    pub(super) fn start_clearance(
        &self,
        pi: usize,
        bodies: &[BuiltPatch],
        patches: &mut [BuiltPatch],
    ) -> Result<(), SceneError> {
        let moved = self.pushed_out(pi, bodies, patches)?;
        for (layer, rest) in moved {
            if let LayerMesh::Surface(m) = &mut patches[pi].layers[layer].mesh {
                m.rest = rest;
            }
        }
        Ok(())
    }

    /// The new rest positions of the patch's own shell layers that `start_clearance` moves.
    fn pushed_out(
        &self,
        pi: usize,
        bodies: &[BuiltPatch],
        patches: &[BuiltPatch],
    ) -> Result<Vec<(usize, Vec<DVec3>)>, SceneError> {
        let p = &patches[pi];
        let with = &p.contact_with;
        let Some(c) = p.contact else { return Ok(Vec::new()) };
        // (layer, its patch's name, its index among this patch's layers: Some where this patch
        // moves it)
        let first = usize::from(p.body.is_some());
        // (a body under KCK18 anchors is not a contact surface: the skin starts on it)
        let anchored = p.anchors.as_ref().map(|a| a.body);
        let mut parts: Vec<(&BuiltLayer, &str, Option<usize>)> = p.layers[first..]
            .iter()
            .enumerate()
            .map(|(i, l)| (i + first, l))
            .filter(|(i, _)| anchored != Some(*i))
            .map(|(i, l)| (l, p.name.as_str(), Some(i)))
            .collect();
        for w in with {
            match *w {
                ContactWith::Body(b) => parts.push((&bodies[b].layers[0], &bodies[b].name, None)),
                ContactWith::Patch(q) => {
                    let o = &patches[q];
                    let own = &o.layers[usize::from(o.body.is_some())..];
                    parts.extend(own.iter().filter(|l| l.kind == LayerKind::Shell).map(|l| (l, o.name.as_str(), None)));
                }
            }
        }
        let (mut layers, mut x, mut kept, mut ends) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, (l, _, own)) in parts.iter().enumerate() {
            let LayerMesh::Surface(m) = &l.mesh else { continue };
            let shell = l.kind == LayerKind::Shell;
            if !shell && l.kind != LayerKind::Kinematic {
                continue;
            }
            let base = x.len() as u32;
            x.extend_from_slice(&m.rest);
            layers.push(SurfaceLayer {
                triangles: m.faces.iter().map(|t| t.map(|v| v + base)).collect(),
                half_thickness: if shell { 0.5 * c.thickness } else { 0.0 },
                moving: shell && own.is_some(),
            });
            kept.push(i);
            ends.push(x.len() as u32);
        }
        let at_layer = |k: usize| kept.iter().position(|&i| parts[i].2 == Some(k)).map(|i| i as u32);
        let bound: Vec<(u32, u32)> = p
            .couplings
            .iter()
            .filter(|k| k.upper >= first && k.lower >= first)
            .filter_map(|k| Some((at_layer(k.upper)?, at_layer(k.lower)?)))
            // (two skins bound to each other touch: `systems::assemble::contact_surface`)
            .filter(|&(a, b)| !(layers[a as usize].moving && layers[b as usize].moving))
            .collect();
        let surface = Surface::new(&layers, x.clone(), c.reach, &bound);
        let moving: Vec<bool> =
            (0..x.len() as u32).map(|v| ends.iter().position(|&e| v < e).is_some_and(|l| layers[l].moving)).collect();
        let pairs = crate::contact::broad::candidates(&surface, &x, None, surface.max_offset());
        let inside = pairs
            .iter()
            .map(|q| (q.squared_distance(&crate::contact::gather(&x, &q.v)).sqrt(), q))
            .filter(|(d, q)| *d <= q.barrier.offset)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((d, q)) = inside else { return Ok(Vec::new()) };
        if let Some((pushed, most)) = push_out(&pairs, &x, &moving, &layers, c.thickness) {
            let mut out = Vec::new();
            for (l, &i) in kept.iter().enumerate() {
                let start = if l == 0 { 0 } else { ends[l - 1] } as usize;
                let range = start..ends[l] as usize;
                if let (Some(k), true) = (parts[i].2, layers[l].moving) {
                    if pushed[range.clone()] != x[range.clone()] {
                        out.push((k, pushed[range].to_vec()));
                    }
                }
            }
            self.note(format!(
                "warning: patches[{pi}] (\"{}\").contact: the start state was closer than the contact thickness \
                 ({d:.3e} m where the barrier keeps {:.3e} m): its shells were pushed out by up to {most:.3e} m",
                p.name, q.barrier.offset
            ));
            return Ok(out);
        }
        let owner = |v: u32| {
            let l = ends.iter().position(|&e| v < e).unwrap_or(0);
            let (layer, patch, _) = parts[kept[l]];
            format!("layer \"{}\" of \"{patch}\"", layer.name)
        };
        let message = format!(
            "the start state is closer than the contact thickness: {} and {} are {d:.3e} m apart where the \
             barrier keeps {:.3e} m: move them apart or give a smaller thickness",
            owner(q.v[0]),
            owner(q.v[3]),
            q.barrier.offset
        );
        Err(self.err(format!("patches[{pi}] (\"{}\").contact", p.name), message))
    }
}

/// Rounds of `push_out`, the margin it leaves over each pair's offset, and the least distance
/// over the offset it pushes out from: a start deeper inside is refused (a thickness far above
/// the layers' spacing would otherwise move every vertex, 50 rounds over every pair).
const PUSH_ROUNDS: usize = 50;
const PUSH_MARGIN: f64 = 1e-3;
const PUSH_LEAST: f64 = 0.25;

/// The start state with every pair closer than its offset pushed apart by moving its `moving`
/// vertices along the pair's separation (Gauss-Seidel over the pairs, linearized: a vertex
/// moves in proportion to its closest-point weight), and the largest move; None when a pair
/// lies deeper than `PUSH_LEAST` of its offset, has no moving vertex, a move exceeds `limit`,
/// the rounds run out, or the result crosses.
fn push_out(
    pairs: &[crate::contact::Pair],
    x: &[DVec3],
    moving: &[bool],
    layers: &[SurfaceLayer],
    limit: f64,
) -> Option<(Vec<DVec3>, f64)> {
    use crate::contact::distance::closest_weights;
    let mut y = x.to_vec();
    let mut clear = false;
    for _ in 0..PUSH_ROUNDS {
        clear = true;
        for q in pairs {
            let at = crate::contact::gather(&y, &q.v);
            let d = q.squared_distance(&at).sqrt();
            let goal = q.barrier.offset * (1.0 + PUSH_MARGIN);
            if d > q.barrier.offset {
                continue;
            }
            clear = false;
            if d < PUSH_LEAST * q.barrier.offset {
                return None;
            }
            let w = closest_weights(q.kind, &at);
            let sep: DVec3 = q.v.iter().zip(&w).map(|(&v, &wi)| wi * y[v as usize]).sum();
            let free = |i: usize| moving[q.v[i] as usize];
            let norm: f64 = (0..4).filter(|&i| free(i)).map(|i| w[i] * w[i]).sum();
            if norm <= 0.0 {
                return None;
            }
            let s = (goal - d) / norm;
            for i in (0..4).filter(|&i| free(i)) {
                y[q.v[i] as usize] += s * w[i] * sep / d;
            }
        }
        if clear {
            break;
        }
    }
    let most = y.iter().zip(x).map(|(a, b)| (*a - *b).length()).fold(0.0, f64::max);
    let tris: Vec<[u32; 3]> = layers.iter().flat_map(|l| l.triangles.iter().copied()).collect();
    (clear && most <= limit && crate::mesh::crossing::crossing_pairs(&tris, &y).is_empty()).then_some((y, most))
}
