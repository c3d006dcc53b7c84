//! Element energies with gradients and Hessians: pure functions on small fixed-size arrays.
//!
//! Every element maps its vertex positions (plus rest data and a material) to an energy,
//! a gradient and a Hessian. Constitutive energy densities are written once, generically over
//! `num_dual::DualNum`, so the same code yields the energy (f64) and the exact first and second
//! derivatives with respect to the deformation gradient (second-order forward AD). The chain
//! rule from F to vertex positions is linear (F = Ds B), so it is applied in closed form.

pub mod cell;
pub mod dual;
pub mod gaussian_bending;
pub mod hinge;
pub mod material;
pub mod membrane;
pub mod prestrain;
pub mod principal;
pub mod psd;
pub(crate) mod quadratic_bending;
pub mod spring;
pub mod tet;

pub use gaussian_bending::GaussianElem;
pub use hinge::{HingeModel, HingeRest};
pub use material::{plate_rigidity, ConstitutiveModel, Lame};
pub use psd::Projection;
pub use quadratic_bending::{BendingElement, QuadraticBending};

#[cfg(test)]
mod tests;
