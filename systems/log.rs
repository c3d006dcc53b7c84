//! Log: sends the frame to Rerun (every layer as a Mesh3D coloured by strain, scalars for
//! energy, Newton iterations and stage timings) and writes requested OBJ files.

use std::collections::HashMap;
use std::path::PathBuf;

use bevy_ecs::prelude::*;
use glam::{DVec2, DVec3};
use skinsim::mesh::{self, shading};
use skinsim::model::*;

/// Where Rerun data goes (a file, a spawned viewer, a connection, or memory in tests).
#[derive(Resource)]
pub struct RerunSink(pub rerun::RecordingStream);

/// Write obj/<patch>/<layer>/<frame>.obj under this directory.
#[derive(Resource, Clone, Debug)]
pub struct ObjExport(pub PathBuf);

pub fn wants_logging(sink: Option<Res<RerunSink>>, obj: Option<Res<ObjExport>>) -> bool {
    sink.is_some() || obj.is_some()
}

/// Triangles of a layer as drawn: its faces, or the boundary of its tetrahedra.
#[derive(Default)]
pub struct RenderMesh {
    epoch: u64,
    vertices: Vec<Entity>,
    tris: Vec<[u32; 3]>,
    rest_area: Vec<f64>,
    logged_topology: bool,
}

#[derive(Default)]
pub struct RenderCache(HashMap<Entity, RenderMesh>);

type LayerQ<'a> = (&'a Layer, &'a TopologyEpoch, Option<&'a LayerFaces>, Option<&'a LayerTets>, Has<RemeshSettings>);

#[allow(clippy::too_many_arguments)]
pub fn log_frame(
    clock: Res<SimClock>,
    timings: Res<Timings>,
    report: Res<FrameReport>,
    sink: Option<Res<RerunSink>>,
    obj: Option<Res<ObjExport>>,
    mut failure: ResMut<SimFailure>,
    mut cache: Local<RenderCache>,
    patches: Query<(&Patch, &PatchLayers)>,
    layers: Query<LayerQ>,
    faces: Query<&FaceVerts>,
    tets: Query<&TetVerts>,
    vertices: Query<(&Position, &RestPos, &MaterialPos)>,
) {
    let rec = sink.as_ref().map(|s| &s.0);
    if let Some(rec) = rec {
        rec.set_time_sequence("frame", clock.frame as i64);
        rec.set_duration_secs("sim_time", clock.time);
    }
    let mut ordered: Vec<_> = patches.iter().collect();
    ordered.sort_by_key(|(p, _)| p.index);
    for (patch, patch_layers) in ordered {
        for &l in patch_layers.entities() {
            let Ok((layer, epoch, lf, lt, remeshed)) = layers.get(l) else { continue };
            let rm = cache.0.entry(l).or_default();
            if rm.vertices.is_empty() || rm.epoch != epoch.0 {
                *rm = render_mesh(epoch.0, lf, lt, &faces, &tets, &vertices);
            }
            if rm.tris.is_empty() {
                continue;
            }
            let pos: Vec<DVec3> =
                rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.0 .0).unwrap_or(DVec3::NAN)).collect();
            if let Some(rec) = rec {
                let path = format!("patches/{}/{}", patch.name, layer.name);
                let strain = log_mesh(rec, &path, rm, &pos, remeshed);
                if remeshed {
                    let uv: Vec<DVec2> =
                        rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.2 .0).unwrap_or(DVec2::ZERO)).collect();
                    log_material_mesh(rec, &format!("material/{}/{}", patch.name, layer.name), rm, &uv, &strain);
                }
            }
            if let Some(ObjExport(dir)) = obj.as_deref() {
                let uv: Vec<DVec2> =
                    rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.2 .0).unwrap_or(DVec2::ZERO)).collect();
                let folder = dir.join("obj").join(&patch.name).join(&layer.name);
                let file = folder.join(format!("{:05}.obj", clock.frame));
                let res = std::fs::create_dir_all(&folder).and_then(|_| mesh::obj::write(&file, &pos, &uv, &rm.tris));
                if let Err(e) = res {
                    failure.0.get_or_insert(format!("cannot write {}: {e}", file.display()));
                }
            }
        }
    }
    if let Some(rec) = rec {
        for p in &report.patches {
            let base = format!("stats/{}", p.name);
            let _ = rec.log(format!("{base}/energy"), &rerun::Scalars::new([p.energy]));
            let _ = rec.log(format!("{base}/newton_iterations"), &rerun::Scalars::new([p.newton_iterations as f64]));
            let _ = rec.log(format!("{base}/residual"), &rerun::Scalars::new([p.residual]));
        }
        for stage in Stage::ALL {
            if stage != Stage::Log {
                let _ = rec.log(format!("timings/{}", stage.key()), &rerun::Scalars::new([timings.get(stage)]));
            }
        }
    }
}

fn render_mesh(
    epoch: u64,
    lf: Option<&LayerFaces>,
    lt: Option<&LayerTets>,
    faces: &Query<&FaceVerts>,
    tets: &Query<&TetVerts>,
    vertices: &Query<(&Position, &RestPos, &MaterialPos)>,
) -> RenderMesh {
    let tris_e: Vec<[Entity; 3]> = if let Some(lf) = lf.filter(|f| !f.entities().is_empty()) {
        lf.entities().iter().filter_map(|f| faces.get(*f).ok().map(|fv| fv.0)).collect()
    } else if let Some(lt) = lt {
        let tet_e: Vec<[Entity; 4]> = lt.entities().iter().filter_map(|t| tets.get(*t).ok().map(|tv| tv.0)).collect();
        let mut index = HashMap::new();
        let mut ents = Vec::new();
        let as_idx: Vec<[u32; 4]> = tet_e
            .iter()
            .map(|t| {
                t.map(|e| {
                    *index.entry(e).or_insert_with(|| {
                        ents.push(e);
                        (ents.len() - 1) as u32
                    })
                })
            })
            .collect();
        mesh::surface_of_tets(&as_idx).into_iter().map(|f| f.map(|i| ents[i as usize])).collect()
    } else {
        Vec::new()
    };
    let mut index = HashMap::new();
    let mut rm = RenderMesh { epoch, ..Default::default() };
    for t in &tris_e {
        let tri = t.map(|e| {
            *index.entry(e).or_insert_with(|| {
                rm.vertices.push(e);
                (rm.vertices.len() - 1) as u32
            })
        });
        rm.tris.push(tri);
    }
    let rest: Vec<DVec3> = rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.1 .0).unwrap_or_default()).collect();
    rm.rest_area = rm.tris.iter().map(|t| shading::triangle_area(&rest, t)).collect();
    rm
}

/// Logs a layer's mesh coloured by strain; returns the per-vertex strain. The triangles are
/// static unless the layer is remeshed: then they are logged at every topology change, on the
/// timeline (static data would shadow every earlier frame's triangles).
fn log_mesh(rec: &rerun::RecordingStream, path: &str, rm: &mut RenderMesh, pos: &[DVec3], remeshed: bool) -> Vec<f64> {
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
fn log_material_mesh(rec: &rerun::RecordingStream, path: &str, rm: &RenderMesh, uv: &[DVec2], strain: &[f64]) {
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
