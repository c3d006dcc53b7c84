//! `skinsim bake` (LK14 5.4): runs a scene and writes, for chosen frames (or the frames where
//! the blend shape reaches chosen weights, or a joint chosen angles), normal maps of a shell
//! layer: an 8-bit RGB map in its material rectangle (world-space normals; LK14's layout), or,
//! in the UV layout of the body its patches sit on (`MapLayout::Asset`, for a shader: one map
//! per body, issue 65), a normal map in the body's tangent space and a height (displacement)
//! map, 16-bit by default, texels square in the asset's UVs (its [0, 1] atlas, or an OBJ body's
//! `vt`), each patch faded into the body's unwrinkled surface over `edge_blend` from its edge
//! and padded across its UV borders by `padding` pixels; optionally blends of the first two
//! maps; everything also logged to a Rerun recording (the maps on a "frame" timeline, the blend
//! on a "weight" timeline). UV triangles that are flipped (skipped) or overlap are reported as
//! warnings naming them.

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use image::RgbImage;
use skinsim::mesh::map_buffer::{
    boundary_distances, fade, height_image16, normal_image16, BodyField, MapBuffer, MapGrid, Surface,
};
use skinsim::mesh::shading::vertex_normals;
use skinsim::mesh::wrinkle_map::{blend, draw_normals, encode, uv_problems};
use skinsim::model::{Interpolation, Keyframes, LayerKind};
use skinsim::scene::built::BuiltDriver;
use skinsim::scene::BuiltScene;
use skinsim_systems::inspect::SurfaceSnapshot;
use skinsim_systems::Simulation;

/// What to bake.
pub struct BakeRequest {
    pub frames: Vec<u32>,
    pub weights: Vec<f64>,
    /// Joint angles in degrees.
    pub angles: Vec<f64>,
    pub size: u32,
    /// None: the top shell layer of each patch.
    pub layer: Option<String>,
    /// Blends of the first two maps written as images.
    pub blends: Vec<f64>,
    pub layout: MapLayout,
    /// Asset maps: pixels of padding around each drawn region (its values carried outward).
    pub padding: u32,
    /// Asset maps: the width (m) over which a patch fades from its edge into the body's
    /// unwrinkled surface (normal (0, 0, 1) in tangent space, height 0).
    pub edge_blend: f64,
    /// Asset maps: bits per channel of the normal map (8 or 16; the height map is 16).
    pub bits: u8,
    /// Asset maps: the height (m) at the height map's white (its black is minus it, grey 0).
    pub height_range: f64,
    /// Asset maps: Loop subdivision levels the skin is drawn at (its limit surface's normals
    /// instead of its triangles' interpolated ones; 0: the triangles).
    pub smooth: u32,
}

impl Default for BakeRequest {
    fn default() -> Self {
        BakeRequest {
            frames: Vec::new(),
            weights: Vec::new(),
            angles: Vec::new(),
            size: 1024,
            layer: None,
            blends: Vec::new(),
            layout: MapLayout::Material,
            padding: 8,
            edge_blend: 2e-3,
            bits: 16,
            height_range: 5e-3,
            smooth: 2,
        }
    }
}

/// Where a map's pixels lie.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MapLayout {
    /// Each layer over its own material rectangle, world-space normals.
    #[default]
    Material,
    /// One map per shared body over the body's UV rectangle (the asset's layout, its islands
    /// where they are), every baked layer of the patches on it drawn at its UVs, normals in the
    /// body's tangent space (T along +u, N the body's posed normal).
    Asset,
}

/// What a bake wrote, and what it warns about.
pub struct BakeOutput {
    pub maps: Vec<Baked>,
    /// The body UV rectangle of each asset map (body name, lo, hi; material units, m).
    pub rectangles: Vec<(String, DVec2, DVec2)>,
    pub warnings: Vec<String>,
}

/// One written map.
pub struct Baked {
    pub patch: String,
    pub layer: String,
    pub frame: u32,
    pub path: PathBuf,
}

/// The frames to bake: the requested ones, plus per requested weight the first frame where the
/// first patch's first blend-shape target is closest to it, and per requested angle the first
/// frame where the first Joint's angle is closest to it.
pub fn frames_for(scene: &BuiltScene, req: &BakeRequest) -> Result<Vec<u32>, String> {
    if let Some(w) = req.weights.iter().find(|w| !w.is_finite()) {
        return Err(format!("--weights must be finite numbers (got {w})"));
    }
    if let Some(a) = req.angles.iter().find(|a| !a.is_finite()) {
        return Err(format!("--angles must be finite numbers of degrees (got {a})"));
    }
    if let Some(b) = req.blends.iter().find(|b| !(0.0..=1.0).contains(*b)) {
        return Err(format!("--blend weights must be in [0, 1] (got {b})"));
    }
    if let Some(name) = &req.layer {
        let layers = scene.patches.iter().flat_map(|p| &p.layers);
        if !layers.clone().any(|l| l.name == *name) {
            let names: Vec<&str> = layers.map(|l| l.name.as_str()).collect();
            return Err(format!("--layer: no layer named \"{name}\" (the scene's: {})", names.join(", ")));
        }
    }
    let mut frames = req.frames.clone();
    if !req.weights.is_empty() {
        let blend = first_driver(scene, |d| match d {
            BuiltDriver::BlendShape { targets, interpolation, .. } => Some((targets[0].1.clone(), *interpolation)),
            _ => None,
        })
        .ok_or("--weights needs a scene with a BlendShape driver")?;
        let keys = Keyframes(blend.0);
        for &w in &req.weights {
            frames.push(closest_frame(scene.scene.frames, w, |f| keys.at(f, blend.1)));
        }
    }
    if !req.angles.is_empty() {
        let keys = first_driver(scene, |d| match d {
            BuiltDriver::Joint { keyframes, .. } => Some(Keyframes(keyframes.clone())),
            _ => None,
        })
        .ok_or("--angles needs a scene with a Joint driver")?;
        for &a in &req.angles {
            frames.push(closest_frame(scene.scene.frames, a.to_radians(), |f| keys.at(f, Interpolation::Linear)));
        }
    }
    if let Some(&f) = frames.iter().find(|&&f| f > scene.scene.frames) {
        return Err(format!("frame {f} is past the scene's last frame ({})", scene.scene.frames));
    }
    frames.sort_unstable();
    frames.dedup();
    if frames.is_empty() {
        return Err("nothing to bake: give --frames, --weights or --angles".into());
    }
    if !req.blends.is_empty() && frames.len() < 2 {
        return Err(format!("--blend needs two baked frames (the frames asked for are {frames:?})"));
    }
    if req.layout == MapLayout::Asset && scene.patches.iter().all(|p| p.body.is_none()) {
        return Err("--layout asset bakes into a shared body's UVs: the scene has no patch on a body".into());
    }
    if !(req.bits == 8 || req.bits == 16) {
        return Err(format!("--bits must be 8 or 16 (got {})", req.bits));
    }
    if !(req.edge_blend >= 0.0 && req.edge_blend.is_finite()) {
        return Err(format!("--edge-blend must be a length of at least 0 (got {})", req.edge_blend));
    }
    if req.smooth > 3 {
        return Err(format!("--smooth must be at most 3 levels (64 triangles per triangle; got {})", req.smooth));
    }
    if !(req.height_range > 0.0 && req.height_range.is_finite()) {
        return Err(format!("--height-range must be a positive length (got {})", req.height_range));
    }
    Ok(frames)
}

/// The first driver of the patches', then the shared bodies', for which `pick` gives a value.
fn first_driver<T>(scene: &BuiltScene, pick: impl Fn(&BuiltDriver) -> Option<T>) -> Option<T> {
    scene.patches.iter().chain(&scene.bodies).flat_map(|p| &p.drivers).find_map(pick)
}

/// The first frame in 0..=last where `value` comes closest to `target`.
fn closest_frame(last: u32, target: f64, value: impl Fn(f64) -> f64) -> u32 {
    (0..=last)
        .min_by(|&a, &b| (value(a as f64) - target).abs().total_cmp(&(value(b as f64) - target).abs()))
        .expect("at least frame 0")
}

/// Runs the scene up to the last requested frame and writes the maps under `out`.
pub fn bake(
    scene: &BuiltScene,
    req: &BakeRequest,
    out: &Path,
    rec: Option<&rerun::RecordingStream>,
) -> Result<BakeOutput, String> {
    let frames = frames_for(scene, req)?;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let mut sim = Simulation::new(scene);
    let layers = chosen_layers(scene, &mut sim, req)?;
    // Asset maps: one per body, named after it; material maps: one per layer.
    let targets: Vec<String> = match req.layout {
        MapLayout::Material => layers.iter().map(|(p, l, _)| format!("{p}_{l}")).collect(),
        MapLayout::Asset => {
            let mut bodies: Vec<String> = layers.iter().filter_map(|(_, _, b)| b.clone()).collect();
            bodies.dedup();
            bodies
        }
    };
    let mut output = BakeOutput { maps: Vec::new(), rectangles: Vec::new(), warnings: Vec::new() };
    let mut checked = std::collections::HashSet::new();
    let mut maps: Vec<(usize, Map)> = Vec::new();
    let unit = scene.scene.units.length.to_si();
    for frame in 0..=*frames.last().unwrap() {
        if frame > 0 {
            sim.step();
            if let Some(reason) = sim.failure() {
                return Err(format!("simulation failed at {reason}; maps written so far are kept"));
            }
        }
        if !frames.contains(&frame) {
            continue;
        }
        for (ti, target) in targets.iter().enumerate() {
            let map = match req.layout {
                MapLayout::Material => {
                    let (patch, layer, _) = &layers[ti];
                    let (uv, pos, faces) = sim.layer_surface(patch, layer);
                    let (lo, hi) = skinsim::mesh::bounds(&uv);
                    let faces =
                        checked_faces(&mut output.warnings, &mut checked, patch, layer, &uv, &faces, req.size, lo, hi);
                    let mut img = RgbImage::from_pixel(req.size, req.size, encode(DVec3::Z));
                    draw_normals(&mut img, &uv, &faces, &vertex_normals(&pos, &faces), lo, hi);
                    Map::Material(img)
                }
                MapLayout::Asset => {
                    let body = sim.layer_snapshot(target, target);
                    let body_uv = asset_uv(&body, unit);
                    let (lo, hi) = MapGrid::rectangle_of(&body_uv);
                    let grid = MapGrid::square_texels(lo, hi, req.size);
                    if frame == frames[0] {
                        output.rectangles.push((target.clone(), grid.lo, grid.hi));
                    }
                    // Each pixel: the tangent normal, the height and the distance to the patch's
                    // edge, interpolated; then faded by that distance (per pixel, as fine as the
                    // map), so that the patch meets the body's unwrinkled surface at its edge.
                    let mut drawn = MapBuffer::new(grid, [0.0, 0.0, 1.0, 0.0, f64::INFINITY]);
                    let under = BodyField::new(Surface::of(&body.pos, &body.rest, &body.faces), &body_uv);
                    for (patch, layer, _) in layers.iter().filter(|(_, _, b)| b.as_ref() == Some(target)) {
                        let skin = sim.layer_snapshot(patch, layer);
                        let uv = asset_uv(&skin, unit);
                        let faces = checked_faces(
                            &mut output.warnings,
                            &mut checked,
                            patch,
                            layer,
                            &uv,
                            &skin.faces,
                            req.size,
                            grid.lo,
                            grid.hi,
                        );
                        let d = boundary_distances(&skin.rest, &faces);
                        let coarse = DrawnSkin { skin: SurfaceSnapshot { faces, ..skin }, uv, distance: d };
                        let DrawnSkin { skin, uv, distance: d } = match smoothed(&coarse, req.smooth) {
                            Ok(s) => s,
                            Err(e) => {
                                let why = format!("{patch}/{layer}: drawn as its triangles, not subdivided ({e})");
                                output.warnings.push(why);
                                coarse
                            }
                        };
                        let surface = Surface::of(&skin.pos, &skin.rest, &skin.faces);
                        let (n, h) = under.tangent_normals_and_heights(surface, &uv);
                        let values: Vec<[f64; 5]> =
                            (0..n.len()).map(|i| [n[i].x, n[i].y, n[i].z, h[i], d[i].min(FAR)]).collect();
                        drawn.draw(&uv, &skin.faces, &values);
                    }
                    let mut normals = MapBuffer::new(grid, [0.0, 0.0, 1.0]);
                    let mut heights = MapBuffer::new(grid, [0.0]);
                    for (i, v) in drawn.values.iter().enumerate().filter(|(i, _)| drawn.covered[*i]) {
                        let w = fade(v[4], req.edge_blend);
                        let n = DVec3::Z + w * (DVec3::new(v[0], v[1], v[2]).normalize_or(DVec3::Z) - DVec3::Z);
                        normals.values[i] = n.normalize_or(DVec3::Z).to_array();
                        heights.values[i] = [w * v[3]];
                        (normals.covered[i], heights.covered[i]) = (true, true);
                    }
                    normals.dilate(req.padding);
                    heights.dilate(req.padding);
                    Map::Asset { normals, heights }
                }
            };
            let path = out.join(format!("{target}_{frame:05}.png"));
            map.save(&path, req).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            if let Map::Asset { heights, .. } = &map {
                let path = out.join(format!("{target}_height_{frame:05}.png"));
                let img = height_image16(heights, req.height_range);
                img.save(&path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            }
            if let Some(rec) = rec {
                rec.set_time_sequence("frame", frame as i64);
                let _ = rec.log(format!("wrinkle_map/{target}"), &map.preview());
            }
            let (patch, layer) = match req.layout {
                MapLayout::Material => (layers[ti].0.clone(), layers[ti].1.clone()),
                MapLayout::Asset => (target.clone(), "tangent".to_string()),
            };
            maps.push((ti, map));
            output.maps.push(Baked { patch, layer, frame, path });
        }
    }
    if req.layout == MapLayout::Asset {
        write_sidecar(out, req, &output)
            .map_err(|e| format!("cannot write the maps' description in {}: {e}", out.display()))?;
    }
    // Blends of the first two maps of the first target (two key poses).
    let first: Vec<&Map> = maps.iter().filter(|(ti, _)| *ti == 0).map(|(_, m)| m).take(2).collect();
    if let [a, b] = first[..] {
        let target = &targets[0];
        for &w in &req.blends {
            let path = out.join(format!("{target}_blend_{w:.2}.png"));
            a.blend(b, w).save(&path, req).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        }
        if let Some(rec) = rec {
            for step in 0..=10 {
                let w = step as f64 / 10.0;
                rec.set_time_sequence("weight_percent", (100.0 * w) as i64);
                let _ = rec.log(format!("wrinkle_map/{target}/blend"), &a.blend(b, w).preview());
            }
        }
    } else if !req.blends.is_empty() {
        return Err("--blend needs two baked frames".into());
    }
    Ok(output)
}

/// A distance to a patch's edge that stands for "far" (m): a closed skin has no edge.
const FAR: f64 = 1e3;

/// One baked map: LK14's 8-bit map in material space, or an asset map's normals (tangent
/// space) and heights as numbers, encoded when written.
enum Map {
    Material(RgbImage),
    Asset { normals: MapBuffer<3>, heights: MapBuffer<1> },
}

impl Map {
    fn save(&self, path: &Path, req: &BakeRequest) -> image::ImageResult<()> {
        match self {
            Map::Material(img) => img.save(path),
            Map::Asset { normals, .. } if req.bits == 16 => normal_image16(normals).save(path),
            Map::Asset { .. } => self.rgb8().save(path),
        }
    }

    fn rgb8(&self) -> RgbImage {
        match self {
            Map::Material(img) => img.clone(),
            Map::Asset { normals, .. } => RgbImage::from_fn(normals.grid.width, normals.grid.height, |x, y| {
                encode(DVec3::from_array(normals.at(x, y)).normalize_or(DVec3::Z))
            }),
        }
    }

    fn preview(&self) -> rerun::Image {
        let img = self.rgb8();
        rerun::Image::from_rgb24(img.to_vec(), [img.width(), img.height()])
    }

    /// The normalized (1 - w) a + w b per pixel (heights: the plain mix).
    fn blend(&self, other: &Map, w: f64) -> Map {
        match (self, other) {
            (Map::Asset { normals: na, heights: ha }, Map::Asset { normals: nb, heights: hb }) => {
                let mut normals = na.clone();
                for (v, b) in normals.values.iter_mut().zip(&nb.values) {
                    let n = DVec3::from_array(*v) * (1.0 - w) + DVec3::from_array(*b) * w;
                    *v = n.normalize_or(DVec3::Z).to_array();
                }
                let mut heights = ha.clone();
                heights.values.iter_mut().zip(&hb.values).for_each(|(v, b)| v[0] = (1.0 - w) * v[0] + w * b[0]);
                Map::Asset { normals, heights }
            }
            _ => Map::Material(blend(&self.rgb8(), &other.rgb8(), w)),
        }
    }
}

/// The skin `levels` times Loop-subdivided (its vertices on the limit surface through the
/// skin's, at the current and the rest positions), its UVs and edge distances interpolated
/// linearly: a quick scene's coarse triangles otherwise show as facets in the map (their
/// vertex normals interpolated linearly), whatever the map's resolution.
fn smoothed(coarse: &DrawnSkin, levels: u32) -> Result<DrawnSkin, String> {
    let DrawnSkin { skin, uv, distance } = coarse;
    let faces = &skin.faces;
    if levels == 0 {
        return Ok(coarse.clone());
    }
    let region: Vec<u32> = (0..faces.len() as u32).collect();
    let r = skinsim::mesh::subdivision::refine(&skin.rest, faces, &region, levels).map_err(|e| e.to_string())?;
    let (mut pos, mut rest) = (Vec::new(), Vec::new());
    skinsim::mesh::subdivision::apply_all(&r.stencils, &skin.pos, &mut pos);
    skinsim::mesh::subdivision::apply_all(&r.stencils, &skin.rest, &mut rest);
    // (each refined vertex's coarse face and barycentric weights: linear in the UVs)
    let k_of = |v: u32, k: usize| if k < 2 { uv[v as usize][k] } else { distance[v as usize] };
    let mix = |(f, w): &(u32, DVec3), k: usize| {
        let c = faces[*f as usize];
        w.x * k_of(c[0], k) + w.y * k_of(c[1], k) + w.z * k_of(c[2], k)
    };
    let uv = r.parent.iter().map(|p| DVec2::new(mix(p, 0), mix(p, 1))).collect();
    let distance = r.parent.iter().map(|p| mix(p, 2)).collect();
    Ok(DrawnSkin { skin: SurfaceSnapshot { uv: Vec::new(), asset_uv: None, pos, rest, faces: r.faces }, uv, distance })
}

/// A skin as drawn into an asset map: its surface, UVs and distances to its edge (m).
#[derive(Clone)]
struct DrawnSkin {
    skin: SurfaceSnapshot,
    uv: Vec<DVec2>,
    distance: Vec<f64>,
}

/// A layer's UVs in the asset's layout: its own UVs where it has them (a character's), else its
/// material coordinates in the scene's length unit (an OBJ body's `vt`).
fn asset_uv(s: &SurfaceSnapshot, unit: f64) -> Vec<DVec2> {
    s.asset_uv.clone().unwrap_or_else(|| s.uv.iter().map(|u| *u / unit).collect())
}

/// `maps.json` beside asset maps: what their pixels mean (the UV rectangle, the encodings, the
/// height range), so that a shader setup needs no guessing.
fn write_sidecar(out: &Path, req: &BakeRequest, output: &BakeOutput) -> std::io::Result<()> {
    let bodies: Vec<serde_json::Value> = output
        .rectangles
        .iter()
        .map(|(name, lo, hi)| serde_json::json!({ "body": name, "uv_lo": [lo.x, lo.y], "uv_hi": [hi.x, hi.y] }))
        .collect();
    let files: Vec<String> =
        output.maps.iter().map(|m| m.path.file_name().unwrap_or_default().to_string_lossy().into_owned()).collect();
    let doc = serde_json::json!({
        "layout": "asset UVs (row 0 at the largest v), texels square",
        "normal_map": format!("{}-bit RGB, tangent space (T along +u, N the body's normal): n = 2 c - 1", req.bits),
        "height_map": "<body>_height_<frame>.png: 16-bit grey, the skin's displacement along the body's normal \
                       from its rest height: h = (g / 65535 * 2 - 1) * height_range_m",
        "height_range_m": req.height_range,
        "padding_px": req.padding,
        "edge_blend_m": req.edge_blend,
        "loop_subdivision_levels": req.smooth,
        "bodies": bodies,
        "normal_maps": files,
    });
    std::fs::write(out.join("maps.json"), serde_json::to_string_pretty(&doc).map_err(std::io::Error::other)?)
}

/// The (patch, layer, its patch's body) to bake: `--layer` in every patch, or the top shell of
/// each patch; for the asset layout, only patches on a body.
fn chosen_layers(
    scene: &BuiltScene,
    sim: &mut Simulation,
    req: &BakeRequest,
) -> Result<Vec<(String, String, Option<String>)>, String> {
    let body_of = |patch: &str| -> Option<String> {
        let p = scene.patches.iter().find(|p| p.name == patch)?;
        p.body.map(|b| scene.bodies[b].name.clone())
    };
    let mut chosen: Vec<(String, String, Option<String>)> = Vec::new();
    for (patch, layer, kind) in sim.layers() {
        let wanted = match &req.layer {
            Some(name) => *name == layer,
            None => kind == LayerKind::Shell,
        };
        let body = body_of(&patch);
        if !wanted || (req.layout == MapLayout::Asset && body.is_none()) {
            continue;
        }
        // Without --layer, the last (top) shell of each patch wins.
        match chosen.iter_mut().find(|(p, ..)| *p == patch) {
            Some(c) if req.layer.is_none() => c.1 = layer,
            _ => chosen.push((patch, layer, body)),
        }
    }
    if chosen.is_empty() {
        return Err(match &req.layer {
            Some(l) => format!("no layer named \"{l}\" with triangles"),
            None => "the scene has no shell layer".into(),
        });
    }
    Ok(chosen)
}

/// The faces of a layer to draw: all but the flipped UV triangles. The first time a layer is
/// drawn, its flipped and overlapping UV triangles become a warning that names them.
#[allow(clippy::too_many_arguments)]
fn checked_faces(
    warnings: &mut Vec<String>,
    checked: &mut std::collections::HashSet<(String, String)>,
    patch: &str,
    layer: &str,
    uv: &[DVec2],
    faces: &[[u32; 3]],
    size: u32,
    lo: DVec2,
    hi: DVec2,
) -> Vec<[u32; 3]> {
    let problems = uv_problems(uv, faces, size, lo, hi);
    if checked.insert((patch.to_string(), layer.to_string())) {
        let list = |f: &[u32]| {
            let shown: Vec<String> = f.iter().take(8).map(|i| i.to_string()).collect();
            format!(
                "{}{}",
                shown.join(", "),
                if f.len() > 8 { format!(", ... ({} in all)", f.len()) } else { String::new() }
            )
        };
        if !problems.flipped.is_empty() {
            warnings.push(format!(
                "{patch}/{layer}: {} UV triangles are flipped (a seam or a mirrored piece) and are left out of the map: \
                 faces {}",
                problems.flipped.len(),
                list(&problems.flipped)
            ));
        }
        if !problems.overlapping.is_empty() {
            warnings.push(format!(
                "{patch}/{layer}: {} UV triangles overlap others in the map (the last drawn wins): faces {}",
                problems.overlapping.len(),
                list(&problems.overlapping)
            ));
        }
    }
    let flipped: std::collections::HashSet<u32> = problems.flipped.into_iter().collect();
    (0..faces.len() as u32).filter(|i| !flipped.contains(i)).map(|i| faces[i as usize]).collect()
}
