//! `beamshaper._beamshaper`: the host tools library (`beamtools`) and the firmware core
//! (`beamshaper`) bound in-process for Python (PyO3, one abi3 wheel for CPython >= 3.9).
//!
//! The Python package `beamshaper` (python/beamshaper/) re-exports these classes and functions
//! and adds the pure-Python `beamshaper.plot`. Every entry point:
//! - converts numpy arrays (float64 or float32, 1-D, any strides) into the library's vectors
//!   and returns numpy arrays that own the library's vectors (no copy out);
//! - maps the library's errors to Python exceptions with the CLI's messages (`{e:#}`, the
//!   causes joined): `OSError` when a file could not be read or written, `ValueError`
//!   otherwise ([`guard::to_py`]);
//! - runs long calls without the GIL and turns a Rust panic into `RuntimeError` (a bug to
//!   report, never a `PanicException`), and Ctrl-C into `KeyboardInterrupt` at the library's
//!   next progress report ([`guard::run_released`]).

mod arrays;
mod diagnose;
mod guard;
mod ident;
mod model;
mod recording;
mod shaper;

use pyo3::prelude::*;

#[pymodule]
fn _beamshaper(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<recording::PyRecording>()?;
    m.add_class::<recording::PySpectrum>()?;
    m.add_class::<ident::PyMode>()?;
    m.add_class::<ident::PyIdentification>()?;
    m.add_class::<shaper::PyShaper>()?;
    m.add_class::<model::PyRig>()?;
    m.add_function(wrap_pyfunction!(recording::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(ident::identify, m)?)?;
    m.add_function(wrap_pyfunction!(shaper::design_shaper, m)?)?;
    m.add_function(wrap_pyfunction!(model::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose::diagnose, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
