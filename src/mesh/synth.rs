//! Synthetic crown-like disk surfaces for tests and the demo.
//!
//! (to be implemented)
