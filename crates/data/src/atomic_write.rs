//! Replace a file atomically: readers see the old content or the new one,
//! never half a file, and after a crash the file is one or the other too.
//!
//! The bytes go to a temporary file with a unique name in the target's
//! folder (a rename is atomic only within one file system), which is
//! synced, renamed over the target, and then the folder is synced so that
//! the rename itself survives a power loss. Unique names let several
//! threads or processes write the same target at once: the last rename
//! wins and each reader sees one whole version. The temporary name starts
//! with `.` and ends with `.tmp`, so folder watchers that skip hidden or
//! temporary files (the daemon's defaults) never pick it up.

use std::fmt;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// The step of [`write_atomic`] that failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// Creating the temporary file in the target's folder.
    Create,
    /// Writing the bytes.
    Write,
    /// Syncing the temporary file to disk.
    Sync,
    /// Renaming it over the target.
    Rename,
    /// Syncing the folder (the rename).
    SyncFolder,
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Step::Create => "cannot create a temporary file beside it",
            Step::Write => "cannot write",
            Step::Sync => "cannot sync",
            Step::Rename => "cannot rename the temporary file onto it",
            Step::SyncFolder => "cannot sync its folder",
        })
    }
}

/// Why a file could not be replaced; names the target file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {step}: {source}", path.display())]
pub struct AtomicWriteError {
    path: PathBuf,
    step: Step,
    source: std::io::Error,
}

impl AtomicWriteError {
    /// The file that was to be written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The step that failed.
    pub fn step(&self) -> Step {
        self.step
    }
}

/// Replace the file `path` by `bytes` atomically and durably (see the
/// module documentation). The folder must exist. On failure the target is
/// unchanged and no temporary file is left behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), AtomicWriteError> {
    let fail = |step| {
        move |source| AtomicWriteError {
            path: path.to_path_buf(),
            step,
            source,
        }
    };
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(path.file_name().unwrap_or_default());
    prefix.push(".");
    // The temporary file is created like any new file (umask applies), not
    // with tempfile's owner-only default: the result is for others to read.
    let mut tmp = tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(".tmp")
        .permissions(new_file_permissions())
        .tempfile_in(folder)
        .map_err(fail(Step::Create))?;
    tmp.write_all(bytes).map_err(fail(Step::Write))?;
    tmp.as_file().sync_all().map_err(fail(Step::Sync))?;
    // On failure `persist` hands the file back; dropping it deletes it.
    tmp.persist(path).map_err(|e| fail(Step::Rename)(e.error))?;
    std::fs::File::open(folder)
        .and_then(|dir| dir.sync_all())
        .map_err(fail(Step::SyncFolder))
}

/// Read-write for everyone, less the umask: what `File::create` gives.
fn new_file_permissions() -> std::fs::Permissions {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::Permissions::from_mode(0o666)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    }

    #[test]
    fn replaces_the_content_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn new_files_are_readable_by_others_as_the_umask_allows() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let ours = dir.path().join("ours");
        write_atomic(&ours, b"x").unwrap();
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&plain));
    }

    #[test]
    fn concurrent_writers_leave_one_whole_version() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shared.bin");
        // Each writer's content is long and uniform, so a torn or mixed
        // file shows as bytes of two writers or a wrong length.
        const LEN: usize = 1 << 18;
        std::thread::scope(|s| {
            for t in 0..16u8 {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..8 {
                        write_atomic(path, &vec![t; LEN]).unwrap();
                    }
                });
            }
        });
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len(), LEN);
        assert!(bytes.iter().all(|&b| b == bytes[0] && b < 16));
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
    }

    #[test]
    fn a_failure_names_the_file_and_the_step() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no such folder").join("x.json");
        let e = write_atomic(&missing, b"x").unwrap_err();
        assert_eq!(e.step(), Step::Create);
        assert_eq!(e.path(), missing);
        assert!(e.to_string().contains("no such folder/x.json"), "{e}");

        // A folder in the way of the rename.
        let blocked = dir.path().join("blocked");
        std::fs::create_dir(&blocked).unwrap();
        let e = write_atomic(&blocked, b"x").unwrap_err();
        assert_eq!(e.step(), Step::Rename);
        assert!(blocked.is_dir());
        assert!(leftovers(dir.path()).is_empty());
    }
}
