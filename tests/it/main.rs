//! The integration tests: one test crate, one module per area and topic.
//! Shared helpers live in `support`; the real teeth are found by
//! `support::data`. A test fails when the real teeth or root (the
//! storage-fault tests) are missing, unless `MORPHOID_SKIP_DATA=1` or
//! `MORPHOID_SKIP_ROOT=1` opts out: then it prints `skipped: …` on stderr.

mod support;

mod align_collection;
mod align_formats;
mod classify_result_files;
mod clean_cloud;
mod clean_crown;
mod clean_exports;
mod clean_pipeline;
mod clean_teeth;
mod clean_variants;
mod cli_batch;
mod cli_classify;
mod cli_config;
mod cli_cwn;
mod cli_demo;
mod cli_inspect;
mod conformal_cleaned_teeth;
mod conformal_compare_conjugate;
mod conformal_flatten;
mod conformal_teeth;
mod cp_accuracy;
mod cp_invariance;
mod cp_prepare_all;
mod cp_screen;
mod cp_synthetic;
mod cw_teeth;
mod cwn_teeth;
mod daemon_faults;
mod daemon_files;
mod daemon_integrity;
mod daemon_load;
mod daemon_notify;
mod daemon_reports;
mod daemon_serial;
mod daemon_signals;
mod daemon_unit;
mod eval_cli;
mod eval_shard;
mod fuzz_replay;
mod http_api;
mod http_auth;
mod http_browser;
mod http_config;
mod http_daemon;
mod http_library;
mod http_pages;
mod http_refusals;
mod http_reviews;
mod http_tls;
mod io_errors;
mod io_huge_header;
mod io_real_data;
mod io_roundtrip;
mod io_synth;
mod library_confidence;
mod library_heldout;
mod lm_classify;
mod lm_daemon;
mod lm_propagate;
mod ops_slurm;
mod report_browser;
mod report_pages;
mod store_basic;
mod store_crash;
mod store_landmarks;
mod store_wal;
mod volume_bad_batches;
mod volume_batch;
mod volume_mounted;
mod volume_scans;
mod volume_teeth;
