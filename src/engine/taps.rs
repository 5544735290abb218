//! Tap tables: a [`Shaper`] sampled on the tick grid for the run-time engine.
//!
//! An impulse `(A, t)` with `t·f_tick = k + φ` (k integer, 0 ≤ φ < 1) is split over the two
//! neighbouring samples by linear interpolation: weight `A(1−φ)` at delay k and `Aφ` at
//! delay k+1. For a reference that is linear between ticks this is exact; sub-tick impulse
//! times are never rounded to the tick.
//!
//! Each tap holds the weight twice: in `f32` for the floating-point path, and in the
//! explicit fixed-point format **Q2.30** (`i32`, value = w / 2³⁰, range [−2, 2)) for the
//! integer path. The Q2.30 weights are rounded to nearest and then the rounding residual
//! is added to the largest tap so that `Σ w_q30 = 2³⁰` **exactly**: unity DC gain to the
//! last count, whatever the shaper.

use crate::shaper::{Shaper, MAX_IMPULSES};

/// Fractional bits of the fixed-point weights (Q2.30).
pub const WEIGHT_FRAC_BITS: u32 = 30;
/// 1.0 in Q2.30.
pub const WEIGHT_ONE: i64 = 1 << WEIGHT_FRAC_BITS;
/// Most taps a table holds (two per impulse).
pub const MAX_TAPS: usize = 2 * MAX_IMPULSES;
/// Largest Σ|A| accepted (UM-ZV has 3). Bounds the i64 accumulator: |x| ≤ 2³⁰ counts and
/// Σ|w| < 4 give |acc| < 2⁶².
pub const MAX_ABS_AMPLITUDE_SUM: f64 = 3.9;
/// An impulse within this fraction of a tick of a sample is put on that sample alone.
const SNAP: f64 = 1e-9;

/// One tap: weight applied to the reference sample `delay` ticks ago.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tap {
    /// Delay in ticks (0 = the current sample).
    pub delay: u32,
    /// Weight in Q2.30.
    pub w_q30: i32,
    /// Weight as f32.
    pub w_f32: f32,
}

/// Why a shaper cannot be run at a tick rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TapError {
    /// Tick rate not finite or ≤ 0.
    TickRate,
    /// The shaper lasts longer than the history buffer holds at this tick rate.
    TooLong {
        /// Shaper duration (s).
        duration_s: f64,
        /// Longest duration the buffer allows at this tick rate (s).
        max_s: f64,
    },
    /// Σ|A| exceeds [`MAX_ABS_AMPLITUDE_SUM`] or a weight does not fit Q2.30.
    AmplitudeRange,
}

/// The shaper on the tick grid: sorted by delay, one tap per delay.
///
/// A plain array and a length (not a `heapless::Vec`) so that [`TapTable::identity`] is a
/// `const fn` and the run-time state can live in a `static`.
#[derive(Clone, Debug, PartialEq)]
pub struct TapTable {
    taps: [Tap; MAX_TAPS],
    len: usize,
}

/// Padding beyond a table's length: delay 0, weight 0.
const ZERO_TAP: Tap = Tap {
    delay: 0,
    w_q30: 0,
    w_f32: 0.0,
};

impl TapTable {
    /// The identity table (one tap of weight 1 at delay 0): shaping off.
    pub const fn identity() -> Self {
        let mut taps = [ZERO_TAP; MAX_TAPS];
        taps[0] = Tap {
            delay: 0,
            w_q30: WEIGHT_ONE as i32,
            w_f32: 1.0,
        };
        TapTable { taps, len: 1 }
    }

    /// Samples `shaper` at `tick_rate_hz` for a history of `history_len` samples.
    ///
    /// Errors: [`TapError::TickRate`], [`TapError::TooLong`] if the last tap's delay would be
    /// ≥ `history_len`, [`TapError::AmplitudeRange`].
    pub fn from_shaper(
        shaper: &Shaper,
        tick_rate_hz: f64,
        history_len: usize,
    ) -> Result<Self, TapError> {
        if !tick_rate_hz.is_finite() || tick_rate_hz <= 0.0 {
            return Err(TapError::TickRate);
        }
        let max_s = (history_len as f64 - 2.0) / tick_rate_hz;
        if shaper.duration_s() > max_s {
            return Err(TapError::TooLong {
                duration_s: shaper.duration_s(),
                max_s,
            });
        }
        if shaper.abs_amplitude_sum() > MAX_ABS_AMPLITUDE_SUM {
            return Err(TapError::AmplitudeRange);
        }
        // f64 weights per delay, merged.
        let mut w: heapless::Vec<(u32, f64), MAX_TAPS> = heapless::Vec::new();
        let mut add = |delay: u32, a: f64| {
            if a == 0.0 {
                return;
            }
            match w.iter_mut().find(|(d, _)| *d == delay) {
                Some((_, v)) => *v += a,
                None => {
                    let _ = w.push((delay, a));
                }
            }
        };
        for imp in shaper.impulses() {
            let pos = imp.time_s * tick_rate_hz;
            let k = libm::floor(pos);
            let frac = pos - k;
            let k = k as u32;
            if frac < SNAP {
                add(k, imp.amplitude);
            } else if frac > 1.0 - SNAP {
                add(k + 1, imp.amplitude);
            } else {
                add(k, imp.amplitude * (1.0 - frac));
                add(k + 1, imp.amplitude * frac);
            }
        }
        // Sort by delay (insertion sort, ≤ 128 entries).
        for i in 1..w.len() {
            let mut j = i;
            while j > 0 && w[j - 1].0 > w[j].0 {
                w.swap(j - 1, j);
                j -= 1;
            }
        }
        let mut table = TapTable {
            taps: [ZERO_TAP; MAX_TAPS],
            len: w.len(),
        };
        let taps = &mut table.taps[..w.len()];
        let mut sum_q: i64 = 0;
        for (t, &(delay, a)) in taps.iter_mut().zip(w.iter()) {
            let q = libm::round(a * WEIGHT_ONE as f64) as i64;
            if q > i32::MAX as i64 || q < i32::MIN as i64 {
                return Err(TapError::AmplitudeRange);
            }
            sum_q += q;
            *t = Tap {
                delay,
                w_q30: q as i32,
                w_f32: a as f32,
            };
        }
        // Exact unity DC gain: put the rounding residual on the largest tap.
        let residual = WEIGHT_ONE - sum_q;
        let (mut big, mut big_abs) = (0usize, 0i64);
        for (i, t) in taps.iter().enumerate() {
            if (t.w_q30 as i64).abs() > big_abs {
                big = i;
                big_abs = (t.w_q30 as i64).abs();
            }
        }
        if let Some(t) = taps.get_mut(big) {
            let v = t.w_q30 as i64 + residual;
            if v > i32::MAX as i64 || v < i32::MIN as i64 {
                return Err(TapError::AmplitudeRange);
            }
            t.w_q30 = v as i32;
        }
        if taps.iter().map(|t| t.w_q30 as i64).sum::<i64>() != WEIGHT_ONE {
            return Err(TapError::AmplitudeRange);
        }
        Ok(table)
    }

    /// The taps, sorted by delay.
    pub fn taps(&self) -> &[Tap] {
        self.taps.get(..self.len).unwrap_or(&[])
    }

    /// Largest delay (ticks): the shaper's duration on the tick grid, rounded up. O(1): the
    /// taps are sorted by strictly increasing delay (an invariant of every constructor).
    pub fn duration_ticks(&self) -> u32 {
        self.taps().last().map(|t| t.delay).unwrap_or(0)
    }

    /// The taps followed by zero-weight taps (delay 0, weight 0) up to a multiple of four:
    /// what the engine's four-tap loops read, with no remainder loop. The entries beyond
    /// `len` are `ZERO_TAP` in every table (both constructors fill the array with it, and
    /// nothing mutates a table), so they add exactly 0 (fixed) or ±0 (f32) to a sum.
    #[inline(always)]
    pub fn taps_padded(&self) -> &[Tap] {
        let n = (self.len + 3) & !3;
        self.taps.get(..n).unwrap_or(&self.taps)
    }

    /// Number of taps.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for a table without taps (never produced by the constructors).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Σ|w|: bounds the shaped velocity relative to the reference's.
    pub fn abs_weight_sum(&self) -> f32 {
        self.taps().iter().map(|t| libm::fabsf(t.w_f32)).sum()
    }
}
