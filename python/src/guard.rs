//! Errors, panics, the GIL and Ctrl-C around every call into the library.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The payload a progress callback unwinds with when Python has a pending signal (Ctrl-C):
/// the exception `check_signals` raised.
struct Interrupted(PyErr);

/// The library's error as a Python exception with the CLI's message (`error: {e:#}` without
/// `error: `): `OSError` when any cause is an I/O error (a file not found, not readable, not
/// writable), `ValueError` otherwise (bad input: the message says which and why).
pub fn to_py(e: anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    let io = e
        .chain()
        .any(|c| c.downcast_ref::<std::io::Error>().is_some());
    match io {
        true => PyOSError::new_err(msg),
        false => PyValueError::new_err(msg),
    }
}

/// A `ValueError` with `msg`.
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// Runs `f` with the GIL released, catching panics: the library's error becomes [`to_py`]'s
/// exception, an interruption ([`SignalCheck`]) the pending `KeyboardInterrupt`, and any other
/// panic a `RuntimeError` naming it a bug.
pub fn run_released<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> anyhow::Result<T> + Send,
) -> PyResult<T> {
    let r = py.allow_threads(|| catch_unwind(AssertUnwindSafe(f)));
    match r {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(to_py(e)),
        Err(payload) => Err(from_panic(payload)),
    }
}

/// The Python exception of a caught panic payload.
fn from_panic(payload: Box<dyn std::any::Any + Send>) -> PyErr {
    let payload = match payload.downcast::<Interrupted>() {
        Ok(i) => return i.0,
        Err(p) => p,
    };
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    PyRuntimeError::new_err(format!(
        "internal error in beamshaper (a bug, please report it): {what}"
    ))
}

/// Checks for a pending Python signal (Ctrl-C) at most every 50 ms, from inside a call that
/// runs without the GIL ([`run_released`]); a pending one unwinds the call with
/// [`Interrupted`], which `run_released` turns into the `KeyboardInterrupt`.
pub struct SignalCheck {
    last: Instant,
}

impl SignalCheck {
    /// A check that first looks at the next [`SignalCheck::poll`].
    pub fn new() -> Self {
        SignalCheck {
            last: Instant::now() - Duration::from_secs(1),
        }
    }

    /// Looks for a pending signal (takes the GIL for a moment); unwinds when one is pending.
    pub fn poll(&mut self) {
        if self.last.elapsed() < Duration::from_millis(50) {
            return;
        }
        self.last = Instant::now();
        let pending = Python::with_gil(|py| py.check_signals());
        if let Err(e) = pending {
            resume_unwind(Box::new(Interrupted(e)));
        }
    }
}

impl beamtools::progress::Progress for SignalCheck {
    fn stage(&mut self, _name: &str) {
        self.poll();
    }
    fn advance(&mut self, _done: u64, _total: u64) {
        self.poll();
    }
}

/// The payload a [`Cancel`] sink unwinds with once the caller gave up (Ctrl-C).
struct Cancelled;

/// A progress sink for [`run_cancellable`]: unwinds the worker at its next progress report
/// once the caller was interrupted.
pub struct Cancel {
    flag: Arc<AtomicBool>,
}

impl beamtools::progress::Progress for Cancel {
    fn stage(&mut self, _name: &str) {
        self.advance(0, 0);
    }
    fn advance(&mut self, _done: u64, _total: u64) {
        if self.flag.load(Ordering::Relaxed) {
            resume_unwind(Box::new(Cancelled));
        }
    }
}

/// Runs `f` on a worker thread while the caller waits without the GIL and looks for Ctrl-C
/// every 50 ms: a pending signal returns its exception (`KeyboardInterrupt`) at once, and the
/// worker stops at its next progress report ([`Cancel`]; work the library runs beside it on
/// threads of its own ends first). Errors and panics as [`run_released`].
pub fn run_cancellable<T: Send + 'static>(
    py: Python<'_>,
    f: impl FnOnce(&mut Cancel) -> anyhow::Result<T> + Send + 'static,
) -> PyResult<T> {
    let flag = Arc::new(AtomicBool::new(false));
    let mut sink = Cancel { flag: flag.clone() };
    let (tx, mut rx) = channel();
    std::thread::Builder::new()
        .name("beamshaper-call".into())
        .stack_size(64 << 20)
        .spawn(move || {
            let _ = tx.send(catch_unwind(AssertUnwindSafe(|| f(&mut sink))));
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start a worker thread: {e}")))?;
    loop {
        // the receiver is moved in and out: it is Send, not Sync
        let (got, back) =
            py.allow_threads(move || (rx.recv_timeout(Duration::from_millis(50)), rx));
        rx = back;
        match got {
            Ok(Ok(Ok(v))) => return Ok(v),
            Ok(Ok(Err(e))) => return Err(to_py(e)),
            Ok(Err(payload)) => return Err(from_panic(payload)),
            Err(RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals() {
                    flag.store(true, Ordering::Relaxed);
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err(
                    "internal error in beamshaper: the worker thread ended without a result",
                ))
            }
        }
    }
}
