//! Headless Chromium for the tests that open pages (Debian's `chromium`,
//! installed by `.ci/run`).

use std::path::PathBuf;

/// The Chromium binary, or `None` (with `skipped: …` on stderr) when it is
/// not installed; with `MORPHOID_REQUIRE_BROWSER` set its absence fails
/// the test instead.
pub(crate) fn chromium_or_skip() -> Option<PathBuf> {
    let found = ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find_map(|name| {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|d| d.join(name))
                    .find(|p| p.is_file())
            })
        });
    if found.is_none() {
        assert!(
            std::env::var_os("MORPHOID_REQUIRE_BROWSER").is_none(),
            "MORPHOID_REQUIRE_BROWSER is set but chromium is not installed"
        );
        eprintln!("skipped: chromium is not installed");
    }
    found
}
