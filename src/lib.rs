//! morphoid: identify anatomical surfaces with the continuous Procrustes
//! distance.
//!
//! The library is layered; each layer only uses the ones above it:
//! - [`hash`], [`atomic_write`]: content hashes and atomic file replacement;
//! - [`stats`]: order statistics over plain numbers;
//! - [`present`]: what every output shares (markup escaping, PNG bytes,
//!   error lines);
//! - [`mesh`]: the triangle-mesh type, file formats, synthetic surfaces;
//! - [`clean`]: turn a raw scan into a clean disk-type surface;
//! - [`conformal`]: normalization and conformal flattening to the unit disk;
//! - [`cp`]: prepared surfaces and the continuous Procrustes distance;
//! - [`cwn`]: the conformal Wasserstein neighbourhood dissimilarity distance;
//! - [`cw`]: the conformal Wasserstein distance (transport over Möbius maps);
//! - [`pipeline`]: one file or mesh to one prepared surface;
//! - [`config`]: the TOML configuration;
//! - [`eval`]: distance matrices and leave-one-out classification;
//! - [`landmarks`]: landmark files and their propagation between surfaces;
//! - [`library`]: the reference library folder, its cache of prepared
//!   references, and identification (nearest taxon per rank);
//! - [`collection`]: a whole collection in correspondence (pseudolandmarks,
//!   GPA, PCA);
//! - [`store`]: the SQLite record of references, scans, results and distances;
//! - [`report`]: per-scan HTML reports and the overview page;
//! - [`classify`]: one scan through preparation, comparison, identification
//!   and the store;
//! - [`http`]: the web console and JSON API inside `morphoid run`, and
//!   the curators' decisions;
//! - [`daemon`]: the export-folder watcher and job loop behind `morphoid run`.
//!
//! See `ARCHITECTURE.md` at the repository root for the data flow.

#![forbid(unsafe_code)]

pub mod atomic_write;
pub mod classify;
pub mod clean;
pub mod collection;
pub mod completeness;
pub mod config;
pub mod conformal;
pub mod cp;
pub mod cw;
pub mod cwn;
pub mod daemon;
pub mod eval;
pub mod hash;
pub mod http;
pub mod landmarks;
pub mod library;
pub mod mesh;
pub mod pipeline;
pub mod present;
pub mod report;
pub mod stats;
pub mod store;
pub mod volume;
