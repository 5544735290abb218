//! Choosing the shortest robust shaper over the core's designs.
//!
//! Every shaper kind of [`beamshaper::shaper`] for mode 1 alone, and for modes 1 + 2 by
//! convolution (paper §4), is scored by its **worst-case percentage vibration** V (paper
//! eq. 27, `residual_vibration`) over the uncertainty band of every identified mode:
//! f ∈ f̂·[1 − b, 1 + b] with b = max(2σ_f/f̂, `min_band`), ζ ∈ [ζ̂ − 2σ_ζ, ζ̂ + 2σ_ζ]. The
//! shortest candidate whose worst case is within the tolerance and that the board can run
//! (tap table fits its history at its tick rate) wins. The core's `shaper` module stays the
//! one place that designs and convolves; this module only designs through it and ranks.

pub mod klipper;
pub mod spectrum;

use crate::ident::ModeEstimate;
use beamshaper::config::{ModeSetting, Settings};
use beamshaper::shaper::{design, residual_vibration, Shaper, ShaperKind};

/// A candidate: one core shaper design per shaped mode, and their convolution.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// Description, e.g. `ZVD(1.100 Hz) * EI(6.900 Hz)`.
    pub name: String,
    /// The mode settings that program it (slot 1, 2, …).
    pub modes: Vec<ModeSetting>,
    /// The combined shaper.
    pub shaper: Shaper,
    /// Worst-case percentage vibration over the bands of all modes (%).
    pub worst_pct: f64,
}

/// One checked band: the frequency interval (Hz) and damping interval of a mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    /// Frequency interval (Hz).
    pub freq_hz: (f64, f64),
    /// Damping-ratio interval.
    pub zeta: (f64, f64),
}

/// The band checked for mode `m` (see the module docs). `min_band` is a fraction (0.02 = 2 %).
pub fn band(m: &ModeEstimate, min_band: f64) -> Band {
    let half = (2.0 * m.freq_hz_std / m.freq_hz).max(min_band);
    Band {
        freq_hz: (m.freq_hz * (1.0 - half), m.freq_hz * (1.0 + half)),
        zeta: (
            (m.zeta - 2.0 * m.zeta_std).max(0.0),
            (m.zeta + 2.0 * m.zeta_std).min(0.99),
        ),
    }
}

/// Worst V (%) of `s` over the bands of `modes` (61 frequencies × 3 damping ratios each).
pub fn worst_case_pct(s: &Shaper, modes: &[ModeEstimate], min_band: f64) -> f64 {
    let mut worst = 0.0f64;
    for m in modes {
        let b = band(m, min_band);
        for i in 0..=60 {
            let f = b.freq_hz.0 + (b.freq_hz.1 - b.freq_hz.0) * i as f64 / 60.0;
            for z in [b.zeta.0, m.zeta, b.zeta.1] {
                worst = worst.max(100.0 * residual_vibration(s, f, z));
            }
        }
    }
    worst
}

/// All candidates (mode 1 alone; modes 1 and 2), sorted by duration then worst case.
/// `v_tol` (fraction) is the EI kinds' design tolerance. Errors: none; kinds the core
/// cannot design at these modes are skipped.
pub fn candidates(modes: &[ModeEstimate], v_tol: f64, min_band: f64) -> Vec<Candidate> {
    let mut out = Vec::new();
    let kinds = ShaperKind::all(v_tol.clamp(0.01, 0.2));
    let setting = |kind: ShaperKind, m: &ModeEstimate| ModeSetting {
        kind,
        freq_hz: m.freq_hz,
        zeta: m.zeta,
    };
    let label = |k: ShaperKind, f: f64| format!("{}({f:.3} Hz)", k.name().to_uppercase());
    let Some(m1) = modes.first() else {
        return out;
    };
    for &k1 in &kinds {
        let Ok(s1) = design(k1, m1.freq_hz, m1.zeta) else {
            continue;
        };
        out.push(Candidate {
            name: label(k1, m1.freq_hz),
            modes: vec![setting(k1, m1)],
            worst_pct: worst_case_pct(&s1, modes, min_band),
            shaper: s1.clone(),
        });
        let Some(m2) = modes.get(1) else { continue };
        for &k2 in &kinds {
            let Ok(s2) = design(k2, m2.freq_hz, m2.zeta) else {
                continue;
            };
            let Ok(s) = s1.convolve(&s2) else { continue };
            out.push(Candidate {
                name: format!("{} * {}", label(k1, m1.freq_hz), label(k2, m2.freq_hz)),
                modes: vec![setting(k1, m1), setting(k2, m2)],
                worst_pct: worst_case_pct(&s, modes, min_band),
                shaper: s,
            });
        }
    }
    out.sort_by(|a, b| {
        a.shaper
            .duration_s()
            .total_cmp(&b.shaper.duration_s())
            .then(a.worst_pct.total_cmp(&b.worst_pct))
    });
    out
}

pub use crate::measures::RecordedVibration;

/// Percentage vibration (%) shaper `s` leaves on a recorded free vibration by superposition
/// (model-free; [`crate::measures::superposed_check`] over windows of `window_s`, windows
/// whose noise or quantisation cannot resolve half of `tolerance_pct` left out). `None`
/// when no window qualifies ([`superposed_check`] says why).
pub fn superposed_pct(
    rec: &RecordedVibration,
    s: &Shaper,
    window_s: f64,
    tolerance_pct: f64,
) -> Option<f64> {
    superposed_check(rec, s, window_s, tolerance_pct).pct
}

/// [`superposed_pct`] with what the check found when no window resolves the tolerance.
pub fn superposed_check(
    rec: &RecordedVibration,
    s: &Shaper,
    window_s: f64,
    tolerance_pct: f64,
) -> crate::measures::SuperposedCheck {
    crate::measures::superposed_check(rec, s, window_s, tolerance_pct / 2.0)
}

/// What the chosen shaper must satisfy.
#[derive(Clone, Copy, Debug)]
pub struct ChoiceRules<'a> {
    /// Percentage-vibration tolerance (%), over the whole band and on the recording.
    pub tolerance_pct: f64,
    /// Minimum half-width of the checked frequency band (fraction).
    pub min_band: f64,
    /// The user's recorded free vibration, when the input holds one.
    pub recorded: Option<&'a RecordedVibration>,
    /// Settling window of the superposition check (s).
    pub window_s: f64,
}

/// The chosen candidate with what the caller's feasibility check returned for it (e.g. the
/// planned move), the feasible runners-up (at most 5, by duration), and the shorter
/// candidates refused because they leave more than the tolerance of the recorded vibration.
pub struct Choice<T> {
    /// Winner.
    pub best: Candidate,
    /// The feasibility check's value for the winner.
    pub best_runs: T,
    /// Feasible runners-up.
    pub runners_up: Vec<Candidate>,
    /// `"<name>: leaves <p> % of the recorded vibration"`, for candidates shorter than the winner.
    pub refused_on_recording: Vec<String>,
}

/// No candidate satisfied the rules.
#[derive(Debug, thiserror::Error)]
#[error("no shaper keeps the percentage vibration under {tolerance_pct} % over the band and runs on this board{}", why_text(.why))]
pub struct NoShaperFits {
    /// The tolerance (%).
    pub tolerance_pct: f64,
    /// Why the first refused candidates were refused (at most 3).
    pub why: Vec<String>,
}

fn why_text(why: &[String]) -> String {
    match why.is_empty() {
        true => "; loosen --tolerance-pct".to_string(),
        false => format!(":\n  {}", why.join("\n  ")),
    }
}

/// The shortest candidate ([`candidates`]) whose worst case over the band is within the
/// tolerance, that leaves the recorded vibration (if any) within it too, and for which `runs`
/// (the board's feasibility, e.g. planning its verification move) succeeds.
/// Errors: [`NoShaperFits`] with the first three reasons.
pub fn choose<T>(
    modes: &[ModeEstimate],
    rules: &ChoiceRules,
    mut runs: impl FnMut(&Candidate) -> Result<T, String>,
) -> Result<Choice<T>, NoShaperFits> {
    let tol = rules.tolerance_pct;
    let (mut feasible, mut why, mut refused_on_recording) = (Vec::new(), Vec::new(), Vec::new());
    for c in candidates(modes, tol / 100.0, rules.min_band) {
        if c.worst_pct > tol {
            continue;
        }
        let on_recording = rules
            .recorded
            .and_then(|r| superposed_pct(r, &c.shaper, rules.window_s, tol));
        if let Some(p) = on_recording.filter(|&p| p > tol) {
            let line = format!("{}: leaves {p:.2} % of the recorded vibration", c.name);
            if feasible.is_empty() {
                refused_on_recording.push(line.clone());
            }
            why.push(line);
            continue;
        }
        match runs(&c) {
            Ok(p) => feasible.push((c, p)),
            Err(e) => why.push(format!("{}: {e}", c.name)),
        }
    }
    if feasible.is_empty() {
        why.truncate(3);
        return Err(NoShaperFits {
            tolerance_pct: tol,
            why,
        });
    }
    let (best, best_runs) = feasible.remove(0);
    Ok(Choice {
        best,
        best_runs,
        runners_up: feasible.into_iter().take(5).map(|(c, _)| c).collect(),
        refused_on_recording,
    })
}

/// The board settings `base` with the candidate's modes in slots 1.. and shaping on.
pub fn settings_with(base: &Settings, c: &Candidate) -> Settings {
    let mut s = base.clone();
    s.modes = [None; beamshaper::config::MAX_MODES];
    for (slot, m) in s.modes.iter_mut().zip(&c.modes) {
        *slot = Some(*m);
    }
    s.custom.clear();
    s.shaping_enabled = true;
    s
}

/// V(f) (%) of `s` at damping `zeta` for each frequency of `freqs_hz`.
pub fn sensitivity(s: &Shaper, freqs_hz: &[f64], zeta: f64) -> Vec<f64> {
    freqs_hz
        .iter()
        .map(|&f| 100.0 * residual_vibration(s, f, zeta))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(f: f64, sf: f64) -> ModeEstimate {
        ModeEstimate {
            freq_hz: f,
            zeta: 0.0074,
            freq_hz_std: sf,
            zeta_std: 0.0005,
            method: "test".into(),
        }
    }

    #[test]
    fn shortest_candidate_meets_its_worst_case_and_is_sorted() {
        let modes = [m(1.1, 0.001), m(6.9, 0.01)];
        let c = candidates(&modes, 0.02, 0.02);
        assert!(c
            .windows(2)
            .all(|w| w[0].shaper.duration_s() <= w[1].shaper.duration_s()));
        let best = c.iter().find(|c| c.worst_pct <= 2.0).unwrap();
        assert_eq!(best.modes.len(), 2, "{}", best.name);
        // The worst case is attained somewhere in the band, and V at the nominal is smaller.
        assert!(100.0 * residual_vibration(&best.shaper, 1.1, 0.0074) <= best.worst_pct);
    }

    /// A free decay at `f_hz` (ζ 0.005), 40 s at 100 Hz.
    fn decay(f_hz: f64) -> RecordedVibration {
        let dt = 0.01;
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let position_m = (0..4000)
            .map(|k| {
                let t = k as f64 * dt;
                1e-3 * (-0.005 * w * t).exp() * (w * t).cos()
            })
            .collect();
        RecordedVibration {
            position_m,
            dt_s: dt,
            quantum_m: 0.0,
            content_hz: f_hz,
            lowest_hz: f_hz,
            note: None,
        }
    }

    #[test]
    fn choose_takes_the_shortest_that_the_board_runs_and_the_recording_agrees_with() {
        let modes = [m(1.1, 0.001), m(6.9, 0.01)];
        let all: Vec<_> = candidates(&modes, 0.02, 0.02)
            .into_iter()
            .filter(|c| c.worst_pct <= 2.0)
            .collect();
        let rules = ChoiceRules {
            tolerance_pct: 2.0,
            min_band: 0.02,
            recorded: None,
            window_s: 5.0,
        };
        // The board refuses the shortest feasible one: the next is chosen, and `runs`' value
        // comes with it.
        let first = all[0].name.clone();
        let c = choose(&modes, &rules, |c| match c.name == first {
            true => Err("too fast".to_string()),
            false => Ok(c.shaper.len()),
        })
        .unwrap();
        assert_eq!(c.best.name, all[1].name);
        assert_eq!(c.best_runs, all[1].shaper.len());
        assert!(c.runners_up.len() <= 5);
        // Nothing runs: the error names the first reasons.
        let e = choose(&modes, &rules, |_| Err::<(), _>("no".to_string()))
            .err()
            .unwrap();
        assert_eq!(e.why.len(), 3);
        assert!(e.to_string().contains(": no"), "{e}");
    }

    #[test]
    fn a_recorded_vibration_at_another_frequency_refuses_the_short_shapers() {
        // The recording rings at 1.3 Hz, the modes say 1.1 Hz: the short 1.1 Hz shapers leave
        // too much of it and are refused with the percentage named; a longer, more robust one
        // that leaves the recording within the tolerance is chosen.
        let modes = [m(1.1, 0.001)];
        let rec = decay(1.3);
        let rules = ChoiceRules {
            tolerance_pct: 2.0,
            min_band: 0.02,
            recorded: Some(&rec),
            window_s: 5.0,
        };
        let c = choose(&modes, &rules, |_| Ok(())).unwrap();
        assert!(!c.refused_on_recording.is_empty());
        assert!(c
            .refused_on_recording
            .iter()
            .all(|w| w.contains("of the recorded vibration")));
        assert!(superposed_pct(&rec, &c.best.shaper, 5.0, 2.0).unwrap() <= 2.0);
        let without = ChoiceRules {
            recorded: None,
            ..rules
        };
        let shortest = choose(&modes, &without, |_| Ok(())).unwrap().best;
        assert!(c.best.shaper.duration_s() > shortest.shaper.duration_s());
        // The recording at the identified frequency lets the shortest one through.
        let rec = decay(1.1);
        let at_mode = ChoiceRules {
            recorded: Some(&rec),
            ..rules
        };
        let c = choose(&modes, &at_mode, |_| Ok(())).unwrap();
        assert_eq!(c.best.name, shortest.name);
        assert!(c.refused_on_recording.is_empty());
    }
}
