//! The cP distance on synthetic crowns (no outside data needed).

use morphoid_core::cp::{self, CpParams};
use morphoid_data::table::{distance_matrix, DistanceMatrix, Labels};
use morphoid_research::eval::leave_one_out;
use morphoid_synth::mesh::{self as synth, CROWN_GENERA};

#[test]
fn rigid_copies_and_mirror_images_are_at_distance_zero() {
    let params = CpParams::default();
    let m = synth::crown(&CROWN_GENERA[1], 3, 2000);
    let a = cp::prepare(&m, &params.prepare).expect("prepare");
    let moved = synth::scale(&synth::rigid_motion(&m, 5), 3.0);
    let c = cp::compare(
        &a,
        &cp::prepare(&moved, &params.prepare).expect("prepare"),
        &params.compare,
    );
    assert!(c.distance < 1e-3 && !c.reflected, "{}", c.distance);
    let mirrored = synth::mirror(&m);
    let c = cp::compare(
        &a,
        &cp::prepare(&mirrored, &params.prepare).expect("prepare"),
        &params.compare,
    );
    assert!(c.distance < 1e-3 && c.reflected, "{}", c.distance);
}

#[test]
fn matrix_is_symmetric_deterministic_and_separates_genera() {
    let params = CpParams::default();
    let mut prepared = Vec::new();
    let mut labels = String::from("name,genus\n");
    for (g, genus) in CROWN_GENERA.iter().enumerate().take(3) {
        for k in 0..3u64 {
            let mesh = synth::crown(genus, 100 + k, 1500);
            let mut p = cp::prepare(&mesh, &params.prepare).expect("prepare");
            p.set_name(format!("g{g}s{k}"));
            labels.push_str(&format!("{},{}\n", p.name(), genus.name));
            prepared.push(p);
        }
    }
    let m = distance_matrix(&prepared, &params.compare, |_| {});
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
        .install(|| distance_matrix(&prepared, &params.compare, |_| {}));
    assert_eq!(m, single);
    for i in 0..m.names().len() {
        assert_eq!(m.values()[i][i], 0.0);
        for j in 0..m.names().len() {
            assert_eq!(m.values()[i][j], m.values()[j][i]);
            assert!(m.values()[i][j].is_finite());
        }
    }
    let text = m.to_csv();
    assert_eq!(
        DistanceMatrix::parse_csv(&text, std::path::Path::new("m.csv")).expect("csv"),
        m
    );
    let labels = Labels::parse(&labels, None, std::path::Path::new("labels.csv")).expect("labels");
    let score = leave_one_out(&m, &labels, &["genus".to_string()]);
    assert_eq!(score[0].total, 9);
    assert!(score[0].correct >= 8, "{score:?}");
}

#[test]
fn the_final_descent_lowers_the_distance_of_different_crowns() {
    let params = CpParams::default();
    let mut searched_only = params.clone();
    searched_only.compare.descent_steps = 0;
    let a =
        cp::prepare(&synth::crown(&CROWN_GENERA[0], 1, 2000), &params.prepare).expect("prepare");
    let b =
        cp::prepare(&synth::crown(&CROWN_GENERA[2], 2, 2000), &params.prepare).expect("prepare");
    let searched = cp::compare(&a, &b, &searched_only.compare);
    let descended = cp::compare(&a, &b, &params.compare);
    // The descent starts from the searched maps and keeps only steps that
    // lower the residual.
    assert!(descended.distance <= searched.distance);
    assert!(
        descended.distance < 0.99 * searched.distance,
        "descent: {} -> {}",
        searched.distance,
        descended.distance
    );
    // The better direction was descended; the other kept its searched map.
    let (down, kept, kept_before) = if searched.forward.distance <= searched.backward.distance {
        (&descended.forward, &descended.backward, &searched.backward)
    } else {
        (&descended.backward, &descended.forward, &searched.forward)
    };
    assert_eq!(down.distance, descended.distance);
    assert_eq!(kept.distance, kept_before.distance);
    // A surface is still at distance zero from itself.
    assert!(cp::compare(&a, &a, &params.compare).distance < 1e-6);
}

/// Moved, remeshed copies of one near-symmetric crown (Lophodon, seed 8)
/// are matched by proper maps, never as mirror images: every directed
/// pair among 10 poses (90 comparisons) at under 0.002. When the search
/// refined the two best candidates overall, 34 of 240 such pairs (16
/// poses) were matched as mirror images at about 0.0047.
#[test]
fn moved_remeshed_copies_of_a_crown_are_never_matched_as_mirror_images() {
    use morphoid_core::mesh::bbox_diagonal;
    use morphoid_data::pipeline::{self, Settings};
    use morphoid_synth::mesh::RigidMotion;
    use rayon::prelude::*;
    let settings = Settings::default();
    let genus = synth::crown_genus("Lophodon").expect("genus");
    let source = pipeline::prepare_mesh(&synth::crown(genus, 8, 5000), "ref", &settings).unwrap();
    let diag = bbox_diagonal(&source.cleaned);
    let fine = synth::scale(&synth::subdivide_midpoint(&source.cleaned, 1), 1000.0);
    let copies: Vec<cp::Prepared> = (40..50u64)
        .into_par_iter()
        .map(|seed| {
            let mesh = RigidMotion::random(seed, 2000.0 * diag).apply(&fine);
            pipeline::prepare_mesh(&mesh, &format!("copy{seed}"), &settings)
                .unwrap()
                .prepared
        })
        .collect();
    let pairs: Vec<(usize, usize)> = (0..copies.len())
        .flat_map(|i| {
            (0..copies.len())
                .filter(move |&j| j != i)
                .map(move |j| (i, j))
        })
        .collect();
    let wrong: Vec<String> = pairs
        .par_iter()
        .filter_map(|&(i, j)| {
            let d = cp::compare_directed(&copies[i], &copies[j], &settings.cp.compare);
            (d.reflected || d.distance >= 0.002).then(|| {
                format!(
                    "{} -> {}: {:.5} reflected {}",
                    40 + i,
                    40 + j,
                    d.distance,
                    d.reflected
                )
            })
        })
        .collect();
    assert!(
        wrong.is_empty(),
        "{} of {}: {wrong:?}",
        wrong.len(),
        pairs.len()
    );
}
