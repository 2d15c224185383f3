//! Prepared surfaces and the continuous Procrustes distance.
//!
//! (to be implemented)
