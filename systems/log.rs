//! Log: sends the frame to Rerun (every layer as a Mesh3D coloured by strain, curvature, height
//! or layer, scalars for energy, Newton iterations and stage timings) and writes the requested
//! OBJ files and USD samples.

use std::collections::HashMap;
use std::path::PathBuf;

use bevy_ecs::prelude::*;
use glam::{DVec2, DVec3};
use skinsim::mesh;
use skinsim::mesh::shading::{self, ColourBy};
use skinsim::mesh::usd::{LayerFrame, UsdStage};
use skinsim::model::*;

use crate::log_mesh::{log_material_mesh, log_mesh, log_stats, Drawing};
use crate::render_mesh::{render_mesh, RenderMesh};

/// Where Rerun data goes (a file, a spawned viewer, a connection, or memory in tests).
#[derive(Resource)]
pub struct RerunSink(pub rerun::RecordingStream);

/// The entity the colour legend is logged to (a text document).
pub const LEGEND: &str = "legend";
/// The entity of the colour bar (an image: red at minus the scale, white at 0, blue at plus).
pub const COLOUR_BAR: &str = "colour_bar";

/// What the layers' colours show (strain when absent), and the curvature (1/m) or height (m)
/// that saturates them for the whole run (None: the first solved frame's, then fixed).
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct Colouring(pub ColourBy, pub Option<f64>);

/// Write obj/<patch>/<layer>/<frame>.obj under this directory.
#[derive(Resource, Clone, Debug)]
pub struct ObjExport(pub PathBuf);

/// Write a USD cache of every layer (`skinsim::mesh::usd`); the run finishes the stage.
#[derive(Resource)]
pub struct UsdExport(pub UsdStage);

pub fn wants_logging(sink: Option<Res<RerunSink>>, obj: Option<Res<ObjExport>>, usd: Option<Res<UsdExport>>) -> bool {
    sink.is_some() || obj.is_some() || usd.is_some()
}

#[derive(Default)]
pub struct RenderCache {
    meshes: HashMap<Entity, RenderMesh>,
    /// The legend last logged (logged again only when it changes).
    legend: String,
    /// Frame 0 (the rest state) is written.
    rest_logged: bool,
}

type LayerQ<'a> = (&'a Layer, &'a TopologyEpoch, Option<&'a LayerFaces>, Option<&'a LayerTets>, Has<RemeshSettings>);

#[allow(clippy::too_many_arguments)]
pub fn log_frame(
    clock: Res<SimClock>,
    timings: Res<Timings>,
    report: Res<FrameReport>,
    sink: Option<Res<RerunSink>>,
    obj: Option<Res<ObjExport>>,
    colouring: Option<Res<Colouring>>,
    mut usd: Option<ResMut<UsdExport>>,
    mut failure: ResMut<SimFailure>,
    mut cache: Local<RenderCache>,
    mut state: Option<ResMut<LogState>>,
    patches: Query<(&Patch, &PatchLayers)>,
    layers: Query<LayerQ>,
    faces: Query<(&FaceVerts, Option<&FacePrestrain>)>,
    tets: Query<(&TetVerts, Option<&TetPrestrain>)>,
    vertices: Query<(&Position, &RestPos, &MaterialPos)>,
    asset_uv: Query<&AssetUv>,
) {
    let rec = sink.as_ref().map(|s| &s.0);
    if let Some(rec) = rec {
        rec.set_time_sequence("frame", clock.frame as i64);
        rec.set_duration_secs("sim_time", clock.time);
    }
    let (by, scale) = colouring.map(|c| (c.0, c.1)).unwrap_or_default();
    let mut legend = Vec::new();
    let mut ordered: Vec<_> = patches.iter().collect();
    ordered.sort_by_key(|(p, _)| p.index);
    // The rest state first, as frame 0, in every output: frame 1 already carries the drivers'
    // first step and any perturbation.
    if let Some(s) = state.as_deref().filter(|s| s.rest_logged && !cache.rest_logged) {
        cache.rest_logged = true;
        for &(l, scale) in &s.colour_scales {
            let rm = cache.meshes.entry(l).or_default();
            (rm.colour_scale, rm.scale_sent) = (scale, true);
        }
    }
    let passes: &[bool] = if cache.rest_logged { &[false] } else { &[true, false] };
    cache.rest_logged = true;
    for &rest in passes {
        let frame = if rest { 0 } else { clock.frame };
        if let Some(rec) = rec.filter(|_| rest) {
            rec.set_time_sequence("frame", 0);
            rec.set_duration_secs("sim_time", 0.0);
            if by != ColourBy::Layer {
                let _ =
                    rec.log_static(COLOUR_BAR, &rerun::Image::from_rgb24(shading::colour_bar_rgb(256, 16), [256, 16]));
            }
        }
        for (patch, patch_layers) in &ordered {
            for (layer_index, &l) in patch_layers.entities().iter().enumerate() {
                let Ok((layer, epoch, lf, lt, remeshed)) = layers.get(l) else { continue };
                let rm = cache.meshes.entry(l).or_default();
                let new_topology = rm.vertices.is_empty() || rm.epoch != epoch.0;
                if new_topology {
                    // (a remesh keeps the layer's colour scale: fixed for the run)
                    let kept = (rm.colour_scale, rm.scale_sent);
                    *rm = render_mesh(epoch.0, lf, lt, &faces, &tets, &vertices);
                    (rm.colour_scale, rm.scale_sent) = kept;
                }
                if rm.tris.is_empty() {
                    continue;
                }
                let at =
                    |e: &Entity| vertices.get(*e).map(|v| if rest { v.1 .0 } else { v.0 .0 }).unwrap_or(DVec3::NAN);
                let pos: Vec<DVec3> = rm.vertices.iter().map(at).collect();
                let uv: Vec<DVec2> =
                    rm.vertices.iter().map(|e| vertices.get(*e).map(|v| v.2 .0).unwrap_or(DVec2::ZERO)).collect();
                let normals = shading::vertex_normals(&pos, &rm.tris);
                if let Some(UsdExport(stage)) = usd.as_deref_mut() {
                    let asset = rm.vertices.iter().map(|e| asset_uv.get(*e).ok().map(|u| u.0)).collect();
                    let (from_asset, st) = stage.st(asset, &uv);
                    let f = LayerFrame {
                        positions: &pos,
                        normals: &normals,
                        uv: &st,
                        tris: &rm.tris,
                        new_topology: new_topology || rest,
                        asset_uv: from_asset,
                    };
                    if let Err(e) = stage.add(&patch.name, &layer.name, remeshed, frame, &f) {
                        let (file, reason) = ("the USD cache".to_string(), e.to_string());
                        failure.0.get_or_insert(Failure::Output { file, reason });
                    }
                }
                if let Some(rec) = rec {
                    let path = format!("patches/{}/{}", patch.name, layer.name);
                    let body = layer.kind == LayerKind::Kinematic;
                    let d = Drawing { by, layer_index, body, rest, scale };
                    let (colours, line) = log_mesh(rec, &path, rm, &pos, remeshed, &d);
                    if !rest {
                        legend.extend(line.map(|line| format!("- **{}/{}**: {line}", patch.name, layer.name)));
                    }
                    if remeshed {
                        log_material_mesh(rec, &format!("material/{}/{}", patch.name, layer.name), rm, &uv, &colours);
                    }
                }
                if let Some(ObjExport(dir)) = obj.as_deref() {
                    let at = (patch.name.as_str(), layer.name.as_str(), frame);
                    if let Err((file, e)) = mesh::obj::write_frame(dir, at, &pos, &uv, &normals, &rm.tris) {
                        let (file, reason) = (file.display().to_string(), e.to_string());
                        failure.0.get_or_insert(Failure::Output { file, reason });
                    }
                }
            }
        }
        if let Some(rec) = rec.filter(|_| rest) {
            rec.set_time_sequence("frame", clock.frame as i64);
            rec.set_duration_secs("sim_time", clock.time);
        }
    }
    if let Some(s) = state.as_deref_mut() {
        s.rest_logged = cache.rest_logged;
        s.colour_scales = cache.meshes.iter().map(|(&l, rm)| (l, rm.colour_scale)).collect();
        s.colour_scales.sort_by_key(|(l, _)| l.to_bits());
    }
    if let Some(rec) = rec {
        let text = format!("### Colour: {}\n{}\n\n{}", by.name(), by.legend(), legend.join("\n"));
        if text != cache.legend {
            let _ = rec.log(LEGEND, &rerun::TextDocument::from_markdown(text.clone()));
            cache.legend = text;
        }
        log_stats(rec, &report, &timings, clock.frame);
    }
}
