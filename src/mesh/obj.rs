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
    #[error("line {line}: a face needs at least 3 corners")]
    ShortFace { line: usize },
    #[error("line {line}: face corner `{corner}` is not a vertex index (i, i/t, i//n or i/t/n)")]
    BadCorner { line: usize, corner: String },
    #[error("line {line}: face corner {index} refers to no vertex (the file has {count})")]
    NoSuchVertex { line: usize, index: i64, count: usize },
}

/// Loads a triangle surface. Positions are multiplied by `to_metres`; material coordinates come
/// from `vt` (scaled the same way) or, without texture coordinates, from the rest xy.
pub fn load(path: &Path, to_metres: f64) -> Result<SurfaceMesh, ObjError> {
    load_groups(path, to_metres).map(|(m, _)| m)
}

/// The OBJ's groups: each `o` or `g` name with the faces it holds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceGroups {
    pub names: Vec<String>,
    /// Per face, the index of its group in `names`.
    pub of_face: Vec<u32>,
}

/// `load`, and which `o` / `g` group each face belongs to. The file is one vertex array whatever
/// its groups: a vertex two groups share stays one vertex (tobj would load each group as a model
/// of its own, duplicating it), so the groups are read here and tobj sees none.
pub(crate) fn load_groups(path: &Path, to_metres: f64) -> Result<(SurfaceMesh, FaceGroups), ObjError> {
    let text = std::fs::read_to_string(path)?;
    let scanned = scan(&text)?;
    // Groups and materials start new tobj models: blanked (lines kept, so tobj's count stays).
    let flat: String = text
        .lines()
        .map(|l| match l.split_whitespace().next() {
            Some("o" | "g" | "usemtl" | "mtllib") => "",
            _ => l,
        })
        .flat_map(|l| [l, "\n"])
        .collect();
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ..Default::default() };
    let (models, _) = tobj::load_obj_buf(&mut flat.as_bytes(), &opts, |_| Ok(Default::default()))?;
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
    // tobj fans a polygon of n corners into n - 2 triangles, in the file's order.
    let of_face: Vec<u32> = scanned.faces.iter().flat_map(|&(g, n)| std::iter::repeat_n(g, n - 2)).collect();
    debug_assert_eq!(of_face.len(), m.faces.len());
    Ok((m, FaceGroups { names: scanned.groups, of_face }))
}

/// Whether the file states texture coordinates (`vt` lines).
pub(crate) fn has_texture_coordinates(path: &Path) -> std::io::Result<bool> {
    Ok(std::fs::read_to_string(path)?.lines().any(|l| l.split_whitespace().next() == Some("vt")))
}

/// The groups an OBJ's faces are in: `groups`, the names of the `o` / `g` groups that hold a
/// face (faces before any: "unnamed_object", as tobj names them); `faces`, per face in the
/// file's order, its group and its number of corners.
struct Scanned {
    groups: Vec<String>,
    faces: Vec<(u32, usize)>,
}

/// tobj drops vertices no face uses, reads NaN and infinity as numbers and reports malformed
/// faces without a line; a mesh with any of these (or with no face) is refused, with the line.
fn scan(text: &str) -> Result<Scanned, ObjError> {
    let mut scanned = Scanned { groups: vec![], faces: vec![] };
    let mut group = "unnamed_object".to_string();
    let mut count = 0usize;
    let mut used = Vec::new();
    // (a face may name a vertex defined after it: indices are checked at the end)
    let mut corners: Vec<(usize, i64)> = Vec::new();
    let mut faces = 0usize;
    for (number, line) in text.lines().enumerate() {
        let line_no = number + 1;
        let mut it = line.split_whitespace();
        let finite = |it: std::str::SplitWhitespace, n: usize| {
            let values: Vec<Option<f64>> =
                it.take(n).map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite())).collect();
            values.len() == n && values.iter().all(Option::is_some)
        };
        match it.next() {
            Some("v") => {
                if !finite(it, 3) {
                    return Err(ObjError::NotFinite { line: line_no, keyword: "v", count: 3 });
                }
                count += 1;
                used.push(line_no);
            }
            Some("vt") if !finite(it.clone(), 2) => {
                return Err(ObjError::NotFinite { line: line_no, keyword: "vt", count: 2 });
            }
            Some("o" | "g") => {
                let name = line.trim_start()[1..].trim();
                group = if name.is_empty() { "unnamed_object".to_string() } else { name.to_string() };
            }
            Some("f") => {
                faces += 1;
                let mut n = 0;
                for tok in it {
                    let index = tok.split('/').next().and_then(|i| i.parse::<i64>().ok()).filter(|&i| i != 0);
                    let well_formed = tok.split('/').count() <= 3
                        && tok.split('/').skip(1).all(|t| t.is_empty() || t.parse::<i64>().is_ok_and(|i| i != 0));
                    match index {
                        Some(i) if well_formed => {
                            // (a negative index counts back from the vertices read so far)
                            corners.push((line_no, if i < 0 { count as i64 + i } else { i - 1 }));
                        }
                        _ => return Err(ObjError::BadCorner { line: line_no, corner: tok.to_string() }),
                    }
                    n += 1;
                }
                if n < 3 {
                    return Err(ObjError::ShortFace { line: line_no });
                }
                let g = match scanned.groups.iter().position(|x| *x == group) {
                    Some(g) => g,
                    None => {
                        scanned.groups.push(group.clone());
                        scanned.groups.len() - 1
                    }
                };
                scanned.faces.push((g as u32, n));
            }
            _ => {}
        }
    }
    if faces == 0 {
        return Err(ObjError::NoFaces);
    }
    for &(line, index) in &corners {
        match usize::try_from(index).ok().and_then(|k| used.get_mut(k)) {
            Some(u) => *u = 0, // (used)
            None => return Err(ObjError::NoSuchVertex { line, index: index + 1, count }),
        }
    }
    match used.iter().position(|&line| line != 0) {
        Some(vertex) => Err(ObjError::Unreferenced { vertex, line: used[vertex] }),
        None => Ok(scanned),
    }
}

/// Writes positions (m) as `v`, material coordinates (m) as `vt`, vertex normals as `vn`, and
/// faces `f v/vt/vn`, smoothing on (`s 1`), so that a DCC shades the frame smooth.
pub fn write(
    path: &Path,
    positions: &[DVec3],
    uv: &[DVec2],
    normals: &[DVec3],
    faces: &[[u32; 3]],
) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    for p in positions {
        writeln!(w, "v {:.17e} {:.17e} {:.17e}", p.x, p.y, p.z)?;
    }
    for t in uv {
        writeln!(w, "vt {:.17e} {:.17e}", t.x, t.y)?;
    }
    for n in normals {
        writeln!(w, "vn {:.9e} {:.9e} {:.9e}", n.x, n.y, n.z)?;
    }
    writeln!(w, "s 1")?;
    for f in faces {
        let (a, b, c) = (f[0] + 1, f[1] + 1, f[2] + 1);
        writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?;
    }
    w.flush()
}

/// Writes a frame of a layer as `dir`/obj/<patch>/<layer>/<frame, 5 digits>.obj (`write`),
/// making the folders; returns the file's path with the error.
pub fn write_frame(
    dir: &Path,
    (patch, layer, frame): (&str, &str, u32),
    positions: &[DVec3],
    uv: &[DVec2],
    normals: &[DVec3],
    faces: &[[u32; 3]],
) -> Result<(), (std::path::PathBuf, std::io::Error)> {
    let folder = dir.join("obj").join(patch).join(layer);
    let file = folder.join(format!("{frame:05}.obj"));
    std::fs::create_dir_all(&folder).and_then(|_| write(&file, positions, uv, normals, faces)).map_err(|e| (file, e))
}

/// Removes the OBJ frames an earlier run wrote under `dir` (obj/<patch>/<layer>/<5 digits>.obj,
/// and the folders that leaves empty), so that a rerun's folder holds only its own frames;
/// nothing else is touched.
pub fn clear_frames(dir: &std::path::Path) -> std::io::Result<()> {
    clear_frames_after(dir, 0).map(|_| ())
}

/// Removes the OBJ frames after `frame` under `dir` (a resumed run's: what the interrupted run
/// wrote after its checkpoint), as `clear_frames` does all of them. Frame 0 is the rest state,
/// written by the first frame: it goes only with `frame` 0.
pub fn clear_frames_after(dir: &std::path::Path, after: u32) -> std::io::Result<()> {
    let obj = dir.join("obj");
    let folders = |d: &std::path::Path| -> std::io::Result<Vec<std::path::PathBuf>> {
        let mut v = Vec::new();
        for e in std::fs::read_dir(d)? {
            let e = e?;
            if e.file_type()?.is_dir() {
                v.push(e.path());
            }
        }
        Ok(v)
    };
    if !obj.is_dir() {
        return Ok(());
    }
    for patch in folders(&obj)? {
        for layer in folders(&patch)? {
            for e in std::fs::read_dir(&layer)? {
                let path = e?.path();
                let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
                let number = name
                    .strip_suffix(".obj")
                    .filter(|s| s.len() == 5 && s.bytes().all(|b| b.is_ascii_digit()))
                    .and_then(|s| s.parse::<u32>().ok());
                let stale = number.is_some_and(|f| after == 0 || f > after);
                if stale && path.is_file() {
                    std::fs::remove_file(&path)?;
                }
            }
            let _ = std::fs::remove_dir(&layer); // (only when empty)
        }
        let _ = std::fs::remove_dir(&patch);
    }
    let _ = std::fs::remove_dir(&obj);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(name: &str, text: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("skinsim-obj-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// A 3 x 3 vertex sheet: its left column of quads in group `a`, its right one in `b`, with a
    /// material switch inside `b` (which also starts a tobj model).
    const TWO_GROUPS: &str = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nv 0 2 0\nv 1 2 0\nv 2 2 0\n\
        g a\nf 1 2 5 4\nf 4 5 8 7\ng b\nusemtl skin\nf 2 3 6 5\nusemtl other\nf 5 6 9 8\n";

    #[test]
    fn groups_share_their_vertices() {
        let (m, groups) = load_groups(&file("two.obj", TWO_GROUPS), 1.0).unwrap();
        assert_eq!(m.rest.len(), 9, "one vertex array across groups");
        assert_eq!(m.faces.len(), 8);
        assert_eq!(groups.names, ["a", "b"]);
        assert_eq!(groups.of_face, [0, 0, 0, 0, 1, 1, 1, 1]);
        // Each face's group holds its corners: group a's faces lie at x <= 1, b's at x >= 1.
        for (f, g) in m.faces.iter().zip(&groups.of_face) {
            let xs = f.map(|i| m.rest[i as usize].x);
            assert!(xs.iter().all(|&x| if *g == 0 { x <= 1.0 } else { x >= 1.0 }), "{f:?} in {g}");
        }
        // The sheet is connected: every vertex but the 4 corners is in more than one triangle
        // and the middle column belongs to both groups.
        let middle = m.rest.iter().position(|p| *p == DVec3::new(1.0, 1.0, 0.0)).unwrap() as u32;
        let of_middle: std::collections::BTreeSet<u32> =
            m.faces.iter().zip(&groups.of_face).filter(|(f, _)| f.contains(&middle)).map(|(_, g)| *g).collect();
        assert_eq!(of_middle.len(), 2);
        assert!(crate::mesh::topology::check_surface(&m).is_ok());
    }

    #[test]
    fn a_face_repeated_in_another_group_is_caught() {
        let text = format!("{TWO_GROUPS}g c\nf 1 2 5 4\n");
        let m = load(&file("dup.obj", &text), 1.0).unwrap();
        assert!(crate::mesh::topology::check_surface(&m).is_err(), "the repeat in group c is a duplicate face");
        // and a fin that a third group hangs on an edge of the sheet is a non-manifold edge
        let text = format!("{TWO_GROUPS}v 1 1 1\ng fin\nf 2 5 10\n");
        let m = load(&file("fin.obj", &text), 1.0).unwrap();
        assert!(matches!(
            crate::mesh::topology::check_surface(&m),
            Err(crate::mesh::topology::MeshError::NonManifold { count: 3, .. })
        ));
    }
}
