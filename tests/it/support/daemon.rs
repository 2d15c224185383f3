//! What the daemon tests share: a small synthetic library and a config in a
//! temporary folder, the real binary started as `morphoid run`, and polling
//! of the database with a timeout.

use morphoid_data::mesh_io;
use morphoid_service::store::{ScanRecord, ScanStatus, Store};
use morphoid_synth::mesh::{self as synth, LibrarySpec, RigidMotion, CROWN_GENERA};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

pub(crate) const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

/// A temporary deployment: library, export folder, database, config.
pub(crate) struct Env {
    /// The folder, removed when the `Env` is dropped (held, never read).
    #[allow(dead_code)]
    pub tmp: tempfile::TempDir,
    pub root: PathBuf,
    pub export: PathBuf,
    pub db: PathBuf,
    pub config: PathBuf,
}

/// A library of 2 crowns per genus (12), 1500 vertices, and a config with
/// `settle_seconds` and any `extra` TOML (e.g. a `[serial]` section).
pub(crate) fn env(settle_seconds: f64, watch_extra: &str, extra: &str) -> Env {
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    env_with(&spec, settle_seconds, watch_extra, extra)
}

/// [`env`] with the library of `spec`, cleaned to its vertex count.
pub(crate) fn env_with(
    spec: &LibrarySpec,
    settle_seconds: f64,
    watch_extra: &str,
    extra: &str,
) -> Env {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    synth::write_synthetic_library(&root.join("library"), spec).unwrap();
    let export = root.join("export");
    std::fs::create_dir_all(&export).unwrap();
    let db = root.join("db.sqlite");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {:?}\nsettle_seconds = {settle_seconds}\n{watch_extra}\n\
             [library]\ndir = {:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             [database]\npath = {:?}\n[clean]\ntarget_vertices = {}\n{extra}\n",
            export,
            root.join("library"),
            root.join("cache"),
            db,
            spec.target_vertices,
        ),
    )
    .unwrap();
    Env {
        tmp,
        root,
        export,
        db,
        config,
    }
}

/// The bytes of a new individual of genus `g` (binary PLY), posed at random.
pub(crate) fn scan_bytes(g: usize, seed: u64) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let genus = &CROWN_GENERA[g % CROWN_GENERA.len()];
    let crown = synth::crown(genus, seed, 1500);
    let posed = RigidMotion::random(seed, 20.0).apply(&crown);
    let path = dir.path().join("s.ply");
    mesh_io::save(&path, &posed).unwrap();
    std::fs::read(&path).unwrap()
}

/// Put `bytes` at `path` (in the export folder) in one step: written to a
/// temporary file beside the export folder, then renamed into place. The
/// daemon thus never sees the file empty or half written, however long
/// the writing thread is descheduled between creating and filling it (an
/// empty file left that way for the settle time would be taken as a scan
/// of its own).
pub(crate) fn put(env: &Env, path: &Path, bytes: &[u8]) {
    use std::io::Write;
    let mut staged = tempfile::NamedTempFile::new_in(&env.root).unwrap();
    staged.write_all(bytes).unwrap();
    staged.persist(path).unwrap();
}

/// A large scan of genus `g` (`vertices` vertices, posed at random) written
/// beside the export folder; rename it into the folder to drop it in. Its
/// job lasts seconds rather than a fraction of one, so that a test polling
/// the database sees it running however the test thread is scheduled.
pub(crate) fn large_scan(env: &Env, g: usize, seed: u64, vertices: usize) -> PathBuf {
    let genus = &CROWN_GENERA[g % CROWN_GENERA.len()];
    let crown = synth::crown(genus, seed, vertices);
    let posed = RigidMotion::random(seed, 20.0).apply(&crown);
    let dir = env.root.join("staging");
    std::fs::create_dir_all(&dir).unwrap();
    let staged = dir.join(format!("large-{seed}.ply"));
    mesh_io::save(&staged, &posed).unwrap();
    staged
}

/// Genus name of index `g`.
pub(crate) fn genus(g: usize) -> &'static str {
    CROWN_GENERA[g % CROWN_GENERA.len()].name
}

/// A running `morphoid run`, killed when dropped.
pub(crate) struct Daemon {
    pub child: Child,
    pub log: PathBuf,
}

impl Daemon {
    /// Start the daemon on `env` and wait until it has loaded the library.
    pub(crate) fn start(env: &Env) -> Daemon {
        Self::start_with(env, &[])
    }

    /// Start with extra environment variables.
    pub(crate) fn start_with(env: &Env, vars: &[(&str, &str)]) -> Daemon {
        let n = std::fs::read_dir(&env.root).unwrap().count();
        let log = env.root.join(format!("daemon-{n}.log"));
        let child = Command::new(BIN)
            .args(["run", "--config"])
            .arg(&env.config)
            .env("MORPHOID_LOG", "info")
            .env_remove("NOTIFY_SOCKET")
            .envs(vars.iter().copied())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        let d = Daemon { child, log };
        assert!(
            wait_until(Duration::from_secs(300), || d
                .log_text()
                .contains("references; watching")),
            "the daemon did not load its library:\n{}",
            d.log_text()
        );
        d
    }

    /// How many references the library loaded (from the log).
    pub(crate) fn references(&self) -> i64 {
        let log = self.log_text();
        let at = log.find(" references; watching").unwrap();
        log[..at]
            .rsplit(' ')
            .next()
            .and_then(|n| n.parse().ok())
            .unwrap()
    }

    /// The web console's base URL, from its "listening" log line.
    pub(crate) fn console_url(&self) -> String {
        let log = self.log_text();
        log.split("web console listening on ")
            .nth(1)
            .and_then(|rest| rest.split_whitespace().next())
            .unwrap_or_else(|| panic!("no listening line:\n{log}"))
            .to_string()
    }

    /// The log so far.
    pub(crate) fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// The log once it contains `needle`, waiting up to 30 s: a line is
    /// written after the database row it reports on, so a test that has
    /// seen the row must still wait for the line. Panics with the log when
    /// the line never comes.
    pub(crate) fn log_once(&self, needle: &str) -> String {
        if !wait_until(Duration::from_secs(30), || self.log_text().contains(needle)) {
            panic!("{needle:?} never logged:\n{}", self.log_text());
        }
        self.log_text()
    }

    /// Process id.
    pub(crate) fn pid(&self) -> i32 {
        self.child.id() as i32
    }

    /// Send a signal.
    pub(crate) fn signal(&self, sig: i32) {
        // SAFETY: plain kill(2) on our own child.
        unsafe {
            libc::kill(self.pid(), sig);
        }
    }

    /// Wait up to `timeout` for the process to exit.
    pub(crate) fn wait_exit(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(s) = self.child.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        None
    }

    /// Peak resident memory in kB (VmHWM), while it runs.
    pub(crate) fn peak_rss_kb(&self) -> Option<u64> {
        let s = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).ok()?;
        s.lines()
            .find(|l| l.starts_with("VmHWM:"))?
            .split_whitespace()
            .nth(1)?
            .parse()
            .ok()
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Poll `f` every 100 ms until it is true or `timeout` passes.
pub(crate) fn wait_until(timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + timeout;
    loop {
        if f() {
            return true;
        }
        if Instant::now() >= end {
            return false;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Every scan recorded, oldest first (empty before the database exists).
pub(crate) fn rows(db: &Path) -> Vec<ScanRecord> {
    if !db.exists() {
        return Vec::new();
    }
    let Ok(mut store) = Store::open(db) else {
        return Vec::new();
    };
    let mut r = store.recent(100_000).unwrap_or_default();
    r.sort_by_key(|s| s.id);
    r
}

/// Number of finished (ok or error) scans.
pub(crate) fn finished(db: &Path) -> usize {
    rows(db)
        .iter()
        .filter(|r| matches!(r.status, ScanStatus::Ok | ScanStatus::Error))
        .count()
}

/// The genus a finished scan was identified as.
pub(crate) fn genus_of(r: &ScanRecord) -> Option<&str> {
    r.ranks
        .iter()
        .find(|k| k.rank == "genus")
        .map(|k| k.taxon.as_str())
}

/// Each thread of process `pid`: its name and nice value (from
/// `/proc/PID/task/TID/stat`).
pub(crate) fn thread_niceness(pid: i32) -> Vec<(String, i64)> {
    let mut out = Vec::new();
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
        let Ok(stat) = std::fs::read_to_string(task.unwrap().path().join("stat")) else {
            continue;
        };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = stat[open + 1..close].to_string();
        // After the name: state is field 3; nice is field 19.
        let nice = stat[close + 2..]
            .split_whitespace()
            .nth(19 - 3)
            .and_then(|f| f.parse().ok())
            .unwrap();
        out.push((name, nice));
    }
    out
}
