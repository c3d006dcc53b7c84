//! Wavefront OBJ input (tobj) and output.

use std::io::Write;
use std::path::Path;

use glam::{DVec2, DVec3};

use super::SurfaceMesh;

/// Why an OBJ file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ObjError {
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Parse(#[from] tobj::LoadError),
    #[error("line {line}: vertex {vertex} is not used by any face")]
    Unreferenced { vertex: usize, line: usize },
    #[error("line {line}: `{keyword}` needs {count} finite numbers")]
    NotFinite { line: usize, keyword: &'static str, count: usize },
    #[error("no faces")]
    NoFaces,
}

/// Loads a triangle surface. Positions are multiplied by `to_metres`; material coordinates come
/// from `vt` (scaled the same way) or, without texture coordinates, from the rest xy.
pub fn load(path: &Path, to_metres: f64) -> Result<SurfaceMesh, ObjError> {
    unreferenced_vertex(path)?;
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ..Default::default() };
    let (models, _) = tobj::load_obj(path, &opts)?;
    let mut m = SurfaceMesh::default();
    for model in models {
        let mesh = model.mesh;
        let base = m.rest.len() as u32;
        let nv = mesh.positions.len() / 3;
        m.rest.extend(mesh.positions.chunks_exact(3).map(|p| DVec3::new(p[0], p[1], p[2]) * to_metres));
        let mut uv: Vec<Option<DVec2>> = vec![None; nv];
        if !mesh.texcoords.is_empty() && mesh.texcoord_indices.len() == mesh.indices.len() {
            for (vi, ti) in mesh.indices.iter().zip(&mesh.texcoord_indices) {
                let t = &mesh.texcoords[2 * *ti as usize..2 * *ti as usize + 2];
                uv[*vi as usize].get_or_insert(DVec2::new(t[0], t[1]) * to_metres);
            }
        }
        for (i, u) in uv.into_iter().enumerate() {
            let p = m.rest[base as usize + i];
            m.uv.push(u.unwrap_or(DVec2::new(p.x, p.y)));
        }
        m.faces.extend(mesh.indices.chunks_exact(3).map(|f| [f[0] + base, f[1] + base, f[2] + base]));
    }
    Ok(m)
}

/// tobj drops vertices no face uses and reads NaN and infinity as numbers; a mesh with either
/// (or with no face) is refused, so scan for them, with line numbers.
fn unreferenced_vertex(path: &Path) -> Result<(), ObjError> {
    let text = std::fs::read_to_string(path)?;
    let mut count = 0usize;
    let mut used = Vec::new();
    let mut faces = 0usize;
    for (number, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        let finite = |it: std::str::SplitWhitespace, n: usize| {
            let values: Vec<Option<f64>> =
                it.take(n).map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite())).collect();
            values.len() == n && values.iter().all(Option::is_some)
        };
        match it.next() {
            Some("v") => {
                if !finite(it, 3) {
                    return Err(ObjError::NotFinite { line: number + 1, keyword: "v", count: 3 });
                }
                count += 1;
                used.push(number + 1);
            }
            Some("vt") if !finite(it.clone(), 2) => {
                return Err(ObjError::NotFinite { line: number + 1, keyword: "vt", count: 2 });
            }
            Some("f") => {
                faces += 1;
                for tok in it {
                    let Some(Ok(i)) = tok.split('/').next().map(str::parse::<i64>) else { continue };
                    let idx = if i < 0 { count as i64 + i } else { i - 1 };
                    if let Some(u) = usize::try_from(idx).ok().and_then(|k| used.get_mut(k)) {
                        *u = 0; // (used)
                    }
                }
            }
            _ => {}
        }
    }
    if faces == 0 {
        return Err(ObjError::NoFaces);
    }
    match used.iter().position(|&line| line != 0) {
        Some(vertex) => Err(ObjError::Unreferenced { vertex, line: used[vertex] }),
        None => Ok(()),
    }
}

/// Writes positions (m) as `v`, material coordinates (m) as `vt`, and faces `f v/vt`.
pub fn write(path: &Path, positions: &[DVec3], uv: &[DVec2], faces: &[[u32; 3]]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    for p in positions {
        writeln!(w, "v {:.17e} {:.17e} {:.17e}", p.x, p.y, p.z)?;
    }
    for t in uv {
        writeln!(w, "vt {:.17e} {:.17e}", t.x, t.y)?;
    }
    for f in faces {
        let (a, b, c) = (f[0] + 1, f[1] + 1, f[2] + 1);
        writeln!(w, "f {a}/{a} {b}/{b} {c}/{c}")?;
    }
    w.flush()
}
