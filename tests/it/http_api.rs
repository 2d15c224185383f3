//! The console's JSON API, `/healthz`, `/metrics` and the OpenAPI
//! document, over a real socket with a real client, on a database filled
//! as the daemon fills it.

use crate::support::http::{settings, Console, REFERENCES};
use morphoid_service::report::utc_time;
use morphoid_service::store::{now_ms, Store};
use serde_json::Value;

/// The ids of a page of scans, in order.
fn ids(page: &Value) -> Vec<i64> {
    page["scans"]
        .as_array()
        .expect("scans")
        .iter()
        .map(|s| s["id"].as_i64().expect("id"))
        .collect()
}

#[test]
fn http_api_lists_filters_and_pages_scans() {
    let c = Console::start(&settings(true));
    let s = c.ids;
    let all = c.get_json("/api/v1/scans", None, 200);
    assert_eq!(
        ids(&all),
        [s.ateles_5, s.pending, s.broken, s.alouatta, s.ateles_1]
    );
    assert_eq!(all["next_cursor"], Value::Null);
    let first = &all["scans"][0];
    assert_eq!(first["scan"], "export/a/ateles-5.ply");
    assert_eq!(first["status"], "ok");
    assert_eq!(first["ranks"]["genus"]["taxon"], "Ateles");
    assert_eq!(first["ranks"]["genus"]["probability"], 0.9);
    assert_eq!(first["no_close_match"], false);
    assert!(first["created_at_ms"].as_i64().unwrap() > 0);
    assert!(first["finished_at_ms"].as_i64().unwrap() >= first["created_at_ms"].as_i64().unwrap());
    assert_eq!(first["review"], Value::Null);
    assert_eq!(
        all["scans"][2]["error"],
        "cannot read export/c/broken.stl: truncated"
    );

    let by = |q: &str| ids(&c.get_json(&format!("/api/v1/scans?{q}"), None, 200));
    assert_eq!(by("genus=Ateles"), [s.ateles_5, s.ateles_1]);
    assert_eq!(by("rank=genus&taxon=ateles"), [s.ateles_5, s.ateles_1]);
    assert_eq!(by("family=Atelidae&genus=Alouatta"), [s.alouatta]);
    assert_eq!(by("genus=Cebus"), Vec::<i64>::new());
    assert_eq!(by("status=error"), [s.broken]);
    assert_eq!(by("status=pending"), [s.pending]);
    assert_eq!(by("no_close_match=true"), [s.alouatta]);
    assert_eq!(by("no_close_match=false"), [s.ateles_5, s.ateles_1]);
    assert_eq!(by("name=ALOUATTA"), [s.alouatta]);
    assert_eq!(by("name=export/a/"), [s.ateles_5, s.ateles_1]);
    let today = &utc_time(now_ms())[..10];
    assert_eq!(by(&format!("since={today}")).len(), 5);
    assert_eq!(by(&format!("until={today}")).len(), 5);
    assert_eq!(by("until=2001-01-01"), Vec::<i64>::new());
    assert_eq!(by("since=2001-01-01&until=2001-01-31"), Vec::<i64>::new());
    // Empty values (as a form sends them) filter nothing.
    assert_eq!(by("status=&genus=&name=").len(), 5);

    // Pages by cursor cover every scan once, in order.
    let mut seen = Vec::new();
    let mut next = String::from("/api/v1/scans?limit=2");
    loop {
        let page = c.get_json(&next, None, 200);
        assert!(ids(&page).len() <= 2);
        seen.extend(ids(&page));
        match page["next_cursor"].as_i64() {
            Some(cursor) => next = format!("/api/v1/scans?limit=2&cursor={cursor}"),
            None => break,
        }
        assert!(seen.len() <= 5, "paging does not end: {seen:?}");
    }
    assert_eq!(seen, ids(&all));
    assert_eq!(by("limit=2&offset=2"), [s.broken, s.alouatta]);

    for (query, named) in [
        ("colour=red", "colour"),
        ("status=done", "status"),
        ("limit=0", "limit"),
        ("since=yesterday", "since"),
        ("taxon=Ateles", "rank"),
        ("cursor=x", "cursor"),
    ] {
        let e = c.get_json(&format!("/api/v1/scans?{query}"), None, 400);
        let message = e["error"].as_str().expect("error text");
        assert!(message.contains(named), "{query}: {message}");
    }
}

#[test]
fn http_api_serves_a_scan_the_library_the_status_health_and_metrics() {
    let c = Console::start(&settings(true));
    let s = c.ids;
    let scan = c.get_json(&format!("/api/v1/scans/{}", s.alouatta), None, 200);
    assert_eq!(scan["id"], s.alouatta);
    assert_eq!(scan["ranks"]["genus"]["taxon"], "Alouatta");
    assert_eq!(scan["ranks"]["genus"]["no_close_match"], true);
    assert_eq!(scan["no_close_match"], true);
    assert_eq!(scan["nearest"].as_array().unwrap().len(), 5);
    assert_eq!(scan["reviews"], serde_json::json!([]));
    for missing in ["999", "0", "-1", "abc", "1.0", "+1"] {
        let e = c.get_json(&format!("/api/v1/scans/{missing}"), None, 404);
        assert!(e["error"].as_str().unwrap().contains("scan"), "{missing}");
    }

    let refs = c.get_json("/api/v1/references", None, 200);
    assert_eq!(refs["count"], REFERENCES);
    let names: Vec<&str> = refs["references"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(names.len(), REFERENCES);
    assert!(names.contains(&"ref000") && names.contains(&"ref011"));
    assert_eq!(refs["references"][0]["state"], "prepared");
    assert_eq!(refs["references"][0]["labels"]["order"], "Primates");

    let status = c.get_json("/api/v1/status", None, 200);
    assert_eq!(status["running"], false);
    assert_eq!(status["queue_length"], 1);
    assert_eq!(status["counts"]["ok"], 3);
    assert_eq!(status["counts"]["error"], 1);
    assert_eq!(status["degraded"], Value::Null);
    assert_eq!(status["version"], env!("CARGO_PKG_VERSION"));
    // What the daemon publishes shows.
    c.live.update(|d| {
        d.running = true;
        d.references = REFERENCES;
        d.calibration = "calibrating".into();
        d.degraded = Some("degraded: database: disk full".into());
        d.current_scan = Some(s.pending);
    });
    let status = c.get_json("/api/v1/status", None, 200);
    assert_eq!(status["running"], true);
    assert_eq!(status["degraded"], "degraded: database: disk full");
    assert_eq!(status["current_scan"], s.pending);
    assert_eq!(status["calibration"], "calibrating");

    // `changes` moves when a scan arrives.
    let before = c.get_json("/api/v1/changes", None, 200)["changes"].clone();
    assert_eq!(before, status["changes"]);
    Store::open(&c.db)
        .unwrap()
        .enqueue("export/e/new.ply", "hash-new", 5)
        .unwrap();
    let after = c.get_json("/api/v1/changes", None, 200)["changes"].clone();
    assert_ne!(before, after);

    assert_eq!(c.get_json("/healthz", None, 200)["status"], "ok");

    let metrics = c.get("/metrics");
    assert_eq!(metrics.status().as_u16(), 200);
    assert!(metrics.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/plain; version=0.0.4"));
    let text = metrics.text().unwrap();
    for line in [
        "morphoid_scans{status=\"ok\"} 3",
        "morphoid_scans{status=\"error\"} 1",
        "morphoid_scans{status=\"pending\"} 2",
        "morphoid_queue_length 2",
        "morphoid_identification_seconds_count 3",
        "morphoid_identification_seconds_bucket{le=\"+Inf\"} 3",
        "morphoid_degraded 1",
        "morphoid_calibrating 1",
        "morphoid_references 12",
        "# TYPE morphoid_identification_seconds histogram",
    ] {
        assert!(text.lines().any(|l| l == line), "{line} missing:\n{text}");
    }
    // Cumulative buckets never decrease and end at the count.
    let buckets: Vec<u64> = text
        .lines()
        .filter(|l| l.starts_with("morphoid_identification_seconds_bucket"))
        .map(|l| l.rsplit(' ').next().unwrap().parse().unwrap())
        .collect();
    assert!(buckets.windows(2).all(|w| w[0] <= w[1]), "{buckets:?}");
    assert_eq!(buckets.last(), Some(&3));
    for l in text.lines().filter(|l| !l.starts_with('#')) {
        assert!(l.starts_with("morphoid_"), "{l}");
    }

    // Every GET the OpenAPI document lists is served.
    let doc = c.get_json("/api/v1/openapi.json", None, 200);
    assert_eq!(doc["openapi"], "3.0.3");
    let paths = doc["paths"].as_object().unwrap();
    for (path, ops) in paths {
        let concrete = path.replace("{id}", &s.ateles_1.to_string());
        if ops.get("get").is_some() {
            let status = c.get(&concrete).status().as_u16();
            assert_eq!(status, 200, "GET {concrete}");
        }
    }
    for needed in [
        "/api/v1/scans",
        "/api/v1/scans/{id}",
        "/api/v1/scans/{id}/review",
        "/api/v1/references",
        "/api/v1/status",
        "/healthz",
        "/metrics",
    ] {
        assert!(paths.contains_key(needed), "{needed}");
    }
}

#[test]
fn http_reads_need_credentials_unless_public() {
    let c = Console::start(&settings(false));
    c.add_curator("ana");
    let token = c.token("ana");
    for path in [
        "/api/v1/scans",
        "/api/v1/scans/1",
        "/api/v1/references",
        "/api/v1/status",
        "/metrics",
    ] {
        let r = c.get(path);
        assert_eq!(r.status().as_u16(), 401, "{path}");
        assert!(r.headers().contains_key("www-authenticate"), "{path}");
        let with_token = c
            .client
            .get(c.url(path))
            .bearer_auth(&token)
            .send()
            .unwrap();
        assert_eq!(with_token.status().as_u16(), 200, "{path} with a token");
        let wrong = c
            .client
            .get(c.url(path))
            .bearer_auth("mph_0000")
            .send()
            .unwrap();
        assert_eq!(wrong.status().as_u16(), 401, "{path} with a wrong token");
        let basic = c
            .client
            .get(c.url(path))
            .header("Authorization", "Basic YW5hOnB3")
            .send()
            .unwrap();
        assert_eq!(basic.status().as_u16(), 401, "{path} with Basic");
    }
    // Pages send the browser to the login form, and back afterwards.
    for path in ["/", "/scans/1", "/library", "/status"] {
        let r = c.get(path);
        assert_eq!(r.status().as_u16(), 303, "{path}");
        let location = r.headers()["location"].to_str().unwrap();
        assert!(
            location.starts_with("/login?next=%2F"),
            "{path}: {location}"
        );
    }
    // What needs no login.
    assert_eq!(c.get("/healthz").status().as_u16(), 200);
    assert_eq!(c.get("/api/v1/openapi.json").status().as_u16(), 200);
    assert_eq!(c.get("/login").status().as_u16(), 200);
}
