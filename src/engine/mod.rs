//! The run-time shaping engine: convolution of the reference with a [`TapTable`], once per
//! tick, and **shaper changes at any tick by superposition**.
//!
//! # Numeric paths ([`NumericPath`])
//! - **Fixed** (default): `y = round(Σ w_q30·x[n−d] / 2³⁰)` with Q2.30 weights and `i64`
//!   accumulation (one SMLAL per tap on the M4). Because `Σ w_q30 = 2³⁰` exactly, a constant
//!   input gives exactly that constant: unity DC gain to the last count, forever. Error bound
//!   against the exact f64 convolution of the same samples: `|y − y_f64| ≤ 0.5 + Σ|δw|·span`
//!   counts, δw ≤ 2⁻³¹ per tap (+ the residual on the largest tap, ≤ n_taps·2⁻³¹), `span` the
//!   range of the reference over the shaper window.
//! - **F32**: `y = x[n] + round(Σ w_f32·(x[n−d] − x[n]))`, the "delta form", with the
//!   differences taken in `i32` (exact: inputs are limited to |x| < 2³⁰) and converted once:
//!   a constant input gives exactly that constant, and the rounding error scales with the
//!   span of the window, not the position: `|y − y_f64| ≤ 0.5 + (n_taps + 2)·2⁻²⁴·Σ|w|·span`.
//!
//! # Changing the shaper at any tick (superposition)
//! Let the change come at tick n_s with `x_s = x(n_s − 1)`, the last sample the old table
//! owns. The reference splits into the part before the switch held at x_s afterwards,
//! `x_f(n) = x(min(n, n_s − 1))`, and the increment after it, `x − x_f`. The engine outputs
//!
//! `y(n) = S_old * x_f (n) + S_new * (x − x_f)(n)`.
//!
//! Both tables have unit DC gain, so `y` is continuous at the switch; the beam is linear, so
//! its motion is the sum of one motion shaped by the old design and one by the new, each
//! without residual vibration at the modes its shaper was designed for. Once the old table's
//! duration has passed, `S_old * x_f ≡ x_s` exactly (fixed path: `Σw = 2³⁰`; f32 path: every
//! difference is 0), the old table is dropped, and what remains is `S_new * x` on the history
//! as it is: the transition is over. It needs no second buffer: the old table reads `x_s`
//! for every sample at or after n_s (an *upper clamp* on its window), the new one reads `x_s`
//! for every sample before it (a *lower clamp*). Several back-to-back switches chain the same
//! way ([`Stage`] list, oldest first); a reset is a lower clamp too (samples older than the
//! reset read the reset value, in O(1)).
//!
//! In the fixed path with stages k = 0…K (k = 0 the oldest), `acc = Σₖ Σᵢ wₖᵢ·xₖ(n − dₖᵢ) −
//! 2³⁰·Σ_{k≥1} x_{s,k}`; in the f32 path `y = x(n) + round(Σₖ Σᵢ wₖᵢ·(xₖ(n − dₖᵢ) − cₖ))` with
//! `cₖ` the held value of a closed stage and `x(n)` for the newest (the constants telescope).
//!
//! # Work per tick
//! Bounded: one push, the sum over the taps of every stage in flight, at most
//! [`TAP_BUDGET`] taps in all ([`EngineState::switch`] refuses more), and O([`MAX_STAGES`])
//! bookkeeping. **Steady state** (one stage, its window entirely after the last reset or
//! switch) runs the fast kernel: when the window lies in one unwrapped run of the ring
//! ([`history`]; all but `max_delay` ticks in every N), the taps are read through a base
//! pointer with no per-tap bounds check, wrap or clamp, four per loop iteration. Its safety
//! is proven once per table (the largest delay, found by inspection when the table is
//! staged, is < N) plus one comparison per tick (`max_delay < N − head`); the remaining
//! ticks use masked indices.
//! Nothing allocates or panics.

pub mod history;
pub mod taps;

pub use history::Ring;
pub use taps::{Tap, TapError, TapTable, MAX_TAPS, WEIGHT_FRAC_BITS, WEIGHT_ONE};

/// Most shaper tables in flight at once (the newest plus up to three still settling).
pub const MAX_STAGES: usize = 4;

/// Most taps one tick evaluates, over all tables in flight: twice the largest table, so any
/// single change from a settled state fits (two 128-tap tables during the transition).
pub const TAP_BUDGET: usize = 2 * MAX_TAPS;

/// Which arithmetic the tick uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NumericPath {
    /// Q2.30 weights, i64 accumulation, exact unity DC gain.
    Fixed,
    /// f32 weights on i32 differences to the newest sample.
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

/// Why a table cannot be staged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchError {
    /// The taps of the tables in flight plus the new one would exceed [`TAP_BUDGET`].
    Budget {
        /// Taps per tick the transition would need.
        taps: usize,
    },
    /// [`MAX_STAGES`] tables are already in flight.
    Stages,
    /// The table's longest delay does not fit the history.
    TooLong,
}

/// One tap table in flight, with the clamps of its window (see the module docs).
#[derive(Clone, Debug, PartialEq)]
struct Stage {
    taps: TapTable,
    /// Longest delay of `taps` (cached).
    max_delay: u32,
    /// Samples pushed since the lower clamp (saturating): delays ≥ this read `fill`.
    valid: u32,
    /// Value of the samples before the lower clamp.
    fill: i32,
    /// Closed by a later switch: delays < `skip` read `hold`.
    closed: bool,
    /// Samples pushed since the upper clamp (saturating).
    skip: u32,
    /// Value of the samples after the upper clamp (= the next stage's `fill`).
    hold: i32,
}

impl Stage {
    /// `max_delay` must be the largest delay of `taps` (see [`true_max_delay`]).
    const fn new(taps: TapTable, max_delay: u32, fill: i32) -> Self {
        Stage {
            taps,
            max_delay,
            valid: 0,
            fill,
            closed: false,
            skip: 0,
            hold: 0,
        }
    }
}

/// The engine without its history buffer: the tables in flight, the ring position and the
/// numeric path. The buffer (`[i32; N]`) is passed to every call, so that the firmware can
/// keep it in `.bss` ([`crate::runtime`]); [`Engine`] bundles both for host use.
#[derive(Clone, Debug)]
pub struct EngineState<const N: usize> {
    ring: Ring<N>,
    stages: [Stage; MAX_STAGES],
    /// Index of the oldest stage in `stages`.
    first: usize,
    /// Stages in flight (≥ 1).
    count: usize,
    path: NumericPath,
    /// Newest sample (or the reset value before the first push).
    newest: i32,
    /// One stage whose whole window is live: the fast kernels, no clamp bookkeeping.
    steady: bool,
}

const fn identity_stage(fill: i32) -> Stage {
    Stage::new(TapTable::identity(), 0, fill)
}

impl<const N: usize> EngineState<N> {
    /// Identity shaping, fixed point, every past sample reading `position`.
    pub const fn new(position: i32) -> Self {
        EngineState {
            ring: Ring::new(),
            stages: [
                identity_stage(position),
                identity_stage(0),
                identity_stage(0),
                identity_stage(0),
            ],
            first: 0,
            count: 1,
            path: NumericPath::Fixed,
            newest: position,
            steady: false,
        }
    }

    #[inline(always)]
    fn idx(&self, k: usize) -> usize {
        (self.first + k) % MAX_STAGES
    }

    fn newest_stage(&self) -> &Stage {
        &self.stages[self.idx(self.count.max(1) - 1)]
    }

    /// Installs `taps` and `path` as the only table and resets the history to `position`
    /// (every past sample reads `position`). For a change at standstill or at boot.
    /// Errors: [`SwitchError::TooLong`] if a delay does not fit the history (nothing changes).
    pub fn install(
        &mut self,
        taps: TapTable,
        path: NumericPath,
        position: i32,
    ) -> Result<(), SwitchError> {
        let max_delay = true_max_delay(&taps);
        if max_delay as usize >= N {
            return Err(SwitchError::TooLong);
        }
        self.first = 0;
        self.count = 1;
        self.stages[0] = Stage::new(taps, max_delay, position);
        self.path = path;
        self.newest = position;
        self.steady = false;
        Ok(())
    }

    /// Forgets the past: every sample reads `position` until new samples are pushed; keeps
    /// the newest table and ends any transition.
    pub fn reset(&mut self, position: i32) {
        let i = self.idx(self.count.max(1) - 1);
        self.stages.swap(0, i);
        self.first = 0;
        self.count = 1;
        let s = &mut self.stages[0];
        s.valid = 0;
        s.fill = position;
        s.closed = false;
        self.newest = position;
        self.steady = false;
    }

    /// Taps per tick the tables in flight need now.
    pub fn taps_in_flight(&self) -> usize {
        (0..self.count)
            .map(|k| self.stages[self.idx(k)].taps.len())
            .sum()
    }

    /// Checks whether `taps` could be switched to now (see [`EngineState::switch`]).
    pub fn can_switch(&self, taps: &TapTable) -> Result<(), SwitchError> {
        if true_max_delay(taps) as usize >= N {
            return Err(SwitchError::TooLong);
        }
        let need = self.taps_in_flight() + taps.len();
        if need > TAP_BUDGET {
            return Err(SwitchError::Budget { taps: need });
        }
        if self.count >= MAX_STAGES {
            return Err(SwitchError::Stages);
        }
        Ok(())
    }

    /// Bound on how much faster than the reference the setpoint can move during a switch to
    /// `new` now: `max_m (Σ_{d ≥ m}|w_newest| + Σ_{d < m}|w_new|) + Σ|w|` of the older tables
    /// still in flight, m ≥ 1 ticks after the switch (the newest table shapes the samples up to
    /// the switch, `new` those after it; each reads live samples only on its side). It is
    /// `Σ|w_new|` for an unswitched table, and at most `Σ|w_old| + Σ|w_new|`. O(n_old·n_new).
    pub fn transition_gain(&self, new: &TapTable) -> f32 {
        let old = self.taps().taps();
        let older: f32 = (0..self.count.saturating_sub(1))
            .map(|k| self.stages[self.idx(k)].taps.abs_weight_sum())
            .sum();
        let tail = |m: u32| -> f32 {
            old.iter()
                .filter(|t| t.delay >= m)
                .map(|t| libm::fabsf(t.w_f32))
                .sum()
        };
        let mut best = tail(1)
            + new
                .taps()
                .iter()
                .filter(|t| t.delay < 1)
                .map(|t| libm::fabsf(t.w_f32))
                .sum::<f32>();
        let mut head = 0.0f32;
        for t in new.taps() {
            head += libm::fabsf(t.w_f32);
            let m = t.delay.saturating_add(1);
            best = best.max(head + tail(m));
        }
        best + older
    }

    /// Switches to `taps` from the next pushed sample on, by superposition (module docs):
    /// the tables in flight keep shaping the reference up to the newest sample, held there;
    /// `taps` shapes the increments after it. No jump, no wait. Errors (nothing changes):
    /// [`SwitchError::Budget`], [`SwitchError::Stages`], [`SwitchError::TooLong`].
    pub fn switch(&mut self, taps: TapTable) -> Result<(), SwitchError> {
        self.can_switch(&taps)?;
        let x_s = self.newest;
        let i = self.idx(self.count - 1);
        let old = &mut self.stages[i];
        if self.steady {
            old.valid = u32::MAX; // its counters stood still in the steady state
            self.steady = false;
        }
        old.closed = true;
        old.skip = 0;
        old.hold = x_s;
        let j = self.idx(self.count);
        let max_delay = true_max_delay(&taps);
        self.stages[j] = Stage::new(taps, max_delay, x_s);
        self.count += 1;
        Ok(())
    }

    /// Pushes `x` (counts, |x| < 2³⁰) and returns the shaped setpoint (counts).
    #[inline]
    pub fn tick(&mut self, buf: &mut [i32; N], x: i32) -> i32 {
        self.ring.push(buf, x);
        self.newest = x;
        if !self.steady {
            self.bookkeeping();
        }
        match (self.path, self.steady) {
            (NumericPath::Fixed, true) => self.fast_fixed(buf),
            (NumericPath::F32, true) => self.fast_f32(buf),
            (NumericPath::Fixed, false) => self.general_fixed(buf),
            (NumericPath::F32, false) => self.general_f32(buf),
        }
    }

    /// Outside the steady state: advances the clamp counters, drops the oldest stages whose
    /// window now reads only their held value (their output is exactly that value, which the
    /// next stage's fill cancels), and detects the steady state (one stage, its whole window
    /// after the last reset or switch), which lasts until the next `switch`/`reset`/`install`.
    #[inline(never)]
    fn bookkeeping(&mut self) {
        for k in 0..self.count {
            let i = self.idx(k);
            let s = &mut self.stages[i];
            s.valid = s.valid.saturating_add(1);
            if s.closed {
                s.skip = s.skip.saturating_add(1);
            }
        }
        while self.count > 1 {
            let s = &self.stages[self.idx(0)];
            if s.closed && s.skip > s.max_delay {
                self.first = (self.first + 1) % MAX_STAGES;
                self.count -= 1;
            } else {
                break;
            }
        }
        self.steady = self.count == 1 && {
            let s = &self.stages[self.idx(0)];
            !s.closed && s.valid > s.max_delay
        };
    }

    /// Steady-state fixed-point kernel: Σ w_q30·x. When the whole window lies in one
    /// unwrapped run of the ring (`max_delay < N − head`: all but `max_delay` ticks in every
    /// N), one unchecked run from `buf[head]`; else the masked indices (no wrap test either).
    #[inline(always)]
    fn fast_fixed(&self, buf: &[i32; N]) -> i32 {
        let s = &self.stages[self.idx(0)];
        let taps = s.taps.taps_padded();
        let head = self.ring.head();
        let acc = if (s.max_delay as usize) < N - head {
            // SAFETY: `head < N` (masked) and every delay d ≤ `max_delay` (the true maximum,
            // computed when the table was staged), so `head + d ≤ head + max_delay < N`:
            // every read is inside `buf`.
            #[allow(unsafe_code)]
            unsafe {
                mac_q30(taps, buf.as_ptr().add(head), 0)
            }
        } else {
            let mut acc = 0i64;
            for t in taps {
                acc += t.w_q30 as i64 * self.ring.get(buf, t.delay) as i64;
            }
            acc
        };
        round_q30(acc)
    }

    /// Steady-state f32 kernel: Σ w_f32·(x − x_newest), as [`EngineState::fast_fixed`].
    #[inline(always)]
    fn fast_f32(&self, buf: &[i32; N]) -> i32 {
        let s = &self.stages[self.idx(0)];
        let taps = s.taps.taps_padded();
        let head = self.ring.head();
        let x0 = self.newest;
        let acc = if (s.max_delay as usize) < N - head {
            // SAFETY: as in `fast_fixed`.
            #[allow(unsafe_code)]
            unsafe {
                mac_f32(taps, buf.as_ptr().add(head), x0, 0.0)
            }
        } else {
            let mut acc = 0.0f32;
            for t in taps {
                acc += t.w_f32 * self.ring.get(buf, t.delay).wrapping_sub(x0) as f32;
            }
            acc
        };
        x0.wrapping_add(round_f32(acc))
    }

    /// The tap ranges of stage `s` this tick: `[0, a)` read its held value (closed stages),
    /// `[a, b)` live samples, `[b, len)` its fill value. Binary searches on the sorted taps.
    #[inline(always)]
    fn ranges(s: &Stage) -> (&[Tap], &[Tap], &[Tap]) {
        let taps = s.taps.taps();
        let a = if s.closed {
            taps.partition_point(|t| t.delay < s.skip)
        } else {
            0
        };
        let b = taps.partition_point(|t| t.delay < s.valid).max(a);
        let (held, rest) = taps.split_at(a);
        let (live, filled) = rest.split_at(b - a);
        (held, live, filled)
    }

    /// Any state (transition, or window reaching back before a reset): every stage, its
    /// taps split by its clamps into held, live and filled ranges (the constant ranges as one
    /// weight sum times the value).
    fn general_fixed(&self, buf: &[i32; N]) -> i32 {
        let mut acc: i64 = 0;
        for k in 0..self.count {
            let s = &self.stages[self.idx(k)];
            let (held, live, filled) = Self::ranges(s);
            let w_held: i64 = held.iter().map(|t| t.w_q30 as i64).sum();
            let w_filled: i64 = filled.iter().map(|t| t.w_q30 as i64).sum();
            acc = acc.wrapping_add(w_held.wrapping_mul(s.hold as i64));
            for t in live {
                acc = acc.wrapping_add(t.w_q30 as i64 * self.ring.get(buf, t.delay) as i64);
            }
            acc = acc.wrapping_add(w_filled.wrapping_mul(s.fill as i64));
            if k > 0 {
                acc = acc.wrapping_sub((s.fill as i64) << WEIGHT_FRAC_BITS);
            }
        }
        round_q30(acc)
    }

    fn general_f32(&self, buf: &[i32; N]) -> i32 {
        let x0 = self.newest;
        let mut acc = 0.0f32;
        for k in 0..self.count {
            let s = &self.stages[self.idx(k)];
            // Held samples equal `c` for a closed stage: their differences are 0.
            let c = if s.closed { s.hold } else { x0 };
            let (_, live, filled) = Self::ranges(s);
            for t in live {
                acc += t.w_f32 * self.ring.get(buf, t.delay).wrapping_sub(c) as f32;
            }
            let w_filled: f32 = filled.iter().map(|t| t.w_f32).sum();
            acc += w_filled * s.fill.wrapping_sub(c) as f32;
        }
        x0.wrapping_add(round_f32(acc))
    }

    /// The newest table (the one a transition ends with).
    pub fn taps(&self) -> &TapTable {
        &self.newest_stage().taps
    }

    /// Tables in flight (1 = steady state, more during a transition).
    pub fn stages(&self) -> usize {
        self.count
    }

    /// Ticks until every table in flight would read a constant window if the reference
    /// stayed still from now on: the longest delay over the stages in flight.
    pub fn settle_ticks(&self) -> u32 {
        (0..self.count)
            .map(|k| self.stages[self.idx(k)].max_delay)
            .max()
            .unwrap_or(0)
    }

    /// The numeric path in use.
    pub fn path(&self) -> NumericPath {
        self.path
    }

    /// True while an older table is still settling.
    pub fn in_transition(&self) -> bool {
        self.count > 1
    }
}

/// The largest delay of `taps`, by inspection of every tap (the fast kernels' safety rests
/// on it, not on the table's sort order). O(taps), once per table staged.
fn true_max_delay(taps: &TapTable) -> u32 {
    taps.taps().iter().map(|t| t.delay).max().unwrap_or(0)
}

/// `acc + Σ w_q30·base[d]` over `taps`, four taps per loop iteration.
///
/// # Safety
/// `base.add(d)` must point inside one live `[i32; N]` for every tap's delay `d`
/// (see `EngineState::fast_fixed`). These are the engine's only unchecked reads.
#[inline(always)]
#[allow(unsafe_code)]
unsafe fn mac_q30(taps: &[Tap], base: *const i32, mut acc: i64) -> i64 {
    let x = |t: &Tap| -> i64 {
        // SAFETY: the caller's contract above.
        unsafe { *base.add(t.delay as usize) as i64 }
    };
    let mut quads = taps.chunks_exact(4);
    for c in &mut quads {
        acc += c[0].w_q30 as i64 * x(&c[0]);
        acc += c[1].w_q30 as i64 * x(&c[1]);
        acc += c[2].w_q30 as i64 * x(&c[2]);
        acc += c[3].w_q30 as i64 * x(&c[3]);
    }
    for t in quads.remainder() {
        acc += t.w_q30 as i64 * x(t);
    }
    acc
}

/// `acc + Σ w_f32·(base[d] − x0)` over `taps` in order (the i32 difference is exact for
/// |x| < 2³⁰), four taps per loop iteration.
///
/// # Safety
/// As [`mac_q30`].
#[inline(always)]
#[allow(unsafe_code)]
unsafe fn mac_f32(taps: &[Tap], base: *const i32, x0: i32, mut acc: f32) -> f32 {
    let x = |t: &Tap| -> f32 {
        // SAFETY: the caller's contract of `mac_q30`.
        unsafe { (*base.add(t.delay as usize)).wrapping_sub(x0) as f32 }
    };
    let mut quads = taps.chunks_exact(4);
    for c in &mut quads {
        acc += c[0].w_f32 * x(&c[0]);
        acc += c[1].w_f32 * x(&c[1]);
        acc += c[2].w_f32 * x(&c[2]);
        acc += c[3].w_f32 * x(&c[3]);
    }
    for t in quads.remainder() {
        acc += t.w_f32 * x(t);
    }
    acc
}

/// `x` rounded to the nearest integer, halves away from zero (as `libm::roundf`), saturating
/// at the `i32` range; NaN gives 0. A few instructions instead of a library call: `x − trunc(x)`
/// is exact in f32, so the comparison with ½ decides exactly.
#[inline(always)]
pub fn round_f32(x: f32) -> i32 {
    let t = x as i32; // truncates toward zero, saturates, NaN → 0
    let frac = x - t as f32;
    if frac >= 0.5 {
        t.saturating_add(1)
    } else if frac <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Round half up: floor((acc + 2²⁹) / 2³⁰).
#[inline(always)]
fn round_q30(acc: i64) -> i32 {
    (acc.wrapping_add(1 << (WEIGHT_FRAC_BITS - 1)) >> WEIGHT_FRAC_BITS) as i32
}

/// [`EngineState`] with its own history buffer of `N` samples (host tools and tests; the
/// firmware keeps the buffer apart, see [`crate::runtime`]).
#[derive(Clone, Debug)]
pub struct Engine<const N: usize> {
    state: EngineState<N>,
    buf: [i32; N],
}

impl<const N: usize> Engine<N> {
    /// Identity shaping, fixed-point path, history reading `position` everywhere.
    pub const fn new(position: i32) -> Self {
        Engine {
            state: EngineState::new(position),
            buf: [0; N],
        }
    }

    /// Installs a new tap table and numeric path and resets the history to `position`. A
    /// table whose delays do not fit the history (never the case for one built by
    /// [`TapTable::from_shaper`] with `history_len = N`) installs the identity instead; use
    /// [`Engine::try_install`] to get the error.
    pub fn install(&mut self, taps: TapTable, path: NumericPath, position: i32) {
        if self.try_install(taps, path, position).is_err() {
            let _ = self.try_install(TapTable::identity(), path, position);
        }
    }

    /// Installs a new tap table (see [`EngineState::install`]).
    pub fn try_install(
        &mut self,
        taps: TapTable,
        path: NumericPath,
        position: i32,
    ) -> Result<(), SwitchError> {
        self.state.install(taps, path, position)
    }

    /// Switches the table at the next tick by superposition ([`EngineState::switch`]).
    pub fn switch(&mut self, taps: TapTable) -> Result<(), SwitchError> {
        self.state.switch(taps)
    }

    /// Resets the history to `position` (e.g. after zeroing the position).
    pub fn reset(&mut self, position: i32) {
        self.state.reset(position);
    }

    /// One tick: pushes `x` (counts, |x| < 2³⁰) and returns the shaped setpoint (counts).
    #[inline]
    pub fn tick(&mut self, x: i32) -> i32 {
        self.state.tick(&mut self.buf, x)
    }

    /// The newest table.
    pub fn taps(&self) -> &TapTable {
        self.state.taps()
    }

    /// The numeric path in use.
    pub fn path(&self) -> NumericPath {
        self.state.path()
    }

    /// The engine state.
    pub fn state(&self) -> &EngineState<N> {
        &self.state
    }
}
