//! One tick of the run-time engine for a two-mode ZVDD shaper (f1 = 1.1 Hz, f2 = 6.9 Hz,
//! ζ = 0.0074, 1 kHz), fixed-point and f32 paths, against the peer of a plain f64
//! convolution of the same taps (what a straightforward host implementation would do).

use beamshaper::config::{ModeSetting, Settings};
use beamshaper::engine::{Engine, NumericPath};
use beamshaper::runtime::{RunParams, Runtime, TickInput, HISTORY_LEN};
use beamshaper::shaper::ShaperKind;
use criterion::{black_box, criterion_group, criterion_main, Criterion};

fn two_mode_zvdd() -> Settings {
    let mut s = Settings::DEFAULT;
    s.modes[0] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 1.1,
        zeta: 0.0074,
    });
    s.modes[1] = Some(ModeSetting {
        kind: ShaperKind::Zvdd,
        freq_hz: 6.9,
        zeta: 0.0074,
    });
    s
}

fn bench(c: &mut Criterion) {
    let settings = two_mode_zvdd();
    let params = RunParams::from_settings(&settings).unwrap();
    println!(
        "two-mode ZVDD at 1 kHz: {} taps (worst case for the interrupt: {} taps)",
        params.taps.taps().len(),
        beamshaper::engine::MAX_TAPS
    );
    for path in [NumericPath::Fixed, NumericPath::F32] {
        let mut e: Box<Engine<HISTORY_LEN>> = Box::new(Engine::new(0));
        e.install(params.taps.clone(), path, 0);
        let mut x = 0i32;
        c.bench_function(&format!("engine_tick_2mode_zvdd_{}", path.name()), |b| {
            b.iter(|| {
                x = x.wrapping_add(997) & 0x3fff_ffff;
                black_box(e.tick(black_box(x)))
            })
        });
    }
    // Peer: the same taps as an f64 dot product over a Vec ring buffer.
    let taps: Vec<(usize, f64)> = params
        .taps
        .taps()
        .iter()
        .map(|t| (t.delay as usize, t.w_f32 as f64))
        .collect();
    let mut ring = vec![0.0f64; HISTORY_LEN];
    let mut head = 0usize;
    let mut x = 0i32;
    c.bench_function("peer_f64_vec_tick_2mode_zvdd", |b| {
        b.iter(|| {
            x = x.wrapping_add(997) & 0x3fff_ffff;
            head = (head + 1) % HISTORY_LEN;
            ring[head] = x as f64;
            let y: f64 = taps
                .iter()
                .map(|&(d, w)| w * ring[(head + HISTORY_LEN - d) % HISTORY_LEN])
                .sum();
            black_box(y)
        })
    });
    // The whole runtime tick (reference source + engine + step output + DAC).
    let mut rt = Box::new(Runtime::new());
    rt.configure_at_boot(params, 0);
    c.bench_function("runtime_tick_2mode_zvdd_fixed", |b| {
        b.iter(|| {
            if rt.status().moving {
            } else {
                let target = if rt.status().reference_counts == 0 {
                    50_000_000
                } else {
                    0
                };
                let _ = rt.start_move(target, 2.0e8, 2.0e9);
            }
            black_box(rt.tick(&TickInput { stepdir_count: 0 }))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
