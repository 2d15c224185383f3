//! Per-scan reports and the overview page, written by `classify --out-dir`
//! and by `morphoid report` from the database: what they show for an
//! identified scan, a failed one, and a scan whose file is gone.

use crate::support::daemon::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A deployment with two identified scans and one that failed, classified
/// with `--out-dir`: the environment, the results folder and the scans.
pub(crate) struct Reported {
    pub env: Env,
    pub out: PathBuf,
    /// `(path, genus index)` of the identified scans.
    pub good: Vec<(PathBuf, usize)>,
    pub bad: PathBuf,
}

/// Classify two synthetic crowns and a broken file into a results folder.
pub(crate) fn reported() -> Reported {
    let env = env(0.5, "", "");
    let good: Vec<(PathBuf, usize)> = [(1usize, 71u64), (4, 72)]
        .iter()
        .map(|&(g, seed)| {
            let p = env.export.join(format!("tooth {g}.ply"));
            put(&env, &p, &scan_bytes(g, seed));
            (p, g)
        })
        .collect();
    let bad = env.export.join("broken.ply");
    put(
        &env,
        &bad,
        b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    );
    let out = env.root.join("results");
    let o = Command::new(BIN)
        .args(["classify", "--config"])
        .arg(&env.config)
        .arg("--out-dir")
        .arg(&out)
        .arg(&good[0].0)
        .arg(&bad)
        .arg(&good[1].0)
        .output()
        .unwrap();
    // One scan failed: exit code 1, the others are recorded.
    assert!(
        !o.status.success(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    Reported {
        env,
        out,
        good,
        bad,
    }
}

/// The report of the scan at `scan` (in the export folder) under `out`.
pub(crate) fn report_path(out: &Path, scan: &Path) -> PathBuf {
    out.join(format!(
        "{}.html",
        scan.file_name().unwrap().to_string_lossy()
    ))
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The text of the element with `id` (the first tag carrying it, up to
/// its closing tag of the same name).
fn element<'a>(html: &'a str, id: &str) -> &'a str {
    let at = html
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no #{id}"));
    let open = html[..at].rfind('<').unwrap();
    let tag: String = html[open + 1..]
        .chars()
        .take_while(|c| c.is_alphanumeric())
        .collect();
    let end = html[at..].find(&format!("</{tag}>")).unwrap() + at;
    &html[open..end]
}

#[test]
fn reports_show_the_answer_the_pictures_and_the_error() {
    let r = reported();
    for (scan, g) in &r.good {
        let path = report_path(&r.out, scan);
        let html = read(&path);
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size < 3_000_000, "{}: {size} bytes", path.display());
        // The answer per rank, with the genus right, and the calibrated
        // confidence and flag as the JSON result records them.
        let ranks = element(&html, "ranks");
        assert!(ranks.contains(&format!("<b>{}</b>", genus(*g))), "{ranks}");
        let json: serde_json::Value =
            serde_json::from_str(&read(&path.with_extension("json"))).unwrap();
        let genus_rank = &json["ranks"]["genus"];
        match genus_rank["probability"].as_f64() {
            Some(p) => assert!(
                ranks.contains(&format!("{:.0} %", p * 100.0)),
                "{p}: {ranks}"
            ),
            None => assert!(ranks.contains("not calibrated"), "{ranks}"),
        }
        let novelty = element(&html, "novelty");
        match json["no_close_match"].as_bool() {
            Some(true) => assert!(novelty.contains("NO CLOSE MATCH"), "{novelty}"),
            Some(false) => assert!(novelty.contains("close match"), "{novelty}"),
            None => assert!(novelty.contains("not calibrated"), "{novelty}"),
        }
        // File name and hash, cleaning report and timings.
        let hash = morphoid_data::hash::content_hash(&std::fs::read(scan).unwrap());
        assert!(element(&html, "scan").contains(&hash));
        assert!(element(&html, "scan").contains(&format!("tooth {g}.ply")));
        assert!(element(&html, "cleaning").contains("<th>output</th>"));
        assert!(element(&html, "cleaning-values").contains("output_vertices"));
        assert!(element(&html, "timings").contains("compare"));
        // Three pairs of pictures (scan and reference) and the 3D view.
        assert_eq!(html.matches("data:image/png;base64,").count(), 6);
        assert!(html.contains("id=\"scene-data\""));
        assert!(html.contains("<canvas id=\"viewer\""));
        assert!(!html.contains("http://") && !html.contains("https://"));
        // The thumbnail is a PNG of the scan.
        let thumb = r.out.join(format!(
            "{}.png",
            scan.file_name().unwrap().to_string_lossy()
        ));
        let png = image::open(&thumb).unwrap().to_rgba8();
        let drawn = png.pixels().filter(|p| p[3] != 0).count();
        assert!(drawn > 500, "{}: {drawn} pixels drawn", thumb.display());
    }
    // The failed scan's report shows its error plainly.
    let html = read(&report_path(&r.out, &r.bad));
    let error = element(&html, "error");
    assert!(error.contains("broken.ply"), "{error}");
    assert!(!html.contains("id=\"ranks\""));
    // The overview: newest first, each linking to its report.
    let index = read(&r.out.join("index.html"));
    let order: Vec<usize> = [
        "tooth%204.ply.html",
        "broken.ply.html",
        "tooth%201.ply.html",
    ]
    .iter()
    .map(|l| index.find(&format!("href=\"{l}\"")).unwrap())
    .collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{order:?}");
    assert!(index.contains(&format!("<b>{}</b>", genus(4))));
    assert!(index.contains("tooth%201.ply.png"));
    assert!(element(&index, "scans").contains("class=\"bad\""));
}

#[test]
fn report_command_writes_from_the_database_and_says_when_the_file_is_gone() {
    let r = reported();
    let again = r.env.root.join("again");
    let o = Command::new(BIN)
        .args(["report", "--last", "3", "--config"])
        .arg(&r.env.config)
        .arg("--out")
        .arg(&again)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (scan, g) in &r.good {
        let html = read(&report_path(&again, scan));
        assert!(element(&html, "ranks").contains(&format!("<b>{}</b>", genus(*g))));
        assert_eq!(html.matches("data:image/png;base64,").count(), 6);
    }
    assert!(element(&read(&report_path(&again, &r.bad)), "error").contains("broken.ply"));
    assert!(again.join("index.html").is_file());

    // The file is gone: the recorded result, and a note instead of pictures.
    let (scan, g) = &r.good[0];
    std::fs::remove_file(scan).unwrap();
    let gone = r.env.root.join("gone");
    let rows = rows(&r.env.db);
    let id = rows.iter().find(|x| Path::new(&x.path) == scan).unwrap().id;
    let o = Command::new(BIN)
        .args(["report", &id.to_string(), "--config"])
        .arg(&r.env.config)
        .arg("--out")
        .arg(&gone)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = read(&report_path(&gone, scan));
    assert!(element(&html, "note").contains("gone"), "{html}");
    assert!(element(&html, "ranks").contains(&format!("<b>{}</b>", genus(*g))));
    assert!(!html.contains("data:image/png"));
}

#[test]
fn an_unwritable_results_folder_is_an_error_and_the_identification_stands() {
    let env = env(0.5, "", "");
    let scan = env.export.join("tooth.ply");
    put(&env, &scan, &scan_bytes(2, 81));
    // A folder below a regular file cannot be created, even by root.
    let blocker = env.root.join("not-a-folder");
    std::fs::write(&blocker, b"x").unwrap();
    let o = Command::new(BIN)
        .args(["classify", "--config"])
        .arg(&env.config)
        .arg("--out-dir")
        .arg(blocker.join("results"))
        .arg(&scan)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("result files") && stderr.contains("not-a-folder"),
        "{stderr}"
    );
    let rows = rows(&env.db);
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].status, morphoid_service::store::ScanStatus::Ok);
    assert_eq!(genus_of(&rows[0]), Some(genus(2)));
}
