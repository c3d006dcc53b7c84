//! Rerun logging of one layer's mesh (for Log): coloured by strain, curvature, height or layer,
//! and in material space for remeshed layers.

use glam::{DVec2, DVec3};
use skinsim::mesh;
use skinsim::mesh::shading::{self, ColourBy};

use crate::render_mesh::RenderMesh;

/// Logs a layer's mesh coloured as `by` asks; returns its vertex colours and its line of the
/// legend (its scale or colour; none for strain, whose scale is fixed).
/// The triangles are static unless the layer is remeshed: then they are logged at every
/// topology change, on the timeline (static data would shadow every earlier frame's triangles).
pub(crate) fn log_mesh(
    rec: &rerun::RecordingStream,
    path: &str,
    rm: &mut RenderMesh,
    pos: &[DVec3],
    remeshed: bool,
    by: ColourBy,
    layer_index: usize,
) -> (Vec<rerun::Color>, Option<String>) {
    let (normals, strain) = shading::normals_and_strain(pos, &rm.tris, &rm.rest_area);
    let f3 = |v: &DVec3| [v.x as f32, v.y as f32, v.z as f32];
    if !rm.logged_topology {
        let indices = rm.tris.iter().map(|t| rerun::datatypes::UVec3D::from(*t));
        let topology = rerun::Mesh3D::update_fields().with_triangle_indices(indices);
        let _ = if remeshed { rec.log(path, &topology) } else { rec.log_static(path, &topology) };
        rm.logged_topology = true;
    }
    let (colours, legend) = colours(rm, pos, &normals, &strain, by, layer_index);
    let mesh = rerun::Mesh3D::update_fields()
        .with_vertex_positions(pos.iter().map(f3))
        .with_vertex_normals(normals.iter().map(f3))
        .with_vertex_colors(colours.clone());
    let _ = rec.log(path, &mesh);
    (colours, legend)
}

fn colours(
    rm: &mut RenderMesh,
    pos: &[DVec3],
    normals: &[DVec3],
    strain: &[f64],
    by: ColourBy,
    layer_index: usize,
) -> (Vec<rerun::Color>, Option<String>) {
    let rgba = |[r, g, b, a]: [u8; 4]| rerun::Color::from_unmultiplied_rgba(r, g, b, a);
    let diverging =
        |values: &[f64], scale: f64| values.iter().map(|v| rgba(shading::diverging_colour(*v, scale))).collect();
    match by {
        ColourBy::Strain => (diverging(strain, shading::STRAIN_SATURATION), None),
        ColourBy::Curvature => {
            let h = shading::mean_curvature(pos, &rm.tris, normals);
            rm.colour_scale = shading::running_scale(rm.colour_scale, &h);
            let line = if rm.colour_scale > 0.0 {
                format!("{} 1/m (radius {} mm)", significant(rm.colour_scale), significant(1e3 / rm.colour_scale))
            } else {
                "flat".to_string()
            };
            (diverging(&h, rm.colour_scale), Some(line))
        }
        ColourBy::Height => {
            let h = shading::plane_height(pos, normals);
            rm.colour_scale = shading::running_scale(rm.colour_scale, &h);
            let line = if rm.colour_scale > 0.0 {
                format!("{} mm", significant(1e3 * rm.colour_scale))
            } else {
                "flat".into()
            };
            (diverging(&h, rm.colour_scale), Some(line))
        }
        ColourBy::Layer => {
            let c = shading::layer_colour(layer_index);
            (vec![rgba(c); pos.len()], Some(format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])))
        }
    }
}

/// Three significant digits, no exponent for the usual sizes ("411", "2.43", "0.0123").
fn significant(x: f64) -> String {
    let digits = (2 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{x:.digits$}")
}

/// A remeshed layer in material space (LK14 fig. 6-4, left and centre): the triangles flat at
/// z = 0 coloured by strain, and their edges as lines, so the adaptive resolution shows.
pub(crate) fn log_material_mesh(
    rec: &rerun::RecordingStream,
    path: &str,
    rm: &RenderMesh,
    uv: &[DVec2],
    colours: &[rerun::Color],
) {
    let p = |u: &DVec2| [u.x as f32, u.y as f32, 0.0];
    let mesh = rerun::Mesh3D::new(uv.iter().map(p))
        .with_triangle_indices(rm.tris.iter().map(|t| rerun::datatypes::UVec3D::from(*t)))
        .with_vertex_colors(colours.iter().copied());
    let _ = rec.log(path.to_string(), &mesh);
    let edges: Vec<[[f32; 3]; 2]> =
        mesh::edges(&rm.tris).iter().map(|e| [p(&uv[e.v[0] as usize]), p(&uv[e.v[1] as usize])]).collect();
    let _ = rec.log(
        format!("{path}/edges"),
        &rerun::LineStrips3D::new(edges).with_colors([rerun::Color::from_rgb(40, 40, 40)]),
    );
}
