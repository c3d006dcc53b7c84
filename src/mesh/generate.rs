//! Procedural meshes: rectangular shell grids and layered tetrahedral slabs.

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

use super::{SurfaceMesh, TetMesh};

/// Triangle pattern of a rectangular grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum GridPattern {
    /// Odd rows shifted by half a cell: equilateral triangles when the row height is
    /// sqrt(3)/2 of the cell width (half triangles close the left and right sides).
    #[default]
    Equilateral,
    /// Each cell cut along the same diagonal.
    RightTriangle,
    /// Diagonals alternating in a checkerboard: no handedness, so bending does not couple to
    /// twist (a one-row strip of `RightTriangle` cells twists as it bends).
    Alternating,
}

/// A rectangular grid [0, size.x] x [0, size.y] at height z with `cells` cells.
pub fn grid(size: DVec2, cells: (u32, u32), pattern: GridPattern, z: f64) -> SurfaceMesh {
    let (nx, ny) = (cells.0 as usize, cells.1 as usize);
    let (dx, dy) = (size.x / nx as f64, size.y / ny as f64);
    let mut m = SurfaceMesh::default();
    let push = |m: &mut SurfaceMesh, x: f64, y: f64| {
        m.rest.push(DVec3::new(x, y, z));
        m.uv.push(DVec2::new(x, y));
        (m.rest.len() - 1) as u32
    };
    match pattern {
        GridPattern::RightTriangle | GridPattern::Alternating => {
            for j in 0..=ny {
                for i in 0..=nx {
                    push(&mut m, i as f64 * dx, j as f64 * dy);
                }
            }
            let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
            for j in 0..ny {
                for i in 0..nx {
                    let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                    if pattern == GridPattern::Alternating && (i + j) % 2 == 1 {
                        m.faces.push([a, b, d]);
                        m.faces.push([b, c, d]);
                    } else {
                        m.faces.push([a, b, c]);
                        m.faces.push([a, c, d]);
                    }
                }
            }
        }
        GridPattern::Equilateral => {
            // Even rows: x = i dx (nx + 1 vertices). Odd rows: 0, dx/2, 3dx/2, ..., size.x (nx + 2).
            let mut rows: Vec<Vec<u32>> = Vec::with_capacity(ny + 1);
            for j in 0..=ny {
                let y = j as f64 * dy;
                let row = if j % 2 == 0 {
                    (0..=nx).map(|i| push(&mut m, i as f64 * dx, y)).collect()
                } else {
                    let mut r = vec![push(&mut m, 0.0, y)];
                    r.extend((0..nx).map(|i| push(&mut m, (i as f64 + 0.5) * dx, y)));
                    r.push(push(&mut m, size.x, y));
                    r
                };
                rows.push(row);
            }
            for j in 0..ny {
                let (even, odd, odd_is_top) =
                    if j % 2 == 0 { (&rows[j], &rows[j + 1], true) } else { (&rows[j + 1], &rows[j], false) };
                // Walk along the strip: even has nx+1 vertices, odd nx+2.
                let mut tris = Vec::with_capacity(2 * nx + 1);
                for i in 0..=nx {
                    // triangle with base on odd row: odd[i], odd[i+1], even[i]
                    tris.push([odd[i], odd[i + 1], even[i]]);
                    if i < nx {
                        tris.push([even[i], odd[i + 1], even[i + 1]]);
                    }
                }
                for t in tris {
                    // Orient counter-clockwise (normal +z).
                    let [a, b, c] = t;
                    let (pa, pb, pc) = (m.uv[a as usize], m.uv[b as usize], m.uv[c as usize]);
                    let ccw = (pb - pa).perp_dot(pc - pa) > 0.0;
                    let _ = odd_is_top;
                    m.faces.push(if ccw { [a, b, c] } else { [a, c, b] });
                }
            }
        }
    }
    m
}

/// A slab of tetrahedra over [0, size.x] x [0, size.y], from z = top - sum(depths) to z = top.
/// `levels` lists, bottom to top, each layer's (depth, elements through it, grading): element
/// thicknesses grow geometrically from the layer's top down so that the bottom one is `grading`
/// times the top one (1 = uniform; > 1 refines towards the surface). Each grid cell is a
/// pair of triangles; each triangular prism is split into three tetrahedra with the diagonal
/// rule "lower-numbered bottom vertex to higher-numbered top vertex", which makes neighbouring
/// prisms conform. Each grid cell of a level is one hexahedral cell of six tetrahedra
/// (`TetMesh::cells`). Returns the mesh and, per tet, the index of its layer.
pub fn tet_slab(size: DVec2, cells: (u32, u32), top: f64, levels: &[(f64, u32, f64)]) -> (TetMesh, Vec<u32>) {
    let (nx, ny) = (cells.0 as usize, cells.1 as usize);
    let mut zs = Vec::new();
    let total: f64 = levels.iter().map(|l| l.0).sum();
    let mut z = top - total;
    zs.push(z);
    let mut layer_of_level = Vec::new();
    for (li, &(depth, n, grading)) in levels.iter().enumerate() {
        // Thickness of element i (bottom to top) relative to the top one: grading^((n-1-i)/(n-1)).
        let weight = |i: u32| if n > 1 { grading.powf((n - 1 - i) as f64 / (n - 1) as f64) } else { 1.0 };
        let sum: f64 = (0..n).map(weight).sum();
        let level_bottom = z;
        let mut acc = 0.0;
        for i in 0..n {
            acc += weight(i);
            z = if i + 1 == n { level_bottom + depth } else { level_bottom + depth * acc / sum };
            zs.push(z);
            layer_of_level.push(li as u32);
        }
    }
    let plane = (nx + 1) * (ny + 1);
    let mut mesh = TetMesh::default();
    for &z in &zs {
        for j in 0..=ny {
            for i in 0..=nx {
                mesh.rest.push(DVec3::new(size.x * i as f64 / nx as f64, size.y * j as f64 / ny as f64, z));
            }
        }
    }
    let mut layer = Vec::new();
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    for (k, &li) in layer_of_level.iter().enumerate() {
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                let cell = ((k * ny + j) * nx + i) as u32;
                for tri in [[a, b, c], [a, c, d]] {
                    let mut t = tri;
                    t.sort_unstable();
                    let bot = |v: usize| (k * plane + v) as u32;
                    let topv = |v: usize| ((k + 1) * plane + v) as u32;
                    let (i0, j0, k0) = (t[0], t[1], t[2]);
                    for tet in [
                        [bot(i0), bot(j0), bot(k0), topv(k0)],
                        [bot(i0), bot(j0), topv(j0), topv(k0)],
                        [bot(i0), topv(i0), topv(j0), topv(k0)],
                    ] {
                        mesh.tets.push(orient(&mesh.rest, tet));
                        mesh.cells.push(cell);
                        layer.push(li);
                    }
                }
            }
        }
    }
    (mesh, layer)
}

fn orient(x: &[DVec3], t: [u32; 4]) -> [u32; 4] {
    let p = |i: usize| x[t[i] as usize];
    let vol = (p(1) - p(0)).cross(p(2) - p(0)).dot(p(3) - p(0));
    if vol < 0.0 {
        [t[0], t[2], t[1], t[3]]
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{check_surface, surface_of_tets};

    #[test]
    fn grids_are_valid_and_cover_the_rectangle() {
        for pattern in [GridPattern::Equilateral, GridPattern::RightTriangle, GridPattern::Alternating] {
            let m = grid(DVec2::new(3.0, 2.0), (6, 4), pattern, 0.0);
            check_surface(&m).unwrap();
            let area: f64 = m
                .faces
                .iter()
                .map(|f| {
                    let p = |i: usize| m.uv[f[i] as usize];
                    0.5 * (p(1) - p(0)).perp_dot(p(2) - p(0))
                })
                .inspect(|a| assert!(*a > 0.0))
                .sum();
            assert!((area - 6.0).abs() < 1e-12, "{pattern:?}: {area}");
        }
    }

    #[test]
    fn slab_is_conforming_and_fills_its_volume() {
        let (m, layer) = tet_slab(DVec2::new(2.0, 1.0), (4, 2), 0.0, &[(1.0, 2, 1.0), (0.5, 1, 1.0)]);
        let vol: f64 = m
            .tets
            .iter()
            .map(|t| {
                let p = |i: usize| m.rest[t[i] as usize];
                (p(1) - p(0)).cross(p(2) - p(0)).dot(p(3) - p(0)) / 6.0
            })
            .inspect(|v| assert!(*v > 0.0))
            .sum();
        assert!((vol - 3.0).abs() < 1e-12);
        assert_eq!(layer.iter().filter(|&&l| l == 1).count(), 4 * 2 * 2 * 3);
        // A conforming mesh's boundary is exactly the box surface: 2 (nx ny + nx nz + ny nz) quads.
        let surf = surface_of_tets(&m.tets);
        assert_eq!(surf.len(), 2 * 2 * (4 * 2 + 4 * 3 + 2 * 3));
        // Cells: six tets each, eight distinct corners, filling one grid cell of one level.
        assert_eq!(m.cells.len(), m.tets.len());
        for c in 0..(4 * 2 * 3) as u32 {
            let tets: Vec<_> = m.tets.iter().zip(&m.cells).filter(|(_, &k)| k == c).map(|(t, _)| *t).collect();
            assert_eq!(tets.len(), 6, "cell {c}");
            let mut corners: Vec<u32> = tets.iter().flatten().copied().collect();
            corners.sort_unstable();
            corners.dedup();
            assert_eq!(corners.len(), 8, "cell {c}");
        }
    }
}
