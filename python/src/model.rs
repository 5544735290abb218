//! `Rig` and `simulate`: the beam-on-moving-base model of the paper's §2.

use crate::arrays::{finite_vec_of, json_to_py, positive};
use crate::guard::{run_released, value_error};
use crate::recording::PyRecording;
use beamtools::model::sim::BaseMotionSim;
use beamtools::model::{BeamModel, ModelOptions, Rig};
use pyo3::prelude::*;
use std::path::PathBuf;

/// A rig file (TOML): the beam, its base and sensors.
#[pyclass(name = "Rig", module = "beamshaper", frozen)]
pub struct PyRig {
    pub rig: Rig,
    pub path: Option<PathBuf>,
}

/// The model of `rig` with `n` basis functions.
fn model(rig: &Rig, n: usize) -> anyhow::Result<BeamModel> {
    if !(1..=20).contains(&n) {
        anyhow::bail!("n_modes {n}: want 1..=20 basis functions");
    }
    BeamModel::new(
        rig,
        &ModelOptions {
            n_modes: n,
            ..Default::default()
        },
    )
}

#[pymethods]
impl PyRig {
    /// Raises OSError (unreadable), ValueError (invalid TOML or parameters).
    #[staticmethod]
    fn from_toml(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let p = path.clone();
        let rig = run_released(py, move || Rig::from_toml_file(&p))?;
        Ok(PyRig {
            rig,
            path: Some(path),
        })
    }

    #[staticmethod]
    fn from_toml_str(text: &str) -> PyResult<Self> {
        let rig = Rig::from_toml_str(text).map_err(crate::guard::to_py)?;
        Ok(PyRig { rig, path: None })
    }

    /// ``beamtool modes --json``: ``beam_mass_kg``, Rayleigh ``rayleigh_alpha1_per_s`` /
    /// ``rayleigh_alpha2_s`` and per mode ``freq_hz_clamped_base``, ``freq_hz_free_base``
    /// (Hz), ``damping_ratio``, ``participation_kg_sqrt``, ``tip_per_modal_coordinate``, from
    /// the Galerkin model with ``n`` basis functions (paper eqs. 10–24).
    #[pyo3(signature = (n=6))]
    fn modes<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, PyAny>> {
        let rig = self.rig.clone();
        let v = run_released(py, move || {
            beamtools::model::modes_report::modes_report(&model(&rig, n)?)
        })?;
        json_to_py(py, &v)
    }

    /// The rig's sensor sample rate (Hz).
    #[getter]
    fn sample_rate_hz(&self) -> f64 {
        self.rig.sample_rate_hz()
    }

    fn __repr__(&self) -> String {
        match &self.path {
            Some(p) => format!("Rig({})", p.display()),
            None => "Rig(<text>)".into(),
        }
    }
}

/// Simulates the beam under a base position command (documented in `beamshaper/__init__.py`).
#[pyfunction]
#[pyo3(signature = (rig, base_cmd_m, rate_hz, n_modes=4))]
pub fn simulate(
    py: Python<'_>,
    rig: PyRef<'_, PyRig>,
    base_cmd_m: &Bound<'_, PyAny>,
    rate_hz: f64,
    n_modes: usize,
) -> PyResult<PyRecording> {
    positive("rate_hz", rate_hz)?;
    let y = finite_vec_of("base_cmd_m", base_cmd_m)?;
    if y.len() < 2 {
        return Err(value_error("base_cmd_m: want at least 2 samples"));
    }
    let r = rig.rig.clone();
    let rec = run_released(py, move || {
        let m = model(&r, n_modes)?;
        let sim = BaseMotionSim::new(&m, 1.0 / rate_hz)?;
        Ok(sim.recording(&y, 0.0))
    })?;
    Ok(PyRecording {
        rec,
        from_npy: false,
        klipper_raw: None,
    })
}
