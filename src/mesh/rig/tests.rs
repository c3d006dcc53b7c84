//! Tests on small glTF assets written here by hand (JSON plus little-endian f32 buffers), so every
//! expected number is known from what was written. Expected poses are computed with the test's own
//! 4x4 arithmetic from the f32-rounded values as stored, never with the module's functions.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DQuat, DVec2, DVec3};
use serde_json::{json, Value};

use super::*;

// ---------------------------------------------------------------------------------------------
// A minimal glTF writer

/// Accessors and buffer views over one binary buffer.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

fn components(ty: &str) -> usize {
    match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT4" => 16,
        _ => panic!("type {ty}"),
    }
}

impl Builder {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn push(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// An f32 accessor with min/max (NaN skipped), which glTF requires for POSITION.
    fn floats(&mut self, data: &[f32], ty: &str) -> usize {
        let n = components(ty);
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let bound = |pick: fn(f32, f32) -> f32| -> Vec<f32> {
            (0..n)
                .map(|c| data.iter().skip(c).step_by(n).filter(|x| x.is_finite()).copied().reduce(pick).unwrap_or(0.0))
                .collect()
        };
        let (min, max) = (bound(f32::min), bound(f32::max));
        let count = data.len() / n;
        self.push(
            json!({"bufferView": view, "componentType": 5126, "count": count, "type": ty, "min": min, "max": max}),
        )
    }

    fn u16s(&mut self, data: &[u16], ty: &str) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.push(json!({"bufferView": view, "componentType": 5123, "count": data.len() / components(ty), "type": ty}))
    }

    fn u8s(&mut self, data: &[u8], ty: &str) -> usize {
        let view = self.view(data);
        self.push(json!({"bufferView": view, "componentType": 5121, "count": data.len() / components(ty), "type": ty}))
    }

    /// A sparse VEC3 f32 accessor of `count` elements: zeros (no `bufferView`) or `base`, with
    /// `values` at the u8 `indices`.
    fn sparse_vec3(&mut self, count: usize, base: Option<&[f32]>, indices: &[u8], values: &[f32]) -> usize {
        let index_view = self.view(indices);
        let value_bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let value_view = self.view(&value_bytes);
        let mut acc = json!({
            "componentType": 5126, "count": count, "type": "VEC3",
            "sparse": {"count": indices.len(),
                       "indices": {"bufferView": index_view, "componentType": 5121},
                       "values": {"bufferView": value_view}},
        });
        if let Some(base) = base {
            let bytes: Vec<u8> = base.iter().flat_map(|x| x.to_le_bytes()).collect();
            acc["bufferView"] = json!(self.view(&bytes));
            // POSITION needs bounds; these cover base and values.
            let all: Vec<f32> = base.iter().chain(values).copied().collect();
            let b = |pick: fn(f32, f32) -> f32| -> Vec<f32> {
                (0..3).map(|c| all.iter().skip(c).step_by(3).copied().reduce(pick).unwrap_or(0.0)).collect()
            };
            acc["min"] = json!(b(f32::min));
            acc["max"] = json!(b(f32::max));
        }
        self.push(acc)
    }

    fn document(&self, rest: Value) -> Value {
        let mut doc = rest;
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([{"byteLength": self.bin.len()}]);
        doc["bufferViews"] = Value::Array(self.views.clone());
        doc["accessors"] = Value::Array(self.accessors.clone());
        doc
    }
}

fn temp_dir(tag: &str) -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("skinsim_rig_{tag}_{}_{n}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Writes `<name>.gltf` with an external `<name>.bin`.
fn write_gltf(dir: &Path, name: &str, doc: &Value, bin: &[u8]) -> PathBuf {
    let mut doc = doc.clone();
    doc["buffers"][0]["uri"] = json!(format!("{name}.bin"));
    std::fs::write(dir.join(format!("{name}.bin")), bin).expect("write bin");
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).expect("json")).expect("write gltf");
    path
}

/// Writes `<name>.gltf` with the buffer as a base64 `data:` uri.
fn write_gltf_data_uri(dir: &Path, name: &str, doc: &Value, bin: &[u8]) -> PathBuf {
    let mut doc = doc.clone();
    doc["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{}", base64(bin)));
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write gltf");
    path
}

/// Writes a binary `<name>.glb` (JSON chunk, BIN chunk).
fn write_glb(dir: &Path, name: &str, doc: &Value, bin: &[u8]) -> PathBuf {
    let mut json_bytes = serde_json::to_vec(doc).expect("json");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    for word in [0x4654_6C67u32, 2, total as u32, json_bytes.len() as u32, 0x4E4F_534A] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json_bytes);
    for word in [bin.len() as u32, 0x004E_4942] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&bin);
    let path = dir.join(format!("{name}.glb"));
    std::fs::write(&path, out).expect("write glb");
    path
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            out.push(if i <= chunk.len() { ALPHABET[(n >> shift) as usize & 63] as char } else { '=' });
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The test rig: a strip of six quads along x, skinned to a chain root -> mid -> tip (1 m apart)
// plus three helper joints, with a UV seam at x = 1.5, two morph targets and two clips.

const ARMATURE: usize = 0;
const ROOT: usize = 1;
const MID: usize = 2;
const TIP: usize = 3;
const HELPER_A: usize = 4;
const HELPER_B: usize = 5;
const STRIP_NODE: usize = 7;

struct TestNode {
    name: &'static str,
    t: [f32; 3],
    r: [f32; 4],
    s: [f32; 3],
    children: Vec<usize>,
}

struct Strip {
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u16>,
    joints0: Vec<[u16; 4]>,
    weights0: Vec<[f32; 4]>,
    joints1: Vec<[u8; 4]>,
    weights1: Vec<[f32; 4]>,
    smile: Vec<[f32; 3]>,
    frown_indices: Vec<u8>,
    frown_values: Vec<[f32; 3]>,
    nodes: Vec<TestNode>,
    /// Skin joints (node indices) and their inverse bind matrices, pure translations.
    joints: Vec<usize>,
    ibm_translation: Vec<[f32; 3]>,
    /// Column-major matrix of the node carrying the unskinned mesh "rigid".
    rigid_matrix: [f32; 16],
    rigid_positions: Vec<[f32; 3]>,
}

fn unit_f32(q: [f32; 4]) -> [f32; 4] {
    let n = q.iter().map(|x| x * x).sum::<f32>().sqrt();
    q.map(|x| x / n)
}

/// f32 quaternion `[x, y, z, w]` for `degrees` about `axis`.
fn axis_angle_f32(axis: [f64; 3], degrees: f64) -> [f32; 4] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let (s, c) = (degrees.to_radians() / 2.0).sin_cos();
    [(axis[0] / n * s) as f32, (axis[1] / n * s) as f32, (axis[2] / n * s) as f32, c as f32]
}

/// glTF vertex of column `c` (x = 0.5 c) and row (y = -0.5, +0.5); column 3 exists twice, the
/// right-hand copy (vertices 14, 15) carrying the other UV island.
fn strip_vertex(c: usize, row: usize, right: bool) -> u16 {
    if c == 3 && right {
        (14 + row) as u16
    } else {
        (2 * c + row) as u16
    }
}

fn column_of(v: usize) -> usize {
    if v >= 14 {
        3
    } else {
        v / 2
    }
}

/// JOINTS_0, WEIGHTS_0, JOINTS_1, WEIGHTS_1 of one column of vertices.
type Column = ([u16; 4], [f32; 4], [u8; 4], [f32; 4]);

fn strip() -> Strip {
    let vertices: Vec<(usize, usize, bool)> =
        (0..7).flat_map(|c| (0..2).map(move |r| (c, r, c > 3))).chain([(3, 0, true), (3, 1, true)]).collect();
    let positions = vertices.iter().map(|&(c, r, _)| [0.5 * c as f32, r as f32 - 0.5, 0.05 * c as f32]).collect();
    let uvs = vertices
        .iter()
        .map(|&(c, r, right)| {
            if right {
                [(c as f32 - 3.0) / 6.0 + 0.5, 0.5 + 0.5 * r as f32]
            } else {
                [c as f32 / 6.0, 0.5 * r as f32]
            }
        })
        .collect();
    let mut indices = Vec::new();
    for c in 0..6 {
        let right = c >= 3;
        let (a, b) = (strip_vertex(c, 0, right), strip_vertex(c + 1, 0, right));
        let (cc, d) = (strip_vertex(c + 1, 1, right), strip_vertex(c, 1, right));
        indices.extend_from_slice(&[a, b, cc, a, cc, d]);
    }
    // Influences per column: one joint, two joints, and six (JOINTS_1) at the seam.
    let per_column: [Column; 7] = [
        ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0], [0; 4], [0.0; 4]),
        ([0, 1, 0, 0], [0.75, 0.25, 0.0, 0.0], [0; 4], [0.0; 4]),
        ([0, 1, 0, 0], [0.5, 0.5, 0.0, 0.0], [0; 4], [0.0; 4]),
        ([0, 1, 2, 3], [0.1, 0.2, 0.3, 0.15], [4, 5, 0, 0], [0.15, 0.1, 0.0, 0.0]),
        ([1, 2, 0, 0], [0.5, 0.5, 0.0, 0.0], [0; 4], [0.0; 4]),
        ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0], [0; 4], [0.0; 4]),
        ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0], [0; 4], [0.0; 4]),
    ];
    let column = |v: &(usize, usize, bool)| per_column[v.0];
    let smile = vertices.iter().map(|&(c, r, _)| [0.01 * c as f32, 0.02 * (r + 1) as f32, -0.03 * c as f32]).collect();
    let node = |name, t, r, children: Vec<usize>| TestNode { name, t, r, s: [1.0; 3], children };
    let id = [0.0, 0.0, 0.0, 1.0];
    Strip {
        positions,
        uvs,
        indices,
        joints0: vertices.iter().map(|v| column(v).0).collect(),
        weights0: vertices.iter().map(|v| column(v).1).collect(),
        joints1: vertices.iter().map(|v| column(v).2).collect(),
        weights1: vertices.iter().map(|v| column(v).3).collect(),
        smile,
        frown_indices: vec![1, 5, 9],
        frown_values: vec![[0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, -0.3]],
        nodes: vec![
            node("Armature", [0.1, -0.2, 0.3], unit_f32([0.1, 0.2, 0.3, 0.9]), vec![1, 7]),
            node("root", [0.0; 3], id, vec![2, 4]),
            node("mid", [1.0, 0.0, 0.0], id, vec![3, 5]),
            node("tip", [1.0, 0.0, 0.0], id, vec![6]),
            node("helper_a", [0.5, 0.5, 0.0], id, vec![]),
            node("helper_b", [0.5, -0.5, 0.0], id, vec![]),
            node("helper_c", [0.5, 0.0, 0.5], id, vec![]),
            // The skinned mesh's own transform, which skinning must ignore.
            node("strip_node", [5.0, 5.0, 5.0], id, vec![]),
        ],
        joints: vec![1, 2, 3, 4, 5, 6],
        ibm_translation: vec![
            [0.0; 3],
            [-1.0, 0.0, 0.0],
            [-2.0, 0.0, 0.0],
            [-0.5, -0.5, 0.0],
            [-1.5, 0.5, 0.0],
            [-2.5, 0.0, -0.5],
        ],
        rigid_matrix: [0.0, 2.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 2.0, 3.0, 1.0],
        rigid_positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.5], [0.0, 1.0, -0.25]],
    }
}

/// Keys of the clip "wave": every interpolation on some property.
struct Wave {
    rot_times: [f32; 3],
    rot: [[f32; 4]; 3],
    step_times: [f32; 3],
    step: [[f32; 3]; 3],
    cubic_times: [f32; 3],
    /// Per key: in-tangent, value, out-tangent.
    cubic: [[f32; 3]; 9],
    weight_times: [f32; 2],
    weights: [f32; 4],
    cubic_rot_times: [f32; 2],
    cubic_rot: [[f32; 4]; 6],
}

fn wave() -> Wave {
    let q1 = axis_angle_f32([0.0, 0.0, 1.0], 60.0);
    // Stored negated: dot(q1, q2) < 0, so LINEAR must flip it to take the shorter arc.
    let q2 = axis_angle_f32([1.0, 1.0, 0.0], 100.0).map(|x| -x);
    Wave {
        rot_times: [0.0, 1.0, 2.0],
        rot: [[0.0, 0.0, 0.0, 1.0], q1, q2],
        step_times: [0.0, 0.5, 1.5],
        step: [[1.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.2, 0.0, 0.1]],
        cubic_times: [0.5, 1.25, 2.5],
        cubic: [
            [0.3, -0.2, 0.1],
            [1.0, 1.0, 1.0],
            [0.5, 0.25, -0.5],
            [-0.4, 0.6, 0.2],
            [1.2, 0.9, 1.1],
            [0.7, -0.3, 0.05],
            [0.2, 0.2, 0.2],
            [0.8, 1.3, 1.0],
            [9.0, 9.0, 9.0],
        ],
        weight_times: [0.0, 2.0],
        weights: [0.0, 0.0, 1.0, 0.5],
        cubic_rot_times: [0.0, 1.0],
        cubic_rot: [
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.8, 0.1, -0.2, 0.0],
            [0.1, 0.3, 0.0, -0.2],
            axis_angle_f32([0.0, 1.0, 0.0], 70.0),
            [0.0, 0.0, 0.0, 0.0],
        ],
    }
}

fn flat<const N: usize, T: Copy>(v: &[[T; N]]) -> Vec<T> {
    v.iter().flatten().copied().collect()
}

/// The strip file as JSON and binary buffer. Accessor 0 is POSITION, 2 is JOINTS_0, 3 WEIGHTS_0.
fn build(s: &Strip) -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let pos = b.floats(&flat(&s.positions), "VEC3");
    let uv = b.floats(&flat(&s.uvs), "VEC2");
    let j0 = b.u16s(&flat(&s.joints0), "VEC4");
    let w0 = b.floats(&flat(&s.weights0), "VEC4");
    let j1 = b.u8s(&flat(&s.joints1), "VEC4");
    let w1 = b.floats(&flat(&s.weights1), "VEC4");
    let idx = b.u16s(&s.indices, "SCALAR");
    let smile = b.floats(&flat(&s.smile), "VEC3");
    let frown = b.sparse_vec3(s.positions.len(), None, &s.frown_indices, &flat(&s.frown_values));
    let ibm: Vec<f32> = s
        .ibm_translation
        .iter()
        .flat_map(|t| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t[0], t[1], t[2], 1.0])
        .collect();
    let ibm = b.floats(&ibm, "MAT4");
    let rigid = b.floats(&flat(&s.rigid_positions), "VEC3");
    let w = wave();
    let sampler = |b: &mut Builder, times: &[f32], values: &[f32], ty: &str, interpolation: &str| {
        let input = b.floats(times, "SCALAR");
        let output = b.floats(values, ty);
        json!({"input": input, "output": output, "interpolation": interpolation})
    };
    let samplers = vec![
        sampler(&mut b, &w.rot_times, &flat(&w.rot), "VEC4", "LINEAR"),
        sampler(&mut b, &w.step_times, &flat(&w.step), "VEC3", "STEP"),
        sampler(&mut b, &w.cubic_times, &flat(&w.cubic), "VEC3", "CUBICSPLINE"),
        sampler(&mut b, &w.weight_times, &w.weights, "SCALAR", "LINEAR"),
        sampler(&mut b, &w.cubic_rot_times, &flat(&w.cubic_rot), "VEC4", "CUBICSPLINE"),
    ];
    let idle = sampler(&mut b, &[0.0], &[0.0, 0.0, 0.0], "VEC3", "STEP");
    let mut nodes: Vec<Value> = s
        .nodes
        .iter()
        .map(|n| {
            let mut v = json!({"name": n.name, "translation": n.t, "rotation": n.r, "scale": n.s});
            if !n.children.is_empty() {
                v["children"] = json!(n.children);
            }
            v
        })
        .collect();
    nodes[STRIP_NODE]["mesh"] = json!(0);
    nodes[STRIP_NODE]["skin"] = json!(0);
    nodes.push(json!({"name": "rigid_node", "matrix": s.rigid_matrix, "mesh": 1}));
    let channel =
        |sampler: usize, node: usize, path: &str| json!({"sampler": sampler, "target": {"node": node, "path": path}});
    let doc = b.document(json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 8]}],
        "nodes": nodes,
        "meshes": [
            {"name": "strip",
             "primitives": [{
                "attributes": {"POSITION": pos, "TEXCOORD_0": uv,
                               "JOINTS_0": j0, "WEIGHTS_0": w0, "JOINTS_1": j1, "WEIGHTS_1": w1},
                "indices": idx,
                "targets": [{"POSITION": smile}, {"POSITION": frown}]}],
             "weights": [0.25, 0.5],
             "extras": {"targetNames": ["smile", "frown"]}},
            {"name": "rigid", "primitives": [{"attributes": {"POSITION": rigid}}]}
        ],
        "skins": [{"name": "Armature", "joints": s.joints, "inverseBindMatrices": ibm, "skeleton": 1}],
        "animations": [
            {"name": "wave", "samplers": samplers, "channels": [
                channel(0, MID, "rotation"), channel(1, TIP, "translation"), channel(2, ROOT, "scale"),
                channel(3, STRIP_NODE, "weights"), channel(4, HELPER_A, "rotation")]},
            {"name": "idle", "samplers": [idle], "channels": [channel(0, ROOT, "translation")]}
        ]
    }));
    (doc, b.bin)
}

fn load_strip(tag: &str, s: &Strip) -> Result<Asset, RigError> {
    let (doc, bin) = build(s);
    Asset::load_mesh(write_gltf(&temp_dir(tag), "strip", &doc, &bin), Some("strip"))
}

// ---------------------------------------------------------------------------------------------
// Independent arithmetic: row-major 4x4 matrices on plain arrays

type M4 = [[f64; 4]; 4];

fn mat_mul(a: &M4, b: &M4) -> M4 {
    let mut m = [[0.0; 4]; 4];
    for (r, row) in m.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    m
}

fn mat_trs(t: [f64; 3], q: [f64; 4], s: [f64; 3]) -> M4 {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let [x, y, z, w] = q.map(|c| c / n);
    let r = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ];
    let mut m = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = r[i][j] * s[j];
        }
        m[i][3] = t[i];
    }
    m
}

fn apply(m: &M4, p: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (i, o) in out.iter_mut().enumerate() {
        *o = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
    }
    out
}

fn f64s<const N: usize>(a: [f32; N]) -> [f64; N] {
    a.map(f64::from)
}

fn dist(a: DVec3, b: [f64; 3]) -> f64 {
    (a - DVec3::from_array(b)).length()
}

/// Local TRS per node (f64 from the stored f32) for the test's own hierarchy walk.
type Locals = Vec<([f64; 3], [f64; 4], [f64; 3])>;

fn file_locals(s: &Strip) -> Locals {
    s.nodes.iter().map(|n| (f64s(n.t), f64s(n.r), f64s(n.s))).collect()
}

fn globals_of(s: &Strip, locals: &Locals) -> Vec<M4> {
    let mut parent = vec![None; s.nodes.len()];
    for (p, n) in s.nodes.iter().enumerate() {
        for &c in &n.children {
            parent[c] = Some(p);
        }
    }
    fn global(n: usize, parent: &[Option<usize>], locals: &Locals) -> M4 {
        let (t, q, s) = locals[n];
        let local = mat_trs(t, q, s);
        match parent[n] {
            Some(p) => mat_mul(&global(p, parent, locals), &local),
            None => local,
        }
    }
    (0..s.nodes.len()).map(|n| global(n, &parent, locals)).collect()
}

/// Expected LBS position of each glTF vertex under `locals` and morph `weights`.
fn expected_lbs(s: &Strip, locals: &Locals, weights: [f64; 2]) -> Vec<[f64; 3]> {
    let globals = globals_of(s, locals);
    let mut frown = vec![[0.0f64; 3]; s.positions.len()];
    for (&i, v) in s.frown_indices.iter().zip(&s.frown_values) {
        frown[i as usize] = f64s(*v);
    }
    (0..s.positions.len())
        .map(|v| {
            let p = f64s(s.positions[v]);
            let d1 = f64s(s.smile[v]);
            let x: [f64; 3] = std::array::from_fn(|i| p[i] + weights[0] * d1[i] + weights[1] * frown[v][i]);
            let pairs: Vec<(usize, f64)> = s.joints0[v]
                .iter()
                .map(|&j| j as usize)
                .zip(f64s(s.weights0[v]))
                .chain(s.joints1[v].iter().map(|&j| j as usize).zip(f64s(s.weights1[v])))
                .collect();
            let total: f64 = pairs.iter().map(|p| p.1).sum();
            let mut out = [0.0; 3];
            for (j, w) in pairs {
                let t = f64s(s.ibm_translation[j]);
                let ibm = mat_trs(t, [0.0, 0.0, 0.0, 1.0], [1.0; 3]);
                let y = apply(&mat_mul(&globals[s.joints[j]], &ibm), x);
                (0..3).for_each(|i| out[i] += w / total * y[i]);
            }
            out
        })
        .collect()
}

fn to_pose(asset: &Asset, locals: &Locals, weights: &[f64]) -> Pose {
    let mut pose = asset.rest_pose();
    for (n, (t, q, s)) in locals.iter().enumerate() {
        pose.locals[n] = Trs::new(DVec3::from_array(*t), DQuat::from_array(*q).normalize(), DVec3::from_array(*s));
    }
    pose.morph_weights = weights.to_vec();
    pose
}

/// A general pose: a bent and scaled chain, a moved helper.
fn bent_locals(s: &Strip) -> Locals {
    let mut locals = file_locals(s);
    locals[MID] = ([1.0, 0.05, 0.0], [0.2, -0.1, 0.4, 0.85], [1.0; 3]);
    locals[TIP].2 = [1.1, 0.9, 1.2];
    locals[HELPER_B].0 = [0.6, -0.4, 0.1];
    locals
}

/// Size of the strip (m), the scale for "relative to size" tolerances.
const SIZE: f64 = 3.0;

// ---------------------------------------------------------------------------------------------
// Reading

#[test]
fn reads_hierarchy_skin_morphs_and_names() {
    let s = strip();
    let asset = load_strip("read", &s).expect("load");
    assert!(asset.warnings.is_empty(), "{:?}", asset.warnings);
    assert_eq!(asset.mesh_name, "strip");
    assert_eq!(asset.mesh_node, Some(STRIP_NODE));
    assert_eq!(asset.nodes.len(), 9);
    assert_eq!(asset.nodes[MID].parent, Some(ROOT));
    assert_eq!(asset.nodes[ROOT].parent, Some(ARMATURE));
    assert_eq!(asset.nodes[8].name, "rigid_node");
    let skin = asset.skin.as_ref().expect("skin");
    assert_eq!(skin.joint_names, ["root", "mid", "tip", "helper_a", "helper_b", "helper_c"]);
    assert_eq!(skin.inverse_bind[2].w_axis.truncate(), DVec3::new(-2.0, 0.0, 0.0));
    assert_eq!(asset.joint_index("mid"), Some(1));
    assert_eq!(asset.joint_index("Armature"), None);
    assert_eq!(asset.morph_index("frown"), Some(1));
    assert_eq!(asset.default_morph_weights, [0.25, 0.5]);
    assert_eq!(asset.rest_pose().morph_weights, [0.25, 0.5]);
    assert_eq!(asset.clips(), ["wave", "idle"]);
    // The armature rotation is renormalised in f64.
    let q = asset.nodes[ARMATURE].rest.rotation;
    assert!((q.length() - 1.0).abs() < 1e-15);
    // Six influences at the seam column, via JOINTS_1, normalised.
    let (joints, weights) = asset.influences.of(asset.weld[6] as usize);
    assert_eq!(joints, [0, 1, 2, 3, 4, 5]);
    assert!((weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    let (joints, weights) = asset.influences.of(asset.weld[2] as usize);
    assert_eq!((joints, weights), (&[0u32, 1][..], &[0.75, 0.25][..]));
}

#[test]
fn sparse_morph_target_reads_zeros_and_substitutions() {
    let s = strip();
    let asset = load_strip("sparse", &s).expect("load");
    let frown = &asset.morphs[asset.morph("frown").expect("frown")];
    for v in 0..s.positions.len() {
        let expected = match s.frown_indices.iter().position(|&i| i as usize == v) {
            Some(k) => DVec3::from_array(f64s(s.frown_values[k])),
            None => DVec3::ZERO,
        };
        assert_eq!(frown.deltas[asset.weld[v] as usize], expected, "vertex {v}");
    }
    let smile = &asset.morphs[0];
    assert_eq!(smile.name, "smile");
    assert_eq!(smile.deltas[asset.weld[13] as usize], DVec3::from_array(f64s(s.smile[13])));
}

#[test]
fn seam_welds_and_keeps_both_uvs_per_corner() {
    let s = strip();
    let asset = load_strip("seam", &s).expect("load");
    assert_eq!(asset.positions.len(), 16);
    assert_eq!(asset.rest.len(), 14);
    assert_eq!(asset.weld[14], asset.weld[6]);
    assert_eq!(asset.weld[15], asset.weld[7]);
    assert_eq!(asset.welded_faces.len(), 12);
    let corner_uv = asset.corner_uv().expect("uvs");
    let seam_bottom = asset.weld[6];
    let uv_at = |f: usize| {
        let k = asset.welded_faces[f].iter().position(|&w| w == seam_bottom).expect("corner at the seam");
        corner_uv[f][k]
    };
    // Face 4 is the quad left of the seam, face 6 the one right of it.
    assert_eq!(uv_at(4), DVec2::new(f64::from(s.uvs[6][0]), f64::from(s.uvs[6][1])));
    assert_eq!(uv_at(6), DVec2::new(f64::from(s.uvs[14][0]), f64::from(s.uvs[14][1])));
    assert_ne!(uv_at(4), uv_at(6));

    // Same position but other joint influences: the copies stay apart (they would move apart).
    let mut s = strip();
    s.weights0[14] = [0.1, 0.2, 0.3, 0.2];
    let asset = load_strip("seam_influences", &s).expect("load");
    assert_eq!(asset.rest.len(), 15);
    assert_ne!(asset.weld[14], asset.weld[6]);
    assert_eq!(asset.weld[15], asset.weld[7]);
}

/// A one-mesh file: a quad with a seam, POSITION sparse over a base view, buffer as a data: uri,
/// also written as .glb; all three load the same.
#[test]
fn single_mesh_file_with_sparse_positions_data_uri_and_glb() {
    let base: Vec<f32> = vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 9.0, 9.0, 9.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0];
    // Vertex 3 is really (0, 0, 0) (a seam copy of vertex 0); vertex 5 a copy of vertex 1.
    let mut b = Builder::default();
    let pos = b.sparse_vec3(6, Some(&base), &[3], &[0.0, 0.0, 0.0]);
    let uv = b.floats(&[0.0, 0.0, 0.5, 0.0, 0.5, 0.5, 1.0, 0.0, 0.0, 0.5, 0.7, 0.1], "VEC2");
    let idx = b.u16s(&[0, 1, 2, 3, 2, 4, 5, 2, 3], "SCALAR");
    let doc = b.document(json!({
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx}]}]
    }));
    let dir = temp_dir("single");
    let loads = [
        Asset::load(write_gltf(&dir, "quad", &doc, &b.bin)),
        Asset::load(write_gltf_data_uri(&dir, "quad_data", &doc, &b.bin)),
        Asset::load(write_glb(&dir, "quad", &doc, &b.bin)),
    ];
    for asset in loads {
        let asset = asset.expect("load");
        assert_eq!(asset.mesh_name, "mesh_0");
        assert_eq!(asset.positions[3], DVec3::ZERO);
        assert_eq!(asset.rest.len(), 4);
        assert_eq!(asset.weld, [0, 1, 2, 0, 3, 1]);
        assert_eq!(asset.welded_faces, [[0, 1, 2], [0, 2, 3], [1, 2, 0]]);
        let uv = asset.corner_uv().expect("uv");
        assert_eq!(uv[0][0], DVec2::new(0.0, 0.0));
        assert_eq!(uv[1][0], DVec2::new(1.0, 0.0));
        assert_eq!(asset.uv().expect("uv").len(), 6);
        // No skin and no node transform: the rest pose is the rest.
        assert_eq!(asset.pose_positions(&asset.rest_pose(), Skinning::Linear).expect("pose"), asset.rest);
    }
}

// ---------------------------------------------------------------------------------------------
// Skinning

#[test]
fn linear_blend_and_morphs_match_independent_computation() {
    let s = strip();
    let asset = load_strip("lbs", &s).expect("load");
    for (locals, weights) in [(file_locals(&s), [0.25, 0.5]), (bent_locals(&s), [0.3, -0.7])] {
        let pose = to_pose(&asset, &locals, &weights);
        let got = asset.pose_positions(&pose, Skinning::Linear).expect("pose");
        let expected = expected_lbs(&s, &locals, weights);
        for (v, e) in expected.iter().enumerate() {
            let d = dist(got[asset.weld[v] as usize], *e);
            assert!(d <= 1e-12 * SIZE, "vertex {v}: off by {d:e}");
        }
    }
    // The rest pose read from the file equals the file's own values.
    let got = asset.pose_positions(&asset.rest_pose(), Skinning::Linear).expect("pose");
    let expected = expected_lbs(&s, &file_locals(&s), [0.25, 0.5]);
    assert!(expected.iter().enumerate().all(|(v, e)| dist(got[asset.weld[v] as usize], *e) <= 1e-12 * SIZE));
}

#[test]
fn unskinned_mesh_follows_its_node_matrix() {
    let s = strip();
    let (doc, bin) = build(&s);
    let path = write_gltf(&temp_dir("rigid"), "strip", &doc, &bin);
    let err = Asset::load(&path).expect_err("two meshes").to_string();
    assert!(err.contains("\"strip\"") && err.contains("\"rigid\""), "{err}");
    let asset = Asset::load_mesh(&path, Some("rigid")).expect("load");
    assert!(asset.skin.is_none());
    let m: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|c| f64::from(s.rigid_matrix[4 * c + r])));
    for skinning in [Skinning::Linear, Skinning::DualQuaternion] {
        let got = asset.pose_positions(&asset.rest_pose(), skinning).expect("pose");
        for (g, p) in got.iter().zip(&s.rigid_positions) {
            assert!(dist(*g, apply(&m, f64s(*p))) <= 1e-14, "{g} vs {p:?}");
        }
    }
    let err = asset.uv().expect_err("no uv").to_string();
    assert!(err.contains("TEXCOORD_0") && err.contains("\"rigid\"") && err.contains("primitive 0"), "{err}");
    let err = Asset::load_mesh(&path, Some("nope")).expect_err("unknown mesh").to_string();
    assert!(err.contains("\"rigid\""), "{err}");
}

#[test]
fn dual_quaternion_equals_linear_for_single_influences_and_rigid_motion() {
    let s = strip();
    let asset = load_strip("dqs", &s).expect("load");
    // Rotated joints, no scale: single-influence vertices (columns 0, 5, 6) agree.
    let mut locals = file_locals(&s);
    locals[ROOT].1 = [0.1, 0.3, -0.2, 0.9];
    locals[MID] = ([1.0, 0.1, 0.0], [0.3, -0.1, 0.4, 0.8], [1.0; 3]);
    locals[TIP].1 = [-0.2, 0.5, 0.1, 0.7];
    let pose = to_pose(&asset, &locals, &[0.4, 0.2]);
    let lbs = asset.pose_positions(&pose, Skinning::Linear).expect("lbs");
    let dqs = asset.pose_positions(&pose, Skinning::DualQuaternion).expect("dqs");
    let mut differ = 0;
    for v in 0..s.positions.len() {
        let w = asset.weld[v] as usize;
        let d = (lbs[w] - dqs[w]).length();
        if [0, 5, 6].contains(&column_of(v)) {
            assert!(d <= 1e-12 * SIZE, "vertex {v}: {d:e}");
        } else if d > 1e-6 {
            differ += 1;
        }
    }
    assert!(differ > 0, "blended vertices should differ between LBS and DQS in a bent pose");
    // The whole skeleton moved rigidly (only the armature root): every vertex agrees.
    let mut locals = file_locals(&s);
    locals[ARMATURE] = ([0.3, -1.0, 2.0], [-0.4, 0.2, 0.7, 0.5], [1.0; 3]);
    let pose = to_pose(&asset, &locals, &[0.0, 0.0]);
    let lbs = asset.pose_positions(&pose, Skinning::Linear).expect("lbs");
    let dqs = asset.pose_positions(&pose, Skinning::DualQuaternion).expect("dqs");
    for (a, b) in lbs.iter().zip(&dqs) {
        assert!((*a - *b).length() <= 1e-12 * SIZE, "{a} vs {b}");
    }
}

#[test]
fn dual_quaternion_keeps_twist_radius_where_linear_blend_collapses() {
    let s = strip();
    let asset = load_strip("twist", &s).expect("load");
    let mut pose = asset.rest_pose();
    pose.locals[ARMATURE] = Trs::IDENTITY;
    pose.morph_weights = vec![0.0, 0.0];
    pose.locals[MID].rotation = rotation_about(DVec3::X, 90.0).expect("axis");
    let lbs = asset.pose_positions(&pose, Skinning::Linear).expect("lbs");
    let dqs = asset.pose_positions(&pose, Skinning::DualQuaternion).expect("dqs");
    // Column 2 (x = 1) is weighted half root, half mid: the twist is shared.
    for v in [4, 5] {
        let p = f64s(s.positions[v]);
        let radius = p[1].hypot(p[2]);
        let w = asset.weld[v] as usize;
        let (l, d) = (lbs[w], dqs[w]);
        assert!((d.y.hypot(d.z) - radius).abs() < 1e-12, "DQS radius {} vs {radius}", d.y.hypot(d.z));
        assert!((d.x - p[0]).abs() < 1e-12);
        let expected_lbs = radius * std::f64::consts::FRAC_1_SQRT_2;
        assert!((l.y.hypot(l.z) - expected_lbs).abs() < 1e-12, "LBS radius {}", l.y.hypot(l.z));
        // The DQS point is the rest point turned 45 degrees about x.
        let q = DQuat::from_axis_angle(DVec3::X, std::f64::consts::FRAC_PI_4);
        assert!((d - q * DVec3::from_array(p)).length() < 1e-12);
    }
}

/// A rotation past 180 degrees: its quaternion may come out in the other hemisphere from the
/// root's; DLB must still take the shorter way (-170 degrees, so -85 at the half-way vertex).
#[test]
fn dual_quaternion_twist_past_half_turn_takes_the_shorter_way() {
    let s = strip();
    let asset = load_strip("twist190", &s).expect("load");
    let mut pose = asset.rest_pose();
    pose.locals[ARMATURE] = Trs::IDENTITY;
    pose.morph_weights = vec![0.0, 0.0];
    pose.locals[MID].rotation = rotation_about(DVec3::X, 190.0).expect("axis");
    let dqs = asset.pose_positions(&pose, Skinning::DualQuaternion).expect("dqs");
    let q = DQuat::from_axis_angle(DVec3::X, (-85.0f64).to_radians());
    for v in [4, 5] {
        let p = DVec3::from_array(f64s(s.positions[v]));
        assert!((dqs[asset.weld[v] as usize] - q * p).length() < 1e-12, "vertex {v}");
    }
}

/// Sign alignment directly: a joint given as -q (the same rotation) must blend as q.
#[test]
fn dual_quaternion_blend_aligns_signs_to_the_first_influence() {
    let q = DQuat::from_axis_angle(DVec3::X, std::f64::consts::FRAC_PI_2);
    let t = DVec3::new(0.0, 0.2, -0.1);
    let a = DualQuat::from_rotation_translation(DQuat::IDENTITY, DVec3::ZERO);
    let b = DualQuat::from_rotation_translation(q, t);
    let b_negated = DualQuat { real: -b.real, dual: -b.dual };
    let p = DVec3::new(0.3, 0.5, 0.1);
    let plain = skin::dual_quat_blend(p, &[0, 1], &[0.5, 0.5], &[a, b]);
    let negated = skin::dual_quat_blend(p, &[0, 1], &[0.5, 0.5], &[a, b_negated]);
    assert!((plain - negated).length() < 1e-15, "{plain} vs {negated}");
    // And b alone applies R p + t.
    assert!((skin::dual_quat_blend(p, &[1], &[1.0], &[a, b_negated]) - (q * p + t)).length() < 1e-15);
}

#[test]
fn dual_quaternion_refuses_scaled_joints() {
    let s = strip();
    let asset = load_strip("dqs_scale", &s).expect("load");
    let mut pose = asset.rest_pose();
    pose.locals[MID].scale = DVec3::new(1.0, 1.0, 1.0 + 1e-6);
    assert!(asset.pose_positions(&pose, Skinning::Linear).is_ok());
    match asset.pose_positions(&pose, Skinning::DualQuaternion) {
        Err(RigError::NotRigid { joint, .. }) => assert_eq!(joint, "mid"),
        other => panic!("expected NotRigid, got {other:?}"),
    }
    // The clip "wave" scales the root with a CUBICSPLINE channel.
    let mut pose = asset.rest_pose();
    asset.clip("wave").expect("wave").sample(1.0, &mut pose).expect("sample");
    let err = asset.pose_positions(&pose, Skinning::DualQuaternion).expect_err("scaled root").to_string();
    assert!(err.contains("\"root\""), "{err}");
}

#[test]
fn pose_of_wrong_size_is_refused() {
    let asset = load_strip("pose_size", &strip()).expect("load");
    let mut pose = asset.rest_pose();
    pose.morph_weights.pop();
    assert!(matches!(asset.pose_positions(&pose, Skinning::Linear), Err(RigError::PoseMismatch(_))));
    let mut pose = asset.rest_pose();
    pose.locals.pop();
    assert!(matches!(asset.clip("wave").expect("wave").sample(0.5, &mut pose), Err(RigError::PoseMismatch(_))));
    assert!(matches!(rotation_about(DVec3::ZERO, 10.0), Err(RigError::BadAxis(_))));
}

// ---------------------------------------------------------------------------------------------
// Animation

fn q64(q: [f32; 4]) -> [f64; 4] {
    let q = f64s(q);
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    q.map(|x| x / n)
}

/// The spec's slerp, written out: shorter arc, acos of the dot product.
fn hand_slerp(a: [f64; 4], b: [f64; 4], s: f64) -> [f64; 4] {
    let mut dot: f64 = (0..4).map(|i| a[i] * b[i]).sum();
    let b = if dot < 0.0 {
        dot = -dot;
        b.map(|x| -x)
    } else {
        b
    };
    let theta = dot.acos();
    let (wa, wb) = (((1.0 - s) * theta).sin() / theta.sin(), (s * theta).sin() / theta.sin());
    std::array::from_fn(|i| wa * a[i] + wb * b[i])
}

/// The spec's cubic Hermite for one component, tangents scaled by the key interval.
fn hand_hermite(t: f64, t0: f64, t1: f64, v0: f64, out0: f64, in1: f64, v1: f64) -> f64 {
    let td = t1 - t0;
    let s = (t - t0) / td;
    (2.0 * s.powi(3) - 3.0 * s * s + 1.0) * v0
        + td * (s.powi(3) - 2.0 * s * s + s) * out0
        + (-2.0 * s.powi(3) + 3.0 * s * s) * v1
        + td * (s.powi(3) - s * s) * in1
}

fn same_rotation(q: DQuat, e: [f64; 4], tol: f64) -> bool {
    let d = (0..4).map(|i| (q.to_array()[i] - e[i]).abs()).fold(0.0, f64::max);
    d <= tol
}

#[test]
fn clip_sampling_follows_the_spec() {
    let s = strip();
    let w = wave();
    let asset = load_strip("anim", &s).expect("load");
    let clip = asset.clip("wave").expect("wave");
    assert_eq!(clip.duration(), 2.5);
    let at = |t: f64| {
        let mut pose = asset.rest_pose();
        clip.sample(t, &mut pose).expect("sample");
        pose
    };
    let v3 = |a: [f32; 3]| DVec3::from_array(f64s(a));

    // STEP holds each key until the next; clamped at both ends.
    for (t, k) in [(-1.0, 0), (0.0, 0), (0.49, 0), (0.5, 1), (1.49, 1), (1.5, 2), (7.0, 2)] {
        assert_eq!(at(t).locals[TIP].translation, v3(w.step[k]), "t = {t}");
    }

    // LINEAR rotation: slerp, and the shorter arc when the stored keys point apart.
    let (q0, q1, q2) = (q64(w.rot[0]), q64(w.rot[1]), q64(w.rot[2]));
    for (t, e) in [(0.3, hand_slerp(q0, q1, 0.3)), (1.6, hand_slerp(q1, q2, 0.6)), (-2.0, q0), (3.0, q2)] {
        let got = at(t).locals[MID].rotation;
        assert!(same_rotation(got, e, 1e-12), "t = {t}: {got:?} vs {e:?}");
    }
    let naive: [f64; 4] = std::array::from_fn(|i| 0.4 * q1[i] + 0.6 * q2[i]);
    assert!(naive.iter().zip(at(1.6).locals[MID].rotation.to_array()).any(|(a, b)| (a - b).abs() > 0.1));

    // LINEAR weights.
    assert_eq!(at(0.5).morph_weights, [0.25, 0.125]);
    assert_eq!(at(5.0).morph_weights, [1.0, 0.5]);

    // CUBICSPLINE scale: Hermite with tangents times the interval; clamps to values, not tangents.
    let c = |k: usize, part: usize| f64s(w.cubic[3 * k + part]);
    let times = f64s(w.cubic_times);
    for (t, k) in [(0.8, 0), (1.25, 1), (2.0, 1), (2.49, 1)] {
        let got = at(t).locals[ROOT].scale;
        for i in 0..3 {
            let e = hand_hermite(t, times[k], times[k + 1], c(k, 1)[i], c(k, 2)[i], c(k + 1, 0)[i], c(k + 1, 1)[i]);
            assert!((got[i] - e).abs() < 1e-12, "t = {t}, component {i}: {} vs {e}", got[i]);
        }
    }
    assert_eq!(at(0.1).locals[ROOT].scale, v3(w.cubic[1]));
    assert_eq!(at(4.0).locals[ROOT].scale, v3(w.cubic[7]));

    // CUBICSPLINE rotation: Hermite per component, then normalised.
    let r = |k: usize| f64s(w.cubic_rot[k]);
    let raw: [f64; 4] = std::array::from_fn(|i| hand_hermite(0.4, 0.0, 1.0, r(1)[i], r(2)[i], r(3)[i], r(4)[i]));
    let n = raw.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(same_rotation(at(0.4).locals[HELPER_A].rotation, raw.map(|x| x / n), 1e-12));

    // Untouched properties keep the pose's values.
    assert_eq!(at(0.7).locals[HELPER_B], asset.rest_pose().locals[HELPER_B]);
    assert!(matches!(clip.sample(f64::NAN, &mut asset.rest_pose()), Err(RigError::BadTime { .. })));
}

// ---------------------------------------------------------------------------------------------
// Bad input: each error names what is wrong

fn load_err(tag: &str, s: &Strip) -> String {
    load_strip(tag, s).expect_err("should fail").to_string()
}

#[test]
fn missing_buffer_file_is_named() {
    let (doc, bin) = build(&strip());
    let dir = temp_dir("missing_bin");
    let path = write_gltf(&dir, "strip", &doc, &bin);
    std::fs::remove_file(dir.join("strip.bin")).expect("remove");
    let err = Asset::load_mesh(&path, Some("strip")).expect_err("no bin");
    assert!(matches!(err, RigError::MissingBufferFile { .. }));
    assert!(err.to_string().contains("strip.bin"), "{err}");
    let err = Asset::load(dir.join("absent.gltf")).expect_err("no gltf").to_string();
    assert!(err.contains("absent.gltf"), "{err}");
}

#[test]
fn nan_position_is_refused_naming_the_accessor() {
    let mut s = strip();
    s.positions[3][1] = f32::NAN;
    let err = load_err("nan", &s);
    assert!(err.contains("accessor 0 (POSITION of mesh \"strip\", primitive 0)"), "{err}");
    assert!(err.contains("element 3"), "{err}");
}

#[test]
fn joint_index_out_of_range_is_refused() {
    let mut s = strip();
    s.joints0[5][1] = 9;
    let err = load_err("joint_range", &s);
    assert!(err.contains("accessor 2 (JOINTS_0 of mesh \"strip\", primitive 0)"), "{err}");
    assert!(err.contains("joint 9") && err.contains("6 joints"), "{err}");
}

#[test]
fn zero_weight_vertex_is_refused() {
    let mut s = strip();
    s.weights0[4] = [0.0; 4];
    let err = load_err("zero_weight", &s);
    assert!(err.contains("accessor 3 (WEIGHTS_0 of mesh \"strip\", primitive 0)"), "{err}");
    assert!(err.contains("vertex 4"), "{err}");
}

#[test]
fn weights_not_summing_to_one_are_normalised_with_one_warning() {
    let mut s = strip();
    s.weights0[0] = [0.9, 0.0, 0.0, 0.0];
    s.weights0[8] = [0.45, 0.45, 0.0, 0.0];
    let asset = load_strip("weights_09", &s).expect("load");
    assert_eq!(asset.warnings.len(), 1, "{:?}", asset.warnings);
    assert!(asset.warnings[0].contains("2 vertices") && asset.warnings[0].contains("0.9"), "{:?}", asset.warnings);
    assert_eq!(asset.influences.of(asset.weld[0] as usize).1, [1.0]);
    assert_eq!(asset.influences.of(asset.weld[8] as usize).1, [0.5, 0.5]);
}

#[test]
fn non_triangle_mode_is_refused() {
    let (mut doc, bin) = build(&strip());
    doc["meshes"][0]["primitives"][0]["mode"] = json!(1);
    let err = Asset::load_mesh(write_gltf(&temp_dir("mode"), "strip", &doc, &bin), Some("strip"))
        .expect_err("lines")
        .to_string();
    assert!(err.contains("mode Lines") && err.contains("\"strip\"") && err.contains("primitive 0"), "{err}");
}

#[test]
fn unknown_names_list_the_known_ones() {
    let asset = load_strip("names", &strip()).expect("load");
    let err = asset.joint("elbow").expect_err("joint").to_string();
    assert!(err.contains("\"elbow\"") && err.contains("\"root\", \"mid\", \"tip\", \"helper_a\""), "{err}");
    let err = asset.morph("blink").expect_err("morph").to_string();
    assert!(err.contains("\"blink\"") && err.contains("\"smile\", \"frown\""), "{err}");
    let err = asset.clip("run").expect_err("clip").to_string();
    assert!(err.contains("\"run\"") && err.contains("\"wave\", \"idle\""), "{err}");
    assert_eq!(asset.joint("tip").expect("tip"), 2);
    assert_eq!(asset.morph("smile").expect("smile"), 0);
}

#[test]
fn bad_animations_are_refused() {
    let (doc, bin) = build(&strip());
    let dir = temp_dir("bad_anim");
    // A channel targeting a node that does not exist (the gltf crate does not validate targets).
    let mut missing = doc.clone();
    missing["animations"][0]["channels"][1]["target"]["node"] = json!(99);
    let err = Asset::load_mesh(write_gltf(&dir, "missing", &missing, &bin), Some("strip")).expect_err("node");
    assert!(matches!(err, RigError::BadChannel { channel: 1, .. }), "{err}");
    let err = err.to_string();
    assert!(err.contains("\"wave\"") && err.contains("node 99"), "{err}");
    // An unknown target path (the gltf crate would panic on it too).
    let mut path = doc.clone();
    path["animations"][1]["channels"][0]["target"]["path"] = json!("pointer");
    let err = Asset::load_mesh(write_gltf(&dir, "path", &path, &bin), Some("strip")).expect_err("path");
    assert!(matches!(err, RigError::BadChannel { channel: 0, .. }) && err.to_string().contains("\"idle\""), "{err}");
    // Output count not matching the key count: point the STEP translation at the 3-key cubic output.
    let mut counts = doc.clone();
    let cubic_output = counts["animations"][0]["samplers"][2]["output"].clone();
    counts["animations"][0]["samplers"][1]["output"] = cubic_output;
    let err = Asset::load_mesh(write_gltf(&dir, "counts", &counts, &bin), Some("strip")).expect_err("count");
    assert!(matches!(err, RigError::BadChannel { channel: 1, .. }), "{err}");
    assert!(err.to_string().contains("\"wave\""), "{err}");
}

#[test]
fn seam_copies_with_different_morph_deltas_are_refused() {
    let mut s = strip();
    s.frown_indices = vec![1, 5, 14];
    let err = load_err("weld_conflict", &s);
    assert!(err.contains("\"frown\"") && err.contains("6") && err.contains("14"), "{err}");
}

#[test]
fn unsorted_sparse_indices_are_refused() {
    let mut s = strip();
    s.frown_indices = vec![5, 1, 9];
    let err = load_err("sparse_order", &s);
    assert!(err.contains("POSITION of morph target 1") && err.contains("increase strictly"), "{err}");
}

#[test]
fn matrix_nodes_decompose() {
    let m = DMat4::from_scale_rotation_translation(
        DVec3::new(2.0, -0.5, 1.5),
        DQuat::from_xyzw(0.3, -0.2, 0.5, 0.7).normalize(),
        DVec3::new(1.0, 2.0, 3.0),
    );
    let (trs, residual) = Trs::from_matrix(&m);
    assert!(residual < 1e-14, "{residual}");
    assert!(trs.matrix().abs_diff_eq(m, 1e-14));
}
