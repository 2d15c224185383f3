//! `docs/slurm-matrix.sh` run for real under a single-node Slurm (Debian's
//! `slurm-wlm` and `munge`, configured and started by the test in a
//! temporary folder) on 10 real teeth: the merged matrix equals the
//! single-machine `morphoid matrix`, byte for byte, with a non-default
//! OUTDIR and CPUS taken from the node; a task killed while it runs and
//! resubmitted as docs/slurm.md says, from a shell with nothing exported,
//! ends in the same matrix. Needs root and minutes:
//!
//! ```sh
//! apt-get install slurm-wlm munge
//! cargo test --release --test it ops_slurm -- --ignored --nocapture
//! ```

use crate::support::data::tooth_paths;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");
const TEETH: usize = 10;
const SHARDS: usize = 4;

/// slurmctld, slurmd and munged, stopped (and waited for) on drop.
struct Cluster {
    dir: PathBuf,
    daemons: Vec<Child>,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Jobs first, so that nothing of ours outlives the test.
        let _ = self.command("scancel").arg("--user=root").status();
        std::thread::sleep(Duration::from_secs(1));
        for child in self.daemons.iter_mut().rev() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Cluster {
    fn conf(&self) -> PathBuf {
        self.dir.join("slurm.conf")
    }

    /// A Slurm client command that talks to this cluster only.
    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", self.conf());
        c
    }

    fn output(&self, program: &str, args: &[&str]) -> String {
        let out = self.command(program).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{program} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn start(dir: &Path) -> Cluster {
        let node = String::from_utf8(Command::new("hostname").arg("-s").output().unwrap().stdout)
            .unwrap()
            .trim()
            .to_string();
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap();
        let mem_mb: u64 = meminfo
            .lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|l| l.split_whitespace().next()?.parse::<u64>().ok())
            .unwrap()
            / 1024
            * 8
            / 10;
        let d = dir.display();
        let key = dir.join("munge.key");
        std::fs::write(&key, rand_key()).unwrap();
        set_mode(&key, 0o400);
        for sub in ["state", "spool"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        std::fs::write(
            dir.join("slurm.conf"),
            format!(
                "ClusterName=morphoidtest\n\
                 SlurmctldHost={node}(127.0.0.1)\n\
                 SlurmUser=root\nSlurmdUser=root\n\
                 AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket={d}/munge.sock\n\
                 StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
                 SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
                 SlurmctldPort=7917\nSlurmdPort=7918\n\
                 ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
                 JobAcctGatherType=jobacct_gather/none\nMpiDefault=none\n\
                 SchedulerType=sched/backfill\nSelectType=select/cons_tres\n\
                 SelectTypeParameters=CR_CPU\nReturnToService=2\n\
                 SlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
                 NodeName={node} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory={mem_mb} State=UNKNOWN\n\
                 PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n"
            ),
        )
        .unwrap();
        let mut cluster = Cluster {
            dir: dir.to_path_buf(),
            daemons: Vec::new(),
        };
        let spawn = |c: &mut Command| {
            c.stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap()
        };
        cluster.daemons.push(spawn(
            Command::new("munged")
                .args(["--foreground", "--force"])
                .arg(format!("--key-file={}", key.display()))
                .arg(format!("--socket={d}/munge.sock"))
                .arg(format!("--log-file={d}/munged.log"))
                .arg(format!("--pid-file={d}/munged.pid"))
                .arg(format!("--seed-file={d}/munged.seed")),
        ));
        wait_for(Duration::from_secs(20), "munged's socket", || {
            dir.join("munge.sock").exists()
        });
        cluster
            .daemons
            .push(spawn(cluster.command("slurmctld").args(["-D", "-i"])));
        cluster
            .daemons
            .push(spawn(cluster.command("slurmd").args(["-D", "-N", &node])));
        wait_for(Duration::from_secs(60), "the node to be idle", || {
            cluster
                .command("sinfo")
                .args(["-h", "-o", "%t"])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "idle")
        });
        cluster
    }

    /// The state of array task `task` of job `array` (empty once it left
    /// the queue).
    fn task_state(&self, array: &str, task: usize) -> String {
        let out = self
            .command("squeue")
            .args(["-h", "-o", "%T", "-j", &format!("{array}_{task}")])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }
}

fn rand_key() -> Vec<u8> {
    use rand::RngCore;
    let mut key = vec![0u8; 1024];
    rand::thread_rng().fill_bytes(&mut key);
    key
}

fn set_mode(path: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
}

fn wait_for(limit: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < limit, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// `bash docs/slurm-matrix.sh ARGS` in `dir` with only `env` set (and
/// PATH, HOME, SLURM_CONF): as from a fresh login shell.
fn script(cluster: &Cluster, dir: &Path, args: &[&str], env: &[(&str, &str)]) -> String {
    run_script("slurm-matrix.sh", cluster, dir, args, env)
}

/// `bash docs/NAME ARGS`, as [`script`] runs slurm-matrix.sh.
fn run_script(
    name: &str,
    cluster: &Cluster,
    dir: &Path,
    args: &[&str],
    env: &[(&str, &str)],
) -> String {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("docs")
        .join(name);
    let out = Command::new("bash")
        .arg(script)
        .args(args)
        .current_dir(dir)
        .env_clear()
        .env("PATH", std::env::var_os("PATH").unwrap_or_default())
        .env("HOME", dir)
        .env("SLURM_CONF", cluster.conf())
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{name} {args:?}: {text}");
    println!("{name} {args:?}: {}", text.trim());
    text
}

/// The array job id in the script's submission message.
fn array_id(message: &str) -> String {
    message
        .split_whitespace()
        .skip_while(|w| *w != "array" && *w != "as")
        .nth(1)
        .unwrap()
        .to_string()
}

fn wait_for_matrix(cluster: &Cluster, path: &Path, outdir: &Path) {
    wait_for_file(cluster, path, outdir, "the merged matrix")
}

/// Wait until `path` exists; a queue that empties without it shows the
/// logs in `outdir`.
fn wait_for_file(cluster: &Cluster, path: &Path, outdir: &Path, what: &str) {
    wait_for(Duration::from_secs(3600), what, || {
        if path.is_file() {
            return true;
        }
        // Nothing queued any more and still no matrix: show the logs.
        let queue = cluster.output("squeue", &["-h"]);
        if queue.trim().is_empty() {
            std::thread::sleep(Duration::from_secs(2));
            if !path.is_file() {
                let logs: Vec<String> = std::fs::read_dir(outdir)
                    .unwrap()
                    .flatten()
                    .filter(|e| e.path().extension().is_some_and(|x| x == "log"))
                    .map(|e| {
                        let text = std::fs::read_to_string(e.path()).unwrap_or_default();
                        format!("{}:\n{text}", e.path().display())
                    })
                    .collect();
                panic!(
                    "the queue is empty and there is no {what}:\n{}",
                    logs.join("\n")
                );
            }
        }
        false
    });
}

/// Root and the Slurm and munge programs, or a failure that says what
/// to install.
fn require_slurm() {
    assert!(
        crate::support::faults::have_root("ops_slurm"),
        "needs root (munged, slurmctld, slurmd)"
    );
    for tool in ["munged", "slurmctld", "slurmd", "sbatch"] {
        assert!(
            Command::new("sh")
                .args(["-c", &format!("command -v {tool}")])
                .status()
                .unwrap()
                .success(),
            "{tool} missing: apt-get install slurm-wlm munge"
        );
    }
}

#[test]
#[ignore = "starts a Slurm cluster (root, slurm-wlm, munge); minutes"]
fn the_job_array_script_merges_to_the_single_machine_matrix_also_after_a_killed_task() {
    require_slurm();
    let Some(teeth) = tooth_paths() else { return };
    let work = tempfile::tempdir().unwrap();
    // Slurm and munge insist on a traversable, non-world-writable folder.
    set_mode(work.path(), 0o755);
    let lib = work.path().join("library");
    std::fs::create_dir(&lib).unwrap();
    for t in teeth.iter().take(TEETH) {
        std::os::unix::fs::symlink(t, lib.join(t.file_name().unwrap())).unwrap();
    }
    let single = work.path().join("single.csv");
    let status = Command::new(BIN)
        .args(["matrix", "--library"])
        .arg(&lib)
        .arg("--out")
        .arg(&single)
        .status()
        .unwrap();
    assert!(status.success());
    let expected = std::fs::read(&single).unwrap();

    let cluster_dir = work.path().join("cluster");
    std::fs::create_dir(&cluster_dir).unwrap();
    set_mode(&cluster_dir, 0o755);
    let cluster = Cluster::start(&cluster_dir);
    let shards = SHARDS.to_string();

    // As documented, with a non-default OUTDIR (relative) and CPUS from
    // the node.
    let env = [
        ("LIBRARY", "library"),
        ("OUTDIR", "runs/first"),
        ("MATRIX", "runs/first/matrix.csv"),
        ("SHARDS", shards.as_str()),
        ("MORPHOID", BIN),
    ];
    let started = Instant::now();
    let message = script(&cluster, work.path(), &[], &env);
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get().min(8));
    assert!(message.contains(&format!("{cpus} CPUs each")), "{message}");
    let first = work.path().join("runs/first");
    wait_for_matrix(&cluster, &first.join("matrix.csv"), &first);
    println!("first run: {:.0} s", started.elapsed().as_secs_f64());
    assert_eq!(
        std::fs::read(first.join("matrix.csv")).unwrap(),
        expected,
        "the merged matrix differs from the single-machine one"
    );

    // A task killed while it runs; resubmitted from a shell where nothing
    // is exported, as docs/slurm.md says.
    let env = [
        ("LIBRARY", "library"),
        ("OUTDIR", "runs/second"),
        ("MATRIX", "runs/second/matrix.csv"),
        ("SHARDS", shards.as_str()),
        ("MORPHOID", BIN),
    ];
    let started = Instant::now();
    let message = script(&cluster, work.path(), &[], &env);
    let array = array_id(&message);
    wait_for(Duration::from_secs(600), "task 2 to run", || {
        cluster.task_state(&array, 2) == "RUNNING"
    });
    cluster.output("scancel", &[&format!("{array}_2")]);
    wait_for(Duration::from_secs(120), "task 2 to end", || {
        cluster.task_state(&array, 2).is_empty()
    });
    let second = work.path().join("runs/second");
    assert!(!second.join("shard-2-of-4.csv").exists());
    let message = script(
        &cluster,
        work.path(),
        &["resubmit", "runs/second", "2"],
        &[],
    );
    assert!(message.contains("resubmitted task(s) 2"), "{message}");
    wait_for_matrix(&cluster, &second.join("matrix.csv"), &second);
    println!(
        "run with a killed task: {:.0} s",
        started.elapsed().as_secs_f64()
    );
    assert_eq!(
        std::fs::read(second.join("matrix.csv")).unwrap(),
        expected,
        "the matrix after a resubmitted task differs from the single-machine one"
    );
    // The manual merge writes the same matrix too.
    std::fs::remove_file(second.join("matrix.csv")).unwrap();
    script(&cluster, work.path(), &["merge", "runs/second"], &[]);
    assert_eq!(std::fs::read(second.join("matrix.csv")).unwrap(), expected);
}

/// The library's calibration file in the cache folder `root` (its one
/// library subfolder) and its bytes.
fn calibration_file(root: &Path) -> (String, Vec<u8>) {
    let sub = std::fs::read_dir(root)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.is_dir())
        .expect("a library cache folder");
    let file = std::fs::read_dir(&sub)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("calibration-"))
        })
        .expect("a calibration file");
    let name = file.file_name().unwrap().to_string_lossy().into_owned();
    (name, std::fs::read(&file).unwrap())
}

/// `docs/slurm-library.sh` on 12 real teeth in 3 tasks per array: the
/// calibration the merge job stores is the single machine's, byte for
/// byte, and so is every prepared reference.
#[test]
#[ignore = "starts a Slurm cluster (root, slurm-wlm, munge); minutes"]
fn the_library_job_arrays_store_the_single_machine_calibration() {
    require_slurm();
    let Some(teeth) = tooth_paths() else { return };
    let work = tempfile::tempdir().unwrap();
    set_mode(work.path(), 0o755);
    let lib = work.path().join("library");
    std::fs::create_dir(&lib).unwrap();
    let names: Vec<String> = teeth
        .iter()
        .take(12)
        .map(|t| {
            std::os::unix::fs::symlink(t, lib.join(t.file_name().unwrap())).unwrap();
            t.file_stem().unwrap().to_string_lossy().into_owned()
        })
        .collect();
    let labels_of = crate::support::data::teeth_dir()
        .unwrap()
        .join("labels.csv");
    let text = std::fs::read_to_string(labels_of).unwrap();
    let mut lines = text.lines();
    let mut labels = format!("{}\n", lines.next().unwrap());
    for line in lines {
        if names
            .iter()
            .any(|n| line.split(',').next() == Some(n.as_str()))
        {
            labels += &format!("{line}\n");
        }
    }
    std::fs::write(lib.join("labels.csv"), labels).unwrap();
    let config = |name: &str| -> PathBuf {
        let path = work.path().join(format!("{name}.toml"));
        let text = format!(
            "[library]\ndir = {:?}\ncache = {:?}\ncalibrate = true\n[database]\npath = {:?}\n",
            lib,
            work.path().join(format!("cache-{name}")),
            work.path().join(format!("{name}.sqlite"))
        );
        std::fs::write(&path, text).unwrap();
        path
    };
    let single = config("single");
    let status = Command::new(BIN)
        .arg("--config")
        .arg(&single)
        .args(["library", "build"])
        .status()
        .unwrap();
    assert!(status.success());
    let expected = calibration_file(&work.path().join("cache-single"));

    let cluster_dir = work.path().join("cluster");
    std::fs::create_dir(&cluster_dir).unwrap();
    set_mode(&cluster_dir, 0o755);
    let cluster = Cluster::start(&cluster_dir);
    config("cluster");
    let env = [
        ("CONFIG", "cluster.toml"),
        ("OUTDIR", "runs/library"),
        ("SHARDS", "3"),
        ("MORPHOID", BIN),
    ];
    let started = Instant::now();
    let message = run_script("slurm-library.sh", &cluster, work.path(), &[], &env);
    assert!(message.contains("calibration array"), "{message}");
    let outdir = work.path().join("runs/library");
    // The merge job's log ends with the calibration it stored.
    let merged = || -> Option<String> {
        std::fs::read_dir(&outdir)
            .ok()?
            .flatten()
            .find(|e| e.file_name().to_string_lossy().starts_with("merge-"))
            .and_then(|e| std::fs::read_to_string(e.path()).ok())
            .filter(|log| log.contains("calibration genus"))
    };
    wait_for(
        Duration::from_secs(3600),
        "the merge job's calibration",
        || {
            if merged().is_some() {
                return true;
            }
            let queue = cluster.output("squeue", &["-h"]);
            if queue.trim().is_empty() {
                std::thread::sleep(Duration::from_secs(2));
                wait_for_file(
                    &cluster,
                    &outdir.join("no such file"),
                    &outdir,
                    "calibration",
                );
            }
            false
        },
    );
    println!("library arrays: {:.0} s", started.elapsed().as_secs_f64());
    let got = calibration_file(&work.path().join("cache-cluster"));
    assert_eq!(
        got.0, expected.0,
        "the calibration of another library or settings"
    );
    assert!(
        got.1 == expected.1,
        "the merged calibration differs from the single machine's"
    );
    for k in 1..=3 {
        assert!(outdir.join(format!("calibration-{k}-of-3.bin")).is_file());
    }
}
