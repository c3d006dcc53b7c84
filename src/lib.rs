//! skinsim: physically based wrinkling of multi-layer skin.
//!
//! The engine library: the ECS vocabulary (`model`), element energies (`physics`), meshes
//! (`mesh`), the solver (`solve`) and scene files (`scene`). Systems live in the
//! `skinsim-systems` package; the `skinsim` binary in `skinsim-cli`.
//!
//! An item is `pub` only when the systems, the tools, the tests or the benchmarks name it;
//! the rest is `pub(crate)` (`unreachable_pub` keeps it so).

#![warn(unreachable_pub)]

pub mod contact;
pub mod coupling;
pub mod mesh;
pub mod model;
pub mod physics;
pub mod scene;
pub mod solve;
