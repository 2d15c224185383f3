//! The curator's loop, simulated on the real teeth with the real daemon
//! and its console: the library starts with half the 116 teeth (per genus,
//! every other tooth); the other half comes in, in a seeded random order,
//! as scans dropped into the export folder. For each, a script reads the
//! answer from the JSON API, confirms it or corrects it to the true taxa,
//! and adds the scan to the library; the next scan waits until the daemon
//! uses the new reference. Prints the genus accuracy of the first and the
//! last quarter of the scans and the time from "add" to the daemon using
//! the new reference. Minutes:
//!
//! ```sh
//! cargo test --release --test it http_the_curators_loop -- --ignored --nocapture
//! ```

use crate::support::daemon::{wait_until, Daemon, Env};
use morphoid_data::table::Labels;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use serde_json::{json, Value};
use std::time::{Duration, Instant};

/// The order of the fed scans.
const SEED: u64 = 32;
const RANKS: [&str; 3] = ["order", "family", "genus"];

/// The teeth split per genus (sorted by genus, then name; teeth without a
/// genus as one group): every other one into the library, the rest fed.
fn split(labels: &Labels, names: &[String]) -> (Vec<String>, Vec<String>) {
    let mut by_genus: Vec<(String, String)> = names
        .iter()
        .map(|n| {
            let genus = labels.get(n, "genus").unwrap_or("NA").to_string();
            (genus, n.clone())
        })
        .collect();
    by_genus.sort();
    let (mut library, mut fed) = (Vec::new(), Vec::new());
    let mut previous = String::new();
    let mut k = 0;
    for (genus, name) in by_genus {
        if genus != previous {
            previous = genus;
            k = 0;
        }
        if k % 2 == 0 {
            library.push(name);
        } else {
            fed.push(name);
        }
        k += 1;
    }
    (library, fed)
}

#[test]
#[ignore = "real data and the real daemon: minutes; run by name"]
fn http_the_curators_loop_grows_the_library_from_its_own_scans() {
    let Some(teeth) = crate::support::data::teeth_dir() else {
        return;
    };
    let labels_path = teeth.join("labels.csv");
    let text = std::fs::read_to_string(&labels_path).unwrap();
    let labels = Labels::parse(&text, Some(&RANKS.map(String::from)), &labels_path).unwrap();
    let names: Vec<String> = crate::support::data::ply_files(&teeth.join("meshes"))
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    let (library_names, mut fed) = split(&labels, &names);
    fed.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(SEED));

    // The library: half the teeth (their files linked) and their rows.
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let lib = root.join("library");
    std::fs::create_dir_all(&lib).unwrap();
    let mut lines = text.lines();
    let mut rows = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let name = line.split(',').next().unwrap_or("");
        if library_names.iter().any(|n| n == name) {
            rows += &format!("{line}\n");
            let file = format!("{name}.ply");
            std::os::unix::fs::symlink(teeth.join("meshes").join(&file), lib.join(&file)).unwrap();
        }
    }
    std::fs::write(lib.join("labels.csv"), rows).unwrap();
    let export = root.join("export");
    std::fs::create_dir_all(&export).unwrap();
    let db = root.join("db.sqlite");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {export:?}\nsettle_seconds = 0.5\n\
             [library]\ndir = {lib:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             [database]\npath = {db:?}\n\
             [http]\nlisten = \"127.0.0.1:0\"\npublic_read = true\n",
            root.join("cache"),
        ),
    )
    .unwrap();
    let env = Env {
        tmp,
        root: root.clone(),
        export: export.clone(),
        db: db.clone(),
        config,
    };
    let daemon = Daemon::start(&env);
    let start_refs = daemon.references();
    assert_eq!(start_refs as usize, library_names.len());
    let base = daemon.console_url();
    // A fresh connection per request: the server closes a kept-alive
    // connection once it has been idle for the header timeout, and a
    // request sent on it at that moment fails (a POST is not retried).
    let client = reqwest::blocking::Client::builder()
        .pool_max_idle_per_host(0)
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap();
    let get = |path: &str| -> Value {
        client
            .get(format!("{base}{path}"))
            .send()
            .and_then(|r| r.error_for_status())
            .and_then(|r| r.json())
            .unwrap_or(Value::Null)
    };
    let mut store = morphoid_service::store::Store::open(&db).unwrap();
    let hash = morphoid_service::http::hash_password("a long password").unwrap();
    store.add_curator("ana", &hash).unwrap();
    let token = morphoid_service::http::new_api_token();
    store
        .add_api_token("ana", &morphoid_service::http::token_hash(&token), "loop")
        .unwrap();
    drop(store);
    let post = |path: &str, body: Value| -> (u16, Value) {
        let r = client
            .post(format!("{base}{path}"))
            .bearer_auth(&token)
            .json(&body)
            .send()
            .unwrap();
        (r.status().as_u16(), r.json().unwrap_or(Value::Null))
    };

    // (scan, genus right or None when its genus is unknown, add → use s)
    let mut outcomes: Vec<(String, Option<bool>, f64)> = Vec::new();
    let mut added_nearest = 0;
    for (k, name) in fed.iter().enumerate() {
        let file = export.join(format!("{name}.ply"));
        std::fs::copy(teeth.join("meshes").join(format!("{name}.ply")), &file).unwrap();
        let path = file.display().to_string();
        let mut scan = Value::Null;
        assert!(
            wait_until(Duration::from_secs(300), || {
                let found = get(&format!("/api/v1/scans?status=ok&name={name}"));
                scan = found["scans"]
                    .as_array()
                    .and_then(|s| s.iter().find(|s| s["scan"] == path.as_str()).cloned())
                    .unwrap_or(Value::Null);
                !scan.is_null()
            }),
            "{name} was not identified:\n{}",
            daemon.log_text()
        );
        let id = scan["id"].as_i64().unwrap();
        let truth = |rank: &str| labels.get(name, rank).map(str::to_string);
        let answer = |rank: &str| scan["ranks"][rank]["taxon"].as_str().map(str::to_string);
        let nearest = scan["ranks"]["genus"]["reference"].as_str().unwrap_or("");
        if fed[..k].iter().any(|f| f == nearest) {
            added_nearest += 1;
        }
        let right = truth("genus").map(|g| answer("genus").as_deref() == Some(g.as_str()));
        // An answer where the truth is unknown (NA) is corrected away:
        // the library then holds what is known, no more.
        let all_right = RANKS.iter().all(|r| truth(r) == answer(r));
        let review = if all_right {
            json!({"decision": "confirm"})
        } else {
            // Every rank, `NA` where the truth is unknown: a rank left
            // out keeps the identified taxon.
            let taxa: serde_json::Map<String, Value> = RANKS
                .iter()
                .map(|r| {
                    (
                        r.to_string(),
                        Value::String(truth(r).unwrap_or("NA".into())),
                    )
                })
                .collect();
            json!({"decision": "correct", "taxa": taxa})
        };
        let (status, body) = post(&format!("/api/v1/scans/{id}/review"), review);
        assert_eq!(status, 201, "{name}: review {body}");
        let before = get("/api/v1/status")["references"].as_i64().unwrap();
        let asked = Instant::now();
        let (status, body) = post(
            &format!("/api/v1/scans/{id}/add-to-library"),
            json!({ "name": name }),
        );
        assert_eq!(status, 201, "{name}: add {body}");
        assert!(
            wait_until(Duration::from_secs(300), || get("/api/v1/status")
                ["references"]
                .as_i64()
                == Some(before + 1)),
            "{name}: the daemon did not take the new reference:\n{}",
            daemon.log_text()
        );
        let secs = asked.elapsed().as_secs_f64();
        println!(
            "{:>3} {name}: genus {} (truth {}), {}; in use after {secs:.1} s",
            k + 1,
            answer("genus").unwrap_or_default(),
            truth("genus").unwrap_or_else(|| "NA".into()),
            if all_right { "confirmed" } else { "corrected" }
        );
        outcomes.push((name.clone(), right, secs));
    }

    let quarter = outcomes.len() / 4;
    let score = |part: &[(String, Option<bool>, f64)]| -> (usize, usize) {
        let known: Vec<bool> = part.iter().filter_map(|o| o.1).collect();
        (known.iter().filter(|&&r| r).count(), known.len())
    };
    let (first_right, first_n) = score(&outcomes[..quarter]);
    let (last_right, last_n) = score(&outcomes[outcomes.len() - quarter..]);
    let (all_right, all_n) = score(&outcomes);
    let mut times: Vec<f64> = outcomes.iter().map(|o| o.2).collect();
    times.sort_by(f64::total_cmp);
    println!(
        "{} scans fed to a library of {start_refs}: genus right {all_right}/{all_n}; \
         first quarter {first_right}/{first_n}, last quarter {last_right}/{last_n}; \
         {added_nearest} answered by a reference added in the loop; \
         add → in use: median {:.1} s, max {:.1} s",
        outcomes.len(),
        times[times.len() / 2],
        times[times.len() - 1],
    );
    // Every scan went round the loop, and the library grew by each.
    assert_eq!(outcomes.len(), fed.len());
    let refs = get("/api/v1/references");
    assert_eq!(refs["count"].as_u64(), Some(names.len() as u64));
    let library =
        morphoid_data::library::Library::open(&lib, Some(&RANKS.map(String::from))).unwrap();
    assert_eq!(library.members().len(), names.len());
    for name in &fed {
        for rank in RANKS {
            assert_eq!(
                library.labels().get(name, rank),
                labels.get(name, rank),
                "{name} {rank}: the library holds what the curator decided"
            );
        }
    }
    assert!(
        added_nearest > 0,
        "no scan was answered by an added reference"
    );
}
