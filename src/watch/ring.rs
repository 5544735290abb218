//! The tick's side of the watch: every `decimation` ticks the shaped setpoint (nm) goes into a
//! small ring, which the estimator reads in thread mode ([`SetpointRing::copy_since`]). A few
//! instructions per tick (a counter, a compare, one store every `decimation` ticks); the
//! estimator itself never runs in the interrupt.

/// Setpoints the ring holds: at the watch's decimated rate (≤ 200 Hz) 1.28 s or more, so the
/// thread may read it that late.
pub const RING_LEN: usize = 256;

/// Decimated setpoints, written by the tick.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SetpointRing {
    buf: [i32; RING_LEN],
    /// The setpoint's change over the tick that recorded it (nm): with it the watch forms the
    /// block mean of the setpoint's acceleration exactly (a telescoping sum).
    step: [i32; RING_LEN],
    /// Setpoints written since [`SetpointRing::arm`] (wrapping).
    written: u32,
    phase: u32,
    /// Ticks per setpoint; 0 = off (the tick does nothing more than one compare).
    decimation: u32,
}

impl Default for SetpointRing {
    fn default() -> Self {
        Self::new()
    }
}

impl SetpointRing {
    /// Off and empty.
    pub const fn new() -> Self {
        SetpointRing {
            buf: [0; RING_LEN],
            step: [0; RING_LEN],
            written: 0,
            phase: 0,
            decimation: 0,
        }
    }

    /// Starts recording one setpoint every `decimation` ticks (0 stops), from the next tick;
    /// the count of written setpoints restarts at 0.
    pub fn arm(&mut self, decimation: u32) {
        self.decimation = decimation;
        self.phase = 0;
        self.written = 0;
    }

    /// Ticks per setpoint (0 = off).
    pub fn decimation(&self) -> u32 {
        self.decimation
    }

    /// Setpoints written since [`SetpointRing::arm`] (wrapping u32).
    pub fn written(&self) -> u32 {
        self.written
    }

    /// The tick's part: this tick's setpoint (nm) and the previous tick's.
    #[inline(always)]
    pub fn record(&mut self, setpoint_nm: i32, previous_nm: i32) {
        if self.decimation == 0 {
            return;
        }
        self.phase += 1;
        if self.phase >= self.decimation {
            self.phase = 0;
            let i = self.written as usize % RING_LEN;
            self.buf[i] = setpoint_nm;
            self.step[i] = setpoint_nm.wrapping_sub(previous_nm);
            self.written = self.written.wrapping_add(1);
        }
    }

    /// Copies the setpoints with index `from`, `from + 1`, … (at most `out.len()`, only those
    /// still in the ring and already written) into `out`, with their one-tick changes into
    /// `steps` (nm). Returns how many were copied and the index of the first one (later than
    /// `from` when the reader fell more than [`RING_LEN`] behind: the older ones are lost).
    pub fn copy_since(&self, from: u32, out: &mut [i32], steps: &mut [i32]) -> (usize, u32) {
        let behind = self.written.wrapping_sub(from);
        let (first, avail) = if behind as usize > RING_LEN {
            (self.written.wrapping_sub(RING_LEN as u32), RING_LEN)
        } else {
            (from, behind as usize)
        };
        let n = avail.min(out.len()).min(steps.len());
        for (i, (slot, d)) in out.iter_mut().zip(steps.iter_mut()).take(n).enumerate() {
            let k = first.wrapping_add(i as u32) as usize % RING_LEN;
            *slot = self.buf[k];
            *d = self.step[k];
        }
        (n, first)
    }
}
