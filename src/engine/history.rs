//! Ring buffer of past reference samples (integer counts).

/// The last `N` reference samples, `N` a power of two.
///
/// Samples older than the last [`History::reset`] read as the reset value: after a reset the
/// history behaves as if the reference had been constant forever, in O(1) (no buffer fill
/// inside the interrupt).
#[derive(Clone, Debug)]
pub struct History<const N: usize> {
    buf: [i32; N],
    /// Index of the newest sample.
    head: usize,
    /// Samples pushed since the last reset (saturates at N).
    len: usize,
    /// Value of every sample older than the last reset.
    fill: i32,
}

impl<const N: usize> History<N> {
    const POW2: () = assert!(
        N.is_power_of_two() && N >= 2,
        "history length must be a power of two"
    );

    /// A history that reads `fill` everywhere.
    pub const fn new(fill: i32) -> Self {
        #[allow(clippy::let_unit_value)]
        let _ = Self::POW2;
        History {
            buf: [0; N],
            head: 0,
            len: 0,
            fill,
        }
    }

    /// Capacity in samples.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Forgets the past: every sample reads `value` until new samples are pushed.
    pub fn reset(&mut self, value: i32) {
        self.len = 0;
        self.fill = value;
    }

    /// Appends the newest sample.
    #[inline]
    pub fn push(&mut self, x: i32) {
        self.head = (self.head + 1) & (N - 1);
        if let Some(slot) = self.buf.get_mut(self.head) {
            *slot = x;
        }
        if self.len < N {
            self.len += 1;
        }
    }

    /// The sample `delay` ticks ago (0 = newest). Delays beyond what was pushed since the
    /// last reset (or ≥ N) read the reset value. Never panics.
    #[inline]
    pub fn get(&self, delay: u32) -> i32 {
        let d = delay as usize;
        if d >= self.len {
            return self.fill;
        }
        self.buf
            .get((self.head + N - d) & (N - 1))
            .copied()
            .unwrap_or(self.fill)
    }

    /// The newest sample.
    #[inline]
    pub fn newest(&self) -> i32 {
        self.get(0)
    }
}
