//! The Mantel test between two distance matrices over the same specimens:
//! the Pearson correlation of their upper triangles, and its significance
//! as the share of random relabelings (one permutation applied to the rows
//! and the columns of one matrix) that correlate at least as well.

use morphoid_data::table::DistanceMatrix;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};

/// Default number of random permutations of the Mantel test.
pub const DEFAULT_PERMUTATIONS: usize = 9_999;
/// Default seed of the Mantel test's permutations.
pub const DEFAULT_SEED: u64 = 1;

/// Permuted correlations within this much below the observed one count as
/// "at least as large": relabelings that only swap specimens with equal
/// distances must not lose the tie to rounding.
const TIE_TOLERANCE: f64 = 1e-12;

/// Result of a Mantel test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Mantel {
    /// Pearson correlation of the upper triangles.
    pub r: f64,
    /// `(1 + #{permutations with r_perm ≥ r}) / (permutations + 1)`.
    pub p: f64,
    /// Number of random permutations drawn (the identity not included).
    pub permutations: usize,
}

/// Why two matrices cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MantelError {
    /// The matrices are not over the same specimens.
    #[error("the matrices are not over the same specimens: only in the first: [{}]; only in the second: [{}]", only_first.join(", "), only_second.join(", "))]
    DifferentSpecimens {
        /// Names found only in the first matrix.
        only_first: Vec<String>,
        /// Names found only in the second matrix.
        only_second: Vec<String>,
    },
    /// A name occurs twice in one matrix.
    #[error("specimen `{0}` occurs more than once in a matrix")]
    DuplicateName(String),
    /// A matrix is not symmetric.
    #[error("a matrix is not symmetric: d({a}, {b}) = {ab} but d({b}, {a}) = {ba}")]
    NotSymmetric {
        /// First specimen.
        a: String,
        /// Second specimen.
        b: String,
        /// `d(a, b)`.
        ab: f64,
        /// `d(b, a)`.
        ba: f64,
    },
    /// A matrix holds a NaN or an infinity.
    #[error("a matrix holds a value that is not finite (row `{0}`)")]
    NotFinite(String),
    /// Fewer than three specimens: the correlation needs at least three pairs.
    #[error("{0} specimens: the Mantel test needs at least 3")]
    TooFew(usize),
    /// All off-diagonal distances of a matrix are equal: no correlation.
    #[error("all distances of a matrix are equal: the correlation is undefined")]
    Constant,
}

/// Pearson's correlation coefficient of two equally long samples; `None`
/// when they differ in length, have fewer than two values or one of them is
/// constant.
fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() || x.len() < 2 {
        return None;
    }
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        let (dx, dy) = (a - mx, b - my);
        sxy += dx * dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    if sxx <= 0.0 || syy <= 0.0 {
        return None;
    }
    // sqrt(s·s) is exactly s in floating point: r = 1 for identical inputs.
    Some((sxy / (sxx * syy).sqrt()).clamp(-1.0, 1.0))
}

/// The entries above the diagonal, row by row: `d(0,1), d(0,2), …, d(1,2), …`.
fn upper_triangle(m: &DistanceMatrix) -> Vec<f64> {
    let n = m.names().len();
    (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .map(|(i, j)| m.get(i, j))
        .collect()
}

/// Check that `m` (square by construction) is finite and symmetric (to a relative 1e-9 of
/// its largest entry) with unique names.
pub(super) fn check_distance_matrix(m: &DistanceMatrix) -> Result<(), MantelError> {
    let n = m.names().len();
    let mut seen = BTreeSet::new();
    for name in m.names() {
        if !seen.insert(name) {
            return Err(MantelError::DuplicateName(name.clone()));
        }
    }
    let mut largest: f64 = 0.0;
    for (name, r) in m.names().iter().zip(m.values()) {
        if r.iter().any(|v| !v.is_finite()) {
            return Err(MantelError::NotFinite(name.clone()));
        }
        largest = r.iter().fold(largest, |a, v| a.max(v.abs()));
    }
    let tol = 1e-9 * largest;
    for i in 0..n {
        for j in i + 1..n {
            let (ab, ba) = (m.get(i, j), m.get(j, i));
            if (ab - ba).abs() > tol {
                return Err(MantelError::NotSymmetric {
                    a: m.names()[i].clone(),
                    b: m.names()[j].clone(),
                    ab,
                    ba,
                });
            }
        }
    }
    Ok(())
}

/// `other` with its rows and columns reordered to follow `reference`'s
/// names; an error names the specimens the two do not share.
pub(super) fn align_to(
    reference: &DistanceMatrix,
    other: &DistanceMatrix,
) -> Result<DistanceMatrix, MantelError> {
    check_distance_matrix(reference)?;
    check_distance_matrix(other)?;
    let index: HashMap<&str, usize> = other
        .names()
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let only_first: Vec<String> = reference
        .names()
        .iter()
        .filter(|n| !index.contains_key(n.as_str()))
        .cloned()
        .collect();
    let ref_names: BTreeSet<&str> = reference.names().iter().map(String::as_str).collect();
    let only_second: Vec<String> = other
        .names()
        .iter()
        .filter(|n| !ref_names.contains(n.as_str()))
        .cloned()
        .collect();
    if !only_first.is_empty() || !only_second.is_empty() {
        return Err(MantelError::DifferentSpecimens {
            only_first,
            only_second,
        });
    }
    let map: Vec<usize> = reference
        .names()
        .iter()
        .filter_map(|n| index.get(n.as_str()).copied())
        .collect();
    let values = map
        .iter()
        .map(|&i| map.iter().map(|&j| other.get(i, j)).collect())
        .collect();
    Ok(DistanceMatrix::square(reference.names().to_vec(), values))
}

/// The Mantel correlation: Pearson r of the upper triangles of `a` and `b`,
/// matching specimens by name.
fn mantel_r(a: &DistanceMatrix, b: &DistanceMatrix) -> Result<f64, MantelError> {
    let b = align_to(a, b)?;
    let n = a.names().len();
    if n < 3 {
        return Err(MantelError::TooFew(n));
    }
    pearson(&upper_triangle(a), &upper_triangle(&b)).ok_or(MantelError::Constant)
}

/// The Mantel test of `a` against `b` (matched by name) with `permutations`
/// random relabelings of `b`, drawn from `seed`. Relabeling `b` by a
/// permutation π pairs `a(i, j)` with `b(π i, π j)`; the upper triangle of
/// the relabeled `b` holds the same values, so its mean and spread do not
/// change and only the cross product needs computing per permutation.
/// Permutation `k` draws from its own ChaCha stream `(seed, k)`, so the
/// result does not depend on the number of threads.
pub fn mantel_test(
    a: &DistanceMatrix,
    b: &DistanceMatrix,
    permutations: usize,
    seed: u64,
) -> Result<Mantel, MantelError> {
    let b = align_to(a, b)?;
    let n = a.names().len();
    if n < 3 {
        return Err(MantelError::TooFew(n));
    }
    let x = standardized_square(a).ok_or(MantelError::Constant)?;
    let y = standardized_square(&b).ok_or(MantelError::Constant)?;
    let identity: Vec<usize> = (0..n).collect();
    // The reported r comes from the plain two-pass formula (exactly 1 for
    // a matrix against itself); permutations are compared with the same
    // cross product they are computed with, so that rounding is alike.
    let r = mantel_r(a, &b)?;
    let observed = cross_product(&x, &y, &identity, n);
    let larger = (1..=permutations)
        .into_par_iter()
        .map_init(
            || identity.clone(),
            |perm, k| {
                perm.copy_from_slice(&identity);
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(k as u64);
                perm.shuffle(&mut rng);
                usize::from(cross_product(&x, &y, perm, n) >= observed - TIE_TOLERANCE)
            },
        )
        .sum::<usize>();
    Ok(Mantel {
        r,
        p: (1 + larger) as f64 / (permutations + 1) as f64,
        permutations,
    })
}

/// The matrix as a flat row-major `n × n` array whose off-diagonal entries
/// are the upper-triangle values centred on their mean and scaled to unit
/// sum of squares over the upper triangle; `None` when they are constant.
fn standardized_square(m: &DistanceMatrix) -> Option<Vec<f64>> {
    let n = m.names().len();
    let upper = upper_triangle(m);
    let mean = upper.iter().sum::<f64>() / upper.len() as f64;
    let norm = upper.iter().map(|v| (v - mean).powi(2)).sum::<f64>().sqrt();
    if norm <= 0.0 || !norm.is_finite() {
        return None;
    }
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let v = (m.get(i, j) - mean) / norm;
            out[i * n + j] = v;
            out[j * n + i] = v;
        }
    }
    Some(out)
}

/// `Σ_{i<j} x(i, j) · y(π i, π j)`: with standardized matrices, the
/// correlation of `x` with `y` relabeled by `perm`.
fn cross_product(x: &[f64], y: &[f64], perm: &[usize], n: usize) -> f64 {
    let mut total = 0.0;
    for (i, &pi) in perm.iter().enumerate() {
        let xrow = &x[i * n + i + 1..(i + 1) * n];
        let yrow = &y[pi * n..(pi + 1) * n];
        let mut s = 0.0;
        for (xv, &pj) in xrow.iter().zip(&perm[i + 1..]) {
            s += xv * yrow[pj];
        }
        total += s;
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    fn matrix(names: &[&str], values: Vec<Vec<f64>>) -> DistanceMatrix {
        DistanceMatrix::new(names.iter().map(|s| s.to_string()).collect(), values).unwrap()
    }

    /// A random symmetric matrix with zero diagonal (distances between
    /// random points in the plane, so that it is a genuine distance).
    fn random_matrix(n: usize, seed: u64) -> DistanceMatrix {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pts: Vec<[f64; 2]> = (0..n).map(|_| [rng.gen(), rng.gen()]).collect();
        let values = pts
            .iter()
            .map(|p| {
                pts.iter()
                    .map(|q| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt())
                    .collect()
            })
            .collect();
        DistanceMatrix::new((0..n).map(|i| format!("s{i:03}")).collect(), values).unwrap()
    }

    /// A copy of `m` with its names and rows changed by `edit`.
    fn edited(
        m: &DistanceMatrix,
        edit: impl FnOnce(&mut Vec<String>, &mut Vec<Vec<f64>>),
    ) -> DistanceMatrix {
        let (mut names, mut values) = m.clone().into_parts();
        edit(&mut names, &mut values);
        DistanceMatrix::new(names, values).unwrap()
    }

    fn from_upper(names: &[&str], upper: &[f64]) -> DistanceMatrix {
        let n = names.len();
        let mut v = vec![vec![0.0; n]; n];
        let pairs = (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j)));
        for ((i, j), &d) in pairs.zip(upper) {
            v[i][j] = d;
            v[j][i] = d;
        }
        matrix(names, v)
    }

    #[test]
    fn hand_computed_five_by_five() {
        // Upper triangles, row by row (ab ac ad ae bc bd be cd ce de):
        //   x = 1 2 3 4 2 3 4 1 2 3     Σx = 25, mean 2.5
        //   y = 2 1 4 3 3 5 4 2 1 5     Σy = 30, mean 3
        // deviations:
        //   dx = -1.5 -0.5 0.5 1.5 -0.5 0.5 1.5 -1.5 -0.5 0.5
        //   dy = -1   -2   1   0    0   2   1   -1   -2   2
        // Σdx·dy = 1.5 + 1 + 0.5 + 0 + 0 + 1 + 1.5 + 1.5 + 1 + 1 = 9
        // Σdx²   = four (±1.5)² and six (±0.5)² = 4·2.25 + 6·0.25 = 10.5
        // Σdy²   = 1 + 4 + 1 + 0 + 0 + 4 + 1 + 1 + 4 + 4 = 20
        // r = 9 / sqrt(10.5 · 20) = 9 / sqrt(210) = 0.621059…
        let names = ["a", "b", "c", "d", "e"];
        let x = from_upper(&names, &[1.0, 2.0, 3.0, 4.0, 2.0, 3.0, 4.0, 1.0, 2.0, 3.0]);
        let y = from_upper(&names, &[2.0, 1.0, 4.0, 3.0, 3.0, 5.0, 4.0, 2.0, 1.0, 5.0]);
        let expected = 9.0 / 210f64.sqrt();
        assert!((expected - 0.621_059).abs() < 1e-6);
        let r = mantel_r(&x, &y).unwrap();
        assert!((r - expected).abs() < 1e-12, "{r} vs {expected}");
        let t = mantel_test(&x, &y, 99, 1).unwrap();
        assert!((t.r - expected).abs() < 1e-12, "{} vs {expected}", t.r);
        assert!(t.p > 0.0 && t.p <= 1.0);
    }

    #[test]
    fn matrix_against_itself() {
        let m = random_matrix(40, 7);
        let t = mantel_test(&m, &m, 999, 1).unwrap();
        assert_eq!(t.r, 1.0);
        assert_eq!(t.p, 1.0 / 1000.0);
        assert_eq!(t.permutations, 999);
    }

    #[test]
    fn unrelated_matrices_are_not_significant() {
        // Under the null hypothesis p is uniform on (0, 1]: over 20 pairs of
        // independent matrices, few fall below 0.05 and the median is large.
        let mut ps: Vec<f64> = (0..20u64)
            .map(|k| {
                let a = random_matrix(30, 100 + 2 * k);
                let b = random_matrix(30, 101 + 2 * k);
                mantel_test(&a, &b, 199, k).unwrap().p
            })
            .collect();
        ps.sort_by(f64::total_cmp);
        let significant = ps.iter().filter(|&&p| p <= 0.05).count();
        assert!(significant <= 3, "{ps:?}");
        assert!(ps[10] > 0.2, "median p {}", ps[10]);
    }

    #[test]
    fn related_matrices_are_significant() {
        // b = a plus independent noise of a third of its size.
        let a = random_matrix(30, 3);
        let noise = random_matrix(30, 4);
        let b = edited(&a, |_, v| {
            for (row, noise) in v.iter_mut().zip(noise.values()) {
                for (x, e) in row.iter_mut().zip(noise) {
                    *x += 0.3 * e;
                }
            }
        });
        let t = mantel_test(&a, &b, 999, 5).unwrap();
        assert!(t.r > 0.5 && t.p < 0.01, "{t:?}");
    }

    /// The straightforward way: relabel the second matrix explicitly, take
    /// both upper triangles, compute Pearson's r from scratch.
    fn naive_mantel(a: &DistanceMatrix, b: &DistanceMatrix, perms: &[Vec<usize>]) -> (f64, usize) {
        let x = upper_triangle(a);
        let r = pearson(&x, &upper_triangle(b)).unwrap();
        let larger = perms
            .iter()
            .filter(|p| {
                let relabeled = DistanceMatrix::new(
                    b.names().to_vec(),
                    p.iter()
                        .map(|&i| p.iter().map(|&j| b.values()[i][j]).collect())
                        .collect(),
                )
                .unwrap();
                pearson(&x, &upper_triangle(&relabeled)).unwrap() >= r - TIE_TOLERANCE
            })
            .count();
        (r, larger)
    }

    #[test]
    fn agrees_with_naive_implementation() {
        let n = 25;
        let a = random_matrix(n, 21);
        let b = random_matrix(n, 22);
        // Make the pair mildly related so that the count is neither 0 nor all.
        let c = edited(&b, |_, v| {
            for (row, a_row) in v.iter_mut().zip(a.values()) {
                for (x, y) in row.iter_mut().zip(a_row) {
                    *x += 0.1 * y;
                }
            }
        });
        let perms: Vec<Vec<usize>> = (1..=200u64)
            .map(|k| {
                let mut rng = ChaCha8Rng::seed_from_u64(9);
                rng.set_stream(k);
                let mut p: Vec<usize> = (0..n).collect();
                p.shuffle(&mut rng);
                p
            })
            .collect();
        let (r, larger) = naive_mantel(&a, &c, &perms);
        let t = mantel_test(&a, &c, 200, 9).unwrap();
        assert!((t.r - r).abs() < 1e-12, "{} vs {r}", t.r);
        assert_eq!(t.p, (1 + larger) as f64 / 201.0);
    }

    #[test]
    fn matches_specimens_by_name() {
        let a = random_matrix(12, 31);
        // The same matrix with its specimens in reverse order.
        let order: Vec<usize> = (0..12).rev().collect();
        let b = DistanceMatrix::new(
            order.iter().map(|&i| a.names()[i].clone()).collect(),
            order
                .iter()
                .map(|&i| order.iter().map(|&j| a.values()[i][j]).collect())
                .collect(),
        )
        .unwrap();
        assert!((mantel_r(&a, &b).unwrap() - 1.0).abs() < 1e-12);
        let t1 = mantel_test(&a, &b, 99, 3).unwrap();
        assert_eq!(t1.p, 0.01);
    }

    #[test]
    fn deterministic_across_thread_counts() {
        let a = random_matrix(20, 41);
        let b = random_matrix(20, 42);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| mantel_test(&a, &b, 500, 77).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn errors_name_the_specimens() {
        let a = random_matrix(5, 1);
        let b = edited(&a, |names, _| names[1] = "zz".into());
        let e = mantel_test(&a, &b, 9, 1).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("s001") && msg.contains("zz"), "{msg}");
        let c = edited(&a, |_, v| v[0][2] += 1.0);
        assert!(matches!(
            mantel_r(&a, &c),
            Err(MantelError::NotSymmetric { .. })
        ));
        let flat = from_upper(&["a", "b", "c"], &[1.0, 1.0, 1.0]);
        assert_eq!(mantel_r(&flat, &flat), Err(MantelError::Constant));
        let two = from_upper(&["a", "b"], &[1.0]);
        assert_eq!(mantel_r(&two, &two), Err(MantelError::TooFew(2)));
        let nan = edited(&a, |_, v| v[1][1] = f64::NAN);
        assert!(matches!(mantel_r(&a, &nan), Err(MantelError::NotFinite(_))));
        let dup = edited(&a, |names, _| names[2] = names[0].clone());
        assert!(matches!(
            mantel_r(&dup, &a),
            Err(MantelError::DuplicateName(_))
        ));
    }
}
