//! The stage in Pixar's crate format (`.usdc`), built as layer data and written by the
//! `openusd` crate. The same prims, attributes and metadata as the text stage (`text.rs`).
//! Unlike the text, the crate is written whole at the end: every sample is read back from the
//! spool into memory first (a few hundred MB for a long run of a large patch).

use std::collections::HashMap;
use std::path::Path;

use openusd::gf;
use openusd::sdf::{self, ChildrenKey, FieldKey, SpecType, Specifier, Value, Variability};
use openusd::usdc::CrateWriter;

use super::{Attr, Prim, UsdStage, ATTRIBUTES};

pub(super) fn write(stage: &UsdStage, path: &Path) -> std::io::Result<()> {
    let data = layer(stage)?;
    CrateWriter::write_to_file(&data, path).map_err(std::io::Error::other)
}

fn io(e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

fn token(s: &str) -> Value {
    Value::Token(s.into())
}

fn tokens<'a>(names: impl IntoIterator<Item = &'a str>) -> Value {
    Value::TokenVec(names.into_iter().map(|n| n.into()).collect())
}

fn named(key: &str, value: &str) -> Value {
    Value::Dictionary(HashMap::from([(key.to_string(), Value::String(value.to_string()))]))
}

fn layer(stage: &UsdStage) -> std::io::Result<sdf::Data> {
    let (first, last) = stage.frames.unwrap_or((0, 0));
    let mut data = sdf::Data::new();
    let root = data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
    root.add(ChildrenKey::PrimChildren, tokens(["skinsim"]));
    root.add(FieldKey::DefaultPrim, token("skinsim"));
    root.add(FieldKey::Documentation, Value::String(stage.doc.clone()));
    root.add("metersPerUnit", Value::Double(1.0));
    root.add("upAxis", token("Z"));
    root.add(FieldKey::StartTimeCode, Value::Double(first as f64));
    root.add(FieldKey::EndTimeCode, Value::Double(last as f64));
    root.add(FieldKey::TimeCodesPerSecond, Value::Double(stage.frames_per_second));
    root.add(FieldKey::FramesPerSecond, Value::Double(stage.frames_per_second));

    let patches = stage.patches();
    let top = sdf::Path::new("/skinsim").map_err(io)?;
    let spec = data.create_spec(top.clone(), SpecType::Prim);
    spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Def));
    spec.add(FieldKey::TypeName, token("Xform"));
    spec.add(ChildrenKey::PrimChildren, tokens(patches.iter().map(|(_, p)| p[0].1.names.0.as_str())));
    for (patch, prims) in &patches {
        let xform = top.append_path(prims[0].1.names.0.as_str()).map_err(io)?;
        let spec = data.create_spec(xform.clone(), SpecType::Prim);
        spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Def));
        spec.add(FieldKey::TypeName, token("Xform"));
        spec.add(FieldKey::CustomData, named("name", patch));
        spec.add(ChildrenKey::PrimChildren, tokens(prims.iter().map(|(_, p)| p.names.1.as_str())));
        for (i, prim) in prims {
            mesh(stage, &mut data, &xform, *i, prim)?;
        }
    }
    Ok(data)
}

/// One attribute of a Mesh prim.
struct Attribute {
    name: &'static str,
    ty: &'static str,
    uniform: bool,
    /// `FieldKey::Default` or `FieldKey::TimeSamples`, and its value.
    value: (FieldKey, Value),
    per_vertex: bool,
}

impl Attribute {
    fn default(name: &'static str, ty: &'static str, value: Value) -> Self {
        Attribute { name, ty, uniform: false, value: (FieldKey::Default, value), per_vertex: false }
    }

    fn uniform(name: &'static str, ty: &'static str, value: Value) -> Self {
        Attribute { uniform: true, ..Attribute::default(name, ty, value) }
    }
}

fn mesh(stage: &UsdStage, data: &mut sdf::Data, parent: &sdf::Path, i: usize, prim: &Prim) -> std::io::Result<()> {
    let path = parent.append_path(prim.names.1.as_str()).map_err(io)?;
    let mut attrs = vec![
        Attribute::uniform("orientation", "token", token("rightHanded")),
        Attribute::uniform("subdivisionScheme", "token", token("none")),
    ];
    if stage.options.double_sided {
        attrs.push(Attribute::uniform("doubleSided", "bool", Value::Bool(true)));
    }
    if let Some((tris, uv)) = &prim.fixed {
        let counts = Value::IntVec(vec![3; tris.len()]);
        let indices = Value::IntVec(tris.iter().flat_map(|t| t.map(|v| v as i32)).collect());
        let st = Value::Vec2fVec(uv.iter().map(|t| gf::Vec2f::from([t.x as f32, t.y as f32])).collect());
        attrs.push(Attribute::default("faceVertexCounts", "int[]", counts));
        attrs.push(Attribute::default("faceVertexIndices", "int[]", indices));
        attrs.push(Attribute { per_vertex: true, ..Attribute::default("primvars:st", "texCoord2f[]", st) });
    }
    for &a in ATTRIBUTES.iter().take(prim.spools.len()) {
        let (ty, name, _) = a.names();
        let value = (FieldKey::TimeSamples, Value::TimeSamples(samples(stage, i, a)?));
        attrs.push(Attribute { name, ty, uniform: false, value, per_vertex: a.per_vertex() });
    }
    let spec = data.create_spec(path.clone(), SpecType::Prim);
    spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Def));
    spec.add(FieldKey::TypeName, token("Mesh"));
    let mut custom = HashMap::from([("name".to_string(), Value::String(prim.layer.clone()))]);
    if prim.asset_uv {
        custom.insert("st".to_string(), Value::String("asset".to_string()));
    } else {
        custom.insert("st".to_string(), Value::String("material".to_string()));
        custom.insert("stMetres".to_string(), Value::Double(stage.options.st_unit));
    }
    spec.add(FieldKey::CustomData, Value::Dictionary(custom));
    spec.add(ChildrenKey::PropertyChildren, tokens(attrs.iter().map(|a| a.name)));
    for a in attrs {
        let spec = data.create_spec(path.append_property(a.name).map_err(io)?, SpecType::Attribute);
        spec.add(FieldKey::TypeName, token(a.ty));
        spec.add(FieldKey::Custom, Value::Bool(false));
        if a.uniform {
            spec.add(FieldKey::Variability, Value::Variability(Variability::Uniform));
        }
        if a.per_vertex {
            spec.add("interpolation", token("vertex"));
        }
        spec.add(a.value.0, a.value.1);
    }
    Ok(())
}

/// Prim `i`'s spooled samples of `a`, as USD values by frame.
fn samples(stage: &UsdStage, i: usize, a: Attr) -> std::io::Result<Vec<(f64, Value)>> {
    let mut r = stage.reader(i, a)?;
    let mut out = Vec::new();
    if a.is_int() {
        while let Some((frame, v)) = r.next_ints()? {
            out.push((frame as f64, Value::IntVec(v)));
        }
        return Ok(out);
    }
    while let Some((frame, v)) = r.next_floats()? {
        let value = match a {
            Attr::St => Value::Vec2fVec(v.chunks_exact(2).map(|c| gf::Vec2f::from([c[0], c[1]])).collect()),
            _ => Value::Vec3fVec(v.chunks_exact(3).map(|c| gf::Vec3f::from([c[0], c[1], c[2]])).collect()),
        };
        out.push((frame as f64, value));
    }
    Ok(out)
}
