//! Order statistics over plain numbers, shared by the cleaning of point
//! clouds and the calibration of confidence.

/// The median of the finite `values`: the upper one of the two middle
/// values for an even count (so it is always one of the values); `None`
/// without finite values.
pub fn upper_median(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upper_median_takes_the_upper_middle_of_the_finite_values() {
        assert_eq!(upper_median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(upper_median(&[4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(
            upper_median(&[5.0, f64::NAN, 1.0, f64::INFINITY]),
            Some(5.0)
        );
        assert_eq!(upper_median(&[f64::NAN]), None);
        assert_eq!(upper_median(&[]), None);
    }
}
