//! Curators' decisions: through the API by two curators at once, their
//! checks, and from the command line (`morphoid review`, `morphoid user`).

use crate::support::daemon::BIN;
use crate::support::http::{settings, Console};
use morphoid_service::store::Store;
use serde_json::{json, Value};
use std::io::Write;
use std::process::{Command, Stdio};
use std::sync::{Arc, Barrier};

/// POST a decision with an API token: the status and the body.
fn decide(c: &Console, token: &str, scan: i64, body: &Value) -> (u16, Value) {
    let r = c
        .client
        .post(c.url(&format!("/api/v1/scans/{scan}/review")))
        .bearer_auth(token)
        .json(body)
        .send()
        .expect("POST review");
    let status = r.status().as_u16();
    (status, r.json().unwrap_or(Value::Null))
}

#[test]
fn http_two_curators_deciding_at_once_are_both_recorded_in_order() {
    let c = Arc::new(Console::start(&settings(false)));
    c.add_curator("ana");
    c.add_curator("bea");
    let tokens = [c.token("ana"), c.token("bea")];
    let scan = c.ids.ateles_1;
    const EACH: usize = 6;

    // Both send their decisions at the same moment, several times over.
    let barrier = Arc::new(Barrier::new(2));
    let threads: Vec<_> = tokens
        .iter()
        .enumerate()
        .map(|(k, token)| {
            let (c, token, barrier) = (Arc::clone(&c), token.clone(), Arc::clone(&barrier));
            std::thread::spawn(move || {
                (0..EACH)
                    .map(|i| {
                        let body = if k == 0 {
                            json!({"decision": "confirm", "comment": format!("ana {i}")})
                        } else {
                            json!({"decision": "correct", "taxa": {"genus": "Alouatta"}, "comment": format!("bea {i}")})
                        };
                        barrier.wait();
                        decide(&c, &token, scan, &body)
                    })
                    .collect::<Vec<_>>()
            })
        })
        .collect();
    let answers: Vec<(u16, Value)> = threads
        .into_iter()
        .flat_map(|t| t.join().unwrap())
        .collect();
    assert!(answers.iter().all(|(s, _)| *s == 201), "{answers:?}");
    let reviews = Store::open(&c.db).unwrap().reviews_of(scan).unwrap();
    assert_eq!(reviews.len(), 2 * EACH);
    // One sequence: 1, 2, …, each decision pointing at the one before.
    for (i, r) in reviews.iter().enumerate() {
        assert_eq!(r.seq, i as i64 + 1);
        assert_eq!(r.previous_id, i.checked_sub(1).map(|p| reviews[p].id));
        assert_eq!(r.identified["genus"], "Ateles");
        match r.curator.as_str() {
            "ana" => assert_eq!(
                (r.decision.as_str(), r.taxa["genus"].as_str()),
                ("confirm", "Ateles")
            ),
            "bea" => assert_eq!(
                (r.decision.as_str(), r.taxa["genus"].as_str()),
                ("correct", "Alouatta")
            ),
            other => panic!("curator {other}"),
        }
    }
    for who in ["ana", "bea"] {
        let comments: Vec<String> = reviews
            .iter()
            .filter(|r| r.curator == who)
            .filter_map(|r| r.comment.clone())
            .collect();
        let expected: Vec<String> = (0..EACH).map(|i| format!("{who} {i}")).collect();
        assert_eq!(
            comments, expected,
            "each curator's decisions in their order"
        );
    }
    // The API answers each one as recorded, and shows the last as the scan's.
    let mut answered: Vec<i64> = answers
        .iter()
        .map(|(_, v)| v["id"].as_i64().unwrap())
        .collect();
    answered.sort();
    let mut stored: Vec<i64> = reviews.iter().map(|r| r.id).collect();
    stored.sort();
    assert_eq!(answered, stored);
    let shown = c.get_json(&format!("/api/v1/scans/{scan}"), Some(&tokens[0]), 200);
    assert_eq!(shown["review"]["id"], reviews.last().unwrap().id);
    assert_eq!(shown["reviews"].as_array().unwrap().len(), 2 * EACH);

    // Both deciding on what they saw as the latest: one is recorded, the
    // other told that the scan was reviewed meanwhile.
    for round in 0..4 {
        let latest = Store::open(&c.db)
            .unwrap()
            .latest_review(scan)
            .unwrap()
            .map(|r| r.id);
        let threads: Vec<_> = tokens
            .iter()
            .map(|token| {
                let (c, token, barrier) = (Arc::clone(&c), token.clone(), Arc::clone(&barrier));
                std::thread::spawn(move || {
                    barrier.wait();
                    decide(
                        &c,
                        &token,
                        scan,
                        &json!({"decision": "reject", "expected_latest": latest}),
                    )
                })
            })
            .collect();
        let mut statuses: Vec<u16> = threads.into_iter().map(|t| t.join().unwrap().0).collect();
        statuses.sort();
        assert_eq!(statuses, [201, 409], "round {round}");
    }
    assert_eq!(
        Store::open(&c.db).unwrap().reviews_of(scan).unwrap().len(),
        2 * EACH + 4
    );
}

#[test]
fn http_decisions_are_checked_and_shown() {
    let c = Console::start(&settings(true));
    c.add_curator("ana");
    let t = c.token("ana");
    let s = c.ids;
    for (scan, body, status, says) in [
        (s.pending, json!({"decision": "confirm"}), 409, "wait"),
        (
            s.broken,
            json!({"decision": "confirm"}),
            409,
            "no identification",
        ),
        (
            s.ateles_1,
            json!({"decision": "correct", "taxa": {"colour": "red"}}),
            400,
            "unknown rank",
        ),
        (
            s.ateles_1,
            json!({"decision": "correct"}),
            400,
            "at least one rank",
        ),
        (
            s.ateles_1,
            json!({"decision": "correct", "taxa": {"genus": " "}}),
            400,
            "genus",
        ),
        (
            s.ateles_1,
            json!({"decision": "confirm", "taxa": {"genus": "Cebus"}}),
            400,
            "correct",
        ),
        (s.ateles_1, json!({"decision": "maybe"}), 400, "maybe"),
        (
            s.ateles_1,
            json!({"decision": "confirm", "extra": 1}),
            400,
            "extra",
        ),
        (999, json!({"decision": "reject"}), 404, "999"),
        (
            s.ateles_1,
            json!({"decision": "reject", "expected_latest": 12345}),
            409,
            "meanwhile",
        ),
    ] {
        let (got, answer) = decide(&c, &t, scan, &body);
        assert_eq!(got, status, "{body}: {answer}");
        let text = answer["error"].as_str().unwrap_or_default();
        assert!(text.contains(says), "{body}: {text}");
    }
    assert_eq!(
        c.get_json("/api/v1/scans?reviewed=true", None, 200)["scans"],
        json!([])
    );

    let (got, _) = decide(
        &c,
        &t,
        s.broken,
        &json!({"decision": "correct", "taxa": {"genus": "Cebus", "family": "Cebidae"}}),
    );
    assert_eq!(got, 201);
    let (got, rejected) = decide(
        &c,
        &t,
        s.alouatta,
        &json!({"decision": "reject", "comment": "two teeth fused", "expected_latest": null}),
    );
    assert_eq!(got, 201);
    assert_eq!(rejected["seq"], 1);
    assert_eq!(rejected["taxa"], json!({}));
    assert_eq!(rejected["identified"]["genus"], "Alouatta");
    let reviewed = c.get_json("/api/v1/scans?reviewed=true", None, 200);
    let ids: Vec<i64> = reviewed["scans"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["id"].as_i64().unwrap())
        .collect();
    assert_eq!(ids, [s.broken, s.alouatta]);
    assert_eq!(reviewed["scans"][1]["review"]["decision"], "reject");
    assert_eq!(reviewed["scans"][1]["review"]["comment"], "two teeth fused");
    assert_eq!(reviewed["scans"][0]["review"]["taxa"]["family"], "Cebidae");
    let not_yet = c.get_json("/api/v1/scans?reviewed=false", None, 200);
    assert_eq!(not_yet["scans"].as_array().unwrap().len(), 3);
    let metrics = c.get("/metrics").text().unwrap();
    assert!(
        metrics.contains("morphoid_reviews{decision=\"correct\"} 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("morphoid_reviews{decision=\"reject\"} 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("morphoid_reviews{decision=\"confirm\"} 0"),
        "{metrics}"
    );
}

/// `morphoid ARGS… --db DB` with `stdin`: exit success, stdout, stderr.
fn morphoid(args: &[&str], db: &std::path::Path, stdin: &str) -> (bool, String, String) {
    let mut child = Command::new(BIN)
        .args(args)
        .arg("--db")
        .arg(db)
        .env("USER", "tester")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn http_review_and_user_from_the_command_line() {
    let c = Console::start(&settings(false));
    let db = c.db.clone();
    let s = c.ids;
    let (ok, out, err) = morphoid(&["review", &s.ateles_1.to_string(), "--confirm"], &db, "");
    assert!(ok, "{err}");
    assert!(out.contains("confirm by unix:tester"), "{out}");
    let (ok, out, err) = morphoid(
        &[
            "review",
            &s.alouatta.to_string(),
            "--taxon",
            "genus=Ateles",
            "--taxon",
            "family=Atelidae",
            "--comment",
            "lower molar",
            "--as",
            "ana",
            "--json",
        ],
        &db,
        "",
    );
    assert!(ok, "{err}");
    let recorded: Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(recorded["curator"], "ana");
    assert_eq!(
        recorded["taxa"],
        json!({"family": "Atelidae", "genus": "Ateles"})
    );
    let (ok, _, err) = morphoid(&["review", &s.pending.to_string(), "--reject"], &db, "");
    assert!(!ok);
    assert!(
        err.contains("cannot be reviewed") && err.contains("pending"),
        "{err}"
    );
    let (ok, _, err) = morphoid(
        &["review", &s.ateles_1.to_string(), "--taxon", "genus"],
        &db,
        "",
    );
    assert!(!ok && err.contains("RANK=NAME"), "{err}");
    let (ok, _, _) = morphoid(&["review", &s.ateles_1.to_string()], &db, "");
    assert!(!ok, "a decision is required");

    // Users: added with the password on stdin, logged in, listed, removed.
    let (ok, _, err) = morphoid(&["user", "add", "cleo"], &db, "a long password\n");
    assert!(ok, "{err}");
    let (ok, _, err) = morphoid(&["user", "add", "cleo"], &db, "another password\n");
    assert!(!ok && err.contains("exists"), "{err}");
    let (ok, _, err) = morphoid(&["user", "add", "bad name"], &db, "a long password\n");
    assert!(!ok && err.contains("not a valid user name"), "{err}");
    let (ok, _, err) = morphoid(&["user", "add", "dora"], &db, "short\n");
    assert!(!ok && err.contains("8 to 1024"), "{err}");
    assert!(c.login("cleo", "a long password").is_ok());
    let (ok, token, err) = morphoid(&["user", "token", "cleo"], &db, "");
    assert!(ok, "{err}");
    let token = token.trim();
    assert!(token.starts_with("mph_") && token.len() == 68, "{token}");
    assert_eq!(
        c.get_json("/api/v1/status", Some(token), 200)["counts"]["ok"],
        3
    );
    let (ok, list, _) = morphoid(&["user", "list", "--json"], &db, "");
    assert!(ok);
    let listed: Value = serde_json::from_str(list.trim()).unwrap();
    assert_eq!(
        (listed["name"].as_str(), listed["tokens"].as_u64()),
        (Some("cleo"), Some(1))
    );
    assert!(!list.contains("argon2"), "{list}");
    let (ok, _, err) = morphoid(&["user", "revoke-tokens", "cleo"], &db, "");
    assert!(ok, "{err}");
    c.get_json("/api/v1/status", Some(token), 401);
    let (ok, _, err) = morphoid(&["user", "remove", "cleo"], &db, "");
    assert!(ok, "{err}");
    assert_eq!(c.login("cleo", "a long password").unwrap_err(), 401);
    let (ok, _, err) = morphoid(&["user", "remove", "cleo"], &db, "");
    assert!(!ok && err.contains("no user"), "{err}");
    // The command line's decisions are in the same trail.
    let reviews = Store::open(&db).unwrap().reviews_of(s.alouatta).unwrap();
    assert_eq!(reviews.len(), 1);
    assert_eq!(reviews[0].comment.as_deref(), Some("lower molar"));
}
