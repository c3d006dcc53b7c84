//! Small tools around the engine, shared by the `skinsim` binary and the tests.

pub mod asset;
pub mod bake;
pub mod field_error;
pub mod film;
pub mod handshake;
pub mod layout;
pub mod lk14_report;
pub mod out_lock;
pub mod plot;
pub mod report;
pub mod resume;
pub mod rrd_sink;
pub mod signals;
pub mod skin_section;
pub mod timing;
pub mod wrinkles;
