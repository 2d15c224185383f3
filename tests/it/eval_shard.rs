//! A sharded matrix run, merged, equals the unsharded matrix exactly.

use morphoid_data::library;
use morphoid_data::pipeline::{prepare_file, Settings};
use morphoid_data::table::{distance_matrix, DistanceMatrix};
use morphoid_research::eval::{compute_shard, merge_shards, Shard, ShardFile};
use morphoid_synth::mesh::{write_synthetic_library, LibrarySpec};
use std::path::PathBuf;

#[test]
fn three_shards_merge_to_the_unsharded_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let spec = LibrarySpec {
        per_genus: 1,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    write_synthetic_library(dir.path(), &spec).unwrap();
    let files = library::surface_files(dir.path()).unwrap();
    let settings = Settings::default();
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    assert!(names.len() >= 5);

    let prepared: Vec<_> = files
        .iter()
        .map(|f| prepare_file(f, &settings).unwrap().prepared)
        .collect();
    let full: DistanceMatrix = distance_matrix(&prepared, &settings.cp.compare, |_| {});

    let out = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    let mut prepared_count = 0;
    for index in 1..=3 {
        let shard = Shard { index, count: 3 };
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let s = compute_shard(
            &names,
            shard,
            |k| {
                calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let hash = morphoid_data::hash::content_hash_file(&files[k]).unwrap().0;
                prepare_file(&files[k], &settings).map(|p| (p.prepared, hash))
            },
            &settings.cp.compare,
            |_| {},
        )
        .unwrap();
        prepared_count += calls.into_inner();
        let path = out.path().join(format!("part{index}.csv"));
        s.write(&path).unwrap();
        paths.push(path);
    }
    // Contiguous parts: the last shard (pairs of the last rows) needs fewer
    // specimens than the whole list.
    assert!(prepared_count < 3 * names.len(), "{prepared_count}");

    let read = |p: &PathBuf| (p.clone(), ShardFile::read(p).unwrap());
    let shards: Vec<_> = paths.iter().map(read).collect();
    let merged = merge_shards(&shards).unwrap();
    assert_eq!(merged, full);
    assert_eq!(merged.to_csv(), full.to_csv());

    let e = merge_shards(&shards[..2]).unwrap_err().to_string();
    assert!(
        e.contains("missing shard(s) 3/3") && e.contains("part1.csv"),
        "{e}"
    );
    let dup = vec![read(&paths[0]), read(&paths[1]), read(&paths[1])];
    let e = merge_shards(&dup).unwrap_err().to_string();
    assert!(e.contains("given twice") && e.contains("part2.csv"), "{e}");
}
