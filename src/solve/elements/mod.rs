//! The registered element kinds: one file each, one line each in `elements!` below. Assemble
//! fills the lists from a patch's layers; the solver iterates over them as `Term`s in this
//! order, which is the order of every sum.

mod anchor;
mod cell;
mod contact;
mod friction;
mod gaussian;
mod hinge;
mod kernel_spring;
mod membrane;
mod pin;
mod quadratic;
mod spring;
mod tet;

pub use anchor::AnchorElem;
pub use cell::CellElem;
pub use hinge::HingeElem;
pub use kernel_spring::KernelSprings;
pub use membrane::MembraneElem;
pub use pin::PinElem;
pub use spring::SpringElem;
pub use tet::TetElem;

use glam::DVec3;

use super::element::{Term, TermList};
use crate::physics::{GaussianElem, QuadraticBending};

/// Declares `Elements`, one list per kind, and its iteration over them.
macro_rules! elements {
    ($( $(#[$doc:meta])* $field:ident: $ty:ty, )*) => {
        /// Element lists indexed by packed vertex number: what Assemble builds from a patch's
        /// layers and what the solver evaluates.
        #[derive(Clone, Debug, Default)]
        pub struct Elements {
            $( $(#[$doc])* pub $field: $ty, )*
        }

        impl Elements {
            /// Every kind, in registration order.
            pub(crate) fn terms(&self) -> Vec<&dyn Term> {
                vec![$( &self.$field as &dyn Term ),*]
            }

            /// The elements `which[kind]` of each kind, renumbered by `to` (the region solve).
            pub(crate) fn pick(&self, which: &[Vec<usize>], to: &dyn Fn(u32) -> u32) -> Elements {
                let mut kind = 0..;
                Elements { $( $field: self.$field.pick(&which[kind.next().unwrap()], to), )* }
            }
        }
    };
}

elements! {
    membranes: Vec<MembraneElem>,
    hinges: Vec<HingeElem>,
    /// Quadratic bending, one element per interior vertex (layers that choose it).
    quadratic: QuadraticBending,
    /// Its Gaussian-curvature term, per triangle (`gaussian_bending`).
    gaussian: Vec<GaussianElem>,
    tets: Vec<TetElem>,
    /// The lambda terms of volume layers with `VolumeElement::Cell` (their tets have lambda 0).
    cells: Vec<CellElem>,
    springs: Vec<SpringElem>,
    /// Anchors at skin vertices and at skin face barycentres (KCK18 section 3).
    vertex_anchors: Vec<AnchorElem<1>>,
    face_anchors: Vec<AnchorElem<3>>,
    /// Attachment springs from a vertex to a point of a face of another layer (an Attach whose
    /// layers are remeshed): v = [vertex, face corners], w = [1, -barycentric], target 0.
    face_springs: Vec<AnchorElem<4>>,
    pins: Vec<PinElem>,
    /// Released LK14 kernels held by soft springs (a patch with contact; `solve::release`).
    kernel_springs: KernelSprings,
    /// Barrier contact pairs near the state (a patch with `contact`; refreshed as it moves).
    contacts: crate::contact::ContactPairs,
    /// Lagged friction: the contact pairs touching at the frame's start (contact with friction).
    friction: crate::contact::FrictionPairs,
}

impl Elements {
    /// Sum of the elements' energies at unit strain (stiffness x volume): the scale of the
    /// round-off in an energy evaluation, whose densities cancel O(1) terms to O(strain^2).
    pub(crate) fn energy_scale(&self, length: f64) -> f64 {
        self.terms().iter().map(|t| t.unit_energy(length)).sum()
    }

    /// Kirchhoff's plate on a shell layer's triangles (`BendingElement::Quadratic`): the
    /// quadratic elements and their Gaussian term, from the hinges' stiffness (property maps
    /// and scale included). `n`: packed vertices (boundary detection).
    pub fn add_plate(
        &mut self,
        tris: &[[u32; 3]],
        rest_at: impl Fn(u32) -> DVec3,
        hinges: &[([u32; 4], f64)],
        n: usize,
        poisson: f64,
    ) {
        let boundary = crate::mesh::boundary_vertices(tris, n);
        let (q, g) = QuadraticBending::plate(tris, rest_at, hinges, &boundary, poisson);
        self.quadratic.extend(q);
        self.gaussian.extend(g);
    }

    /// A volume layer's tets, and its cells where `cell_of` groups them (`CellElem::group`).
    pub fn add_volume(&mut self, mut tets: Vec<TetElem>, cell_of: &[Option<u32>]) {
        self.cells.extend(CellElem::group(&mut tets, cell_of));
        self.tets.extend(tets);
    }
}
