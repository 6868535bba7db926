//! Images: reading and writing PNG, EXR and PFM (`io`), and error metrics and per-pixel tests
//! against references (`metrics`).
pub mod io;
pub mod metrics;
