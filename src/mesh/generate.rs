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

/// In-plane coarsening of a slab with depth (issue 25 item 3): wrinkle displacements decay like
/// exp(-2 pi d / lambda) below the surface (H15 4.1), so deep planes need fewer vertices. Every
/// `every` below z = `from`, the grid halves along each axis whose cell count is even.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coarsening {
    pub every: f64,
    pub from: f64,
}

impl Coarsening {
    /// The grid of a vertex plane at height z, for the finest grid `cells`.
    pub(crate) fn cells_at(&self, cells: (u32, u32), z: f64) -> (u32, u32) {
        let level = ((self.from - z) / self.every + 1e-6).floor().max(0.0) as u32;
        // Counted, not iterated: a grid stops halving when its counts are odd, after at most
        // 32 halvings (a tiny `every` or a far `from` gave billions of levels).
        let mut c = cells;
        for _ in 0..level.min(64) {
            let h = halved(c);
            if h == c {
                break;
            }
            c = h;
        }
        c
    }
}

fn halved(c: (u32, u32)) -> (u32, u32) {
    let half = |n: u32| if n.is_multiple_of(2) { n / 2 } else { n };
    (half(c.0), half(c.1))
}

/// An element across which the grid would halve twice: its bottom and top z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseningError {
    pub bottom: f64,
    pub top: f64,
}

/// Where each vertex plane of a slab lies in its mesh, bottom to top: its first vertex and grid.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SlabPlanes {
    pub first: Vec<usize>,
    pub cells: Vec<(u32, u32)>,
}

/// A slab of tetrahedra over [0, size.x] x [0, size.y], from z = top - sum(depths) to z = top.
/// `levels` lists, bottom to top, each layer's (depth, elements through it, grading): element
/// thicknesses grow geometrically from the layer's top down so that the bottom one is `grading`
/// times the top one (1 = uniform; > 1 refines towards the surface). Each grid cell is a
/// pair of triangles; each triangular prism is split into three tetrahedra with the diagonal
/// rule "lower-numbered bottom vertex to higher-numbered top vertex", which makes neighbouring
/// prisms conform. Each grid cell of a level is one hexahedral cell of six tetrahedra
/// (`TetMesh::cells`). With `coarsen`, a vertex plane's grid is `Coarsening::cells_at` its
/// height; an element whose bottom grid is coarser is a transition cell (`transition_cell`).
/// Returns the mesh, per tet the index of its layer, and the vertex planes; an error when two
/// neighbouring planes' grids differ by more than one halving.
pub fn tet_slab(
    size: DVec2,
    cells: (u32, u32),
    top: f64,
    levels: &[(f64, u32, f64)],
    coarsen: Option<Coarsening>,
) -> Result<(TetMesh, Vec<u32>, SlabPlanes), CoarseningError> {
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
    let mut planes = SlabPlanes::default();
    let mut mesh = TetMesh::default();
    for &z in &zs {
        let (nx, ny) = coarsen.map_or(cells, |c| c.cells_at(cells, z));
        planes.first.push(mesh.rest.len());
        planes.cells.push((nx, ny));
        for j in 0..=ny {
            for i in 0..=nx {
                mesh.rest.push(DVec3::new(size.x * i as f64 / nx as f64, size.y * j as f64 / ny as f64, z));
            }
        }
    }
    let mut layer = Vec::new();
    let mut cell = 0u32;
    for (k, &li) in layer_of_level.iter().enumerate() {
        let (lower, upper) = (planes.cells[k], planes.cells[k + 1]);
        let at = |p: usize, i: usize, j: usize| (planes.first[p] + j * (planes.cells[p].0 as usize + 1) + i) as u32;
        let (nx, ny) = (lower.0 as usize, lower.1 as usize);
        if lower != upper {
            if lower != halved(upper) {
                return Err(CoarseningError { bottom: zs[k], top: zs[k + 1] });
            }
            let f = ((upper.0 / lower.0) as usize, (upper.1 / lower.1) as usize);
            for j in 0..ny {
                for i in 0..nx {
                    for tet in transition_cell(|p, i, j| at(k + p, i, j), (i, j), f) {
                        mesh.tets.push(orient(&mesh.rest, tet));
                        mesh.cells.push(cell);
                        layer.push(li);
                    }
                    cell += 1;
                }
            }
            continue;
        }
        for j in 0..ny {
            for i in 0..nx {
                let id = |i: usize, j: usize| j * (nx + 1) + i;
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                for tri in [[a, b, c], [a, c, d]] {
                    let mut t = tri;
                    t.sort_unstable();
                    let bot = |v: usize| (planes.first[k] + v) as u32;
                    let topv = |v: usize| (planes.first[k + 1] + v) as u32;
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
                cell += 1;
            }
        }
    }
    Ok((mesh, layer, planes))
}

/// The tetrahedra of a transition cell: the coarse grid cell (i, j) of the lower plane under
/// f.0 x f.1 cells of the upper plane (`at(0 | 1, i, j)`: a vertex of the lower or upper plane).
/// The cell is convex, so coning from its lowest corner over the triangles of the faces that do
/// not hold that corner fills it without new vertices. Each quad is cut along its
/// (low, low)-(high, high) diagonal as the prisms are, and each side face is fanned from its
/// lower bottom corner, so neighbouring cells and the planes above and below conform.
fn transition_cell(
    at: impl Fn(usize, usize, usize) -> u32,
    (i, j): (usize, usize),
    f: (usize, usize),
) -> Vec<[u32; 4]> {
    let apex = at(0, i, j);
    let mut tris = Vec::new();
    let (fi, fj) = (f.0 * i, f.1 * j);
    for v in fj..fj + f.1 {
        for u in fi..fi + f.0 {
            let (a, b, c, d) = (at(1, u, v), at(1, u + 1, v), at(1, u + 1, v + 1), at(1, u, v + 1));
            tris.extend([[a, b, c], [a, c, d]]);
        }
    }
    // Side x = high: bottom (i + 1, j), (i + 1, j + 1); top along y.
    let fan = |tris: &mut Vec<[u32; 3]>, lo: u32, hi: u32, tops: Vec<u32>| {
        tris.push([lo, hi, *tops.last().unwrap()]);
        tris.extend(tops.windows(2).rev().map(|w| [lo, w[1], w[0]]));
    };
    fan(&mut tris, at(0, i + 1, j), at(0, i + 1, j + 1), (fj..=fj + f.1).map(|v| at(1, fi + f.0, v)).collect());
    fan(&mut tris, at(0, i, j + 1), at(0, i + 1, j + 1), (fi..=fi + f.0).map(|u| at(1, u, fj + f.1)).collect());
    tris.into_iter().map(|t| [apex, t[0], t[1], t[2]]).collect()
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
        let (m, layer, _) = tet_slab(DVec2::new(2.0, 1.0), (4, 2), 0.0, &[(1.0, 2, 1.0), (0.5, 1, 1.0)], None).unwrap();
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

    /// Signed volume of each tet (all positive) and the total.
    fn volumes(m: &TetMesh) -> f64 {
        m.tets
            .iter()
            .map(|t| {
                let p = |i: usize| m.rest[t[i] as usize];
                (p(1) - p(0)).cross(p(2) - p(0)).dot(p(3) - p(0)) / 6.0
            })
            .inspect(|v| assert!(*v > 1e-12, "a flat or inverted tet: {v}"))
            .sum()
    }

    #[test]
    fn a_grid_halves_only_while_it_can_however_many_levels_are_asked() {
        // 1e-12 m levels over 1 m: about 1e12 levels, which the grid stops needing after 6.
        // (the old loop iterated every level: 4e9 steps here, many seconds)
        let c = Coarsening { every: 1e-12, from: 1.0 };
        assert_eq!(c.cells_at((64, 96), 0.0), (1, 3));
        assert_eq!(Coarsening { every: 1e-3, from: 2e-3 }.cells_at((64, 96), 0.0), (16, 24));
    }

    #[test]
    fn a_coarsening_slab_is_conforming_and_fills_its_volume() {
        // 8 x 4 cells on top, halving every 0.3 below z = 0 through 1.5 deep in 5 elements (a
        // plane on a boundary takes the coarser grid): from the top 8x4, 4x2, 2x1, then 1x1 (each
        // axis halves while even); one cell across y (plane strain) coarsens along x alone.
        let coarsen = Coarsening { every: 0.3, from: 0.0 };
        for (cells, expect) in [
            ((8, 4), vec![(1, 1), (1, 1), (1, 1), (2, 1), (4, 2), (8, 4)]),
            ((8, 1), vec![(1, 1), (1, 1), (1, 1), (2, 1), (4, 1), (8, 1)]),
        ] {
            let (m, _, planes) = tet_slab(DVec2::new(2.0, 1.0), cells, 0.0, &[(1.5, 5, 1.0)], Some(coarsen)).unwrap();
            assert_eq!(planes.cells, expect);
            assert!((volumes(&m) - 3.0).abs() < 1e-12);
            // Conforming: the boundary is the box's surface, each of its faces cut by the grid of
            // the plane or planes it touches; no interior face is left unmatched.
            let surf = surface_of_tets(&m.tets);
            let area: f64 = surf
                .iter()
                .map(|f| {
                    let p = |i: usize| m.rest[f[i] as usize];
                    0.5 * (p(1) - p(0)).cross(p(2) - p(0)).length()
                })
                .sum();
            assert!((area - 2.0 * (2.0 + 2.0 * 1.5 + 1.5)).abs() < 1e-12, "{cells:?}: boundary area {area}");
            let on_box = |p: DVec3| {
                p.x.abs() < 1e-12
                    || (p.x - 2.0).abs() < 1e-12
                    || p.y.abs() < 1e-12
                    || (p.y - 1.0).abs() < 1e-12
                    || p.z.abs() < 1e-12
                    || (p.z + 1.5).abs() < 1e-12
            };
            let centroid = |f: &[u32; 3]| f.iter().map(|&v| m.rest[v as usize]).sum::<DVec3>() / 3.0;
            assert!(surf.iter().all(|f| on_box(centroid(f))), "{cells:?}: an interior face is unmatched");
        }
    }

    #[test]
    fn without_transitions_the_coarsening_slab_is_the_plain_one() {
        let plain = tet_slab(DVec2::new(2.0, 1.0), (4, 2), 0.0, &[(1.0, 3, 2.0)], None).unwrap();
        let far = Coarsening { every: 10.0, from: 0.0 };
        let coarse = tet_slab(DVec2::new(2.0, 1.0), (4, 2), 0.0, &[(1.0, 3, 2.0)], Some(far)).unwrap();
        assert_eq!(
            (plain.0.rest, plain.0.tets, plain.0.cells, plain.2),
            (coarse.0.rest, coarse.0.tets, coarse.0.cells, coarse.2)
        );
    }

    #[test]
    fn two_halvings_across_one_element_are_refused() {
        let steep = Coarsening { every: 0.1, from: 0.0 };
        let e = tet_slab(DVec2::new(2.0, 1.0), (8, 4), 0.0, &[(1.0, 2, 1.0)], Some(steep)).unwrap_err();
        assert_eq!(e, CoarseningError { bottom: -0.5, top: 0.0 });
    }
}
