//! `diagnose`: the CLI's `beamtool diagnose` in-process, its JSON report as Python objects.

use crate::arrays::json_to_py;
use crate::guard::run_cancellable;
use crate::model::PyRig;
use beamtools::diagnose::load::load_with;
use beamtools::diagnose::report::to_json;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Diagnoses `rig` against recordings (documented in `beamshaper/__init__.py`).
#[pyfunction]
#[pyo3(signature = (rig, fit, validate, columns=None))]
pub fn diagnose<'py>(
    py: Python<'py>,
    rig: PyRef<'_, PyRig>,
    fit: Vec<PathBuf>,
    validate: PathBuf,
    columns: Option<&Bound<'_, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let opts = crate::recording::read_options(columns, None)?;
    if fit.is_empty() {
        return Err(crate::guard::value_error(
            "fit: want at least one recording to fit the model on",
        ));
    }
    let r = rig.rig.clone();
    let (report, notes) = run_cancellable(py, move |cancel| {
        let mut notes = Vec::new();
        let mut prepared = |p: &PathBuf| -> anyhow::Result<_> {
            let l = load_with(p, &r, &opts)?;
            notes.extend(l.notes.iter().map(|n| format!("{}: {n}", p.display())));
            Ok(l.prepared)
        };
        let fit: Vec<_> = fit
            .iter()
            .map(&mut prepared)
            .collect::<anyhow::Result<_>>()?;
        let val = prepared(&validate)?;
        let d = beamtools::diagnose::diagnose(&r, &fit, &val, cancel)?;
        Ok((to_json(&d), notes))
    })?;
    // what reading noted, as the CLI prints it: Python warnings
    let warn = py.import("warnings")?;
    for n in notes {
        warn.call_method1("warn", (format!("note: {n}"),))?;
    }
    json_to_py(py, &report)
}
