//! Reference generators and the step-rate rule: the public rule is the one the runtime
//! applies; sine sweeps (paper eqs. 33–34) start and end at rest, follow their frequency law
//! and respect their speed bound; `stop` ends moves and sweeps within their limits.

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::output::{check_move_step_rate, check_step_rate};
use beamshaper::reference::{SineSweep, SweepError, SweepKind, TrapezoidMove};
use beamshaper::runtime::{RunParams, Runtime, RuntimeError, TickInput, HISTORY_LEN};
use beamshaper::shaper::ShaperKind;
use beamshaper_host_tests::Board;
use proptest::prelude::*;

fn settings(maxrate: u32, step_nm: u32) -> Settings {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Ei { v_tol: 0.05 },
        freq_hz: 1.1,
        zeta: 0.0074,
    });
    s.modes[1] = Some(ModeSetting {
        kind: ShaperKind::UmZv,
        freq_hz: 6.9,
        zeta: 0.0074,
    });
    s.max_step_rate_hz = maxrate;
    s.step_nm = step_nm;
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// `check_move_step_rate` answers exactly what `start_move` answers (one rule).
    #[test]
    fn the_public_rule_is_the_runtime_rule(
        target_mm in -900.0f64..900.0,
        speed in 1.0f64..3000.0,
        accel in 10.0f64..50_000.0,
        maxrate in 1_000u32..500_000,
        step_nm in 1u32..5000,
    ) {
        let s = settings(maxrate, step_nm);
        let p = RunParams::from_settings(&s).unwrap();
        let taps = s.tap_table(HISTORY_LEN).unwrap();
        let mut rt = Box::new(Runtime::new());
        rt.configure_at_boot(p, 0);
        let target = (target_mm * 1e6).round() as i32;
        let (v, a) = ((speed * 1e6) as f32, (accel * 1e6) as f32);
        let rule = check_move_step_rate(&taps, step_nm, maxrate, target.unsigned_abs(), v, a);
        match (rt.start_move(target, v, a), rule) {
            (Ok(_), Ok(())) => {}
            (Err(RuntimeError::StepRate(e)), Err(r)) => prop_assert_eq!(e, r),
            (got, r) => prop_assert!(false, "runtime {got:?} vs rule {r:?}"),
        }
    }
}

#[test]
fn the_rule_names_the_limit_and_a_move_at_that_limit_passes() {
    let s = settings(100_000, 1000);
    let taps = s.tap_table(HISTORY_LEN).unwrap();
    let gain = taps.abs_weight_sum();
    assert!(gain > 1.0, "UM-ZV has negative impulses: {gain}");
    let e = check_move_step_rate(&taps, 1000, 100_000, 500_000_000, 2.0e8, 1.0e9).unwrap_err();
    assert_eq!(e.max_step_rate_hz, 100_000);
    assert!((e.shaped_peak_steps_s - 2.0e8 * gain / 1000.0).abs() < 1.0);
    let v_ok = e.max_reference_speed_nm_s * 0.999;
    assert!(check_move_step_rate(&taps, 1000, 100_000, 500_000_000, v_ok, 1.0e9).is_ok());
    // A short move never reaches its speed limit: the triangular peak counts.
    assert!(check_move_step_rate(&taps, 1000, 100_000, 1_000, 2.0e8, 1.0e9).is_ok());
    assert!(check_step_rate(&taps, 1000, 100_000, 2.0e8).is_err());
}

/// Samples of a sweep until it is done, starting with x₀.
fn sweep_samples(sw: &mut SineSweep, x0: i32) -> Vec<i32> {
    let mut v = vec![x0];
    while !sw.done() {
        v.push(sw.next());
    }
    v
}

#[test]
fn sweeps_start_and_end_at_rest_and_follow_eqs_33_and_34() {
    let rate = 1000.0;
    for kind in [SweepKind::Linear, SweepKind::Exponential] {
        let (f0, f1, amp, t) = (0.5, 8.0, 5.0e6, 20.0);
        let mut sw = SineSweep::new(kind, 1_000_000, f0, f1, amp, t, rate).unwrap();
        let bound = sw.peak_speed() as f64;
        let x = sweep_samples(&mut sw, 1_000_000);
        assert_eq!(x.len(), 20_001);
        assert_eq!(*x.last().unwrap(), 1_000_000, "ends at x0 exactly");
        // Starts at rest: the first ticks move by (rounding) nothing; speed within the bound.
        assert!((x[1] - x[0]).abs() <= 1, "{kind:?}: {} {}", x[0], x[1]);
        let peak = x
            .windows(2)
            .map(|w| (w[1] - w[0]).abs() as f64 * rate)
            .fold(0.0, f64::max);
        assert!(peak <= bound + rate, "{kind:?}: {peak} > {bound}");
        let max = x.iter().map(|v| (v - 1_000_000).abs()).max().unwrap();
        assert!(max as f64 <= amp + 1.0 && max as f64 > 0.99 * amp, "{max}");
        // Instantaneous frequency from the time between upward zero crossings in the middle
        // (full amplitude) against eq. 33 / eq. 34.
        let up: Vec<usize> = (1..x.len())
            .filter(|&k| x[k - 1] < 1_000_000 && x[k] >= 1_000_000)
            .collect();
        for w in up.windows(2) {
            let tm = (w[0] + w[1]) as f64 / 2.0 / rate;
            if !(0.2 * t..0.8 * t).contains(&tm) {
                continue;
            }
            let f_meas = rate / (w[1] - w[0]) as f64;
            let f_law = match kind {
                SweepKind::Linear => f0 + (f1 - f0) * tm / t,
                SweepKind::Exponential => f0 * (f1 / f0).powf(tm / t),
            };
            assert!(
                (f_meas - f_law).abs() <= 0.02 * f_law + f_law * f_law / rate,
                "{kind:?} t={tm}: {f_meas} vs {f_law}"
            );
        }
    }
}

#[test]
fn sweep_refusals_are_checked_before_it_starts() {
    let s = |f0, f1, a, t| SineSweep::new(SweepKind::Exponential, 0, f0, f1, a, t, 1000.0);
    assert_eq!(s(0.0, 8.0, 1e6, 10.0).unwrap_err(), SweepError::Profile);
    assert_eq!(s(1.0, 8.0, 1e6, f64::NAN).unwrap_err(), SweepError::Profile);
    assert_eq!(s(1.0, 101.0, 1e6, 10.0).unwrap_err(), SweepError::Nyquist);
    assert_eq!(s(1.0, 8.0, 1.1e9, 10.0).unwrap_err(), SweepError::Stroke);

    let mut b = Board::new();
    b.err("sweep lin 1 8 2000 10", "range");
    b.err("sweep log 1 8 2 10", "syntax");
    b.err("sweep lin 1 8 2", "syntax");
    b.err("sweep exp 1 400 2 10", "range");
    b.ok("move 999");
    b.run(12_000);
    b.err("sweep lin 1 8 2 10", "range"); // 999 + 2 mm leaves the stroke
    b.ok("move 0");
    b.run(12_000);
    b.ok("maxrate 20000");
    b.run(10);
    // 10 mm at 8 Hz: ~0.5 m/s peak = 500 000 steps/s > 20 000.
    let (out, _) = b.cmd("sweep exp 0.5 8 10 20");
    assert!(
        out.contains("err step-rate:") && out.contains("# shaped peak"),
        "{out}"
    );
    b.ok("sweep exp 0.5 8 0.2 20");
}

#[test]
fn stop_ends_a_sweep_at_its_start_and_a_move_within_its_acceleration() {
    let mut b = Board::new();
    b.ok("move 10");
    b.run(2000);
    b.ok("sweep lin 1 5 3 30");
    b.run(10_000);
    assert!(b.rt.status().moving);
    let out = b.ok("stop");
    let n: u32 = out.trim().rsplit('=').next().unwrap().parse().unwrap();
    assert!(n > 0 && n <= 3000, "{out}");
    b.run(n as usize);
    assert!(!b.rt.status().moving);
    assert_eq!(b.rt.status().reference_counts, 10_000_000);

    // A 100 mm move at 100 mm/s, 1000 mm/s^2, stopped at full speed after 0.5 s (45 mm):
    // rest 5 mm later.
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(RunParams::from_settings(&Settings::DEFAULT).unwrap(), 0);
    rt.start_move(100_000_000, 1.0e8, 1.0e9).unwrap();
    let mut x = vec![0i64];
    for _ in 0..500 {
        x.push(rt.tick(&TickInput::default()).reference_counts as i64);
    }
    let n = rt.stop();
    assert_eq!(n, 100);
    for _ in 0..(n + 50) {
        x.push(rt.tick(&TickInput::default()).reference_counts as i64);
    }
    let end = *x.last().unwrap();
    assert!((end - 50_000_000).abs() <= 1, "{end}");
    assert!(!rt.status().moving);
    let dt2 = 1e-6; // (1 ms)^2
    for w in x.windows(3) {
        let a = (w[2] - 2 * w[1] + w[0]) as f64 / dt2;
        // f32 positions near 5e7 nm carry up to ±2 nm of rounding (ulp 4): ±8 nm in a
        // second difference.
        assert!(a.abs() <= 1.0e9 + 8.0 / dt2, "accel {a}");
    }
    assert_eq!(rt.stop(), 0, "nothing to stop");
    // The move's own profile is the trapezoid it would have been up to the stop.
    let mut m = TrapezoidMove::new(0, 100_000_000, 1.0e8, 1.0e9, 1000.0).unwrap();
    for k in 1..=500 {
        assert_eq!(m.next() as i64, x[k]);
    }
}
