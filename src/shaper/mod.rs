//! Input shapers: sequences of impulses `(amplitude, time_s)` convolved with a reference.
//!
//! - [`design`]: the single-mode designs (ZV, ZVD, ZVDD of the paper's eqs. 30–32; ZVDDD,
//!   MZV, EI, 2-hump EI, 3-hump EI, UM-ZV; custom lists).
//! - [`vibration`]: percentage residual vibration `V(f, ζ)` and the insensitivity band.
//! - [`Shaper`]: an impulse list with convolution (multi-mode shapers, paper §4) and merging.
//!
//! All design math is `f64` through `libm`, so that the host and the Cortex-M4 produce
//! bit-identical tables (the M4F has no double-precision FPU; `libm` is pure software on both).

pub mod design;
pub mod vibration;

pub use design::{design, ShaperKind};
pub use vibration::{insensitivity_band, residual_vibration};

/// Largest number of impulses a [`Shaper`] holds (after convolution and merging).
///
/// 64 = a three-mode ZVDD (4³), or a two-mode shaper of two 8-impulse factors.
pub const MAX_IMPULSES: usize = 64;

/// Two impulse times closer than this (seconds) are merged into one impulse by
/// [`Shaper::convolve`] (e.g. `t = T/2 + T/2` and `t = T` of a ZVD convolved with itself).
pub const MERGE_TOLERANCE_S: f64 = 1e-9;

/// One impulse of a shaper: amplitude (dimensionless) at a time (s) after the first impulse.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Impulse {
    /// Amplitude `A_i` (dimensionless; the amplitudes of a shaper sum to 1).
    pub amplitude: f64,
    /// Time `t_i` in seconds, `t_1 = 0`.
    pub time_s: f64,
}

/// Why a shaper could not be designed or combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShaperError {
    /// Natural frequency not finite or `<= 0` (Hz).
    Frequency,
    /// Damping ratio not finite, negative, or `>= 1`.
    Damping,
    /// Vibration tolerance of an EI shaper outside `(0, 0.5)`.
    Tolerance,
    /// More than [`MAX_IMPULSES`] impulses.
    TooManyImpulses,
    /// An impulse with a non-finite amplitude or time, a negative time, or amplitudes
    /// that do not sum to 1 (custom lists).
    BadImpulse,
    /// The numerical design (UM-ZV with damping) did not converge.
    NoConvergence,
}

impl ShaperError {
    /// A short human-readable message (the console prints it after `err <code>:`).
    pub fn message(self) -> &'static str {
        match self {
            ShaperError::Frequency => "natural frequency must be finite and > 0 Hz",
            ShaperError::Damping => "damping ratio must be finite and in [0, 1)",
            ShaperError::Tolerance => "vibration tolerance must be in (0, 0.5)",
            ShaperError::TooManyImpulses => "too many impulses",
            ShaperError::BadImpulse => {
                "impulse list invalid (finite, t >= 0, sum of amplitudes = 1)"
            }
            ShaperError::NoConvergence => "shaper design did not converge",
        }
    }
}

/// An input shaper: impulses sorted by time, the first at `t = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Shaper {
    impulses: heapless::Vec<Impulse, MAX_IMPULSES>,
}

impl Default for Shaper {
    /// The identity shaper (one unit impulse at t = 0): no shaping.
    fn default() -> Self {
        Self::identity()
    }
}

impl Shaper {
    /// The identity shaper `[(1, 0)]`.
    pub fn identity() -> Self {
        let mut impulses = heapless::Vec::new();
        let _ = impulses.push(Impulse {
            amplitude: 1.0,
            time_s: 0.0,
        });
        Shaper { impulses }
    }

    /// Builds a shaper from `(amplitude, time_s)` pairs, sorting by time, merging times
    /// closer than [`MERGE_TOLERANCE_S`] and shifting so the first impulse is at t = 0.
    ///
    /// Errors: [`ShaperError::BadImpulse`] for a non-finite value, a negative time, an
    /// empty list or amplitudes whose sum differs from 1 by more than 1e-9;
    /// [`ShaperError::TooManyImpulses`] above [`MAX_IMPULSES`].
    pub fn from_impulses(list: &[Impulse]) -> Result<Self, ShaperError> {
        if list.is_empty() || list.len() > MAX_IMPULSES {
            return Err(if list.is_empty() {
                ShaperError::BadImpulse
            } else {
                ShaperError::TooManyImpulses
            });
        }
        let mut v: heapless::Vec<Impulse, MAX_IMPULSES> = heapless::Vec::new();
        for imp in list {
            if !imp.amplitude.is_finite() || !imp.time_s.is_finite() || imp.time_s < 0.0 {
                return Err(ShaperError::BadImpulse);
            }
            let _ = v.push(*imp);
        }
        let s = Self::normalised(v);
        let sum: f64 = s.impulses.iter().map(|i| i.amplitude).sum();
        if libm::fabs(sum - 1.0) > 1e-9 || s.impulses.is_empty() {
            return Err(ShaperError::BadImpulse);
        }
        Ok(s)
    }

    /// Sorts (insertion sort: n ≤ 64, stable, no allocation), merges coincident impulses,
    /// drops zero amplitudes and shifts the first impulse to t = 0.
    fn normalised(mut v: heapless::Vec<Impulse, MAX_IMPULSES>) -> Self {
        for i in 1..v.len() {
            let mut j = i;
            while j > 0 && v[j - 1].time_s > v[j].time_s {
                v.swap(j - 1, j);
                j -= 1;
            }
        }
        let mut out: heapless::Vec<Impulse, MAX_IMPULSES> = heapless::Vec::new();
        for imp in v.iter() {
            match out.last_mut() {
                Some(last) if imp.time_s - last.time_s <= MERGE_TOLERANCE_S => {
                    last.amplitude += imp.amplitude;
                }
                _ => {
                    let _ = out.push(*imp);
                }
            }
        }
        out.retain(|i| i.amplitude != 0.0);
        if let Some(t0) = out.first().map(|i| i.time_s) {
            for imp in out.iter_mut() {
                imp.time_s -= t0;
            }
        }
        Shaper { impulses: out }
    }

    /// Convolution of two shapers (paper §4: multi-mode shapers by convolution, N = n^m
    /// impulses before merging). Coincident impulses are merged.
    ///
    /// Errors: [`ShaperError::TooManyImpulses`] if the product, after merging, exceeds
    /// [`MAX_IMPULSES`]. The product of two sequences whose amplitudes sum to 1 sums to 1.
    pub fn convolve(&self, other: &Shaper) -> Result<Shaper, ShaperError> {
        // Accumulate into a merged, sorted list directly so that intermediate products
        // larger than MAX_IMPULSES but merging below it still work.
        let mut out: heapless::Vec<Impulse, MAX_IMPULSES> = heapless::Vec::new();
        for a in self.impulses.iter() {
            for b in other.impulses.iter() {
                let imp = Impulse {
                    amplitude: a.amplitude * b.amplitude,
                    time_s: a.time_s + b.time_s,
                };
                if let Some(m) = out
                    .iter_mut()
                    .find(|m| libm::fabs(m.time_s - imp.time_s) <= MERGE_TOLERANCE_S)
                {
                    m.amplitude += imp.amplitude;
                } else if out.push(imp).is_err() {
                    return Err(ShaperError::TooManyImpulses);
                }
            }
        }
        Ok(Self::normalised(out))
    }

    /// The impulses, sorted by time; the first is at t = 0.
    pub fn impulses(&self) -> &[Impulse] {
        &self.impulses
    }

    /// Number of impulses.
    pub fn len(&self) -> usize {
        self.impulses.len()
    }

    /// Always false: a shaper has at least one impulse.
    pub fn is_empty(&self) -> bool {
        self.impulses.is_empty()
    }

    /// Duration (s): the time of the last impulse, i.e. the delay the shaper adds to a move.
    pub fn duration_s(&self) -> f64 {
        self.impulses.last().map_or(0.0, |i| i.time_s)
    }

    /// Sum of amplitudes (1 for every valid shaper: unity DC gain).
    pub fn amplitude_sum(&self) -> f64 {
        self.impulses.iter().map(|i| i.amplitude).sum()
    }

    /// Sum of absolute amplitudes: 1 for positive shapers, 3 for UM-ZV. Bounds the peak
    /// velocity of a shaped move relative to the unshaped one.
    pub fn abs_amplitude_sum(&self) -> f64 {
        self.impulses.iter().map(|i| libm::fabs(i.amplitude)).sum()
    }

    /// Shaped value at time `t_s` of a reference signal `r(t)` (0 before t = 0):
    /// `Σ A_i r(t − t_i)`. Reference implementation for tests and the host tools.
    pub fn apply_at(&self, t_s: f64, r: impl Fn(f64) -> f64) -> f64 {
        self.impulses
            .iter()
            .map(|i| i.amplitude * r(t_s - i.time_s))
            .sum()
    }
}
