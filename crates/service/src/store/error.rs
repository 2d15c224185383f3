//! The store's error type.

use super::ScanStatus;
use std::path::PathBuf;

/// Errors of the store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The file could not be opened or configured.
    #[error("cannot open database {path}: {source}")]
    Open {
        /// Database file.
        path: PathBuf,
        /// SQLite's error.
        source: rusqlite::Error,
    },
    /// Any other SQLite error.
    #[error("database error: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// The file was written by a newer morphoid.
    #[error(
        "database {path}: schema version {found} is newer than this morphoid \
         supports (version {supported}); use a newer morphoid or another database file"
    )]
    SchemaTooNew {
        /// Database file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Newest version this build knows.
        supported: u32,
    },
    /// The file is an SQLite database of some other application.
    #[error("{path} is not a morphoid database (SQLite application id {application_id:#010x})")]
    NotMorphoid {
        /// Database file.
        path: PathBuf,
        /// The file's `application_id`.
        application_id: i32,
    },
    /// No scan has this id.
    #[error("no scan with id {0}")]
    NoSuchScan(i64),
    /// The scan is not in a state that allows the operation.
    #[error("scan {scan_id} is {status}; {operation} needs {expected}")]
    WrongStatus {
        /// Scan id.
        scan_id: i64,
        /// Its status.
        status: ScanStatus,
        /// What was attempted.
        operation: &'static str,
        /// The status it needs.
        expected: &'static str,
    },
    /// A result names a reference that is not registered as current.
    #[error("unknown reference {0:?} (register it before recording results against it)")]
    UnknownReference(String),
    /// NaN, infinity or a negative distance in an outcome.
    #[error("invalid value {value} for {field}")]
    InvalidNumber {
        /// Which field.
        field: String,
        /// The value.
        value: f64,
    },
    /// A value that does not fit the database (e.g. a size above 2⁶³).
    #[error("value out of range for {0}")]
    OutOfRange(&'static str),
    /// A JSON column could not be written or read.
    #[error("JSON column {column}: {source}")]
    Json {
        /// Column.
        column: &'static str,
        /// serde_json's error.
        source: serde_json::Error,
    },
    /// The database holds something this build cannot interpret.
    #[error("corrupt database: {0}")]
    Corrupt(String),
}

impl StoreError {
    /// Whether SQLite reported the disk full (`SQLITE_FULL`).
    pub fn is_disk_full(&self) -> bool {
        let source = match self {
            StoreError::Open { source, .. } | StoreError::Sqlite(source) => source,
            _ => return false,
        };
        source.sqlite_error_code() == Some(rusqlite::ErrorCode::DiskFull)
    }

    /// Whether the storage failed rather than the request: the disk is
    /// full, an I/O error, the file or its folder is read-only, another
    /// connection holds the lock, the file cannot be opened (deleted,
    /// replaced, not a database). The same operation may succeed later on a
    /// fresh connection; anything else (a scan in the wrong state, a bad
    /// value) will fail again.
    pub fn is_storage_fault(&self) -> bool {
        use rusqlite::ErrorCode as C;
        let source = match self {
            StoreError::Open { .. } => return true,
            StoreError::Sqlite(e) => e,
            _ => return false,
        };
        matches!(
            source.sqlite_error_code(),
            Some(
                C::DiskFull
                    | C::SystemIoFailure
                    | C::ReadOnly
                    | C::DatabaseBusy
                    | C::DatabaseLocked
                    | C::CannotOpen
                    | C::FileLockingProtocolFailed
                    | C::NotADatabase
                    | C::DatabaseCorrupt
                    | C::PermissionDenied
                    | C::OutOfMemory
            )
        )
    }
}
