//! Helpers shared by the integration tests, one module per area.

pub(crate) mod browser;
pub(crate) mod clean;
pub(crate) mod cp;
pub(crate) mod daemon;
pub(crate) mod data;
pub(crate) mod exports;
pub(crate) mod faults;
pub(crate) mod fuzz_seeds;
pub(crate) mod http;
pub(crate) mod library;
pub(crate) mod lm;
#[allow(dead_code)] // used by the benches, which include this module
pub(crate) mod measured;
pub(crate) mod store;

/// What a test does when something it needs is missing (`what`, and `how`
/// to provide it): it fails, naming both. A developer who cannot provide
/// it opts out with `skip_var=1` in the build's environment: `build.rs`
/// then compiles the tests that need it as ignored, with the reason, so
/// they never get here; if they are run anyway (`--ignored`), this prints
/// `skipped: …` on stderr and the test returns early. `require_var=1` (the
/// former switch, set by older scripts) overrides the opt-out.
#[track_caller]
pub(crate) fn missing(what: &str, how: &str, skip_var: &str, require_var: &str) {
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
