//! morphoid's service: what `morphoid classify` and the daemon do with a
//! scan, on top of the core and the data crate.
//! - [`identify`]: the nearest taxon per rank and its calibration;
//! - [`config`]: the TOML configuration;
//! - [`store`]: the SQLite record of references, scans, results and distances;
//! - [`report`]: per-scan HTML reports and the overview page;
//! - [`classify`]: one scan through preparation, comparison, identification
//!   and the store;
//! - [`daemon`]: the export-folder watcher and job loop behind `morphoid run`;
//! - [`http`]: the web console and JSON API inside `morphoid run`, and
//!   the curators' decisions;
//! - [`app`]: what every command decides the same way (configuration
//!   source, caches, building and calibrating a library).

pub mod app;
pub mod classify;
pub mod config;
pub mod daemon;
pub mod http;
pub mod identify;
mod priority;
pub mod report;
pub mod store;
