//! The database schema and its migrations.
//!
//! The schema version is SQLite's `user_version`: version k means that
//! migrations 1..=k have been applied. Each migration runs in the same
//! transaction as the version bump, so a database is always at exactly one
//! version. Append new migrations at the end; never edit a published one.

use super::StoreError;
use rusqlite::{Connection, OptionalExtension, TransactionBehavior};
use std::path::Path;

/// `PRAGMA application_id` of a morphoid database ("MRPH"), so that a
/// different SQLite file given by mistake is refused instead of altered.
pub const APPLICATION_ID: i32 = 0x4d52_5048;

/// The migrations, in order; migration k (1-based) is `MIGRATIONS[k - 1]`.
pub const MIGRATIONS: &[&str] = &[
    MIGRATION_1,
    MIGRATION_2,
    MIGRATION_3,
    MIGRATION_4,
    MIGRATION_5,
    MIGRATION_6,
    MIGRATION_7,
    MIGRATION_8,
    MIGRATION_9,
];

/// The schema version this build writes and understands.
pub const SCHEMA_VERSION: u32 = MIGRATIONS.len() as u32;

/// Migration 1: references, scans (the job queue), results and distances.
/// Landmarks come in migration 2.
const MIGRATION_1: &str = r#"
CREATE TABLE reference (
    id           INTEGER PRIMARY KEY,
    name         TEXT NOT NULL,
    content_hash TEXT NOT NULL,
    -- {"rank": "taxon" | null, ...}
    labels       TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(labels)),
    state        TEXT NOT NULL DEFAULT 'pending'
                 CHECK (state IN ('pending', 'prepared', 'failed', 'superseded', 'removed')),
    error        TEXT,
    added_at     INTEGER NOT NULL,
    prepared_at  INTEGER,
    UNIQUE (name, content_hash)
);
-- At most one current (not superseded, not removed) version of each name.
CREATE UNIQUE INDEX reference_current_name ON reference (name)
    WHERE state NOT IN ('superseded', 'removed');

CREATE TABLE scan (
    id           INTEGER PRIMARY KEY AUTOINCREMENT,
    path         TEXT NOT NULL,
    -- One row per content: the same bytes are identified exactly once.
    content_hash TEXT NOT NULL UNIQUE,
    size         INTEGER NOT NULL CHECK (size >= 0),
    status       TEXT NOT NULL DEFAULT 'pending'
                 CHECK (status IN ('pending', 'running', 'ok', 'error')),
    error        TEXT,
    attempts     INTEGER NOT NULL DEFAULT 0,
    created_at   INTEGER NOT NULL,
    started_at   INTEGER,
    finished_at  INTEGER,
    timings      TEXT CHECK (timings IS NULL OR json_valid(timings)),
    cleaning     TEXT CHECK (cleaning IS NULL OR json_valid(cleaning)),
    CHECK ((status IN ('ok', 'error')) = (finished_at IS NOT NULL)),
    CHECK ((status = 'error') = (error IS NOT NULL))
);
CREATE INDEX scan_status ON scan (status, id);
CREATE INDEX scan_finished_at ON scan (finished_at);

CREATE TABLE result (
    scan_id      INTEGER NOT NULL REFERENCES scan (id) ON DELETE CASCADE,
    ordinal      INTEGER NOT NULL,  -- rank order, broadest first
    rank         TEXT NOT NULL,
    taxon        TEXT NOT NULL,
    reference_id INTEGER NOT NULL REFERENCES reference (id),
    distance     REAL NOT NULL,
    runner_up    TEXT,
    margin       REAL,
    PRIMARY KEY (scan_id, rank)
) WITHOUT ROWID;
CREATE INDEX result_reference ON result (reference_id);

CREATE TABLE distance (
    scan_id      INTEGER NOT NULL REFERENCES scan (id) ON DELETE CASCADE,
    reference_id INTEGER NOT NULL REFERENCES reference (id),
    forward      REAL NOT NULL,     -- d(scan, reference)
    backward     REAL NOT NULL,     -- d(reference, scan)
    distance     REAL NOT NULL,     -- the reported distance
    reflected    INTEGER NOT NULL CHECK (reflected IN (0, 1)),
    PRIMARY KEY (scan_id, reference_id)
) WITHOUT ROWID;
CREATE INDEX distance_reference ON distance (reference_id);
"#;

/// Migration 2: the landmarks of the nearest reference carried onto a
/// scan (one row per landmark, in the scan's file coordinates), written in
/// the same transaction as the scan's result.
const MIGRATION_2: &str = r#"
CREATE TABLE landmark (
    scan_id      INTEGER NOT NULL REFERENCES scan (id) ON DELETE CASCADE,
    idx          INTEGER NOT NULL CHECK (idx >= 0),   -- order in the reference's file
    label        TEXT,
    x            REAL NOT NULL,
    y            REAL NOT NULL,
    z            REAL NOT NULL,
    -- the reference whose landmarks were carried over
    reference_id INTEGER NOT NULL REFERENCES reference (id),
    PRIMARY KEY (scan_id, idx)
) WITHOUT ROWID;
CREATE INDEX landmark_reference ON landmark (reference_id);
"#;

/// Migration 3: a file whose content equals an earlier scan's gets its own
/// row (status `duplicate`, `duplicate_of` the earlier scan), so the content
/// hash is unique among the other rows only; `files_due` marks a finished
/// scan whose result files are still to be written (set in the transaction
/// that finishes it, cleared once they are). SQLite cannot change a CHECK
/// constraint in place: the table is rebuilt (foreign keys are off during
/// migrations, so the results pointing at scans are kept).
const MIGRATION_3: &str = r#"
CREATE TABLE scan_new (
    id           INTEGER PRIMARY KEY AUTOINCREMENT,
    path         TEXT NOT NULL,
    content_hash TEXT NOT NULL,
    size         INTEGER NOT NULL CHECK (size >= 0),
    status       TEXT NOT NULL DEFAULT 'pending'
                 CHECK (status IN ('pending', 'running', 'ok', 'error', 'duplicate')),
    error        TEXT,
    attempts     INTEGER NOT NULL DEFAULT 0,
    created_at   INTEGER NOT NULL,
    started_at   INTEGER,
    finished_at  INTEGER,
    timings      TEXT CHECK (timings IS NULL OR json_valid(timings)),
    cleaning     TEXT CHECK (cleaning IS NULL OR json_valid(cleaning)),
    duplicate_of INTEGER REFERENCES scan (id),
    files_due    INTEGER NOT NULL DEFAULT 0 CHECK (files_due IN (0, 1)),
    CHECK ((status IN ('ok', 'error', 'duplicate')) = (finished_at IS NOT NULL)),
    CHECK ((status = 'error') = (error IS NOT NULL)),
    CHECK ((status = 'duplicate') = (duplicate_of IS NOT NULL))
);
INSERT INTO scan_new (id, path, content_hash, size, status, error, attempts, created_at,
                      started_at, finished_at, timings, cleaning)
    SELECT id, path, content_hash, size, status, error, attempts, created_at,
           started_at, finished_at, timings, cleaning FROM scan;
DROP TABLE scan;
ALTER TABLE scan_new RENAME TO scan;
-- One identified row per content; each further file of that content once.
CREATE UNIQUE INDEX scan_content ON scan (content_hash) WHERE status <> 'duplicate';
CREATE UNIQUE INDEX scan_duplicate ON scan (content_hash, path) WHERE status = 'duplicate';
CREATE INDEX scan_status ON scan (status, id);
CREATE INDEX scan_finished_at ON scan (finished_at);
CREATE INDEX scan_duplicate_of ON scan (duplicate_of) WHERE duplicate_of IS NOT NULL;
CREATE INDEX scan_files_due ON scan (id) WHERE files_due = 1;
"#;

/// Migration 4: the calibrated confidence of each rank's answer (see
/// `library::Calibration`): the probability that the taxon is right, the
/// novelty score, the library's threshold for it and the "no close match"
/// flag. Null when the library was not calibrated (and for older results).
const MIGRATION_4: &str = r#"
ALTER TABLE result ADD COLUMN probability REAL
    CHECK (probability IS NULL OR (probability >= 0 AND probability <= 1));
ALTER TABLE result ADD COLUMN novelty REAL;
ALTER TABLE result ADD COLUMN novelty_threshold REAL;
ALTER TABLE result ADD COLUMN no_close_match INTEGER
    CHECK (no_close_match IS NULL OR no_close_match IN (0, 1));
"#;

/// Migration 5: why a finished scan's result files could not be written
/// (`files_error`, set by the attempt that failed, cleared by the one that
/// writes them), and whether the scan was identified while the library's
/// calibration was still running (`calibrating`: its confidence columns are
/// null for that reason, not because the library is uncalibrated).
const MIGRATION_5: &str = r#"
ALTER TABLE scan ADD COLUMN files_error TEXT;
ALTER TABLE scan ADD COLUMN calibrating INTEGER NOT NULL DEFAULT 0
    CHECK (calibrating IN (0, 1));
"#;

/// Migration 6: the status `superseded` (issue 30): a queued scan whose
/// file held other content when its job read it is not identified; its
/// row ends `superseded`, pointing (`superseded_by`) at the row of the
/// content that was read. A superseded row does not count as the
/// content's identified row, so the same content arriving again is queued.
/// The table is rebuilt for the new CHECK constraints. Also drops the
/// index of distances by reference: nothing reads distances by reference,
/// and with one entry per reference it made each scan's transaction touch
/// a page per reference (most of a scan's write-ahead log).
const MIGRATION_6: &str = r#"
CREATE TABLE scan_new (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    path          TEXT NOT NULL,
    content_hash  TEXT NOT NULL,
    size          INTEGER NOT NULL CHECK (size >= 0),
    status        TEXT NOT NULL DEFAULT 'pending'
                  CHECK (status IN ('pending', 'running', 'ok', 'error', 'duplicate',
                                    'superseded')),
    error         TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    created_at    INTEGER NOT NULL,
    started_at    INTEGER,
    finished_at   INTEGER,
    timings       TEXT CHECK (timings IS NULL OR json_valid(timings)),
    cleaning      TEXT CHECK (cleaning IS NULL OR json_valid(cleaning)),
    duplicate_of  INTEGER REFERENCES scan (id),
    files_due     INTEGER NOT NULL DEFAULT 0 CHECK (files_due IN (0, 1)),
    files_error   TEXT,
    calibrating   INTEGER NOT NULL DEFAULT 0 CHECK (calibrating IN (0, 1)),
    superseded_by INTEGER REFERENCES scan (id),
    CHECK ((status IN ('ok', 'error', 'duplicate', 'superseded')) = (finished_at IS NOT NULL)),
    CHECK ((status = 'error') = (error IS NOT NULL)),
    CHECK ((status = 'duplicate') = (duplicate_of IS NOT NULL)),
    CHECK ((status = 'superseded') = (superseded_by IS NOT NULL))
);
INSERT INTO scan_new (id, path, content_hash, size, status, error, attempts, created_at,
                      started_at, finished_at, timings, cleaning, duplicate_of, files_due,
                      files_error, calibrating)
    SELECT id, path, content_hash, size, status, error, attempts, created_at,
           started_at, finished_at, timings, cleaning, duplicate_of, files_due,
           files_error, calibrating FROM scan;
DROP TABLE scan;
ALTER TABLE scan_new RENAME TO scan;
CREATE UNIQUE INDEX scan_content ON scan (content_hash)
    WHERE status NOT IN ('duplicate', 'superseded');
CREATE UNIQUE INDEX scan_duplicate ON scan (content_hash, path) WHERE status = 'duplicate';
CREATE INDEX scan_status ON scan (status, id);
CREATE INDEX scan_finished_at ON scan (finished_at);
CREATE INDEX scan_duplicate_of ON scan (duplicate_of) WHERE duplicate_of IS NOT NULL;
CREATE INDEX scan_superseded_by ON scan (superseded_by) WHERE superseded_by IS NOT NULL;
CREATE INDEX scan_files_due ON scan (id) WHERE files_due = 1;
DROP INDEX distance_reference;
"#;

/// Migration 7: several specimens in one scan (issue 29). The scan's own
/// row (the job) gets `specimens`, their number; each specimen gets a row
/// of its own, `<scan>#n`, with `parent_id` the scan's row, `specimen`
/// its number n (1-based, in order along the scan's longest axis) and
/// `position` its bounding box (JSON: `voxels` in the input's voxels for
/// a volume, `bounds` in the file's coordinates). A specimen's row holds
/// its result, distances and landmarks like any scan's. The content's
/// uniqueness counts the scans' own rows only.
const MIGRATION_7: &str = r#"
ALTER TABLE scan ADD COLUMN parent_id INTEGER REFERENCES scan (id);
ALTER TABLE scan ADD COLUMN specimen INTEGER CHECK (specimen IS NULL OR specimen >= 1);
ALTER TABLE scan ADD COLUMN position TEXT CHECK (position IS NULL OR json_valid(position));
ALTER TABLE scan ADD COLUMN specimens INTEGER CHECK (specimens IS NULL OR specimens >= 2);
DROP INDEX scan_content;
CREATE UNIQUE INDEX scan_content ON scan (content_hash)
    WHERE status NOT IN ('duplicate', 'superseded') AND parent_id IS NULL;
CREATE UNIQUE INDEX scan_specimen ON scan (parent_id, specimen) WHERE parent_id IS NOT NULL;
"#;

/// Migration 8: the web console's curators (issue 32). `curator`: users
/// with their argon2 password hash (PHC string); `api_token`: the SHA-256
/// of each API token, never the token. `review`: every decision a curator
/// took on a scan (confirm, correct with a taxon per rank, reject), with
/// who, when, what the identification said then, and its place in the
/// scan's sequence of decisions (`seq`, `previous_id`; unique per scan, so
/// two decisions taken at once are both kept, one after the other). An
/// audit trail: triggers refuse every UPDATE and DELETE. No foreign key to
/// `scan`: a specimen's row goes when its scan is identified again, the
/// decisions taken on it stay (with the content hash and path they were
/// taken on).
const MIGRATION_8: &str = r#"
CREATE TABLE curator (
    id            INTEGER PRIMARY KEY,
    name          TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 64),
    password_hash TEXT NOT NULL,
    created_at    INTEGER NOT NULL
);
CREATE TABLE api_token (
    id          INTEGER PRIMARY KEY,
    curator_id  INTEGER NOT NULL REFERENCES curator (id) ON DELETE CASCADE,
    token_hash  TEXT NOT NULL UNIQUE,
    label       TEXT NOT NULL DEFAULT '',
    created_at  INTEGER NOT NULL
);
CREATE INDEX api_token_curator ON api_token (curator_id);
CREATE TABLE review (
    id           INTEGER PRIMARY KEY AUTOINCREMENT,
    scan_id      INTEGER NOT NULL,
    seq          INTEGER NOT NULL CHECK (seq >= 1),
    previous_id  INTEGER REFERENCES review (id),
    content_hash TEXT NOT NULL,
    path         TEXT NOT NULL,
    curator      TEXT NOT NULL CHECK (length(curator) >= 1),
    decided_at   INTEGER NOT NULL,
    decision     TEXT NOT NULL CHECK (decision IN ('confirm', 'correct', 'reject')),
    -- {"rank": "taxon"}: the taxa confirmed or given; {} for a rejection
    taxa         TEXT NOT NULL CHECK (json_valid(taxa)),
    -- {"rank": "taxon"}: what the identification said when the decision was taken
    identified   TEXT NOT NULL CHECK (json_valid(identified)),
    comment      TEXT,
    UNIQUE (scan_id, seq),
    CHECK ((seq = 1) = (previous_id IS NULL))
);
CREATE TRIGGER review_append_only_update BEFORE UPDATE ON review
BEGIN
    SELECT RAISE(ABORT, 'review is an audit trail: a decision is never rewritten');
END;
CREATE TRIGGER review_append_only_delete BEFORE DELETE ON review
BEGIN
    SELECT RAISE(ABORT, 'review is an audit trail: a decision is never deleted');
END;
"#;

/// Migration 9: the time each scan was claimed, indexed, so that the
/// fingerprint of the scan table that every open console polls
/// (`Store::changes_fingerprint`: its newest claim among others) is read
/// from indexes instead of the whole table (tens of milliseconds with
/// 100,000 scans, every 2 s per browser).
const MIGRATION_9: &str = r#"
CREATE INDEX scan_started_at ON scan (started_at);
"#;

/// Bring the database on `conn` to [`SCHEMA_VERSION`]: refuse a file of
/// another application or of a newer morphoid, then apply the missing
/// migrations, each in its own immediate transaction. Running it on an
/// up-to-date database changes nothing. `path` names the file in errors.
pub fn migrate(conn: &mut Connection, path: &Path) -> Result<u32, StoreError> {
    // A table rebuild must not cascade its DROP into the rows that point at
    // it; the pragma cannot change inside a transaction, so it is set
    // around them, and each migration checks the keys before it commits.
    let enforced: bool = conn.query_row("PRAGMA foreign_keys", [], |r| r.get(0))?;
    conn.pragma_update(None, "foreign_keys", false)?;
    let out = apply_migrations(conn, path);
    let restored = conn.pragma_update(None, "foreign_keys", enforced);
    let version = out?;
    restored?;
    Ok(version)
}

/// The loop of [`migrate`], with foreign keys off.
fn apply_migrations(conn: &mut Connection, path: &Path) -> Result<u32, StoreError> {
    loop {
        // IMMEDIATE: two processes opening a fresh file at once must not
        // both apply migration 1.
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let app: i32 = tx.query_row("PRAGMA application_id", [], |r| r.get(0))?;
        let found: i64 = tx.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        let found = u32::try_from(found)
            .map_err(|_| StoreError::Corrupt(format!("negative schema version {found}")))?;
        if app != APPLICATION_ID && !(app == 0 && is_empty(&tx)?) {
            return Err(StoreError::NotMorphoid {
                path: path.to_path_buf(),
                application_id: app,
            });
        }
        if found > SCHEMA_VERSION {
            return Err(StoreError::SchemaTooNew {
                path: path.to_path_buf(),
                found,
                supported: SCHEMA_VERSION,
            });
        }
        let Some(sql) = MIGRATIONS.get(found as usize) else {
            return Ok(found);
        };
        tx.execute_batch(sql)?;
        let dangling: Option<String> = tx
            .query_row("PRAGMA foreign_key_check", [], |r| r.get("table"))
            .optional()?;
        if let Some(table) = dangling {
            return Err(StoreError::Corrupt(format!(
                "migration {} leaves a dangling foreign key in table {table}",
                found + 1
            )));
        }
        tx.pragma_update(None, "user_version", found + 1)?;
        tx.pragma_update(None, "application_id", APPLICATION_ID)?;
        tx.commit()?;
    }
}

/// A file with no tables at all (new, or created empty by someone else).
fn is_empty(conn: &Connection) -> Result<bool, StoreError> {
    let n: i64 = conn.query_row("SELECT count(*) FROM sqlite_schema", [], |r| r.get(0))?;
    Ok(n == 0)
}
