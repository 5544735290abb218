//! `Recording`, `Spectrum` and `read_recording`: the files every command reads, and numpy
//! arrays of one axis.

use crate::arrays::{to_numpy, vec_of};
use crate::guard::{run_released, value_error};
use beamtools::ident::magspec::{read_lvm, MagnitudeSpectrum};
use beamtools::recording::psd::{is_spectrum_file, read_spectrum, KlipperSpectrum};
use beamtools::recording::{Axis, ColumnMap, ReadOptions, Recording, CHANNELS};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::PathBuf;

/// A recording: time base (s) and optional channels of one axis, all of length N, SI units.
#[pyclass(name = "Recording", module = "beamshaper", frozen)]
#[derive(Clone)]
pub struct PyRecording {
    pub rec: Recording,
    /// Read from a `.npy` [time; signal] file (its signal is an acceleration for
    /// `design_shaper`'s recorded-vibration check, as `beamtool tune` reads it).
    pub from_npy: bool,
    /// Read from a Klipper raw accelerometer CSV (the file and how it was read): `identify`
    /// then takes the file's path as `beamtool identify` does (a resonance test's sweep goes
    /// to the peaks of Klipper's PSD, `ident::klipper_raw`).
    pub klipper_raw: Option<(PathBuf, ReadOptions)>,
}

#[pymethods]
impl PyRecording {
    /// A recording from numpy arrays of shape (N,) (float64 or float32, any strides; the
    /// values are copied once into the library). Raises ValueError: an array not 1-D, no
    /// channel besides ``time_s``, N < 2, lengths that differ, NaN or inf, time not strictly
    /// increasing (the message names the row).
    #[staticmethod]
    #[pyo3(signature = (time_s, tip_pos_m=None, base_pos_m=None, base_cmd_m=None, force_n=None, tip_acc_m_s2=None))]
    fn from_arrays(
        time_s: &Bound<'_, PyAny>,
        tip_pos_m: Option<&Bound<'_, PyAny>>,
        base_pos_m: Option<&Bound<'_, PyAny>>,
        base_cmd_m: Option<&Bound<'_, PyAny>>,
        force_n: Option<&Bound<'_, PyAny>>,
        tip_acc_m_s2: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let ch = |name: &str, o: Option<&Bound<'_, PyAny>>| o.map(|o| vec_of(name, o)).transpose();
        let rec = Recording {
            time_s: vec_of("time_s", time_s)?,
            tip_pos_m: ch("tip_pos_m", tip_pos_m)?,
            base_pos_m: ch("base_pos_m", base_pos_m)?,
            base_cmd_m: ch("base_cmd_m", base_cmd_m)?,
            force_n: ch("force_n", force_n)?,
            tip_acc_m_s2: ch("tip_acc_m_s2", tip_acc_m_s2)?,
            notes: vec![],
        };
        if CHANNELS.iter().all(|c| rec.channel(c).is_none()) {
            return Err(value_error(
                "a recording needs at least one channel besides time_s (tip_pos_m, base_pos_m, base_cmd_m, force_n, tip_acc_m_s2)",
            ));
        }
        rec.validate_gapped()
            .map_err(|e| value_error(format!("invalid recording: {e:#}")))?;
        Ok(PyRecording {
            rec,
            from_npy: false,
            klipper_raw: None,
        })
    }

    /// ``{"time_s": (N,), <each present channel>: (N,)}`` as new float64 arrays (SI).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("time_s", to_numpy(py, self.rec.time_s.clone()))?;
        for name in CHANNELS {
            if let Some(c) = self.rec.channel(name) {
                d.set_item(name, to_numpy(py, c.to_vec()))?;
            }
        }
        Ok(d)
    }

    /// Sample times (s), shape (N,).
    #[getter]
    fn time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_numpy(py, self.rec.time_s.clone()).into_any()
    }

    /// Names of the channels present besides ``time_s``.
    #[getter]
    fn channels(&self) -> Vec<&'static str> {
        CHANNELS
            .iter()
            .copied()
            .filter(|c| self.rec.channel(c).is_some())
            .collect()
    }

    /// What reading noted or mended (columns ignored, units converted, …).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.rec.notes.clone()
    }

    /// 1 / median sample interval (Hz).
    #[getter]
    fn sample_rate_hz(&self) -> f64 {
        self.rec.sample_rate_hz()
    }

    fn __len__(&self) -> usize {
        self.rec.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Recording({} samples, {:.6} Hz median, channels: {})",
            self.rec.len(),
            self.rec.sample_rate_hz(),
            self.channels().join(", ")
        )
    }
}

/// The two spectrum files the CLI reads.
#[derive(Clone)]
pub enum SpectrumData {
    /// A LabVIEW `.lvm` magnitude spectrum (dB) of an impact test.
    Magnitude(MagnitudeSpectrum),
    /// Klipper's `resonances_*.csv` / `calibration_data_*.csv` PSD.
    Klipper(KlipperSpectrum),
}

/// A spectrum file: a magnitude spectrum (`.lvm`) or Klipper's PSD file.
#[pyclass(name = "Spectrum", module = "beamshaper", frozen)]
#[derive(Clone)]
pub struct PySpectrum {
    pub path: PathBuf,
    pub data: SpectrumData,
}

#[pymethods]
impl PySpectrum {
    #[getter]
    fn kind(&self) -> &'static str {
        match self.data {
            SpectrumData::Magnitude(_) => "magnitude",
            SpectrumData::Klipper(_) => "klipper_psd",
        }
    }

    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Frequency bins (Hz), shape (M,).
    #[getter]
    fn freq_hz<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        let f = match &self.data {
            SpectrumData::Magnitude(s) => s.freq_hz.clone(),
            SpectrumData::Klipper(s) => s.freq_hz.clone(),
        };
        to_numpy(py, f).into_any()
    }

    /// The columns as float64 arrays of shape (M,) (and ``unit`` / ``normalized``).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        match &self.data {
            SpectrumData::Magnitude(s) => {
                d.set_item("freq_hz", to_numpy(py, s.freq_hz.clone()))?;
                d.set_item("magnitude_db", to_numpy(py, s.mag_db.clone()))?;
                d.set_item("unit", s.unit.clone())?;
            }
            SpectrumData::Klipper(s) => {
                d.set_item("freq_hz", to_numpy(py, s.freq_hz.clone()))?;
                d.set_item("psd_x", to_numpy(py, s.psd_x.clone()))?;
                d.set_item("psd_y", to_numpy(py, s.psd_y.clone()))?;
                d.set_item("psd_z", to_numpy(py, s.psd_z.clone()))?;
                d.set_item("psd_xyz", to_numpy(py, s.psd_sum.clone()))?;
                d.set_item("normalized", s.normalized)?;
            }
        }
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let n = match &self.data {
            SpectrumData::Magnitude(s) => s.freq_hz.len(),
            SpectrumData::Klipper(s) => s.freq_hz.len(),
        };
        format!(
            "Spectrum({}, {n} bins, {})",
            self.kind(),
            self.path.display()
        )
    }
}

/// The CLI's `--columns` (a string `channel=column[:scale],…` or a dict `{channel: column}` /
/// `{channel: (column, scale)}`) and `--axis`.
pub(crate) fn read_options(
    columns: Option<&Bound<'_, PyAny>>,
    axis: Option<&str>,
) -> PyResult<ReadOptions> {
    let spec = match columns {
        None => None,
        Some(c) if c.is_instance_of::<PyString>() => Some(c.extract::<String>()?),
        Some(c) => {
            let d = c.downcast::<PyDict>().map_err(|_| {
                value_error("columns: want a str `channel=column[:scale],…` or a dict")
            })?;
            let mut items = Vec::new();
            for (k, v) in d.iter() {
                let ch: String = k.extract()?;
                let entry = match v.extract::<(String, f64)>() {
                    Ok((col, scale)) => format!("{ch}={col}:{scale}"),
                    Err(_) => format!("{ch}={}", v.extract::<String>()?),
                };
                items.push(entry);
            }
            Some(items.join(","))
        }
    };
    let columns = spec
        .map(|s| ColumnMap::parse(&s))
        .transpose()
        .map_err(|e| value_error(format!("{e:#}")))?;
    let axis = axis
        .map(Axis::from_name)
        .transpose()
        .map_err(|e| value_error(format!("{e:#}")))?;
    Ok(ReadOptions { columns, axis })
}

/// Reads a recording or spectrum file (documented in `beamshaper/__init__.py`).
#[pyfunction]
#[pyo3(signature = (path, columns=None, axis=None))]
pub fn read_recording(
    py: Python<'_>,
    path: PathBuf,
    columns: Option<&Bound<'_, PyAny>>,
    axis: Option<&str>,
) -> PyResult<PyObject> {
    let opts = read_options(columns, axis)?;
    let is_lvm = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("lvm"));
    if is_lvm || is_spectrum_file(&path) {
        let p = path.clone();
        let data = run_released(py, move || match is_lvm {
            true => read_lvm(&p).map(SpectrumData::Magnitude),
            false => read_spectrum(&p).map(SpectrumData::Klipper),
        })?;
        return Ok(PySpectrum { path, data }
            .into_pyobject(py)?
            .into_any()
            .unbind());
    }
    let from_npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let klipper_raw =
        beamtools::recording::rawpsd::is_raw_file(&path).then(|| (path.clone(), opts.clone()));
    let mut check = crate::guard::SignalCheck::new();
    let rec = run_released(py, move || {
        Recording::read_any_with(&path, &opts, &mut |_| check.poll())
    })?;
    Ok(PyRecording {
        rec,
        from_npy,
        klipper_raw,
    }
    .into_pyobject(py)?
    .into_any()
    .unbind())
}
