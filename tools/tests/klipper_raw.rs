//! Klipper's raw accelerometer file end to end (issue 70, items 1, 2, 4): a synthetic
//! `raw_data_x_*.csv` of Klipper's resonance test is written into a temporary directory, then
//! - its PSD (`recording::rawpsd`, Klipper's method) peaks at the resonance;
//! - `identify` takes the spectrum path and reports a mode inside the half-power band of the
//!   largest peak of that PSD of the axis read;
//! - `tune`'s design from the raw file equals the design from the same PSD written out in
//!   Klipper's `calibration_data_*.csv` and `resonances_*.csv` formats.
//!
//! The generator: Klipper's test (docs `Measuring_Resonances.md`, `[resonance_tester]` of
//! v0.13.0: accel_per_hz 60 mm/s²/Hz, hz_per_sec 1, 5–135 Hz, and the slow back-and-forth
//! sweeping motion of ±400 mm/s², period 1.2 s) as a square wave of acceleration ±60·f whose
//! frequency rises linearly — switching where the phase ∫f dt crosses a half-integer — drives
//! the toolhead through two lightly damped modes (belt/frame: 42 Hz, ζ 0.06 and 75 Hz, ζ 0.08,
//! each base-excited, q'' + 2ζωq' + ω²q = −g·u, propagated exactly between switches and
//! samples). The chip (ADXL345 at 3200 Hz nominal, its clock 0.01 % slow) reports the mean
//! acceleration over each sample interval, with white noise of 50 mm/s² RMS, quantised to its
//! 3.9 mg step (38.3 mm/s²); the printer stamps each sample with 1 µs RMS clock jitter.

use beamtools::ident::identify::{identify_file, IdentPath, IdentifyOptions};
use beamtools::recording::psd::{normalize_to_frequencies, KlipperSpectrum};
use beamtools::recording::rawpsd::{format_spectrum_csv, raw_spectrum, read_raw};
use beamtools::shaping::klipper::{worst_response, FitSpectrum};
use beamtools::shaping::spectrum::{Objective, VIBRATION_MARGIN};
use beamtools::tune::spectrum::design_file;
use rand::{rngs::StdRng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;
use std::io::Write;
use std::path::Path;

/// ADXL345 step (mm/s²): 3.9 mg.
const LSB_MM_S2: f64 = 38.3;
/// The modes: (f Hz, ζ, participation g).
const MODES: [(f64, f64, f64); 2] = [(42.0, 0.06, 1.0), (75.0, 0.08, 0.4)];

/// One base-excited mode's state (relative displacement, velocity) under a constant input.
#[derive(Clone, Copy)]
struct Mode {
    w: f64,
    z: f64,
    g: f64,
    q: f64,
    v: f64,
}

impl Mode {
    /// Advances by `dt` s under base acceleration `u` (exact for a constant input).
    fn step(&mut self, u: f64, dt: f64) {
        let c = -self.g * u;
        let qp = c / (self.w * self.w);
        let (s, wd) = (self.z * self.w, self.w * (1.0 - self.z * self.z).sqrt());
        let (e0, v0) = (self.q - qp, self.v);
        let (ex, co, si) = ((-s * dt).exp(), (wd * dt).cos(), (wd * dt).sin());
        self.q = qp + ex * (e0 * co + (v0 + s * e0) / wd * si);
        self.v = ex * (v0 * co - (s * v0 + self.w * self.w * e0) / wd * si);
    }
}

/// Switch times and accelerations of the test's square wave (mm/s²): the phase
/// φ(t) = f0 t + r t²/2 crosses k/2 at t_k; between t_k and t_{k+1} the acceleration is
/// ±60·f(t_k), alternating.
fn test_switches(f0: f64, f1: f64, rate: f64, per_hz: f64) -> Vec<(f64, f64)> {
    let mut out = vec![];
    let mut k = 0u64;
    loop {
        let t = (-f0 + (f0 * f0 + rate * k as f64).sqrt()) / rate;
        let f = f0 + rate * t;
        if f > f1 {
            out.push((t, 0.0));
            return out;
        }
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        out.push((t, sign * per_hz * f));
        k += 1;
    }
}

/// The toolhead's acceleration along the test axis, the chip's mean over each sample interval
/// (mm/s²), at `fs` Hz for the whole test plus 1 s.
fn simulate(fs: f64) -> Vec<f64> {
    let sw = test_switches(5.0, 135.0, 1.0, 60.0);
    let end = sw.last().unwrap().0;
    let mut modes: Vec<Mode> = MODES
        .iter()
        .map(|&(f, z, g)| Mode {
            w: 2.0 * PI * f,
            z,
            g,
            q: 0.0,
            v: 0.0,
        })
        .collect();
    let n = ((end + 1.0) * fs) as usize;
    // j: the test's segment; ks: the sweeping motion's half-period (±400 mm/s², 0.6 s each)
    let (mut t, mut base_v, mut j, mut ks) = (0.0f64, 0.0f64, 0usize, 0u64);
    let (mut last_v, mut out) = (0.0, Vec::with_capacity(n));
    for i in 1..=n {
        let ti = i as f64 / fs;
        while t < ti {
            let next_test = sw.get(j + 1).map_or(f64::INFINITY, |s| s.0);
            let next_sweep = (ks + 1) as f64 * 0.6;
            let next = ti.min(next_test).min(next_sweep);
            let sweeping = match (t < end, ks % 2 == 0) {
                (false, _) => 0.0,
                (true, true) => 400.0,
                (true, false) => -400.0,
            };
            let u = sw[j].1 + sweeping;
            let dt = next - t;
            base_v += u * dt;
            for m in &mut modes {
                m.step(u, dt);
            }
            t = next;
            if next == next_test {
                j += 1;
            }
            if next == next_sweep {
                ks += 1;
            }
        }
        let v = base_v + modes.iter().map(|m| m.v).sum::<f64>();
        out.push((v - last_v) * fs);
        last_v = v;
    }
    out
}

/// Writes the raw file (chip at `nominal_hz`, its clock 0.01 % slow): x the test axis, y 10 % of it (mounting), z gravity + 5 %; noise,
/// quantisation, the chip's clock and the printer's stamps (module docs).
fn write_raw(path: &Path, seed: u64, nominal_hz: f64) {
    let fs_chip = nominal_hz * (1.0 - 1e-4);
    let a = simulate(fs_chip);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut clock = StdRng::seed_from_u64(seed + 1);
    let noise = Normal::new(0.0, 50.0).unwrap();
    let jitter = Normal::new(0.0, 1e-6).unwrap();
    let mut q = |v: f64| ((v + noise.sample(&mut rng)) / LSB_MM_S2).round() * LSB_MM_S2;
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    writeln!(f, "#time,accel_x,accel_y,accel_z").unwrap();
    for (i, &x) in a.iter().enumerate() {
        let (ax, ay, az) = (q(x), q(0.1 * x), q(9806.65 + 0.05 * x));
        let st = 1234.5 + i as f64 / fs_chip + jitter.sample(&mut clock);
        writeln!(f, "{st:.6},{ax:.3},{ay:.3},{az:.3}").unwrap();
    }
}

/// The largest bin of `p` within 5–200 Hz and its half-power band (the first bins outside
/// half its value on each side), Hz.
fn largest_peak(freq: &[f64], p: &[f64]) -> (f64, f64, f64) {
    let k = (0..p.len())
        .filter(|&i| (5.0..=200.0).contains(&freq[i]))
        .max_by(|&a, &b| p[a].total_cmp(&p[b]))
        .unwrap();
    let (mut lo, mut hi) = (k, k);
    while lo > 0 && p[lo] >= 0.5 * p[k] {
        lo -= 1;
    }
    while hi + 1 < p.len() && p[hi] >= 0.5 * p[k] {
        hi += 1;
    }
    (freq[k], freq[lo], freq[hi])
}

/// `s` divided by frequency as Klipper does before it writes a calibration file.
fn normalized(s: &KlipperSpectrum) -> KlipperSpectrum {
    let n = |p: &[f64]| normalize_to_frequencies(&s.freq_hz, p);
    KlipperSpectrum {
        psd_x: n(&s.psd_x),
        psd_y: n(&s.psd_y),
        psd_z: n(&s.psd_z),
        psd_sum: n(&s.psd_sum),
        normalized: true,
        ..s.clone()
    }
}

/// `s` in the resonances layout at full precision (bins below 200 Hz).
fn exact_csv(s: &KlipperSpectrum) -> String {
    let mut out = String::from("freq,psd_x,psd_y,psd_z,psd_xyz\n");
    for i in (0..s.freq_hz.len()).filter(|&i| s.freq_hz[i] < 200.0) {
        out += &format!(
            "{:e},{:e},{:e},{:e},{:e}\n",
            s.freq_hz[i], s.psd_x[i], s.psd_y[i], s.psd_z[i], s.psd_sum[i]
        );
    }
    out
}

#[test]
fn a_raw_resonance_test_file_identifies_and_tunes_like_its_psd_file() {
    let dir = tempfile::tempdir().unwrap();
    let raw_path = dir.path().join("raw_data_x_20260101_000000.csv");
    write_raw(&raw_path, 7, 3200.0);
    let raw = read_raw(&raw_path).unwrap();
    assert!(raw.time_s.len() > 400_000);
    let s = raw_spectrum(&raw).unwrap();
    assert_eq!(
        2 * (s.freq_hz.len() - 1),
        2048,
        "0.5 s at 3.2 kHz: 2048-sample segments"
    );

    // the PSD's largest peak is the resonance (the input's f² growth moves it by O(ζ²))
    let (fpk, f_lo, f_hi) = largest_peak(&s.freq_hz, &s.psd_x);
    assert!(
        f_lo < MODES[0].0 && MODES[0].0 < f_hi,
        "{fpk} ({f_lo}-{f_hi}) Hz"
    );

    // identify: the spectrum path, a mode inside that half-power band
    let id = identify_file(&raw_path, &IdentifyOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(id.path, IdentPath::KlipperPsd, "{}", id.reason);
    assert!(id.reason.contains("swept excitation"), "{}", id.reason);
    let m = id
        .modes
        .iter()
        .find(|m| f_lo < m.freq_hz && m.freq_hz < f_hi)
        .unwrap_or_else(|| panic!("no mode in {f_lo}-{f_hi} Hz: {:?}", id.modes));
    assert!((m.freq_hz / MODES[0].0 - 1.0).abs() < 0.02, "{m:?}");
    // half-power damping, widened by the Kaiser window's own band (2.3 Hz here)
    assert!((m.zeta / MODES[0].1 - 1.0).abs() < 0.3, "{m:?}");
    assert!(id
        .modes
        .iter()
        .any(|m| (m.freq_hz / MODES[1].0 - 1.0).abs() < 0.05));

    same_design_from_its_spectrum_files(dir.path(), &raw_path, &s);
}

/// `tune`'s design from the raw file at `raw_path` against its spectrum `s` written out in `dir`
/// (module docs).
fn same_design_from_its_spectrum_files(dir: &Path, raw_path: &Path, s: &KlipperSpectrum) {
    let (_, _, from_raw) = design_file(raw_path, Objective::default(), VIBRATION_MARGIN).unwrap();
    let cal = normalized(s);
    let fit = FitSpectrum::from_spectrum(&cal);
    let cols: Vec<(String, Vec<f64>)> = from_raw
        .klipper
        .fitted
        .iter()
        .map(|f| {
            let v = worst_response(&f.shaper, &cal.freq_hz);
            (format!("{}({:.1})", f.kind.name(), f.freq_hz), v)
        })
        .collect();
    assert!(fit.freq_hz.len() > 100);
    let cal_path = dir.join("calibration_data_x_20260101_000000.csv");
    std::fs::write(&cal_path, format_spectrum_csv(&cal, &cols)).unwrap();
    let res_path = dir.join("resonances_x_20260101_000000.csv");
    std::fs::write(&res_path, format_spectrum_csv(s, &[])).unwrap();
    let exact_path = dir.join("resonances_exact.csv");
    std::fs::write(&exact_path, exact_csv(s)).unwrap();
    // at full precision the spectrum file gives the raw file's answer exactly
    let (_, _, c) = design_file(&exact_path, Objective::default(), VIBRATION_MARGIN).unwrap();
    let (k, kr) = (&c.klipper.best, &from_raw.klipper.best);
    assert_eq!((k.kind, k.freq_hz), (kr.kind, kr.freq_hz));
    assert_eq!(c.ours.name, from_raw.ours.name);
    assert_eq!(c.ours.metrics, from_raw.ours.metrics);
    // Klipper's files round the bins to 0.1 Hz and the PSDs to 4 digits: near-tied fits (0.2 Hz
    // grid) may trade places, so the same kind within 1 % (two grid steps at 43 Hz), and our
    // design within 1 % smoothing and 0.5 point of vibrations (half the "not worse" margin)
    for p in [&cal_path, &res_path] {
        let (_, _, c) = design_file(p, Objective::default(), VIBRATION_MARGIN).unwrap();
        let (k, kr) = (&c.klipper.best, &from_raw.klipper.best);
        let (o, or) = (&c.ours.metrics, &from_raw.ours.metrics);
        let what = format!(
            "{}: Klipper {} {} Hz vs {} {} Hz; ours {} {:?} vs {} {:?}",
            p.display(),
            k.kind.name(),
            k.freq_hz,
            kr.kind.name(),
            kr.freq_hz,
            c.ours.name,
            o,
            from_raw.ours.name,
            or
        );
        assert!(
            k.kind == kr.kind && (k.freq_hz / kr.freq_hz - 1.0).abs() <= 0.01,
            "{what}"
        );
        assert!(
            (o.smoothing_mm / or.smoothing_mm - 1.0).abs() <= 0.01,
            "{what}"
        );
        assert!((o.vibrations - or.vibrations).abs() <= 0.005, "{what}");
    }
}

#[test]
fn a_lis2dw_rate_file_also_identifies_at_its_psds_largest_peak() {
    // LIS2DW (Klipper's other common chip) at 1.6 kHz: 1024-sample segments, Δf 1.56 Hz
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("raw_data_x_lis2dw_20260101_000000.csv");
    write_raw(&p, 11, 1600.0);
    let s = raw_spectrum(&read_raw(&p).unwrap()).unwrap();
    assert_eq!(2 * (s.freq_hz.len() - 1), 1024);
    let (fpk, f_lo, f_hi) = largest_peak(&s.freq_hz, &s.psd_x);
    let id = identify_file(&p, &IdentifyOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(id.path, IdentPath::KlipperPsd, "{}", id.reason);
    assert!(
        id.modes
            .iter()
            .any(|m| f_lo < m.freq_hz && m.freq_hz < f_hi),
        "{fpk} ({f_lo}-{f_hi}) Hz: {:?}",
        id.modes
    );
}

#[test]
fn a_raw_file_too_short_for_klippers_psd_is_refused_in_words() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("raw_data_x_short.csv");
    let mut text = String::from("#time,accel_x,accel_y,accel_z\n");
    for i in 0..1000 {
        text += &format!("{:.6},1.0,2.0,9806.0\n", i as f64 / 3200.0);
    }
    std::fs::write(&p, text).unwrap();
    let e = design_file(&p, Objective::default(), VIBRATION_MARGIN).unwrap_err();
    assert!(format!("{e:#}").contains("more than one segment"), "{e:#}");
    let e = read_raw(&dir.path().join("missing.csv")).unwrap_err();
    assert!(format!("{e:#}").contains("missing.csv"), "{e:#}");
}
