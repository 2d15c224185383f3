//! Real storage faults for the daemon tests: small file systems that fill
//! up (tmpfs), file systems that fail every I/O with EIO (a loop-mounted
//! ext4 shut down with `EXT4_IOC_SHUTDOWN`: device-mapper is not available
//! on every machine, this needs only loop devices), read-only bind
//! mounts. Mounts are undone by a guard's `Drop`, also when a test fails.
//! All of it needs root: without it a test fails, unless the developer
//! opts out with `MORPHOID_SKIP_ROOT=1` (the test then prints `skipped: …`
//! on stderr and passes; see [`super::missing`]). `MORPHOID_REQUIRE_ROOT=1`,
//! the former switch, is still accepted: it overrides the opt-out.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Whether the test can run: true as root; otherwise the test fails,
/// unless `MORPHOID_SKIP_ROOT=1`, where this prints `skipped: …` on stderr
/// and gives false, and the test returns early.
#[track_caller]
pub(crate) fn have_root(test: &str) -> bool {
    if running_as_root() {
        return true;
    }
    super::missing(
        &format!("{test} needs root"),
        "run the tests as root, as CI does",
        "MORPHOID_SKIP_ROOT",
        "MORPHOID_REQUIRE_ROOT",
    );
    false
}

/// Whether the tests run as root (effective user id 0).
pub(crate) fn running_as_root() -> bool {
    // SAFETY: geteuid cannot fail and touches no memory.
    unsafe { libc::geteuid() == 0 }
}

fn run(cmd: &str, args: &[&str]) {
    let out = Command::new(cmd).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{cmd} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn run_quietly(cmd: &str, args: &[&str]) {
    let _ = Command::new(cmd).args(args).output();
}

/// A mount on `target`, undone when dropped.
pub(crate) struct Mount {
    target: PathBuf,
    image: Option<PathBuf>,
    device: Option<String>,
}

impl Mount {
    /// A tmpfs of `size` (e.g. `"4m"`) on `target` (created).
    pub(crate) fn tmpfs(target: &Path, size: &str) -> Mount {
        std::fs::create_dir_all(target).unwrap();
        let t = target.to_str().unwrap();
        run(
            "mount",
            &["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs", t],
        );
        Mount {
            target: target.to_path_buf(),
            image: None,
            device: None,
        }
    }

    /// A fresh ext4 of `mb` MB in the image file `image`, loop-mounted on
    /// `target` (created).
    pub(crate) fn ext4(target: &Path, image: &Path, mb: u64) -> Mount {
        std::fs::create_dir_all(target).unwrap();
        let f = std::fs::File::create(image).unwrap();
        f.set_len(mb << 20).unwrap();
        drop(f);
        run("mkfs.ext4", &["-q", "-F", image.to_str().unwrap()]);
        let mut m = Mount {
            target: target.to_path_buf(),
            image: Some(image.to_path_buf()),
            device: None,
        };
        m.attach();
        m
    }

    fn attach(&mut self) {
        let image = self.image.as_ref().unwrap().to_str().unwrap();
        let out = Command::new("losetup")
            .args(["-f", "--show", image])
            .output()
            .unwrap();
        assert!(out.status.success(), "losetup: {:?}", out);
        let dev = String::from_utf8(out.stdout).unwrap().trim().to_string();
        run("mount", &[&dev, self.target.to_str().unwrap()]);
        self.device = Some(dev);
    }

    /// `target` bound onto itself read-only (root ignores permission bits,
    /// not a read-only mount).
    pub(crate) fn read_only(target: &Path) -> Mount {
        let t = target.to_str().unwrap();
        run("mount", &["--bind", t, t]);
        run("mount", &["-o", "remount,bind,ro", t]);
        Mount {
            target: target.to_path_buf(),
            image: None,
            device: None,
        }
    }

    /// Shut the ext4 file system down: from now on every read and write
    /// under it fails with EIO.
    pub(crate) fn fail_io(&self) {
        let dir = std::fs::File::open(&self.target).unwrap();
        use std::os::fd::AsRawFd as _;
        // EXT4_IOC_SHUTDOWN = _IOR('X', 125, __u32); flag 2: no log flush
        // (as a device that stops answering would).
        const EXT4_IOC_SHUTDOWN: libc::c_ulong = 0x8004_587D;
        let flags: u32 = 2;
        // SAFETY: the ioctl reads one u32 from the pointer, which is valid.
        let rc = unsafe { libc::ioctl(dir.as_raw_fd(), EXT4_IOC_SHUTDOWN as _, &flags) };
        assert_eq!(rc, 0, "shutdown: {}", std::io::Error::last_os_error());
    }

    /// Bring a shut-down ext4 back: unmount it (lazily: the daemon may
    /// still hold files on it) and mount its image again on a new loop
    /// device, as after replacing a failed disk. The journal is replayed.
    pub(crate) fn recover(&mut self) {
        self.detach();
        self.attach();
    }

    fn detach(&mut self) {
        run_quietly("umount", &["-l", self.target.to_str().unwrap()]);
        if let Some(dev) = self.device.take() {
            run_quietly("losetup", &["-d", &dev]);
        }
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        self.detach();
    }
}

/// Fill the file system of `dir` with a file `name` until it is full;
/// removing the file frees the space.
pub(crate) fn fill(dir: &Path, name: &str) -> PathBuf {
    use std::io::Write as _;
    let path = dir.join(name);
    let mut f = std::fs::File::create(&path).unwrap();
    let block = vec![0u8; 64 << 10];
    while f.write_all(&block).is_ok() {}
    // The last partial block.
    let small = [0u8; 512];
    while f.write_all(&small).is_ok() {}
    let _ = f.sync_all();
    path
}
