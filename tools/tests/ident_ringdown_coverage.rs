//! The pooled ring-down path's 1-σ is honest on synthetic closed-loop recordings
//! (`ident::ringdown_sim`, `beamtool ringdown-coverage`): over 12 drawn designs (truth, gains,
//! amplitude, period, quantisation steps and grid offsets drawn from seeds 1..=12, the CLI's
//! default seed), the sum of the squared z-scores (f̂ − f)/σ_f and (ζ̂ − ζ)/σ_ζ must lie inside the
//! two-sided 99.8 % interval of χ² with 24 degrees of freedom (what 24 standard normal z-scores
//! give; the f and ζ of one run are not independent, so this is approximate). The jackknife
//! over segments alone (the σ before the bootstrap) must fall outside it: the check has power.

use beamtools::ident::ringdown_sim::{ringdown_coverage, CoverageSpec, LinkDesign};
use beamtools::ident::ringdowns::RingdownOptions;
use statrs::distribution::{ChiSquared, ContinuousCDF};

#[test]
fn ringdown_sigma_covers_the_truth() {
    let spec = CoverageSpec {
        base: LinkDesign::default(),
        vary: true,
        rest_mid_step: false,
        opts: RingdownOptions::default(),
    };
    let runs = 12;
    let c = ringdown_coverage(&spec, runs, 1, &mut |_, _| {});
    assert_eq!(c.failed, 0, "{c:?}");
    let dof = 2.0 * runs as f64;
    let chi = ChiSquared::new(dof).unwrap();
    let (lo, hi) = (chi.inverse_cdf(0.001), chi.inverse_cdf(0.999));
    let sum_z2 = |sig: &dyn Fn(&beamtools::ident::ringdown_sim::CoverageRun) -> (f64, f64)| {
        c.per_run
            .iter()
            .map(|p| {
                let s = sig(p);
                ((p.estimate.0 - p.truth.0) / s.0).powi(2)
                    + ((p.estimate.1 - p.truth.1) / s.1).powi(2)
            })
            .sum::<f64>()
    };
    let reported = sum_z2(&|p| p.sigma);
    let jack = sum_z2(&|p| p.jackknife);
    eprintln!(
        "sum z² over {runs} runs (f and ζ): reported σ {reported:.1}, jackknife alone {jack:.1}; \
         χ²({dof}) 99.8 % interval [{lo:.1}, {hi:.1}]; coverage f {}/{runs}, ζ {}/{runs}",
        c.reported.covered.0, c.reported.covered.1
    );
    assert!(
        reported >= lo && reported <= hi,
        "reported σ: Σz² {reported} outside [{lo}, {hi}]"
    );
    assert!(
        jack > hi,
        "the jackknife alone passes too (Σz² {jack}): the check has no power"
    );
}
