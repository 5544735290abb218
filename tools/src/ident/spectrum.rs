//! Hamming-windowed amplitude spectra and peak picking.

use realfft::RealFftPlanner;

/// Hamming window of length n (paper §3.1, Step 2).
pub fn hamming(n: usize) -> Vec<f64> {
    if n < 2 {
        return vec![1.0; n];
    }
    (0..n)
        .map(|k| 0.54 - 0.46 * (2.0 * std::f64::consts::PI * k as f64 / (n - 1) as f64).cos())
        .collect()
}

/// Amplitude spectrum |X(f)| of `x` (mean removed, Hamming window, zero-padded ×4):
/// returns (frequencies Hz, magnitudes).
pub fn amplitude_spectrum(x: &[f64], rate_hz: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let nfft = (4 * n).next_power_of_two();
    let mean = x.iter().sum::<f64>() / n as f64;
    let w = hamming(n);
    let mut buf = vec![0.0; nfft];
    for k in 0..n {
        buf[k] = (x[k] - mean) * w[k];
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(nfft);
    let mut spec = fft.make_output_vec();
    let _ = fft.process(&mut buf, &mut spec);
    let f = (0..spec.len())
        .map(|k| k as f64 * rate_hz / nfft as f64)
        .collect();
    (f, spec.iter().map(|c| c.norm()).collect())
}

/// Local maxima of `mag` within [f_min, f_max], strongest first, each refined by a parabola
/// through the log-magnitudes of its three bins: (frequency Hz, magnitude).
pub fn peaks(f: &[f64], mag: &[f64], f_min: f64, f_max: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for k in 1..mag.len().saturating_sub(1) {
        if f[k] < f_min || f[k] > f_max || !(mag[k] > mag[k - 1] && mag[k] >= mag[k + 1]) {
            continue;
        }
        let (a, b, c) = (
            mag[k - 1].max(1e-300).ln(),
            mag[k].max(1e-300).ln(),
            mag[k + 1].max(1e-300).ln(),
        );
        let d = a - 2.0 * b + c;
        let p = if d.abs() > 0.0 {
            0.5 * (a - c) / d
        } else {
            0.0
        };
        let df = f[1] - f[0];
        out.push((
            f[k] + p.clamp(-0.5, 0.5) * df,
            (b - 0.25 * (a - c) * p).exp(),
        ));
    }
    out.sort_by(|x, y| y.1.total_cmp(&x.1));
    out
}
