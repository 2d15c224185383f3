//! What the console refuses: paths that try to leave it (plain and
//! percent-encoded), bodies and heads over the limits, a client that
//! sends its request too slowly, and any change to the audit trail.

use crate::support::http::{raw, raw_get, settings, Console};
use morphoid_service::store::{Decision, NewReview, Store};
use std::time::{Duration, Instant};

#[test]
fn http_paths_never_reach_files() {
    let c = Console::start(&settings(true));
    let marker = "SECRET-MARKER-7f3a";
    std::fs::write(c.tmp.path().join("secret.txt"), marker).unwrap();
    std::fs::write(c.tmp.path().join("1.html"), marker).unwrap();
    let targets = [
        "/../secret.txt",
        "/scans/../secret.txt",
        "/scans/../../../../etc/passwd",
        "/scans/..%2F..%2Fsecret.txt",
        "/scans/%2e%2e%2f%2e%2e%2fsecret.txt",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/scans/1/..%2F..%2F..%2Fetc%2Fpasswd",
        "/scans/1%2F..%2F..%2Fsecret.txt",
        "/scans/..%5c..%5csecret.txt",
        "/api/v1/scans/..%2Fsecret.txt",
        "/api/v1/scans/1%00.html",
        "/secret.txt",
        "/db.sqlite",
        "/scans/1.html",
        "//etc/passwd",
    ];
    for target in targets {
        let (status, text) = raw_get(c.addr(), target);
        assert!((400..500).contains(&status), "{target}: {status}\n{text}");
        assert!(!text.contains(marker), "{target} leaked a file");
        assert!(!text.contains("root:x:0:0"), "{target} leaked /etc/passwd");
        assert!(
            !text.contains("SQLite format"),
            "{target} leaked the database"
        );
    }
    // The scan pages themselves are served by id.
    let (status, text) = raw_get(c.addr(), &format!("/scans/{}", c.ids.ateles_1));
    assert_eq!(status, 200, "{text}");
    assert!(text.contains("ateles-1.ply"));
}

#[test]
fn http_oversized_bodies_and_heads_are_refused() {
    let c = Console::start(&settings(true));
    c.add_curator("ana");
    let token = c.token("ana");
    let big = format!(
        "{{\"decision\": \"reject\", \"comment\": \"{}\"}}",
        "x".repeat(100 * 1024)
    );
    let url = c.url(&format!("/api/v1/scans/{}/review", c.ids.ateles_1));
    let r = c
        .client
        .post(&url)
        .bearer_auth(&token)
        .header("Content-Type", "application/json")
        .body(big.clone())
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 413);
    // The same without a declared length (chunked): the server answers 413
    // once the limit is passed and closes the connection, which the client
    // may see as the answer or as its body cut off; never as accepted.
    let chunked = c
        .client
        .post(&url)
        .bearer_auth(&token)
        .header("Content-Type", "application/json")
        // A reader of unknown length: sent chunked.
        .body(reqwest::blocking::Body::new(std::io::Cursor::new(
            big.clone().into_bytes(),
        )))
        .send();
    match chunked {
        Ok(r) => assert_eq!(r.status().as_u16(), 413),
        Err(e) => assert!(e.is_body() || e.is_request(), "{e:?}"),
    }
    let r = c
        .client
        .post(c.url("/login"))
        .header("Content-Type", "application/x-www-form-urlencoded")
        .body(format!("name={}", "a".repeat(100 * 1024)))
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 413);
    assert!(Store::open(&c.db)
        .unwrap()
        .reviews_of(c.ids.ateles_1)
        .unwrap()
        .is_empty());

    // A head over `max_header_bytes` (16 kB).
    let head = format!(
        "GET /healthz HTTP/1.1\r\nHost: x\r\nX-Padding: {}\r\nConnection: close\r\n\r\n",
        "p".repeat(20 * 1024)
    );
    let (status, _) = raw(c.addr(), head.as_bytes(), Duration::from_secs(10));
    assert_eq!(status, 431);
    // The server goes on.
    assert_eq!(raw_get(c.addr(), "/healthz").0, 200);
}

#[test]
fn http_a_slow_client_is_cut_off() {
    let c = Console::start(&settings(true));
    // `settings`: a request head must arrive within 1 s.
    let started = Instant::now();
    let (status, text) = raw(
        c.addr(),
        b"GET /api/v1/status HTTP/1.1\r\nHost: x\r\n",
        Duration::from_secs(15),
    );
    let waited = started.elapsed();
    assert!(
        waited < Duration::from_secs(8),
        "the connection stayed open {waited:?}"
    );
    assert!(status == 0 || status == 408, "{status}: {text}");
    assert!(!text.contains("queue_length"), "{text}");
    // A connection that sends nothing at all is not kept either.
    let started = Instant::now();
    let (status, text) = raw(c.addr(), b"", Duration::from_secs(15));
    assert!(
        started.elapsed() < Duration::from_secs(8),
        "an idle connection stayed open {:?}",
        started.elapsed()
    );
    assert!(status == 0 || status == 408, "{status}: {text}");
    // Meanwhile and afterwards, others are served.
    assert_eq!(raw_get(c.addr(), "/healthz").0, 200);
}

#[test]
fn http_the_audit_trail_refuses_updates_and_deletes() {
    let c = Console::start(&settings(true));
    let mut store = Store::open(&c.db).unwrap();
    let recorded = store
        .record_review(&NewReview {
            scan_id: c.ids.ateles_1,
            curator: "ana",
            decision: Decision::Confirm,
            comment: None,
            expected_latest: None,
            ranks: &[],
        })
        .unwrap();
    drop(store);
    let conn = rusqlite::Connection::open(&c.db).unwrap();
    for sql in [
        "UPDATE review SET curator = 'mallory'",
        "UPDATE review SET decision = 'reject' WHERE id = 1",
        "DELETE FROM review",
        "DELETE FROM review WHERE id = 1",
    ] {
        let e = conn.execute(sql, []).expect_err(sql).to_string();
        assert!(e.contains("audit trail"), "{sql}: {e}");
    }
    let (n, curator): (i64, String) = conn
        .query_row("SELECT count(*), max(curator) FROM review", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap();
    assert_eq!((n, curator.as_str()), (1, "ana"));
    // Read back through the API, unchanged.
    let scan = c.get_json(&format!("/api/v1/scans/{}", c.ids.ateles_1), None, 200);
    assert_eq!(scan["review"]["id"], recorded.id);
    assert_eq!(scan["review"]["curator"], "ana");
}
