//! Generalized Procrustes analysis (GPA) of landmark configurations in
//! correspondence: every configuration centred, scaled to unit centroid
//! size and rotated onto the iteratively re-estimated mean.

use morphoid_core::cp::{Handedness, Moments};

/// The similarity `x ↦ R (x − c) / s` that takes a configuration (or its
/// surface) into the Procrustes frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Superimposition {
    /// The centroid `c` of the configuration.
    pub centroid: [f64; 3],
    /// Its centroid size `s` (root of the summed squared distances to `c`).
    pub size: f64,
    /// The orthogonal matrix `R`, row-major (determinant −1 when the
    /// configuration was fitted as a mirror image).
    pub rotation: [[f64; 3]; 3],
}

impl Superimposition {
    /// The image of `x`.
    pub fn apply(&self, x: [f64; 3]) -> [f64; 3] {
        let y = [0, 1, 2].map(|d| (x[d] - self.centroid[d]) / self.size);
        rotate(&self.rotation, y)
    }

    /// Whether `R` is a reflection (faces of a moved mesh then need their
    /// corner order reversed to keep their outward side).
    pub fn reflects(&self) -> bool {
        determinant(&self.rotation) < 0.0
    }
}

/// The result of [`generalized_procrustes`].
#[derive(Debug, Clone, PartialEq)]
pub struct Gpa {
    /// Each configuration in the Procrustes frame (the Procrustes
    /// coordinates), in input order.
    pub aligned: Vec<Vec<[f64; 3]>>,
    /// The mean shape (unit centroid size, centred).
    pub mean: Vec<[f64; 3]>,
    /// The similarity that took each configuration there.
    pub superimpositions: Vec<Superimposition>,
    /// Iterations until the mean stopped moving.
    pub iterations: usize,
}

/// Why GPA cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpaError {
    /// No configuration.
    #[error("no landmark configurations")]
    Empty,
    /// Configurations of different lengths.
    #[error("configuration {index} has {found} landmarks, the first {expected}")]
    Count {
        /// Which configuration.
        index: usize,
        /// Landmarks of the first.
        expected: usize,
        /// Landmarks of this one.
        found: usize,
    },
    /// A configuration has no extent or a non-finite coordinate.
    #[error("configuration {0} is degenerate (all landmarks at one point, or not finite)")]
    Degenerate(usize),
}

fn rotate(r: &[[f64; 3]; 3], x: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2])
}

fn determinant(r: &[[f64; 3]; 3]) -> f64 {
    r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0])
}

/// Centroid and centroid size of a configuration.
pub(crate) fn centroid_size(points: &[[f64; 3]]) -> ([f64; 3], f64) {
    let n = points.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n;
        }
    }
    let s = points
        .iter()
        .map(|p| (0..3).map(|d| (p[d] - c[d]).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt();
    (c, s)
}

/// The optimal rotation (of the given handedness) of `x` onto `y`, both
/// centred.
fn rotation_onto(x: &[[f64; 3]], y: &[[f64; 3]], handedness: Handedness) -> [[f64; 3]; 3] {
    let mut m = Moments::default();
    for (p, q) in x.iter().zip(y) {
        m.add(*p, *q, 1.0);
    }
    m.fit(handedness).rotation
}

/// Squared distance between two configurations.
fn squared_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>())
        .sum()
}

/// GPA of `configurations` (landmarks paired by index). Each is centred
/// and scaled to unit centroid size, then rotated onto the mean — a proper
/// rotation, or a rotation with a reflection where `handedness[i]` is
/// `Improper` (a configuration carried by an orientation-reversing map is
/// a mirror image of the others) — and the mean is re-estimated, until it
/// moves less than `1e-12` (at most 100 rounds). The first mean is the
/// configuration `reference`, and each new mean is rotated onto the
/// previous one, so the frame is the reference's own.
pub(crate) fn generalized_procrustes(
    configurations: &[Vec<[f64; 3]>],
    handedness: &[Handedness],
    reference: usize,
) -> Result<Gpa, GpaError> {
    let first = configurations.first().ok_or(GpaError::Empty)?;
    let k = first.len();
    let mut standard = Vec::with_capacity(configurations.len());
    let mut frames = Vec::with_capacity(configurations.len());
    for (i, c) in configurations.iter().enumerate() {
        if c.len() != k {
            return Err(GpaError::Count {
                index: i,
                expected: k,
                found: c.len(),
            });
        }
        let (centroid, size) = centroid_size(c);
        if !(size.is_finite() && size > 0.0) || k < 2 {
            return Err(GpaError::Degenerate(i));
        }
        standard.push(
            c.iter()
                .map(|p| [0, 1, 2].map(|d| (p[d] - centroid[d]) / size))
                .collect::<Vec<_>>(),
        );
        frames.push((centroid, size));
    }
    let hand = |i: usize| handedness.get(i).copied().unwrap_or(Handedness::Proper);
    let reference = reference.min(standard.len() - 1);
    let mut mean = standard[reference].clone();
    let mut rotations = vec![[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]; standard.len()];
    let mut iterations = 0;
    while iterations < 100 {
        iterations += 1;
        for (i, x) in standard.iter().enumerate() {
            rotations[i] = rotation_onto(x, &mean, hand(i));
        }
        let mut next = vec![[0.0; 3]; k];
        for (x, r) in standard.iter().zip(&rotations) {
            for (m, p) in next.iter_mut().zip(x) {
                let q = rotate(r, *p);
                for d in 0..3 {
                    m[d] += q[d] / standard.len() as f64;
                }
            }
        }
        let (_, size) = centroid_size(&next);
        if size.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let next: Vec<[f64; 3]> = next.iter().map(|p| p.map(|v| v / size)).collect();
        let r = rotation_onto(&next, &mean, Handedness::Proper);
        let next: Vec<[f64; 3]> = next.iter().map(|p| rotate(&r, *p)).collect();
        let moved = squared_distance(&next, &mean);
        mean = next;
        if moved < 1e-24 {
            break;
        }
    }
    for (i, x) in standard.iter().enumerate() {
        rotations[i] = rotation_onto(x, &mean, hand(i));
    }
    let aligned = standard
        .iter()
        .zip(&rotations)
        .map(|(x, r)| x.iter().map(|p| rotate(r, *p)).collect())
        .collect();
    let superimpositions = frames
        .iter()
        .zip(&rotations)
        .map(|(&(centroid, size), &rotation)| Superimposition {
            centroid,
            size,
            rotation,
        })
        .collect();
    Ok(Gpa {
        aligned,
        mean,
        superimpositions,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_rotation(rng: &mut impl Rng) -> [[f64; 3]; 3] {
        let m = nalgebra::Matrix3::from_fn(|_, _| rng.gen::<f64>() - 0.5);
        let q = m.qr().q();
        let q = if q.determinant() < 0.0 { -q } else { q };
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| q[(i, j)]))
    }

    #[test]
    fn similar_copies_superimpose_exactly() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let base: Vec<[f64; 3]> = (0..12)
            .map(|_| [0, 1, 2].map(|_| rng.gen::<f64>()))
            .collect();
        let mut configs = Vec::new();
        let mut hands = Vec::new();
        for i in 0..6 {
            let r = random_rotation(&mut rng);
            let s = 0.5 + rng.gen::<f64>() * 3.0;
            let t = [0, 1, 2].map(|_| rng.gen::<f64>() * 10.0);
            let mirror = i % 3 == 2;
            configs.push(
                base.iter()
                    .map(|p| {
                        let p = if mirror { [-p[0], p[1], p[2]] } else { *p };
                        let q = rotate(&r, p);
                        [0, 1, 2].map(|d| s * q[d] + t[d])
                    })
                    .collect::<Vec<_>>(),
            );
            hands.push(if mirror {
                Handedness::Improper
            } else {
                Handedness::Proper
            });
        }
        let gpa = generalized_procrustes(&configs, &hands, 0).unwrap();
        for a in &gpa.aligned {
            assert!(squared_distance(a, &gpa.mean) < 1e-20);
        }
        let (c, s) = centroid_size(&gpa.mean);
        assert!((s - 1.0).abs() < 1e-12 && c.iter().all(|v| v.abs() < 1e-12));
        // The frame is the reference's: its standardized form is the mean.
        let (c0, s0) = centroid_size(&configs[0]);
        for (p, m) in configs[0].iter().zip(&gpa.mean) {
            for d in 0..3 {
                assert!(((p[d] - c0[d]) / s0 - m[d]).abs() < 1e-9);
            }
        }
        assert!(gpa.superimpositions[2].reflects() && !gpa.superimpositions[1].reflects());
        let moved = gpa.superimpositions[3].apply(configs[3][4]);
        assert!(squared_distance(&[moved], &[gpa.aligned[3][4]]) < 1e-24);
    }

    #[test]
    fn bad_configurations_are_errors() {
        assert_eq!(generalized_procrustes(&[], &[], 0), Err(GpaError::Empty));
        let a = vec![[0.0; 3], [1.0, 0.0, 0.0]];
        let b = vec![[0.0; 3]];
        assert!(matches!(
            generalized_procrustes(&[a.clone(), b], &[], 0),
            Err(GpaError::Count { index: 1, .. })
        ));
        let flat = vec![[2.0; 3], [2.0; 3]];
        assert_eq!(
            generalized_procrustes(&[a, flat], &[], 0),
            Err(GpaError::Degenerate(1))
        );
    }

    #[test]
    fn the_mean_of_noisy_copies_is_between_them() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let base: Vec<[f64; 3]> = (0..20)
            .map(|_| [0, 1, 2].map(|_| rng.gen::<f64>()))
            .collect();
        let configs: Vec<Vec<[f64; 3]>> = (0..10)
            .map(|_| {
                let r = random_rotation(&mut rng);
                base.iter()
                    .map(|p| rotate(&r, p.map(|v| v + 0.01 * (rng.gen::<f64>() - 0.5))))
                    .collect()
            })
            .collect();
        let gpa = generalized_procrustes(&configs, &[], 3).unwrap();
        let (c, s) = centroid_size(&base);
        let std: Vec<[f64; 3]> = base
            .iter()
            .map(|p| [0, 1, 2].map(|d| (p[d] - c[d]) / s))
            .collect();
        let r = rotation_onto(&std, &gpa.mean, Handedness::Proper);
        let fitted: Vec<[f64; 3]> = std.iter().map(|p| rotate(&r, *p)).collect();
        // Noise of ±0.005 on a shape of size ~1.3: the mean is within it.
        assert!(squared_distance(&fitted, &gpa.mean).sqrt() < 0.01);
        assert!(gpa.iterations < 100);
    }
}
