//! `morphoid run` and the export folder: slow writers, temporary names,
//! bad inputs, restarts.

mod daemon_support;

use daemon_support::*;
use morphoid::store::ScanStatus;
use std::io::Write;
use std::time::Duration;

#[test]
fn a_file_written_slowly_and_a_renamed_part_file_are_each_processed_once() {
    let env = env(2.0, "", "");
    let d = Daemon::start(&env);

    // Written in 6 chunks over 10 s: never taken early.
    let bytes = scan_bytes(1, 901);
    let target = env.export.join("slow.ply");
    let mut f = std::fs::File::create(&target).unwrap();
    let chunk = bytes.len().div_ceil(6);
    for (i, part) in bytes.chunks(chunk).enumerate() {
        f.write_all(part).unwrap();
        f.flush().unwrap();
        if i + 1 < bytes.len().div_ceil(chunk) {
            std::thread::sleep(Duration::from_secs(2));
            assert!(rows(&env.db).is_empty(), "taken before its last chunk");
        }
    }
    drop(f);

    // Written under a temporary name, renamed at the end.
    let part = env.export.join("x.part");
    std::fs::write(&part, scan_bytes(3, 902)).unwrap();
    std::thread::sleep(Duration::from_secs(3));
    std::fs::rename(&part, env.export.join("x.ply")).unwrap();

    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 2),
        "not processed: {:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(3));
    let r = rows(&env.db);
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(r[0].path.ends_with("slow.ply"), "{}", r[0].path);
    assert!(r[1].path.ends_with("x.ply"), "{}", r[1].path);
    for (row, g) in r.iter().zip([1, 3]) {
        assert_eq!(row.status, ScanStatus::Ok, "{row:?}");
        assert_eq!(
            row.size as usize,
            if g == 1 {
                bytes.len()
            } else {
                row.size as usize
            }
        );
        assert_eq!(genus_of(row), Some(genus(g)), "{row:?}");
    }
    let log = d.log_text();
    assert!(log.contains("slow.ply: order="), "{log}");
    assert!(
        !log.contains("\u{1b}["),
        "colour codes in a non-terminal log"
    );
}
