//! A generated report and overview opened from disk in headless Chromium
//! (Debian's `chromium`, installed by `.ci/run`): no console message at
//! all (the pages log nothing, so any line is an error or an uncaught
//! exception), the 3D view draws (the page's own pixel check, read from the
//! dumped DOM), and a screenshot is not empty. WebGL runs on SwiftShader,
//! Chromium's software renderer. Skips without Chromium unless
//! `MORPHOID_REQUIRE_BROWSER=1`.

use super::report_pages::{report_path, reported};
use crate::support::browser::chromium_or_skip;
use std::path::Path;
use std::process::Command;

/// Headless Chromium on `page` with `extra` arguments: (stdout, console
/// lines of the log).
fn open(browser: &Path, page: &Path, extra: &[&str]) -> (String, Vec<String>) {
    let profile = tempfile::tempdir().unwrap();
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let o = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--use-gl=angle",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            "--window-size=1100,1400",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(&url)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{}: {stderr}", page.display());
    let console = stderr
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_string)
        .collect();
    (String::from_utf8_lossy(&o.stdout).into_owned(), console)
}

#[test]
fn reports_open_in_headless_chromium() {
    let Some(browser) = chromium_or_skip() else {
        return;
    };
    let r = reported();
    let report = report_path(&r.out, &r.good[0].0);

    let (dom, console) = open(&browser, &report, &["--dump-dom"]);
    assert!(console.is_empty(), "console: {console:#?}");
    let at = dom.find("id=\"viewer-check\"").expect("no #viewer-check");
    let drawn: i64 = dom[at..]
        .split("data-drawn=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or(-1);
    // The canvas is 880×440; the two crowns cover a good part of it.
    assert!(drawn > 880 * 440 / 20, "3D view drew {drawn} pixels");

    let (dom, console) = open(&browser, &r.out.join("index.html"), &["--dump-dom"]);
    assert!(console.is_empty(), "console: {console:#?}");
    assert!(dom.contains("tooth%201.ply.html"), "{dom}");

    let shot = r.env.root.join("shot.png");
    let (_, console) = open(
        &browser,
        &report,
        &[&format!("--screenshot={}", shot.display())],
    );
    assert!(console.is_empty(), "console: {console:#?}");
    let png = image::open(&shot).unwrap().to_rgb8();
    let inked = png
        .pixels()
        .filter(|p| p.0.iter().any(|&c| c < 200))
        .count();
    assert!(
        inked > (png.width() * png.height() / 50) as usize,
        "screenshot {}×{} has {inked} non-white pixels",
        png.width(),
        png.height()
    );
}
