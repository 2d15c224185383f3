//! Calibrated confidence and "no close match": a synthetic library that
//! lacks one configuration (cheap, in CI), and the leave-one-genus-out
//! measurement on the 116 real teeth (`#[ignore]`, run by name).

use morphoid_data::library::{Cache, Library};
use morphoid_data::pipeline::Settings;
use morphoid_data::table::Labels;
use morphoid_service::classify::{self, Classifier};
use morphoid_service::identify::{
    expected_calibration_error, reliability, roc_auc, share_caught_at, Calibration, DistanceRow,
    ReferenceDistances,
};
use morphoid_service::store::Store;
use morphoid_synth::mesh::{self as synth, LibrarySpec};
use std::path::Path;

/// A synthetic library of four of the five configurations (four crowns
/// each); a new crown of one of them is a close match, a crown of the
/// fifth is not; the confidence goes into the
/// database, the JSON and back, and the distances among the references
/// are computed once and then taken from the cache.
#[test]
fn a_scan_of_a_missing_taxon_is_flagged_and_one_of_a_held_taxon_is_not() {
    let tmp = tempfile::tempdir().unwrap();
    let all = tmp.path().join("all");
    let spec = LibrarySpec {
        per_genus: 5,
        target_vertices: 1000,
        seed: 11,
        random_pose: false,
    };
    let specimens = synth::write_synthetic_library(&all, &spec).unwrap();
    let lib = tmp.path().join("library");
    let scans = tmp.path().join("scans");
    std::fs::create_dir_all(&lib).unwrap();
    std::fs::create_dir_all(&scans).unwrap();
    let mut labels = String::from("name,order,family,genus\n");
    let (mut held_scan, mut novel_scan) = (None, None);
    for s in &specimens {
        let index: usize = s.name[4..].parse().unwrap();
        let novel = s.genus.name == synth::CROWN_GENERA[0].name;
        let file = format!("{}.ply", s.name);
        if novel || index == 5 {
            let to = scans.join(&file);
            std::fs::copy(&s.path, &to).unwrap();
            if novel && novel_scan.is_none() {
                novel_scan = Some((to, s.genus.name));
            } else if !novel && held_scan.is_none() {
                held_scan = Some((to, s.genus.name));
            }
        } else {
            std::fs::copy(&s.path, lib.join(&file)).unwrap();
            labels += &format!(
                "{},{},{},{}\n",
                s.name, s.genus.order, s.genus.family, s.genus.name
            );
        }
    }
    std::fs::write(lib.join("labels.csv"), labels).unwrap();
    let (held_scan, held_genus) = held_scan.unwrap();
    let (novel_scan, _) = novel_scan.unwrap();

    let library = Library::open(&lib, None).unwrap();
    assert_eq!(library.members().len(), 16);
    let cache = Cache::open(&tmp.path().join("cache")).unwrap();
    let mut settings = Settings::default();
    settings.clean.target_vertices = 1000;
    let (classifier, built) = Classifier::build(&library, &cache, &settings, |_| {}).unwrap();
    let calibration = classifier.calibration().expect("calibrated").clone();
    let genus = calibration
        .ranks()
        .iter()
        .find(|r| r.rank == "genus")
        .unwrap();
    assert_eq!(genus.held, 16);
    assert!(genus.threshold.is_some(), "{genus:?}");

    let db = tmp.path().join("morphoid.sqlite");
    let mut store = Store::open(&db).unwrap();
    classifier.register(&mut store, &built).unwrap();
    let held = classify::identify_file(&mut store, &classifier, &held_scan).unwrap();
    let novel = classify::identify_file(&mut store, &classifier, &novel_scan).unwrap();

    let genus_of = |r: &morphoid_service::store::ScanRecord| {
        r.ranks.iter().find(|k| k.rank == "genus").unwrap().clone()
    };
    let h = genus_of(&held);
    assert_eq!(h.taxon, held_genus);
    let hc = h.confidence.clone().expect("confidence of the held taxon");
    assert_eq!(hc.no_close_match, Some(false), "{hc:?}");
    assert!(hc.probability > 0.8, "{hc:?}");
    let n = genus_of(&novel);
    let nc = n
        .confidence
        .clone()
        .expect("confidence of the missing taxon");
    assert_eq!(nc.no_close_match, Some(true), "{nc:?}");
    assert!(nc.novelty > hc.novelty);
    assert_eq!(novel.no_close_match(), Some(true));
    assert_eq!(held.no_close_match(), Some(false));

    // The JSON carries it per rank and for the scan.
    let json = serde_json::to_value(&novel).unwrap();
    assert_eq!(json["no_close_match"], true, "{json}");
    assert_eq!(json["ranks"]["genus"]["no_close_match"], true, "{json}");
    let p = json["ranks"]["genus"]["probability"].as_f64().unwrap();
    assert!((p - nc.probability).abs() < 1e-12);
    assert!(json["ranks"]["genus"]["novelty_threshold"].is_number());

    // Read back from the database after reopening: the same confidence.
    drop(store);
    let mut store = Store::open(&db).unwrap();
    let recent = store.recent(2).unwrap();
    assert_eq!(genus_of(&recent[0]).confidence, Some(nc));
    assert_eq!(genus_of(&recent[1]).confidence, Some(hc));

    // A second build takes the distances among the references from the
    // cache: one file, the same calibration.
    let files = |dir: &Path| -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("calibration-"))
            .collect()
    };
    let first = files(cache.dir());
    assert_eq!(first.len(), 1, "{first:?}");
    let (again, _) = Classifier::build(&library, &cache, &settings, |_| {}).unwrap();
    assert_eq!(again.calibration(), Some(&calibration));
    assert_eq!(files(cache.dir()), first);
    // A changed comparison setting changes the distances: a new file
    // replaces the old one.
    let mut other = settings.clone();
    other.cp.compare.descent_steps += 1;
    let (_, _) = Classifier::build(&library, &cache, &other, |_| {}).unwrap();
    let second = files(cache.dir());
    assert_eq!(second.len(), 1);
    assert_ne!(second, first);
}

/// Leave-one-genus-out on the 116 real teeth through the product's
/// functions: the distances among the teeth from the library build's
/// calibration (`library::reference_distances`), and for each tooth with
/// a known genus a calibration fitted on the library without it
/// (`Calibration::fit`) and its confidence (`Calibration::assess`), once
/// against all other teeth (genus present) and once against the teeth
/// of other genera (genus absent). Asserts ROC AUC ≥ 0.93 of the novelty
/// score, that it beats the raw nearest distance in AUC and in the share
/// flagged at ≤ 5 % false flags, that the product's own threshold flags at
/// most 10 % of present-genus teeth, and the genus probability's expected
/// calibration error < 0.05; prints the shares flagged, the fitted weights
/// of the rank term and the reliability table. Set `MORPHOID_CALIBRATION_CACHE` to a folder to keep the
/// prepared teeth and their distances between runs.
#[test]
#[ignore = "full 116-tooth measurement (minutes); run by name"]
fn novelty_and_calibration_on_the_116_teeth() {
    let Some(real) = crate::support::library::real_library() else {
        return;
    };
    assert_eq!(real.classifier.references().len(), 116);
    let table = &real.table;
    assert!(table.is_complete());
    let labels = real.library.labels();
    let m = measure(table, labels);

    eprintln!(
        "leave-one-out right: order {}, family {}, genus {}",
        m.right[0], m.right[1], m.right[2]
    );
    let auc = roc_auc(&m.absent, &m.present).unwrap();
    let caught = share_caught_at(&m.absent, &m.present, 0.05).unwrap();
    let raw_auc = roc_auc(&m.raw_absent, &m.raw_present).unwrap();
    let raw_caught = share_caught_at(&m.raw_absent, &m.raw_present, 0.05).unwrap();
    eprintln!("genus absent vs present ({} teeth):", m.present.len());
    eprintln!(
        "  raw nearest distance: AUC {raw_auc:.3}, caught at 5 % false flags {raw_caught:.3}"
    );
    eprintln!("  novelty score:        AUC {auc:.3}, caught at 5 % false flags {caught:.3}");
    eprintln!(
        "  the product's flag:   absent flagged {:.3}, present flagged {:.3}",
        m.flagged_absent, m.flagged_present
    );
    let ece = expected_calibration_error(&m.probability, &m.correct, 10).unwrap();
    let mut w = m.weights.clone();
    w.sort_by(f64::total_cmp);
    eprintln!(
        "genus weight of the rank term over the {} calibrations: min {:.3}, median {:.3}, max {:.3}",
        w.len(),
        w[0],
        w[w.len() / 2],
        w[w.len() - 1]
    );
    eprintln!("genus probability (leave-one-out): ECE {ece:.4}");
    eprintln!("| probability | teeth | mean probability | share right |");
    eprintln!("|---|---|---|---|");
    for b in reliability(&m.probability, &m.correct, 10).unwrap() {
        eprintln!(
            "| {:.1}–{:.1} | {} | {:.3} | {:.3} |",
            b.from, b.to, b.count, b.mean_probability, b.share_right
        );
    }
    assert_eq!(m.right, [114, 101, 96], "identification changed");
    assert!(auc >= 0.93, "novelty AUC {auc:.3} < 0.93");
    assert!(auc > raw_auc, "no better than the raw distance");
    assert!(caught > raw_caught, "catches no more than the raw distance");
    assert!(
        m.flagged_present <= 0.10,
        "the product flags {:.3} of present-genus teeth",
        m.flagged_present
    );
    assert!(ece < 0.05, "genus ECE {ece:.4} ≥ 0.05");
}

/// What [`measure`] found.
struct Measured {
    /// Right answers of the plain leave-one-out per rank (order, family, genus).
    right: [usize; 3],
    /// Genus novelty scores with the genus present / absent.
    present: Vec<f64>,
    absent: Vec<f64>,
    /// Raw nearest distances, likewise.
    raw_present: Vec<f64>,
    raw_absent: Vec<f64>,
    /// Share flagged by the product's threshold.
    flagged_present: f64,
    flagged_absent: f64,
    /// Genus probability and whether the genus was right (present case).
    probability: Vec<f64>,
    correct: Vec<bool>,
    /// The genus weight of the rank term of every calibration fitted.
    weights: Vec<f64>,
}

/// The distances of tooth `i` to the teeth `keep`, as a scan's rows.
fn rows_of(
    table: &ReferenceDistances,
    full: &[Vec<f64>],
    i: usize,
    keep: &[usize],
) -> Vec<DistanceRow> {
    keep.iter()
        .map(|&j| DistanceRow {
            reference: table.names()[j].clone(),
            forward: full[i][j],
            backward: full[i][j],
            distance: full[i][j],
            reflected: false,
        })
        .collect()
}

/// The genus-level measurements of the leave-one-genus-out.
fn measure(table: &ReferenceDistances, labels: &Labels) -> Measured {
    let names = table.names().to_vec();
    let n = names.len();
    // The full square table, row by row from the product's table.
    let full: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| table.distance(i, j).unwrap()).collect())
        .collect();
    let genus: Vec<Option<&str>> = names.iter().map(|x| labels.get(x, "genus")).collect();
    let mut m = Measured {
        right: [0; 3],
        present: vec![],
        absent: vec![],
        raw_present: vec![],
        raw_absent: vec![],
        flagged_present: 0.0,
        flagged_absent: 0.0,
        probability: vec![],
        correct: vec![],
        weights: vec![],
    };
    let (mut fp, mut fa) = (0usize, 0usize);
    for i in 0..n {
        let others: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        let rows = rows_of(table, &full, i, &others);
        let id = morphoid_service::identify::identify(&rows, labels, 1);
        for (k, rank) in ["order", "family", "genus"].iter().enumerate() {
            let got = id
                .ranks
                .iter()
                .find(|r| r.rank == *rank)
                .map(|r| r.taxon.as_str());
            if got.is_some() && got == labels.get(&names[i], rank) {
                m.right[k] += 1;
            }
        }
        let Some(g) = genus[i] else { continue };
        let absent_keep: Vec<usize> = (0..n).filter(|&j| genus[j] != Some(g)).collect();
        for (keep, present) in [(&others, true), (&absent_keep, false)] {
            let cal = Calibration::fit(table.subset(keep).unwrap(), labels);
            m.weights.extend(
                cal.ranks()
                    .iter()
                    .filter(|r| r.rank == "genus")
                    .map(|r| r.weight),
            );
            let rows = rows_of(table, &full, i, keep);
            let mut id = morphoid_service::identify::identify(&rows, labels, 1);
            cal.assess(&rows, &mut id.ranks);
            let r = id.ranks.iter().find(|r| r.rank == "genus").unwrap();
            let c = r.confidence.clone().expect("genus confidence");
            let flagged = c.no_close_match == Some(true);
            if present {
                m.present.push(c.novelty);
                m.raw_present.push(r.distance);
                fp += usize::from(flagged);
                m.probability.push(c.probability);
                m.correct.push(r.taxon == g);
            } else {
                m.absent.push(c.novelty);
                m.raw_absent.push(r.distance);
                fa += usize::from(flagged);
            }
        }
    }
    m.flagged_present = fp as f64 / m.present.len() as f64;
    m.flagged_absent = fa as f64 / m.absent.len() as f64;
    m
}
