//! Length-true material coordinates from a character's UV atlas.
//!
//! A production asset's UVs are an atlas in [0, 1]: its islands packed at whatever texel density
//! the artist chose. The simulator's material space is in metres (wavelengths, stiffness maps,
//! sizes and remeshing work there), so each UV island is mapped to length units by its 3D rest
//! metric, and where an island is distorted a region gets a conformal chart of its own. The
//! asset's UVs are never changed (they stay for export): this module only computes.
//!
//! - [`islands`]: faces sharing a welded edge whose UVs agree at both ends are one island.
//! - [`length_true`]: each island scaled by sqrt(A_3D / A_UV) about its UV centroid, which lands
//!   at the origin (islands overlap in material space: every coordinate is per face corner), a
//!   mirrored island mirrored back; and per island a distortion report.
//! - [`conformal_chart`]: least squares conformal maps (LSCM, Lévy, Petitjean, Ray, Maillot 2002)
//!   of a disk-like face region of the rest surface, scaled to its true area.
//! - [`distortion`] / [`region_distortion`]: how far per-corner coordinates are from the rest
//!   metric over a face set.
//! - [`per_vertex`]: per-corner coordinates collapsed to per-vertex over a face set that no seam
//!   crosses.
//!
//! Distortion is read from each face's 2x2 map J from its rest triangle (in its own plane) to its
//! material triangle: the principal stretches sigma1 >= sigma2 are J's singular values,
//! sigma1 / sigma2 the anisotropy (1 for a conformal map) and sigma1 sigma2 the area ratio.

use std::ops::Index;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use glam::{DVec2, DVec3};

/// Two UVs agree when each component is equal or differs by at most this fraction of the UV
/// extent (the larger side of the bounding box of the UVs compared).
pub(crate) const AGREE: f64 = 1e-12;

/// A triangle is degenerate when twice its area is at most this fraction of its longest edge
/// squared (a height below 1e-12 of its longest edge); an island or region has zero area when
/// its area is at most this fraction of its bounding box's larger side squared.
pub(crate) const DEGENERATE: f64 = 1e-12;

/// What is wrong with the input. Faces, islands and vertices are named by their index.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum UvError {
    #[error("{corners} per-face corner UV triples for {faces} faces")]
    CornerCount { faces: usize, corners: usize },
    #[error("face {face} names vertex {vertex}, but there are {vertices} vertices")]
    VertexOutOfRange { face: u32, vertex: u32, vertices: usize },
    #[error("vertex {vertex} has a non-finite rest position")]
    NonFinitePosition { vertex: u32 },
    #[error("face {face} has a non-finite UV")]
    NonFiniteUv { face: u32 },
    #[error("the island labels are for {labels} faces, not {faces}")]
    LabelCount { faces: usize, labels: usize },
    #[error("face {face} is in island {island}, but there are {count} islands")]
    LabelOutOfRange { face: u32, island: u32, count: usize },
    #[error("island {island} has no face")]
    EmptyIsland { island: u32 },
    #[error("UV island {island} (face {face}) has zero UV area")]
    ZeroUvArea { island: u32, face: u32 },
    #[error("UV island {island} (face {face}) has zero rest (3D) area")]
    ZeroRestArea { island: u32, face: u32 },
    #[error("the face region is empty")]
    EmptyRegion,
    #[error("region face {face} is not a face (there are {faces})")]
    FaceOutOfRange { face: u32, faces: usize },
    #[error("region face {face} names one vertex twice")]
    RepeatedVertex { face: u32 },
    #[error("edge ({a}, {b}) is shared by more than two faces of the region")]
    NonManifoldEdge { a: u32, b: u32 },
    #[error("region faces {face} and {other} are wound oppositely across their shared edge")]
    InconsistentWinding { face: u32, other: u32 },
    #[error("region face {face} is not edge-connected to region face {first}")]
    NotConnected { face: u32, first: u32 },
    #[error("the region is not a disk: Euler characteristic {euler}, {boundary_loops} boundary loops (want 1 and 1)")]
    NotDisk { euler: i64, boundary_loops: usize },
    #[error("vertex {vertex} lies only on degenerate region faces (face {face})")]
    DegenerateFace { face: u32, vertex: u32 },
    #[error("the region (face {face}) has zero rest area or a degenerate boundary")]
    DegenerateRegion { face: u32 },
    #[error("the conformal chart's least squares system could not be solved: {0}")]
    Solve(String),
}

/// The UV islands of a mesh.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Islands {
    /// Per face, its island: islands are numbered in the order of their lowest face.
    pub of_face: Vec<u32>,
    pub count: usize,
    /// The welded edges (a < b, sorted) shared by two or more faces some two of which disagree
    /// on the UVs of its ends: the UV seams inside the welded surface.
    pub seams: Vec<[u32; 2]>,
}

impl Islands {
    /// The faces of `island`, in increasing order.
    #[cfg(test)]
    pub(crate) fn faces(&self, island: u32) -> Vec<u32> {
        (0..self.of_face.len() as u32).filter(|&f| self.of_face[f as usize] == island).collect()
    }
}

/// A UV island's scale to metres and its distortion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IslandReport {
    pub faces: usize,
    /// Its lowest face.
    pub first_face: u32,
    /// Rest area (m^2).
    pub area_3d: f64,
    /// UV area (the absolute areas of its UV triangles summed), in the asset's UV units squared.
    pub area_uv: f64,
    /// sqrt(area_3d / area_uv): metres per UV unit.
    pub scale: f64,
    /// The area-weighted centroid of its UV triangles: the point that lands at the origin.
    pub centroid_uv: DVec2,
    /// Its UVs are mirrored (most of its UV area wound clockwise seen along the face normals):
    /// the length-true coordinates are mirrored back (u -> -u), so that every island winds as
    /// its faces.
    pub mirrored: bool,
    /// Area-weighted mean and max of sigma1 / sigma2 over its faces (1 for a conformal UV map).
    pub stretch_mean: f64,
    pub stretch_max: f64,
    /// Min and max over its faces of sigma1 sigma2 after the island scale (both 1 where the
    /// texel density is uniform).
    pub area_ratio_min: f64,
    pub area_ratio_max: f64,
    /// Faces whose UV triangle winds opposite to the island's majority (by area).
    pub flipped: usize,
    /// Faces degenerate in 3D or in UV: left out of the stretch and area-ratio figures.
    pub degenerate: usize,
}

/// How far material coordinates are from the rest metric over a face set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Distortion {
    pub faces: usize,
    /// Rest area (m^2) and material area (the absolute areas of the material triangles summed).
    pub area_3d: f64,
    pub area_material: f64,
    /// area_material / area_3d (1 for length-true coordinates or a chart scaled to true area).
    pub area_ratio: f64,
    /// Area-weighted (rest area) mean and max over the faces of sigma1 / sigma2.
    pub stretch_mean: f64,
    pub stretch_max: f64,
    /// Min and max over the faces of sigma1 sigma2 (the local area ratio).
    pub area_ratio_min: f64,
    pub area_ratio_max: f64,
    /// Faces wound opposite to the set's majority (by material area).
    pub flipped: usize,
    /// Faces degenerate at rest or in material space: left out of the per-face figures (NaN
    /// when every face is).
    pub degenerate: usize,
}

/// A conformal chart of a face region: per welded vertex its coordinates (m).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ConformalChart {
    /// Per welded vertex (as many as rest positions), metres; NaN for vertices outside the region.
    pub coords: Vec<DVec2>,
    /// The region's vertices, increasing.
    pub vertices: Vec<u32>,
    /// The pinned boundary vertices (lower index first): the first at the origin, the second on +x.
    pub pins: [u32; 2],
    /// The chart's distortion over the region (area_ratio 1 up to round-off).
    pub report: Distortion,
}

impl Index<usize> for ConformalChart {
    type Output = DVec2;

    fn index(&self, vertex: usize) -> &DVec2 {
        &self.coords[vertex]
    }
}

/// The UV islands: faces sharing a welded edge (the same two vertices) whose corner UVs agree at
/// both its ends (bit-identical, or within [`AGREE`] of the extent of all finite UVs) are in one
/// island, and islands are what that relation connects. Faces past the end of `corner_uv` are
/// islands of their own; a face with a NaN UV joins nothing across that corner's edges
/// ([`length_true`] rejects it).
pub(crate) fn islands(faces: &[[u32; 3]], corner_uv: &[[DVec2; 3]]) -> Islands {
    let n = faces.len();
    let tol = AGREE * extent(corner_uv.iter().flatten());
    // (low vertex, high vertex, face, corner at low, corner at high)
    let mut edges: Vec<(u32, u32, u32, u8, u8)> = Vec::with_capacity(3 * n);
    for (f, face) in faces.iter().enumerate().take(corner_uv.len()) {
        for i in 0..3 {
            let j = (i + 1) % 3;
            let (a, b) = (face[i], face[j]);
            if a != b {
                let (lo, hi, ci, cj) = if a < b { (a, b, i, j) } else { (b, a, j, i) };
                edges.push((lo, hi, f as u32, ci as u8, cj as u8));
            }
        }
    }
    edges.sort_unstable();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut seams = Vec::new();
    for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        let mut seam = false;
        for (i, e) in group.iter().enumerate() {
            for o in &group[i + 1..] {
                let (ue, uo) = (&corner_uv[e.2 as usize], &corner_uv[o.2 as usize]);
                if agree(ue[e.3 as usize], uo[o.3 as usize], tol) && agree(ue[e.4 as usize], uo[o.4 as usize], tol) {
                    union(&mut parent, e.2, o.2);
                } else {
                    seam = true;
                }
            }
        }
        if seam {
            seams.push([group[0].0, group[0].1]);
        }
    }
    // The root of each set is its lowest face: numbering roots as they come numbers islands by
    // their lowest face.
    let mut label = vec![u32::MAX; n];
    let mut of_face = Vec::with_capacity(n);
    let mut count = 0usize;
    for f in 0..n {
        let r = find(&mut parent, f as u32) as usize;
        if label[r] == u32::MAX {
            label[r] = count as u32;
            count += 1;
        }
        of_face.push(label[r]);
    }
    Islands { of_face, count, seams }
}

/// Length-true coordinates (m) per face corner: each island's UVs scaled by its
/// sqrt(A_3D / A_UV) about its area-weighted UV centroid, which lands at the origin (islands
/// keep neither their atlas positions nor their relative layout, and overlap); an island whose
/// UV area is mostly wound clockwise (seen along the face normals) is mirrored back (u -> -u).
/// Per island, its report. Errors: inconsistent lengths or labels, a vertex out of range, a
/// non-finite position or UV (naming the first such face), an island of zero UV or rest area
/// (naming it and its lowest face).
pub(crate) fn length_true(
    rest: &[DVec3],
    faces: &[[u32; 3]],
    corner_uv: &[[DVec2; 3]],
    islands: &Islands,
) -> Result<(Vec<[DVec2; 3]>, Vec<IslandReport>), UvError> {
    if corner_uv.len() != faces.len() {
        return Err(UvError::CornerCount { faces: faces.len(), corners: corner_uv.len() });
    }
    if islands.of_face.len() != faces.len() {
        return Err(UvError::LabelCount { faces: faces.len(), labels: islands.of_face.len() });
    }
    check_vertices(rest, faces, 0..faces.len() as u32)?;
    if let Some(f) = corner_uv.iter().position(|c| !c.iter().all(|p| p.is_finite())) {
        return Err(UvError::NonFiniteUv { face: f as u32 });
    }
    let count = islands.count;
    if let Some(f) = islands.of_face.iter().position(|&i| i as usize >= count) {
        return Err(UvError::LabelOutOfRange { face: f as u32, island: islands.of_face[f], count });
    }

    #[derive(Clone)]
    struct Sum {
        faces: usize,
        first: u32,
        area_3d: Compensated,
        area_uv: Compensated,
        signed_uv: Compensated,
        weighted: [Compensated; 2],
        lo_uv: DVec2,
        hi_uv: DVec2,
        lo_3d: DVec3,
        hi_3d: DVec3,
    }
    let empty = Sum {
        faces: 0,
        first: u32::MAX,
        area_3d: Compensated::default(),
        area_uv: Compensated::default(),
        signed_uv: Compensated::default(),
        weighted: [Compensated::default(); 2],
        lo_uv: DVec2::INFINITY,
        hi_uv: DVec2::NEG_INFINITY,
        lo_3d: DVec3::INFINITY,
        hi_3d: DVec3::NEG_INFINITY,
    };
    let mut sums = vec![empty; count];
    for (f, (face, uv)) in faces.iter().zip(corner_uv).enumerate() {
        let s = &mut sums[islands.of_face[f] as usize];
        let p = face.map(|v| rest[v as usize]);
        let a_uv = 0.5 * (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
        s.faces += 1;
        s.first = s.first.min(f as u32);
        s.area_3d.add(0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length());
        s.area_uv.add(a_uv.abs());
        s.signed_uv.add(a_uv);
        let centre = (uv[0] + uv[1] + uv[2]) / 3.0;
        s.weighted[0].add(a_uv.abs() * centre.x);
        s.weighted[1].add(a_uv.abs() * centre.y);
        for k in 0..3 {
            (s.lo_uv, s.hi_uv) = (s.lo_uv.min(uv[k]), s.hi_uv.max(uv[k]));
            (s.lo_3d, s.hi_3d) = (s.lo_3d.min(p[k]), s.hi_3d.max(p[k]));
        }
    }
    // (scale, centroid, mirrored) per island
    let mut maps = Vec::with_capacity(count);
    let mut areas = Vec::with_capacity(count);
    for (i, s) in sums.iter().enumerate() {
        let island = i as u32;
        if s.faces == 0 {
            return Err(UvError::EmptyIsland { island });
        }
        let (area_3d, area_uv) = (s.area_3d.get(), s.area_uv.get());
        if !exceeds(area_3d, DEGENERATE * (s.hi_3d - s.lo_3d).max_element().powi(2)) {
            return Err(UvError::ZeroRestArea { island, face: s.first });
        }
        if !exceeds(area_uv, DEGENERATE * (s.hi_uv - s.lo_uv).max_element().powi(2)) {
            return Err(UvError::ZeroUvArea { island, face: s.first });
        }
        let centre = DVec2::new(s.weighted[0].get(), s.weighted[1].get()) / area_uv;
        maps.push(((area_3d / area_uv).sqrt(), centre, s.signed_uv.get() < 0.0));
        areas.push((area_3d, area_uv));
    }
    let coords: Vec<[DVec2; 3]> = corner_uv
        .iter()
        .zip(&islands.of_face)
        .map(|(uv, &i)| {
            let (scale, centre, mirrored) = maps[i as usize];
            uv.map(|p| {
                let q = scale * (p - centre);
                if mirrored {
                    DVec2::new(-q.x, q.y)
                } else {
                    q
                }
            })
        })
        .collect();
    let mut members: Vec<Vec<u32>> = sums.iter().map(|s| Vec::with_capacity(s.faces)).collect();
    for (f, &i) in islands.of_face.iter().enumerate() {
        members[i as usize].push(f as u32);
    }
    let reports = sums
        .iter()
        .zip(&maps)
        .zip(&members)
        .zip(&areas)
        .map(|(((s, &(scale, centroid_uv, mirrored)), m), &(area_3d, area_uv))| {
            let d = measure(rest, faces, &coords, m);
            IslandReport {
                faces: s.faces,
                first_face: s.first,
                area_3d,
                area_uv,
                scale,
                centroid_uv,
                mirrored,
                stretch_mean: d.stretch_mean,
                stretch_max: d.stretch_max,
                area_ratio_min: d.area_ratio_min,
                area_ratio_max: d.area_ratio_max,
                flipped: d.flipped,
                degenerate: d.degenerate,
            }
        })
        .collect();
    Ok((coords, reports))
}

/// The distortion of per-corner material coordinates `corners` (one triple per face of `faces`)
/// against the rest metric over the faces `region` (duplicates count once).
pub(crate) fn distortion(
    rest: &[DVec3],
    faces: &[[u32; 3]],
    corners: &[[DVec2; 3]],
    region: &[u32],
) -> Result<Distortion, UvError> {
    if corners.len() != faces.len() {
        return Err(UvError::CornerCount { faces: faces.len(), corners: corners.len() });
    }
    let region = checked_region(faces, region)?;
    check_vertices(rest, faces, region.iter().copied())?;
    if let Some(&f) = region.iter().find(|&&f| !corners[f as usize].iter().all(|p| p.is_finite())) {
        return Err(UvError::NonFiniteUv { face: f });
    }
    Ok(measure(rest, faces, corners, &region))
}

/// (stretch_mean, area_ratio) of [`distortion`]: the area-weighted mean of sigma1 / sigma2 and
/// the region's material area over its rest area; (NaN, NaN) on bad input (every comparison with
/// a threshold then fails: a caller choosing between UVs and a chart picks the chart, whose own
/// checks name the problem).
pub(crate) fn region_distortion(
    rest: &[DVec3],
    faces: &[[u32; 3]],
    corners: &[[DVec2; 3]],
    region: &[u32],
) -> (f64, f64) {
    distortion(rest, faces, corners, region).map_or((f64::NAN, f64::NAN), |d| (d.stretch_mean, d.area_ratio))
}

/// A least squares conformal map (LSCM) of the rest surface of the faces `region`, which must be
/// an edge-connected, consistently wound, edge-manifold disk (Euler characteristic 1, one
/// boundary loop). Two boundary vertices far apart are pinned (a double sweep of the farthest
/// boundary vertex from the lowest-numbered one; the lower-numbered pin at the origin, the other
/// on +x); the free coordinates solve the normal equations by a sparse Cholesky (faer, AMD
/// ordering, sequential). The chart is then scaled about the origin so its area equals the
/// region's rest area, and winds as the faces. Rest-degenerate faces carry no conformal energy.
pub(crate) fn conformal_chart(rest: &[DVec3], faces: &[[u32; 3]], region: &[u32]) -> Result<ConformalChart, UvError> {
    let region = checked_region(faces, region)?;
    check_vertices(rest, faces, region.iter().copied())?;
    if let Some(&f) = region.iter().find(|&&f| {
        let t = faces[f as usize];
        t[0] == t[1] || t[1] == t[2] || t[2] == t[0]
    }) {
        return Err(UvError::RepeatedVertex { face: f });
    }
    let mut vertices: Vec<u32> = region.iter().flat_map(|&f| faces[f as usize]).collect();
    vertices.sort_unstable();
    vertices.dedup();
    let local = |v: u32| vertices.binary_search(&v).unwrap_or(usize::MAX);

    // Topology: edges with their faces and direction (lo -> hi in the face's winding).
    let mut edges: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(3 * region.len());
    for &f in &region {
        let t = faces[f as usize];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), f, a < b));
        }
    }
    edges.sort_unstable();
    let index_of = |f: u32| region.binary_search(&f).unwrap_or(0) as u32;
    let mut parent: Vec<u32> = (0..region.len() as u32).collect();
    let mut boundary: Vec<(u32, u32)> = Vec::new();
    let mut edge_count = 0i64;
    for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        edge_count += 1;
        match group {
            [e] => boundary.push((e.0, e.1)),
            [e, o] => {
                if e.3 == o.3 {
                    return Err(UvError::InconsistentWinding { face: e.2, other: o.2 });
                }
                union(&mut parent, index_of(e.2), index_of(o.2));
            }
            _ => return Err(UvError::NonManifoldEdge { a: group[0].0, b: group[0].1 }),
        }
    }
    if let Some(k) = (0..region.len() as u32).find(|&k| find(&mut parent, k) != 0) {
        return Err(UvError::NotConnected { face: region[k as usize], first: region[0] });
    }
    let euler = vertices.len() as i64 - edge_count + region.len() as i64;
    let mut bparent: Vec<u32> = (0..vertices.len() as u32).collect();
    let mut on_boundary = vec![false; vertices.len()];
    for &(a, b) in &boundary {
        let (la, lb) = (local(a), local(b));
        on_boundary[la] = true;
        on_boundary[lb] = true;
        union(&mut bparent, la as u32, lb as u32);
    }
    let loops = (0..vertices.len()).filter(|&l| on_boundary[l] && find(&mut bparent, l as u32) == l as u32).count();
    if euler != 1 || loops != 1 {
        return Err(UvError::NotDisk { euler, boundary_loops: loops });
    }

    // Pins: a double sweep for a far-apart pair of boundary vertices.
    let degenerate = UvError::DegenerateRegion { face: region[0] };
    let bverts: Vec<usize> = (0..vertices.len()).filter(|&l| on_boundary[l]).collect();
    let at = |l: usize| rest[vertices[l] as usize];
    let farthest = |from: usize| {
        let mut best = (from, 0.0);
        for &l in &bverts {
            let d = at(l).distance_squared(at(from));
            if d > best.1 {
                best = (l, d);
            }
        }
        best.0
    };
    let b = farthest(bverts[0]);
    let a = farthest(b);
    if a == b {
        return Err(degenerate);
    }
    let (p0, p1) = (a.min(b), a.max(b));
    let pinned = [DVec2::ZERO, DVec2::new(at(p0).distance(at(p1)), 0.0)];

    // Free unknowns: (u, v) of each unpinned vertex at 2k, 2k + 1.
    let mut free = vec![usize::MAX; vertices.len()];
    let mut n_free = 0;
    for (l, slot) in free.iter_mut().enumerate() {
        if l != p0 && l != p1 {
            *slot = n_free;
            n_free += 1;
        }
    }
    let n = 2 * n_free;
    let mut covered = vec![false; vertices.len()];
    covered[p0] = true;
    covered[p1] = true;
    let mut triplets: Vec<(usize, usize, f64)> = Vec::with_capacity(region.len() * 42);
    let mut rhs = vec![0.0; n];
    for &f in &region {
        let t = faces[f as usize];
        let Some((x1, x2, y2)) = flat(t.map(|v| rest[v as usize])) else { continue };
        let ls = t.map(local);
        ls.iter().for_each(|&l| covered[l] = true);
        // Cauchy-Riemann residuals u_x - v_y and u_y + v_x times sqrt(area): with e_j the edge
        // opposite corner j, sum_j (-e_j.y u_j - e_j.x v_j) and sum_j (e_j.x u_j - e_j.y v_j)
        // over 2 sqrt(area).
        let e = [DVec2::new(x2 - x1, y2), DVec2::new(-x2, -y2), DVec2::new(x1, 0.0)];
        let w = 1.0 / (2.0 * (0.5 * x1 * y2).sqrt());
        for row in 0..2 {
            let mut entries = [(0usize, 0.0f64); 6];
            for j in 0..3 {
                let (cu, cv) = if row == 0 { (-e[j].y, -e[j].x) } else { (e[j].x, -e[j].y) };
                entries[2 * j] = (2 * ls[j], w * cu);
                entries[2 * j + 1] = (2 * ls[j] + 1, w * cv);
            }
            let mut known = 0.0;
            let mut vars = [(0usize, 0.0f64); 6];
            let mut m = 0;
            for &(var, c) in &entries {
                let l = var / 2;
                if l == p0 || l == p1 {
                    let p = pinned[usize::from(l == p1)];
                    known += c * if var % 2 == 0 { p.x } else { p.y };
                } else {
                    vars[m] = (2 * free[l] + var % 2, c);
                    m += 1;
                }
            }
            for (i, &(ri, ci)) in vars[..m].iter().enumerate() {
                rhs[ri] -= ci * known;
                for &(rj, cj) in &vars[..=i] {
                    let (r, c) = (ri.max(rj), ri.min(rj));
                    triplets.push((c, r, ci * cj));
                }
            }
        }
    }
    if let Some(l) = covered.iter().position(|&c| !c) {
        let v = vertices[l];
        let face = region.iter().copied().find(|&f| faces[f as usize].contains(&v)).unwrap_or(region[0]);
        return Err(UvError::DegenerateFace { face, vertex: v });
    }
    let x = solve_spd(n, triplets, rhs)?;

    let mut chart = vec![DVec2::ZERO; vertices.len()];
    for (l, c) in chart.iter_mut().enumerate() {
        *c = if l == p0 {
            pinned[0]
        } else if l == p1 {
            pinned[1]
        } else {
            DVec2::new(x[2 * free[l]], x[2 * free[l] + 1])
        };
    }
    let (mut area_3d, mut area_chart) = (Compensated::default(), Compensated::default());
    for &f in &region {
        let t = faces[f as usize];
        let p = t.map(|v| rest[v as usize]);
        let q = t.map(|v| chart[local(v)]);
        area_3d.add(0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length());
        area_chart.add(0.5 * (q[1] - q[0]).perp_dot(q[2] - q[0]).abs());
    }
    let k = (area_3d.get() / area_chart.get()).sqrt();
    if !(k.is_finite() && k > 0.0) {
        return Err(degenerate);
    }
    let mut coords = vec![DVec2::NAN; rest.len()];
    for (l, &v) in vertices.iter().enumerate() {
        coords[v as usize] = k * chart[l];
    }
    let corners: Vec<[DVec2; 3]> =
        faces.iter().map(|t| t.map(|v| coords.get(v as usize).copied().unwrap_or(DVec2::NAN))).collect();
    let report = measure(rest, faces, &corners, &region);
    Ok(ConformalChart { coords, pins: [vertices[p0], vertices[p1]], vertices, report })
}

// ------------------------------------------------------------------------------- helpers

/// The triangle in its own plane, p0 at the origin, p1 on +x and p2 above it: (x1, x2, y2), so
/// p1 = (x1, 0) and p2 = (x2, y2); None when degenerate (or not finite).
fn flat(t: [DVec3; 3]) -> Option<(f64, f64, f64)> {
    let (a, b) = (t[1] - t[0], t[2] - t[0]);
    let twice = a.cross(b).length();
    let longest = a.length_squared().max(b.length_squared()).max((t[2] - t[1]).length_squared());
    if !(twice.is_finite() && exceeds(twice, DEGENERATE * longest)) {
        return None;
    }
    let x1 = a.length();
    Some((x1, a.dot(b) / x1, twice / x1))
}

/// The principal stretches (sigma1 >= sigma2 >= 0) and the determinant of the 2x2 map J from a
/// rest triangle in its plane (`flat`) to a 2D triangle with edges d1 = q1 - q0, d2 = q2 - q0.
fn stretches((x1, x2, y2): (f64, f64, f64), d1: DVec2, d2: DVec2) -> (f64, f64, f64) {
    // J [x1 x2; 0 y2] = [d1 d2]
    let c0 = d1 / x1;
    let c1 = (d2 - c0 * x2) / y2;
    let (a, b, c, d) = (c0.x, c1.x, c0.y, c1.y);
    let q = (0.5 * (a + d)).hypot(0.5 * (c - b));
    let r = (0.5 * (a - d)).hypot(0.5 * (c + b));
    (q + r, (q - r).abs(), a * d - b * c)
}

/// The distortion of `corners` over the faces `set` (checked, sorted, no duplicates).
fn measure(rest: &[DVec3], faces: &[[u32; 3]], corners: &[[DVec2; 3]], set: &[u32]) -> Distortion {
    let [mut area_3d, mut area_material, mut signed] = [Compensated::default(); 3];
    let (mut weight, mut stretch_sum, mut stretch_max) = (Compensated::default(), Compensated::default(), f64::NAN);
    let (mut ratio_min, mut ratio_max) = (f64::NAN, f64::NAN);
    let (mut positive, mut negative, mut degenerate) = (0usize, 0usize, 0usize);
    for &f in set {
        let t = faces[f as usize].map(|v| rest[v as usize]);
        let q = corners[f as usize];
        let a3 = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        let (d1, d2) = (q[1] - q[0], q[2] - q[0]);
        let twice = d1.perp_dot(d2);
        area_3d.add(a3);
        area_material.add(0.5 * twice.abs());
        signed.add(0.5 * twice);
        let longest = d1.length_squared().max(d2.length_squared()).max((q[2] - q[1]).length_squared());
        let Some(frame) = flat(t).filter(|_| twice.abs() > DEGENERATE * longest) else {
            degenerate += 1;
            continue;
        };
        let (s1, s2, det) = stretches(frame, d1, d2);
        let ratio = s1 / s2;
        weight.add(a3);
        stretch_sum.add(a3 * ratio);
        stretch_max = stretch_max.max(ratio);
        ratio_min = ratio_min.min(s1 * s2);
        ratio_max = ratio_max.max(s1 * s2);
        if det < 0.0 {
            negative += 1;
        } else {
            positive += 1;
        }
    }
    let (area_3d, area_material, weight) = (area_3d.get(), area_material.get(), weight.get());
    Distortion {
        faces: set.len(),
        area_3d,
        area_material,
        area_ratio: area_material / area_3d,
        stretch_mean: if weight > 0.0 { stretch_sum.get() / weight } else { f64::NAN },
        stretch_max,
        area_ratio_min: ratio_min,
        area_ratio_max: ratio_max,
        flipped: if signed.get() < 0.0 { positive } else { negative },
        degenerate,
    }
}

/// The region's faces sorted without duplicates; errors for an empty region or a face out of range.
fn checked_region(faces: &[[u32; 3]], region: &[u32]) -> Result<Vec<u32>, UvError> {
    if region.is_empty() {
        return Err(UvError::EmptyRegion);
    }
    if let Some(&f) = region.iter().find(|&&f| f as usize >= faces.len()) {
        return Err(UvError::FaceOutOfRange { face: f, faces: faces.len() });
    }
    let mut r = region.to_vec();
    r.sort_unstable();
    r.dedup();
    Ok(r)
}

/// Every vertex of the faces `set` is in range and its rest position finite.
fn check_vertices(rest: &[DVec3], faces: &[[u32; 3]], set: impl Iterator<Item = u32>) -> Result<(), UvError> {
    for f in set {
        for &v in &faces[f as usize] {
            match rest.get(v as usize) {
                None => return Err(UvError::VertexOutOfRange { face: f, vertex: v, vertices: rest.len() }),
                Some(p) if !p.is_finite() => return Err(UvError::NonFinitePosition { vertex: v }),
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// The larger side of the bounding box of the finite points (0 for none).
fn extent<'a>(points: impl Iterator<Item = &'a DVec2>) -> f64 {
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for p in points.filter(|p| p.is_finite()) {
        (lo, hi) = (lo.min(*p), hi.max(*p));
    }
    if lo.x <= hi.x {
        (hi - lo).max_element()
    } else {
        0.0
    }
}

/// A sum with Neumaier's compensation: plain summation of many similar areas drifts by ~1e-14
/// (its rounding is biased as the sum grows), which is more than the scale's own precision.
#[derive(Clone, Copy, Debug, Default)]
struct Compensated {
    sum: f64,
    carry: f64,
}

impl Compensated {
    fn add(&mut self, x: f64) {
        let t = self.sum + x;
        self.carry += if self.sum.abs() >= x.abs() { (self.sum - t) + x } else { (x - t) + self.sum };
        self.sum = t;
    }

    fn get(self) -> f64 {
        self.sum + self.carry
    }
}

/// x > threshold, false when either is NaN.
fn exceeds(x: f64, threshold: f64) -> bool {
    x > threshold
}

fn agree(a: DVec2, b: DVec2, tol: f64) -> bool {
    (a.x == b.x || (a.x - b.x).abs() <= tol) && (a.y == b.y || (a.y - b.y).abs() <= tol)
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Joins the sets of a and b under the lower root.
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}

/// Solves the n x n symmetric positive definite system given by lower-triangle (column, row,
/// value) entries (duplicates summed) with a sparse LL^T (AMD ordering, sequential).
fn solve_spd(n: usize, mut entries: Vec<(usize, usize, f64)>, mut rhs: Vec<f64>) -> Result<Vec<f64>, UvError> {
    if n == 0 {
        return Ok(rhs);
    }
    entries.sort_unstable_by_key(|e| (e.0, e.1));
    let mut col_ptr = vec![0usize; n + 1];
    let mut row_idx = Vec::with_capacity(entries.len());
    let mut values: Vec<f64> = Vec::with_capacity(entries.len());
    for group in entries.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
        col_ptr[group[0].0 + 1] += 1;
        row_idx.push(group[0].1);
        values.push(group.iter().map(|e| e.2).sum());
    }
    for c in 0..n {
        col_ptr[c + 1] += col_ptr[c];
    }
    let fail = |what: &str| UvError::Solve(what.to_owned());
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let symbolic =
        factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Amd, CholeskySymbolicParams::default())
            .map_err(|e| fail(&format!("symbolic factorization: {e:?}")))?;
    let req = StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
    ]);
    let mut mem = MemBuffer::try_new(req).map_err(|_| fail("out of memory"))?;
    let mut l_values = vec![0.0; symbolic.len_val()];
    let llt = symbolic
        .factorize_numeric_llt(
            &mut l_values,
            SparseColMatRef::new(sym, &values),
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|_| fail("the normal matrix is not positive definite (a degenerate region?)"))?;
    llt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(&mut rhs, n, 1),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    if rhs.iter().all(|x| x.is_finite()) {
        Ok(rhs)
    } else {
        Err(fail("non-finite solution"))
    }
}

#[cfg(test)]
#[path = "uv_islands_tests.rs"]
mod tests;
