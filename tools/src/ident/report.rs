//! Human-readable tables and SVG plots of identification results (JSON is serde of
//! [`IdentResult`]).

use super::frf::Frf;
use super::pipeline::IdentResult;
use super::ModeEstimate;
use crate::plot::{lines_svg, Series};
use anyhow::Result;
use std::fmt::Write;

/// An [`super::Identification`] as text: path and reason, the modes (f, ζ with 1-σ, at a
/// precision matched to the σ), rejected estimates, Rayleigh coefficients, warnings.
pub fn identification_table(id: &super::Identification) -> String {
    use crate::recording::fmt_sig;
    let mut s = String::new();
    let _ = writeln!(s, "path: {} — {}", id.path, id.reason);
    if id.sample_rate_hz.is_finite() {
        let _ = writeln!(
            s,
            "used {}..{} s at {} Hz",
            fmt_sig(id.span_s.0, 4),
            fmt_sig(id.span_s.1, 4),
            fmt_sig(id.sample_rate_hz, 5)
        );
    }
    mode_rows(&mut s, &id.modes);
    for r in &id.rejected {
        let _ = writeln!(
            s,
            "  rejected {} Hz (zeta {}): {}",
            fmt_sig(r.mode.freq_hz, 5),
            fmt_sig(r.mode.zeta, 3),
            r.reason
        );
    }
    if let Some((a1, a2)) = id.rayleigh {
        let _ = writeln!(
            s,
            "Rayleigh damping from modes 1-2 (eq. 22): alpha1 = {} 1/s, alpha2 = {} s",
            fmt_sig(a1, 4),
            fmt_sig(a2, 4)
        );
    }
    for w in &id.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    s
}

/// The mode table: a header, then one row per mode (natural frequency in Hz, damping ratio,
/// each with its 1-σ, and the method that gave it).
fn mode_rows(s: &mut String, modes: &[ModeEstimate]) {
    let _ = writeln!(
        s,
        "{:>4} {:>10} {:>9} {:>9} {:>9}  {}",
        "mode", "f (Hz)", "+-1sd", "zeta", "+-1sd", "method"
    );
    for (i, m) in modes.iter().enumerate() {
        let _ = writeln!(
            s,
            "{:>4} {:>10.4} {:>9.4} {:>9.5} {:>9.5}  {}",
            i + 1,
            m.freq_hz,
            m.freq_hz_std,
            m.zeta,
            m.zeta_std,
            m.method
        );
    }
}

/// The result as a table: combined modes, then each method, Rayleigh coefficients, warnings.
pub fn table(r: &IdentResult) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "FRF: {} -> {}", r.input, r.output);
    if r.df_hz.is_finite() {
        let _ = writeln!(
            s,
            "band {:.3}..{:.3} Hz, line spacing {:.5} Hz, {} average(s)",
            r.band_hz.0, r.band_hz.1, r.df_hz, r.n_averages
        );
    }
    mode_rows(&mut s, &r.modes);
    if r.methods.len() > 1 {
        let _ = writeln!(s, "per method:");
        for mr in &r.methods {
            let v: Vec<String> = mr
                .modes
                .iter()
                .map(|m| format!("{:.4} Hz / {:.5}", m.freq_hz, m.zeta))
                .collect();
            let _ = writeln!(
                s,
                "  {:>6}: {}",
                mr.method.name(),
                if v.is_empty() {
                    "no mode".into()
                } else {
                    v.join(", ")
                }
            );
        }
    }
    if let Some((a1, a2)) = r.rayleigh {
        let _ = writeln!(
            s,
            "Rayleigh damping from modes 1-2 (eq. 22): alpha1 = {a1:.5e} 1/s, alpha2 = {a2:.5e} s"
        );
    }
    for w in &r.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    s
}

/// |H1|, |H2| (log scale) and the coherence of `frf` in `f_lo..=f_hi` as two SVG documents.
pub fn frf_svgs(frf: &Frf, f_lo: f64, f_hi: f64) -> Result<(String, String)> {
    let band = frf.band(f_lo, f_hi);
    let f = &frf.freq_hz[band.clone()];
    let h1: Vec<f64> = frf.h1[band.clone()].iter().map(|c| c.norm()).collect();
    let h2: Vec<f64> = frf.h2[band.clone()].iter().map(|c| c.norm()).collect();
    let title = format!("FRF {} -> {}", frf.input, frf.output);
    let mags = [
        Series {
            label: "|H1|".into(),
            x: f,
            y: &h1,
        },
        Series {
            label: "|H2|".into(),
            x: f,
            y: &h2,
        },
    ];
    let frf_svg = lines_svg(&title, "frequency (Hz)", "|H|", &mags, true)?;
    let coh = [Series {
        label: "coherence".into(),
        x: f,
        y: &frf.coherence[band],
    }];
    let title = format!("coherence ({} averages)", frf.n_averages);
    let coh_svg = lines_svg(&title, "frequency (Hz)", "gamma^2", &coh, false)?;
    Ok((frf_svg, coh_svg))
}
