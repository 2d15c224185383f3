//! The configuration file (`config/morphoid.toml` is the documented
//! example). Unknown keys are errors, so a typo never silently falls back
//! to a default.

use morphoid_data::library::{Cache, CacheError, Library, LibraryError};
use morphoid_data::pipeline::Settings;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The whole configuration.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// The scanner's export folder.
    pub watch: Watch,
    /// The reference library.
    pub library: LibraryConfig,
    /// The SQLite database.
    pub database: Database,
    /// Optional serial trigger (absent: none).
    pub serial: Option<Serial>,
    /// Cleaning parameters.
    pub clean: morphoid_core::clean::CleanOptions,
    /// cP engine parameters.
    pub cp: morphoid_core::cp::CpParams,
    /// Slice stacks and volume files.
    pub volume: morphoid_core::volume::VolumeOptions,
    /// Optional result files (absent: the database only).
    pub results: Results,
    /// The web console and JSON API (off unless `listen` is set).
    pub http: Http,
}

/// `[http]`: the web console and JSON API inside `morphoid run`
/// (`crate::http`). Off unless `listen` is set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Http {
    /// Address and port to listen on, e.g. `127.0.0.1:8472` (absent: no
    /// server). Any address but loopback needs at least one user.
    pub listen: Option<String>,
    /// Whether reading (pages, `GET` API, metrics) needs no login.
    pub public_read: bool,
    /// Largest request body accepted, in bytes.
    pub max_body_bytes: usize,
    /// Largest request head (request line and headers), in bytes.
    pub max_header_bytes: usize,
    /// How long a client may take to send a request's head; a kept-alive
    /// connection idle this long is closed too (the wait for the next head).
    pub header_timeout_seconds: f64,
    /// How long one request may take, its body included.
    pub request_timeout_seconds: f64,
    /// Connections served at once; more wait to be accepted.
    pub max_connections: usize,
    /// How long a login lasts without use.
    pub session_hours: f64,
    /// Failed logins allowed per client address (and per user name) in a
    /// minute; more are refused until the minute is over.
    pub login_failures_per_minute: u32,
    /// PEM certificate chain to serve HTTPS with, with `tls_key` (absent:
    /// plain HTTP, e.g. behind a reverse proxy that terminates TLS).
    pub tls_cert: Option<PathBuf>,
    /// The PEM private key of `tls_cert`.
    pub tls_key: Option<PathBuf>,
}

impl Default for Http {
    fn default() -> Self {
        Http {
            listen: None,
            public_read: false,
            max_body_bytes: 64 * 1024,
            max_header_bytes: 16 * 1024,
            header_timeout_seconds: 10.0,
            request_timeout_seconds: 30.0,
            max_connections: 256,
            session_hours: 12.0,
            login_failures_per_minute: 5,
            tls_cert: None,
            tls_key: None,
        }
    }
}

impl Http {
    /// `listen` as a socket address (`None`: the server is off).
    pub fn listen_addr(&self) -> Result<Option<std::net::SocketAddr>, ValueError> {
        self.listen
            .as_deref()
            .map(|l| {
                l.parse().map_err(|_| ValueError::NotAnAddress {
                    value: l.to_string(),
                })
            })
            .transpose()
    }

    /// Checks of the values the types do not catch.
    fn validate(&self) -> Result<(), ValueError> {
        self.listen_addr()?;
        let positive = |key: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ValueError::NotPositive { key, value })
            }
        };
        positive("http.header_timeout_seconds", self.header_timeout_seconds)?;
        positive("http.request_timeout_seconds", self.request_timeout_seconds)?;
        positive("http.session_hours", self.session_hours)?;
        if self.max_body_bytes == 0 || self.max_connections == 0 {
            return Err(ValueError::NoBodyOrConnections);
        }
        // hyper's smallest read buffer: a head must fit in it.
        if self.max_header_bytes < 8192 {
            return Err(ValueError::TooSmall {
                key: "http.max_header_bytes",
                least: 8192,
                value: self.max_header_bytes,
            });
        }
        if self.tls_cert.is_some() != self.tls_key.is_some() {
            return Err(ValueError::TlsHalf);
        }
        if self.login_failures_per_minute == 0 {
            return Err(ValueError::NoLoginFailures);
        }
        Ok(())
    }
}

/// `[results]`: a folder that receives `<stem>.json` (the `classify --json`
/// line) and, when landmarks were carried onto the scan, `<stem>.fcsv` for
/// each identified scan.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Results {
    /// The folder (created when missing; absent: no result files).
    pub dir: Option<PathBuf>,
}

/// `[watch]`: the export folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Watch {
    /// Folder to watch.
    pub dir: PathBuf,
    /// Watch subfolders too.
    pub recursive: bool,
    /// A file counts as complete when unchanged this long.
    pub settle_seconds: f64,
    /// Glob patterns of names to skip (temporary files).
    pub ignore: Vec<String>,
    /// Where unusable files are moved (absent: left in place).
    pub quarantine: Option<PathBuf>,
    /// How long a settled file whose own format says it is incomplete (a
    /// binary STL shorter than its triangle count needs, a PLY or OFF
    /// short of its declared elements, a slice folder with a numbering
    /// gap) waits for the rest before it is recorded as an error.
    pub incomplete_seconds: f64,
}

impl Default for Watch {
    fn default() -> Self {
        Watch {
            dir: "export".into(),
            recursive: true,
            settle_seconds: 2.0,
            ignore: vec!["*.part".into(), "*.tmp".into(), ".*".into()],
            quarantine: None,
            incomplete_seconds: 600.0,
        }
    }
}

/// `[library]`: the reference library.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LibraryConfig {
    /// Folder with labels.csv and the surfaces.
    pub dir: PathBuf,
    /// Rank columns of labels.csv, broadest first (empty: all but `name`).
    pub ranks: Vec<String>,
    /// Cache of prepared references (absent: the user's cache folder).
    pub cache: Option<PathBuf>,
    /// Calibrate the confidence and the "no close match" flag on the
    /// library's own leave-one-out (compares every pair of references
    /// once per library, then cached).
    pub calibrate: bool,
}

impl Default for LibraryConfig {
    fn default() -> Self {
        LibraryConfig {
            dir: "library".into(),
            ranks: vec!["order".into(), "family".into(), "genus".into()],
            cache: None,
            calibrate: true,
        }
    }
}

/// `[database]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Database {
    /// The SQLite file.
    pub path: PathBuf,
}

impl Default for Database {
    fn default() -> Self {
        Database {
            path: "morphoid.sqlite".into(),
        }
    }
}

/// `[serial]`: a "scan complete" line from the scanner triggers a rescan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Serial {
    /// Device, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Baud rate.
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Regular expression matched against each received line.
    #[serde(default = "default_trigger")]
    pub trigger: String,
}

fn default_baud() -> u32 {
    9600
}

fn default_trigger() -> String {
    "^SCAN (COMPLETE|DONE)".into()
}

/// The standard rates `serial.baud` is checked against (others are
/// usually typos).
const STANDARD_BAUDS: [u32; 11] = [
    1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600,
];

/// Whether `baud` is a standard rate.
fn is_standard_baud(baud: u32) -> bool {
    STANDARD_BAUDS.contains(&baud)
}

/// Why a configuration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML or has a wrong key or value.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The parser's message (names the key and the line).
        message: String,
    },
    /// A value the types accept but the checks do not.
    #[error("{path}: {source}")]
    Value {
        /// The file.
        path: PathBuf,
        /// Which value, and why.
        source: ValueError,
    },
}

/// A configuration value that parses but cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ValueError {
    /// A number of seconds below zero, or not a number.
    #[error("{key} must be a non-negative number, not {value}")]
    Negative {
        /// The key.
        key: &'static str,
        /// Its value.
        value: f64,
    },
    /// A value that must be above zero.
    #[error("{key} must be a positive number, not {value}")]
    NotPositive {
        /// The key.
        key: &'static str,
        /// Its value.
        value: f64,
    },
    /// A count below its least value.
    #[error("{key} must be at least {least}, not {value}")]
    TooSmall {
        /// The key.
        key: &'static str,
        /// The least value.
        least: usize,
        /// Its value.
        value: usize,
    },
    /// `results.dir = ""`.
    #[error("results.dir is empty (leave it out for no result files)")]
    EmptyResultsDir,
    /// A `[cp]` value.
    #[error("[cp] {0}")]
    Cp(#[source] morphoid_core::cp::ParamError),
    /// `serial.port = ""`.
    #[error("serial.port is empty")]
    EmptySerialPort,
    /// `serial.baud = 0`.
    #[error("serial.baud must be positive")]
    NoBaud,
    /// `serial.trigger` is not a regular expression.
    #[error("serial.trigger {pattern:?} is not a valid regex: {source}")]
    Trigger {
        /// The pattern.
        pattern: String,
        /// Why the regex crate refused it.
        source: regex::Error,
    },
    /// An empty `watch.ignore` pattern.
    #[error("watch.ignore contains an empty pattern")]
    EmptyIgnorePattern,
    /// `http.listen` is not an address and port.
    #[error("http.listen {value:?} is not an address and port such as 127.0.0.1:8472")]
    NotAnAddress {
        /// The value.
        value: String,
    },
    /// `http.max_body_bytes` or `http.max_connections` is zero.
    #[error("http.max_body_bytes and http.max_connections must be positive")]
    NoBodyOrConnections,
    /// Only one of `http.tls_cert` and `http.tls_key`.
    #[error("http.tls_cert and http.tls_key go together (both or neither)")]
    TlsHalf,
    /// `http.login_failures_per_minute = 0`.
    #[error("http.login_failures_per_minute must be at least 1")]
    NoLoginFailures,
}

impl Config {
    /// Read and check a configuration file.
    pub fn read(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parse configuration text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let invalid = |message: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        let config: Config =
            toml::from_str(text).map_err(|e| invalid(e.to_string().trim().replace('\n', " ")))?;
        config.validate().map_err(|source| ConfigError::Value {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(config)
    }

    /// Checks of values that the types alone do not catch.
    fn validate(&self) -> Result<(), ValueError> {
        let non_negative = |key: &'static str, value: f64| {
            if value.is_finite() && value >= 0.0 {
                Ok(())
            } else {
                Err(ValueError::Negative { key, value })
            }
        };
        non_negative("watch.settle_seconds", self.watch.settle_seconds)?;
        non_negative("watch.incomplete_seconds", self.watch.incomplete_seconds)?;
        if self.clean.target_vertices < 100 {
            return Err(ValueError::TooSmall {
                key: "clean.target_vertices",
                least: 100,
                value: self.clean.target_vertices,
            });
        }
        if self
            .results
            .dir
            .as_ref()
            .is_some_and(|d| d.as_os_str().is_empty())
        {
            return Err(ValueError::EmptyResultsDir);
        }
        self.cp.validate().map_err(ValueError::Cp)?;
        if let Some(s) = &self.serial {
            if s.port.is_empty() {
                return Err(ValueError::EmptySerialPort);
            }
            if s.baud == 0 {
                return Err(ValueError::NoBaud);
            }
            regex::Regex::new(&s.trigger).map_err(|source| ValueError::Trigger {
                pattern: s.trigger.clone(),
                source,
            })?;
        }
        if self.watch.ignore.iter().any(String::is_empty) {
            return Err(ValueError::EmptyIgnorePattern);
        }
        self.http.validate()?;
        Ok(())
    }

    /// Checks that `check-config` adds to [`Config::read`]: values the
    /// daemon would accept but that are most likely mistakes (a baud rate
    /// no serial adapter uses), and paths that exist as the wrong kind of
    /// file. `path` names the configuration file in the error.
    pub fn check_plausible(&self, path: &Path) -> Result<(), ConfigError> {
        let invalid = |message: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if let Some(s) = &self.serial {
            if !is_standard_baud(s.baud) {
                return Err(invalid(format!(
                    "serial.baud {} is not a standard baud rate (one of {STANDARD_BAUDS:?})",
                    s.baud
                )));
            }
        }
        if let Some(dir) = &self.results.dir {
            if dir.exists() && !dir.is_dir() {
                return Err(invalid(format!(
                    "results.dir {} exists and is not a folder",
                    dir.display()
                )));
            }
        }
        Ok(())
    }

    /// The preparation settings (cleaning + engine).
    pub fn settings(&self) -> Settings {
        Settings {
            clean: self.clean.clone(),
            cp: self.cp.clone(),
            volume: self.volume.clone(),
        }
    }

    /// The rank columns, `None` meaning every column but `name`.
    pub fn ranks(&self) -> Option<&[String]> {
        (!self.library.ranks.is_empty()).then_some(self.library.ranks.as_slice())
    }

    /// The configured library folder, checked, with its rank columns.
    pub fn open_library(&self) -> Result<Library, LibraryError> {
        Library::open(&self.library.dir, self.ranks())
    }

    /// The cache of the configured library ([`Config::cache_for`] its
    /// folder).
    pub fn open_cache(&self) -> Result<Cache, CacheError> {
        self.cache_for(&self.library.dir, None)
    }

    /// The cache of prepared surfaces for the folder `folder`, the one rule
    /// of every command: the cache folder `explicit` (`--cache`) if given,
    /// else `[library] cache`, else the default cache folder; in it, the
    /// subfolder of `folder` ([`Cache::for_folder`]).
    pub fn cache_for(&self, folder: &Path, explicit: Option<&Path>) -> Result<Cache, CacheError> {
        Cache::for_folder(explicit.or(self.library.cache.as_deref()), folder)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_the_checks_refuse_are_named_with_the_file() {
        let message = |text: &str| match Config::parse(text, Path::new("m.toml")) {
            Err(e @ ConfigError::Value { .. }) => e.to_string(),
            other => panic!("{text}: {other:?}"),
        };
        let cases = [
            (
                "[watch]\nsettle_seconds = -1.0\n",
                "m.toml: watch.settle_seconds must be a non-negative number, not -1",
            ),
            (
                "[clean]\ntarget_vertices = 10\n",
                "m.toml: clean.target_vertices must be at least 100, not 10",
            ),
            (
                "[results]\ndir = \"\"\n",
                "m.toml: results.dir is empty (leave it out for no result files)",
            ),
            (
                "[serial]\nport = \"/dev/ttyS0\"\ntrigger = \"(\"\n",
                "m.toml: serial.trigger \"(\" is not a valid regex: ",
            ),
            (
                "[http]\nlisten = \"somewhere\"\n",
                "m.toml: http.listen \"somewhere\" is not an address and port such as 127.0.0.1:8472",
            ),
            (
                "[http]\nsession_hours = 0.0\n",
                "m.toml: http.session_hours must be a positive number, not 0",
            ),
            (
                "[http]\nmax_header_bytes = 100\n",
                "m.toml: http.max_header_bytes must be at least 8192, not 100",
            ),
            (
                "[http]\ntls_cert = \"c.pem\"\n",
                "m.toml: http.tls_cert and http.tls_key go together (both or neither)",
            ),
        ];
        for (text, expected) in cases {
            let got = message(text);
            assert!(got.starts_with(expected), "{text}: {got}");
        }
    }

    #[test]
    fn the_documented_example_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/morphoid.toml");
        let c = Config::read(&path).unwrap();
        assert_eq!(c.library.ranks, ["order", "family", "genus"]);
        assert!(c.serial.is_none());
    }

    #[test]
    fn a_bad_trigger_or_ignore_pattern_is_refused_and_odd_values_are_flagged() {
        let p = Path::new("x.toml");
        let e = Config::parse("[serial]\nport = \"/dev/ttyS0\"\ntrigger = \"(\"\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("serial.trigger") && e.contains("x.toml"), "{e}");
        let e = Config::parse("[watch]\nignore = [\"\"]\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("watch.ignore"), "{e}");
        let odd = Config::parse("[serial]\nport = \"/dev/ttyS0\"\nbaud = 9601\n", p).unwrap();
        let e = odd.check_plausible(p).unwrap_err().to_string();
        assert!(e.contains("9601") && e.contains("x.toml"), "{e}");
        let fine = Config::parse("[serial]\nport = \"/dev/ttyS0\"\nbaud = 9600\n", p).unwrap();
        assert!(fine.check_plausible(p).is_ok());
        assert!(is_standard_baud(115200) && !is_standard_baud(9601));
    }

    #[test]
    fn wrong_keys_and_values_are_named() {
        let p = Path::new("x.toml");
        let e = Config::parse("[watch]\nsettle_secs = 2\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("settle_secs") && e.contains("x.toml"), "{e}");
        let e = Config::parse("[watch]\nsettle_seconds = -1\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("settle_seconds"), "{e}");
        let e = Config::parse("[watch]\nrecursive = \"yes\"\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("recursive"), "{e}");
        let e = Config::parse("[serial]\nbaud = 9600\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("port"), "{e}");
        let e = Config::parse("[results]\ndir = \"\"\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("results.dir"), "{e}");
        let e = Config::parse("[results]\nfolder = \"r\"\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("folder"), "{e}");
        let c = Config::parse("[results]\ndir = \"out\"\n", p).unwrap();
        assert_eq!(c.results.dir, Some(PathBuf::from("out")));
        assert_eq!(Config::parse("", p).unwrap(), Config::default());
    }

    #[test]
    fn cp_values_are_checked_and_named_with_their_section() {
        let p = Path::new("x.toml");
        let e = Config::parse("[cp]\nwarp_width = 0\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("[cp] warp_width = 0: must be"), "{e}");
        let e = Config::parse("[cp]\ndescent_damping = nan\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("[cp] descent_damping = NaN"), "{e}");
        let c = Config::parse("[cp]\nsamples = 120\ndescent_steps = 0\n", p).unwrap();
        assert_eq!((c.cp.prepare.samples, c.cp.compare.descent_steps), (120, 0));
    }
}
