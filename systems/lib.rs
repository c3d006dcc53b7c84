//! skinsim systems: one file per stage of the frame (ARCHITECTURE.md 2) and `schedule.rs`,
//! which orders them. Systems are thin adapters between the ECS and `skinsim`'s math.

pub mod anchors;
pub mod assemble;
pub mod attach;
pub mod capture;
pub mod checkpoint;
mod checkpoint_restore;
pub mod inspect;
pub mod kernels;
mod layer_arrays;
pub mod log;
pub mod log_anchors;
pub mod log_contact;
mod log_mesh;
pub mod log_read;
pub mod motion;
pub mod properties;
pub mod remesh;
mod remesh_contact;
mod remesh_write;
mod render_mesh;
pub mod schedule;
pub mod settle;
pub mod simulation;
pub mod solve;
pub mod writeback;

pub use schedule::{build_schedule, StageSet};
pub use simulation::{without_timings, FrameStats, Simulation};
