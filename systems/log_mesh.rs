//! Rerun logging of one layer's mesh (for Log): coloured by strain, and in material space for
//! remeshed layers.

use glam::{DVec2, DVec3};
use skinsim::mesh::{self, shading};

use crate::log::RenderMesh;

/// Logs a layer's mesh coloured by strain; returns the per-vertex strain. The triangles are
/// static unless the layer is remeshed: then they are logged at every topology change, on the
/// timeline (static data would shadow every earlier frame's triangles).
pub(crate) fn log_mesh(
    rec: &rerun::RecordingStream,
    path: &str,
    rm: &mut RenderMesh,
    pos: &[DVec3],
    remeshed: bool,
) -> Vec<f64> {
    let (normals, strain) = shading::normals_and_strain(pos, &rm.tris, &rm.rest_area);
    let f3 = |v: &DVec3| [v.x as f32, v.y as f32, v.z as f32];
    if !rm.logged_topology {
        let indices = rm.tris.iter().map(|t| rerun::datatypes::UVec3D::from(*t));
        let topology = rerun::Mesh3D::update_fields().with_triangle_indices(indices);
        let _ = if remeshed { rec.log(path, &topology) } else { rec.log_static(path, &topology) };
        rm.logged_topology = true;
    }
    let mesh = rerun::Mesh3D::update_fields()
        .with_vertex_positions(pos.iter().map(f3))
        .with_vertex_normals(normals.iter().map(f3))
        .with_vertex_colors(colours(&strain));
    let _ = rec.log(path, &mesh);
    strain
}

fn colours(strain: &[f64]) -> Vec<rerun::Color> {
    strain
        .iter()
        .map(|s| {
            let [r, g, b, a] = shading::strain_colour(*s);
            rerun::Color::from_unmultiplied_rgba(r, g, b, a)
        })
        .collect()
}

/// A remeshed layer in material space (LK14 fig. 6-4, left and centre): the triangles flat at
/// z = 0 coloured by strain, and their edges as lines, so the adaptive resolution shows.
pub(crate) fn log_material_mesh(
    rec: &rerun::RecordingStream,
    path: &str,
    rm: &RenderMesh,
    uv: &[DVec2],
    strain: &[f64],
) {
    let p = |u: &DVec2| [u.x as f32, u.y as f32, 0.0];
    let mesh = rerun::Mesh3D::new(uv.iter().map(p))
        .with_triangle_indices(rm.tris.iter().map(|t| rerun::datatypes::UVec3D::from(*t)))
        .with_vertex_colors(colours(strain));
    let _ = rec.log(path.to_string(), &mesh);
    let edges: Vec<[[f32; 3]; 2]> =
        mesh::edges(&rm.tris).iter().map(|e| [p(&uv[e.v[0] as usize]), p(&uv[e.v[1] as usize])]).collect();
    let _ = rec.log(
        format!("{path}/edges"),
        &rerun::LineStrips3D::new(edges).with_colors([rerun::Color::from_rgb(40, 40, 40)]),
    );
}
