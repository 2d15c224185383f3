//! A reviewed scan into the library: through the API and the command
//! line, its file copied and its row appended as the folder lays them out,
//! refused when not settled, changed, unreadable or already there; the
//! daemon asked to reload.

use crate::support::daemon::BIN;
use crate::support::http::{settings, Console, REFERENCES};
use crate::support::store::outcome;
use morphoid_data::hash::content_hash;
use morphoid_data::library::Library;
use morphoid_service::store::Store;
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// Put a scan file in the console's export folder and record it
/// identified as `genus` (family Atelidae); its id.
fn identified_file(c: &Console, name: &str, bytes: &[u8], genus: &str) -> i64 {
    let export = c.tmp.path().join("export");
    std::fs::create_dir_all(&export).unwrap();
    let path = export.join(name);
    std::fs::write(&path, bytes).unwrap();
    let mut store = Store::open(&c.db).unwrap();
    let id = store
        .enqueue(
            path.to_str().unwrap(),
            &content_hash(bytes),
            bytes.len() as u64,
        )
        .unwrap()
        .scan_id();
    store.claim(id).unwrap().unwrap();
    let mut out = outcome(id as u64, REFERENCES);
    for rank in &mut out.ranks {
        rank.taxon = match rank.rank.as_str() {
            "genus" => genus.into(),
            "family" => "Atelidae".into(),
            _ => "Primates".into(),
        };
    }
    store.complete(id, &out).unwrap();
    id
}

/// POST with a token: status and body.
fn post(c: &Console, token: &str, path: &str, body: Option<Value>) -> (u16, Value) {
    let mut r = c.client.post(c.url(path)).bearer_auth(token);
    if let Some(b) = body {
        r = r.json(&b);
    }
    let r = r.send().unwrap();
    (r.status().as_u16(), r.json().unwrap_or(Value::Null))
}

/// Whether the console asked the daemon to reload (within a second).
fn reload_requested(c: &Console) -> bool {
    let signal = c.live.reload_signal();
    tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap()
        .block_on(async {
            tokio::time::timeout(Duration::from_secs(1), signal.notified())
                .await
                .is_ok()
        })
}

#[test]
fn http_reviewed_scans_grow_the_library() {
    let c = Console::start(&settings(true));
    c.add_curator("ana");
    let t = c.token("ana");
    let bytes = b"ply\nformat ascii 1.0\ncomment a new ateles\nend_header\n";
    let scan = identified_file(&c, "new-ateles.ply", bytes, "Ateles");
    let add = format!("/api/v1/scans/{scan}/add-to-library");

    // Not without a login, not before a decision settles its taxa.
    let anonymous = c.client.post(c.url(&add)).send().unwrap();
    assert_eq!(anonymous.status().as_u16(), 401);
    let (status, e) = post(&c, &t, &add, None);
    assert_eq!(status, 409, "{e}");
    assert!(e["error"]
        .as_str()
        .unwrap()
        .contains("not confirmed or corrected"));
    post(
        &c,
        &t,
        &format!("/api/v1/scans/{scan}/review"),
        Some(json!({"decision": "reject"})),
    );
    assert_eq!(post(&c, &t, &add, None).0, 409, "a rejected scan");
    assert!(!reload_requested(&c));

    let (status, _) = post(
        &c,
        &t,
        &format!("/api/v1/scans/{scan}/review"),
        Some(json!({"decision": "confirm"})),
    );
    assert_eq!(status, 201);
    let (status, added) = post(&c, &t, &add, None);
    assert_eq!(status, 201, "{added}");
    assert_eq!(added["reference"], "new-ateles");
    assert_eq!(
        added["labels"],
        json!({"order": "Primates", "family": "Atelidae", "genus": "Ateles"})
    );
    assert!(reload_requested(&c));
    let copied = c.library.join("meshes/new-ateles.ply");
    assert_eq!(std::fs::read(&copied).unwrap(), bytes);
    let labels = std::fs::read_to_string(c.library.join("labels.csv")).unwrap();
    assert!(
        labels.ends_with("\nnew-ateles,Primates,Atelidae,Ateles\n"),
        "{labels}"
    );
    let library = Library::open(&c.library, None).unwrap();
    assert_eq!(library.members().len(), 4);
    assert_eq!(library.labels().get("new-ateles", "genus"), Some("Ateles"));
    let (status, e) = post(&c, &t, &add, None);
    assert_eq!(status, 409, "{e}");
    assert!(e["error"].as_str().unwrap().contains("already"));

    // A correction's taxa, under a name given; names are plain stems.
    let howler = identified_file(
        &c,
        "odd one.ply",
        b"ply\ncomment howler\nend_header\n",
        "Ateles",
    );
    post(
        &c,
        &t,
        &format!("/api/v1/scans/{howler}/review"),
        Some(json!({"decision": "correct", "taxa": {"genus": "Alouatta"}})),
    );
    let path = format!("/api/v1/scans/{howler}/add-to-library");
    assert_eq!(
        post(&c, &t, &path, Some(json!({"name": "../escape"}))).0,
        400
    );
    assert_eq!(
        post(
            &c,
            &t,
            &path,
            Some(json!({"name": "x", "path": "/etc/passwd"}))
        )
        .0,
        400
    );
    let (status, added) = post(&c, &t, &path, Some(json!({"name": "howler-1"})));
    assert_eq!(status, 201, "{added}");
    assert_eq!(added["labels"]["genus"], "Alouatta");
    assert_eq!(added["labels"]["family"], "Atelidae");
    assert!(!c.tmp.path().join("escape.ply").exists());

    // A file changed since it was identified, or gone, is not taken.
    let changed = identified_file(&c, "changed.ply", b"ply\ncomment first\n", "Ateles");
    std::fs::write(
        c.tmp.path().join("export/changed.ply"),
        b"ply\ncomment second\n",
    )
    .unwrap();
    post(
        &c,
        &t,
        &format!("/api/v1/scans/{changed}/review"),
        Some(json!({"decision": "confirm"})),
    );
    let (status, e) = post(
        &c,
        &t,
        &format!("/api/v1/scans/{changed}/add-to-library"),
        None,
    );
    assert_eq!(status, 409);
    assert!(
        e["error"]
            .as_str()
            .unwrap()
            .contains("changed since it was identified"),
        "{e}"
    );
    let broken = c.ids.broken;
    post(
        &c,
        &t,
        &format!("/api/v1/scans/{broken}/review"),
        Some(json!({"decision": "correct", "taxa": {"genus": "Cebus"}})),
    );
    let (status, e) = post(
        &c,
        &t,
        &format!("/api/v1/scans/{broken}/add-to-library"),
        None,
    );
    assert_eq!(status, 409, "{e}");
    assert_eq!(Library::open(&c.library, None).unwrap().members().len(), 5);

    // The command line does the same.
    let cli = identified_file(
        &c,
        "from-cli.ply",
        b"ply\ncomment cli\nend_header\n",
        "Ateles",
    );
    Store::open(&c.db)
        .unwrap()
        .record_review(&morphoid_service::store::NewReview {
            scan_id: cli,
            curator: "ana",
            decision: morphoid_service::store::Decision::Confirm,
            comment: None,
            expected_latest: None,
            ranks: &[],
        })
        .unwrap();
    let run = |args: &[&str]| {
        Command::new(BIN)
            .args(args)
            .arg("--db")
            .arg(&c.db)
            .arg("--library")
            .arg(&c.library)
            .output()
            .unwrap()
    };
    let out = run(&["library", "add", &cli.to_string()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("added as reference from-cli"));
    let again = run(&["library", "add", &cli.to_string()]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("already"));
    let library = Library::open(&c.library, None).unwrap();
    assert_eq!(library.members().len(), 6);
    assert!(Path::new(&c.library.join("meshes/from-cli.ply")).is_file());
}
