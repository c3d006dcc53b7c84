//! Mesh topology, generators, checks and OBJ input/output. Plain arrays, no ECS.

pub mod bodies;
pub mod bounds;
pub mod crossing;
pub(crate) mod generate;
pub mod hand;
pub mod imperfection;
pub mod locate;
pub mod map_buffer;
pub mod obj;
pub mod remesh;
pub mod rig;
pub mod select;
pub mod shading;
pub mod subdivision;
pub mod topology;
pub mod usd;
pub(crate) mod uv_islands;
pub mod wrinkle_map;

/// Seeded randomness for the mesh modules' tests (rand_pcg behind the few draws they use).
#[cfg(test)]
pub(crate) mod test_rng {
    use rand::{Rng as _, SeedableRng};

    pub(crate) struct Rng(rand_pcg::Pcg64);

    impl Rng {
        pub(crate) fn new(seed: u64) -> Rng {
            Rng(rand_pcg::Pcg64::seed_from_u64(seed))
        }

        /// Uniform in [lo, hi).
        pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
            self.0.random_range(lo..hi)
        }

        /// Uniform in 0..n.
        pub(crate) fn below(&mut self, n: usize) -> usize {
            self.0.random_range(0..n)
        }

        pub(crate) fn coin(&mut self) -> bool {
            self.0.random()
        }
    }
}

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
