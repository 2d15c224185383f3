//! The console's pages: the overview with its filters and live rows, a
//! scan's report from the database with its decisions, the library, the
//! daemon's state; everything a scan's file name holds is escaped, and
//! only the console's own scripts may run.

use crate::support::http::{identified, settings, Console};
use morphoid_service::store::Store;

/// A page's body, after checking its status and its script policy: every
/// `<script>` carries the nonce the Content-Security-Policy names.
fn page(c: &Console, path: &str, status: u16) -> String {
    let r = c.get(path);
    assert_eq!(r.status().as_u16(), status, "{path}");
    let csp = r.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_string();
    assert!(csp.contains("default-src 'none'"), "{csp}");
    let nonce = csp
        .split("'nonce-")
        .nth(1)
        .and_then(|s| s.split('\'').next())
        .expect("a script nonce")
        .to_string();
    assert_eq!(r.headers()["x-content-type-options"], "nosniff");
    let html = r.text().unwrap();
    for tag in html
        .match_indices("<script")
        .map(|(i, _)| &html[i..i + 60.min(html.len() - i)])
    {
        if !tag.starts_with("<script type=\"application/json\"") {
            assert!(tag.contains(&format!("nonce=\"{nonce}\"")), "{path}: {tag}");
        }
    }
    html
}

#[test]
fn http_pages_show_the_overview_reports_library_and_daemon() {
    let c = Console::start(&settings(true));
    let s = c.ids;
    let hostile = identified(
        &mut Store::open(&c.db).unwrap(),
        "export/<img src=x onerror=alert(1)>\".ply",
        9,
        "<script>alert(2)</script>",
        "Atelidae",
        false,
    );

    let overview = page(&c, "/", 200);
    for id in [
        s.ateles_1, s.alouatta, s.broken, s.pending, s.ateles_5, hostile,
    ] {
        assert!(
            overview.contains(&format!("href=\"/scans/{id}\"")),
            "scan {id} missing"
        );
    }
    assert!(overview.contains("<form id=\"filters\""));
    assert!(
        overview.contains("/api/v1/changes"),
        "the live rows' script"
    );
    assert!(!overview.contains("<script>alert(2)"));
    assert!(!overview.contains("<img src=x"));
    assert!(overview.contains("&lt;img src=x onerror=alert(1)&gt;&quot;.ply"));
    assert!(overview.contains("&lt;script&gt;alert(2)&lt;/script&gt;"));

    let filtered = page(&c, "/?genus=Ateles&name=", 200);
    assert!(filtered.contains("ateles-1.ply") && filtered.contains("ateles-5.ply"));
    assert!(!filtered.contains("alouatta-2.ply") && !filtered.contains("broken.stl"));
    assert!(
        filtered.contains("value=\"Ateles\"")
            || filtered.contains("<option selected>genus</option>")
            || filtered.contains("genus")
    );
    let errors = page(&c, "/?status=error", 200);
    assert!(errors.contains("broken.stl") && !errors.contains("ateles-1.ply"));
    assert!(errors.contains("<option selected>error</option>"));
    let refused = c.get("/?colour=red");
    assert_eq!(refused.status().as_u16(), 400);
    assert!(refused.text().unwrap().contains("colour"));

    let report = page(&c, &format!("/scans/{}", s.alouatta), 200);
    assert!(report.contains("alouatta-2.ply"));
    assert!(report.contains("<b>Alouatta</b>") || report.contains("Alouatta"));
    assert!(report.contains("Curators' decisions"));
    assert!(report.contains("id=\"console-nav\""));
    assert!(
        report.contains("Log in</a> to confirm"),
        "anonymous: no form"
    );
    assert!(!report.contains("id=\"review-form\""));
    let failed = page(&c, &format!("/scans/{}", s.broken), 200);
    assert!(failed.contains("truncated"));
    let evil = page(&c, &format!("/scans/{hostile}"), 200);
    assert!(!evil.contains("<script>alert(2)") && !evil.contains("<img src=x"));
    assert!(evil.contains("&lt;script&gt;alert(2)&lt;/script&gt;"));
    assert_eq!(c.get("/scans/999").status().as_u16(), 404);

    let library = page(&c, "/library", 200);
    for i in 0..12 {
        assert!(
            library.contains(&format!("<td>ref{i:03}</td>")),
            "ref{i:03}"
        );
    }
    assert!(library.contains("12 references, 12 prepared"));

    let daemon = page(&c, "/status", 200);
    assert!(daemon.contains("not running"));
    assert!(daemon.contains("<span id=\"queue\">1</span> pending"));
    c.live.update(|d| {
        d.running = true;
        d.status_line = "idle, 12 references, 4 scans today".into();
        d.degraded = Some("degraded: results folder: read-only".into());
    });
    let daemon = page(&c, "/status", 200);
    assert!(daemon.contains("running: idle, 12 references, 4 scans today"));
    assert!(daemon.contains("degraded: results folder: read-only"));

    // A logged-in curator gets the decision form, with the scan's latest
    // decision as the one they saw.
    c.add_curator("ana");
    let session = c.login("ana", crate::support::http::PASSWORD).unwrap();
    let form = c
        .client
        .get(c.url(&format!("/scans/{}", s.ateles_1)))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert!(form.contains("id=\"review-form\""));
    assert!(form.contains("name=\"expected_latest\" value=\"none\""));
    for rank in ["order", "family", "genus"] {
        assert!(form.contains(&format!("name=\"taxon.{rank}\"")), "{rank}");
    }
}
