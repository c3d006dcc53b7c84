//! `skinsim bake` (LK14 5.4): runs a scene and writes, for chosen frames (or the frames where
//! the blend shape reaches chosen weights), an 8-bit RGB normal map of a shell layer in
//! material space; optionally blends of the first two maps; everything also logged to a Rerun
//! recording (the maps on a "frame" timeline, the blend on a "weight" timeline).

use std::path::{Path, PathBuf};

use image::RgbImage;
use skinsim::mesh::shading::vertex_normals;
use skinsim::mesh::wrinkle_map::{blend, normal_map};
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
        let blend = scene
            .patches
            .iter()
            .flat_map(|p| &p.drivers)
            .find_map(|d| match d {
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
        let keys = scene
            .patches
            .iter()
            .flat_map(|p| &p.drivers)
            .find_map(|d| match d {
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
    Ok(frames)
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
) -> Result<Vec<Baked>, String> {
    let frames = frames_for(scene, req)?;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let mut sim = Simulation::new(scene);
    let layers: Vec<(String, String)> = {
        let all = sim.layers();
        let mut chosen: Vec<(String, String)> = Vec::new();
        for (patch, layer, kind) in all {
            let wanted = match &req.layer {
                Some(name) => *name == layer,
                None => kind == LayerKind::Shell,
            };
            if !wanted {
                continue;
            }
            // Without --layer, the last (top) shell of each patch wins.
            match chosen.iter_mut().find(|(p, _)| *p == patch) {
                Some(c) if req.layer.is_none() => c.1 = layer,
                _ => chosen.push((patch, layer)),
            }
        }
        chosen
    };
    if layers.is_empty() {
        return Err(match &req.layer {
            Some(l) => format!("no layer named \"{l}\" with triangles"),
            None => "the scene has no shell layer".into(),
        });
    }
    let mut baked = Vec::new();
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
        for (li, (patch, layer)) in layers.iter().enumerate() {
            let (uv, pos, faces) = sim.layer_surface(patch, layer);
            let normals = vertex_normals(&pos, &faces);
            let (lo, hi) = skinsim::mesh::bounds(&uv);
            let img = normal_map(&uv, &faces, &normals, req.size, lo, hi);
            let path = out.join(format!("{patch}_{layer}_{frame:05}.png"));
            img.save(&path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            if let Some(rec) = rec {
                rec.set_time_sequence("frame", frame as i64);
                let _ = rec.log(
                    format!("wrinkle_map/{patch}/{layer}"),
                    &rerun::Image::from_rgb24(img.to_vec(), [req.size; 2]),
                );
            }
            maps.push((li, img));
            baked.push(Baked { patch: patch.clone(), layer: layer.clone(), frame, path });
        }
    }
    // Blends of the first two maps of the first layer (two key poses).
    let first: Vec<&RgbImage> = maps.iter().filter(|(li, _)| *li == 0).map(|(_, m)| m).take(2).collect();
    if let [a, b] = first[..] {
        let (patch, layer) = &layers[0];
        for &w in &req.blends {
            let path = out.join(format!("{patch}_{layer}_blend_{w:.2}.png"));
            blend(a, b, w).save(&path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        }
        if let Some(rec) = rec {
            for step in 0..=10 {
                let w = step as f64 / 10.0;
                rec.set_time_sequence("weight_percent", (100.0 * w) as i64);
                let img = blend(a, b, w);
                let _ = rec.log(
                    format!("wrinkle_map/{patch}/{layer}/blend"),
                    &rerun::Image::from_rgb24(img.to_vec(), [req.size; 2]),
                );
            }
        }
    } else if !req.blends.is_empty() {
        return Err("--blend needs two baked frames".into());
    }
    Ok(baked)
}
