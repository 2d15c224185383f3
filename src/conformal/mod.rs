//! Normalization and conformal flattening onto the unit disk.
//!
//! (to be implemented)
