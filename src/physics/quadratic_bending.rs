//! Quadratic bending: the squared cotangent Laplacian of the positions, one element per
//! interior vertex (Wardetzky, Bergou, Harmon, Zorin, Grinspun 2007, "Discrete quadratic
//! curvature energies"; Bergou, Wardetzky, Harmon, Zorin, Grinspun 2006, "A quadratic bending
//! model for inextensible surfaces").
//!
//! For a vertex v with mixed Voronoi area M_v, (L x)_v = sum_j w_vj (x_j - x_v),
//! w_vj = (cot a_vj + cot b_vj) / 2 from the rest (material) triangles, approximates the mean
//! curvature normal times M_v, so W_v = D_v / (2 M_v) |(L x)_v|^2 approximates the mean
//! curvature part (D / 2) (2H)^2 M_v of Kirchhoff's plate energy. The energy is quadratic in
//! x: a constant, positive semidefinite Hessian, no projection. Its Gaussian-curvature part,
//! -(1 - nu) D K, is the triangle element of `gaussian_bending`; `plate` builds both. Without it
//! a field harmonic in material space (a saddle, an edge wave) would bend for free.
//!
//! Why it exists next to the hinge: the hinge's energy depends on the mesh (PHYSICS.md 1.2),
//! and on the anisotropic meshes the remesher makes it holds 11-13 % less bending energy than
//! a fine uniform mesh. Bent into a cylinder, this element is within 1 % of D / (2 R^2) on
//! equilateral, right-triangle and jittered meshes and on a 4:1 stretched lattice, where the
//! hinge is off by -46 % (VALIDATION.md case 5 in tests/validation_shells.rs); non-Delaunay
//! meshes cost it accuracy (+4.3 % on a jittered 4:1 one, unit tests below). With its Gaussian
//! term it is within 2 % of D (1 + nu) / R^2 on a dome and D (1 - nu) / R^2 on a saddle.
//!
//! Limits: a flat rest state (no rest curvature), small in-plane strain where it bends; boundary
//! vertices carry no element (their one-sided Laplacian does not vanish on flat states). In the
//! compressed LK14 sweeps (`skinsim report --only lk14 --bending quadratic`) Newton reached its
//! iteration limit in one frame of most adaptive runs, with or without the Gaussian term, where
//! the hinge reached it in none, at 1.5-6x the hinge's time per frame (a two-ring stencil fills
//! the factor more). Hence opt-in.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::gaussian_bending::{self, GaussianElem};

/// Which bending element a shell layer uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum BendingElement {
    /// Discrete-shell hinge per interior edge (PHYSICS.md 1.2): any rest curvature, mesh-dependent.
    #[default]
    Hinge,
    /// Squared cotangent Laplacian per interior vertex: flat rest only, nearly mesh-independent.
    Quadratic,
}

/// All quadratic bending elements of a body: stencils packed one after another.
#[derive(Clone, Debug, Default)]
pub struct QuadraticBending {
    /// Element i's stencil is `v[start[i]..start[i + 1]]` (its vertex first, then its
    /// neighbours in increasing order) with weights `w` (summing to zero).
    pub start: Vec<u32>,
    pub v: Vec<u32>,
    pub w: Vec<f64>,
    /// D_v / M_v (N / m).
    pub k: Vec<f64>,
    /// M_v, the mixed Voronoi area (m^2).
    pub area: Vec<f64>,
}

impl QuadraticBending {
    /// Elements for the interior vertices of a triangle mesh. `faces` index `rest` (the rest,
    /// flat, material positions); `edge_rigidity` gives D (N m) on edges, a vertex taking the
    /// mean over its edges listed; `boundary` flags the vertices on the mesh's boundary
    /// (`mesh::boundary_vertices`), which carry no element.
    pub fn build(
        faces: &[[u32; 3]],
        rest: impl Fn(u32) -> DVec3,
        edge_rigidity: &[([u32; 2], f64)],
        boundary: &[bool],
    ) -> Self {
        let n = faces.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
        let mut weights: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        let mut area = vec![0.0; n];
        for f in faces {
            let p = f.map(&rest);
            let twice_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
            if twice_area.is_nan() || twice_area <= 0.0 {
                continue; // a degenerate rest triangle bends nothing
            }
            // cot[k]: the angle at corner k, opposite the edge (k + 1, k + 2).
            let cot: [f64; 3] = std::array::from_fn(|k| {
                let (a, b) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                a.dot(b) / twice_area
            });
            for k in 0..3 {
                let (i, j) = (f[(k + 1) % 3], f[(k + 2) % 3]);
                weights[i as usize].push((j, 0.5 * cot[k]));
                weights[j as usize].push((i, 0.5 * cot[k]));
            }
            for (k, a) in mixed_areas(&p, &cot, 0.5 * twice_area).into_iter().enumerate() {
                area[f[k] as usize] += a;
            }
        }
        let (mut d_sum, mut d_count) = (vec![0.0; n], vec![0u32; n]);
        for &([a, b], d) in edge_rigidity {
            for v in [a, b].into_iter().filter(|&v| (v as usize) < n) {
                d_sum[v as usize] += d;
                d_count[v as usize] += 1;
            }
        }
        let mut out = QuadraticBending { start: vec![0], ..Default::default() };
        for v in 0..n {
            if boundary.get(v).copied().unwrap_or(false)
                || weights[v].is_empty()
                || d_count[v] == 0
                || area[v].is_nan()
                || area[v] <= 0.0
            {
                continue;
            }
            let mut ws = std::mem::take(&mut weights[v]);
            ws.sort_by_key(|&(j, _)| j);
            let mut merged: Vec<(u32, f64)> = Vec::with_capacity(ws.len());
            for (j, w) in ws {
                match merged.last_mut() {
                    Some(last) if last.0 == j => last.1 += w,
                    _ => merged.push((j, w)),
                }
            }
            out.v.push(v as u32);
            out.w.push(-merged.iter().map(|(_, w)| w).sum::<f64>());
            for (j, w) in merged {
                out.v.push(j);
                out.w.push(w);
            }
            out.start.push(out.v.len() as u32);
            out.k.push(d_sum[v] / d_count[v] as f64 / area[v]);
            out.area.push(area[v]);
        }
        out
    }

    /// Elements from a layer's hinges, (x0, x1 the edge, x2, x3 the opposite vertices; rest
    /// weight k_b 3 |e|^2 / A): each edge's D read back from its hinge (`rigidity_of_hinge`).
    pub(crate) fn from_hinges(
        faces: &[[u32; 3]],
        rest: impl Fn(u32) -> DVec3,
        hinges: &[([u32; 4], f64)],
        boundary: &[bool],
    ) -> Self {
        let rigidity: Vec<([u32; 2], f64)> =
            hinges.iter().map(|(v, weight)| ([v[0], v[1]], rigidity_of_hinge(*weight, v.map(&rest)))).collect();
        Self::build(faces, rest, &rigidity, boundary)
    }

    /// A layer's Kirchhoff plate: its elements from the hinges (`from_hinges`) and their
    /// Gaussian-curvature term for Poisson's ratio `poisson` (`gaussian_bending`).
    pub fn plate(
        faces: &[[u32; 3]],
        rest: impl Fn(u32) -> DVec3,
        hinges: &[([u32; 4], f64)],
        boundary: &[bool],
        poisson: f64,
    ) -> (Self, Vec<GaussianElem>) {
        let q = Self::from_hinges(faces, &rest, hinges, boundary);
        let g = gaussian_bending::elements(&q, faces, &rest, poisson);
        (q, g)
    }

    pub fn len(&self) -> usize {
        self.k.len()
    }

    pub fn is_empty(&self) -> bool {
        self.k.is_empty()
    }

    /// Appends another body part's elements (vertex indices already packed).
    pub fn extend(&mut self, other: QuadraticBending) {
        let base = *self.start.last().unwrap_or(&0);
        if self.start.is_empty() {
            self.start.push(0);
        }
        self.start.extend(other.start.iter().skip(1).map(|s| s + base));
        self.v.extend(other.v);
        self.w.extend(other.w);
        self.k.extend(other.k);
        self.area.extend(other.area);
    }

    /// Element i's vertices and weights.
    #[inline]
    pub fn stencil(&self, i: usize) -> (&[u32], &[f64]) {
        let (s, e) = (self.start[i] as usize, self.start[i + 1] as usize);
        (&self.v[s..e], &self.w[s..e])
    }

    /// (L x)_v of element i.
    #[inline]
    pub(crate) fn laplacian(&self, i: usize, x: &[DVec3]) -> DVec3 {
        let (vs, ws) = self.stencil(i);
        vs.iter().zip(ws).map(|(&v, &w)| w * x[v as usize]).sum()
    }

    /// W_i = k_i / 2 |(L x)_i|^2 (J).
    #[inline]
    pub fn element_energy(&self, i: usize, x: &[DVec3]) -> f64 {
        0.5 * self.k[i] * self.laplacian(i, x).length_squared()
    }

    /// Total energy, summed in element order.
    pub fn energy(&self, x: &[DVec3]) -> f64 {
        (0..self.len()).map(|i| self.element_energy(i, x)).sum()
    }

    /// Sum of D_v (J): the energy scale at unit curvature times area.
    pub(crate) fn rigidity_sum(&self) -> f64 {
        self.k.iter().zip(&self.area).map(|(k, a)| k * a).sum()
    }
}

/// The mixed Voronoi areas of a triangle's corners (Meyer, Desbrun, Schroeder, Barr 2003):
/// the Voronoi parts when no angle is obtuse, else half the area to the obtuse corner and a
/// quarter to the others.
fn mixed_areas(p: &[DVec3; 3], cot: &[f64; 3], area: f64) -> [f64; 3] {
    if let Some(obtuse) = (0..3).find(|&k| cot[k] < 0.0) {
        return std::array::from_fn(|k| if k == obtuse { 0.5 * area } else { 0.25 * area });
    }
    std::array::from_fn(|k| {
        // Corner k's Voronoi part: edges (k, k+1) and (k, k+2), each times the cotangent of
        // the angle opposite it, over 8.
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        ((p[a] - p[k]).length_squared() * cot[b] + (p[b] - p[k]).length_squared() * cot[a]) / 8.0
    })
}

/// The rigidity D (N m) a hinge of weight k_b 3 |e|^2 / A with rest positions `x` stands for:
/// k_b = D / 6 x scale (PHYSICS.md 1.2), so the hinge's property maps and scale carry over.
pub(crate) fn rigidity_of_hinge(weight: f64, x: [DVec3; 4]) -> f64 {
    let e2 = (x[1] - x[0]).length_squared();
    let a = 0.5 * ((x[1] - x[0]).cross(x[2] - x[0]).length() + (x[1] - x[0]).cross(x[3] - x[0]).length());
    6.0 * weight * a / (3.0 * e2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered or stretched triangulated grid over [0, n) x [0, n): (rest positions, faces,
    /// boundary vertices).
    fn grid(n: u32, jitter: f64, stretch: f64) -> (Vec<DVec3>, Vec<[u32; 3]>, Vec<bool>) {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let s = ((i * 31 + j * 17) as f64 * 12.9898).sin() * 43758.5453;
                let t = ((i * 13 + j * 7) as f64 * 78.233).sin() * 12345.678;
                let inner = i > 0 && i < n && j > 0 && j < n;
                let d = if inner { jitter } else { 0.0 };
                p.push(DVec3::new(
                    stretch * (i as f64 + d * (2.0 * s.fract().abs() - 1.0)),
                    j as f64 + d * (2.0 * t.fract().abs() - 1.0),
                    0.0,
                ));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut f = Vec::new();
        for j in 0..n {
            for i in 0..n {
                // alternate diagonals: no preferred direction
                if (i + j) % 2 == 0 {
                    f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                } else {
                    f.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                    f.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        let boundary = (0..=n).flat_map(|j| (0..=n).map(move |i| i == 0 || j == 0 || i == n || j == n)).collect();
        (p, f, boundary)
    }

    /// D = 1 on every edge (each interior edge listed twice: the mean is the same).
    fn unit_rigidity(faces: &[[u32; 3]]) -> Vec<([u32; 2], f64)> {
        faces.iter().flat_map(|f| [[f[0], f[1]], [f[1], f[2]], [f[2], f[0]]]).map(|e| (e, 1.0)).collect()
    }

    /// Energy per area of the mesh wrapped on a cylinder of radius r about an axis at `angle`
    /// to y, over elements away from the boundary, against D / (2 r^2).
    fn cylinder_error(p: &[DVec3], f: &[[u32; 3]], boundary: &[bool], r: f64, angle: f64) -> f64 {
        let q = QuadraticBending::build(f, |i| p[i as usize], &unit_rigidity(f), boundary);
        let (c, s) = (angle.cos(), angle.sin());
        let x: Vec<DVec3> = p
            .iter()
            .map(|v| {
                let u = v.x * c - v.y * s;
                let along = v.x * s + v.y * c;
                DVec3::new(r * (u / r).sin(), along, r * (1.0 - (u / r).cos()))
            })
            .collect();
        let (lo, hi) = p.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        let margin = 0.15 * (hi - lo);
        let (mut e, mut a) = (0.0, 0.0);
        for i in 0..q.len() {
            let v = p[q.stencil(i).0[0] as usize];
            if (v - lo).truncate().cmpgt(margin.truncate()).all() && (hi - v).truncate().cmpgt(margin.truncate()).all()
            {
                e += q.element_energy(i, &x);
                a += q.area[i];
            }
        }
        e / a / (0.5 / (r * r)) - 1.0
    }

    /// Meshes with fixed (alternating-diagonal) connectivity: jitter makes them non-Delaunay,
    /// which the cotangent weights feel. Measured: regular -0.04 %; jittered by 0.15 of the
    /// spacing +0.71 .. +1.01 %; 1:4 anisotropic jittered by 0.1 +4.3 % (its stretched lattice
    /// alone: -0.003 %, tests/validation_shells.rs).
    #[test]
    fn cylinder_energy_is_kirchhoff_on_many_meshes() {
        for (name, jitter, stretch, tol) in [
            ("regular", 0.0, 1.0, 0.005),
            ("jittered", 0.15, 1.0, 0.015),
            ("anisotropic 1:4, short edges across the axis", 0.1, 0.25, 0.05),
        ] {
            let (p, f, boundary) = grid(40, jitter, stretch);
            let angles: &[f64] = if stretch < 1.0 { &[0.0] } else { &[0.0, 0.4, std::f64::consts::FRAC_PI_2] };
            for &angle in angles {
                let err = cylinder_error(&p, &f, &boundary, 20.0 * stretch, angle);
                assert!(err.abs() < tol, "{name}, angle {angle}: {err:+.4}");
            }
        }
    }

    /// With its Gaussian term (`gaussian_bending`), the element is Kirchhoff's plate:
    /// D / 2 [(2H)^2 - 2 (1 - nu) K] per area, so D (1 + nu) / R^2 on a dome of curvature 1 / R
    /// both ways, D (1 - nu) / R^2 on a saddle (1 / R, -1 / R), where the quadratic part alone
    /// holds nothing. Shallow shapes (slopes below 0.02) over the flat mesh, away from the
    /// boundary.
    #[test]
    fn with_its_gaussian_term_it_is_kirchhoffs_plate() {
        let (nu, r) = (0.3, 1000.0);
        for (name, jitter) in [("regular", 0.0), ("jittered", 0.15)] {
            let (p, f, boundary) = grid(40, jitter, 1.0);
            let q = QuadraticBending::build(&f, |i| p[i as usize], &unit_rigidity(&f), &boundary);
            let g = gaussian_bending::elements(&q, &f, |i| p[i as usize], nu);
            let inside = |v: DVec3| v.x > 6.0 && v.x < 34.0 && v.y > 6.0 && v.y < 34.0;
            for (shape, sign, expected) in [("dome", 1.0, (1.0 + nu) / (r * r)), ("saddle", -1.0, (1.0 - nu) / (r * r))]
            {
                let x: Vec<DVec3> = p
                    .iter()
                    .map(|v| DVec3::new(v.x, v.y, ((v.x - 20.0).powi(2) + sign * (v.y - 20.0).powi(2)) / (2.0 * r)))
                    .collect();
                let (mut e, mut a) = (0.0, 0.0);
                for i in (0..q.len()).filter(|&i| inside(p[q.stencil(i).0[0] as usize])) {
                    e += q.element_energy(i, &x);
                    a += q.area[i];
                }
                for t in &g {
                    let corners = gaussian_bending::corner_energies(t, &t.v.map(|v| x[v as usize]));
                    e += (0..3).filter(|&k| inside(p[t.v[k] as usize])).map(|k| corners[k]).sum::<f64>();
                }
                let err = e / a / expected - 1.0;
                eprintln!("plate: {name} mesh, {shape}: {:+.3} %", 100.0 * err);
                assert!(err.abs() < 0.02, "{name}, {shape}: {err:+.4}");
            }
        }
    }

    #[test]
    fn flat_and_rigid_motions_cost_nothing() {
        let (p, f, boundary) = grid(8, 0.3, 1.0);
        let q = QuadraticBending::build(&f, |i| p[i as usize], &unit_rigidity(&f), &boundary);
        assert!(!q.is_empty());
        let rot = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        // An in-plane affine stretch, then a rotation and a translation: still flat.
        let x: Vec<DVec3> =
            p.iter().map(|v| rot * DVec3::new(1.3 * v.x + 0.2 * v.y, 0.8 * v.y, 0.0) + DVec3::splat(5.0)).collect();
        assert!(q.energy(&x) < 1e-20, "{}", q.energy(&x));
        for i in 0..q.len() {
            assert!(q.stencil(i).1.iter().sum::<f64>().abs() < 1e-12);
        }
    }

    #[test]
    fn hinge_rigidity_round_trips() {
        let x = [DVec3::ZERO, DVec3::X, DVec3::new(0.3, 0.8, 0.0), DVec3::new(0.6, -0.5, 0.0)];
        let rest = super::super::HingeRest::from_rest(super::super::HingeModel::Tan, 2.5e-6 / 6.0, x);
        assert!((rigidity_of_hinge(rest.weight, x) / 2.5e-6 - 1.0).abs() < 1e-12);
    }
}
