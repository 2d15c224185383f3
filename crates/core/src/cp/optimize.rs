//! Derivative-free local minimization (Nelder–Mead) of the refinement
//! over disk automorphisms near a candidate map.

/// Relative spread of the simplex's values at which the refinement stops:
/// the objective is a squared distance, so this settles the distance to
/// about 5e-5 of itself, far below what separates two specimens.
const NELDER_MEAD_TOLERANCE: f64 = 1e-4;

/// Minimize `f` over R³ from `x0` with the Nelder–Mead simplex method,
/// initial steps `step`, about `max_evals` evaluations: no step starts
/// with fewer than two left, and a step that ends in a shrink takes up to
/// five (fewer once the simplex's values agree to
/// [`NELDER_MEAD_TOLERANCE`]).
pub(crate) fn nelder_mead(
    f: impl FnMut([f64; 3]) -> f64,
    x0: [f64; 3],
    step: [f64; 3],
    max_evals: usize,
) -> ([f64; 3], f64) {
    nelder_mead_unless(f, x0, step, max_evals, None)
}

/// When a minimization is not worth finishing: once `after` evaluations
/// are spent, a best value still above `above` ends it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct GiveUp {
    /// Evaluations spent before the check.
    pub after: usize,
    /// The value the best vertex must be at or below by then.
    pub above: f64,
}

/// [`nelder_mead`], ended early by `give_up`. Until it ends, the steps
/// are exactly those of [`nelder_mead`], so a minimization that is not
/// given up gives the same result.
pub(super) fn nelder_mead_unless(
    mut f: impl FnMut([f64; 3]) -> f64,
    x0: [f64; 3],
    step: [f64; 3],
    max_evals: usize,
    give_up: Option<GiveUp>,
) -> ([f64; 3], f64) {
    let mut simplex: Vec<([f64; 3], f64)> = Vec::with_capacity(4);
    simplex.push((x0, f(x0)));
    for k in 0..3 {
        let mut x = x0;
        x[k] += step[k];
        simplex.push((x, f(x)));
    }
    let mut evals = 4;
    let lerp = |a: [f64; 3], b: [f64; 3], t: f64| [0, 1, 2].map(|k| a[k] + t * (b[k] - a[k]));
    while evals + 2 <= max_evals {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let worst = simplex[3];
        let centroid =
            [0, 1, 2].map(|k| (simplex[0].0[k] + simplex[1].0[k] + simplex[2].0[k]) / 3.0);
        let xr = lerp(centroid, worst.0, -1.0);
        let fr = f(xr);
        evals += 1;
        if fr < simplex[0].1 {
            let xe = lerp(centroid, worst.0, -2.0);
            let fe = f(xe);
            evals += 1;
            simplex[3] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[2].1 {
            simplex[3] = (xr, fr);
        } else {
            let xc = if fr < worst.1 {
                lerp(centroid, xr, 0.5)
            } else {
                lerp(centroid, worst.0, 0.5)
            };
            let fc = f(xc);
            evals += 1;
            if fc < worst.1.min(fr) {
                simplex[3] = (xc, fc);
            } else {
                // Shrink towards the best vertex.
                let best = simplex[0].0;
                for s in simplex.iter_mut().skip(1) {
                    let x = lerp(best, s.0, 0.5);
                    *s = (x, f(x));
                    evals += 1;
                }
            }
        }
        let spread = simplex
            .iter()
            .map(|s| s.1)
            .fold(f64::NEG_INFINITY, f64::max)
            - simplex.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
        if spread <= NELDER_MEAD_TOLERANCE * simplex[0].1.abs().max(1e-300) {
            break;
        }
        if let Some(g) = give_up {
            let best = simplex.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
            if evals >= g.after && best > g.above {
                break;
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quadratic_bowl_is_minimized() {
        let centre = [0.3, -0.2, 1.1];
        let f = |x: [f64; 3]| {
            1.0 + (0..3)
                .map(|k| (k + 1) as f64 * (x[k] - centre[k]).powi(2))
                .sum::<f64>()
        };
        let (x, fx) = nelder_mead(f, [0.0; 3], [0.1; 3], 2000);
        for k in 0..3 {
            assert!((x[k] - centre[k]).abs() < 0.05, "{x:?}");
        }
        // The tolerance stops it once the values agree to 1e-4.
        assert!((1.0..1.0 + 1e-3).contains(&fx), "{fx}");
    }

    #[test]
    fn the_evaluation_budget_is_kept_and_the_start_is_never_lost() {
        let mut calls = 0;
        let f = |x: [f64; 3]| {
            calls += 1;
            x[0].powi(2) + (x[1] - 1.0).powi(2) + x[2].abs()
        };
        let (_, fx) = nelder_mead(f, [0.5, 0.5, 0.5], [0.05; 3], 20);
        assert!(calls <= 20 + 3, "{calls} evaluations");
        assert!(fx <= 0.25 + 0.25 + 0.5);
        // With only the initial simplex allowed, its best vertex comes back.
        let g = |x: [f64; 3]| x[0] + x[1] + x[2];
        let (x, gx) = nelder_mead(g, [0.0; 3], [-1.0, 0.0, 0.0], 4);
        assert_eq!((x, gx), ([-1.0, 0.0, 0.0], -1.0));
    }

    #[test]
    fn giving_up_ends_a_hopeless_minimization_and_changes_no_other() {
        fn counted(calls: &mut usize) -> impl FnMut([f64; 3]) -> f64 + '_ {
            move |x| {
                *calls += 1;
                1.0 + x[0].powi(2) + 2.0 * (x[1] - 0.5).powi(2) + x[2].powi(2)
            }
        }
        let (mut full_calls, mut kept_calls, mut gave_up_calls) = (0, 0, 0);
        let full = nelder_mead(counted(&mut full_calls), [0.3; 3], [0.1; 3], 200);
        // A bound the minimization meets in time: the same steps, the same
        // result.
        let met = GiveUp {
            after: 20,
            above: 10.0,
        };
        let kept = nelder_mead_unless(counted(&mut kept_calls), [0.3; 3], [0.1; 3], 200, Some(met));
        assert_eq!(full, kept);
        assert_eq!(full_calls, kept_calls);
        // A bound below the minimum: it ends soon after 20 evaluations.
        let missed = GiveUp {
            after: 20,
            above: 0.5,
        };
        let (_, fx) = nelder_mead_unless(
            counted(&mut gave_up_calls),
            [0.3; 3],
            [0.1; 3],
            200,
            Some(missed),
        );
        assert!(fx > 1.0);
        assert!((20..=26).contains(&gave_up_calls), "{gave_up_calls}");
        assert!(full_calls > 40, "{full_calls}");
    }

    #[test]
    fn a_flat_function_stops_at_once() {
        let mut calls = 0;
        let f = |_: [f64; 3]| {
            calls += 1;
            2.0
        };
        let (_, fx) = nelder_mead(f, [0.0; 3], [1.0; 3], 1000);
        assert_eq!(fx, 2.0);
        assert!(calls < 10, "{calls} evaluations");
    }
}
