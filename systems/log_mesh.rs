//! Rerun logging of one layer's mesh (for Log): coloured by strain, curvature, height or layer,
//! and in material space for remeshed layers.

use glam::{DVec2, DVec3};
use skinsim::mesh;
use skinsim::mesh::shading::{self, ColourBy};

use crate::render_mesh::RenderMesh;

/// The colour of a kinematic body: a neutral grey, so that no body reads as strained skin.
const BODY_GREY: [u8; 4] = [178, 178, 178, 255];
/// A body is drawn this fraction of its size inside its surface (along its normals), so that a
/// skin lying on it (offset 0: a KCK18 sleeve, the creature) shows instead of z-fighting with it.
const BODY_INSET: f64 = 2e-3;

/// How one layer is drawn.
pub(crate) struct Drawing {
    pub by: ColourBy,
    pub layer_index: usize,
    /// A kinematic body: neutral grey, drawn slightly inside its surface.
    pub body: bool,
    /// The rest state (frame 0): a curvature or height scale is not taken from it.
    pub rest: bool,
    /// The curvature (1/m) or height (m) that saturates the colours, for every frame; None: the
    /// first solved frame's 98th percentile, then fixed for the run.
    pub scale: Option<f64>,
}

/// Logs a layer's mesh coloured as `d.by` asks; returns its vertex colours and its line of the
/// legend (its scale or colour; none for strain, whose scale is fixed).
/// The triangles are static unless the layer is remeshed: then they are logged at every
/// topology change, on the timeline (static data would shadow every earlier frame's triangles).
pub(crate) fn log_mesh(
    rec: &rerun::RecordingStream,
    path: &str,
    rm: &mut RenderMesh,
    pos: &[DVec3],
    remeshed: bool,
    d: &Drawing,
) -> (Vec<rerun::Color>, Option<String>) {
    let (normals, strain) = shading::normals_and_strain(pos, &rm.tris, &rm.rest_area);
    let f3 = |v: &DVec3| [v.x as f32, v.y as f32, v.z as f32];
    if !rm.logged_topology {
        let indices = rm.tris.iter().map(|t| rerun::datatypes::UVec3D::from(*t));
        let topology = rerun::Mesh3D::update_fields().with_triangle_indices(indices);
        let _ = if remeshed { rec.log(path, &topology) } else { rec.log_static(path, &topology) };
        rm.logged_topology = true;
    }
    let (colours, legend, drawn, scale) = if d.body {
        let (lo, hi) = pos.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let inset = BODY_INSET * (hi - lo).length();
        let drawn: Vec<DVec3> = pos.iter().zip(&normals).map(|(p, n)| *p - inset * *n).collect();
        let line = format!("body, neutral grey (drawn {} mm inside its surface)", significant(1e3 * inset));
        (vec![rgba(BODY_GREY); pos.len()], Some(line), drawn, None)
    } else {
        let (c, l, scale) = colours(rm, pos, &normals, &strain, d);
        (c, l, pos.to_vec(), scale)
    };
    // The scale the colours saturate at, once, in the recording's properties.
    if let Some(s) = scale.filter(|s| *s > 0.0 && !rm.scale_sent) {
        let _ = rec.send_property(format!("colour_scale/{path}"), &rerun::Scalars::new([s]));
        rm.scale_sent = true;
    }
    let mesh = rerun::Mesh3D::update_fields()
        .with_vertex_positions(drawn.iter().map(f3))
        .with_vertex_normals(normals.iter().map(f3))
        .with_vertex_colors(colours.clone());
    let _ = rec.log(path, &mesh);
    (colours, legend)
}

fn rgba([r, g, b, a]: [u8; 4]) -> rerun::Color {
    rerun::Color::from_unmultiplied_rgba(r, g, b, a)
}

/// The scale of `values`' colours: the one set for the run, else the first solved frame's 98th
/// percentile of |value|, kept for the rest of the run (the same colour means the same value on
/// every frame, when scrubbing back too).
fn fixed_scale(rm: &mut RenderMesh, values: &[f64], d: &Drawing) -> f64 {
    if let Some(s) = d.scale {
        return s;
    }
    if rm.colour_scale == 0.0 && !d.rest {
        rm.colour_scale = shading::running_scale(0.0, values);
    }
    rm.colour_scale
}

fn colours(
    rm: &mut RenderMesh,
    pos: &[DVec3],
    normals: &[DVec3],
    strain: &[f64],
    d: &Drawing,
) -> (Vec<rerun::Color>, Option<String>, Option<f64>) {
    let diverging =
        |values: &[f64], scale: f64| values.iter().map(|v| rgba(shading::diverging_colour(*v, scale))).collect();
    match d.by {
        ColourBy::Strain => (diverging(strain, shading::STRAIN_SATURATION), None, Some(shading::STRAIN_SATURATION)),
        ColourBy::Curvature => {
            let h = shading::mean_curvature(pos, &rm.tris, normals);
            let scale = fixed_scale(rm, &h, d);
            let line = if scale > 0.0 {
                format!("{} 1/m (radius {} mm)", significant(scale), significant(1e3 / scale))
            } else {
                "flat".to_string()
            };
            (diverging(&h, scale), Some(line), Some(scale))
        }
        ColourBy::Height => {
            let h = shading::plane_height(pos, normals);
            let scale = fixed_scale(rm, &h, d);
            let line = if scale > 0.0 { format!("{} mm", significant(1e3 * scale)) } else { "flat".into() };
            (diverging(&h, scale), Some(line), Some(scale))
        }
        ColourBy::Layer => {
            let c = shading::layer_colour(d.layer_index);
            (vec![rgba(c); pos.len()], Some(format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])), None)
        }
    }
}

/// Each patch's energy, Newton iterations and residual (also as its log10: it spans decades)
/// under stats/<patch>, and the stage timings: frame 1's, which hold the set-up (analyses, first
/// factorizations) and would flatten the plot of the others, under setup_timings.
pub(crate) fn log_stats(
    rec: &rerun::RecordingStream,
    report: &skinsim::model::FrameReport,
    timings: &skinsim::model::Timings,
    frame: u32,
) {
    for p in &report.patches {
        let base = format!("stats/{}", p.name);
        let o = &p.outcome;
        let _ = rec.log(format!("{base}/energy"), &rerun::Scalars::new([o.energy]));
        let _ = rec.log(format!("{base}/newton_iterations"), &rerun::Scalars::new([o.iterations as f64]));
        let _ = rec.log(format!("{base}/residual"), &rerun::Scalars::new([o.residual]));
        let _ = rec.log(format!("{base}/log10_residual"), &rerun::Scalars::new([o.residual.max(1e-300).log10()]));
    }
    let root = if frame <= 1 { "setup_timings" } else { "timings" };
    for stage in skinsim::model::Stage::ALL.into_iter().filter(|s| *s != skinsim::model::Stage::Log) {
        let _ = rec.log(format!("{root}/{}", stage.key()), &rerun::Scalars::new([timings.get(stage)]));
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
