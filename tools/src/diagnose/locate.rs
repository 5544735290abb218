//! Locating the discrepancy: where the residual (recording − calibrated nominal model) is
//! large and structured — by channel, by time window (moving, around velocity reversals, free
//! decay, high/low vibration amplitude), by frequency (residual spectrum against the model's
//! modes) and by correlation (velocity sign, velocity, position ripple, time shift, amplitude).

use super::fit::CHANNEL_NAMES;
use super::model::{Prediction, Prepared};
use crate::ident::spectrum::{amplitude_spectrum, peaks};
use serde::Serialize;

/// One located feature.
#[derive(Clone, Debug, Serialize)]
pub struct ChannelLocation {
    /// Channel name.
    pub channel: String,
    /// RMS residual (channel unit).
    pub rms: f64,
    /// NRMSE = rms residual / rms of the signal (tip: of the deflection tip − base).
    pub nrmse: f64,
    /// RMS residual by window: moving, within 0.3 s of a velocity reversal, free decay.
    pub rms_moving: f64,
    /// Around reversals.
    pub rms_reversal: f64,
    /// Still (free decay).
    pub rms_still: f64,
    /// Still and high vs low vibration amplitude (tip only; NaN otherwise).
    pub rms_high_amplitude: f64,
    /// Low amplitude.
    pub rms_low_amplitude: f64,
    /// Strongest residual spectral peaks (Hz, amplitude).
    pub spectrum_peaks: Vec<(f64, f64)>,
    /// Correlation of the residual with sign(velocity).
    pub corr_velocity_sign: f64,
    /// Correlation with the velocity.
    pub corr_velocity: f64,
    /// Correlation with the time derivative of the prediction (a time shift).
    pub corr_time_shift: f64,
    /// Best position ripple: (pitch m, fraction of residual variance explained).
    pub position_ripple: (f64, f64),
}

/// The whole location report.
#[derive(Clone, Debug, Serialize)]
pub struct Location {
    /// Per channel.
    pub channels: Vec<ChannelLocation>,
    /// The model's clamped-base natural frequencies (Hz).
    pub model_freqs_hz: Vec<f64>,
    /// Plain-words summary.
    pub words: Vec<String>,
}

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    if n < 3.0 {
        return 0.0;
    }
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

fn rms_where(r: &[f64], m: &[bool]) -> f64 {
    let (s, n) = r
        .iter()
        .zip(m)
        .filter(|(_, k)| **k)
        .fold((0.0, 0usize), |(s, n), (x, _)| (s + x * x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// Best pitch p (m) for `r ≈ a sin(2πy/p) + b cos(2πy/p)` over moving samples, scanning
/// 2 mm…200 mm; returns (pitch, sin amplitude, cos amplitude, explained variance fraction).
pub fn ripple_scan(r: &[f64], y: &[f64], moving: &[bool]) -> (f64, f64, f64, f64) {
    ripple_peaks(r, y, moving, 1)
        .first()
        .copied()
        .unwrap_or((0.01, 0.0, 0.0, 0.0))
}

/// The `k` best local maxima of the explained variance over the pitch scan of [`ripple_scan`],
/// best first, each (pitch m, sin amplitude, cos amplitude, explained fraction). The scan of a
/// residual that holds model-form error besides a ripple is multimodal: the true pitch need not
/// be the best point, only among the best few.
pub fn ripple_peaks(r: &[f64], y: &[f64], moving: &[bool], k: usize) -> Vec<(f64, f64, f64, f64)> {
    let idx: Vec<usize> = (0..r.len()).filter(|&k| moving[k]).collect();
    let total: f64 = idx.iter().map(|&k| r[k] * r[k]).sum();
    if idx.len() < 20 || total <= 0.0 {
        return Vec::new();
    }
    let n = 400;
    let mut scan = Vec::with_capacity(n);
    for i in 0..n {
        let p = 0.002 * (100.0f64).powf(i as f64 / (n - 1) as f64);
        let kw = 2.0 * std::f64::consts::PI / p;
        let (mut ss, mut cc, mut sc, mut rs, mut rc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &k in &idx {
            let (s, c) = (kw * y[k]).sin_cos();
            ss += s * s;
            cc += c * c;
            sc += s * c;
            rs += r[k] * s;
            rc += r[k] * c;
        }
        let det = ss * cc - sc * sc;
        if det.abs() < 1e-12 {
            scan.push((p, 0.0, 0.0, 0.0));
            continue;
        }
        let a = (rs * cc - rc * sc) / det;
        let b = (rc * ss - rs * sc) / det;
        scan.push((p, a, b, (a * rs + b * rc) / total));
    }
    let mut peaks: Vec<(f64, f64, f64, f64)> = (0..n)
        .filter(|&i| {
            let e = scan[i].3;
            e > 0.0 && (i == 0 || e > scan[i - 1].3) && (i + 1 == n || e >= scan[i + 1].3)
        })
        .map(|i| scan[i])
        .collect();
    peaks.sort_by(|x, y| y.3.total_cmp(&x.3));
    peaks.truncate(k);
    peaks
}

/// Linear least squares of the force residual on [tanh(v/1 mm/s), v] over all samples.
pub fn friction_ls(r: &[f64], v: &[f64]) -> (f64, f64) {
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (e, vel) in r.iter().zip(v) {
        let s = (vel / 1e-3).tanh();
        a11 += s * s;
        a12 += s * vel;
        a22 += vel * vel;
        b1 += s * e;
        b2 += vel * e;
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() < 1e-300 {
        return (0.0, 0.0);
    }
    ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det)
}

/// Velocity (central difference) of a position series.
pub fn velocity(y: &[f64], dt: f64) -> Vec<f64> {
    let n = y.len();
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            if b > a {
                (y[b] - y[a]) / ((b - a) as f64 * dt)
            } else {
                0.0
            }
        })
        .collect()
}

/// One channel's residual and the signals it is compared with, over every recording.
#[derive(Default)]
struct Gathered {
    r: Vec<f64>,
    sig: Vec<f64>,
    amp: Vec<f64>,
    mov: Vec<bool>,
    rev: Vec<bool>,
    still: Vec<bool>,
    v: Vec<f64>,
    vs: Vec<f64>,
    dp: Vec<f64>,
    y: Vec<f64>,
    spectra: Vec<(f64, f64)>,
}

/// Samples within ±0.3 s of the start of a move whose direction differs from the move before.
fn reversals(v: &[f64], moving: &[bool], dt: f64) -> Vec<bool> {
    let n = v.len();
    let mut reversal = vec![false; n];
    let mut last_sign = 0.0;
    let w = (0.3 / dt) as usize;
    for k in 1..n {
        if moving[k] && !moving[k - 1] {
            let s = v[k.min(n - 1)].signum();
            if last_sign != 0.0 && s != last_sign {
                for j in k.saturating_sub(w)..(k + w).min(n) {
                    reversal[j] = true;
                }
            }
            last_sign = s;
        }
    }
    reversal
}

impl Gathered {
    /// Adds recording `d` (prediction `p`) of channel `c`, if recorded.
    fn add(&mut self, d: &Prepared, p: &Prediction, c: usize) {
        let (meas, pr) = match c {
            0 => (&d.base_m, &p.base_m),
            1 => (&d.tip_m, &p.tip_m),
            _ => (&d.force_n, &p.force_n),
        };
        let (Some(meas), Some(pr)) = (meas, pr) else {
            return;
        };
        let drive = d.drive_as_sampled();
        let v = velocity(d.cmd_as_sampled(), d.dt);
        let vd = velocity(drive, d.dt);
        let n = meas.len();
        let r: Vec<f64> = meas.iter().zip(pr).map(|(a, b)| a - b).collect();
        let moving: Vec<bool> = v.iter().map(|x| x.abs() > 1e-4).collect();
        let reversal = reversals(&v, &moving, d.dt);
        let signal: Vec<f64> = if c == 1 {
            meas.iter().zip(drive).map(|(a, b)| a - b).collect()
        } else {
            meas.clone()
        };
        let mean = signal.iter().sum::<f64>() / n as f64;
        self.sig.extend(signal.iter().map(|x| x - mean));
        if c == 1 {
            self.amp.extend(signal.iter().map(|x| (x - mean).abs()));
        }
        let (f, m) = amplitude_spectrum(&r, 1.0 / d.dt);
        for (fk, mk) in peaks(&f, &m, 0.2, super::model::band_edge_hz(d.dt))
            .into_iter()
            .take(4)
        {
            self.spectra.push((fk, mk));
        }
        self.r.extend(r);
        self.still.extend(moving.iter().map(|m| !m));
        self.mov.extend(moving);
        self.rev.extend(reversal);
        self.v.extend(vd.iter().copied());
        self.vs.extend(
            vd.iter()
                .map(|x| if x.abs() > 1e-4 { x.signum() } else { 0.0 }),
        );
        self.dp.extend(velocity(pr, d.dt));
        self.y.extend(drive.iter().copied());
    }

    /// rms of the residual in free decay above and below the median deflection amplitude.
    fn amplitude_split(&self) -> (f64, f64) {
        let mut a: Vec<f64> = self
            .amp
            .iter()
            .zip(&self.still)
            .filter(|(_, s)| **s)
            .map(|(a, _)| *a)
            .collect();
        a.sort_by(|x, y| x.total_cmp(y));
        let med = a.get(a.len() / 2).copied().unwrap_or(0.0);
        let pick = |high: bool| -> Vec<bool> {
            self.amp
                .iter()
                .zip(&self.still)
                .map(|(a, s)| *s && ((*a > med) == high))
                .collect()
        };
        (
            rms_where(&self.r, &pick(true)),
            rms_where(&self.r, &pick(false)),
        )
    }

    /// The channel's location summary.
    fn summary(mut self, c: usize) -> ChannelLocation {
        let ones = vec![true; self.r.len()];
        let rms = rms_where(&self.r, &ones);
        let sig_rms = rms_where(&self.sig, &ones);
        let (hi, lo) = if c == 1 {
            self.amplitude_split()
        } else {
            (f64::NAN, f64::NAN)
        };
        self.spectra.sort_by(|a, b| b.1.total_cmp(&a.1));
        self.spectra.truncate(4);
        let rip = ripple_scan(&self.r, &self.y, &self.mov);
        ChannelLocation {
            channel: CHANNEL_NAMES[c].to_string(),
            rms,
            nrmse: rms / sig_rms.max(1e-300),
            rms_moving: rms_where(&self.r, &self.mov),
            rms_reversal: rms_where(&self.r, &self.rev),
            rms_still: rms_where(&self.r, &self.still),
            rms_high_amplitude: hi,
            rms_low_amplitude: lo,
            spectrum_peaks: self.spectra,
            corr_velocity_sign: corr(&self.r, &self.vs),
            corr_velocity: corr(&self.r, &self.v),
            corr_time_shift: corr(&self.r, &self.dp),
            position_ripple: (rip.0, rip.3),
        }
    }
}

/// One channel's location in words (three lines).
fn channel_words(ch: &ChannelLocation, model_freqs_hz: &[f64]) -> Vec<String> {
    let mut s = format!(
        "{}: residual rms {:.3e} (NRMSE {:.3}); moving {:.3e}, at reversals {:.3e}, in free decay {:.3e}",
        ch.channel, ch.rms, ch.nrmse, ch.rms_moving, ch.rms_reversal, ch.rms_still
    );
    if ch.rms_high_amplitude.is_finite() {
        s += &format!(
            ", free decay high/low amplitude {:.3e}/{:.3e}",
            ch.rms_high_amplitude, ch.rms_low_amplitude
        );
    }
    let pk: Vec<String> = ch
        .spectrum_peaks
        .iter()
        .map(|(f, a)| format!("{f:.2} Hz ({a:.2e})"))
        .collect();
    let near: Vec<String> = ch
        .spectrum_peaks
        .iter()
        .filter_map(|(f, _)| {
            model_freqs_hz
                .iter()
                .find(|m| (*m / f - 1.0).abs() < 0.08)
                .map(|m| format!("{f:.2} Hz ≈ model mode {m:.2} Hz"))
        })
        .collect();
    vec![
        s,
        format!(
            "  spectrum peaks: {}{}",
            pk.join(", "),
            if near.is_empty() {
                String::from(" (none at a model mode)")
            } else {
                format!("; {}", near.join(", "))
            }
        ),
        format!(
            "  correlation with sign(velocity) {:+.2}, velocity {:+.2}, d/dt of the prediction (time shift) {:+.2}; best position ripple pitch {:.1} mm explains {:.0} % of the moving residual",
            ch.corr_velocity_sign,
            ch.corr_velocity,
            ch.corr_time_shift,
            1e3 * ch.position_ripple.0,
            100.0 * ch.position_ripple.1
        ),
    ]
}

/// Locates the discrepancy of `preds` (calibrated nominal) on `data`.
pub fn locate(data: &[Prepared], preds: &[Prediction], model_freqs_hz: &[f64]) -> Location {
    let mut channels = Vec::new();
    for c in 0..3 {
        let mut g = Gathered::default();
        for (d, p) in data.iter().zip(preds) {
            g.add(d, p, c);
        }
        if !g.r.is_empty() {
            channels.push(g.summary(c));
        }
    }
    let words = channels
        .iter()
        .flat_map(|ch| channel_words(ch, model_freqs_hz))
        .collect();
    Location {
        channels,
        model_freqs_hz: model_freqs_hz.to_vec(),
        words,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_weaker_ripple_is_among_the_best_pitches_of_the_scan() {
        // a carriage sweeping 0.2 m back and forth; a ripple of 17.5 mm pitch under a stronger
        // one of 7.3 mm (model-form error that happens to project on a pitch)
        let y: Vec<f64> = (0..4000)
            .map(|k| 0.1 * (1.0 - (2.0 * std::f64::consts::PI * k as f64 / 2000.0).cos()))
            .collect();
        let ripple = |p: f64, a: f64| {
            y.iter()
                .map(move |x| a * (2.0 * std::f64::consts::PI * x / p).sin())
                .collect::<Vec<f64>>()
        };
        let r: Vec<f64> = ripple(0.0073, 1.0)
            .iter()
            .zip(ripple(0.0175, 0.6))
            .map(|(a, b)| a + b)
            .collect();
        let moving = vec![true; y.len()];
        let best = ripple_scan(&r, &y, &moving);
        assert!((best.0 - 0.0073).abs() < 0.0002, "{best:?}");
        let peaks = ripple_peaks(&r, &y, &moving, 3);
        assert!(
            peaks.iter().any(|p| (p.0 - 0.0175).abs() < 0.0004),
            "{peaks:?}"
        );
    }
}
