//! skinsim: physically based wrinkling of multi-layer skin.
//!
//! The engine library: the ECS vocabulary (`model`), element energies (`physics`), meshes
//! (`mesh`), the solver (`solve`) and scene files (`scene`). Systems live in the
//! `skinsim-systems` package; the `skinsim` binary in `skinsim-cli`.

pub mod coupling;
pub mod mesh;
pub mod model;
pub mod physics;
pub mod scene;
pub mod solve;
