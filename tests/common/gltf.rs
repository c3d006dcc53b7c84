//! A small glTF 2.0 writer for the system tests (issue 62): a triangle mesh with UVs, optionally
//! a chain of joints with linear skinning weights, morph targets and one rotation clip. The
//! tests write their own assets so that every figure has an independent computation beside it.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

/// A joint: its name, parent joint and rest translation relative to the parent (glTF frame).
pub struct Joint {
    pub name: String,
    pub parent: Option<usize>,
    pub translation: [f32; 3],
}

/// A clip turning one joint: key times (s) and rotation quaternions (x, y, z, w).
pub struct Clip {
    pub name: String,
    pub joint: usize,
    pub times: Vec<f32>,
    pub rotations: Vec<[f32; 4]>,
}

#[derive(Default)]
pub struct Asset {
    pub positions: Vec<[f32; 3]>,
    pub uv: Option<Vec<[f32; 2]>>,
    pub indices: Vec<u32>,
    pub joints: Vec<Joint>,
    /// Per vertex: four joint indices and weights (JOINTS_0 / WEIGHTS_0).
    pub influences: Vec<([u16; 4], [f32; 4])>,
    /// Per vertex: four more (JOINTS_1 / WEIGHTS_1; empty: none), for up to eight influences.
    pub influences_1: Vec<([u16; 4], [f32; 4])>,
    /// (name, per-vertex displacement)
    pub morphs: Vec<(String, Vec<[f32; 3]>)>,
    pub clips: Vec<Clip>,
    /// Extra vertex attributes, written as given (for bad-input tests): (semantic, accessor).
    pub extra: Vec<(String, Value)>,
}

struct Buffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    fn push(
        &mut self,
        bytes: &[u8],
        count: usize,
        component: u32,
        ty: &str,
        minmax: Option<(Vec<f32>, Vec<f32>)>,
    ) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        let mut a = json!({"bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": ty});
        if let Some((min, max)) = minmax {
            a["min"] = json!(min);
            a["max"] = json!(max);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, v: &[[f32; N]], ty: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let minmax = bounds.then(|| {
            let min = (0..N).map(|k| v.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min)).collect();
            let max = (0..N).map(|k| v.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max)).collect();
            (min, max)
        });
        self.push(&bytes, v.len(), 5126, ty, minmax)
    }
}

/// Writes `name.gltf` and `name.bin` into `dir`; returns the .gltf path.
pub fn write(dir: &Path, name: &str, a: &Asset) -> PathBuf {
    let mut b = Buffer { bin: Vec::new(), views: Vec::new(), accessors: Vec::new() };
    let mut attributes = json!({"POSITION": b.floats(&a.positions, "VEC3", true)});
    if let Some(uv) = &a.uv {
        attributes["TEXCOORD_0"] = json!(b.floats(uv, "VEC2", false));
    }
    for (set, influences) in [&a.influences, &a.influences_1].into_iter().enumerate() {
        if influences.is_empty() {
            continue;
        }
        let joints: Vec<u8> = influences.iter().flat_map(|i| i.0).flat_map(|j| j.to_le_bytes()).collect();
        attributes[format!("JOINTS_{set}")] = json!(b.push(&joints, influences.len(), 5123, "VEC4", None));
        let weights: Vec<[f32; 4]> = influences.iter().map(|i| i.1).collect();
        attributes[format!("WEIGHTS_{set}")] = json!(b.floats(&weights, "VEC4", false));
    }
    for (semantic, accessor) in &a.extra {
        b.accessors.push(accessor.clone());
        attributes[semantic.as_str()] = json!(b.accessors.len() - 1);
    }
    let index_bytes: Vec<u8> = a.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let indices = b.push(&index_bytes, a.indices.len(), 5125, "SCALAR", None);
    let targets: Vec<Value> = a.morphs.iter().map(|(_, d)| json!({"POSITION": b.floats(d, "VEC3", true)})).collect();
    let mut primitive = json!({"attributes": attributes, "indices": indices, "mode": 4});
    let mut mesh = json!({"name": name, "primitives": []});
    if !targets.is_empty() {
        primitive["targets"] = json!(targets);
        mesh["weights"] = json!(vec![0.0; targets.len()]);
        mesh["extras"] = json!({"targetNames": a.morphs.iter().map(|m| m.0.clone()).collect::<Vec<_>>()});
    }
    mesh["primitives"] = json!([primitive]);
    // Nodes: the joints first, then the node that carries the mesh (a root, as the spec wants).
    let mut nodes: Vec<Value> = a
        .joints
        .iter()
        .enumerate()
        .map(|(i, j)| {
            let children: Vec<usize> = (0..a.joints.len()).filter(|&c| a.joints[c].parent == Some(i)).collect();
            let mut n = json!({"name": j.name, "translation": j.translation});
            if !children.is_empty() {
                n["children"] = json!(children);
            }
            n
        })
        .collect();
    let mesh_node = nodes.len();
    let mut node = json!({"name": format!("{name}_mesh"), "mesh": 0});
    let mut skins = Vec::new();
    if !a.joints.is_empty() {
        // Rest rotations are the identity: each inverse bind matrix undoes the joint's global
        // translation.
        let global = |mut j: usize| {
            let mut t = [0.0f32; 3];
            loop {
                (0..3).for_each(|k| t[k] += a.joints[j].translation[k]);
                match a.joints[j].parent {
                    Some(p) => j = p,
                    None => return t,
                }
            }
        };
        let ibm: Vec<[f32; 16]> = (0..a.joints.len())
            .map(|j| {
                let t = global(j);
                [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -t[0], -t[1], -t[2], 1.0]
            })
            .collect();
        let inverse = b.floats(&ibm, "MAT4", false);
        skins.push(json!({"joints": (0..a.joints.len()).collect::<Vec<_>>(), "inverseBindMatrices": inverse}));
        node["skin"] = json!(0);
    }
    nodes.push(node);
    let roots: Vec<usize> = (0..a.joints.len()).filter(|&j| a.joints[j].parent.is_none()).chain([mesh_node]).collect();
    let mut animations = Vec::new();
    for c in &a.clips {
        let times: Vec<[f32; 1]> = c.times.iter().map(|t| [*t]).collect();
        let input = b.floats(&times, "SCALAR", true);
        let output = b.floats(&c.rotations, "VEC4", false);
        animations.push(json!({
            "name": c.name,
            "samplers": [{"input": input, "output": output, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": c.joint, "path": "rotation"}}],
        }));
    }
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "skinsim tests"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": [mesh],
        "buffers": [{"uri": format!("{name}.bin"), "byteLength": b.bin.len()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
    });
    if !skins.is_empty() {
        doc["skins"] = json!(skins);
    }
    if !animations.is_empty() {
        doc["animations"] = json!(animations);
    }
    std::fs::write(dir.join(format!("{name}.bin")), &b.bin).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// An open cylinder along the glTF x axis (radius r, length l, `arc` radians of it centred on
/// glTF +Y; `around` x `along` quads, each split in two), its UVs the unrolled surface in metres
/// (x, r x angle: length-true). Returns positions, UVs and triangle indices; with arc = 2 pi the
/// seam's vertices are duplicated (one island cut open along the seam).
pub fn cylinder(r: f32, l: f32, around: u32, along: u32, arc: f32) -> (Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u32>) {
    let (mut p, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..=along {
        let x = -0.5 * l + l * i as f32 / along as f32;
        for j in 0..=around {
            let t = -0.5 * arc + arc * j as f32 / around as f32;
            // glTF +Y up: the cylinder's top (t = 0) faces +Y. A full circle's last column is its
            // first, bit for bit, so that the loader welds the seam (its angles -pi and pi have
            // sines of opposite signs in f32, +-8.7e-8, not 0).
            let full = (arc - std::f32::consts::TAU).abs() <= 1e-6;
            let at = if full && j == around { -0.5 * arc } else { t };
            p.push([x, r * at.cos(), r * at.sin()]);
            uv.push([x, r * t]);
        }
    }
    let w = around + 1;
    for i in 0..along {
        for j in 0..around {
            let v = |di: u32, dj: u32| (i + di) * w + j + dj;
            if (i + j) % 2 == 0 {
                idx.extend([v(0, 0), v(0, 1), v(1, 1), v(0, 0), v(1, 1), v(1, 0)]);
            } else {
                idx.extend([v(0, 0), v(0, 1), v(1, 0), v(0, 1), v(1, 1), v(1, 0)]);
            }
        }
    }
    (p, uv, idx)
}
