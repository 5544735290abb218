//! The drift watch: from the tip accelerometer ([`crate::sensor`]) and the shaped setpoint the
//! tick wrote ([`ring::SetpointRing`]), it estimates, after every move, the natural frequency
//! and damping ratio of each mode the installed shaper targets, measures the residual vibration
//! after the move, and compares the frequencies with the band certified for the shaper.
//!
//! **Method** (docs/watch.md). Both signals are decimated to a common rate `fs` (50–250 Hz,
//! ≥ 5 × the highest watched mode): the acceleration by the mean of `rate / fs` samples, the
//! setpoint's acceleration by the same block mean (from the ring's one-tick changes). A move
//! is the span from the first change of the decimated setpoint until it has been still for
//! `max(3 / f_min, 1 s)`. Over the move (and `max(1.5 / f_min, 0.5 s)` after it) the modal
//! output model of [`modal`] is fitted by variable projection: input the setpoint's
//! acceleration, output the tip acceleration, one relative-acceleration filter per watched mode
//! plus the carriage's terms and the vibration the move started with. Using the known setpoint
//! as input is what makes a well-shaped move measurable: the beam vibrates *during* the move
//! even when nothing is left after it (at 1.1 Hz the residual of a good shaper is below one
//! ADXL345 step). Each watched mode is searched within ±[`MATCH_RANGE`] of the shaper's
//! frequency, its damping ratio within [`modal::ZETA_RANGE`]. The residual is the RMS of the
//! tip acceleration about its mean once the shaped setpoint is still.
//!
//! The estimator gets no frequency from anywhere but the installed shaper (where to search,
//! and the decimated rate) and its own signals.
//!
//! **Bad input.** A [`SensorEvent::Lost`], a sensor silent while the tick keeps writing
//! setpoints, a saturated sample or a move over which every reading was the same make that
//! move's result [`WatchState::NoSensor`] or [`WatchState::Saturated`]: no frequency is
//! reported for it and nothing is retuned.
//!
//! **Cost.** [`Watch::push`]: a few additions per accelerometer sample. [`Watch::poll`]: per
//! decimated sample a copy into the move buffer; once per move the fit (bounded: a fixed
//! number of evaluations, each linear in the move's samples, ≤ [`modal::MOVE_LEN`]).
//! Measured under QEMU: README, docs/watch.md.

pub mod modal;
pub mod ring;

use crate::config::{Settings, MAX_MODES};
use crate::sensor::{AccelConfig, SensorEvent};
use modal::{ModalGuess, MoveBuffer};
use ring::SetpointRing;

/// A watched mode's pole must lie within this fraction of the shaper's frequency (±35 %).
pub const MATCH_RANGE: f64 = 0.35;
/// Largest damping ratio accepted for a watched mode's pole.
pub const ZETA_MAX: f64 = 0.3;
/// Decimated acceleration samples the thread may leave unread ([`Watch::poll`]).
pub const QUEUE_LEN: usize = 64;
/// The first moves after `watch on` whose mean residual is the reference of
/// `residual_ratio`.
pub const REFERENCE_MOVES: u32 = 2;
/// Vibration tolerance (fraction) of the band used when the certificate holds none for a
/// slot: the shaper's own insensitivity band at 5 % ([`crate::shaper::insensitivity_band`]).
pub const FALLBACK_BAND_V_TOL: f64 = 0.05;
/// Longest move fitted (s); a longer one is fitted at this length.
pub const MAX_FIT_S: f32 = 60.0;
/// Decimated rates the watch may use (Hz), lowest first; one must divide the tick rate and
/// the accelerometer's rate.
pub const RATES_HZ: [u32; 5] = [50, 100, 125, 200, 250];

/// One measured mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoleMode {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio (dimensionless).
    pub zeta: f64,
}

/// What the watch says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WatchState {
    /// Not watching.
    Off,
    /// The measured frequencies lie in their bands (or no move measured yet).
    Ok,
    /// A measured frequency left its band.
    Drift,
    /// The sensor is absent, stopped answering, lost samples or reads a constant.
    NoSensor,
    /// The sensor reached its full scale during the move.
    Saturated,
}

impl WatchState {
    /// `off`, `ok`, `drift`, `no_sensor`, `saturated`.
    pub fn name(self) -> &'static str {
        match self {
            WatchState::Off => "off",
            WatchState::Ok => "ok",
            WatchState::Drift => "drift",
            WatchState::NoSensor => "no_sensor",
            WatchState::Saturated => "saturated",
        }
    }

    /// The inverse of [`WatchState::name`].
    pub fn from_name(s: &str) -> Option<WatchState> {
        [
            WatchState::Off,
            WatchState::Ok,
            WatchState::Drift,
            WatchState::NoSensor,
            WatchState::Saturated,
        ]
        .into_iter()
        .find(|w| w.name() == s)
    }
}

/// One watched mode: the shaper's slot and frequency, its band, the last measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchedMode {
    /// Mode slot of the shaper (0-based).
    pub slot: usize,
    /// The shaper's natural frequency for it (Hz).
    pub shaper_freq_hz: f64,
    /// The shaper's damping ratio for it.
    pub shaper_zeta: f64,
    /// The band (Hz) it is compared with: the certificate's, else the shaper's 5 %
    /// insensitivity band.
    pub band_hz: (f64, f64),
    /// Last measured mode (frequency Hz, damping ratio), if the last move resolved it.
    pub measured: Option<PoleMode>,
    /// The measurement of the move before it.
    pub previous: Option<PoleMode>,
}

/// Two consecutive measurements confirm each other when their frequencies differ by less
/// than this fraction (an automatic retune needs it: a move that started with the beam
/// still ringing from a mistuned one can mislead a single fit).
pub const CONFIRM_FRACTION: f64 = 0.01;

impl WatchedMode {
    /// The mean frequency (Hz) of the last two measurements when they confirm each other
    /// ([`CONFIRM_FRACTION`]).
    pub fn confirmed_hz(&self) -> Option<f64> {
        let (a, b) = (self.measured?.freq_hz, self.previous?.freq_hz);
        (libm::fabs(a / b - 1.0) < CONFIRM_FRACTION).then_some(0.5 * (a + b))
    }

    /// The last measurement lies outside the band.
    pub fn drifted(&self) -> bool {
        self.measured
            .is_some_and(|p| !(self.band_hz.0..=self.band_hz.1).contains(&p.freq_hz))
    }
}

/// The watch's current report (the console's `watch` line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchReport {
    /// State.
    pub state: WatchState,
    /// The watched modes in slot order.
    pub modes: [Option<WatchedMode>; MAX_MODES],
    /// RMS of the tip acceleration about its mean after the last move (m/s²).
    pub residual_rms_m_s2: Option<f64>,
    /// That residual over the mean of the first [`REFERENCE_MOVES`] moves' after `watch on`.
    pub residual_ratio: Option<f64>,
    /// Moves measured since `watch on`.
    pub moves: u32,
}

/// Move segmentation.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Idle,
    /// In a move; `still` decimated samples since the setpoint last changed.
    Moving {
        still: u32,
    },
}

/// Statistics of one move's raw and decimated acceleration.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MoveStats {
    raw_min: f32,
    raw_max: f32,
    saturated: bool,
    lost: bool,
    /// Σ, Σ², n of the decimated acceleration once the setpoint is still (the residual).
    res: (f64, f64, u32),
    samples: u32,
}

impl MoveStats {
    const NEW: MoveStats = MoveStats {
        raw_min: f32::INFINITY,
        raw_max: f32::NEG_INFINITY,
        saturated: false,
        lost: false,
        res: (0.0, 0.0, 0),
        samples: 0,
    };
}

/// The estimator (thread mode only). `Clone` so the console can be cloned on the host.
#[derive(Clone, Debug)]
pub struct Watch {
    enabled: bool,
    accel: Option<AccelConfig>,
    fs_hz: f64,
    dec_acc: u32,
    dec_tick: u32,
    settle: u32,
    /// Samples after the setpoint stopped that the fit uses (`max(1.5 / f_min, 0.5 s)`).
    settle_fit: u32,
    /// Buffer length when the setpoint last moved.
    move_end: usize,
    max_samples: u32,
    // decimator
    acc_sum: f32,
    acc_n: u32,
    queue: heapless::Deque<f32, QUEUE_LEN>,
    sp_next: u32,
    /// The last setpoint and its one-tick change (nm).
    sp_hist: [i32; 2],
    primed: u32,
    resync_pending: bool,
    phase: Phase,
    stats: MoveStats,
    buf: MoveBuffer,
    report: WatchReport,
    reference: (f64, u32),
}

impl Default for Watch {
    fn default() -> Self {
        Self::new()
    }
}

/// Decimated rate and the two decimations for a tick rate, an accelerometer rate and the
/// highest watched frequency: the lowest of [`RATES_HZ`] ≥ 8 × `f_max_hz` dividing both
/// (else the highest that does). `None` if none divides both.
pub fn decimated_rate(tick_rate_hz: u32, accel_rate_hz: f32, f_max_hz: f64) -> Option<(u32, u32)> {
    let fits = |fs: u32| {
        let a = accel_rate_hz / fs as f32;
        let ai = libm::roundf(a);
        tick_rate_hz % fs == 0 && ai >= 1.0 && libm::fabsf(a - ai) < 1e-3 * ai
    };
    let want = 5.0 * f_max_hz;
    let pick = RATES_HZ
        .iter()
        .copied()
        .find(|&fs| fs as f64 >= want && fits(fs))
        .or_else(|| RATES_HZ.iter().rev().copied().find(|&fs| fits(fs)))?;
    Some((pick, libm::roundf(accel_rate_hz / pick as f32) as u32))
}

impl Watch {
    /// Off, no sensor, nothing watched.
    pub const fn new() -> Self {
        Watch {
            enabled: false,
            accel: None,
            fs_hz: 0.0,
            dec_acc: 0,
            dec_tick: 0,
            settle: 0,
            settle_fit: 0,
            move_end: 0,
            max_samples: 0,
            acc_sum: 0.0,
            acc_n: 0,
            queue: heapless::Deque::new(),
            sp_next: 0,
            sp_hist: [0; 2],
            primed: 0,
            resync_pending: false,
            phase: Phase::Idle,
            stats: MoveStats::NEW,
            buf: MoveBuffer::new(),
            report: WatchReport {
                state: WatchState::Off,
                modes: [None; MAX_MODES],
                residual_rms_m_s2: None,
                residual_ratio: None,
                moves: 0,
            },
            reference: (0.0, 0),
        }
    }

    /// The current report.
    pub fn report(&self) -> &WatchReport {
        &self.report
    }

    /// The accelerometer's configuration (`None`: no sensor).
    pub fn accel(&self) -> Option<AccelConfig> {
        self.accel
    }

    /// Decimated rate in use (Hz; 0 when not watching).
    pub fn rate_hz(&self) -> f64 {
        self.fs_hz
    }

    /// Sets the accelerometer (`None`: the driver found no chip). Call [`Watch::configure`]
    /// afterwards.
    pub fn set_accel(&mut self, accel: Option<AccelConfig>) {
        self.accel = accel;
    }

    /// Resets the counters of `watch on`: moves, the residual reference, the measurements.
    pub fn restart(&mut self) {
        self.report.moves = 0;
        self.report.residual_rms_m_s2 = None;
        self.report.residual_ratio = None;
        self.reference = (0.0, 0);
        for m in self.report.modes.iter_mut().flatten() {
            m.measured = None;
        }
    }

    /// (Re)configures from the settings in force (watched modes, bands, on/off) and the tick
    /// rate; the measurement in progress is dropped, the counters kept. Returns the
    /// decimation the tick's [`SetpointRing`] must be armed with (0 = off); the caller arms
    /// it, which restarts its count, matching this watch's.
    pub fn configure(&mut self, settings: &Settings, tick_rate_hz: u32) -> u32 {
        self.enabled = settings.watch.enabled;
        let old = self.report.modes;
        self.report.modes = watched_modes(settings);
        for (new, old) in self.report.modes.iter_mut().zip(old.iter()) {
            if let (Some(n), Some(o)) = (new.as_mut(), old) {
                n.measured = o.measured;
                n.previous = o.previous;
            }
        }
        let count = self.report.modes.iter().flatten().count();
        let f_max = self
            .report
            .modes
            .iter()
            .flatten()
            .fold(0.0f64, |m, w| m.max(w.shaper_freq_hz));
        let f_min = self
            .report
            .modes
            .iter()
            .flatten()
            .fold(f64::INFINITY, |m, w| m.min(w.shaper_freq_hz));
        self.resync();
        self.dec_tick = 0;
        self.fs_hz = 0.0;
        if !self.enabled {
            self.report.state = WatchState::Off;
            return 0;
        }
        let rates = self
            .accel
            .and_then(|a| decimated_rate(tick_rate_hz, a.rate_hz, f_max));
        let Some((fs, dec_acc)) = rates.filter(|_| count > 0) else {
            if self.accel.is_none() {
                self.report.state = WatchState::NoSensor;
            }
            return 0;
        };
        // The kept measurements compared with the (possibly new) bands: after a retune the
        // last measurement lies in the new shaper's band.
        self.report.state = match self.report.state {
            WatchState::Off | WatchState::Ok | WatchState::Drift => {
                if self.report.modes.iter().flatten().any(|m| m.drifted()) {
                    WatchState::Drift
                } else {
                    WatchState::Ok
                }
            }
            other => other,
        };
        self.fs_hz = fs as f64;
        self.dec_acc = dec_acc;
        self.dec_tick = tick_rate_hz / fs;
        let settle_s = (3.0 / f_min).max(1.0);
        self.settle = (settle_s * self.fs_hz) as u32;
        self.settle_fit = ((1.5 / f_min).max(0.5) * self.fs_hz) as u32;
        self.max_samples = ((MAX_FIT_S * fs as f32) as u32).min(modal::MOVE_LEN as u32);
        self.dec_tick
    }

    /// Drops the measurement in progress and the queued samples; the next setpoint to pair
    /// is index 0 of a freshly armed ring.
    fn resync(&mut self) {
        self.acc_sum = 0.0;
        self.acc_n = 0;
        self.queue.clear();
        self.sp_next = 0;
        self.primed = 0;
        self.resync_pending = false;
        self.phase = Phase::Idle;
        self.stats = MoveStats::NEW;
        self.buf.clear();
    }

    /// One event from the sensor driver, in order. A few additions per sample.
    pub fn push(&mut self, event: SensorEvent) {
        if self.dec_tick == 0 {
            return;
        }
        let s = match event {
            SensorEvent::Lost => {
                // Samples are missing: the pairing with the setpoints restarts at the next
                // poll, and the move in progress is not measured.
                self.stats.lost = true;
                self.acc_sum = 0.0;
                self.acc_n = 0;
                self.queue.clear();
                self.resync_pending = true;
                return;
            }
            SensorEvent::Sample(s) => s,
        };
        let a = s.acc_m_s2;
        self.stats.saturated |= s.saturated || !a.is_finite();
        if a.is_finite() {
            self.stats.raw_min = self.stats.raw_min.min(a);
            self.stats.raw_max = self.stats.raw_max.max(a);
            self.acc_sum += a;
        }
        self.acc_n += 1;
        if self.acc_n >= self.dec_acc {
            let mean = self.acc_sum / self.acc_n as f32;
            self.acc_sum = 0.0;
            self.acc_n = 0;
            if self.queue.push_back(mean).is_err() {
                // The thread did not poll: the pairing is lost for this move.
                self.stats.lost = true;
                self.queue.clear();
            }
        }
    }

    /// Index of the next setpoint this watch wants from the ring
    /// ([`SetpointRing::copy_since`]).
    pub fn next_setpoint(&self) -> u32 {
        self.sp_next
    }

    /// [`Watch::poll`] reading `ring` directly (host, QEMU). The firmware copies the
    /// setpoints out of the interrupt-owned ring first, then polls outside the critical section.
    pub fn poll_ring(&mut self, ring: &SetpointRing) -> Option<WatchState> {
        let mut sp = [0i32; QUEUE_LEN];
        let mut steps = [0i32; QUEUE_LEN];
        let (n, first) = ring.copy_since(self.sp_next, &mut sp, &mut steps);
        self.poll(
            sp.get(..n).unwrap_or(&[]),
            steps.get(..n).unwrap_or(&[]),
            first,
            ring.written(),
        )
    }

    /// Pairs the queued accelerations with `setpoints` and their one-tick `steps` (nm; ring
    /// indices `first`, `first + 1`, …, copied by [`SetpointRing::copy_since`] from
    /// [`Watch::next_setpoint`]; `written` the ring's count then), advances the fit, and at the
    /// end of a move evaluates it. Returns `Some(state)` when a move was just measured (or the
    /// sensor was found silent).
    pub fn poll(
        &mut self,
        setpoints: &[i32],
        steps: &[i32],
        first: u32,
        written: u32,
    ) -> Option<WatchState> {
        if self.dec_tick == 0 {
            return None;
        }
        if self.resync_pending {
            self.resync_pending = false;
            self.sp_next = written;
            self.queue.clear();
            return None;
        }
        if first != self.sp_next {
            // Fell behind the ring: the pairing is lost.
            self.stats.lost = true;
            self.sp_next = first;
            self.queue.clear();
        }
        let pairs = setpoints.len().min(self.queue.len());
        let mut done = None;
        for (&s, &d) in setpoints.iter().zip(steps.iter()).take(pairs) {
            let y = self.queue.pop_front().unwrap_or(0.0);
            self.sp_next = self.sp_next.wrapping_add(1);
            if let Some(st) = self.step(s, d, y as f64) {
                done = Some(st);
            }
        }
        // The ring filled while no acceleration arrived: the sensor is silent.
        let waiting = written.wrapping_sub(self.sp_next) as usize;
        if self.queue.is_empty() && waiting >= ring::RING_LEN / 2 {
            self.sp_next = written;
            self.report.state = WatchState::NoSensor;
            for m in self.report.modes.iter_mut().flatten() {
                m.measured = None;
            }
            self.phase = Phase::Idle;
            self.stats = MoveStats::NEW;
            self.buf.clear();
            done = Some(WatchState::NoSensor);
        }
        done
    }

    /// One decimated pair: setpoint (nm), its one-tick change (nm) and the tip acceleration
    /// (m/s², the mean over the block).
    fn step(&mut self, sp_nm: i32, step_nm: i32, y: f64) -> Option<WatchState> {
        if self.primed == 0 {
            // The first setpoint: the history starts at rest there.
            self.sp_hist = [sp_nm, 0];
        }
        // The mean of the setpoint's acceleration over the block, as the acceleration is
        // averaged: the tick's second differences telescope to the change of its one-tick
        // velocity, (v_k − v_(k−1)) · fs with v = step · tick rate.
        let tick_hz = self.fs_hz * self.dec_tick as f64;
        let u = (step_nm as f64 - self.sp_hist[1] as f64) * 1e-9 * tick_hz * self.fs_hz;
        let moving = sp_nm != self.sp_hist[0];
        self.sp_hist = [sp_nm, step_nm];
        let mut done = None;
        if self.primed >= 1 {
            match self.phase {
                Phase::Idle if moving => {
                    self.phase = Phase::Moving { still: 0 };
                    let keep = (self.stats.lost, self.stats.saturated);
                    self.stats = MoveStats::NEW;
                    (self.stats.lost, self.stats.saturated) = keep;
                    self.buf.clear();
                }
                _ => {}
            }
        } else {
            self.primed += 1;
        }
        if let Phase::Moving { still } = self.phase {
            self.buf.push(u as f32, y as f32);
            if moving {
                self.move_end = self.buf.len();
            }
            self.stats.samples += 1;
            let still = if moving { 0 } else { still + 1 };
            if still == 0 {
                self.stats.res = (0.0, 0.0, 0);
            } else {
                let r = &mut self.stats.res;
                *r = (r.0 + y, r.1 + y * y, r.2 + 1);
            }
            self.phase = Phase::Moving { still };
            if still >= self.settle || self.stats.samples >= self.max_samples {
                done = Some(self.finish());
                self.phase = Phase::Idle;
            }
        } else if !moving {
            // Between moves: faults before a move belong to no move.
            self.stats = MoveStats::NEW;
        }
        done
    }

    /// Evaluates the move just ended.
    fn finish(&mut self) -> WatchState {
        let st = self.stats;
        self.stats = MoveStats::NEW;
        let lsb = self.accel.map_or(0.0, |a| a.lsb_m_s2);
        let state = if st.lost {
            WatchState::NoSensor
        } else if st.saturated {
            WatchState::Saturated
        } else if !(st.raw_max - st.raw_min > 1.5 * lsb) {
            WatchState::NoSensor
        } else {
            return self.evaluate(st);
        };
        self.report.state = state;
        for m in self.report.modes.iter_mut().flatten() {
            m.measured = None;
            m.previous = None;
        }
        state
    }

    /// Fits the watched modes to the move ([`modal::fit_modes`]), measures the residual.
    fn evaluate(&mut self, st: MoveStats) -> WatchState {
        let mut guesses = [ModalGuess {
            freq_hz: 1.0,
            zeta: 0.01,
        }; MAX_MODES];
        let mut n = 0;
        for (g, m) in guesses.iter_mut().zip(self.report.modes.iter().flatten()) {
            *g = ModalGuess {
                freq_hz: m.shaper_freq_hz as f32,
                zeta: (m.shaper_zeta as f32).max(modal::ZETA_RANGE.0),
            };
            n += 1;
        }
        self.buf.truncate(self.move_end + self.settle_fit as usize);
        let fitted = modal::fit_modes(&self.buf, &guesses[..n], self.fs_hz as f32);
        self.buf.clear();
        let mut drift = false;
        let mut resolved = 0;
        for (m, f) in self.report.modes.iter_mut().flatten().zip(fitted.iter()) {
            m.previous = m.measured;
            m.measured = f.map(|g| PoleMode {
                freq_hz: g.freq_hz as f64,
                zeta: g.zeta as f64,
            });
            if m.measured.is_some() {
                resolved += 1;
                drift |= m.drifted();
            }
        }
        let (s, s2, k) = st.res;
        let residual = (k > 0).then(|| {
            let mean = s / k as f64;
            libm::sqrt((s2 / k as f64 - mean * mean).max(0.0))
        });
        self.report.moves = self.report.moves.saturating_add(1);
        if let Some(r) = residual {
            if self.report.moves <= REFERENCE_MOVES {
                self.reference = (self.reference.0 + r, self.reference.1 + 1);
            }
        }
        self.report.residual_rms_m_s2 = residual;
        let (sum, cnt) = self.reference;
        self.report.residual_ratio = residual
            .filter(|_| cnt > 0 && sum > 0.0)
            .map(|r| r / (sum / cnt as f64));
        self.report.state = if resolved == 0 {
            self.report.state
        } else if drift {
            WatchState::Drift
        } else {
            WatchState::Ok
        };
        self.report.state
    }
}

/// The modes the installed shaper targets, with their bands.
fn watched_modes(settings: &Settings) -> [Option<WatchedMode>; MAX_MODES] {
    let mut out = [None; MAX_MODES];
    if !settings.shaping_enabled {
        return out;
    }
    let shaper = settings.shaper().ok();
    for (slot, (m, band)) in settings
        .modes
        .iter()
        .zip(settings.certificate.band_hz.iter())
        .enumerate()
    {
        let Some(m) = m else { continue };
        let band_hz = match band {
            Some((lo, hi)) => (*lo as f64, *hi as f64),
            None => shaper
                .as_ref()
                .and_then(|s| {
                    crate::shaper::insensitivity_band(s, m.freq_hz, m.zeta, FALLBACK_BAND_V_TOL)
                })
                .unwrap_or((m.freq_hz, m.freq_hz)),
        };
        if let Some(o) = out.get_mut(slot) {
            *o = Some(WatchedMode {
                slot,
                shaper_freq_hz: m.freq_hz,
                shaper_zeta: m.zeta,
                band_hz,
                measured: None,
                previous: None,
            });
        }
    }
    out
}
