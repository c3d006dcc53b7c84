//! `skinsim bake` (LK14 5.4): runs a scene and writes, for chosen frames (or the frames where
//! the blend shape reaches chosen weights, or a joint chosen angles), an 8-bit RGB normal map
//! of a shell layer: in its material rectangle (world-space normals), or in the UV layout of the
//! body its patches sit on (`MapLayout::Asset`: one map per body, normals in the body's tangent
//! space, ready for a shader); optionally blends of the first two maps; everything also logged
//! to a Rerun recording (the maps on a "frame" timeline, the blend on a "weight" timeline).
//! UV triangles that are flipped (skipped) or overlap are reported as warnings naming them.

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use image::RgbImage;
use skinsim::mesh::shading::vertex_normals;
use skinsim::mesh::wrinkle_map::{blend, draw_normals, encode, tangent_frames, uv_problems};
use skinsim::model::{Interpolation, Keyframes, LayerKind};
use skinsim::scene::built::BuiltDriver;
use skinsim::scene::BuiltScene;
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
    if req.layout == MapLayout::Asset && scene.patches.iter().all(|p| p.body.is_none()) {
        return Err("--layout asset bakes into a shared body's UVs: the scene has no patch on a body".into());
    }
    // A glTF body's material coordinates are its UV islands made length-true, each centred on
    // the origin, so they overlap: a map laid out in them would be wrong. (Its own [0, 1] UVs
    // reach the USD cache's `st`; maps in them are issue 65's.)
    let gltf =
        scene.patches.iter().filter_map(|p| p.body).map(|b| &scene.bodies[b]).find(|b| b.layers[0].asset.is_some());
    if let (MapLayout::Asset, Some(body)) = (req.layout, gltf) {
        return Err(format!(
            "--layout asset: \"{}\" is a glTF body, whose length-true UV islands overlap in material space; bake \
             with --layout material (one map per patch, in its own chart)",
            body.name
        ));
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
    let mut maps: Vec<(usize, RgbImage)> = Vec::new();
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
            let flat = RgbImage::from_pixel(req.size, req.size, encode(DVec3::Z));
            let img = match req.layout {
                MapLayout::Material => {
                    let (patch, layer, _) = &layers[ti];
                    let (uv, pos, faces) = sim.layer_surface(patch, layer);
                    let (lo, hi) = skinsim::mesh::bounds(&uv);
                    let faces =
                        checked_faces(&mut output.warnings, &mut checked, patch, layer, &uv, &faces, req.size, lo, hi);
                    let mut img = flat;
                    draw_normals(&mut img, &uv, &faces, &vertex_normals(&pos, &faces), lo, hi);
                    img
                }
                MapLayout::Asset => {
                    let (body_uv, body_pos, body_faces) = sim.layer_surface(target, target);
                    let (lo, hi) = skinsim::mesh::bounds(&body_uv);
                    if frame == frames[0] {
                        output.rectangles.push((target.clone(), lo, hi));
                    }
                    let frames_of =
                        tangent_frames(&body_pos, &body_uv, &body_faces, &vertex_normals(&body_pos, &body_faces));
                    let at_uv: std::collections::HashMap<[u64; 2], usize> =
                        body_uv.iter().enumerate().map(|(i, u)| (u.to_array().map(f64::to_bits), i)).collect();
                    let mut img = flat;
                    for (patch, layer, _) in layers.iter().filter(|(_, _, b)| b.as_ref() == Some(target)) {
                        let (uv, pos, faces) = sim.layer_surface(patch, layer);
                        let faces = checked_faces(
                            &mut output.warnings,
                            &mut checked,
                            patch,
                            layer,
                            &uv,
                            &faces,
                            req.size,
                            lo,
                            hi,
                        );
                        let normals = vertex_normals(&pos, &faces);
                        // The skin is cut from the body: each vertex has the body's UV.
                        let tangent: Vec<DVec3> = uv
                            .iter()
                            .zip(&normals)
                            .map(|(u, n)| match at_uv.get(&u.to_array().map(f64::to_bits)) {
                                Some(&b) => frames_of[b].transpose() * *n,
                                None => *n,
                            })
                            .collect();
                        draw_normals(&mut img, &uv, &faces, &tangent, lo, hi);
                    }
                    img
                }
            };
            let path = out.join(format!("{target}_{frame:05}.png"));
            img.save(&path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            if let Some(rec) = rec {
                rec.set_time_sequence("frame", frame as i64);
                let _ =
                    rec.log(format!("wrinkle_map/{target}"), &rerun::Image::from_rgb24(img.to_vec(), [req.size; 2]));
            }
            let (patch, layer) = match req.layout {
                MapLayout::Material => (layers[ti].0.clone(), layers[ti].1.clone()),
                MapLayout::Asset => (target.clone(), "tangent".to_string()),
            };
            maps.push((ti, img));
            output.maps.push(Baked { patch, layer, frame, path });
        }
    }
    // Blends of the first two maps of the first target (two key poses).
    let first: Vec<&RgbImage> = maps.iter().filter(|(ti, _)| *ti == 0).map(|(_, m)| m).take(2).collect();
    if let [a, b] = first[..] {
        let target = &targets[0];
        for &w in &req.blends {
            let path = out.join(format!("{target}_blend_{w:.2}.png"));
            blend(a, b, w).save(&path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        }
        if let Some(rec) = rec {
            for step in 0..=10 {
                let w = step as f64 / 10.0;
                rec.set_time_sequence("weight_percent", (100.0 * w) as i64);
                let img = blend(a, b, w);
                let _ = rec
                    .log(format!("wrinkle_map/{target}/blend"), &rerun::Image::from_rgb24(img.to_vec(), [req.size; 2]));
            }
        }
    } else if !req.blends.is_empty() {
        return Err("--blend needs two baked frames".into());
    }
    Ok(output)
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
