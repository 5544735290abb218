//! Which of a spectrum's local maxima are distinct resonances: a peak counts only when, between
//! it and every higher peak already kept, the spectrum dips below a fraction of the lower of
//! the two (for half power, 0.5: the half-power bands of the two do not merge). Shared by the
//! spectrum path of identification ([`crate::ident::klipper_raw`]) and the spectrum design
//! ([`crate::shaping::spectrum`]).

/// The candidates `cand` (indices into the power spectrum `p`) that are distinct peaks, highest
/// first, at most `max_n`: a candidate is kept when the minimum of `p` between it and each
/// peak kept before it is below `dip_fraction` × the smaller of the two.
pub fn distinct_peaks(
    p: &[f64],
    mut cand: Vec<usize>,
    dip_fraction: f64,
    max_n: usize,
) -> Vec<usize> {
    cand.sort_by(|&a, &b| p[b].total_cmp(&p[a]));
    let mut kept: Vec<usize> = vec![];
    for i in cand {
        if kept.len() == max_n {
            break;
        }
        let distinct = kept.iter().all(|&j| {
            let (a, b) = (i.min(j), i.max(j));
            let dip = p[a..=b].iter().cloned().fold(f64::INFINITY, f64::min);
            dip < dip_fraction * p[i].min(p[j])
        });
        if distinct {
            kept.push(i);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shoulder_is_not_a_second_peak_and_a_separate_one_is() {
        // peaks at 2 (10), 4 (6, dip 5 between: above half of 6), 8 (4, dip 1 between)
        let p = [0.0, 3.0, 10.0, 5.0, 6.0, 3.0, 1.0, 2.0, 4.0, 1.0];
        assert_eq!(distinct_peaks(&p, vec![2, 4, 8], 0.5, 4), vec![2, 8]);
        assert_eq!(distinct_peaks(&p, vec![8, 4, 2], 0.5, 1), vec![2]);
    }
}
