//! Helpers shared by the integration tests, one module per area.

pub mod clean;
pub mod cp;
pub mod daemon;
pub mod data;
pub mod exports;
pub mod faults;
pub mod fuzz_seeds;
pub mod library;
pub mod lm;
pub mod mounting;
pub mod store;
