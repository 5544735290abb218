//! `identify`, `Identification` and `Mode`: the CLI's `beamtool identify` in-process.

use crate::arrays::{json_to_py, to_numpy};
use crate::guard::{run_released, value_error, SignalCheck};
use crate::recording::{PyRecording, PySpectrum, SpectrumData};
use beamtools::ident::freedecay::FreeDecayOptions;
use beamtools::ident::frf::{InputChannel, OutputChannel, Window};
use beamtools::ident::identify_paths::identify_spectrum_file;
use beamtools::ident::{
    identify as identify_recording, IdentOptions, Identification, IdentifyOptions, Method,
    ModeEstimate, PathChoice,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// One identified mode (natural frequency, damping ratio, their 1-σ, how it was found).
#[pyclass(name = "Mode", module = "beamshaper", frozen)]
#[derive(Clone)]
pub struct PyMode {
    pub m: ModeEstimate,
}

#[pymethods]
impl PyMode {
    #[new]
    #[pyo3(signature = (freq_hz, zeta, freq_hz_std=0.0, zeta_std=0.0, method="given".to_string()))]
    pub fn new(
        freq_hz: f64,
        zeta: f64,
        freq_hz_std: f64,
        zeta_std: f64,
        method: String,
    ) -> PyResult<Self> {
        crate::arrays::positive("freq_hz", freq_hz)?;
        if !(zeta.is_finite() && (0.0..1.0).contains(&zeta)) {
            return Err(value_error(format!("zeta {zeta}: want 0 <= zeta < 1")));
        }
        if !(freq_hz_std.is_finite()
            && freq_hz_std >= 0.0
            && zeta_std.is_finite()
            && zeta_std >= 0.0)
        {
            return Err(value_error(
                "freq_hz_std and zeta_std: want finite numbers >= 0",
            ));
        }
        let m = ModeEstimate {
            freq_hz,
            zeta,
            freq_hz_std,
            zeta_std,
            method,
        };
        Ok(PyMode { m })
    }
    #[getter]
    fn freq_hz(&self) -> f64 {
        self.m.freq_hz
    }
    #[getter]
    fn zeta(&self) -> f64 {
        self.m.zeta
    }
    #[getter]
    fn freq_hz_std(&self) -> f64 {
        self.m.freq_hz_std
    }
    #[getter]
    fn zeta_std(&self) -> f64 {
        self.m.zeta_std
    }
    #[getter]
    fn method(&self) -> String {
        self.m.method.clone()
    }
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.m)
    }
    fn __repr__(&self) -> String {
        let m = &self.m;
        format!(
            "Mode(freq_hz={:.6} ± {:.2e}, zeta={:.6} ± {:.2e}, method={:?})",
            m.freq_hz, m.freq_hz_std, m.zeta, m.zeta_std, m.method
        )
    }
}

/// The result of `identify`.
#[pyclass(name = "Identification", module = "beamshaper", frozen)]
pub struct PyIdentification {
    pub id: Identification,
}

#[pymethods]
impl PyIdentification {
    /// Physical modes, ascending in frequency.
    #[getter]
    fn modes(&self) -> Vec<PyMode> {
        self.id
            .modes
            .iter()
            .map(|m| PyMode { m: m.clone() })
            .collect()
    }
    /// The path taken (``free decay``, ``FRF (input/output)``, …).
    #[getter]
    fn path(&self) -> String {
        self.id.path.to_string()
    }
    /// Why this path, and what it used.
    #[getter]
    fn reason(&self) -> String {
        self.id.reason.clone()
    }
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.id.warnings.clone()
    }
    /// Estimates that are not physical modes, with the reason.
    #[getter]
    fn rejected(&self) -> Vec<(PyMode, String)> {
        let r = self.id.rejected.iter();
        r.map(|r| (PyMode { m: r.mode.clone() }, r.reason.clone()))
            .collect()
    }
    /// Rayleigh α1 (1/s), α2 (s) of the first two modes (paper eq. 22).
    #[getter]
    fn rayleigh(&self) -> Option<(f64, f64)> {
        self.id.rayleigh
    }
    /// Time span used (s).
    #[getter]
    fn span_s(&self) -> (f64, f64) {
        self.id.span_s
    }
    #[getter]
    fn sample_rate_hz(&self) -> f64 {
        self.id.sample_rate_hz
    }
    /// The CLI's ``identify --json`` as Python objects.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.id)
    }
    /// FRF path: ``{"diagram": {method, orders: [{order, poles: [[{freq_hz, zeta}, label]]}],
    /// modes}, "freq_hz": (M,), "h1_abs": (M,), "band_hz": (lo, hi)}``; ``None`` otherwise.
    fn stabilisation<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some((r, frf)) = &self.id.frf_result else {
            return Ok(None);
        };
        let Some(d) = r.methods.iter().find_map(|m| m.diagram.as_ref()) else {
            return Ok(None);
        };
        let out = PyDict::new(py);
        out.set_item("diagram", json_to_py(py, d)?)?;
        out.set_item("freq_hz", to_numpy(py, frf.freq_hz.clone()))?;
        let mag: Vec<f64> = frf.h1.iter().map(|c| c.norm()).collect();
        out.set_item("h1_abs", to_numpy(py, mag))?;
        out.set_item("band_hz", r.band_hz)?;
        Ok(Some(out))
    }
    fn __repr__(&self) -> String {
        let f: Vec<String> = self
            .id
            .modes
            .iter()
            .map(|m| format!("{:.4} Hz", m.freq_hz))
            .collect();
        format!(
            "Identification(path={:?}, modes=[{}])",
            self.path(),
            f.join(", ")
        )
    }
}

/// The CLI's `identify` options (`identify_options_of` with the given values).
fn options(
    f_min_hz: f64,
    f_max_hz: f64,
    path: &str,
    method: &str,
    band_hz: Option<(f64, f64)>,
    n_modes: Option<usize>,
) -> anyhow::Result<IdentifyOptions> {
    for (name, v) in [("f_min_hz", f_min_hz), ("f_max_hz", f_max_hz)] {
        if !v.is_finite() || v < 0.0 {
            anyhow::bail!("{name} {v}: want a finite frequency >= 0 Hz");
        }
    }
    if f_max_hz <= f_min_hz {
        anyhow::bail!("f_max_hz {f_max_hz} must exceed f_min_hz {f_min_hz}");
    }
    let mut frf = IdentOptions {
        methods: Method::parse_list(method)?,
        input: InputChannel::from_name("accel")?,
        output: OutputChannel::from_name("deflection")?,
        band_hz,
        n_modes,
        ..Default::default()
    };
    frf.welch.window = Window::from_name("rect")?;
    Ok(IdentifyOptions {
        path: PathChoice::from_name(path)?,
        frf,
        decay: FreeDecayOptions {
            f_min_hz,
            f_max_hz,
            ..Default::default()
        },
        ..Default::default()
    })
}

/// Identifies the modes of a recording or `.lvm` magnitude spectrum (documented in `beamshaper/__init__.py`).
#[pyfunction]
#[pyo3(signature = (recording, f_min_hz=None, f_max_hz=None, path="auto", method="lscf", band_hz=None, n_modes=None))]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    recording: &Bound<'_, PyAny>,
    f_min_hz: Option<f64>,
    f_max_hz: Option<f64>,
    path: &str,
    method: &str,
    band_hz: Option<(f64, f64)>,
    n_modes: Option<usize>,
) -> PyResult<PyIdentification> {
    let (lo, hi) = (f_min_hz.unwrap_or(0.2), f_max_hz.unwrap_or(500.0));
    let opts = options(lo, hi, path, method, band_hz, n_modes).map_err(crate::guard::to_py)?;
    if let Ok(s) = recording.downcast::<PySpectrum>() {
        let s = s.get().clone();
        let SpectrumData::Magnitude(_) = s.data else {
            return Err(value_error(
                "a Klipper PSD holds no phase and no time signal: pass it to design_shaper (Klipper's shaper fit), not identify",
            ));
        };
        let id = run_released(py, move || identify_spectrum_file(&s.path, &opts))?;
        return Ok(PyIdentification { id });
    }
    let pyrec = recording.downcast::<PyRecording>().map_err(|_| {
        value_error(
            "identify wants a Recording or a Spectrum (read_recording, Recording.from_arrays)",
        )
    })?;
    if let Some((file, read)) = pyrec.get().klipper_raw.clone() {
        // a Klipper raw file: the CLI's own entry point, so a resonance test's sweep takes the
        // peaks of Klipper's PSD as `beamtool identify FILE` does
        let opts = IdentifyOptions { read, ..opts };
        let mut check = SignalCheck::new();
        let id = run_released(py, move || {
            beamtools::ident::identify::identify_file(&file, &opts, &mut |_| check.poll())
        })?;
        return Ok(PyIdentification { id });
    }
    let rec = pyrec.get().rec.clone();
    let mut check = SignalCheck::new();
    let id = run_released(py, move || {
        let mut id = identify_recording(&rec, &opts, &mut |_| check.poll())?;
        // what reading noted heads the warnings, as `identify_file` does
        id.warnings.splice(0..0, rec.notes.iter().cloned());
        Ok(id)
    })?;
    Ok(PyIdentification { id })
}
