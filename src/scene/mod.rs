//! Scene files: the RON schema (serde), its validation, building meshes, and spawning into a World.
//!
//! `load` reads and validates a scene and builds every mesh, so `skinsim check` catches every
//! input error without running; `spawn` turns a built scene into entities.

pub mod anchors;
pub mod bounds;
mod build;
pub mod built;
mod character;
mod contact;
mod context;
mod couplings;
mod drivers;
pub mod error;
pub mod estimate;
mod geometry;
mod layers;
mod meshes;
mod preflight;
pub mod properties;
pub mod schema;
pub mod spawn;
pub mod targets;

pub use build::{load, load_str, load_str_within, load_within};
pub use built::BuiltScene;
pub use error::SceneError;
pub use meshes::MAX_GENERATED_VERTICES;
pub use spawn::spawn;
