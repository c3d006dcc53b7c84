//! The triangles a layer is drawn with (its faces, or the boundary of its tetrahedra), kept
//! from frame to frame until the layer's topology changes.

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::mesh;
use skinsim::mesh::shading;
use skinsim::model::*;

/// Triangles of a layer as drawn: its faces, or the boundary of its tetrahedra.
#[derive(Default)]
pub struct RenderMesh {
    pub(crate) epoch: u64,
    pub(crate) vertices: Vec<Entity>,
    pub(crate) tris: Vec<[u32; 3]>,
    pub(crate) rest_area: Vec<f64>,
    pub(crate) logged_topology: bool,
    /// The curvature or height colours' scale, fixed at the first solved frame (0 until then),
    /// so that a colour means the same value on every frame.
    pub(crate) colour_scale: f64,
    /// The scale is in the recording's properties (`colour_scale/<entity>`).
    pub(crate) scale_sent: bool,
}

pub(crate) fn render_mesh(
    epoch: u64,
    lf: Option<&LayerFaces>,
    lt: Option<&LayerTets>,
    faces: &Query<(&FaceVerts, Option<&FacePrestrain>)>,
    tets: &Query<(&TetVerts, Option<&TetPrestrain>)>,
    vertices: &Query<(&Position, &RestPos, &MaterialPos)>,
) -> RenderMesh {
    // Each drawn triangle's prestrain F0 (a shell face's, or the tet's a boundary face bounds):
    // its colour is the elastic strain, measured from the stress-free shape.
    let mut prestrain = Vec::new();
    let tris_e: Vec<[Entity; 3]> = if let Some(lf) = lf.filter(|f| !f.entities().is_empty()) {
        let mut tris = Vec::new();
        for (fv, f0) in lf.entities().iter().filter_map(|f| faces.get(*f).ok()) {
            tris.push(fv.0);
            prestrain.push(f0.map(|p| shading::Prestrain::Face(p.0)));
        }
        tris
    } else if let Some(lt) = lt {
        let (tet_e, tet_f0): (Vec<[Entity; 4]>, Vec<_>) =
            lt.entities().iter().filter_map(|t| tets.get(*t).ok().map(|(tv, f0)| (tv.0, f0.map(|p| p.0)))).unzip();
        let (ents, as_idx) = mesh::compact(&tet_e);
        let surface = mesh::surface_faces_of_tets(&as_idx);
        prestrain = surface.iter().map(|(_, t)| tet_f0[*t].map(shading::Prestrain::Tet)).collect();
        surface.into_iter().map(|(f, _)| f.map(|i| ents[i as usize])).collect()
    } else {
        Vec::new()
    };
    let (vertices_e, tris) = mesh::compact(&tris_e);
    let mut rm = RenderMesh { epoch, vertices: vertices_e, tris, ..Default::default() };
    let rest: Vec<DVec3> = rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.1 .0).unwrap_or_default()).collect();
    rm.rest_area = shading::stress_free_areas(&rest, &rm.tris, &prestrain);
    rm
}
