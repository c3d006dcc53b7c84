//! Rest data of a shell's faces and hinges and the lumped masses of a layer: one path for the
//! elements a scene spawns and for those a remesh creates (PropertyResample).

use glam::{DMat2, DVec2, DVec3};

use super::{factors_at, Bending, LayerPrestrain, LayerProperties};
use crate::physics::hinge::HingeRest;
use crate::physics::membrane::MembraneRest;
use crate::physics::prestrain::hinge_with_curvature;

/// What a shell layer's rest data depends on.
#[derive(Clone, Copy, Debug)]
pub struct ShellRest<'a> {
    /// The layer's thickness (m), before the property map's factor.
    pub thickness: f64,
    pub prestrain: Option<&'a LayerPrestrain>,
    pub properties: Option<&'a LayerProperties>,
}

/// A face's rest data.
#[derive(Clone, Copy, Debug)]
pub struct FaceRestData {
    pub rest: MembraneRest,
    /// The layer's prestrain F0 in the face's rest frame (H15 4.3), folded into `rest`.
    pub prestrain: Option<DMat2>,
    /// The property map's Young's modulus factor at the face.
    pub young: f64,
}

impl ShellRest<'_> {
    /// The rest data of the triangle `tri` (rest positions) whose vertices sit at `uv` in
    /// material space; None for a degenerate triangle. LK14 5.2: the property map is sampled at
    /// the centroid.
    pub fn face(&self, tri: [DVec3; 3], uv: [DVec2; 3]) -> Option<FaceRestData> {
        let centre = uv.iter().sum::<DVec2>() / 3.0;
        let f0 = self.prestrain.map(|p| p.face_f0(tri, centre));
        let local = factors_at(self.properties, centre);
        let rest =
            MembraneRest::from_rest_triangle(tri, self.thickness * local.thickness, f0.unwrap_or(DMat2::IDENTITY))?;
        Some(FaceRestData { rest, prestrain: f0, young: local.young })
    }

    /// The rest data of a hinge with rest positions `x` (edge, then opposite vertices) whose edge
    /// ends sit at `edge_uv`: the layer's stiffness times `modulus` (its faces' randomized modulus)
    /// and the map's bending factor at the edge midpoint (LK14 5.2: D ~ E h^3), and the
    /// prestrain's rest curvature.
    pub fn hinge(&self, bending: &Bending, modulus: f64, x: [DVec3; 4], edge_uv: [DVec2; 2]) -> HingeRest {
        let mid = 0.5 * (edge_uv[0] + edge_uv[1]);
        let k_b = bending.stiffness * modulus * factors_at(self.properties, mid).bending();
        let (kappa, along) = self.prestrain.map_or((0.0, 0), |p| (p.curvature, p.along));
        hinge_with_curvature(bending.model, k_b, x, kappa, along)
    }

    /// Lumped masses of a shell's vertices: density x thickness x area / 3 per face corner, the
    /// thickness scaled by the map at the face's centroid.
    pub fn masses(&self, density: f64, rest: &[DVec3], uv: &[DVec2], faces: &[[u32; 3]]) -> Vec<f64> {
        let mut mass = vec![0.0; rest.len()];
        for f in faces {
            let p = |i: usize| rest[f[i] as usize];
            let a = 0.5 * (p(1) - p(0)).cross(p(2) - p(0)).length();
            let centre = f.iter().map(|&i| uv[i as usize]).sum::<DVec2>() / 3.0;
            let t = factors_at(self.properties, centre).thickness;
            for &v in f {
                mass[v as usize] += density * self.thickness * t * a / 3.0;
            }
        }
        mass
    }
}

/// Lumped masses of a solid's vertices: density x volume / 4 per tetrahedron corner.
pub(crate) fn volume_masses(density: f64, rest: &[DVec3], tets: &[[u32; 4]]) -> Vec<f64> {
    let mut mass = vec![0.0; rest.len()];
    for t in tets {
        let p = |i: usize| rest[t[i] as usize];
        let vol = (p(1) - p(0)).cross(p(2) - p(0)).dot(p(3) - p(0)) / 6.0;
        for &v in t {
            mass[v as usize] += density * vol / 4.0;
        }
    }
    mass
}
