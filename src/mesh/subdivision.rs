//! Loop subdivision of a region of a triangle body mesh, embedded in the body.
//!
//! A skin patch must be finer than the body it lies on. [`refine`] splits a region of the body's
//! faces `levels` times (each face into four, midpoint split) and places every refined vertex on
//! the body's smooth Loop limit surface instead of its flat facets. Each refined vertex is given
//! as a fixed sparse linear combination of coarse body vertices (a [`Stencil`]), so whatever later
//! moves the body (skinning, morphs) moves the refined vertices exactly: `y = S x`.
//!
//! Rules (Loop 1987, with Loop's original weight): a vertex of valence `n` moves to
//! `(1 - n beta) v + beta sum(neighbours)` with `beta = (1/n) (5/8 - (3/8 + 1/4 cos(2 pi / n))^2)`
//! (1/16 at valence 6, 3/16 at valence 3); an edge point is `3/8 (a + b) + 1/8 (c + d)` from the
//! edge's ends and the two opposite vertices. The limit position of a vertex is
//! `(1 - n chi) v + chi sum(neighbours)` with `chi = 1 / (3 / (8 beta) + n)` (1/2 and 1/12 each
//! at valence 6). Body boundaries (edges with one face) follow the cubic B-spline curve rules:
//! edge point `(a + b) / 2`, boundary vertex `3/4 v + 1/8 (n1 + n2)`, limit
//! `2/3 v + 1/6 (n1 + n2)`, from the two boundary neighbours only. Corners (boundary vertices of
//! one face) get no special rule: the boundary curve is smoothed through them.
//!
//! Loop is approximating: the limit surface does not pass through the body's vertices. Where the
//! body is convex it lies inside them by about the facets' sagitta (up to 0.5 mm on a 60 mm radius
//! forehead of 12-17 mm triangles, whose facet centres are 0.4 mm inside).
//!
//! Neighbourhood: only the region and ONE ring of faces around it (every face that shares a
//! vertex with a region face) are subdivided, and after each level only the region's
//! descendants and one ring of faces of that level around them are kept. One ring is enough:
//! a refined vertex's limit position needs its one ring of the last level; a level's vertex needs
//! its parent's one ring of the previous level (an edge point: the two faces of its edge). By
//! induction the limit over a region face at any level depends only on its vertices' fans and
//! their one rings: Stam's (1998) N + 6 control vertices. Every vertex also carries two flags,
//! "its fan is the body's" and "its position equals that of subdividing the whole body", so a
//! cut that reached the region would be reported ([`SubdivisionError::Incomplete`]), never
//! returned silently.
//!
//! Each level is a sparse operator on the previous level's vertices; the rows are composed down
//! to coarse vertices as they are made (a dense scratch accumulator over the neighbourhood's
//! coarse vertices, sorted, exact zeros dropped).

use glam::DVec3;

/// The most levels [`refine`] and [`levels_for`] accept: 4^8 = 65536 refined faces per coarse face.
pub(crate) const MAX_LEVELS: u32 = 8;

/// A problem with the input of [`refine`] or [`levels_for`], naming the element that shows it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SubdivisionError {
    #[error("the region has no faces")]
    EmptyRegion,
    #[error("region entry {index} is face {face}, but the body has {count} faces")]
    RegionFaceOutOfRange { index: usize, face: u32, count: usize },
    #[error("face {face} appears twice in the region")]
    DuplicateRegionFace { face: u32 },
    #[error("face {face} refers to vertex {vertex}, but the body has {count} vertices")]
    BadVertex { face: usize, vertex: u32, count: usize },
    #[error("face {face} repeats a vertex")]
    DegenerateFace { face: usize },
    #[error("edge ({a}, {b}) is shared by {count} faces (non-manifold)")]
    NonManifoldEdge { a: u32, b: u32, count: usize },
    #[error("the faces around vertex {vertex} do not form a single disk or half-disk (non-manifold)")]
    NonManifoldVertex { vertex: u32 },
    #[error("{levels} levels asked, at most {max} are allowed")]
    TooManyLevels { levels: u32, max: u32 },
    #[error("the target edge length {target} is not positive and finite")]
    BadTarget { target: f64 },
    #[error("vertex {vertex} of the region has a non-finite position")]
    NonFinite { vertex: u32 },
    #[error("the longest region edge ({longest}) needs more than {max} levels to reach {target}")]
    TargetTooFine { longest: f64, target: f64, max: u32 },
    #[error("internal error: a refined vertex of region face {face} depends on faces outside the kept neighbourhood")]
    Incomplete { face: u32 },
}

/// A refined vertex as a combination of coarse body vertices. The weights sum to one (affine).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stencil {
    /// Coarse body vertex indices, ascending.
    pub vertices: Vec<u32>,
    pub weights: Vec<f64>,
}

impl Stencil {
    /// `sum w_i x[v_i]`. An index past the end of `x` contributes NaN.
    pub fn apply(&self, x: &[DVec3]) -> DVec3 {
        self.vertices
            .iter()
            .zip(&self.weights)
            .fold(DVec3::ZERO, |s, (&v, &w)| s + w * x.get(v as usize).copied().unwrap_or(DVec3::NAN))
    }
}

/// Every stencil applied to the coarse positions `x`, into `out` (cleared first).
pub fn apply_all(stencils: &[Stencil], x: &[DVec3], out: &mut Vec<DVec3>) {
    out.clear();
    out.extend(stencils.iter().map(|s| s.apply(x)));
}

/// A refined region: a triangle mesh whose vertices are embedded in the coarse body.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refinement {
    /// Refined faces, indices into `stencils` / `parent`; each oriented as its coarse face.
    pub faces: Vec<[u32; 3]>,
    /// Per refined vertex: its position on the Loop limit surface of the body.
    pub stencils: Vec<Stencil>,
    /// Per refined vertex: a coarse region face and the vertex's barycentric coordinates in it
    /// (in the face's corner order), in the midpoint-split parameterisation: linear interpolation
    /// of per-corner data (UVs) at these coordinates. A vertex on several region faces (a coarse
    /// vertex or a point of a shared edge) takes the one with the lowest face index.
    pub parent: Vec<(u32, DVec3)>,
    /// The number of midpoint splits applied.
    pub levels: u32,
}

/// Refines the faces `region` (indices into `faces`) of the body `faces` `levels` times; faces
/// outside the region serve only as neighbours. `rest` is used only for its length: the stencils
/// depend on the connectivity alone.
///
/// Refined vertices come in order: the region's coarse vertices (in order of first use by the
/// region's faces), then each level's new vertices. Refined faces come per region face, in
/// region order. The region may touch the body's boundary and need not be connected. Every face
/// of the body must index `rest` and have three distinct vertices; the region's vertices must
/// be manifold (a single fan, closed or open) and the edges near it have at most two faces.
pub fn refine(rest: &[DVec3], faces: &[[u32; 3]], region: &[u32], levels: u32) -> Result<Refinement, SubdivisionError> {
    refine_with_rings(rest.len(), faces, region, levels, 1)
}

/// The smallest number of levels `k` for which the longest edge of the region's faces, halved `k`
/// times, is at most `target_edge` (lengths measured on `rest`). Errors when that takes more than
/// [`MAX_LEVELS`].
pub(crate) fn levels_for(
    rest: &[DVec3],
    faces: &[[u32; 3]],
    region: &[u32],
    target_edge: f64,
) -> Result<u32, SubdivisionError> {
    if !(target_edge.is_finite() && target_edge > 0.0) {
        return Err(SubdivisionError::BadTarget { target: target_edge });
    }
    check_region(faces.len(), region)?;
    let mut longest = 0.0f64;
    for &r in region {
        let f = faces[r as usize];
        for &v in &f {
            match rest.get(v as usize) {
                None => return Err(SubdivisionError::BadVertex { face: r as usize, vertex: v, count: rest.len() }),
                Some(p) if !p.is_finite() => return Err(SubdivisionError::NonFinite { vertex: v }),
                Some(_) => {}
            }
        }
        for k in 0..3 {
            longest = longest.max(rest[f[k] as usize].distance(rest[f[(k + 1) % 3] as usize]));
        }
    }
    (0..=MAX_LEVELS).find(|&k| longest / f64::from(1u32 << k) <= target_edge).ok_or(SubdivisionError::TargetTooFine {
        longest,
        target: target_edge,
        max: MAX_LEVELS,
    })
}

/// Sizes of the refinement of `region_faces` faces by `levels` levels, for a memory check before
/// the run: `(vertices, faces)`. Faces are exact (`F 4^k`); vertices are an upper bound,
/// `F 4^k / 2 + 3 F 2^k / 2 + F` (Euler: `V = F_k / 2 + B_k / 2 + chi`, with at most `3 F`
/// boundary edges at the coarse level and at most `F` components); a compact patch has close to
/// `F 4^k / 2` plus its boundary length in refined edges. Saturates instead of overflowing.
pub fn estimate(region_faces: usize, levels: u32) -> (usize, usize) {
    let f = region_faces;
    let faces = f.saturating_mul(4usize.saturating_pow(levels));
    let boundary = f.saturating_mul(3).saturating_mul(2usize.saturating_pow(levels));
    let vertices = (faces / 2).saturating_add(boundary.div_ceil(2)).saturating_add(f);
    (vertices, faces)
}

fn check_region(face_count: usize, region: &[u32]) -> Result<(), SubdivisionError> {
    if region.is_empty() {
        return Err(SubdivisionError::EmptyRegion);
    }
    let mut seen = vec![false; face_count];
    for (index, &face) in region.iter().enumerate() {
        match seen.get_mut(face as usize) {
            None => return Err(SubdivisionError::RegionFaceOutOfRange { index, face, count: face_count }),
            Some(s) if *s => return Err(SubdivisionError::DuplicateRegionFace { face }),
            Some(s) => *s = true,
        }
    }
    Ok(())
}

/// Sparse rows over the neighbourhood's coarse vertices (local indices), CSR.
#[derive(Default)]
struct Rows {
    start: Vec<usize>,
    idx: Vec<u32>,
    w: Vec<f64>,
}

impl Rows {
    fn identity(n: usize) -> Rows {
        Rows { start: (0..=n).collect(), idx: (0..n as u32).collect(), w: vec![1.0; n] }
    }

    fn with_capacity(rows: usize, entries: usize) -> Rows {
        let mut start = Vec::with_capacity(rows + 1);
        start.push(0);
        Rows { start, idx: Vec::with_capacity(entries), w: Vec::with_capacity(entries) }
    }

    fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let (a, b) = (self.start[i], self.start[i + 1]);
        (&self.idx[a..b], &self.w[a..b])
    }

    fn push_empty(&mut self) {
        self.start.push(self.idx.len());
    }
}

/// Dense scratch accumulator for one sparse row.
struct Acc {
    val: Vec<f64>,
    seen: Vec<bool>,
    touched: Vec<u32>,
}

impl Acc {
    fn new(n: usize) -> Acc {
        Acc { val: vec![0.0; n], seen: vec![false; n], touched: Vec::new() }
    }

    /// Adds `c` times row `i` of `rows`.
    fn add(&mut self, rows: &Rows, i: u32, c: f64) {
        let (idx, w) = rows.row(i as usize);
        for (&j, &wj) in idx.iter().zip(w) {
            let j = j as usize;
            if !self.seen[j] {
                self.seen[j] = true;
                self.touched.push(j as u32);
            }
            self.val[j] += c * wj;
        }
    }

    /// The accumulated row, sorted, exact zeros dropped, appended to `out`; the scratch is reset.
    fn flush(&mut self, out: &mut Rows) {
        self.touched.sort_unstable();
        for &j in &self.touched {
            let v = std::mem::take(&mut self.val[j as usize]);
            self.seen[j as usize] = false;
            if v != 0.0 {
                out.idx.push(j);
                out.w.push(v);
            }
        }
        self.touched.clear();
        out.start.push(out.idx.len());
    }
}

/// One undirected edge of a level: ends (ascending), opposite vertices and number of faces.
struct Edge {
    v: [u32; 2],
    opp: [u32; 2],
    count: u32,
}

/// Edges and vertex neighbourhoods of one level.
struct Topology {
    edges: Vec<Edge>,
    /// Per face: the edge of `(f[k], f[k + 1])` for k = 0, 1, 2.
    face_edges: Vec<[u32; 3]>,
    nbr_start: Vec<usize>,
    nbr: Vec<u32>,
    /// Per vertex: its first two boundary neighbours and its number of boundary edges.
    bnd: Vec<[u32; 2]>,
    bcount: Vec<u32>,
}

impl Topology {
    /// An edge of more than two faces keeps the opposite vertices of its first two.
    fn build(faces: &[[u32; 3]], nv: usize) -> Topology {
        let mut half: Vec<(u64, u32)> = Vec::with_capacity(faces.len() * 3);
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                half.push(((u64::from(a.min(b)) << 32) | u64::from(a.max(b)), (fi * 3 + k) as u32));
            }
        }
        half.sort_unstable();
        let mut edges: Vec<Edge> = Vec::with_capacity(half.len() / 2 + 8);
        let mut face_edges = vec![[0u32; 3]; faces.len()];
        let mut i = 0;
        while i < half.len() {
            let key = half[i].0;
            let mut j = i;
            while j < half.len() && half[j].0 == key {
                j += 1;
            }
            let (a, b) = ((key >> 32) as u32, key as u32);
            let mut opp = [u32::MAX; 2];
            for (slot, &(_, h)) in half[i..j].iter().enumerate() {
                let (fi, k) = (h as usize / 3, h as usize % 3);
                face_edges[fi][k] = edges.len() as u32;
                if slot < 2 {
                    opp[slot] = faces[fi][(k + 2) % 3];
                }
            }
            edges.push(Edge { v: [a, b], opp, count: (j - i) as u32 });
            i = j;
        }
        let mut nbr_start = vec![0usize; nv + 1];
        for e in &edges {
            nbr_start[e.v[0] as usize + 1] += 1;
            nbr_start[e.v[1] as usize + 1] += 1;
        }
        for v in 0..nv {
            nbr_start[v + 1] += nbr_start[v];
        }
        let mut fill = nbr_start.clone();
        let mut nbr = vec![0u32; nbr_start[nv]];
        let mut bnd = vec![[u32::MAX; 2]; nv];
        let mut bcount = vec![0u32; nv];
        for e in &edges {
            let [a, b] = e.v;
            nbr[fill[a as usize]] = b;
            fill[a as usize] += 1;
            nbr[fill[b as usize]] = a;
            fill[b as usize] += 1;
            if e.count == 1 {
                for (v, other) in [(a, b), (b, a)] {
                    let c = &mut bcount[v as usize];
                    if *c < 2 {
                        bnd[v as usize][*c as usize] = other;
                    }
                    *c += 1;
                }
            }
        }
        Topology { edges, face_edges, nbr_start, nbr, bnd, bcount }
    }

    fn nbrs(&self, v: usize) -> &[u32] {
        &self.nbr[self.nbr_start[v]..self.nbr_start[v + 1]]
    }

    /// The even (vertex) rule's terms at `v`, or None where the fan is neither a disk nor a
    /// half-disk.
    fn even_terms(&self, v: usize, terms: &mut Vec<(u32, f64)>) -> Option<()> {
        terms.clear();
        match self.bcount[v] {
            0 => {
                let nb = self.nbrs(v);
                let beta = loop_beta(nb.len());
                terms.push((v as u32, 1.0 - nb.len() as f64 * beta));
                terms.extend(nb.iter().map(|&u| (u, beta)));
            }
            2 => {
                let [p, q] = self.bnd[v];
                terms.extend([(v as u32, 0.75), (p, 0.125), (q, 0.125)]);
            }
            _ => return None,
        }
        Some(())
    }

    /// The limit-position rule's terms at `v`, or None as for `even_terms`.
    fn limit_terms(&self, v: usize, terms: &mut Vec<(u32, f64)>) -> Option<()> {
        terms.clear();
        match self.bcount[v] {
            0 => {
                let nb = self.nbrs(v);
                let n = nb.len() as f64;
                let chi = 1.0 / (3.0 / (8.0 * loop_beta(nb.len())) + n);
                terms.push((v as u32, 1.0 - n * chi));
                terms.extend(nb.iter().map(|&u| (u, chi)));
            }
            2 => {
                let [p, q] = self.bnd[v];
                terms.extend([(v as u32, 2.0 / 3.0), (p, 1.0 / 6.0), (q, 1.0 / 6.0)]);
            }
            _ => return None,
        }
        Some(())
    }
}

/// Loop's original vertex weight for valence `n`.
fn loop_beta(n: usize) -> f64 {
    let n = n as f64;
    let c = 0.375 + 0.25 * (2.0 * std::f64::consts::PI / n).cos();
    (0.625 - c * c) / n
}

/// One level of the kept neighbourhood.
struct Level {
    faces: Vec<[u32; 3]>,
    /// Per face: its coarse ancestor, an index into the neighbourhood's faces (region first).
    anc: Vec<u32>,
    /// Per face: its corners' barycentric coordinates in the ancestor (ancestor's corner order).
    bary: Vec<[DVec3; 3]>,
    /// Per vertex: its fan is the whole body's (trusted only where `valid`).
    complete: Vec<bool>,
    /// Per vertex: its row equals that of subdividing the whole body.
    valid: Vec<bool>,
    /// Per vertex: position over the neighbourhood's coarse vertices (empty where not `valid`).
    rows: Rows,
}

/// Checks the body's faces, gathers the region and `rings` rings of faces around it, and
/// checks the fans of the vertices whose fans are complete.
fn neighbourhood(
    nv: usize,
    faces: &[[u32; 3]],
    region: &[u32],
    rings: u32,
) -> Result<(Vec<u32>, Vec<u32>, Level), SubdivisionError> {
    check_region(faces.len(), region)?;
    for (fi, f) in faces.iter().enumerate() {
        if let Some(&vertex) = f.iter().find(|&&v| v as usize >= nv) {
            return Err(SubdivisionError::BadVertex { face: fi, vertex, count: nv });
        }
        if f[0] == f[1] || f[1] == f[2] || f[2] == f[0] {
            return Err(SubdivisionError::DegenerateFace { face: fi });
        }
    }
    let mut in_sub = vec![false; faces.len()];
    let mut sub_faces: Vec<u32> = region.to_vec();
    let mut marked = vec![false; nv];
    for &r in region {
        in_sub[r as usize] = true;
        faces[r as usize].iter().for_each(|&v| marked[v as usize] = true);
    }
    for _ in 0..rings {
        let first = sub_faces.len();
        for (fi, f) in faces.iter().enumerate() {
            if !in_sub[fi] && f.iter().any(|&v| marked[v as usize]) {
                in_sub[fi] = true;
                sub_faces.push(fi as u32);
            }
        }
        for &fi in &sub_faces[first..] {
            faces[fi as usize].iter().for_each(|&v| marked[v as usize] = true);
        }
    }
    // Local numbering: vertices in order of first use by the neighbourhood's faces (region first).
    let mut local = vec![u32::MAX; nv];
    let mut sub_verts: Vec<u32> = Vec::new();
    let mut local_faces = Vec::with_capacity(sub_faces.len());
    for &fi in &sub_faces {
        let f = faces[fi as usize];
        local_faces.push(f.map(|v| {
            if local[v as usize] == u32::MAX {
                local[v as usize] = sub_verts.len() as u32;
                sub_verts.push(v);
            }
            local[v as usize]
        }));
    }
    let n0 = sub_verts.len();
    let mut body_count = vec![0u32; n0];
    for f in faces {
        for &v in f {
            if local[v as usize] != u32::MAX {
                body_count[local[v as usize] as usize] += 1;
            }
        }
    }
    let mut sub_count = vec![0u32; n0];
    local_faces.iter().flatten().for_each(|&v| sub_count[v as usize] += 1);
    let complete: Vec<bool> = (0..n0).map(|v| body_count[v] == sub_count[v]).collect();
    // Edges of more than two faces, then the fans of the complete vertices.
    let topo = Topology::build(&local_faces, n0);
    if let Some(e) = topo.edges.iter().find(|e| e.count > 2) {
        let (a, b) = (sub_verts[e.v[0] as usize], sub_verts[e.v[1] as usize]);
        return Err(SubdivisionError::NonManifoldEdge { a: a.min(b), b: a.max(b), count: e.count as usize });
    }
    let mut fan_start = vec![0usize; n0 + 1];
    local_faces.iter().flatten().for_each(|&v| fan_start[v as usize + 1] += 1);
    for v in 0..n0 {
        fan_start[v + 1] += fan_start[v];
    }
    let mut fill = fan_start.clone();
    let mut fan = vec![(0u32, 0u32); fan_start[n0]];
    for f in &local_faces {
        for k in 0..3 {
            let v = f[k] as usize;
            fan[fill[v]] = (f[(k + 1) % 3], f[(k + 2) % 3]);
            fill[v] += 1;
        }
    }
    for v in (0..n0).filter(|&v| complete[v]) {
        if !single_fan(&fan[fan_start[v]..fan_start[v + 1]], topo.nbrs(v), topo.bcount[v]) {
            return Err(SubdivisionError::NonManifoldVertex { vertex: sub_verts[v] });
        }
    }
    let level = Level {
        bary: vec![[DVec3::X, DVec3::Y, DVec3::Z]; local_faces.len()],
        anc: (0..local_faces.len() as u32).collect(),
        faces: local_faces,
        complete,
        valid: vec![true; n0],
        rows: Rows::identity(n0),
    };
    Ok((sub_faces, sub_verts, level))
}

/// Whether the link of a vertex (one `(a, b)` pair per face around it, on edges of at most two
/// faces) is a single cycle of at least three edges or a single path.
fn single_fan(pairs: &[(u32, u32)], nbrs: &[u32], bcount: u32) -> bool {
    if pairs.is_empty() || !(bcount == 0 || bcount == 2) || (bcount == 0 && pairs.len() < 3) {
        return false;
    }
    // Union-find over the link's vertices (the vertex's neighbours), positions in `nbrs`.
    let mut root: Vec<usize> = (0..nbrs.len()).collect();
    fn find(root: &mut [usize], mut i: usize) -> usize {
        while root[i] != i {
            root[i] = root[root[i]];
            i = root[i];
        }
        i
    }
    let pos = |v: u32| nbrs.iter().position(|&u| u == v);
    for &(a, b) in pairs {
        let (Some(i), Some(j)) = (pos(a), pos(b)) else { return false };
        let (ri, rj) = (find(&mut root, i), find(&mut root, j));
        root[ri] = rj;
    }
    let r0 = find(&mut root, 0);
    (1..nbrs.len()).all(|i| find(&mut root, i) == r0)
}

/// One Loop step of the kept neighbourhood, then the pruning to the region's descendants and one
/// ring of faces around them.
fn step(lv: Level, nregion: u32, acc: &mut Acc) -> Level {
    let nv = lv.complete.len();
    let topo = Topology::build(&lv.faces, nv);
    let n2 = nv + topo.edges.len();
    let mut complete = Vec::with_capacity(n2);
    let mut valid = Vec::with_capacity(n2);
    let mut rows = Rows::with_capacity(n2, lv.rows.idx.len() * 4);
    let mut terms: Vec<(u32, f64)> = Vec::with_capacity(16);
    for v in 0..nv {
        let ok = lv.complete[v]
            && lv.valid[v]
            && topo.nbrs(v).iter().all(|&u| lv.valid[u as usize])
            && topo.even_terms(v, &mut terms).is_some();
        complete.push(lv.complete[v]);
        valid.push(ok);
        if ok {
            terms.iter().for_each(|&(u, c)| acc.add(&lv.rows, u, c));
            acc.flush(&mut rows);
        } else {
            rows.push_empty();
        }
    }
    for e in &topo.edges {
        let [a, b] = e.v.map(|v| v as usize);
        let edge_complete = lv.complete[a] || lv.complete[b];
        let ok = edge_complete
            && e.count <= 2
            && lv.valid[a]
            && lv.valid[b]
            && e.opp[..e.count as usize].iter().all(|&o| lv.valid[o as usize]);
        complete.push(edge_complete);
        valid.push(ok);
        if ok {
            if e.count == 1 {
                acc.add(&lv.rows, e.v[0], 0.5);
                acc.add(&lv.rows, e.v[1], 0.5);
            } else {
                acc.add(&lv.rows, e.v[0], 0.375);
                acc.add(&lv.rows, e.v[1], 0.375);
                acc.add(&lv.rows, e.opp[0], 0.125);
                acc.add(&lv.rows, e.opp[1], 0.125);
            }
            acc.flush(&mut rows);
        } else {
            rows.push_empty();
        }
    }
    let mut faces = Vec::with_capacity(lv.faces.len() * 4);
    let mut anc = Vec::with_capacity(lv.faces.len() * 4);
    let mut bary = Vec::with_capacity(lv.faces.len() * 4);
    for (fi, f) in lv.faces.iter().enumerate() {
        let m = topo.face_edges[fi].map(|e| nv as u32 + e);
        let b = lv.bary[fi];
        let h = [0.5 * (b[0] + b[1]), 0.5 * (b[1] + b[2]), 0.5 * (b[2] + b[0])];
        faces.extend([[f[0], m[0], m[2]], [m[0], f[1], m[1]], [m[2], m[1], f[2]], [m[0], m[1], m[2]]]);
        bary.extend([[b[0], h[0], h[2]], [h[0], b[1], h[1]], [h[2], h[1], b[2]], [h[0], h[1], h[2]]]);
        anc.extend([lv.anc[fi]; 4]);
    }
    // Keep the faces that touch a descendant of the region; the vertices of the others lose a
    // face of their fan.
    let mut desc = vec![false; n2];
    for (f, &a) in faces.iter().zip(&anc) {
        if a < nregion {
            f.iter().for_each(|&v| desc[v as usize] = true);
        }
    }
    let keep: Vec<bool> = faces.iter().map(|f| f.iter().any(|&v| desc[v as usize])).collect();
    let mut used = vec![false; n2];
    for (f, &k) in faces.iter().zip(&keep) {
        for &v in f {
            if k {
                used[v as usize] = true;
            } else {
                complete[v as usize] = false;
            }
        }
    }
    let mut new_index = vec![u32::MAX; n2];
    let mut out = Level {
        faces: Vec::with_capacity(faces.len()),
        anc: Vec::with_capacity(faces.len()),
        bary: Vec::with_capacity(faces.len()),
        complete: Vec::with_capacity(n2),
        valid: Vec::with_capacity(n2),
        rows: Rows::with_capacity(n2, rows.idx.len()),
    };
    for v in (0..n2).filter(|&v| used[v]) {
        new_index[v] = out.complete.len() as u32;
        out.complete.push(complete[v]);
        out.valid.push(valid[v]);
        let (idx, w) = rows.row(v);
        out.rows.idx.extend_from_slice(idx);
        out.rows.w.extend_from_slice(w);
        out.rows.start.push(out.rows.idx.len());
    }
    for (i, f) in faces.iter().enumerate().filter(|&(i, _)| keep[i]) {
        out.faces.push(f.map(|v| new_index[v as usize]));
        out.anc.push(anc[i]);
        out.bary.push(bary[i]);
    }
    out
}

/// `refine` with a chosen number of coarse rings around the region (one is enough; zero lets
/// the tests see the cut detected).
fn refine_with_rings(
    nv: usize,
    faces: &[[u32; 3]],
    region: &[u32],
    levels: u32,
    rings: u32,
) -> Result<Refinement, SubdivisionError> {
    if levels > MAX_LEVELS {
        return Err(SubdivisionError::TooManyLevels { levels, max: MAX_LEVELS });
    }
    let (sub_faces, sub_verts, mut lv) = neighbourhood(nv, faces, region, rings)?;
    let nregion = region.len() as u32;
    let mut acc = Acc::new(sub_verts.len());
    for _ in 0..levels {
        lv = step(lv, nregion, &mut acc);
    }
    // The output: the region's descendants, renumbered in level order.
    let nv = lv.complete.len();
    let topo = Topology::build(&lv.faces, nv);
    let mut parent: Vec<(u32, DVec3)> = vec![(u32::MAX, DVec3::ZERO); nv];
    for ((f, &a), b) in lv.faces.iter().zip(&lv.anc).zip(&lv.bary) {
        if a < nregion {
            let coarse = sub_faces[a as usize];
            for k in 0..3 {
                let p = &mut parent[f[k] as usize];
                if coarse < p.0 {
                    *p = (coarse, b[k]);
                }
            }
        }
    }
    let mut new_index = vec![u32::MAX; nv];
    let mut out = Refinement { levels, ..Refinement::default() };
    let mut terms: Vec<(u32, f64)> = Vec::with_capacity(16);
    let mut limit = Rows::with_capacity(1, 64);
    let mut entries: Vec<(u32, f64)> = Vec::with_capacity(64);
    for v in (0..nv).filter(|&v| parent[v].0 != u32::MAX) {
        let ok = lv.complete[v]
            && lv.valid[v]
            && topo.nbrs(v).iter().all(|&u| lv.valid[u as usize])
            && topo.limit_terms(v, &mut terms).is_some();
        if !ok {
            return Err(SubdivisionError::Incomplete { face: parent[v].0 });
        }
        new_index[v] = out.stencils.len() as u32;
        limit.idx.clear();
        limit.w.clear();
        limit.start.truncate(1);
        terms.iter().for_each(|&(u, c)| acc.add(&lv.rows, u, c));
        acc.flush(&mut limit);
        entries.clear();
        entries.extend(limit.idx.iter().zip(&limit.w).map(|(&j, &w)| (sub_verts[j as usize], w)));
        entries.sort_unstable_by_key(|e| e.0);
        out.stencils.push(Stencil {
            vertices: entries.iter().map(|e| e.0).collect(),
            weights: entries.iter().map(|e| e.1).collect(),
        });
        out.parent.push(parent[v]);
    }
    // Faces per region face in region order (each level keeps a face's children together in
    // order, so a stable sort by ancestor gives that order).
    let mut order: Vec<usize> = (0..lv.faces.len()).filter(|&i| lv.anc[i] < nregion).collect();
    order.sort_by_key(|&i| lv.anc[i]);
    out.faces = order.iter().map(|&i| lv.faces[i].map(|v| new_index[v as usize])).collect();
    Ok(out)
}

#[cfg(test)]
#[path = "subdivision_tests.rs"]
mod tests;
