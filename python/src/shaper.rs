//! `design_shaper` and `Shaper`: `beamtool tune`'s design step, and the firmware core's
//! shaper and run-time engine.

use crate::arrays::{finite_vec_of, positive, to_numpy};
use crate::guard::{run_released, value_error, SignalCheck};
use crate::ident::{PyIdentification, PyMode};
use crate::recording::{PyRecording, PySpectrum, SpectrumData};
use beamshaper::config::Settings;
use beamshaper::engine::NumericPath;
use beamshaper::shaper::{residual_vibration, Shaper};
use beamtools::board::plan::plan_move;
use beamtools::ident::ModeEstimate;
use beamtools::shaping::klipper::FitSpectrum;
use beamtools::shaping::spectrum::{design_for_spectrum, Objective, VIBRATION_MARGIN};
use beamtools::shaping::{choose, settings_with, Candidate, ChoiceRules, RecordedVibration};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A designed input shaper (impulse sequence) and how it was chosen.
#[pyclass(name = "Shaper", module = "beamshaper", frozen)]
#[derive(Clone)]
pub struct PyShaper {
    pub name: String,
    pub shaper: Shaper,
    pub worst_pct: f64,
    pub runners_up: Vec<PyShaper>,
    pub refused_on_recording: Vec<String>,
}

impl PyShaper {
    fn of(c: &Candidate) -> Self {
        PyShaper {
            name: c.name.clone(),
            shaper: c.shaper.clone(),
            worst_pct: c.worst_pct,
            runners_up: vec![],
            refused_on_recording: vec![],
        }
    }
}

#[pymethods]
impl PyShaper {
    /// E.g. ``ZVD(6.055 Hz)`` or ``ZV(1.100 Hz) * EI(6.900 Hz)``.
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }
    /// Shape (n, 2): column 0 ``time_s`` (s, first 0), column 1 ``amplitude`` (sums to 1).
    #[getter]
    fn impulses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rows: Vec<Vec<f64>> = self
            .shaper
            .impulses()
            .iter()
            .map(|i| vec![i.time_s, i.amplitude])
            .collect();
        Ok(PyArray2::from_vec2(py, &rows)?)
    }
    /// Time of the last impulse (s): the delay the shaper adds to a move.
    #[getter]
    fn duration_s(&self) -> f64 {
        self.shaper.duration_s()
    }
    /// Worst-case percentage vibration over the modes' bands (%), or Klipper's remaining
    /// vibrations (%) for a design on a PSD.
    #[getter]
    fn worst_pct(&self) -> f64 {
        self.worst_pct
    }
    /// Feasible longer designs (at most 5, by duration).
    #[getter]
    fn runners_up(&self) -> Vec<PyShaper> {
        self.runners_up.clone()
    }
    /// Shorter designs refused because they leave too much of the recorded vibration.
    #[getter]
    fn refused_on_recording(&self) -> Vec<String> {
        self.refused_on_recording.clone()
    }

    /// Percentage vibration V (%) left at natural frequency ``freq_hz`` (Hz, scalar or
    /// shape (M,)) and damping ratio ``zeta``: 100 · e^{−ζωt_n} √(C² + S²) with
    /// C = Σ Aᵢ e^{ζωtᵢ} cos(ω_d tᵢ), S the same with sin (paper eq. 27; Singer & Seering 1990).
    /// Raises ValueError: freq_hz ≤ 0 or NaN, zeta outside [0, 1).
    fn vibration_pct<'py>(
        &self,
        py: Python<'py>,
        freq_hz: &Bound<'py, PyAny>,
        zeta: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        if !(zeta.is_finite() && (0.0..1.0).contains(&zeta)) {
            return Err(value_error(format!("zeta {zeta}: want 0 <= zeta < 1")));
        }
        let v = |f: f64| -> PyResult<f64> {
            positive("freq_hz", f)?;
            Ok(100.0 * residual_vibration(&self.shaper, f, zeta))
        };
        if let Ok(f) = freq_hz.extract::<f64>() {
            return Ok(v(f)?.into_pyobject(py)?.into_any());
        }
        let f = finite_vec_of("freq_hz", freq_hz)?;
        let out: Vec<f64> = f.into_iter().map(v).collect::<PyResult<_>>()?;
        Ok(to_numpy(py, out).into_any())
    }

    /// ``signal`` (m, shape (N,), one sample per tick at ``rate_hz``) shaped by the firmware
    /// core's run-time engine exactly as the board runs it: the shaper sampled into a tap
    /// table at ``rate_hz``, the signal in nanometre counts, ``path`` ``"fixed"`` (Q2.30
    /// weights, exact unity DC gain) or ``"f32"``; the history starts at ``signal[0]``.
    /// Returns float64 (m), shape (N,). Raises ValueError: empty, NaN, |signal| ≥ 1 m (the
    /// engine's counts are below 2³⁰ nm), ``rate_hz`` ≤ 0, a shaper too long for the history.
    #[pyo3(signature = (signal, rate_hz, path="fixed"))]
    fn apply<'py>(
        &self,
        py: Python<'py>,
        signal: &Bound<'py, PyAny>,
        rate_hz: f64,
        path: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        positive("rate_hz", rate_hz)?;
        let x = finite_vec_of("signal", signal)?;
        if let Some(k) = x.iter().position(|v| v.abs() >= 1.0) {
            return Err(value_error(format!(
                "signal[{k}] = {}: the engine runs on nanometre counts below 2^30 (|signal| < 1 m)",
                x[k]
            )));
        }
        let path = match path {
            "fixed" => NumericPath::Fixed,
            "f32" => NumericPath::F32,
            _ => return Err(value_error(format!("path `{path}`: want fixed or f32"))),
        };
        let s = self.shaper.clone();
        let y = run_released(py, move || {
            beamtools::model::shape_with_engine(&s, rate_hz, &x, path)
        })?;
        Ok(to_numpy(py, y).into_any())
    }

    fn __repr__(&self) -> String {
        format!(
            "Shaper({:?}, {} impulses, {:.4} s, worst {:.3} %)",
            self.name,
            self.shaper.len(),
            self.shaper.duration_s(),
            self.worst_pct
        )
    }
}

/// The modes of `modes`: an `Identification`, a list of `Mode` or of `(freq_hz, zeta)` /
/// `(freq_hz, zeta, freq_hz_std, zeta_std)` tuples.
fn modes_of(modes: &Bound<'_, PyAny>) -> PyResult<Vec<ModeEstimate>> {
    if let Ok(id) = modes.downcast::<PyIdentification>() {
        return Ok(id.get().id.modes.clone());
    }
    let mut out = Vec::new();
    for item in modes.try_iter().map_err(|_| {
        value_error("modes: want an Identification, a list of Mode or of (freq_hz, zeta) tuples")
    })? {
        let item = item?;
        if let Ok(m) = item.downcast::<PyMode>() {
            out.push(m.get().m.clone());
            continue;
        }
        let t: Vec<f64> = item.extract().map_err(|_| {
            value_error(
                "modes: each item a Mode or a tuple (freq_hz, zeta[, freq_hz_std, zeta_std])",
            )
        })?;
        let (f, z, sf, sz) =
            match t[..] {
                [f, z] => (f, z, 0.0, 0.0),
                [f, z, sf, sz] => (f, z, sf, sz),
                _ => return Err(value_error(
                    "modes: each tuple (freq_hz, zeta) or (freq_hz, zeta, freq_hz_std, zeta_std)",
                )),
            };
        let m = PyMode::new(f, z, sf, sz, "given".into())?;
        out.push(m.m);
    }
    if out.is_empty() {
        return Err(value_error(
            "modes is empty: design_shaper needs at least one mode",
        ));
    }
    out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok(out)
}

/// The board plan of `design_shaper(move_mm=…)`: the firmware's default settings with the
/// caller's `board` entries.
#[derive(Clone)]
struct BoardMove {
    settings: Settings,
    move_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
}

/// `tune`'s design step on `modes` (documented in `beamshaper/__init__.py`).
fn design_modes(
    modes: &[ModeEstimate],
    tolerance_pct: f64,
    min_band_pct: f64,
    recorded: Option<&RecordedVibration>,
    board: Option<BoardMove>,
) -> anyhow::Result<PyShaper> {
    let window_s = (6.0 / modes[0].freq_hz).clamp(2.0, 20.0);
    let rules = ChoiceRules {
        tolerance_pct,
        min_band: min_band_pct / 100.0,
        recorded,
        window_s,
    };
    let runs = |c: &Candidate| -> Result<(), String> {
        let Some(b) = &board else { return Ok(()) };
        let s = settings_with(&b.settings, c);
        plan_move(&s, 0.0, b.move_mm, b.speed_mm_s, b.accel_mm_s2, window_s)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    let choice = choose(modes, &rules, runs)?;
    let mut best = PyShaper::of(&choice.best);
    best.runners_up = choice.runners_up.iter().map(PyShaper::of).collect();
    best.refused_on_recording = choice.refused_on_recording;
    Ok(best)
}

/// Our design on a Klipper PSD, Klipper's recommendation as the runner-up.
fn design_spectrum(s: &beamtools::recording::psd::KlipperSpectrum) -> anyhow::Result<PyShaper> {
    let fit = FitSpectrum::from_spectrum(s);
    if fit.freq_hz.len() < 3 {
        anyhow::bail!("the spectrum has fewer than 3 bins at or below 200 Hz");
    }
    let c = design_for_spectrum(&fit, Objective::default(), VIBRATION_MARGIN);
    let mut best = PyShaper::of(&beamtools::tune::spectrum::candidate(&c));
    let k = &c.klipper.best;
    best.runners_up.push(PyShaper {
        name: format!("{} {:.1} Hz (Klipper's)", k.kind.name(), k.freq_hz),
        shaper: k.shaper.clone(),
        worst_pct: 100.0 * k.vibrations,
        runners_up: vec![],
        refused_on_recording: vec![],
    });
    Ok(best)
}

/// The firmware's default settings with `board`'s `tick_rate_hz`, `step_nm`,
/// `max_step_rate_hz` (integers). Errors: another key, a value the firmware refuses.
fn board_settings(board: Option<&Bound<'_, PyDict>>) -> PyResult<Settings> {
    let mut s = Settings::default();
    for (k, v) in board.into_iter().flat_map(|d| d.iter()) {
        let key: String = k.extract()?;
        let v: u32 = v
            .extract()
            .map_err(|_| value_error(format!("board[{key:?}]: want an integer >= 0")))?;
        match key.as_str() {
            "tick_rate_hz" => s.tick_rate_hz = v,
            "step_nm" => s.step_nm = v,
            "max_step_rate_hz" => s.max_step_rate_hz = v,
            _ => {
                return Err(value_error(format!(
                    "board: unknown setting `{key}` (tick_rate_hz, step_nm, max_step_rate_hz)"
                )))
            }
        }
    }
    s.validate()
        .map_err(|e| value_error(format!("board: the firmware refuses these settings: {e:?}")))?;
    Ok(s)
}

/// The recorded free vibration of `rec` for the model-free check.
fn recorded_of(
    rec: &PyRecording,
    signal: Option<&str>,
    modes: &[ModeEstimate],
) -> PyResult<RecordedVibration> {
    let acceleration = match signal {
        None => rec.from_npy,
        Some("position") => false,
        Some("acceleration") => true,
        Some(s) => {
            return Err(value_error(format!(
                "signal `{s}`: want position or acceleration"
            )))
        }
    };
    let fv = beamtools::tune::recorded::free_vibration_of(&rec.rec).map_err(value_error)?;
    let f_max = modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max);
    Ok(beamtools::tune::recorded::recorded_position(
        fv,
        acceleration,
        modes[0].freq_hz,
        f_max,
    ))
}

/// Designs the shortest robust shaper (documented in `beamshaper/__init__.py`).
#[pyfunction]
#[pyo3(signature = (modes, tolerance_pct=2.0, min_band_pct=2.0, recording=None, signal=None, move_mm=None, speed_mm_s=150.0, accel_mm_s2=2000.0, board=None))]
#[allow(clippy::too_many_arguments)]
pub fn design_shaper(
    py: Python<'_>,
    modes: &Bound<'_, PyAny>,
    tolerance_pct: f64,
    min_band_pct: f64,
    recording: Option<PyRef<'_, PyRecording>>,
    signal: Option<&str>,
    move_mm: Option<f64>,
    speed_mm_s: f64,
    accel_mm_s2: f64,
    board: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyShaper> {
    if let Ok(s) = modes.downcast::<PySpectrum>() {
        let SpectrumData::Klipper(k) = &s.get().data else {
            return Err(value_error("a magnitude spectrum (.lvm): identify it first, then design_shaper(identification)"));
        };
        let k = k.clone();
        return run_released(py, move || design_spectrum(&k));
    }
    if !(tolerance_pct.is_finite() && (0.2..=50.0).contains(&tolerance_pct)) {
        return Err(value_error(format!(
            "tolerance_pct {tolerance_pct}: want 0.2..=50"
        )));
    }
    if !(min_band_pct.is_finite() && (0.0..=50.0).contains(&min_band_pct)) {
        return Err(value_error(format!(
            "min_band_pct {min_band_pct}: want 0..=50"
        )));
    }
    let modes = modes_of(modes)?;
    let recorded = recording
        .map(|r| recorded_of(&r, signal, &modes))
        .transpose()?;
    let board = match move_mm {
        None => None,
        Some(m) if m.is_finite() && m != 0.0 => Some(BoardMove {
            settings: board_settings(board)?,
            move_mm: m,
            speed_mm_s: positive("speed_mm_s", speed_mm_s)?,
            accel_mm_s2: positive("accel_mm_s2", accel_mm_s2)?,
        }),
        Some(m) => {
            return Err(value_error(format!(
                "move_mm {m}: want a finite non-zero move"
            )))
        }
    };
    let mut check = SignalCheck::new();
    run_released(py, move || {
        check.poll();
        design_modes(
            &modes,
            tolerance_pct,
            min_band_pct,
            recorded.as_ref(),
            board,
        )
    })
}
