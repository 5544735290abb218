//! Issue 72's proof on real data: the watch's fit (the same core code the board runs,
//! `beamshaper::watch`) on the real aluminium-cantilever free decays
//! (`../shared/data/real/aluminium-cantilever/`, ADXL357 near the tip, ~4 kHz with logging
//! gaps) gives f1 within 0.5 % of `identify`'s (`identify_free_decay`, the tools' free-decay
//! identification). The signal is resampled to the ADXL345's 3 200 Hz, decimated as the
//! watch decimates (block means to the rate `decimated_rate` picks for the shaper), and fitted
//! from a shaper 5 % off both modes (MZV at f1, ZV at f2, as `tune` chose for these beams): the
//! estimate comes from the data, not from the shaper. A free decay has no setpoint input: the
//! fit's input terms are zero and its free-response terms carry the decay.

use beamshaper::watch::decimated_rate;
use beamshaper::watch::modal::{fit_modes, ModalGuess, MoveBuffer, MOVE_LEN};
use beamtools::ident::freedecay::{identify_free_decay, FreeDecayOptions};
use beamtools::recording::Recording;

const RATE_HZ: f64 = 3200.0;

/// Linear interpolation of (t, x) onto a uniform grid at `rate` Hz from `t0` to the end.
fn resample(t: &[f64], x: &[f64], t0: f64, rate: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut j = 0;
    let mut k = 0usize;
    loop {
        let tk = t0 + k as f64 / rate;
        if tk >= *t.last().unwrap() {
            return out;
        }
        while t[j + 1] < tk {
            j += 1;
        }
        let w = (tk - t[j]) / (t[j + 1] - t[j]);
        out.push(x[j] + w * (x[j + 1] - x[j]));
        k += 1;
    }
}

#[test]
fn the_watch_fit_matches_identify_on_the_real_aluminium_decays() {
    let dir = "../../shared/data/real/aluminium-cantilever";
    for name in [
        "40cm_adxl_08-12_11-42-08_adxl6cmfromtip2cmID.npy",
        "50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy",
        "60cm_adxl_08-12_21-22-38_4cmID.npy",
    ] {
        let (t, x) = Recording::read_npy(format!("{dir}/{name}")).unwrap();
        let id = identify_free_decay(&t, &x, &FreeDecayOptions::default()).unwrap();
        let f1 = id.mode.freq_hz;
        let f2 = id
            .other_peaks_hz
            .iter()
            .copied()
            .find(|&f| f > 5.0 * f1)
            .unwrap_or(6.3 * f1);
        // The decay after the pluck: from 0.5 s after the largest reading.
        let peak = (0..x.len())
            .max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()))
            .unwrap();
        let u = resample(&t, &x, t[peak] + 0.5, RATE_HZ);
        let guess = [
            ModalGuess {
                freq_hz: (1.05 * f1) as f32,
                zeta: 0.01,
            },
            ModalGuess {
                freq_hz: (1.05 * f2) as f32,
                zeta: 0.01,
            },
        ];
        let (fs, dec) = decimated_rate(1000, RATE_HZ as f32, 1.05 * f2).unwrap();
        let mut buf = MoveBuffer::new();
        for block in u.chunks_exact(dec as usize).take(MOVE_LEN) {
            let mean = block.iter().sum::<f64>() / block.len() as f64;
            buf.push(0.0, mean as f32);
        }
        let fitted = fit_modes(&buf, &guess, fs as f32);
        let m = fitted[0].expect("mode 1 resolved");
        let err = m.freq_hz as f64 / f1 - 1.0;
        println!(
            "{name}: identify f1 = {f1:.4} Hz; watch fit f1 = {:.4} Hz ({:+.3} %), zeta1 = {:.5} \
             (identify {:.5}); fs = {fs} Hz, {} samples",
            m.freq_hz,
            100.0 * err,
            m.zeta,
            id.mode.zeta,
            buf.len()
        );
        assert!(
            err.abs() < 0.005,
            "{name}: f1 {} vs identify {f1}",
            m.freq_hz
        );
    }
}
