//! Logging in to the console: sessions, CSRF tokens, API tokens, the
//! limit on failed logins, and the refusal to serve beyond loopback
//! without curators.

use crate::support::daemon::{self, BIN};
use crate::support::http::{hidden, library_folder, settings, sources, Console, PASSWORD};
use morphoid_service::http::{LiveStatus, Server};
use morphoid_service::store::Store;
use std::process::Command;

#[test]
fn http_login_sessions_csrf_and_logout() {
    let c = Console::start(&settings(false));
    c.add_curator("ana");
    assert_eq!(c.login("ana", "wrong password").unwrap_err(), 401);
    assert_eq!(c.login("nobody", PASSWORD).unwrap_err(), 401);
    let session = c.login("ana", PASSWORD).expect("login");
    // HttpOnly, SameSite=Strict; not Secure over plain HTTP.
    assert!(
        session.attributes.contains("HttpOnly"),
        "{}",
        session.attributes
    );
    assert!(
        session.attributes.contains("SameSite=Strict"),
        "{}",
        session.attributes
    );
    assert!(
        !session.attributes.contains("Secure"),
        "{}",
        session.attributes
    );

    // A login without the form's CSRF cookie is refused.
    let form = c.get("/login").text().unwrap();
    let csrf = hidden(&form, "csrf").unwrap();
    let forged = c
        .client
        .post(c.url("/login"))
        .form(&[
            ("csrf", csrf.as_str()),
            ("name", "ana"),
            ("password", PASSWORD),
        ])
        .send()
        .unwrap();
    assert_eq!(forged.status().as_u16(), 403);

    // The session reads pages and the API.
    let page = c
        .client
        .get(c.url("/"))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap();
    assert_eq!(page.status().as_u16(), 200);
    assert!(page.text().unwrap().contains("<b id=\"user\">ana</b>"));

    // API writes of a session need its CSRF token.
    let url = c.url(&format!("/api/v1/scans/{}/review", c.ids.ateles_1));
    let body = serde_json::json!({"decision": "confirm"});
    for token in [
        None,
        Some("0123"),
        Some(&session.csrf[..session.csrf.len() - 1]),
    ] {
        let mut r = c
            .client
            .post(&url)
            .header("Cookie", &session.cookie)
            .json(&body);
        if let Some(t) = token {
            r = r.header("X-CSRF-Token", t);
        }
        assert_eq!(r.send().unwrap().status().as_u16(), 403, "{token:?}");
    }
    let ok = c
        .client
        .post(&url)
        .header("Cookie", &session.cookie)
        .header("X-CSRF-Token", &session.csrf)
        .json(&body)
        .send()
        .unwrap();
    assert_eq!(ok.status().as_u16(), 201);
    let recorded: serde_json::Value = ok.json().unwrap();
    assert_eq!(recorded["curator"], "ana");
    assert_eq!(recorded["taxa"]["genus"], "Ateles");

    // The page's form: without its token refused, with it recorded.
    let form_url = c.url(&format!("/scans/{}/review", c.ids.alouatta));
    let fields = [
        ("decision", "correct"),
        ("taxon.genus", "Ateles"),
        ("comment", "the cusps"),
    ];
    let refused = c
        .client
        .post(&form_url)
        .header("Cookie", &session.cookie)
        .form(&fields)
        .send()
        .unwrap();
    assert_eq!(refused.status().as_u16(), 403);
    let scan_page = c
        .client
        .get(c.url(&format!("/scans/{}", c.ids.alouatta)))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap()
        .text()
        .unwrap();
    let page_csrf = hidden(&scan_page, "csrf").expect("the review form's token");
    assert_eq!(page_csrf, session.csrf);
    let mut with_token = fields.to_vec();
    with_token.push(("csrf", &page_csrf));
    with_token.push(("expected_latest", "none"));
    let done = c
        .client
        .post(&form_url)
        .header("Cookie", &session.cookie)
        .form(&with_token)
        .send()
        .unwrap();
    assert_eq!(done.status().as_u16(), 303);
    let reviews = Store::open(&c.db)
        .unwrap()
        .reviews_of(c.ids.alouatta)
        .unwrap();
    assert_eq!(reviews.len(), 1);
    assert_eq!(reviews[0].decision, "correct");
    assert_eq!(reviews[0].taxa["genus"], "Ateles");
    assert_eq!(reviews[0].identified["genus"], "Alouatta");
    assert_eq!(reviews[0].comment.as_deref(), Some("the cusps"));

    // Logging out needs the token too, and ends the session.
    let out = c
        .client
        .post(c.url("/logout"))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap();
    assert_eq!(out.status().as_u16(), 403);
    let out = c
        .client
        .post(c.url("/logout"))
        .header("Cookie", &session.cookie)
        .form(&[("csrf", session.csrf.as_str())])
        .send()
        .unwrap();
    assert_eq!(out.status().as_u16(), 303);
    let after = c
        .client
        .get(c.url("/api/v1/status"))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap();
    assert_eq!(after.status().as_u16(), 401);
}

#[test]
fn http_failed_logins_are_limited_per_address() {
    let c = Console::start(&settings(true));
    c.add_curator("ana");
    // `settings` allows 3 failures a minute.
    for _ in 0..3 {
        assert_eq!(c.login("ana", "wrong password").unwrap_err(), 401);
    }
    assert_eq!(c.login("ana", "wrong password").unwrap_err(), 429);
    // Refused before the password is looked at, right or not, for any
    // name from this address.
    assert_eq!(c.login("ana", PASSWORD).unwrap_err(), 429);
    assert_eq!(c.login("bea", PASSWORD).unwrap_err(), 429);
    // The API tokens of scripts are not affected.
    let token = c.token("ana");
    let r = c
        .client
        .post(c.url(&format!("/api/v1/scans/{}/review", c.ids.ateles_5)))
        .bearer_auth(&token)
        .json(&serde_json::json!({"decision": "reject", "comment": "cracked"}))
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
}

#[test]
fn http_tokens_and_sessions_end_with_their_curator() {
    let c = Console::start(&settings(false));
    c.add_curator("ana");
    let token = c.token("ana");
    let session = c.login("ana", PASSWORD).expect("login");
    assert_eq!(
        c.get_json("/api/v1/status", Some(&token), 200)["counts"]["ok"],
        3
    );
    Store::open(&c.db).unwrap().remove_curator("ana").unwrap();
    c.get_json("/api/v1/status", Some(&token), 401);
    let r = c
        .client
        .get(c.url("/api/v1/status"))
        .header("Cookie", &session.cookie)
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    // Anonymous writes are refused whatever the read policy.
    let open = Console::start(&settings(true));
    let r = open
        .client
        .post(open.url(&format!("/api/v1/scans/{}/review", open.ids.ateles_1)))
        .json(&serde_json::json!({"decision": "confirm"}))
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    assert!(Store::open(&open.db)
        .unwrap()
        .reviews_of(open.ids.ateles_1)
        .unwrap()
        .is_empty());
}

#[test]
fn http_beyond_loopback_needs_a_curator() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("db.sqlite");
    drop(Store::open(&db).unwrap());
    let library = library_folder(dir.path());
    for listen in ["0.0.0.0:0", "[::]:0"] {
        let addr = listen.parse().unwrap();
        let e = Server::start(
            addr,
            &settings(true),
            sources(&db, &library, &LiveStatus::new()),
        )
        .expect_err("no curator");
        let text = e.to_string();
        assert!(
            text.contains(&format!("refusing to serve on {addr}")),
            "{text}"
        );
        assert!(text.contains("morphoid user add"), "{text}");
    }
    // Loopback needs none.
    let loopback = Server::start(
        "127.0.0.1:0".parse().unwrap(),
        &settings(true),
        sources(&db, &library, &LiveStatus::new()),
    );
    assert!(loopback.is_ok());

    // `morphoid run` refuses to start, naming the address, before it loads
    // the library.
    let env = daemon::env(0.5, "", "[http]\nlisten = \"0.0.0.0:0\"\n");
    let out = Command::new(BIN)
        .args(["run", "--config"])
        .arg(&env.config)
        .env_remove("NOTIFY_SOCKET")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("refusing to serve on 0.0.0.0:0"),
        "{stderr}"
    );
}
