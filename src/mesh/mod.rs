//! Mesh topology, generators, checks and OBJ input/output. Plain arrays, no ECS.

pub mod bodies;
pub mod bounds;
pub mod generate;
pub mod hand;
pub mod imperfection;
pub mod locate;
pub mod obj;
pub mod remesh;
pub mod rig;
pub mod select;
pub mod shading;
pub mod subdivision;
pub mod topology;
pub mod usd;
pub mod uv_islands;
pub mod wrinkle_map;

pub use bounds::bounds;
pub use generate::{grid, tet_slab, Coarsening, CoarseningError, GridPattern, SlabPlanes};
pub use topology::{
    boundary_vertices, check_surface, compact, edges, grow_rings, surface_faces_of_tets, surface_of_tets, EdgeInfo,
    MeshError,
};

use glam::{DVec2, DVec3};

/// A triangle surface: rest positions (m), material coordinates (m) and faces.
#[derive(Clone, Debug, Default)]
pub struct SurfaceMesh {
    pub rest: Vec<DVec3>,
    pub uv: Vec<DVec2>,
    pub faces: Vec<[u32; 3]>,
}

/// A tetrahedral solid: rest positions (m) and positively oriented tetrahedra.
#[derive(Clone, Debug, Default)]
pub struct TetMesh {
    pub rest: Vec<DVec3>,
    pub tets: Vec<[u32; 4]>,
    /// Per tet, the hexahedral cell it fills with five others (`physics::cell`).
    pub cells: Vec<u32>,
}
