//! A patch's `contact`: validated and converted to SI (`model::Contact`), with what it needs
//! of the rest of the patch, and a start state whose shell surfaces do not cross.

use super::built::{BuiltLayer, BuiltPatch, ContactWith, LayerMesh};
use super::context::Builder;
use super::error::SceneError;
use super::schema::{ContactSpec, PatchSpec, Scene};
use crate::model::{Contact, LayerKind};
use crate::solve::SolveMode;

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
        let sticking = match c.sticking {
            Some(s) => positive("sticking", s)?,
            None => 0.01 * thickness,
        };
        // What the contact solve does not combine with yet.
        let refuse = |why: &str| Err(self.err(at.to_string(), format!("contact {why} is not supported yet")));
        if p.solver.globalization == crate::solve::Globalization::TrustRegion {
            return refuse("with the TrustRegion globalization (its steps take no collision bound)");
        }
        if layers.iter().any(|l| l.remesh.is_some()) {
            return refuse("on a remeshed layer");
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
}
