//! Layer coupling: LK14 constraint kernels and the KCK18 surface walk.

pub mod geodesic;
pub mod kernels;
pub mod walk;
