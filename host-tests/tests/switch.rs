//! Mid-move shaper changes by superposition (`beamshaper::engine`): continuity, exact final
//! position, the superposition identity against f64, random back-to-back switches (proptest),
//! residual vibration on a beam model, the step/direction pass-through, the tap budget.

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::{Engine, NumericPath, SwitchError, TapTable, TAP_BUDGET};
use beamshaper::reference::TrapezoidMove;
use beamshaper::runtime::{Applies, RunParams, Runtime, RuntimeError, TickInput, HISTORY_LEN};
use beamshaper::shaper::{design, Shaper, ShaperKind};
use beamshaper_host_tests::{shaped_f64, Board};
use proptest::prelude::*;

const RATE: f64 = 1000.0;

fn two_mode(kind: ShaperKind, f1: f64, f2: f64) -> Shaper {
    design(kind, f1, 0.0074)
        .unwrap()
        .convolve(&design(kind, f2, 0.0074).unwrap())
        .unwrap()
}

fn table(s: &Shaper) -> TapTable {
    TapTable::from_shaper(s, RATE, HISTORY_LEN).unwrap()
}

/// Trapezoid samples (nm) from `start` to `target`, then held for `hold` ticks.
fn trapezoid(start: i32, target: i32, speed: f32, accel: f32, hold: usize) -> Vec<i32> {
    let mut m = TrapezoidMove::new(start, target, speed, accel, RATE as f32).unwrap();
    let mut v = vec![start];
    while !m.done() {
        v.push(m.next());
    }
    v.extend(std::iter::repeat(target).take(hold));
    v
}

/// Runs `x` through an engine starting with `shapers[0]`, switching to `shapers[k]` before
/// the sample `at[k − 1]` is pushed. Returns the outputs and the switches that were accepted.
fn run_switched(
    shapers: &[Shaper],
    at: &[usize],
    x: &[i32],
    path: NumericPath,
) -> (Vec<i32>, Vec<(usize, usize)>) {
    let mut e: Box<Engine<HISTORY_LEN>> = Box::new(Engine::new(x[0]));
    e.install(table(&shapers[0]), path, x[0]);
    let mut accepted = vec![];
    let mut y = Vec::with_capacity(x.len());
    for (n, &xn) in x.iter().enumerate() {
        for (k, &t) in at.iter().enumerate() {
            if t == n && e.switch(table(&shapers[k + 1])).is_ok() {
                accepted.push((n, k + 1));
            }
        }
        y.push(e.tick(xn));
    }
    (y, accepted)
}

/// The superposition in f64, independently of the engine: stage k shapes the increment of x
/// between its switch points, `seg_k(n) = x(clamp(n, s_k, s_{k+1})) − x(s_k)` with s_k the
/// last sample before the switch (seg_0 = x(min(n, s_1))).
fn superposed_f64(shapers: &[Shaper], switches: &[(usize, usize)], x: &[i32]) -> Vec<f64> {
    let mut bounds: Vec<(usize, usize)> = vec![(0, 0)];
    bounds.extend(switches.iter().copied());
    let mut y = vec![0.0; x.len()];
    for (k, &(start, which)) in bounds.iter().enumerate() {
        let lo = if k == 0 { 0 } else { start - 1 };
        let hi = bounds.get(k + 1).map(|&(n, _)| n - 1).unwrap_or(usize::MAX);
        let base = if k == 0 { 0 } else { x[lo] };
        let seg: Vec<i32> = (0..x.len())
            .map(|n| x[n.clamp(lo, hi.min(x.len() - 1))] - base)
            .collect();
        for (yn, s) in y.iter_mut().zip(shaped_f64(&shapers[which], RATE, &seg)) {
            *yn += s;
        }
    }
    y
}

fn max_tick_change(y: &[i32]) -> i64 {
    y.windows(2)
        .map(|w| (w[1] as i64 - w[0] as i64).abs())
        .max()
        .unwrap()
}

/// Σ|w| bound of the transition (EngineState::transition_gain) from a steady `old`.
fn transition_gain(old: &Shaper, new: &Shaper) -> f64 {
    let mut e: Box<Engine<HISTORY_LEN>> = Box::new(Engine::new(0));
    e.install(table(old), NumericPath::Fixed, 0);
    e.state().transition_gain(&table(new)) as f64
}

#[test]
fn a_switch_mid_move_is_continuous_and_ends_exactly_at_the_target() {
    let old = two_mode(ShaperKind::Zvd, 1.0, 6.5);
    let new = two_mode(ShaperKind::Zvdd, 1.1, 6.9);
    let x = trapezoid(0, 50_000_000, 2.0e8, 2.0e9, 3000);
    let dx = max_tick_change(&x) as f64;
    for path in [NumericPath::Fixed, NumericPath::F32] {
        let (plain_old, _) = run_switched(&[old.clone()], &[], &x, path);
        let (plain_new, _) = run_switched(&[new.clone()], &[], &x, path);
        let unswitched = max_tick_change(&plain_old).max(max_tick_change(&plain_new));
        for at in [1usize, 60, 150, 200, 260, 500] {
            let (y, acc) = run_switched(&[old.clone(), new.clone()], &[at], &x, path);
            assert_eq!(acc, vec![(at, 1)]);
            // Continuity: no jump at or after the switch. The per-tick change is bounded by
            // the transition's gain times the reference's (a few counts of rounding); for
            // these two positive shapers that is within the unswitched runs' largest change
            // plus what the overlap of the two windows adds.
            let got = max_tick_change(&y);
            let bound = transition_gain(&old, &new) * dx + 2.0;
            assert!(got as f64 <= bound, "{path:?} at {at}: {got} > {bound}");
            assert!(
                (got as f64) < 1.6 * unswitched as f64,
                "{path:?} at {at}: {got} vs unswitched {unswitched}"
            );
            let around = (at.saturating_sub(3)..(at + 3).min(y.len() - 1))
                .map(|n| (y[n + 1] as i64 - y[n] as i64).abs())
                .max()
                .unwrap();
            assert!(
                around <= unswitched,
                "{path:?}: step {around} at the switch"
            );
            assert_eq!(*y.last().unwrap(), 50_000_000, "{path:?} at {at}");
        }
    }
}

#[test]
fn the_switched_output_is_the_superposition_of_the_two_shaped_parts() {
    let old = two_mode(ShaperKind::Ei { v_tol: 0.05 }, 1.1, 6.9);
    let new = design(ShaperKind::UmZv, 2.3, 0.02).unwrap();
    let x = trapezoid(-3_000_000, 47_000_000, 1.5e8, 1.0e9, 2500);
    for at in [5usize, 177, 333] {
        let (yf, acc) = run_switched(&[old.clone(), new.clone()], &[at], &x, NumericPath::Fixed);
        let (y32, _) = run_switched(&[old.clone(), new.clone()], &[at], &x, NumericPath::F32);
        let exact = superposed_f64(&[old.clone(), new.clone()], &acc, &x);
        let span = 50_000_000f64;
        let n_taps = (table(&old).len() + table(&new).len()) as f64;
        let abs_w = transition_gain(&old, &new).max(3.0);
        let fixed_bound = 0.5 + (n_taps + 2.0) * 2f64.powi(-31) * span;
        let f32_bound = 0.5 + (n_taps + 2.0) * 2f64.powi(-24) * abs_w * span;
        for n in 0..x.len() {
            assert!(
                (yf[n] as f64 - exact[n]).abs() <= fixed_bound,
                "fixed n={n}: {} vs {}",
                yf[n],
                exact[n]
            );
            assert!(
                (y32[n] as f64 - exact[n]).abs() <= f32_bound,
                "f32 n={n}: {} vs {}",
                y32[n],
                exact[n]
            );
        }
    }
}

fn shaper_strategy() -> impl Strategy<Value = Shaper> {
    (0usize..9, 0.8f64..12.0, 0.0f64..0.1, any::<bool>()).prop_map(|(k, f, z, two)| {
        let s = design(ShaperKind::all(0.05)[k], f, z).unwrap();
        if two {
            s.convolve(&design(ShaperKind::Zvd, f * 3.7, z).unwrap())
                .unwrap()
        } else {
            s
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Random tables, moves and switch times, including back-to-back switches during a
    /// transition: the engine equals the f64 superposition of every accepted switch, refuses
    /// only over the budget or stage limit, and ends exactly at the target.
    #[test]
    fn random_back_to_back_switches_match_the_f64_superposition(
        shapers in proptest::collection::vec(shaper_strategy(), 2..6),
        gaps in proptest::collection::vec(1usize..400, 5),
        first in 0usize..600,
        target in -80_000_000i32..80_000_000,
        f32_path in any::<bool>(),
    ) {
        let path = if f32_path { NumericPath::F32 } else { NumericPath::Fixed };
        let x = trapezoid(1_000_000, target, 1.2e8, 1.5e9, 4000);
        let mut at = vec![first.max(1)];
        for g in gaps.iter().take(shapers.len() - 2) {
            let next = at.last().unwrap() + g;
            at.push(next);
        }
        let (y, acc) = run_switched(&shapers, &at, &x, path);
        prop_assert!(!acc.is_empty(), "the first switch from a steady state always fits");
        let exact = superposed_f64(&shapers, &acc, &x);
        let span = (target as f64 - 1e6).abs();
        let abs_w: f64 = shapers.iter().map(|s| s.abs_amplitude_sum()).sum();
        let taps: f64 = shapers.iter().map(|s| table(s).len() as f64).sum();
        let bound = 0.5 + (taps + 2.0) * 2f64.powi(-23) * abs_w * span + 1.0;
        for n in 0..x.len() {
            prop_assert!((y[n] as f64 - exact[n]).abs() <= bound, "n={} {} vs {}", n, y[n], exact[n]);
        }
        prop_assert_eq!(*y.last().unwrap(), target);
    }
}

/// A modal beam model: modes (Hz, damping ratio, tip gain) excited by the base (the
/// setpoint, linear between ticks). Returns the peak tip deflection (counts) over 15 s after
/// the last sample of `y` that moved.
fn residual_tip(y: &[i32]) -> f64 {
    let modes = [(1.1f64, 0.0074f64, 1.566f64), (6.9, 0.0074, -0.868)];
    let dt = 1.0 / RATE;
    let last_move = (1..y.len()).rev().find(|&k| y[k] != y[k - 1]).unwrap_or(0);
    let total = last_move + 15 * RATE as usize;
    let at = |k: usize| y[k.min(y.len() - 1)] as f64;
    let mut state: Vec<(f64, f64)> = vec![(0.0, 0.0); modes.len()];
    let mut peak: f64 = 0.0;
    for k in 1..total {
        // Base acceleration of a piecewise-linear position: velocity kicks at the ticks.
        let kick = (at(k + 1) - 2.0 * at(k) + at(k - 1)) / dt;
        let mut tip = 0.0;
        for (m, (f, z, g)) in modes.iter().enumerate() {
            let w = 2.0 * std::f64::consts::PI * f;
            let wd = w * (1.0 - z * z).sqrt();
            let (mut q, mut v) = state[m];
            v -= g * kick;
            // Exact free decay over one tick.
            let (e, c, s) = ((-z * w * dt).exp(), (wd * dt).cos(), (wd * dt).sin());
            let q1 = e * (q * c + (v + z * w * q) / wd * s);
            let v1 = e * (v * c - (w * w * q + z * w * v) / wd * s);
            q = q1;
            v = v1;
            state[m] = (q, v);
            tip += q;
        }
        if k > last_move {
            peak = peak.max(tip.abs());
        }
    }
    peak
}

#[test]
fn residual_vibration_after_a_mid_move_retune_stays_within_the_worse_shaper() {
    // Live retuning: the old design is 8 % off the beam, the new one on it.
    let old = two_mode(ShaperKind::Zvd, 1.02, 6.4);
    let new = two_mode(ShaperKind::Zvd, 1.1, 6.9);
    let x = trapezoid(0, 100_000_000, 2.0e8, 2.0e9, 2000);
    let (y_old, _) = run_switched(&[old.clone()], &[], &x, NumericPath::Fixed);
    let (y_new, _) = run_switched(&[new.clone()], &[], &x, NumericPath::Fixed);
    let (r_old, r_new) = (residual_tip(&y_old), residual_tip(&y_new));
    let r_none = residual_tip(&x);
    assert!(
        r_new < r_old && r_old < 0.5 * r_none,
        "{r_none} {r_old} {r_new}"
    );
    for at in [50usize, 200, 400, 550, 700, 1200] {
        let (y, _) = run_switched(&[old.clone(), new.clone()], &[at], &x, NumericPath::Fixed);
        let r = residual_tip(&y);
        assert!(
            r <= r_old.max(r_new) * 1.02,
            "switch at {at}: residual {r:.0} nm > worse shaper {:.0} nm (new {r_new:.0})",
            r_old
        );
    }
}

fn settings_with(kind: ShaperKind, f: f64) -> Settings {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind,
        freq_hz: f,
        zeta: 0.0074,
    });
    s.max_step_rate_hz = 5_000_000;
    s
}

#[test]
fn step_dir_pass_through_that_is_never_still_applies_the_change() {
    let mut s = settings_with(ShaperKind::Zvd, 1.1);
    s.source = beamshaper::config::Source::StepDir;
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(RunParams::from_settings(&s).unwrap(), 0);
    let mut count = 0u16;
    let mut prev = rt.status().setpoint_counts;
    let mut max_step = 0i64;
    let mut gain = 0.0;
    for k in 0..6000u32 {
        // 3 input steps per tick, never still.
        count = count.wrapping_add(3);
        if k == 1000 {
            let mut b = s.clone();
            b.modes[0] = Some(ModeSetting {
                kind: ShaperKind::Zvdd,
                freq_hz: 1.3,
                zeta: 0.0074,
            });
            let p = RunParams::from_settings(&b).unwrap();
            assert_eq!(rt.request(p.clone()).unwrap(), Applies::NextTick);
            gain = rt.engine().transition_gain(&p.taps) as f64;
            let out = rt.tick(&TickInput {
                stepdir_count: count,
            });
            max_step = max_step.max((out.setpoint_counts as i64 - prev as i64).abs());
            prev = out.setpoint_counts;
            assert_eq!(rt.engine().taps(), &p.taps, "applied at the next tick");
            assert!(rt.status().stages == 2 && !rt.status().waiting.any());
            continue;
        }
        let out = rt.tick(&TickInput {
            stepdir_count: count,
        });
        max_step = max_step.max((out.setpoint_counts as i64 - prev as i64).abs());
        prev = out.setpoint_counts;
    }
    assert_eq!(rt.status().stages, 1, "transition over");
    // 3000 nm per tick in; during the transition the two windows overlap (ZVD 1.1 Hz ->
    // ZVDD 1.3 Hz: gain 1.25), never a jump.
    assert!(gain > 1.0 && gain < 1.3, "{gain}");
    assert!(
        max_step as f64 <= gain * 3_000.0 + 2.0,
        "{max_step} (gain {gain})"
    );
    // A rate change still waits for standstill, and says so.
    let mut r = s.clone();
    r.tick_rate_hz = 2000;
    assert_eq!(
        rt.request(RunParams::from_settings(&r).unwrap()).unwrap(),
        Applies::WhenStill
    );
    let st = rt.status();
    assert!(st.waiting.tick_rate && !st.waiting.path, "{:?}", st.waiting);
}

#[test]
fn a_transition_over_the_tap_budget_is_refused() {
    let big = |f: f64| {
        let mut s = Settings::DEFAULT;
        for (i, g) in [f, f * 6.3, f * 15.8].iter().enumerate() {
            s.modes[i] = Some(ModeSetting {
                kind: ShaperKind::Zvdd,
                freq_hz: *g,
                zeta: 0.0074,
            });
        }
        s
    };
    let a = RunParams::from_settings(&big(1.1)).unwrap();
    let b = RunParams::from_settings(&big(1.2)).unwrap();
    let c = RunParams::from_settings(&big(1.3)).unwrap();
    assert!(a.taps.len() > 120 && b.taps.len() > 120, "{}", a.taps.len());
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(a, 0);
    assert_eq!(rt.request(b).unwrap(), Applies::NextTick);
    rt.tick(&TickInput::default());
    assert!(rt.status().taps_in_flight <= TAP_BUDGET);
    match rt.request(c.clone()) {
        Err(RuntimeError::Switch(SwitchError::Budget { taps })) => assert!(taps > TAP_BUDGET),
        other => panic!("{other:?}"),
    }
    // Once the old table has settled, the same change is accepted.
    for _ in 0..rt.engine().settle_ticks() + 1 {
        rt.tick(&TickInput::default());
    }
    assert_eq!(rt.status().stages, 1);
    assert_eq!(rt.request(c).unwrap(), Applies::NextTick);

    // On the console: the refusal names the budget and changes nothing.
    let mut bd = Board::new();
    bd.ok("mode 1 zvdd 1.1 0.0074");
    bd.ok("mode 2 zvdd 6.9 0.0074");
    bd.ok("mode 3 zvdd 17.3 0.0074");
    bd.run(10_000);
    bd.ok("mode 1 zvdd 1.2 0.0074");
    bd.run(1);
    let (out, _) = bd.cmd("mode 1 zvdd 1.3 0.0074");
    assert!(
        out.contains("the budget is 256") && out.contains("err budget:"),
        "{out}"
    );
    bd.err("mode 1 zvdd 1.3 0.0074", "budget");
}

#[test]
fn mode_during_a_move_on_the_console_applies_at_the_next_tick_without_a_jump() {
    let mut b = Board::new();
    b.ok("mode 1 zvd 1.0 0.0074");
    b.run(10);
    b.ok("capture 1");
    b.ok("move 50 100 2000");
    b.run(150);
    let out = b.ok("mode 1 zvdd 1.1 0.0074");
    assert!(out.contains("applies=next-tick"), "{out}");
    b.run(3000);
    let cap: Vec<i32> = b.rt.capture().samples().to_vec();
    assert!(cap.len() > 3000);
    let unswitched = 100_000; // 100 mm/s at 1 kHz: the reference's own per-tick change
    assert!(
        max_tick_change(&cap) <= unswitched,
        "{}",
        max_tick_change(&cap)
    );
    assert_eq!(*cap.last().unwrap(), 50_000_000);
    let st = b.ok("status");
    assert!(
        st.contains("stages=1") && st.contains("waiting=none"),
        "{st}"
    );
}

#[test]
fn a_switch_that_could_exceed_the_step_rate_mid_move_is_refused() {
    let mut b = Board::new();
    b.ok("maxrate 250000");
    b.run(5);
    b.ok("mode 1 zv 1.0 0");
    b.run(5);
    // 200 mm/s = 200 000 steps/s; ZV -> identity overlaps: 1.5 x = 300 000 steps/s.
    b.ok("move 100 200 2000");
    b.run(300);
    let (out, _) = b.cmd("shaping off");
    assert!(out.contains("err step-rate:"), "{out}");
    b.run(1000);
    b.ok("shaping off");
}
