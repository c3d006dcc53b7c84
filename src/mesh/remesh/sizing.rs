//! The sizing field of adaptive remeshing (REMESH.md, after Narain et al. 2012): per face a
//! symmetric 2x2 metric M in material space, an edge u being short enough when u^T M u <= 1.

use glam::{DMat2, DVec2, DVec3};

use super::RemeshParams;
use crate::mesh::shading::vertex_normals;
use crate::physics::hinge::dihedral_f64;

/// One face's geometry: material-space and world-space corners.
#[derive(Clone, Copy, Debug)]
pub struct FaceGeometry {
    pub uv: [DVec2; 3],
    pub x: [DVec3; 3],
}

impl FaceGeometry {
    /// Material-space edge matrix Dm = [u1 - u0, u2 - u0].
    pub(crate) fn dm(&self) -> DMat2 {
        DMat2::from_cols(self.uv[1] - self.uv[0], self.uv[2] - self.uv[0])
    }

    /// Signed material-space area.
    pub fn area(&self) -> f64 {
        0.5 * self.dm().determinant()
    }

    /// Gradient of a per-vertex 3-vector field over the face: [w1 - w0, w2 - w0] Dm^-1 (3x2,
    /// as two columns).
    fn gradient(&self, w: [DVec3; 3]) -> [DVec3; 2] {
        let inv = self.dm().inverse();
        let (a, b) = (w[1] - w[0], w[2] - w[0]);
        [a * inv.x_axis.x + b * inv.x_axis.y, a * inv.y_axis.x + b * inv.y_axis.y]
    }
}

/// The Green strain (F^T F - I) / 2 of a face's map from material to world space.
pub(crate) fn green_strain(face: &FaceGeometry) -> DMat2 {
    (gram(face.gradient(face.x)) - DMat2::IDENTITY) * 0.5
}

/// G^T G for a 3x2 matrix G given by its columns.
fn gram(g: [DVec3; 2]) -> DMat2 {
    let off = g[0].dot(g[1]);
    DMat2::from_cols(DVec2::new(g[0].length_squared(), off), DVec2::new(off, g[1].length_squared()))
}

/// Eigen-decomposition of a symmetric 2x2 matrix: (eigenvalues ascending, unit eigenvector of
/// the first).
pub(crate) fn sym_eigen(m: DMat2) -> ([f64; 2], DVec2) {
    let (a, b, d) = (m.x_axis.x, 0.5 * (m.x_axis.y + m.y_axis.x), m.y_axis.y);
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (lo, hi) = (mean - r, mean + r);
    // Eigenvector of lo: (b, lo - a) or (lo - d, b), whichever is better conditioned.
    let v1 = DVec2::new(b, lo - a);
    let v2 = DVec2::new(lo - d, b);
    let v = if v1.length_squared() >= v2.length_squared() { v1 } else { v2 };
    let v = if v.length_squared() > 0.0 { v.normalize() } else { DVec2::X };
    ([lo, hi], v)
}

/// The symmetric matrix with eigenvalues `l` on the eigenvectors (v, perp v).
fn from_eigen(l: [f64; 2], v: DVec2) -> DMat2 {
    let p = v.perp();
    let outer = |u: DVec2| DMat2::from_cols(u * u.x, u * u.y);
    outer(v) * l[0] + outer(p) * l[1]
}

/// Applies f to the eigenvalues of a symmetric matrix.
fn map_eigen(m: DMat2, f: impl Fn(f64) -> f64) -> DMat2 {
    let (l, v) = sym_eigen(m);
    from_eigen([f(l[0]), f(l[1])], v)
}

/// A symmetric 2x2 matrix as a disk in the plane ((a - d) / 2, b) with radius (a + d) / 2:
/// B - A is positive semidefinite exactly when disk(B) contains disk(A).
#[derive(Clone, Copy, Debug)]
struct Disk {
    c: DVec2,
    r: f64,
}

impl Disk {
    fn of(m: DMat2) -> Disk {
        let (a, b, d) = (m.x_axis.x, 0.5 * (m.x_axis.y + m.y_axis.x), m.y_axis.y);
        Disk { c: DVec2::new(0.5 * (a - d), b), r: 0.5 * (a + d) }
    }

    fn matrix(self) -> DMat2 {
        let (p, b, m) = (self.c.x, self.c.y, self.r);
        DMat2::from_cols(DVec2::new(m + p, b), DVec2::new(b, m - p))
    }

    fn contains(self, o: Disk) -> bool {
        self.c.distance(o.c) + o.r <= self.r * (1.0 + 1e-12) + 1e-300
    }

    /// The smallest disk containing both.
    fn enclose(self, o: Disk) -> Disk {
        if self.contains(o) {
            return self;
        }
        if o.contains(self) {
            return o;
        }
        let d = self.c.distance(o.c);
        let r = 0.5 * (d + self.r + o.r);
        let c = self.c + (o.c - self.c) * ((r - self.r) / d);
        Disk { c, r }
    }
}

/// A "tensor max" of PSD metrics: a PSD matrix that dominates every term (the smallest such
/// for two terms; for more, the terms are enclosed one at a time, which may exceed the smallest
/// by a little and so refines slightly more, never less).
pub(crate) fn tensor_max(terms: &[DMat2]) -> DMat2 {
    let mut iter = terms.iter().map(|&m| Disk::of(m));
    let Some(first) = iter.next() else { return DMat2::ZERO };
    iter.fold(first, Disk::enclose).matrix()
}

/// Clamps a metric (REMESH.md): eigenvalues into [1/size_max^2, 1/size_min^2], and each at
/// least aspect_min^2 times the largest. A non-finite metric asks for the finest size.
pub fn clamp(m: DMat2, p: &RemeshParams) -> DMat2 {
    let (lo, hi) = (1.0 / (p.size_max * p.size_max), 1.0 / (p.size_min * p.size_min));
    if !m.is_finite() {
        return DMat2::IDENTITY * hi;
    }
    let (l, v) = sym_eigen(m);
    let l = l.map(|x| x.clamp(lo, hi));
    let floor = p.aspect_min * p.aspect_min * l[1];
    from_eigen([l[0].max(floor), l[1].max(floor)], v)
}

/// Curvature operator of a face (REMESH.md): S = -(1/area) sum_e 1/2 theta_e |e| t_e t_e^T over
/// its edges, theta_e the dihedral angle (0 on the boundary), t_e the unit in-plane normal.
pub fn curvature(face: &FaceGeometry, theta: [f64; 3]) -> DMat2 {
    let area = face.area().abs();
    let mut s = DMat2::ZERO;
    for (k, angle) in theta.iter().enumerate() {
        let e = face.uv[(k + 1) % 3] - face.uv[k];
        let len = e.length();
        if len == 0.0 {
            continue;
        }
        let t = e.perp() / len;
        s += DMat2::from_cols(t * t.x, t * t.y) * (0.5 * angle * len);
    }
    s * (-1.0 / area)
}

/// Compression term (REMESH.md): with e = F^T F - I and N the normal gradient,
/// pos(-e + ssqrt(e^T e - 4 c^2 adj(N^T N))) / (2 c^2); max(-e, 0) / c^2 without curvature.
pub fn compression(e: DMat2, normal_gram: DMat2, c: f64) -> DMat2 {
    let adj = DMat2::from_cols(
        DVec2::new(normal_gram.y_axis.y, -normal_gram.x_axis.y),
        DVec2::new(-normal_gram.y_axis.x, normal_gram.x_axis.x),
    );
    let d = e.transpose() * e - adj * (4.0 * c * c);
    let root = map_eigen(d, |l| l.signum() * l.abs().sqrt());
    map_eigen(root - e, |l| l.max(0.0)) * (1.0 / (2.0 * c * c))
}

/// The unclamped metric of one face: curvature (dihedral and normal gradient), compression and,
/// when `velocity` is given, the velocity gradient, combined by `tensor_max`.
pub(crate) fn face_metric(
    face: &FaceGeometry,
    theta: [f64; 3],
    normals: [DVec3; 3],
    velocity: Option<[DVec3; 3]>,
    p: &RemeshParams,
) -> DMat2 {
    let inv_angle2 = 1.0 / (p.refine_angle * p.refine_angle);
    let s = curvature(face, theta);
    let n_gram = gram(face.gradient(normals));
    let f = face.gradient(face.x);
    let strain = gram(f) - DMat2::IDENTITY;
    let mut terms =
        vec![s.transpose() * s * inv_angle2, n_gram * inv_angle2, compression(strain, n_gram, p.refine_compression)];
    if let (Some(v), Some(rv)) = (velocity, p.refine_velocity) {
        terms.push(gram(face.gradient(v)) * (1.0 / (rv * rv)));
    }
    tensor_max(&terms)
}

/// Wavelength-aware refinement (issue 26): where the compression a layer is driven to passes
/// `onset` times its critical strain, edges across the wrinkles are at most lambda /
/// `per_wavelength`, so that the solve that buckles sees a mesh that can hold the mode.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WavelengthSizing {
    pub per_wavelength: f64,
    pub onset: f64,
    /// Every edge bounded there, not only those across the compression: the mesh then holds
    /// wrinkles of any direction and phase (where they form later, or beside the compression
    /// that drives them, their direction is not the one the driver shows now).
    pub isotropic: bool,
    /// The compression the kinematic layers below reach now and at their motions' later
    /// keyframes, and not that of the layers between: the mesh is refined before the load gets
    /// there, and not again for what the layers between take once wrinkled.
    pub lookahead: bool,
    /// And within this material distance (m) of those faces: the layers between spread the
    /// compression of the driven region around it (a pinched disc's ring of wrinkles).
    pub margin: f64,
    /// At every remesh after the layer's first, leave alone the faces under the term whose edges
    /// already meet its bound (`held_faces`): refined before they wrinkle, they are not
    /// remeshed again once they have (issue 26 items 2 and 3; a remesh of a wrinkled region
    /// lets its pattern relax, which costs Newton iterations at every remesh). A held face with
    /// an edge the whole sizing field wants split is released (`RemeshStats::released`).
    pub hold: bool,
}

/// The compressive strain at which a plate of thickness h held to wrinkles of wavelength lambda
/// buckles: N = D k^2 with k = 2 pi / lambda over the membrane stiffness E h / (1 - nu^2), so
/// (k h)^2 / 12 (LK14 3.1: the kernels fix the wavelength, the layer's bending sets the load).
pub(crate) fn critical_strain(thickness: f64, lambda: f64) -> f64 {
    let k = 2.0 * std::f64::consts::PI / lambda;
    (k * thickness).powi(2) / 12.0
}

/// The wavelength term of one face: `strain` the (Green) membrane strain the face is driven to,
/// in material coordinates; (per_wavelength / lambda)^2 along the most compressed direction
/// when its compression passes `onset` x `critical`, else zero (an edge along the wrinkles'
/// crests is left to the other terms and the aspect bound).
pub fn wavelength_term(strain: DMat2, lambda: f64, critical: f64, w: &WavelengthSizing) -> DMat2 {
    let (l, v) = sym_eigen(strain);
    // (a NaN wavelength asks for nothing)
    if lambda.is_nan() || lambda <= 0.0 || -l[0] <= w.onset * critical {
        return DMat2::ZERO;
    }
    let k = w.per_wavelength / lambda;
    if w.isotropic {
        return DMat2::IDENTITY * (k * k);
    }
    from_eigen([k * k, 0.0], v)
}

/// `terms` grown by `margin`: a face without a term takes that of the nearest face with one whose
/// centroid lies within `margin` of its own (the first such face on a tie).
pub(crate) fn grow_terms(terms: &[DMat2], centroids: &[DVec2], margin: f64) -> Vec<DMat2> {
    if margin <= 0.0 {
        return terms.to_vec();
    }
    let cell = |c: DVec2| ((c.x / margin).floor() as i64, (c.y / margin).floor() as i64);
    let mut bins: std::collections::HashMap<(i64, i64), Vec<usize>> = std::collections::HashMap::new();
    for i in (0..terms.len()).filter(|&i| terms[i] != DMat2::ZERO) {
        bins.entry(cell(centroids[i])).or_default().push(i);
    }
    let nearest = |c: DVec2| {
        let (bx, by) = cell(c);
        let near = (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (bx + dx, by + dy)));
        let candidates = near.filter_map(|b| bins.get(&b)).flatten();
        candidates
            .map(|&j| (centroids[j].distance_squared(c), j))
            .filter(|&(d2, _)| d2 <= margin * margin)
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
    };
    terms
        .iter()
        .zip(centroids)
        .map(|(&t, &c)| if t != DMat2::ZERO { t } else { nearest(c).map_or(t, |(_, j)| terms[j]) })
        .collect()
}

/// How far past the wavelength bound a held face's edges may be (`held_faces`' slack): at the
/// edge of the term's region a vertex's metric is the mean of its faces', with and without the
/// term, so the refinement leaves edges there up to about sqrt 2 of the bound.
pub const HOLD_SLACK: f64 = 1.5;

/// The faces a remesh leaves alone under `WavelengthSizing::hold`: those with a wavelength term
/// (`terms`, one per face) whose every edge is at most `slack` long in it.
pub fn held_faces(terms: &[DMat2], uv: &[DVec2], faces: &[[u32; 3]], slack: f64) -> Vec<bool> {
    faces
        .iter()
        .zip(terms)
        .map(|(f, &t)| {
            t != DMat2::ZERO
                && (0..3).all(|k| {
                    let e = uv[f[(k + 1) % 3] as usize] - uv[f[k] as usize];
                    e.dot(t * e) <= slack * slack
                })
        })
        .collect()
}

/// The material centroid of each face.
pub(crate) fn face_centroids(uv: &[DVec2], faces: &[[u32; 3]]) -> Vec<DVec2> {
    faces.iter().map(|f| f.iter().map(|&i| uv[i as usize]).sum::<DVec2>() / 3.0).collect()
}

/// Raises each face's wavelength term (`terms`, by `tensor_max`) to the one a lower layer asks:
/// the lower layer's strain at the face's material centroid, lambda from the nearest of
/// `centres` (kernel centre, wavelength), the critical strain from `thickness`. `lower` is the
/// lower layer's (material positions, positions, faces).
pub fn add_wavelength_terms(
    terms: &mut [DMat2],
    centroids: &[DVec2],
    centres: &[(DVec2, f64)],
    thickness: f64,
    lower: (&[DVec2], &[DVec3], &[[u32; 3]]),
    w: &WavelengthSizing,
) {
    let (uv, x, faces) = lower;
    if faces.is_empty() {
        return;
    }
    let flat: Vec<DVec3> = uv.iter().map(|u| u.extend(0.0)).collect();
    let strain: Vec<DMat2> = faces
        .iter()
        .map(|f| green_strain(&FaceGeometry { uv: f.map(|i| uv[i as usize]), x: f.map(|i| x[i as usize]) }))
        .collect();
    let locator = crate::mesh::locate::XyLocator::new(&flat, faces);
    for (&c, term) in centroids.iter().zip(terms) {
        let nearest = centres.iter().min_by(|a, b| a.0.distance_squared(c).total_cmp(&b.0.distance_squared(c)));
        let (Some(&(_, lambda)), Some((face, _))) = (nearest, locator.locate(c.extend(0.0))) else { continue };
        *term = tensor_max(&[*term, wavelength_term(strain[face], lambda, critical_strain(thickness, lambda), w)]);
    }
}

/// A layer below the remeshed one, as its wavelength term reads it: material positions,
/// faces, and the positions it is measured at (now, and under lookahead at later keyframes).
pub struct LowerLayer {
    pub uv: Vec<DVec2>,
    pub faces: Vec<[u32; 3]>,
    pub poses: Vec<Vec<DVec3>>,
}

/// The wavelength term of each face of a layer (material positions `uv`, `faces`; issue 26
/// item 1): the largest any layer below asks at any of its poses (`add_wavelength_terms`),
/// grown by `w.margin` (`grow_terms`).
pub fn wavelength_terms(
    uv: &[DVec2],
    faces: &[[u32; 3]],
    centres: &[(DVec2, f64)],
    thickness: f64,
    below: &[LowerLayer],
    w: &WavelengthSizing,
) -> Vec<DMat2> {
    let centroids = face_centroids(uv, faces);
    let mut terms = vec![DMat2::ZERO; faces.len()];
    for lower in below {
        for x in &lower.poses {
            add_wavelength_terms(&mut terms, &centroids, centres, thickness, (&lower.uv, x, &lower.faces), w);
        }
    }
    grow_terms(&terms, &centroids, w.margin)
}

/// Per-vertex metrics for a surface (REMESH.md): each face's clamped metric, then the
/// material-area-weighted mean over a vertex's faces. `extra`, when not empty, holds one more
/// term per face (the wavelength term), combined by `tensor_max` before the clamp.
pub(crate) fn vertex_sizing(
    uv: &[DVec2],
    x: &[DVec3],
    velocity: Option<&[DVec3]>,
    faces: &[[u32; 3]],
    extra: &[DMat2],
    p: &RemeshParams,
) -> Vec<DMat2> {
    let normals = vertex_normals(x, faces);
    let mut theta = vec![[0.0f64; 3]; faces.len()];
    for e in crate::mesh::edges(faces).iter().filter(|e| e.is_interior()) {
        let q = [e.v[0], e.v[1], e.opposite[0], e.opposite[1]].map(|i| x[i as usize]);
        let angle = dihedral_f64(&q);
        for side in 0..2 {
            let f = faces[e.faces[side] as usize];
            let k = (0..3).find(|&k| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                (a, b) == (e.v[0], e.v[1]) || (a, b) == (e.v[1], e.v[0])
            });
            if let Some(k) = k {
                theta[e.faces[side] as usize][k] = angle;
            }
        }
    }
    let mut sum = vec![DMat2::ZERO; uv.len()];
    let mut weight = vec![0.0; uv.len()];
    for (fi, f) in faces.iter().enumerate() {
        let geo = FaceGeometry { uv: f.map(|i| uv[i as usize]), x: f.map(|i| x[i as usize]) };
        let area = geo.area().abs();
        if area == 0.0 {
            continue;
        }
        let vel = velocity.map(|v| f.map(|i| v[i as usize]));
        let mut m = face_metric(&geo, theta[fi], f.map(|i| normals[i as usize]), vel, p);
        if let Some(&term) = extra.get(fi) {
            m = tensor_max(&[m, term]);
        }
        let m = clamp(m, p);
        for &v in f {
            sum[v as usize] += m * area;
            weight[v as usize] += area;
        }
    }
    sum.iter().zip(&weight).map(|(m, w)| if *w > 0.0 { *m * (1.0 / w) } else { DMat2::ZERO }).collect()
}

/// The metric length of a material-space edge u between vertices with metrics ma and mb.
pub(crate) fn edge_size(u: DVec2, ma: DMat2, mb: DMat2) -> f64 {
    (0.5 * (u.dot(ma * u) + u.dot(mb * u))).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> RemeshParams {
        RemeshParams {
            size_min: 0.01,
            size_max: 1.0,
            aspect_min: 0.2,
            refine_angle: 0.3,
            refine_compression: 0.01,
            refine_velocity: None,
            curved_splits: true,
        }
    }

    fn close(a: DMat2, b: DMat2, tol: f64) -> bool {
        (a - b).to_cols_array().iter().all(|d| d.abs() <= tol)
    }

    #[test]
    fn tensor_max_dominates_every_term_and_is_exact_for_two() {
        let a = DMat2::from_cols(DVec2::new(4.0, 0.0), DVec2::new(0.0, 1.0));
        let b = DMat2::from_cols(DVec2::new(1.0, 0.0), DVec2::new(0.0, 4.0));
        let m = tensor_max(&[a, b]);
        assert!(close(m, DMat2::IDENTITY * 4.0, 1e-12), "{m:?}");
        let c = DMat2::from_cols(DVec2::new(2.0, 1.5), DVec2::new(1.5, 2.0));
        let m = tensor_max(&[a, b, c, DMat2::ZERO]);
        for t in [a, b, c] {
            let (l, _) = sym_eigen(m - t);
            assert!(l[0] >= -1e-12, "{m:?} does not dominate {t:?}");
        }
        // A dominated term changes nothing.
        assert!(close(tensor_max(&[a, a * 0.5]), a, 1e-12));
    }

    #[test]
    fn clamp_bounds_sizes_and_aspect_and_refuses_nan() {
        let p = params();
        let m = clamp(DMat2::from_cols(DVec2::new(1e9, 0.0), DVec2::new(0.0, 0.0)), &p);
        let (l, _) = sym_eigen(m);
        assert!((l[1] - 1e4).abs() < 1e-6, "largest at 1/size_min^2: {l:?}");
        assert!((l[0] - 0.04 * 1e4).abs() < 1e-6, "aspect floor: {l:?}");
        let m = clamp(DMat2::ZERO, &p);
        assert!(close(m, DMat2::IDENTITY, 1e-12), "flat and unstrained: size_max");
        let m = clamp(DMat2::from_cols(DVec2::new(f64::NAN, 0.0), DVec2::ZERO), &p);
        assert!(m.is_finite() && close(m, DMat2::IDENTITY * 1e4, 1e-9));
    }

    #[test]
    fn compression_without_curvature_is_the_compressed_strain_over_c_squared() {
        let e = DMat2::from_cols(DVec2::new(-0.19, 0.0), DVec2::new(0.0, 0.05));
        let m = compression(e, DMat2::ZERO, 0.01);
        assert!(close(m, DMat2::from_cols(DVec2::new(0.19e4, 0.0), DVec2::ZERO), 1e-8), "{m:?}");
    }

    #[test]
    fn a_bent_sheet_asks_for_edges_of_refine_angle_over_curvature() {
        // A strip rolled onto a cylinder of radius r: the normal turns by |u| / r along u = x.
        let r = 2.0;
        let (nx, ny, h) = (40, 4, 0.05);
        let mut uv = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                uv.push(DVec2::new(i as f64 * h, j as f64 * h));
            }
        }
        let x: Vec<DVec3> =
            uv.iter().map(|u| DVec3::new(r * (u.x / r).sin(), u.y, r * (1.0 - (u.x / r).cos()))).collect();
        let mut faces = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let v = (j * (nx + 1) + i) as u32;
                let w = v + nx as u32 + 1;
                faces.push([v, v + 1, w + 1]);
                faces.push([v, w + 1, w]);
            }
        }
        let p = params();
        let m = vertex_sizing(&uv, &x, None, &faces, &[], &p);
        let mid = m[(2 * (nx + 1) + nx / 2) as usize];
        // Along the curvature 1 / (r refine_angle)^2; across it only the aspect floor.
        let along = DVec2::X.dot(mid * DVec2::X);
        let expect = 1.0 / (r * p.refine_angle).powi(2);
        assert!((along / expect - 1.0).abs() < 0.05, "{along} against {expect}");
        let across = DVec2::Y.dot(mid * DVec2::Y);
        assert!(across <= 1.01 * (p.aspect_min * p.aspect_min * along).max(1.0), "{across}");
    }
}
