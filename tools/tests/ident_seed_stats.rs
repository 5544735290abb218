//! Statistics over 20 noise seeds of the accuracy protocol (docs/ident.md). Run with
//! `WHICH=bt cargo test --test ident_seed_stats -- --ignored --nocapture` (b = noise on
//! base_pos_m, t = on tip_pos_m; `SK=n` Sanathanan–Koerner iterations; `NOCMD=1` drops the
//! noise-free `base_cmd_m` so that the base is tracking-filtered instead of predicted from it;
//! `NOISYCMD=1` adds 5 % noise to `base_cmd_m` too).
use beamtools::ident::frf::InputChannel;
use beamtools::ident::protocol::{simulate_sweep, truth};
use beamtools::ident::sweep::{SweepKind, SweepSpec};
use beamtools::ident::{identify_recording, IdentOptions, Method};
use beamtools::model::{BeamModel, ModelOptions, Rig};
#[test]
#[ignore]
fn stats() {
    let rig = Rig::from_toml_file("../rigs/paper.toml").unwrap();
    let m = BeamModel::new(&rig, &ModelOptions::default()).unwrap();
    let tr = truth(&m).unwrap();
    let beta = 60.0 * (8.0f64 / 0.1).log2() / 120.0;
    for meth in [Method::Lscf] {
        let mut e = vec![vec![]; 4];
        let mut miss = 0;
        for seed in 100..120 {
            let spec = SweepSpec {
                tail_s: 20.0,
                ..SweepSpec::paper(SweepKind::Exponential, beta)
            };
            let clean = simulate_sweep(&m, &spec, 100.0, 0.0, seed).unwrap();
            let mut noisy = clean.clone();
            beamtools::ident::protocol::add_noise(&mut noisy, 0.05, seed);
            let mut rec = clean.clone();
            let which = std::env::var("WHICH").unwrap_or_default();
            if which.contains('b') {
                rec.base_pos_m = noisy.base_pos_m.clone();
            }
            if which.contains('t') {
                rec.tip_pos_m = noisy.tip_pos_m.clone();
            }
            if std::env::var("NOISYCMD").is_ok() {
                let mut c = clean.clone();
                c.base_pos_m = c.base_cmd_m.take();
                beamtools::ident::protocol::add_noise(&mut c, 0.05, seed + 1000);
                rec.base_cmd_m = c.base_pos_m;
            }
            if std::env::var("NOCMD").is_ok() {
                rec.base_cmd_m = None;
            }
            let opts = IdentOptions {
                methods: vec![meth],
                input: InputChannel::BaseAccel,
                band_hz: Some((0.3, 8.0)),
                n_modes: Some(2),
                sk_iterations: std::env::var("SK")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(IdentOptions::default().sk_iterations),
                track_input: std::env::var("NOTRACK").is_err(),
                ..Default::default()
            };
            let Ok((r, _)) = identify_recording(&rec, &opts) else {
                miss += 1;
                continue;
            };
            if r.modes.len() < 2 {
                miss += 1;
                continue;
            }
            let t = tr.for_input(InputChannel::BaseAccel);
            for i in 0..2 {
                e[i].push(100.0 * (r.modes[i].freq_hz / t[i].0 - 1.0));
                e[2 + i].push(100.0 * (r.modes[i].zeta / t[i].1 - 1.0));
            }
        }
        for (name, v) in ["f1", "f2", "z1", "z2"].iter().zip(&e) {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let maxabs = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let within = v
                .iter()
                .filter(|x| x.abs() < if name.starts_with('f') { 0.2 } else { 15.0 })
                .count();
            eprintln!("{meth:?} {name}: mean {mean:+.3}% sd {sd:.3}% max|e| {maxabs:.3}% within target {within}/{}", v.len());
        }
        eprintln!("{meth:?} missing {miss}");
    }
}
