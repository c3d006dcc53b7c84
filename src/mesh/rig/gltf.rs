//! Reading a rigged mesh from glTF 2.0 (`.gltf` with external or `data:` buffers, or `.glb`).
//!
//! The gltf crate parses and validates the JSON (index ranges, required fields) and resolves the
//! buffers; values are read with its accessor iterator, which also applies sparse substitutions.
//! That iterator trusts the layout it is given: a zero count, a stride smaller than an element or
//! unsorted sparse indices make it panic or misread, and it turns an out-of-range accessor into
//! `None`. So every accessor is checked here first ([`check_layout`]) and every value afterwards
//! (finite, in range), each error naming the accessor and its role.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::gltf::accessor::{Accessor, DataType, Dimensions, Item, Iter};
use ::gltf::animation::{Interpolation as GltfInterpolation, Property as GltfProperty};
use ::gltf::mesh::{Mode, Semantic};
use ::gltf::scene::Transform;
use ::gltf::Document;
use glam::{DMat4, DQuat, DVec2, DVec3};

use super::animation::{Channel, Clip, Interpolation, Property};
use super::{unit_quat, AccessorRef, Asset, Influences, MorphTarget, Names, Node, RigError, Skin, Trs};

type Buffers = [::gltf::buffer::Data];

/// Weights whose sum is further than this from one are reported when normalised. f32 storage of
/// up to eight weights rounds their sum by well under 1e-6, so this flags only real exporter slips.
const WEIGHT_SUM_TOLERANCE: f64 = 1e-5;

/// A node matrix whose `T * R * S` decomposition differs from it by more than this (relative to
/// its largest entry) has shear, which glTF forbids for nodes; it is reported, not refused.
const DECOMPOSITION_TOLERANCE: f64 = 1e-6;

impl Asset {
    /// Reads the only mesh of a glTF file; an error lists the meshes if there are several.
    pub fn load(path: impl AsRef<Path>) -> Result<Asset, RigError> {
        Asset::load_mesh(path, None)
    }

    /// Reads the mesh named `mesh_name` (`None`: the only mesh) with its skin, morph targets, node
    /// hierarchy and animations, validates it and welds its vertices.
    pub(crate) fn load_mesh(path: impl AsRef<Path>, mesh_name: Option<&str>) -> Result<Asset, RigError> {
        let path = path.as_ref();
        let gltf = ::gltf::Gltf::open(path).map_err(|source| RigError::Open { path: path.to_owned(), source })?;
        let ::gltf::Gltf { document, blob } = gltf;
        let base = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or_else(|| Path::new("."));
        check_buffer_files(&document, path, base)?;
        let buffers = ::gltf::import_buffers(&document, Some(base), blob)
            .map_err(|source| RigError::Buffers { path: path.to_owned(), source })?;
        read_asset(path, &document, &buffers, mesh_name)
    }
}

/// Everything after the buffers are in memory, so that it does not depend on where they came from.
fn read_asset(path: &Path, doc: &Document, buffers: &Buffers, mesh_name: Option<&str>) -> Result<Asset, RigError> {
    let mut warnings = Vec::new();
    let (nodes, order) = read_nodes(doc, &mut warnings)?;
    let mesh = pick_mesh(doc, path, mesh_name)?;
    let name = mesh_display_name(&mesh);
    let mesh_node = doc.nodes().find(|n| n.mesh().is_some_and(|m| m.index() == mesh.index()));
    if mesh_node.is_none() {
        warnings.push(format!("mesh {name:?} is carried by no node; it is posed with the identity transform"));
    }
    let skin = match mesh_node.as_ref().and_then(|n| n.skin()) {
        Some(skin) => Some(read_skin(&skin, &nodes, buffers)?),
        None => None,
    };
    let target_names = morph_target_names(&mesh, &mut warnings);
    let ctx =
        MeshCtx { name: &name, buffers, joints: skin.as_ref().map(|s| s.joints.len()), targets: target_names.len() };
    let raw = read_primitives(&mesh, &ctx, &mut warnings)?;
    let (weld, first) = weld_vertices(&raw.positions, &raw.influences);
    let morphs = weld_morphs(&raw.deltas, &target_names, &weld, &first)?;
    let default_morph_weights = default_weights(&mesh, &name, target_names.len())?;
    let welded_faces: Vec<[u32; 3]> = raw.faces.iter().map(|f| f.map(|v| weld[v as usize])).collect();
    let corner_uv = raw.uv.as_ref().map(|uv| raw.faces.iter().map(|f| f.map(|v| uv[v as usize])).collect());
    let influences = select_rows(&raw.influences, &first);
    let rest = first.iter().map(|&v| raw.positions[v]).collect();
    let clips = read_animations(doc, buffers, mesh_node.as_ref().map(|n| n.index()))?;
    Ok(Asset {
        path: path.to_owned(),
        mesh: mesh.index(),
        mesh_name: name,
        mesh_node: mesh_node.map(|n| n.index()),
        nodes,
        skin,
        positions: raw.positions,
        uv: raw.uv,
        faces: raw.faces,
        weld,
        rest,
        welded_faces,
        corner_uv,
        influences,
        morphs,
        default_morph_weights,
        clips,
        warnings,
        uv_missing: raw.uv_missing,
        order,
    })
}

// ---------------------------------------------------------------------------------------------
// Buffers

/// The gltf crate reports a missing buffer file as a bare I/O error without its name, and panics on
/// a relative uri whose percent escapes are not UTF-8; resolving each external uri here first turns
/// both into errors naming the buffer and file.
fn check_buffer_files(doc: &Document, gltf: &Path, base: &Path) -> Result<(), RigError> {
    for buffer in doc.buffers() {
        let ::gltf::buffer::Source::Uri(uri) = buffer.source() else { continue };
        let bad = |reason: &str| RigError::BadBufferUri {
            gltf: gltf.to_owned(),
            buffer: buffer.index(),
            uri: uri.to_owned(),
            reason: reason.to_owned(),
        };
        let file = if uri.starts_with("data:") {
            continue;
        } else if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
            PathBuf::from(rest)
        } else if uri.contains(':') {
            return Err(bad("only data: and file: schemes and relative paths are supported"));
        } else {
            base.join(percent_decode(uri).ok_or_else(|| bad("its percent escapes do not decode to UTF-8"))?)
        };
        if !file.is_file() {
            return Err(RigError::MissingBufferFile { gltf: gltf.to_owned(), buffer: buffer.index(), file });
        }
    }
    Ok(())
}

/// Decodes `%XX` escapes as the gltf crate does (invalid escapes stay literal); `None` when the
/// result is not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |k: usize| bytes.get(k).and_then(|&b| (b as char).to_digit(16));
        match (bytes[i], hex(i + 1), hex(i + 2)) {
            (b'%', Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (b, _, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

// ---------------------------------------------------------------------------------------------
// Accessors

fn bad(accessor: &AccessorRef, problem: impl Into<String>) -> RigError {
    RigError::BadAccessor { accessor: accessor.clone(), problem: problem.into() }
}

fn accessor_ref(acc: &Accessor, role: impl Into<String>) -> AccessorRef {
    AccessorRef { index: acc.index(), role: role.into() }
}

/// The bytes of a buffer view, or an error if the view runs past its buffer.
fn view_bytes<'b>(view: &::gltf::buffer::View, r: &AccessorRef, buffers: &'b Buffers) -> Result<&'b [u8], RigError> {
    let data = buffers.get(view.buffer().index()).map(|d| d.0.as_slice()).unwrap_or(&[]);
    view.offset().checked_add(view.length()).and_then(|end| data.get(view.offset()..end)).ok_or_else(|| {
        bad(r, format!("buffer view {} runs past the end of buffer {}", view.index(), view.buffer().index()))
    })
}

/// Checks that `count` elements of `elem` bytes at `offset` with the view's stride (or tightly
/// packed) fit in the view, and returns the stride.
fn check_span(
    view: &::gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    r: &AccessorRef,
    buffers: &Buffers,
) -> Result<usize, RigError> {
    let bytes = view_bytes(view, r, buffers)?;
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(bad(r, format!("byte stride {stride} is smaller than its {elem}-byte elements")));
    }
    let end = count
        .checked_sub(1)
        .and_then(|c| c.checked_mul(stride))
        .and_then(|s| s.checked_add(offset))
        .and_then(|s| s.checked_add(elem));
    match end {
        Some(end) if end <= bytes.len() => Ok(stride),
        _ => {
            Err(bad(r, format!("{count} elements do not fit in buffer view {} ({} bytes)", view.index(), bytes.len())))
        }
    }
}

/// Makes the layout safe for the gltf crate's iterator (see the module comment): a non-zero count,
/// strides at least an element, everything inside its views, and sparse indices strictly
/// increasing and below the count, as the spec requires.
fn check_layout(acc: &Accessor, r: &AccessorRef, buffers: &Buffers) -> Result<(), RigError> {
    let count = acc.count();
    if count == 0 {
        return Err(bad(r, "count is 0"));
    }
    if let Some(view) = acc.view() {
        check_span(&view, acc.offset(), count, acc.size(), r, buffers)?;
    }
    let Some(sparse) = acc.sparse() else { return Ok(()) };
    let n = sparse.count();
    if n == 0 || n > count {
        return Err(bad(r, format!("sparse count {n} is not in 1..={count}")));
    }
    let values = sparse.values();
    check_span(&values.view(), values.offset(), n, acc.size(), r, buffers)?;
    let indices = sparse.indices();
    let size = indices.index_type().size();
    let stride = check_span(&indices.view(), indices.offset(), n, size, r, buffers)?;
    let bytes = view_bytes(&indices.view(), r, buffers)?;
    let mut previous: Option<u32> = None;
    for i in 0..n {
        let at = indices.offset() + i * stride;
        let index = read_uint(&bytes[at..at + size]);
        if index as usize >= count || previous.is_some_and(|p| index <= p) {
            return Err(bad(
                r,
                format!("sparse index {i} is {index}; indices must increase strictly and stay below {count}"),
            ));
        }
        previous = Some(index);
    }
    Ok(())
}

/// A little-endian unsigned integer of 1, 2 or 4 bytes.
fn read_uint(bytes: &[u8]) -> u32 {
    bytes.iter().rev().fold(0u32, |acc, &b| (acc << 8) | u32::from(b))
}

/// All elements of an accessor as the gltf crate's iterator yields them (sparse values applied).
/// `T` must match the accessor's component type and dimensions, which the callers check.
fn items<T: Item + Clone>(acc: &Accessor, r: &AccessorRef, buffers: &Buffers) -> Result<Vec<T>, RigError> {
    check_layout(acc, r, buffers)?;
    if acc.view().is_none() && acc.sparse().is_none() {
        return Ok(vec![T::zero(); acc.count()]);
    }
    let get = |b: ::gltf::Buffer| buffers.get(b.index()).map(|d| d.0.as_slice());
    let values: Vec<T> =
        Iter::<T>::new(acc.clone(), get).ok_or_else(|| bad(r, "its data lies outside its buffer"))?.collect();
    if values.len() != acc.count() {
        return Err(bad(r, format!("yields {} elements, not its count {}", values.len(), acc.count())));
    }
    Ok(values)
}

fn expect_dimensions(acc: &Accessor, r: &AccessorRef, dims: Dimensions) -> Result<(), RigError> {
    if acc.dimensions() != dims {
        return Err(bad(r, format!("has type {:?}, expected {dims:?}", acc.dimensions())));
    }
    Ok(())
}

/// Reads an N-component float accessor: f32, or, when `normalized_ok`, normalised 8/16-bit
/// integers converted as the spec says. Rejects non-finite values.
fn read_floats<const N: usize>(
    acc: &Accessor,
    r: &AccessorRef,
    buffers: &Buffers,
    normalized_ok: bool,
) -> Result<Vec<[f64; N]>, RigError>
where
    [f32; N]: Item + Clone,
    [i8; N]: Item + Clone,
    [u8; N]: Item + Clone,
    [i16; N]: Item + Clone,
    [u16; N]: Item + Clone,
{
    let dims = match N {
        2 => Dimensions::Vec2,
        3 => Dimensions::Vec3,
        _ => Dimensions::Vec4,
    };
    expect_dimensions(acc, r, dims)?;
    let values: Vec<[f64; N]> = match (acc.data_type(), acc.normalized() && normalized_ok) {
        (DataType::F32, _) => items::<[f32; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(f64::from)).collect(),
        (DataType::I8, true) => items::<[i8; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(unorm_i8)).collect(),
        (DataType::U8, true) => items::<[u8; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(unorm_u8)).collect(),
        (DataType::I16, true) => items::<[i16; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(unorm_i16)).collect(),
        (DataType::U16, true) => items::<[u16; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(unorm_u16)).collect(),
        (other, _) => return Err(bad(r, format!("has component type {other:?}, expected float"))),
    };
    check_finite(values.iter().flatten().copied(), N, r)?;
    Ok(values)
}

/// Reads a scalar float accessor, as [`read_floats`].
fn read_scalars(acc: &Accessor, r: &AccessorRef, buffers: &Buffers, normalized_ok: bool) -> Result<Vec<f64>, RigError> {
    expect_dimensions(acc, r, Dimensions::Scalar)?;
    let values: Vec<f64> = match (acc.data_type(), acc.normalized() && normalized_ok) {
        (DataType::F32, _) => items::<f32>(acc, r, buffers)?.into_iter().map(f64::from).collect(),
        (DataType::I8, true) => items::<i8>(acc, r, buffers)?.into_iter().map(unorm_i8).collect(),
        (DataType::U8, true) => items::<u8>(acc, r, buffers)?.into_iter().map(unorm_u8).collect(),
        (DataType::I16, true) => items::<i16>(acc, r, buffers)?.into_iter().map(unorm_i16).collect(),
        (DataType::U16, true) => items::<u16>(acc, r, buffers)?.into_iter().map(unorm_u16).collect(),
        (other, _) => return Err(bad(r, format!("has component type {other:?}, expected float"))),
    };
    check_finite(values.iter().copied(), 1, r)?;
    Ok(values)
}

/// The spec's integer-to-float rules for normalised accessors.
fn unorm_i8(c: i8) -> f64 {
    (f64::from(c) / 127.0).max(-1.0)
}
fn unorm_u8(c: u8) -> f64 {
    f64::from(c) / 255.0
}
fn unorm_i16(c: i16) -> f64 {
    (f64::from(c) / 32767.0).max(-1.0)
}
fn unorm_u16(c: u16) -> f64 {
    f64::from(c) / 65535.0
}

/// NaN or infinity anywhere would silently poison every pose, so it is refused at load.
fn check_finite(values: impl Iterator<Item = f64>, width: usize, r: &AccessorRef) -> Result<(), RigError> {
    for (i, value) in values.enumerate() {
        if !value.is_finite() {
            return Err(RigError::NonFinite { accessor: r.clone(), element: i / width, value });
        }
    }
    Ok(())
}

/// Reads an unsigned-integer accessor (vertex indices, joint indices) of N components.
fn read_uints<const N: usize>(acc: &Accessor, r: &AccessorRef, buffers: &Buffers) -> Result<Vec<[u32; N]>, RigError>
where
    [u8; N]: Item + Clone,
    [u16; N]: Item + Clone,
    [u32; N]: Item + Clone,
{
    expect_dimensions(acc, r, if N == 4 { Dimensions::Vec4 } else { Dimensions::Scalar })?;
    Ok(match acc.data_type() {
        DataType::U8 => items::<[u8; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(u32::from)).collect(),
        DataType::U16 => items::<[u16; N]>(acc, r, buffers)?.into_iter().map(|a| a.map(u32::from)).collect(),
        DataType::U32 => items::<[u32; N]>(acc, r, buffers)?,
        other => return Err(bad(r, format!("has component type {other:?}, expected an unsigned integer"))),
    })
}

/// Reads a scalar unsigned-integer accessor (vertex indices).
fn read_indices(acc: &Accessor, r: &AccessorRef, buffers: &Buffers) -> Result<Vec<u32>, RigError> {
    expect_dimensions(acc, r, Dimensions::Scalar)?;
    Ok(match acc.data_type() {
        DataType::U8 => items::<u8>(acc, r, buffers)?.into_iter().map(u32::from).collect(),
        DataType::U16 => items::<u16>(acc, r, buffers)?.into_iter().map(u32::from).collect(),
        DataType::U32 => items::<u32>(acc, r, buffers)?,
        other => return Err(bad(r, format!("has component type {other:?}, expected an unsigned integer"))),
    })
}

// ---------------------------------------------------------------------------------------------
// Nodes and skin

/// Every node's name, rest transform and parent, plus an order with parents first. A node with two
/// parents or a cycle is refused: the global matrices would be ambiguous or undefined.
fn read_nodes(doc: &Document, warnings: &mut Vec<String>) -> Result<(Vec<Node>, Vec<usize>), RigError> {
    let mut nodes = Vec::with_capacity(doc.nodes().len());
    for node in doc.nodes() {
        let name = node.name().map_or_else(|| format!("node_{}", node.index()), str::to_owned);
        let rest = node_rest(&node.transform(), &name, warnings)?;
        let weights = node.weights().map(|w| w.iter().map(|&x| f64::from(x)).collect());
        let children = node.children().map(|c| c.index()).collect();
        nodes.push(Node { name, parent: None, children, rest, weights });
    }
    for p in 0..nodes.len() {
        for c in nodes[p].children.clone() {
            if let Some(q) = nodes[c].parent {
                return Err(RigError::BadHierarchy(format!(
                    "node {:?} is a child of both {:?} and {:?}",
                    nodes[c].name, nodes[q].name, nodes[p].name
                )));
            }
            nodes[c].parent = Some(p);
        }
    }
    let order = parents_first(&nodes)?;
    Ok((nodes, order))
}

/// Breadth-first from the roots; nodes not reached are on a cycle.
fn parents_first(nodes: &[Node]) -> Result<Vec<usize>, RigError> {
    let mut order: Vec<usize> = (0..nodes.len()).filter(|&n| nodes[n].parent.is_none()).collect();
    let mut next = 0;
    while next < order.len() {
        order.extend_from_slice(&nodes[order[next]].children);
        next += 1;
    }
    if order.len() != nodes.len() {
        let mut on_cycle = vec![true; nodes.len()];
        order.iter().for_each(|&n| on_cycle[n] = false);
        let names = (0..nodes.len()).filter(|&n| on_cycle[n]).map(|n| nodes[n].name.as_str());
        return Err(RigError::BadHierarchy(format!("nodes {} form a cycle", Names::of(names))));
    }
    Ok(order)
}

/// A node's local transform as TRS. Quaternions are renormalised in f64 (f32 storage leaves them
/// off unit length by ~1e-7); a matrix is decomposed, with a warning if it has shear.
fn node_rest(transform: &Transform, name: &str, warnings: &mut Vec<String>) -> Result<Trs, RigError> {
    match transform {
        Transform::Decomposed { translation, rotation, scale } => {
            let [x, y, z, w] = rotation.map(f64::from);
            let rotation = unit_quat(DQuat::from_xyzw(x, y, z, w))
                .ok_or_else(|| RigError::BadHierarchy(format!("node {name:?} has rotation {rotation:?}")))?;
            let trs = Trs::new(
                DVec3::from_array(translation.map(f64::from)),
                rotation,
                DVec3::from_array(scale.map(f64::from)),
            );
            if !(trs.translation.is_finite() && trs.scale.is_finite()) {
                return Err(RigError::BadHierarchy(format!("node {name:?} has a non-finite transform")));
            }
            Ok(trs)
        }
        Transform::Matrix { matrix } => {
            let m = DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)));
            if !m.is_finite() {
                return Err(RigError::BadHierarchy(format!("node {name:?} has a non-finite matrix")));
            }
            let (trs, residual) = Trs::from_matrix(&m);
            let size = m.to_cols_array().iter().fold(1.0f64, |a, b| a.max(b.abs()));
            if residual > DECOMPOSITION_TOLERANCE * size {
                warnings.push(format!(
                    "node {name:?}: its matrix is not translation * rotation * scale (off by {residual:e}); \
                     the shear is dropped"
                ));
            }
            Ok(trs)
        }
    }
}

fn read_skin(skin: &::gltf::Skin, nodes: &[Node], buffers: &Buffers) -> Result<Skin, RigError> {
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    let joint_names = joints.iter().map(|&j| nodes[j].name.clone()).collect();
    let skin_name =
        skin.name().map_or_else(|| format!("skin {}", skin.index()), |n| format!("skin {} ({n:?})", skin.index()));
    let Some(acc) = skin.inverse_bind_matrices() else {
        return Ok(Skin {
            inverse_bind: vec![DMat4::IDENTITY; joints.len()],
            joints,
            joint_names,
            inverse_bind_from_file: false,
        });
    };
    let r = accessor_ref(&acc, format!("inverse bind matrices of {skin_name}"));
    expect_dimensions(&acc, &r, Dimensions::Mat4)?;
    if acc.data_type() != DataType::F32 {
        return Err(bad(&r, format!("has component type {:?}, expected F32", acc.data_type())));
    }
    let mats = items::<[[f32; 4]; 4]>(&acc, &r, buffers)?;
    let inverse_bind: Vec<DMat4> =
        mats.iter().map(|m| DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from)))).collect();
    check_finite(inverse_bind.iter().flat_map(|m| m.to_cols_array()), 16, &r)?;
    if inverse_bind.len() < joints.len() {
        return Err(bad(&r, format!("has {} matrices for {} joints", inverse_bind.len(), joints.len())));
    }
    Ok(Skin { inverse_bind: inverse_bind[..joints.len()].to_vec(), joints, joint_names, inverse_bind_from_file: true })
}

// ---------------------------------------------------------------------------------------------
// Mesh

fn mesh_display_name(mesh: &::gltf::Mesh) -> String {
    mesh.name().map_or_else(|| format!("mesh_{}", mesh.index()), str::to_owned)
}

fn pick_mesh<'a>(doc: &'a Document, path: &Path, name: Option<&str>) -> Result<::gltf::Mesh<'a>, RigError> {
    let known = || Names(doc.meshes().map(|m| mesh_display_name(&m)).collect());
    match name {
        Some(name) => doc
            .meshes()
            .find(|m| mesh_display_name(m) == name)
            .ok_or_else(|| RigError::UnknownMesh { name: name.to_owned(), known: known() }),
        None => match doc.meshes().len() {
            0 => Err(RigError::NoMesh { path: path.to_owned() }),
            1 => doc.meshes().next().ok_or_else(|| RigError::NoMesh { path: path.to_owned() }),
            _ => Err(RigError::SeveralMeshes { path: path.to_owned(), known: known() }),
        },
    }
}

/// Target names from `mesh.extras.targetNames` (Blender's convention, not part of the spec), else
/// `target_<k>`. The count comes from the first primitive; all must agree (checked when reading).
fn morph_target_names(mesh: &::gltf::Mesh, warnings: &mut Vec<String>) -> Vec<String> {
    let count = mesh.primitives().next().map_or(0, |p| p.morph_targets().len());
    let mut names: Vec<String> = (0..count).map(|k| format!("target_{k}")).collect();
    let Some(raw) = mesh.extras() else { return names };
    let extras: serde_json::Value = match serde_json::from_str(raw.get()) {
        Ok(v) => v,
        Err(e) => {
            warnings
                .push(format!("mesh {:?}: extras are not JSON ({e}); default target names", mesh_display_name(mesh)));
            return names;
        }
    };
    let Some(list) = extras.get("targetNames").and_then(|t| t.as_array()) else { return names };
    if list.len() != count {
        warnings.push(format!(
            "mesh {:?}: extras.targetNames has {} names for {count} morph targets",
            mesh_display_name(mesh),
            list.len()
        ));
    }
    for (name, given) in names.iter_mut().zip(list) {
        if let Some(s) = given.as_str() {
            *name = s.to_owned();
        }
    }
    names
}

fn default_weights(mesh: &::gltf::Mesh, name: &str, targets: usize) -> Result<Vec<f64>, RigError> {
    match mesh.weights() {
        None => Ok(vec![0.0; targets]),
        Some(w) if w.len() == targets && w.iter().all(|x| x.is_finite()) => {
            Ok(w.iter().map(|&x| f64::from(x)).collect())
        }
        Some(w) => Err(RigError::BadMesh {
            mesh: name.to_owned(),
            problem: format!("weights {w:?} do not give one finite weight for each of {targets} morph targets"),
        }),
    }
}

struct MeshCtx<'a> {
    name: &'a str,
    buffers: &'a Buffers,
    /// The skin's joint count, if the mesh node has a skin.
    joints: Option<usize>,
    targets: usize,
}

/// All primitives of the mesh, concatenated, per glTF vertex.
#[derive(Default)]
struct RawMesh {
    positions: Vec<DVec3>,
    uv: Option<Vec<DVec2>>,
    uv_missing: Option<usize>,
    faces: Vec<[u32; 3]>,
    influences: Influences,
    /// Per target, per glTF vertex.
    deltas: Vec<Vec<DVec3>>,
}

fn read_primitives(mesh: &::gltf::Mesh, ctx: &MeshCtx, warnings: &mut Vec<String>) -> Result<RawMesh, RigError> {
    let mut raw = RawMesh {
        uv: Some(Vec::new()),
        influences: Influences { start: vec![0], ..Influences::default() },
        deltas: vec![Vec::new(); ctx.targets],
        ..RawMesh::default()
    };
    for (p, prim) in mesh.primitives().enumerate() {
        read_primitive(&prim, p, ctx, &mut raw, warnings)?;
    }
    Ok(raw)
}

fn read_primitive(
    prim: &::gltf::Primitive,
    p: usize,
    ctx: &MeshCtx,
    raw: &mut RawMesh,
    warnings: &mut Vec<String>,
) -> Result<(), RigError> {
    if prim.mode() != Mode::Triangles {
        return Err(RigError::NotTriangles {
            mesh: ctx.name.to_owned(),
            primitive: p,
            mode: format!("{:?}", prim.mode()),
        });
    }
    let role = |what: &str| format!("{what} of mesh {:?}, primitive {p}", ctx.name);
    let attribute = |semantic: Semantic| -> Result<Option<(Accessor, AccessorRef)>, RigError> {
        let Some(acc) = prim.get(&semantic) else { return Ok(None) };
        Ok(Some((acc.clone(), accessor_ref(&acc, role(&semantic.to_string())))))
    };
    let (pos_acc, pos_ref) = attribute(Semantic::Positions)?.ok_or_else(|| RigError::MissingAttribute {
        mesh: ctx.name.to_owned(),
        primitive: p,
        semantic: "POSITION".into(),
    })?;
    let positions = read_floats::<3>(&pos_acc, &pos_ref, ctx.buffers, false)?;
    let n = positions.len();
    let same_count = |acc: &Accessor, r: &AccessorRef| {
        if acc.count() == n {
            Ok(())
        } else {
            Err(bad(r, format!("has {} elements, but POSITION has {n}", acc.count())))
        }
    };
    let base = raw.positions.len() as u32;

    match attribute(Semantic::TexCoords(0))? {
        Some((acc, r)) => {
            same_count(&acc, &r)?;
            let uv = read_floats::<2>(&acc, &r, ctx.buffers, true)?;
            if let Some(all) = raw.uv.as_mut() {
                all.extend(uv.into_iter().map(DVec2::from_array));
            }
        }
        None => {
            raw.uv = None;
            raw.uv_missing.get_or_insert(p);
        }
    }

    let corners = match prim.indices() {
        Some(acc) => {
            let r = accessor_ref(&acc, role("indices"));
            let indices = read_indices(&acc, &r, ctx.buffers)?;
            if let Some((i, &v)) = indices.iter().enumerate().find(|(_, &v)| v as usize >= n) {
                return Err(bad(&r, format!("index {i} is {v}, but the primitive has {n} vertices")));
            }
            if !indices.len().is_multiple_of(3) {
                return Err(bad(&r, format!("{} indices are not whole triangles", indices.len())));
            }
            indices
        }
        None if n.is_multiple_of(3) => (0..n as u32).collect(),
        None => return Err(bad(&pos_ref, format!("{n} unindexed vertices are not whole triangles"))),
    };
    raw.faces.extend(corners.chunks_exact(3).map(|c| [c[0] + base, c[1] + base, c[2] + base]));

    let sets = joint_sets(prim, p, ctx)?;
    match ctx.joints {
        Some(joints) => {
            let mut read = Vec::with_capacity(sets.len());
            for (j_acc, w_acc) in &sets {
                let j_ref = accessor_ref(j_acc, role(&Semantic::Joints(read.len() as u32).to_string()));
                let w_ref = accessor_ref(w_acc, role(&Semantic::Weights(read.len() as u32).to_string()));
                same_count(j_acc, &j_ref)?;
                same_count(w_acc, &w_ref)?;
                let j = read_uints::<4>(j_acc, &j_ref, ctx.buffers)?;
                let w = read_floats::<4>(w_acc, &w_ref, ctx.buffers, true)?;
                read.push((j, j_ref, w, w_ref));
            }
            append_influences(&read, n, joints, &mut raw.influences, warnings, &role("weights"))?;
        }
        None => {
            if !sets.is_empty() {
                warnings.push(format!("{} has JOINTS/WEIGHTS but its node has no skin; ignored", role("primitive")));
            }
            let last = raw.influences.joint.len() as u32;
            raw.influences.start.extend(std::iter::repeat_n(last, n));
        }
    }

    let targets: Vec<_> = prim.morph_targets().collect();
    if targets.len() != ctx.targets {
        return Err(RigError::BadMesh {
            mesh: ctx.name.to_owned(),
            problem: format!("primitive {p} has {} morph targets, primitive 0 has {}", targets.len(), ctx.targets),
        });
    }
    for (k, target) in targets.iter().enumerate() {
        let deltas = match target.positions() {
            Some(acc) => {
                let r = accessor_ref(&acc, role(&format!("POSITION of morph target {k}")));
                same_count(&acc, &r)?;
                read_floats::<3>(&acc, &r, ctx.buffers, true)?
            }
            None => vec![[0.0; 3]; n],
        };
        raw.deltas[k].extend(deltas.into_iter().map(DVec3::from_array));
    }
    raw.positions.extend(positions.into_iter().map(DVec3::from_array));
    Ok(())
}

/// The JOINTS_n/WEIGHTS_n pairs of a primitive, in set order; a set without its partner, or a gap
/// in the numbering, is refused because the influences would be incomplete.
fn joint_sets<'a>(
    prim: &::gltf::Primitive<'a>,
    p: usize,
    ctx: &MeshCtx,
) -> Result<Vec<(Accessor<'a>, Accessor<'a>)>, RigError> {
    let mut sets = Vec::new();
    let count = prim
        .attributes()
        .filter_map(|(s, _)| match s {
            Semantic::Joints(k) | Semantic::Weights(k) => Some(k as usize + 1),
            _ => None,
        })
        .max()
        .unwrap_or(0);
    for k in 0..count as u32 {
        match (prim.get(&Semantic::Joints(k)), prim.get(&Semantic::Weights(k))) {
            (Some(j), Some(w)) => sets.push((j, w)),
            _ => {
                return Err(RigError::BadMesh {
                    mesh: ctx.name.to_owned(),
                    problem: format!("primitive {p} lacks JOINTS_{k} or WEIGHTS_{k} (sets must come in pairs from 0)"),
                })
            }
        }
    }
    if ctx.joints.is_some() && sets.is_empty() {
        return Err(RigError::BadMesh {
            mesh: ctx.name.to_owned(),
            problem: format!("its node has a skin but primitive {p} has no JOINTS_0/WEIGHTS_0"),
        });
    }
    Ok(sets)
}

type JointSet = (Vec<[u32; 4]>, AccessorRef, Vec<[f64; 4]>, AccessorRef);

/// Per vertex: gathers the influences of all sets, checks joint indices and weights, drops zero
/// weights, merges repeated joints, sorts by joint and normalises (warning once per primitive
/// when a sum was off, which the spec allows readers to fix this way).
fn append_influences(
    sets: &[JointSet],
    n: usize,
    joints: usize,
    out: &mut Influences,
    warnings: &mut Vec<String>,
    what: &str,
) -> Result<(), RigError> {
    let mut pairs: Vec<(u32, f64)> = Vec::with_capacity(4 * sets.len());
    let (mut off, mut first_off) = (0usize, None);
    for v in 0..n {
        pairs.clear();
        for (j, j_ref, w, w_ref) in sets {
            for (&joint, &weight) in j[v].iter().zip(&w[v]) {
                if joint as usize >= joints {
                    return Err(RigError::JointOutOfRange { accessor: j_ref.clone(), vertex: v, joint, joints });
                }
                if weight < 0.0 {
                    return Err(bad(w_ref, format!("vertex {v} has negative weight {weight}")));
                }
                if weight > 0.0 {
                    pairs.push((joint, weight));
                }
            }
        }
        pairs.sort_by_key(|&(j, _)| j);
        pairs.dedup_by(|later, kept| {
            let same = later.0 == kept.0;
            if same {
                kept.1 += later.1;
            }
            same
        });
        let sum: f64 = pairs.iter().map(|&(_, w)| w).sum();
        if sum == 0.0 {
            return Err(RigError::ZeroWeights { accessor: sets[0].3.clone(), vertex: v });
        }
        if (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            off += 1;
            first_off.get_or_insert((v, sum));
        }
        out.joint.extend(pairs.iter().map(|&(j, _)| j));
        out.weight.extend(pairs.iter().map(|&(_, w)| w / sum));
        out.start.push(out.joint.len() as u32);
    }
    if let Some((v, sum)) = first_off {
        warnings.push(format!(
            "{what}: {off} vertices have weights not summing to one (first: vertex {v}, sum {sum:.7}); normalised"
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Welding

/// glTF splits a vertex wherever an attribute differs (UV seams); the simulation needs one vertex
/// per material point. Vertices weld when rest position (bitwise) and influences agree, so welding
/// never changes how a vertex moves. Returns the welded index of each glTF vertex and the first
/// glTF vertex of each welded one.
fn weld_vertices(positions: &[DVec3], influences: &Influences) -> (Vec<u32>, Vec<usize>) {
    type Key = ([u64; 3], Vec<(u32, u64)>);
    let mut seen: HashMap<Key, u32> = HashMap::with_capacity(positions.len());
    let mut first = Vec::new();
    let weld = positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let (j, w) = influences.of(v);
            let key = (p.to_array().map(f64::to_bits), j.iter().zip(w).map(|(&j, w)| (j, w.to_bits())).collect());
            *seen.entry(key).or_insert_with(|| {
                first.push(v);
                first.len() as u32 - 1
            })
        })
        .collect();
    (weld, first)
}

/// Morph deltas per welded vertex, refusing copies that disagree (welding them would lose a delta).
fn weld_morphs(
    deltas: &[Vec<DVec3>],
    names: &[String],
    weld: &[u32],
    first: &[usize],
) -> Result<Vec<MorphTarget>, RigError> {
    let bits = |d: DVec3| d.to_array().map(f64::to_bits);
    deltas
        .iter()
        .zip(names)
        .map(|(d, name)| {
            for (v, &w) in weld.iter().enumerate() {
                let f = first[w as usize];
                if bits(d[v]) != bits(d[f]) {
                    return Err(RigError::WeldConflict { target: name.clone(), first: f, other: v });
                }
            }
            Ok(MorphTarget { name: name.clone(), deltas: first.iter().map(|&v| d[v]).collect() })
        })
        .collect()
}

/// The influence rows of the given glTF vertices, in that order.
fn select_rows(all: &Influences, rows: &[usize]) -> Influences {
    let mut out = Influences { start: vec![0], ..Influences::default() };
    for &v in rows {
        let (j, w) = all.of(v);
        out.joint.extend_from_slice(j);
        out.weight.extend_from_slice(w);
        out.start.push(out.joint.len() as u32);
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Animations

fn read_animations(doc: &Document, buffers: &Buffers, mesh_node: Option<usize>) -> Result<Vec<Clip>, RigError> {
    doc.animations()
        .map(|anim| {
            let name = anim.name().map_or_else(|| format!("animation_{}", anim.index()), str::to_owned);
            let channels = anim
                .channels()
                .enumerate()
                .map(|(c, ch)| read_channel(&ch, c, &name, doc, buffers))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Clip::new(name, channels, doc.nodes().len(), mesh_node))
        })
        .collect()
}

fn read_channel(
    ch: &::gltf::animation::Channel,
    c: usize,
    clip: &str,
    doc: &Document,
    buffers: &Buffers,
) -> Result<Channel, RigError> {
    let fail = |problem: String| RigError::BadChannel { clip: clip.to_owned(), channel: c, problem };
    let (node_index, gltf_property) = checked_target(doc, ch).map_err(fail)?;
    let node =
        doc.nodes().nth(node_index).ok_or_else(|| fail(format!("targets node {node_index}, which does not exist")))?;
    let sampler = ch.sampler();
    let role = |what: &str| format!("{what} of sampler {} of animation {clip:?}", sampler.index());
    let input = sampler.input();
    let input_ref = accessor_ref(&input, role("input"));
    if input.data_type() != DataType::F32 {
        return Err(bad(&input_ref, "key times must be F32"));
    }
    let times = read_scalars(&input, &input_ref, buffers, false)?;
    if let Some(k) = (1..times.len()).find(|&k| times[k] <= times[k - 1]) {
        return Err(bad(&input_ref, format!("key times must increase strictly, but key {k} is at {} s", times[k])));
    }
    let interpolation = match sampler.interpolation() {
        GltfInterpolation::Step => Interpolation::Step,
        GltfInterpolation::Linear => Interpolation::Linear,
        GltfInterpolation::CubicSpline => Interpolation::CubicSpline,
    };
    let output = sampler.output();
    let output_ref = accessor_ref(&output, role("output"));
    let (property, width, mut values) = match gltf_property {
        GltfProperty::Translation => {
            (Property::Translation, 3, flat(read_floats::<3>(&output, &output_ref, buffers, false)?))
        }
        GltfProperty::Scale => (Property::Scale, 3, flat(read_floats::<3>(&output, &output_ref, buffers, false)?)),
        GltfProperty::Rotation => (Property::Rotation, 4, flat(read_floats::<4>(&output, &output_ref, buffers, true)?)),
        GltfProperty::MorphTargetWeights => {
            let mesh = node
                .mesh()
                .ok_or_else(|| fail(format!("animates the weights of node {node_index}, which has no mesh")))?;
            let width = mesh.primitives().next().map_or(0, |p| p.morph_targets().len());
            if width == 0 {
                return Err(fail(format!(
                    "animates the weights of mesh {:?}, which has no morph targets",
                    mesh_display_name(&mesh)
                )));
            }
            (Property::Weights, width, read_scalars(&output, &output_ref, buffers, true)?)
        }
    };
    let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
    if values.len() != times.len() * per_key {
        return Err(fail(format!(
            "{} output values for {} keys; {interpolation:?} {property:?} needs {per_key} per key",
            values.len(),
            times.len()
        )));
    }
    if property == Property::Rotation && interpolation != Interpolation::CubicSpline {
        for q in values.chunks_exact_mut(4) {
            let unit = unit_quat(DQuat::from_slice(q)).ok_or_else(|| bad(&output_ref, "has a zero quaternion"))?;
            q.copy_from_slice(&unit.to_array());
        }
    }
    Ok(Channel { node: node_index, property, interpolation, times, values, width })
}

/// The channel's target node and property, read from the JSON: the gltf crate's validation skips
/// channel targets, and its `Target::node()` / `Target::property()` unwrap, so a target node out of
/// range or an unknown path would panic there.
fn checked_target(doc: &Document, ch: &::gltf::animation::Channel) -> Result<(usize, GltfProperty), String> {
    let target = doc
        .as_json()
        .animations
        .get(ch.animation().index())
        .and_then(|a| a.channels.get(ch.index()))
        .map(|c| &c.target)
        .ok_or_else(|| "is missing from the document".to_owned())?;
    let node = target.node.value();
    if node >= doc.nodes().len() {
        return Err(format!("targets node {node}, but the file has {} nodes", doc.nodes().len()));
    }
    match target.path {
        ::gltf::json::validation::Checked::Valid(property) => Ok((node, property)),
        ::gltf::json::validation::Checked::Invalid => Err("has an unknown target path".to_owned()),
    }
}

fn flat<const N: usize>(v: Vec<[f64; N]>) -> Vec<f64> {
    v.into_iter().flatten().collect()
}
