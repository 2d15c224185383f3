//! morphoid's data and formats: what is read from and written to files.
//!
//! Modules, each using only the ones listed before it (and the core):
//! - [`atomic_write`]: atomic file replacement;
//! - [`present`]: what every output shares (markup escaping, PNG bytes,
//!   error lines);
//! - [`table`]: CSV tables (labels, distance matrices);
//! - [`volume`]: slice stacks and volume files read into a working grid,
//!   hashed as read;
//! - [`hash`]: content hashes of files and slice folders;
//! - [`completeness`]: whether an export is complete;
//! - [`mesh_io`]: surface file formats (PLY, OBJ, STL, OFF, XYZ);
//! - [`pipeline`]: one file or mesh to prepared surfaces;
//! - [`landmarks`]: landmark files and their propagation between surfaces;
//! - [`library`]: the reference library folder and its cache of prepared
//!   references.

pub mod atomic_write;
pub mod completeness;
pub mod hash;
pub mod landmarks;
pub mod library;
pub mod mesh_io;
pub mod pipeline;
pub mod present;
pub mod shard;
pub mod table;
pub mod volume;
