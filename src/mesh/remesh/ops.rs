//! The remeshing operations on a working mesh (REMESH.md "Operations"): split, flip (metric
//! Delaunay, independent sets), collapse. Adjacency is one incident-face list per vertex: an
//! edge's faces are the intersection of two short lists, so every operation is local and the
//! whole pass is linear in the mesh size (no rescans after a collapse, unlike ARCSim).

use std::collections::VecDeque;

use glam::{DMat2, DVec2, DVec3};

use super::sizing::edge_size;
use super::{RemeshParams, RemeshVertex, Remeshed};

/// Flip hysteresis of the metric Delaunay test (REMESH.md).
const FLIP_HYSTERESIS: f64 = 0.01;
/// A collapse may not create an edge longer than this in the metric (the gap to 1 prevents
/// split/collapse ping-pong).
const COLLAPSE_SIZE: f64 = 0.9;
/// Smallest material-space face area an operation may create, relative to size_min^2.
const AREA_MIN: f64 = 1e-3;
/// Caps: flip passes per call, refinement rounds.
const FLIP_PASSES: usize = 64;
const REFINE_ROUNDS: usize = 48;

/// What one remesh did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RemeshStats {
    pub splits: u32,
    pub flips: u32,
    pub collapses: u32,
    /// Held faces released (`WorkMesh::release_held`).
    pub released: u32,
}

pub(super) struct WorkMesh<'a> {
    p: &'a RemeshParams,
    verts: Vec<RemeshVertex>,
    sizing: Vec<DMat2>,
    /// Unit vertex normals (world), for curved split midpoints.
    normals: Vec<DVec3>,
    v_alive: Vec<bool>,
    boundary: Vec<bool>,
    /// Boundary corners: never removed.
    corner: Vec<bool>,
    faces: Vec<[u32; 3]>,
    f_alive: Vec<bool>,
    /// Faces no operation may change (an input face held; every new face is free).
    f_held: Vec<bool>,
    /// Faces whose shape is kept, near contact: split on the straight edge (the surface stays
    /// the same point set), never flipped or collapsed (either would move the surface, maybe
    /// into what it touches). A split face's halves are kept too.
    f_kept: Vec<bool>,
    /// Alive faces around each vertex.
    vf: Vec<Vec<u32>>,
    /// Flip passes: a vertex is touched in the current pass when its mark equals `pass`.
    mark: Vec<u32>,
    pass: u32,
    stats: RemeshStats,
}

/// The faces of an edge (a, b): (face, opposite vertex), the face holding a -> b first.
type EdgeFaces = ([(u32, u32); 2], usize);

fn cross(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b)
}

/// A triangle's shape quality in material space: 12 sqrt 3 (signed) area / perimeter^2, 1 for an
/// equilateral triangle, 0 for a degenerate one.
pub(super) fn quality(u: [DVec2; 3]) -> f64 {
    let area = 0.5 * cross(u[1] - u[0], u[2] - u[0]);
    let perimeter = (u[1] - u[0]).length() + (u[2] - u[1]).length() + (u[0] - u[2]).length();
    12.0 * 3f64.sqrt() * area / (perimeter * perimeter)
}

impl<'a> WorkMesh<'a> {
    pub(super) fn new(
        vertices: &[RemeshVertex],
        faces: &[[u32; 3]],
        sizing: Vec<DMat2>,
        held: &[bool],
        kept: &[bool],
        p: &'a RemeshParams,
    ) -> Self {
        let n = vertices.len();
        let verts: Vec<RemeshVertex> =
            vertices.iter().enumerate().map(|(i, v)| RemeshVertex { origin: Some(i as u32), ..*v }).collect();
        let mut vf = vec![Vec::new(); n];
        for (fi, f) in faces.iter().enumerate() {
            for &v in f {
                vf[v as usize].push(fi as u32);
            }
        }
        let x: Vec<DVec3> = verts.iter().map(|v| v.x).collect();
        let normals = crate::mesh::shading::vertex_normals(&x, faces);
        let mut mesh = WorkMesh {
            p,
            verts,
            sizing,
            normals,
            v_alive: vec![true; n],
            boundary: vec![false; n],
            corner: vec![false; n],
            faces: faces.to_vec(),
            f_alive: vec![true; faces.len()],
            f_held: (0..faces.len()).map(|f| held.get(f).copied().unwrap_or(false)).collect(),
            f_kept: (0..faces.len()).map(|f| kept.get(f).copied().unwrap_or(false)).collect(),
            vf,
            mark: vec![0; n],
            pass: 0,
            stats: RemeshStats::default(),
        };
        // Boundary edges per vertex: a corner is where the boundary turns or branches.
        let mut along: Vec<Vec<DVec2>> = vec![Vec::new(); n];
        let edges = crate::mesh::edges(faces);
        for e in edges.iter().filter(|e| !e.is_interior()) {
            let [a, b] = e.v.map(|v| v as usize);
            let d = mesh.verts[b].uv - mesh.verts[a].uv;
            along[a].push(d);
            along[b].push(-d);
        }
        for (v, dirs) in along.iter().enumerate() {
            mesh.boundary[v] = !dirs.is_empty();
            mesh.corner[v] = match dirs.as_slice() {
                [] => false,
                [d0, d1] => cross(*d0, *d1).abs() > 1e-9 * d0.length() * d1.length() || d0.dot(*d1) > 0.0,
                _ => true,
            };
        }
        mesh.release_held(&edges);
        mesh
    }

    /// Releases the held faces a free face meets across an edge the metric wants split, and so
    /// on from those: such an edge cannot be split while a held face holds it, and the free
    /// faces beside it, split toward it, cut slivers down to degenerate ones (test
    /// `a_held_face_the_metric_wants_split_is_released`). A held region with no free face across
    /// such an edge (a whole strip held) stays held however its edges compare with the metric.
    fn release_held(&mut self, edges: &[crate::mesh::EdgeInfo]) {
        let mut across: Vec<Vec<u32>> = vec![Vec::new(); self.faces.len()];
        for e in edges.iter().filter(|e| e.is_interior() && self.size(e.v[0], e.v[1]) > 1.0) {
            across[e.faces[0] as usize].push(e.faces[1]);
            across[e.faces[1] as usize].push(e.faces[0]);
        }
        let mut free: Vec<u32> = (0..self.faces.len() as u32).filter(|&f| !self.f_held[f as usize]).collect();
        while let Some(f) = free.pop() {
            for &g in &across[f as usize] {
                if self.f_held[g as usize] {
                    self.f_held[g as usize] = false;
                    self.stats.released += 1;
                    free.push(g);
                }
            }
        }
    }

    fn edge_faces(&self, a: u32, b: u32) -> EdgeFaces {
        let mut out = [(u32::MAX, u32::MAX); 2];
        let mut count = 0;
        for &f in &self.vf[a as usize] {
            let t = self.faces[f as usize];
            if let Some(k) = (0..3).find(|&k| t[k] == a) {
                let (next, prev) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                if next == b {
                    out[1] = out[0];
                    out[0] = (f, prev);
                    count += 1;
                } else if prev == b {
                    let slot = if out[0].0 == u32::MAX { 0 } else { 1 };
                    out[slot] = (f, next);
                    count += 1;
                }
            }
        }
        (out, count.min(2))
    }

    fn size(&self, a: u32, b: u32) -> f64 {
        let (a, b) = (a as usize, b as usize);
        edge_size(self.verts[b].uv - self.verts[a].uv, self.sizing[a], self.sizing[b])
    }

    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut n: Vec<u32> =
            self.vf[v as usize].iter().flat_map(|&f| self.faces[f as usize]).filter(|&u| u != v).collect();
        n.sort_unstable();
        n.dedup();
        n
    }

    fn area(&self, f: [u32; 3]) -> f64 {
        let u = f.map(|i| self.verts[i as usize].uv);
        0.5 * cross(u[1] - u[0], u[2] - u[0])
    }

    fn normal(&self, f: [u32; 3]) -> DVec3 {
        let x = f.map(|i| self.verts[i as usize].x);
        (x[1] - x[0]).cross(x[2] - x[0])
    }

    fn area_min(&self) -> f64 {
        AREA_MIN * self.p.size_min * self.p.size_min
    }

    fn unique_edges(&self, faces: impl IntoIterator<Item = u32>) -> Vec<(u32, u32)> {
        let mut e: Vec<(u32, u32)> = faces
            .into_iter()
            .filter(|&f| self.f_alive[f as usize])
            .flat_map(|f| {
                let t = self.faces[f as usize];
                (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])))
            })
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }

    fn add_face(&mut self, f: [u32; 3]) -> u32 {
        let id = self.faces.len() as u32;
        self.faces.push(f);
        self.f_alive.push(true);
        self.f_held.push(false);
        self.f_kept.push(false);
        for &v in &f {
            self.vf[v as usize].push(id);
        }
        id
    }

    fn detach(&mut self, v: u32, f: u32) {
        self.vf[v as usize].retain(|&g| g != f);
    }

    // ------------------------------------------------------------ split

    /// Splits edge (a, b) at its material midpoint; returns the new vertex.
    fn split(&mut self, a: u32, b: u32) -> u32 {
        let (ef, count) = self.edge_faces(a, b);
        let (va, vb) = (self.verts[a as usize], self.verts[b as usize]);
        let (na, nb) = (self.normals[a as usize], self.normals[b as usize]);
        let m = self.verts.len() as u32;
        // State transfer: the mean of the ends (REMESH.md "Split"), the position lifted onto
        // the curved surface the two normals describe: the midpoint of the cubic Bezier edge of
        // a PN triangle (Vlachos et al. 2001), which recovers a circular arc's sagitta to
        // second order in the turning angle.
        let d = vb.x - va.x;
        let kept = ef[..count].iter().any(|&(f, _)| self.f_kept[f as usize]);
        let lift = if self.p.curved_splits && !kept { -(d.dot(na) * na - d.dot(nb) * nb) / 8.0 } else { DVec3::ZERO };
        self.verts.push(RemeshVertex {
            uv: 0.5 * (va.uv + vb.uv),
            x: 0.5 * (va.x + vb.x) + lift,
            v: 0.5 * (va.v + vb.v),
            rest: 0.5 * (va.rest + vb.rest),
            fixed: std::array::from_fn(|k| va.fixed[k] && vb.fixed[k]),
            origin: None,
        });
        self.sizing.push(0.5 * (self.sizing[a as usize] + self.sizing[b as usize]));
        self.normals.push((na + nb).normalize_or_zero());
        self.v_alive.push(true);
        self.boundary.push(count == 1);
        self.corner.push(false);
        self.vf.push(Vec::new());
        for &(f, opp) in &ef[..count] {
            let t = self.faces[f as usize];
            let k = (0..3).find(|&k| t[k] == a || t[k] == b).expect("edge face");
            // (p, q, opp) in the face's orientation.
            let (p, q) = if t[(k + 1) % 3] == opp { (t[(k + 2) % 3], t[k]) } else { (t[k], t[(k + 1) % 3]) };
            self.faces[f as usize] = [p, m, opp];
            self.detach(q, f);
            self.vf[m as usize].push(f);
            let half = self.add_face([m, q, opp]);
            self.f_kept[half as usize] = self.f_kept[f as usize];
        }
        self.stats.splits += 1;
        m
    }

    /// Splits every edge longer than the metric allows, longest first, until none is left.
    pub(super) fn refine(&mut self) {
        for _ in 0..REFINE_ROUNDS {
            let mut bad: Vec<(f64, u32, u32)> = self
                .unique_edges(0..self.faces.len() as u32)
                .into_iter()
                .map(|(a, b)| (self.size(a, b), a, b))
                .filter(|e| e.0 > 1.0)
                .collect();
            if bad.is_empty() {
                return;
            }
            bad.sort_by(|x, y| y.0.total_cmp(&x.0).then((x.1, x.2).cmp(&(y.1, y.2))));
            for (_, a, b) in bad {
                let (ef, count) = self.edge_faces(a, b);
                // (a split halves its faces: none is made below the area every operation keeps)
                let blocked = |&(f, _): &(u32, u32)| {
                    self.f_held[f as usize] || self.area(self.faces[f as usize]) <= 2.0 * self.area_min()
                };
                if count == 0 || self.size(a, b) <= 1.0 || ef[..count].iter().any(blocked) {
                    continue;
                }
                let m = self.split(a, b);
                let around = self.vf[m as usize].clone();
                self.flip_around(around);
            }
        }
    }

    // ------------------------------------------------------------ flip

    /// The metric Delaunay test of edge (x, z) with opposite vertices w (face of x -> z) and y.
    fn should_flip(&self, x: u32, z: u32, w: u32, y: u32) -> bool {
        let [ux, uz, uw, uy] = [x, z, w, y].map(|i| self.verts[i as usize].uv);
        let m = [x, z, w, y].iter().map(|&i| self.sizing[i as usize]).fold(DMat2::ZERO, |a, b| a + b) * 0.25;
        let dot = |a: DVec2, b: DVec2| a.dot(m * b);
        let area0 = cross(uz - uy, ux - uy).abs();
        let area1 = cross(ux - uw, uz - uw).abs();
        area0 * dot(ux - uw, uz - uw) + dot(uz - uy, ux - uy) * area1 < -FLIP_HYSTERESIS * (area0 + area1)
    }

    /// Flips (a, b) if it is interior, fails the Delaunay test, and the two new faces are
    /// well-formed; returns the two faces.
    fn try_flip(&mut self, a: u32, b: u32) -> Option<[u32; 2]> {
        let (ef, count) = self.edge_faces(a, b);
        if count != 2 || ef.iter().any(|&(f, _)| self.f_held[f as usize] || self.f_kept[f as usize]) {
            return None;
        }
        // ef[0] holds a -> b (opposite c), ef[1] holds b -> a (opposite d), or the reverse.
        let (f0, c) = ef[0];
        let (f1, d) = ef[1];
        let t0 = self.faces[f0 as usize];
        let forward = (0..3).any(|k| t0[k] == a && t0[(k + 1) % 3] == b);
        let (a, b) = if forward { (a, b) } else { (b, a) };
        if c == d || self.neighbours(c).binary_search(&d).is_ok() || !self.should_flip(a, b, c, d) {
            return None;
        }
        let (n0, n1) = ([a, d, c], [d, b, c]);
        let min = self.area_min();
        let old = self.normal(t0) + self.normal(self.faces[f1 as usize]);
        if self.area(n0) <= min
            || self.area(n1) <= min
            || self.normal(n0).dot(old) <= 0.0
            || self.normal(n1).dot(old) <= 0.0
        {
            return None;
        }
        self.faces[f0 as usize] = n0;
        self.faces[f1 as usize] = n1;
        self.detach(a, f1);
        self.detach(b, f0);
        self.vf[c as usize].push(f1);
        self.vf[d as usize].push(f0);
        self.stats.flips += 1;
        Some([f0, f1])
    }

    /// Flips edges of the given faces to the metric Delaunay triangulation, an independent set
    /// (no shared vertex) per pass, following the flips outward.
    fn flip_around(&mut self, faces: Vec<u32>) {
        let mut active = faces;
        for _ in 0..FLIP_PASSES {
            self.pass += 1;
            self.mark.resize(self.verts.len(), 0);
            let pass = self.pass;
            let mut next = Vec::new();
            let mut flipped = false;
            for (a, b) in self.unique_edges(active.iter().copied()) {
                let (ef, count) = self.edge_faces(a, b);
                if count != 2 {
                    continue;
                }
                let quad = [a, b, ef[0].1, ef[1].1];
                if quad.iter().any(|&v| self.mark[v as usize] == pass) {
                    next.extend([ef[0].0, ef[1].0]);
                    continue;
                }
                if let Some(f) = self.try_flip(a, b) {
                    quad.iter().for_each(|&v| self.mark[v as usize] = pass);
                    next.extend(f);
                    flipped = true;
                }
            }
            if !flipped {
                return;
            }
            next.sort_unstable();
            next.dedup();
            active = next;
        }
    }

    pub(super) fn flip_all(&mut self) {
        self.flip_around((0..self.faces.len() as u32).collect());
    }

    // ------------------------------------------------------------ collapse

    /// Removes v onto its neighbour w when every REMESH.md condition holds.
    fn try_collapse(&mut self, v: u32, w: u32) -> bool {
        let (ef, count) = self.edge_faces(v, w);
        if count == 0 || (self.boundary[v as usize] && count != 1) {
            return false;
        }
        // (every face around v changes)
        if self.vf[v as usize].iter().any(|&f| self.f_held[f as usize] || self.f_kept[f as usize]) {
            return false;
        }
        // Link condition: v and w share exactly the edge's opposite vertices (stays manifold).
        let (nv, nw) = (self.neighbours(v), self.neighbours(w));
        let common = nv.iter().filter(|u| nw.binary_search(u).is_ok()).count();
        if common != count {
            return false;
        }
        let min = self.area_min();
        let aspect_min = self.p.aspect_min;
        let gone = [ef[0].0, ef[1].0];
        let kept: Vec<u32> = self.vf[v as usize].iter().copied().filter(|f| !gone[..count].contains(f)).collect();
        for &f in &kept {
            let t = self.faces[f as usize];
            let n = t.map(|u| if u == v { w } else { u });
            let area = self.area(n);
            let aspect = quality(n.map(|i| self.verts[i as usize].uv));
            if area <= min || aspect < aspect_min || self.normal(n).dot(self.normal(t)) <= 0.0 {
                return false;
            }
            if n.iter().any(|&u| u != w && self.size(w, u) > COLLAPSE_SIZE) {
                return false;
            }
        }
        for &(f, _) in &ef[..count] {
            self.f_alive[f as usize] = false;
            for u in self.faces[f as usize] {
                self.detach(u, f);
            }
        }
        for &f in &kept {
            let t = &mut self.faces[f as usize];
            t.iter_mut().filter(|u| **u == v).for_each(|u| *u = w);
            self.vf[w as usize].push(f);
        }
        self.vf[v as usize].clear();
        self.v_alive[v as usize] = false;
        self.stats.collapses += 1;
        true
    }

    /// Collapses what the field allows: a worklist of vertices in index order; a success puts
    /// the kept vertex's neighbours back on it.
    pub(super) fn coarsen(&mut self) {
        let n = self.verts.len();
        let mut queued = vec![true; n];
        let mut queue: VecDeque<u32> = (0..n as u32).collect();
        while let Some(v) = queue.pop_front() {
            queued[v as usize] = false;
            let vi = v as usize;
            if !self.v_alive[vi] || self.corner[vi] || self.verts[vi].fixed.iter().any(|&f| f) {
                continue;
            }
            let mut nbrs: Vec<(f64, u32)> = self.neighbours(v).into_iter().map(|w| (self.size(v, w), w)).collect();
            nbrs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for (_, w) in nbrs {
                if self.try_collapse(v, w) {
                    for u in self.neighbours(w).into_iter().chain([w]) {
                        if !queued[u as usize] {
                            queued[u as usize] = true;
                            queue.push_back(u);
                        }
                    }
                    let around = self.vf[w as usize].clone();
                    self.flip_around(around);
                    break;
                }
            }
        }
    }

    // ------------------------------------------------------------ output

    pub(super) fn finish(self) -> Remeshed {
        let mut index = vec![u32::MAX; self.verts.len()];
        let mut vertices = Vec::new();
        let mut sizing = Vec::new();
        for (i, v) in self.verts.iter().enumerate().filter(|(i, _)| self.v_alive[*i]) {
            index[i] = vertices.len() as u32;
            vertices.push(*v);
            sizing.push(self.sizing[i]);
        }
        let faces = self
            .faces
            .iter()
            .zip(&self.f_alive)
            .filter(|(_, a)| **a)
            .map(|(f, _)| f.map(|v| index[v as usize]))
            .collect();
        Remeshed { vertices, faces, sizing, stats: self.stats, at_rest: false }
    }
}
