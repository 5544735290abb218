//! Ring buffer of past reference samples (integer counts), newest first.
//!
//! The buffer is a plain `[i32; N]` (N a power of two) owned by the caller, so that the
//! firmware can keep it in `.bss` and initialise it in place (see [`crate::runtime`]). Samples
//! are stored in *descending* index order: the newest sample is at `head`, the one `d` ticks
//! older at `(head + d) mod N`. A window of delays `0..lim` with `lim = N − head` is therefore
//! one contiguous run `buf[head..]`, and the older delays `lim..N` continue at `buf[0..]`:
//! a tap table sorted by delay splits into at most two runs, each read without wrapping
//! (see [`crate::engine`]).

/// Position of the newest sample in a ring of `N` samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ring<const N: usize> {
    head: usize,
}

impl<const N: usize> Ring<N> {
    const POW2: () = assert!(
        N.is_power_of_two() && N >= 2,
        "history length must be a power of two"
    );

    /// A ring whose newest sample is at index 0.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let _ = Self::POW2;
        Ring { head: 0 }
    }

    /// Capacity in samples.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Index of the newest sample (always < N).
    #[inline(always)]
    pub fn head(&self) -> usize {
        self.head & (N - 1)
    }

    /// Appends the newest sample.
    #[inline(always)]
    pub fn push(&mut self, buf: &mut [i32; N], x: i32) {
        self.head = self.head.wrapping_sub(1) & (N - 1);
        buf[self.head] = x;
    }

    /// The sample `delay` ticks ago (0 = newest), `delay` taken modulo N. Never panics.
    #[inline(always)]
    pub fn get(&self, buf: &[i32; N], delay: u32) -> i32 {
        buf[(self.head + delay as usize) & (N - 1)]
    }

    /// Delays below this limit are stored at `head + delay` (no wrap): `N − head`.
    #[inline(always)]
    pub fn unwrapped_limit(&self) -> u32 {
        (N - self.head()) as u32
    }
}

impl<const N: usize> Default for Ring<N> {
    fn default() -> Self {
        Self::new()
    }
}
