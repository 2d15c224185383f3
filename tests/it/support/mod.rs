//! Helpers shared by the integration tests, one module per area.

pub mod clean;
pub mod cp;
pub mod daemon;
pub mod data;
pub mod exports;
pub mod faults;
pub mod fuzz_seeds;
pub mod http;
pub mod library;
pub mod lm;
pub mod mounting;
pub mod store;

/// What a test does when something it needs is missing (`what`, and `how`
/// to provide it): it fails, naming both. A developer who cannot provide
/// it opts out with `skip_var=1`: the test then prints `skipped: …` on
/// stderr and returns early, so the skip stays visible. `require_var=1`
/// (the former switch, set by older scripts) overrides the opt-out.
#[track_caller]
pub fn missing(what: &str, how: &str, skip_var: &str, require_var: &str) {
    let set = |var: &str| std::env::var(var).is_ok_and(|v| v == "1");
    if set(require_var) {
        panic!("{what}: {how} ({require_var}=1 is set)");
    }
    if set(skip_var) {
        eprintln!("skipped: {what} ({skip_var}=1)");
        return;
    }
    panic!("{what}: {how}, or set {skip_var}=1 to skip the tests that need it");
}
