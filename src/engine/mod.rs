//! The run-time shaping engine: convolution of the reference with a [`TapTable`], once per tick.
//!
//! Per tick the work is one push into the [`History`] ring buffer and a sum over at most
//! [`MAX_TAPS`] taps: bounded, allocation-free and panic-free (all indexing is checked
//! with fall-backs, all arithmetic is widened so it cannot overflow for |x| ≤ 2³⁰ counts).
//!
//! Two numeric paths ([`NumericPath`]):
//! - **Fixed** (default): `y = round(Σ w_q30·x[n−d] / 2³⁰)` with Q2.30 weights and `i64`
//!   accumulation. Because `Σ w_q30 = 2³⁰` exactly, a constant input gives exactly that
//!   constant: unity DC gain to the last count, forever (an FIR filter has no state that
//!   could drift). Error bound against the exact f64 convolution of the same samples:
//!   `|y − y_f64| ≤ 0.5 + Σ|δw|·span` counts, where δw ≤ 2⁻³¹ per tap (+ the residual on
//!   the largest tap, ≤ n_taps·2⁻³¹) and `span` is the range of the reference over the
//!   shaper window; for a 50 mm move in nm and 32 taps that is 0.5 + 0.05 counts.
//! - **F32**: `y = x[n] + round(Σ w_f32·(x[n−d] − x[n]))`, the "delta form": the sum runs on
//!   differences, so a constant input again gives exactly that constant, and the f32
//!   rounding error scales with the span of the window, not with the absolute position:
//!   `|y − y_f64| ≤ 0.5 + (n_taps + 2)·2⁻²⁴·Σ|w|·span` counts.

pub mod history;
pub mod taps;

pub use history::History;
pub use taps::{Tap, TapError, TapTable, MAX_TAPS, WEIGHT_FRAC_BITS, WEIGHT_ONE};

/// Which arithmetic the tick uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumericPath {
    /// Q2.30 weights, i64 accumulation, exact unity DC gain.
    Fixed,
    /// f32 weights on differences to the newest sample.
    F32,
}

impl NumericPath {
    /// `fixed` or `f32`.
    pub fn name(self) -> &'static str {
        match self {
            NumericPath::Fixed => "fixed",
            NumericPath::F32 => "f32",
        }
    }
}

/// History plus taps plus numeric path.
#[derive(Clone, Debug)]
pub struct Engine<const N: usize> {
    history: History<N>,
    taps: TapTable,
    path: NumericPath,
}

impl<const N: usize> Engine<N> {
    /// Identity shaping, fixed-point path, history reading `position` everywhere.
    pub const fn new(position: i32) -> Self {
        Engine {
            history: History::new(position),
            taps: TapTable::identity(),
            path: NumericPath::Fixed,
        }
    }

    /// Installs a new tap table and numeric path and resets the history to `position`
    /// (the caller guarantees the reference has been constant at `position` for the old
    /// table's duration, so the output does not jump: see [`crate::runtime`]).
    pub fn install(&mut self, taps: TapTable, path: NumericPath, position: i32) {
        self.taps = taps;
        self.path = path;
        self.history.reset(position);
    }

    /// Resets the history to `position` (e.g. after zeroing the position).
    pub fn reset(&mut self, position: i32) {
        self.history.reset(position);
    }

    /// One tick: pushes the reference sample `x` (counts, |x| ≤ 2³⁰) and returns the shaped
    /// setpoint (counts).
    #[inline]
    pub fn tick(&mut self, x: i32) -> i32 {
        self.history.push(x);
        match self.path {
            NumericPath::Fixed => self.output_fixed(),
            NumericPath::F32 => self.output_f32(),
        }
    }

    /// Fixed-point output of the current window (see the module docs).
    #[inline]
    pub fn output_fixed(&self) -> i32 {
        let mut acc: i64 = 0;
        for t in self.taps.taps() {
            acc = acc.wrapping_add((t.w_q30 as i64).wrapping_mul(self.history.get(t.delay) as i64));
        }
        // Round half up: floor((acc + 2^29) / 2^30).
        ((acc.wrapping_add(1 << (WEIGHT_FRAC_BITS - 1))) >> WEIGHT_FRAC_BITS) as i32
    }

    /// f32 delta-form output of the current window, before rounding: `Σ w·(x[n−d] − x[n])`
    /// (counts, relative to the newest sample).
    #[inline]
    pub fn offset_f32(&self) -> f32 {
        let x0 = self.history.newest() as i64;
        let mut acc = 0.0f32;
        for t in self.taps.taps() {
            acc += t.w_f32 * (self.history.get(t.delay) as i64 - x0) as f32;
        }
        acc
    }

    /// f32 output of the current window (see the module docs).
    #[inline]
    pub fn output_f32(&self) -> i32 {
        let y = self.history.newest() as i64 + libm::roundf(self.offset_f32()) as i64;
        y.clamp(i32::MIN as i64, i32::MAX as i64) as i32
    }

    /// The installed taps.
    pub fn taps(&self) -> &TapTable {
        &self.taps
    }

    /// The numeric path in use.
    pub fn path(&self) -> NumericPath {
        self.path
    }

    /// The history buffer.
    pub fn history(&self) -> &History<N> {
        &self.history
    }
}
