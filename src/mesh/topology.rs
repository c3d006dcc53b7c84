//! Edges and adjacency, surface extraction, and the checks a mesh must pass before it is used.

use std::collections::HashMap;

use super::SurfaceMesh;

/// A problem with a mesh, with the element that shows it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("the mesh has no faces")]
    Empty,
    #[error("face {face} refers to vertex {vertex}, but the mesh has {count} vertices")]
    BadIndex { face: usize, vertex: u32, count: usize },
    #[error("face {face} is degenerate (repeated vertex or zero area)")]
    Degenerate { face: usize },
    #[error("faces {first} and {second} use the same three vertices")]
    Duplicate { first: usize, second: usize },
    #[error("edge ({a}, {b}) is shared by {count} faces (non-manifold)")]
    NonManifold { a: u32, b: u32, count: usize },
    #[error("vertex {vertex} is not used by any face")]
    Unreferenced { vertex: usize },
}

/// One undirected edge of a triangle mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeInfo {
    /// Endpoints, oriented as in the first face (`faces[0]`).
    pub v: [u32; 2],
    /// Adjacent faces; `faces[1] == u32::MAX` on the boundary.
    pub faces: [u32; 2],
    /// Vertex opposite the edge in each adjacent face.
    pub opposite: [u32; 2],
}

impl EdgeInfo {
    pub fn is_interior(&self) -> bool {
        self.faces[1] != u32::MAX
    }
}

/// Unique edges in a stable order (first appearance in face order). Assumes a checked mesh.
pub fn edges(faces: &[[u32; 3]]) -> Vec<EdgeInfo> {
    let mut index: HashMap<(u32, u32), usize> = HashMap::with_capacity(faces.len() * 2);
    let mut out: Vec<EdgeInfo> = Vec::with_capacity(faces.len() * 3 / 2 + 8);
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b, o) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            let key = (a.min(b), a.max(b));
            match index.get(&key) {
                Some(&e) => {
                    out[e].faces[1] = fi as u32;
                    out[e].opposite[1] = o;
                }
                None => {
                    index.insert(key, out.len());
                    out.push(EdgeInfo { v: [a, b], faces: [fi as u32, u32::MAX], opposite: [o, u32::MAX] });
                }
            }
        }
    }
    out
}

/// Per vertex (`n` of them): whether it lies on a boundary edge (an edge of one face).
pub fn boundary_vertices(faces: &[[u32; 3]], n: usize) -> Vec<bool> {
    let mut boundary = vec![false; n];
    for e in edges(faces).iter().filter(|e| !e.is_interior()) {
        boundary[e.v[0] as usize] = true;
        boundary[e.v[1] as usize] = true;
    }
    boundary
}

/// Grows a marked set of vertices by `rings` rings: each ring adds every vertex of a face that
/// has a marked vertex. Vertices farther than `rings` faces from the set stay unmarked.
pub fn grow_rings(faces: &[[u32; 3]], marked: &mut [bool], rings: u32) {
    for _ in 0..rings {
        let touched: Vec<[u32; 3]> = faces.iter().filter(|f| f.iter().any(|&v| marked[v as usize])).copied().collect();
        touched.iter().flatten().for_each(|&v| marked[v as usize] = true);
    }
}

/// Checks a surface: indices in range, no degenerate or duplicate faces, manifold edges
/// (at most two faces each), every vertex used.
pub fn check_surface(m: &SurfaceMesh) -> Result<(), MeshError> {
    if m.faces.is_empty() {
        return Err(MeshError::Empty);
    }
    let n = m.rest.len();
    let mut used = vec![false; n];
    let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(m.faces.len());
    let mut edge_count: HashMap<(u32, u32), usize> = HashMap::with_capacity(m.faces.len() * 2);
    for (fi, f) in m.faces.iter().enumerate() {
        for &v in f {
            if v as usize >= n {
                return Err(MeshError::BadIndex { face: fi, vertex: v, count: n });
            }
            used[v as usize] = true;
        }
        let (a, b, c) = (m.rest[f[0] as usize], m.rest[f[1] as usize], m.rest[f[2] as usize]);
        let scale = (b - a).length_squared().max((c - a).length_squared());
        if f[0] == f[1]
            || f[1] == f[2]
            || f[0] == f[2]
            || (b - a).cross(c - a).length_squared() <= 1e-24 * scale * scale
        {
            return Err(MeshError::Degenerate { face: fi });
        }
        let mut key = *f;
        key.sort_unstable();
        if let Some(&first) = seen.get(&key) {
            return Err(MeshError::Duplicate { first, second: fi });
        }
        seen.insert(key, fi);
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edge_count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut bad: Vec<_> = edge_count.into_iter().filter(|(_, c)| *c > 2).collect();
    bad.sort_unstable();
    if let Some(((a, b), count)) = bad.first() {
        return Err(MeshError::NonManifold { a: *a, b: *b, count: *count });
    }
    if let Some(vertex) = used.iter().position(|u| !u) {
        return Err(MeshError::Unreferenced { vertex });
    }
    Ok(())
}

/// Boundary triangles of a tetrahedral mesh, oriented outwards, in a stable order.
/// Elements over arbitrary vertex keys (entities, say) as indices into the keys they use, in
/// first-use order: (keys, elements).
pub fn compact<T: Copy + Eq + std::hash::Hash, const N: usize>(elements: &[[T; N]]) -> (Vec<T>, Vec<[u32; N]>) {
    let mut index: HashMap<T, u32> = HashMap::new();
    let mut keys = Vec::new();
    let indexed = elements
        .iter()
        .map(|e| {
            e.map(|k| {
                *index.entry(k).or_insert_with(|| {
                    keys.push(k);
                    (keys.len() - 1) as u32
                })
            })
        })
        .collect();
    (keys, indexed)
}

pub fn surface_of_tets(tets: &[[u32; 4]]) -> Vec<[u32; 3]> {
    surface_faces_of_tets(tets).into_iter().map(|(f, _)| f).collect()
}

/// The boundary faces of `tets` as [`surface_of_tets`] gives them, each with the index of the
/// tet it bounds.
pub fn surface_faces_of_tets(tets: &[[u32; 4]]) -> Vec<([u32; 3], usize)> {
    // Faces of a positively oriented tet (a, b, c, d) with outward normals.
    let mut count: HashMap<[u32; 3], (usize, [u32; 3], usize)> = HashMap::with_capacity(tets.len() * 2);
    let mut order = Vec::with_capacity(tets.len() * 4);
    for (i, t) in tets.iter().enumerate() {
        let [a, b, c, d] = *t;
        for f in [[a, c, b], [a, b, d], [a, d, c], [b, c, d]] {
            let mut key = f;
            key.sort_unstable();
            let e = count.entry(key).or_insert((0, f, i));
            if e.0 == 0 {
                order.push(key);
            }
            e.0 += 1;
        }
    }
    order.into_iter().filter(|k| count[k].0 == 1).map(|k| (count[&k].1, count[&k].2)).collect()
}

#[cfg(test)]
mod tests {

    #[test]
    fn compact_numbers_keys_in_first_use_order() {
        let (keys, tris) = compact(&[['c', 'a', 'b'], ['b', 'a', 'd']]);
        assert_eq!(keys, ['c', 'a', 'b', 'd']);
        assert_eq!(tris, [[0, 1, 2], [2, 1, 3]]);
    }

    use super::*;
    use glam::{DVec2, DVec3};

    fn quad() -> SurfaceMesh {
        SurfaceMesh {
            rest: vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            uv: vec![DVec2::ZERO; 4],
            faces: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    /// Issue 26 item 2: the settled region is the changed faces plus `rings` rings; the settle
    /// moves only the vertices it is given (`solve::settle`'s test), so everything beyond stays
    /// bitwise where it was.
    #[test]
    fn rings_grow_by_one_face_each_and_no_further() {
        // A strip of 10 x 1 cells, right triangles: vertex i at the bottom, 11 + i at the top.
        let m = crate::mesh::grid(DVec2::new(10.0, 1.0), (10, 1), crate::mesh::GridPattern::RightTriangle, 0.0);
        let column = |v: usize| m.uv[v].x.round() as i64;
        for rings in 0..4u32 {
            let mut marked = vec![false; m.uv.len()];
            marked.iter_mut().enumerate().filter(|(v, _)| column(*v) == 5).for_each(|(_, b)| *b = true);
            grow_rings(&m.faces, &mut marked, rings);
            for (v, &b) in marked.iter().enumerate() {
                assert_eq!(b, (column(v) - 5).abs() <= rings as i64, "vertex {v} with {rings} rings");
            }
        }
    }

    #[test]
    fn edges_of_a_quad() {
        let e = edges(&quad().faces);
        assert_eq!(e.len(), 5);
        let interior: Vec<_> = e.iter().filter(|e| e.is_interior()).collect();
        assert_eq!(interior.len(), 1);
        assert_eq!(interior[0].opposite, [1, 3]);
    }

    #[test]
    fn checks_catch_each_problem() {
        assert_eq!(check_surface(&quad()), Ok(()));
        let mut m = quad();
        m.faces.push([2, 0, 1]);
        assert!(matches!(check_surface(&m), Err(MeshError::Duplicate { .. })));
        let mut m = quad();
        m.faces[1] = [0, 2, 2];
        assert!(matches!(check_surface(&m), Err(MeshError::Degenerate { face: 1 })));
        let mut m = quad();
        m.rest.push(DVec3::Z);
        m.faces.push([0, 2, 4]);
        assert!(matches!(check_surface(&m), Err(MeshError::NonManifold { a: 0, b: 2, count: 3 })));
        let mut m = quad();
        m.rest.push(DVec3::Z);
        assert!(matches!(check_surface(&m), Err(MeshError::Unreferenced { vertex: 4 })));
    }
}
