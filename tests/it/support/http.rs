//! What the web console's tests share: a real SQLite file filled through
//! the store as the daemon fills it, the console served on 127.0.0.1 port
//! 0 in this process, a real HTTP client, and raw requests over TCP for
//! what a client library would tidy up (dot segments, huge heads, slow
//! senders).

use super::store::{outcome, register_references};
use morphoid_service::config::Http;
use morphoid_service::http::{
    hash_password, new_api_token, token_hash, LiveStatus, Server, Sources,
};
use morphoid_service::identify::Confidence;
use morphoid_service::store::Store;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::time::Duration;

/// The library's ranks in these tests.
pub(crate) const RANKS: [&str; 3] = ["order", "family", "genus"];

/// References registered.
pub(crate) const REFERENCES: usize = 12;

/// A password the tests' curators use.
pub(crate) const PASSWORD: &str = "correct horse battery";

/// A database and the console serving it.
pub(crate) struct Console {
    /// The folder, removed when dropped (held, never read).
    #[allow(dead_code)]
    pub tmp: tempfile::TempDir,
    /// The database file.
    pub db: PathBuf,
    /// The library folder ([`library_folder`]).
    pub library: PathBuf,
    /// What the console shows of the (absent) daemon.
    pub live: LiveStatus,
    /// The server.
    pub server: Server,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// A client that follows no redirects.
    pub client: reqwest::blocking::Client,
    /// The seeded scans' ids (see [`seed`]).
    pub ids: Seeded,
}

/// The seeded scans.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Seeded {
    /// `a/ateles-1.ply`: ok, genus Ateles.
    pub ateles_1: i64,
    /// `b/alouatta-2.ply`: ok, genus Alouatta, no close match.
    pub alouatta: i64,
    /// `c/broken.stl`: error.
    pub broken: i64,
    /// `d/waiting.ply`: pending.
    pub pending: i64,
    /// `a/ateles-5.ply`: ok, genus Ateles.
    pub ateles_5: i64,
}

/// What a test console serves.
pub(crate) fn sources(
    db: &std::path::Path,
    library: &std::path::Path,
    live: &LiveStatus,
) -> Sources {
    Sources {
        db: db.to_path_buf(),
        library: library.to_path_buf(),
        ranks: RANKS.iter().map(|r| r.to_string()).collect(),
        live: live.clone(),
    }
}

/// A library folder as a person lays it out: `labels.csv` and the
/// surfaces under `meshes/` (the files' contents are never read here).
pub(crate) fn library_folder(root: &std::path::Path) -> PathBuf {
    let dir = root.join("library");
    std::fs::create_dir_all(dir.join("meshes")).expect("library folder");
    let mut labels = String::from("name,order,family,genus\n");
    for i in 0..3 {
        labels.push_str(&format!("ref{i:03},Primates,F{i},G{i}\n"));
        std::fs::write(dir.join("meshes").join(format!("ref{i:03}.ply")), b"ply\n").expect("mesh");
    }
    std::fs::write(dir.join("labels.csv"), labels).expect("labels");
    dir
}

/// Settings for the tests: loopback, the given read policy, small limits.
pub(crate) fn settings(public_read: bool) -> Http {
    Http {
        listen: Some("127.0.0.1:0".into()),
        public_read,
        header_timeout_seconds: 1.0,
        login_failures_per_minute: 3,
        ..Http::default()
    }
}

/// Record an identified scan at `path` whose genus is `genus`.
pub(crate) fn identified(
    store: &mut Store,
    path: &str,
    seed: u64,
    genus: &str,
    family: &str,
    flagged: bool,
) -> i64 {
    let id = store
        .enqueue(path, &format!("hash-{path}"), 1000 + seed)
        .expect("enqueue")
        .scan_id();
    let job = store.claim(id).expect("claim").expect("pending");
    let mut out = outcome(seed, REFERENCES);
    for rank in &mut out.ranks {
        rank.taxon = match rank.rank.as_str() {
            "genus" => genus.into(),
            "family" => family.into(),
            _ => "Primates".into(),
        };
        rank.confidence = Some(Confidence {
            probability: if flagged { 0.2 } else { 0.9 },
            novelty: if flagged { 3.0 } else { 0.5 },
            novelty_threshold: Some(1.5),
            no_close_match: Some(flagged),
        });
    }
    store.complete(job.scan_id, &out).expect("complete");
    id
}

/// Fill a new database: 12 references and five scans (three identified,
/// one failed, one waiting).
pub(crate) fn seed(store: &mut Store) -> Seeded {
    register_references(store, REFERENCES);
    let ateles_1 = identified(
        store,
        "export/a/ateles-1.ply",
        1,
        "Ateles",
        "Atelidae",
        false,
    );
    let alouatta = identified(
        store,
        "export/b/alouatta-2.ply",
        2,
        "Alouatta",
        "Atelidae",
        true,
    );
    let broken = store
        .enqueue("export/c/broken.stl", "hash-broken", 10)
        .expect("enqueue")
        .scan_id();
    store.claim(broken).expect("claim").expect("pending");
    store
        .fail(broken, "cannot read export/c/broken.stl: truncated")
        .expect("fail");
    let pending = store
        .enqueue("export/d/waiting.ply", "hash-waiting", 10)
        .expect("enqueue")
        .scan_id();
    let ateles_5 = identified(
        store,
        "export/a/ateles-5.ply",
        5,
        "Ateles",
        "Atelidae",
        false,
    );
    Seeded {
        ateles_1,
        alouatta,
        broken,
        pending,
        ateles_5,
    }
}

impl Console {
    /// A seeded database served with `settings`.
    pub(crate) fn start(settings: &Http) -> Console {
        let tmp = tempfile::tempdir().expect("temp dir");
        let db = tmp.path().join("db.sqlite");
        let ids = seed(&mut Store::open(&db).expect("open"));
        let library = library_folder(tmp.path());
        let live = LiveStatus::new();
        let server = Server::start_configured(settings, sources(&db, &library, &live))
            .expect("start")
            .expect("listen is set");
        let base = format!("http://{}", server.local_addr());
        // A fresh connection per request: the server closes a kept-alive
        // connection once it has been idle for the header timeout, and a
        // request sent on it at that moment fails (a POST is not retried).
        let client = reqwest::blocking::Client::builder()
            .pool_max_idle_per_host(0)
            .redirect(reqwest::redirect::Policy::none())
            .timeout(Duration::from_secs(20))
            .build()
            .expect("client");
        Console {
            tmp,
            db,
            library,
            live,
            server,
            base,
            client,
            ids,
        }
    }

    /// The server's address.
    pub(crate) fn addr(&self) -> SocketAddr {
        self.server.local_addr()
    }

    /// `base` + `path`.
    pub(crate) fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// GET `path` (no credentials).
    pub(crate) fn get(&self, path: &str) -> reqwest::blocking::Response {
        self.client.get(self.url(path)).send().expect("GET")
    }

    /// GET `path` as JSON, checking the status.
    pub(crate) fn get_json(
        &self,
        path: &str,
        token: Option<&str>,
        status: u16,
    ) -> serde_json::Value {
        let mut request = self.client.get(self.url(path));
        if let Some(t) = token {
            request = request.bearer_auth(t);
        }
        let response = request.send().expect("GET");
        assert_eq!(response.status().as_u16(), status, "GET {path}");
        response.json().expect("JSON body")
    }

    /// Add a curator with [`PASSWORD`].
    pub(crate) fn add_curator(&self, name: &str) {
        let hash = hash_password(PASSWORD).expect("hash");
        Store::open(&self.db)
            .expect("open")
            .add_curator(name, &hash)
            .expect("add curator");
    }

    /// A new API token of the curator `name`.
    pub(crate) fn token(&self, name: &str) -> String {
        let token = new_api_token();
        Store::open(&self.db)
            .expect("open")
            .add_api_token(name, &token_hash(&token), "test")
            .expect("add token");
        token
    }

    /// Log in through the form as a browser does; the session's cookie
    /// (`name=value`) and its CSRF token.
    pub(crate) fn login(&self, name: &str, password: &str) -> Result<Login, u16> {
        let form = self.get("/login");
        assert_eq!(form.status().as_u16(), 200);
        let cookie = set_cookie(&form, "morphoid_login_csrf").expect("login CSRF cookie");
        let html = form.text().expect("body");
        let csrf = hidden(&html, "csrf").expect("csrf field");
        let response = self
            .client
            .post(self.url("/login"))
            .header("Cookie", format!("morphoid_login_csrf={cookie}"))
            .form(&[
                ("csrf", csrf.as_str()),
                ("name", name),
                ("password", password),
                ("next", "/"),
            ])
            .send()
            .expect("POST /login");
        if response.status().as_u16() != 303 {
            return Err(response.status().as_u16());
        }
        let attributes = response
            .headers()
            .get_all("set-cookie")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .find(|v| v.starts_with("morphoid_session="))
            .expect("session cookie")
            .to_string();
        let value = set_cookie(&response, "morphoid_session").expect("session cookie");
        let session: serde_json::Value = self
            .client
            .get(self.url("/api/v1/session"))
            .header("Cookie", format!("morphoid_session={value}"))
            .send()
            .expect("GET session")
            .json()
            .expect("JSON");
        Ok(Login {
            cookie: format!("morphoid_session={value}"),
            csrf: session["csrf"].as_str().expect("csrf").to_string(),
            attributes,
        })
    }
}

/// A logged-in browser's credentials.
#[derive(Debug, Clone)]
pub(crate) struct Login {
    /// `morphoid_session=…`, for the `Cookie` header.
    pub cookie: String,
    /// The session's CSRF token.
    pub csrf: String,
    /// The whole `Set-Cookie` value it came in (its attributes).
    pub attributes: String,
}

/// The value of the cookie `name` a response sets.
pub(crate) fn set_cookie(response: &reqwest::blocking::Response, name: &str) -> Option<String> {
    response
        .headers()
        .get_all("set-cookie")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find_map(|v| v.strip_prefix(&format!("{name}=")))
        .and_then(|v| v.split(';').next())
        .map(str::to_string)
}

/// The value of the hidden form field `name` in a page.
pub(crate) fn hidden(html: &str, name: &str) -> Option<String> {
    let at = html.find(&format!("name=\"{name}\" value=\""))?;
    let rest = &html[at + name.len() + 15..];
    Some(rest[..rest.find('"')?].to_string())
}

/// Send `request` (bytes as they are) and read the answer until the server
/// closes or `timeout` passes: its status (0: none) and the whole text.
pub(crate) fn raw(addr: SocketAddr, request: &[u8], timeout: Duration) -> (u16, String) {
    let mut stream = TcpStream::connect(addr).expect("connect");
    stream.set_read_timeout(Some(timeout)).expect("timeout");
    stream.write_all(request).expect("send");
    let mut answer = Vec::new();
    let mut chunk = [0u8; 8192];
    loop {
        match stream.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => answer.extend_from_slice(&chunk[..n]),
            Err(_) => break,
        }
    }
    let text = String::from_utf8_lossy(&answer).into_owned();
    let status = text
        .strip_prefix("HTTP/1.1 ")
        .and_then(|s| s.get(..3))
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    (status, text)
}

/// A GET of `target` exactly as written, closing the connection after.
pub(crate) fn raw_get(addr: SocketAddr, target: &str) -> (u16, String) {
    raw(
        addr,
        format!("GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes(),
        Duration::from_secs(10),
    )
}
