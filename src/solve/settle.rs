//! Settling the vertices a remesh touched, before the frame's solve (REMESH.md "Split": ARCSim
//! places a split vertex by one local Newton step of a unit-stiffness stretch + bend energy; we
//! minimize the patch's own membrane + bending energy instead, over every vertex of a changed
//! face, the rest held). Nonlinear block Gauss-Seidel: per vertex, a Newton step on its 3x3
//! block of the projected Hessian, backtracked on the energy of its own elements, so no sweep
//! raises the energy.
//!
//! Why: a geometric guess at the new vertices (the curved-patch midpoint) ignores the
//! membrane, which is 10^4-10^6 times stiffer than bending in skin layers. Measured on the LK14
//! fig. 3-3 strip refined from 4 to 16 elements per wavelength: the curved midpoints raised the
//! membrane energy 19x, and one run then converged to a folded state (dihedral angles 2.4 rad).

use glam::{DMat3, DVec3};

use super::constraints::Constraints;
use super::element::Term;
use super::elements::Elements;
use crate::contact::{ccd, gather, ContactState, Pair};

/// What a settle did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settled {
    pub vertices: usize,
    pub sweeps: u32,
    /// Membrane + bending energy of the settled vertices' elements, before and after (J).
    pub energy_before: f64,
    pub energy_after: f64,
    /// Steps the collision bound shortened (with contact).
    pub ccd_cuts: u32,
}

/// The collision bound on a settle's steps, with contact (issue 64: continuous collision
/// detection bounds every step, in Newton and in Settle): the pairs near the start within the
/// list's reach, each vertex's among them, and the start. A vertex goes no farther than half the
/// list's margin from its start, so the list holds every pair it can reach (a Verlet list's
/// rule), and no step passes the time of impact of a pair it moves (additive CCD).
pub struct Bound {
    pairs: Vec<Pair>,
    of: Vec<Vec<u32>>,
    at: Vec<DVec3>,
    reach: f64,
}

impl Bound {
    pub fn new(state: &ContactState, x: &[DVec3], fixed: &[[bool; 3]]) -> Bound {
        let pairs = state.free_pairs(x, None, fixed);
        let mut of = vec![Vec::new(); x.len()];
        for (i, p) in pairs.iter().enumerate() {
            for &v in &p.v {
                of[v as usize].push(i as u32);
            }
        }
        Bound { pairs, of, at: x.to_vec(), reach: 0.5 * state.margin }
    }

    /// The largest fraction in [0, 1] of moving vertex v by `step` from `x` that keeps it within
    /// reach of its start and that no pair crosses.
    fn vertex(&self, x: &[DVec3], v: usize, step: DVec3) -> f64 {
        if step == DVec3::ZERO {
            return 1.0;
        }
        let mut alpha = self.within(x, v, step).min(1.0);
        for &i in &self.of[v] {
            let p = &self.pairs[i as usize];
            let d: [[f64; 3]; 4] = p.v.map(|u| if u as usize == v { step.to_array() } else { [0.0; 3] });
            if let Some(t) = ccd::additive_toi(p.kind, &gather(x, &p.v), &d, p.barrier.offset, alpha) {
                alpha = alpha.min(t);
            }
        }
        alpha.max(0.0)
    }

    /// The largest a with x[v] + a step within reach of v's start: the positive root of
    /// |c + a step| = reach, c = x[v] - start (|c| <= reach). `step` is not zero.
    fn within(&self, x: &[DVec3], v: usize, step: DVec3) -> f64 {
        let (c, ss) = (x[v] - self.at[v], step.length_squared());
        let cs = c.dot(step);
        (-cs + (cs * cs - ss * (c.length_squared() - self.reach * self.reach)).max(0.0).sqrt()) / ss
    }

    /// The same for moving every vertex by `d` at once.
    fn all(&self, x: &[DVec3], d: &[DVec3]) -> f64 {
        let mut alpha = 1.0f64;
        for (v, step) in d.iter().enumerate().filter(|(_, s)| **s != DVec3::ZERO) {
            alpha = alpha.min(self.within(x, v, *step));
        }
        alpha.min(ContactState::step_bound(&self.pairs, x, d)).max(0.0)
    }
}

/// Sweeps at most; a sweep whose largest step is below `STEP_TOL` of the vertices' mean edge
/// length ends the settle.
const SWEEPS: u32 = 4;
const STEP_TOL: f64 = 1e-4;
const HALVINGS: u32 = 12;
/// Conjugate-gradient iterations at most for the constraint correction.
const KEEP_ITERATIONS: usize = 200;

/// An element a vertex belongs to: its kind (`Elements::terms`), its index, and the vertex's
/// slot in it.
#[derive(Clone, Copy)]
struct Slot {
    kind: u8,
    element: u32,
    slot: usize,
}

/// Each vertex's prescribed coordinates, and its tie (`PackedState::tie`).
pub type Pins<'a> = (&'a [[bool; 3]], &'a [(u32, [bool; 3])]);

/// Settles the vertices `which` (packed indices; vertices with a prescribed coordinate or a
/// shared one are left alone) in `x`, then restores the kernel constraints' values (`keep`).
/// With contact, `bound` bounds every step. Deterministic: vertices in the order given.
pub fn settle(
    el: &Elements,
    constraints: &Constraints,
    x: &mut [DVec3],
    (fixed, tie): Pins,
    which: &[u32],
    bound: Option<&Bound>,
) -> Settled {
    let free: Vec<u32> = which
        .iter()
        .copied()
        .filter(|&v| !fixed[v as usize].iter().any(|&f| f) && tie[v as usize].0 == v && !tie[v as usize].1[0])
        .collect();
    let mut local = vec![u32::MAX; x.len()];
    free.iter().enumerate().for_each(|(i, &v)| local[v as usize] = i as u32);
    let mut slots: Vec<Vec<Slot>> = vec![Vec::new(); free.len()];
    // The kinds that settle (the shell's own energies) name their slots.
    let terms = el.terms();
    for (kind, t) in terms.iter().enumerate() {
        t.settle_slots(&mut |element, slot, v| {
            if local[v as usize] != u32::MAX {
                slots[local[v as usize] as usize].push(Slot { kind: kind as u8, element, slot });
            }
        });
    }
    let energy_of = |x: &[DVec3]| -> f64 {
        let mut seen = std::collections::BTreeSet::new();
        slots.iter().flatten().filter(|s| seen.insert((s.kind, s.element))).map(|s| slot_energy(&terms, x, *s)).sum()
    };
    let mut out = Settled { vertices: free.len(), energy_before: energy_of(x), ..Default::default() };
    let scale = mean_edge(el, x, &local);
    let start: Vec<DVec3> = free.iter().map(|&v| x[v as usize]).collect();
    for _ in 0..SWEEPS {
        out.sweeps += 1;
        let mut largest = 0.0f64;
        for (i, &v) in free.iter().enumerate() {
            let (step, cut) = relax_vertex(&terms, x, v as usize, &slots[i], bound);
            largest = largest.max(step);
            out.ccd_cuts += u32::from(cut);
        }
        if largest < STEP_TOL * scale {
            break;
        }
    }
    out.ccd_cuts += u32::from(keep(constraints, &free, &local, &start, x, bound));
    out.energy_after = energy_of(x);
    out
}

/// Undoes what the settle did to the LK14 kernel constraints (eq. 4.1), which ConstraintAdjust
/// has just made continuous across the remesh: the smallest correction d of the settled
/// vertices with sum_i w_ki d_i = -(the settle's change of kernel k's upper sum) for every
/// kernel, d = W^T y, (W W^T) y = -change, by conjugate gradients (the three coordinates share
/// W). Only the upper side is kept: a settled lower layer moves its kernels' targets through
/// its normals, left to the solve. (Measured on the remesh test scene: the constraint jump at a
/// remesh is 6.8e-5 of the patch size settled without this, 2.97e-5 with it, as unsettled.)
/// With `bound`, the correction is shortened where it would cross a pair; returns whether it was.
fn keep(
    constraints: &Constraints,
    free: &[u32],
    local: &[u32],
    start: &[DVec3],
    x: &mut [DVec3],
    bound: Option<&Bound>,
) -> bool {
    // Kernel rows over settled vertices: (local index, weight).
    let rows: Vec<Vec<(usize, f64)>> = constraints
        .kernels
        .iter()
        .map(|k| {
            k.upper
                .iter()
                .filter(|(v, _)| local[*v as usize] != u32::MAX)
                .map(|&(v, w)| (local[v as usize] as usize, w))
                .collect()
        })
        .filter(|r: &Vec<(usize, f64)>| !r.is_empty())
        .collect();
    if rows.is_empty() {
        return false;
    }
    let apply_t = |y: &[DVec3]| {
        let mut d = vec![DVec3::ZERO; free.len()];
        for (r, &yk) in rows.iter().zip(y) {
            r.iter().for_each(|&(i, w)| d[i] += w * yk);
        }
        d
    };
    let apply = |d: &[DVec3]| -> Vec<DVec3> { rows.iter().map(|r| r.iter().map(|&(i, w)| w * d[i]).sum()).collect() };
    let moved: Vec<DVec3> = free.iter().zip(start).map(|(&v, s)| x[v as usize] - *s).collect();
    let b: Vec<DVec3> = apply(&moved).into_iter().map(|c| -c).collect();
    let dot = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(p, q)| p.dot(*q)).sum::<f64>();
    let (mut y, mut r, mut p) = (vec![DVec3::ZERO; rows.len()], b.clone(), b.clone());
    let (mut rr, target) = (dot(&r, &r), 1e-24 * dot(&b, &b));
    for _ in 0..KEEP_ITERATIONS {
        if rr <= target {
            break;
        }
        let ap = apply(&apply_t(&p));
        let alpha = rr / dot(&p, &ap);
        if !alpha.is_finite() {
            return false;
        }
        y.iter_mut().zip(&p).for_each(|(y, p)| *y += alpha * *p);
        r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * *a);
        let next = dot(&r, &r);
        p.iter_mut().zip(&r).for_each(|(p, r)| *p = *r + (next / rr) * *p);
        rr = next;
    }
    let mut d = vec![DVec3::ZERO; x.len()];
    for (&v, dv) in free.iter().zip(apply_t(&y)) {
        d[v as usize] = dv;
    }
    let alpha = bound.map_or(1.0, |b| b.all(x, &d));
    x.iter_mut().zip(&d).for_each(|(x, d)| *x += alpha * *d);
    alpha < 1.0
}

fn slot_energy(terms: &[&dyn Term], x: &[DVec3], s: Slot) -> f64 {
    terms[s.kind as usize].element_energy(s.element as usize, x)
}

/// One projected Newton step on vertex v, backtracked on its elements' energy from the fraction
/// `bound` allows; the step taken, and whether the bound shortened it.
fn relax_vertex(terms: &[&dyn Term], x: &mut [DVec3], v: usize, slots: &[Slot], bound: Option<&Bound>) -> (f64, bool) {
    let (mut g, mut h) = (DVec3::ZERO, DMat3::ZERO);
    for &s in slots {
        let (gv, hv) = terms[s.kind as usize].block(s.element as usize, s.slot, x);
        g += gv;
        h += hv;
    }
    // The exact block, its eigenvalues clamped to a floor (a descent direction even where the
    // vertex sits on a ridge of its own energy, a finite step where it is weakly held).
    let Some(step) = projected_newton_step(h, g) else { return (0.0, false) };
    if !step.is_finite() {
        return (0.0, false);
    }
    let start = x[v];
    let e0: f64 = slots.iter().map(|&s| slot_energy(terms, x, s)).sum();
    let mut alpha = bound.map_or(1.0, |b| b.vertex(x, v, step));
    let cut = alpha < 1.0;
    for _ in 0..HALVINGS {
        x[v] = start + alpha * step;
        let e: f64 = slots.iter().map(|&s| slot_energy(terms, x, s)).sum();
        if e < e0 {
            return (alpha * step.length(), cut);
        }
        alpha *= 0.5;
    }
    x[v] = start;
    (0.0, cut)
}

/// -H^+ g with H's eigenvalues clamped below at 1e-6 of the largest (None if H is zero or
/// not finite).
fn projected_newton_step(h: DMat3, g: DVec3) -> Option<DVec3> {
    let m = nalgebra::Matrix3::from_fn(|r, c| h.col(c)[r]);
    let eigen = nalgebra::SymmetricEigen::new(m);
    let top = eigen.eigenvalues.iter().fold(0.0f64, |a, l| a.max(l.abs()));
    if !(top > 0.0 && top.is_finite()) {
        return None;
    }
    let gv = nalgebra::Vector3::new(g.x, g.y, g.z);
    let q = &eigen.eigenvectors;
    let coeffs = (q.transpose() * gv).zip_map(&eigen.eigenvalues, |c, l| -c / l.max(1e-6 * top));
    let s = q * coeffs;
    Some(DVec3::new(s.x, s.y, s.z))
}

/// Mean length of the membrane edges at the settled vertices (the step tolerance's scale).
fn mean_edge(el: &Elements, x: &[DVec3], local: &[u32]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for m in el.membranes.iter().filter(|m| m.v.iter().any(|&v| local[v as usize] != u32::MAX)) {
        for k in 0..3 {
            sum += x[m.v[k] as usize].distance(x[m.v[(k + 1) % 3] as usize]);
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use glam::DMat2;

    use super::*;
    use crate::mesh::{edges, grid, GridPattern};
    use crate::physics::hinge::HingeRest;
    use crate::physics::membrane::MembraneRest;
    use crate::physics::{gaussian_bending, BendingElement, ConstitutiveModel, HingeModel, Lame, QuadraticBending};
    use crate::solve::{HingeElem, MembraneElem};

    /// A flat 1 x 1 sheet, 6 x 6 cells, with its membranes and hinges or quadratic bending
    /// elements (skin-like: the membrane 10^5 times stiffer than bending).
    fn sheet(element: BendingElement) -> (Elements, Vec<DVec3>) {
        let m = grid(glam::DVec2::ONE, (6, 6), GridPattern::Equilateral, 0.0);
        let lame = Lame::plane_stress(1.0, 0.3);
        let mut el = Elements::default();
        for f in &m.faces {
            let rest = MembraneRest::from_rest_triangle(f.map(|v| m.rest[v as usize]), 1e-2, DMat2::IDENTITY);
            let (model, v) = (ConstitutiveModel::BazantHencky, *f);
            el.membranes.push(MembraneElem { v, rest: rest.unwrap(), model, lame });
        }
        if element == BendingElement::Quadratic {
            let rigidity: Vec<_> = edges(&m.faces).iter().map(|e| (e.v, 6e-7)).collect();
            let boundary = crate::mesh::boundary_vertices(&m.faces, m.rest.len());
            el.quadratic = QuadraticBending::build(&m.faces, |i| m.rest[i as usize], &rigidity, &boundary);
            el.gaussian = gaussian_bending::elements(&el.quadratic, &m.faces, |i| m.rest[i as usize], 0.45);
            return (el, m.rest.clone());
        }
        for e in edges(&m.faces).iter().filter(|e| e.is_interior()) {
            let v = [e.v[0], e.v[1], e.opposite[0], e.opposite[1]];
            let rest = HingeRest::from_rest(HingeModel::Tan, 1e-7, v.map(|i| m.rest[i as usize]));
            el.hinges.push(HingeElem { v, rest, model: HingeModel::Tan, image: None });
        }
        (el, m.rest.clone())
    }

    #[test]
    fn settling_lowers_the_energy_moves_only_what_it_is_given_and_repeats_exactly() {
        for element in [BendingElement::Hinge, BendingElement::Quadratic] {
            settles(element);
        }
    }

    fn settles(element: BendingElement) {
        let (el, rest) = sheet(element);
        let n = rest.len() as u32;
        let centre = DVec3::new(0.5, 0.5, 0.0);
        // The vertices near the centre lifted off the plane: a stretched membrane, the pop a bad
        // split placement makes. Only they are settled; the boundary is held.
        let which: Vec<u32> = (0..n).filter(|&i| rest[i as usize].distance(centre) < 0.3).collect();
        let bumped: Vec<DVec3> = (0..n as usize)
            .map(|i| rest[i] + DVec3::Z * if which.contains(&(i as u32)) { 0.02 } else { 0.0 })
            .collect();
        let fixed: Vec<[bool; 3]> =
            rest.iter().map(|p| [p.x == 0.0 || p.x == 1.0 || p.y == 0.0 || p.y == 1.0; 3]).collect();
        let tie: Vec<(u32, [bool; 3])> = (0..n).map(|i| (i, [false; 3])).collect();
        let mut x = bumped.clone();
        let s = settle(&el, &Constraints::default(), &mut x, (&fixed, &tie), &which, None);
        println!("{element:?}: {:.3} of the energy left", s.energy_after / s.energy_before);
        assert!(which.len() >= 5 && s.vertices == which.len(), "{s:?}");
        // (four sweeps: measured 0.058 of the energy left with hinges, 0.053 quadratic)
        assert!(s.energy_after < 0.1 * s.energy_before, "{s:?}");
        for i in (0..n).filter(|i| !which.contains(i)) {
            assert_eq!(x[i as usize], bumped[i as usize], "vertex {i} moved");
        }
        let mut again = bumped.clone();
        assert_eq!(settle(&el, &Constraints::default(), &mut again, (&fixed, &tie), &which, None), s);
        assert_eq!(again, x);
    }

    /// With contact: a vertex lifted 0.1 over a flat sheet settles back down through a small
    /// held triangle 0.05 over the sheet without the collision bound, and stops over it with
    /// the bound (issue 64: CCD bounds every step in Settle).
    #[test]
    fn a_settle_under_the_collision_bound_does_not_pass_through() {
        use crate::contact::{Surface, SurfaceLayer};
        let (el, rest) = sheet(BendingElement::Hinge);
        let n = rest.len() as u32;
        let v = (0..n).min_by(|&a, &b| {
            let d = |i: u32| rest[i as usize].distance(DVec3::new(0.5, 0.5, 0.0));
            d(a).total_cmp(&d(b))
        });
        let v = v.unwrap();
        let c = rest[v as usize] + DVec3::Z * 0.05;
        let r = 0.03;
        let triangle = [
            c + DVec3::new(r, 0.0, 0.0),
            c + DVec3::new(-0.5 * r, 0.8 * r, 0.0),
            c + DVec3::new(-0.5 * r, -0.8 * r, 0.0),
        ];
        let all: Vec<DVec3> = rest.iter().copied().chain(triangle).collect();
        let mut x = all.clone();
        x[v as usize].z = 0.1;
        let mut fixed: Vec<[bool; 3]> =
            rest.iter().map(|p| [p.x == 0.0 || p.x == 1.0 || p.y == 0.0 || p.y == 1.0; 3]).collect();
        fixed.extend([[true; 3]; 3]);
        let tie: Vec<(u32, [bool; 3])> = (0..n + 3).map(|i| (i, [false; 3])).collect();
        let m = grid(glam::DVec2::ONE, (6, 6), GridPattern::Equilateral, 0.0);
        let layers = [
            SurfaceLayer { triangles: m.faces.clone(), half_thickness: 0.002, moving: true },
            SurfaceLayer { triangles: vec![[n, n + 1, n + 2]], half_thickness: 0.0, moving: false },
        ];
        let state = ContactState::new(Surface::new(&layers, all.clone(), 0.002, &[]), 0.2);
        let mut free = x.clone();
        settle(&el, &Constraints::default(), &mut free, (&fixed, &tie), &[v], None);
        assert!(free[v as usize].z < 0.05, "unbounded, the vertex settles through: z = {}", free[v as usize].z);
        let bound = Bound::new(&state, &x, &fixed);
        let s = settle(&el, &Constraints::default(), &mut x, (&fixed, &tie), &[v], Some(&bound));
        assert!(x[v as usize].z > 0.05 + 0.002, "bounded, it stays over the triangle: z = {}", x[v as usize].z);
        assert!(s.ccd_cuts > 0 && s.energy_after < s.energy_before, "{s:?}");
    }
}
