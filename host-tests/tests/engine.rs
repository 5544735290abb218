//! The run-time engine: fixed vs f32 vs f64, fractional delays, exact final position,
//! no drift over 10⁶ moves, no lost steps, parameter changes without a setpoint jump.

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::{Engine, NumericPath, TapError, TapTable};
use beamshaper::output::StepOutput;
use beamshaper::reference::TrapezoidMove;
use beamshaper::runtime::{RunParams, Runtime, TickInput, HISTORY_LEN};
use beamshaper::shaper::{design, Impulse, Shaper, ShaperKind};
use beamshaper_host_tests::shaped_f64;
use proptest::prelude::*;

fn engine(shaper: &Shaper, rate: f64, path: NumericPath, x0: i32) -> Box<Engine<HISTORY_LEN>> {
    let taps = TapTable::from_shaper(shaper, rate, HISTORY_LEN).unwrap();
    let mut e = Box::new(Engine::new(x0));
    e.install(taps, path, x0);
    e
}

/// A trapezoidal move in nm sampled at `rate`, then held for `hold` ticks.
fn move_samples(
    start: i32,
    target: i32,
    speed: f32,
    accel: f32,
    rate: f32,
    hold: usize,
) -> Vec<i32> {
    let mut m = TrapezoidMove::new(start, target, speed, accel, rate).unwrap();
    let mut v = vec![start];
    while !m.done() {
        v.push(m.next());
    }
    v.extend(std::iter::repeat(target).take(hold));
    v
}

fn all_shapers(f: f64, z: f64) -> Vec<Shaper> {
    let mut v: Vec<Shaper> = ShaperKind::all(0.05)
        .iter()
        .map(|&k| design(k, f, z).unwrap())
        .collect();
    let two = design(ShaperKind::Zvdd, 1.1, 0.0074)
        .unwrap()
        .convolve(&design(ShaperKind::Zvdd, 6.9, 0.0074).unwrap())
        .unwrap();
    v.push(two);
    v
}

/// Bounds stated in `beamshaper::engine` docs, checked on the paper's 0 → 50 mm move.
#[test]
fn fixed_and_f32_paths_stay_within_the_stated_bounds_of_f64() {
    let rate = 1000.0;
    let x = move_samples(0, 50_000_000, 2.0e8, 2.0e9, rate as f32, 3000);
    let span = 50_000_000f64;
    for s in all_shapers(1.1, 0.0074) {
        let exact = shaped_f64(&s, rate, &x);
        let taps = TapTable::from_shaper(&s, rate, HISTORY_LEN).unwrap();
        let n_taps = taps.taps().len() as f64;
        let abs_w: f64 = taps.taps().iter().map(|t| (t.w_f32 as f64).abs()).sum();
        let fixed_bound = 0.5 + (n_taps + 1.0) * 2f64.powi(-31) * span + 1e-9;
        let f32_bound = 0.5 + (n_taps + 2.0) * 2f64.powi(-24) * abs_w * span;
        let mut ef = engine(&s, rate, NumericPath::Fixed, 0);
        let mut e32 = engine(&s, rate, NumericPath::F32, 0);
        let (mut worst_fixed, mut worst_f32) = (0.0f64, 0.0f64);
        for (k, &xk) in x.iter().enumerate() {
            let yf = ef.tick(xk) as f64;
            let y32 = e32.tick(xk) as f64;
            worst_fixed = worst_fixed.max((yf - exact[k]).abs());
            worst_f32 = worst_f32.max((y32 - exact[k]).abs());
        }
        assert!(
            worst_fixed <= fixed_bound,
            "{} taps: fixed error {worst_fixed} > {fixed_bound}",
            n_taps
        );
        assert!(
            worst_f32 <= f32_bound,
            "{} taps: f32 error {worst_f32} > {f32_bound}",
            n_taps
        );
        println!("{} taps: worst |fixed − f64| = {worst_fixed:.4} (bound {fixed_bound:.3}), worst |f32 − f64| = {worst_f32:.4} (bound {f32_bound:.3}) counts", n_taps);
    }
}

#[test]
fn sub_tick_impulse_times_are_interpolated_not_rounded() {
    // An impulse at 2.3 ticks on a ramp: the output must be the ramp delayed by exactly
    // 2.3 ticks (linear interpolation is exact on a ramp), not by 2 ticks.
    let rate = 1000.0;
    let s = Shaper::from_impulses(&[
        Impulse {
            amplitude: 0.5,
            time_s: 0.0,
        },
        Impulse {
            amplitude: 0.5,
            time_s: 2.3e-3,
        },
    ])
    .unwrap();
    let taps = TapTable::from_shaper(&s, rate, HISTORY_LEN).unwrap();
    assert_eq!(taps.taps().len(), 3);
    assert_eq!(taps.taps()[1].delay, 2);
    assert_eq!(taps.taps()[2].delay, 3);
    let mut e = engine(&s, rate, NumericPath::Fixed, 0);
    let slope = 1000; // counts per tick
    let mut last = 0;
    for n in 0..100i32 {
        last = e.tick(n * slope);
    }
    // y = 0.5·x[n] + 0.5·x(n − 2.3) = x[n] − 0.5·2.3·slope
    assert_eq!(last, 99 * slope - 1150);
    let mut e32 = engine(&s, rate, NumericPath::F32, 0);
    for n in 0..100i32 {
        last = e32.tick(n * slope);
    }
    assert_eq!(last, 99 * slope - 1150);
}

#[test]
fn exact_final_position_for_every_shaper_and_both_paths() {
    for rate in [500.0, 1000.0, 3333.0, 10_000.0] {
        for s in all_shapers(3.7, 0.03) {
            let hold = (s.duration_s() * rate) as usize + 3;
            for (start, target) in [
                (0, 50_000_000),
                (123_457, -987_653),
                (-1_000_000_000, 1_000_000_000),
            ] {
                let x = move_samples(start, target, 3.0e8, 5.0e9, rate as f32, hold);
                for path in [NumericPath::Fixed, NumericPath::F32] {
                    let mut e = engine(&s, rate, path, start);
                    let y: Vec<i32> = x.iter().map(|&v| e.tick(v)).collect();
                    assert_eq!(
                        *y.last().unwrap(),
                        target,
                        "rate {rate} path {path:?} shaper {:?}",
                        s.impulses()
                    );
                    assert_eq!(y[0], start);
                }
            }
        }
    }
}

#[test]
fn no_drift_over_a_million_moves() {
    // 10⁶ step moves to random targets, each held for the shaper's duration: the fixed-point
    // setpoint equals the target to the count after every one (FIR + exact unity DC gain).
    let s = design(ShaperKind::Zvd, 200.0, 0.05)
        .unwrap()
        .convolve(&design(ShaperKind::UmZv, 310.0, 0.02).unwrap())
        .unwrap();
    let rate = 10_000.0;
    let mut e = engine(&s, rate, NumericPath::Fixed, 0);
    let hold = e.taps().duration_ticks() as usize + 1;
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..1_000_000 {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let target = (rng % (1 << 31)) as i32 - (1 << 30);
        let mut y = 0;
        for _ in 0..hold {
            y = e.tick(target);
        }
        assert_eq!(y, target);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random shapers, step sizes and moves through the whole runtime: after every tick the
    /// emitted step count equals ⌊setpoint / step⌋ and the signed pulses add up to it.
    #[test]
    fn no_step_is_ever_lost(
        f in 0.5f64..40.0, z in 0.0f64..0.2, kind in 0usize..9,
        step_nm in 10u32..5000, targets in proptest::collection::vec(-200_000_000i32..200_000_000, 1..4),
        path_f32 in any::<bool>(),
    ) {
        let mut settings = Settings::DEFAULT;
        settings.modes[0] = Some(ModeSetting { kind: ShaperKind::all(0.05)[kind], freq_hz: f, zeta: z });
        settings.step_nm = step_nm;
        settings.max_step_rate_hz = 50_000_000;
        settings.path = if path_f32 { NumericPath::F32 } else { NumericPath::Fixed };
        let params = RunParams::from_settings(&settings).unwrap();
        let mut rt = Box::new(Runtime::new());
        rt.configure_at_boot(params, 0);
        let mut signed: i64 = rt.step_output().emitted();
        for &t in &targets {
            rt.start_move(t, 1.0e8, 4.0e9).unwrap();
            for _ in 0..20_000 {
                let out = rt.tick(&TickInput::default());
                signed += if out.step.forward { out.step.pulses as i64 } else { -(out.step.pulses as i64) };
                let want = (out.setpoint_counts as i64).div_euclid(step_nm as i64);
                prop_assert_eq!(rt.step_output().emitted(), want);
                prop_assert_eq!(signed, want);
                if !rt.status().moving && rt.status().still_ticks > rt.status().duration_ticks { break; }
            }
            prop_assert_eq!(rt.status().setpoint_counts, t);
        }
    }
}

#[test]
fn step_output_accounting_across_negative_positions() {
    let mut s = StepOutput::new(1000, 10, -1);
    assert_eq!(s.emitted(), -1);
    let c = s.update(-1000);
    assert_eq!((c.pulses, c.forward), (0, true));
    let c = s.update(-1001);
    assert_eq!((c.pulses, c.forward, s.emitted()), (1, false, -2));
    let c = s.update(25_000);
    assert_eq!((c.pulses, s.emitted(), s.rate_faults()), (27, 25, 1));
}

/// Changing the shaper together with the tick rate and numeric path during a move: such a
/// change waits until the reference has been still for the old shaper's duration (a change of
/// the shaper alone applies at the next tick: `tests/switch.rs`), the setpoint never jumps,
/// and the final position is exact.
#[test]
fn shaper_change_while_moving_never_jumps() {
    let mut a = Settings::DEFAULT;
    a.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 1.1,
        zeta: 0.0074,
    });
    let mut b = a.clone();
    b.modes[1] = Some(ModeSetting {
        kind: ShaperKind::Ei { v_tol: 0.05 },
        freq_hz: 6.9,
        zeta: 0.0074,
    });
    b.path = NumericPath::F32;
    b.tick_rate_hz = 2000;
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(RunParams::from_settings(&a).unwrap(), 0);
    let speed = 2.0e8f32;
    rt.start_move(50_000_000, speed, 2.0e9).unwrap();
    let mut prev = 0i32;
    let mut max_step = 0i64;
    let mut applied_at = None;
    let old_duration = rt.status().duration_ticks as u64;
    for k in 0..10_000u64 {
        if k == 100 {
            rt.request(RunParams::from_settings(&b).unwrap()).unwrap();
        }
        let out = rt.tick(&TickInput::default());
        max_step = max_step.max((out.setpoint_counts as i64 - prev as i64).abs());
        prev = out.setpoint_counts;
        if applied_at.is_none() && rt.pending().is_none() && k >= 100 {
            applied_at = Some(k);
            assert_eq!(rt.tick_rate_hz(), 2000);
        }
    }
    let applied_at = applied_at.expect("pending change applied");
    // Move lasts 0.25 s + 0.1 s = 350 ticks; then still for the old duration.
    assert!(
        applied_at >= 350 + old_duration - 2,
        "applied at {applied_at}"
    );
    // Largest per-tick change is the shaped velocity, never a jump.
    assert!(
        max_step as f32 <= speed / 1000.0 + 2.0,
        "max per-tick change {max_step}"
    );
    assert_eq!(prev, 50_000_000);
}

#[test]
fn a_shaper_longer_than_the_buffer_is_refused() {
    let s = design(ShaperKind::Zvdd, 0.2, 0.0074).unwrap(); // 7.5 s
    assert!(TapTable::from_shaper(&s, 1000.0, HISTORY_LEN).is_ok());
    match TapTable::from_shaper(&s, 10_000.0, HISTORY_LEN) {
        Err(TapError::TooLong { duration_s, max_s }) => {
            assert!((duration_s - 7.5).abs() < 0.01 && (max_s - 1.6382).abs() < 1e-3);
        }
        other => panic!("expected TooLong, got {other:?}"),
    }
}

#[test]
fn q30_weights_sum_exactly_to_one() {
    for rate in [500.0, 977.0, 1000.0, 7919.0] {
        for s in all_shapers(2.3, 0.04) {
            let t = TapTable::from_shaper(&s, rate, HISTORY_LEN).unwrap();
            assert_eq!(
                t.taps().iter().map(|t| t.w_q30 as i64).sum::<i64>(),
                1 << 30
            );
        }
    }
}

/// Pass-through of the upstream step/direction stream: the 16-bit encoder count wraps, the
/// reference follows it in nm, is shaped, and ends exactly at the upstream position.
#[test]
fn stepdir_pass_through_unwraps_the_16_bit_counter_and_shapes_it() {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvd,
        freq_hz: 5.0,
        zeta: 0.02,
    });
    s.source = beamshaper::config::Source::StepDir;
    s.input_nm_per_count = 1000;
    s.max_step_rate_hz = 10_000_000;
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(RunParams::from_settings(&s).unwrap(), 65_000);
    // Upstream controller: 150 000 steps forward at 300 steps/tick, wrapping the counter twice.
    let mut raw: u16 = 65_000;
    let mut upstream: i64 = 0;
    let mut signed_pulses: i64 = rt.step_output().emitted();
    for k in 0..2000 {
        if k < 500 {
            raw = raw.wrapping_add(300);
            upstream += 300;
        }
        let out = rt.tick(&TickInput { stepdir_count: raw });
        assert_eq!(out.reference_counts as i64, upstream * 1000);
        signed_pulses += if out.step.forward {
            out.step.pulses as i64
        } else {
            -(out.step.pulses as i64)
        };
        assert_eq!(signed_pulses, (out.setpoint_counts as i64).div_euclid(1000));
    }
    assert_eq!(rt.status().setpoint_counts, 150_000_000);
    assert_eq!(rt.step_output().emitted(), 150_000);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    /// The engine's cheap rounding equals `roundf` (halves away from zero) in the i32 range.
    #[test]
    fn round_f32_matches_roundf(x in -2.1e9f32..2.1e9, frac in prop::sample::select(vec![0.0f32, 0.5, -0.5, 0.49999997, 0.50000006, 0.25])) {
        for v in [x, x.trunc() + frac, frac, -frac] {
            prop_assert_eq!(beamshaper::engine::round_f32(v), v.round() as i32, "{}", v);
        }
    }
}
