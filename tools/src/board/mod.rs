//! The virtual board: the firmware's core (console + tick loop) running on the host, with the
//! console on a pseudo-terminal, so that everything can be tried without hardware and the
//! tools program it through the same serial-port code ([`client`]) as a real board.
//!
//! Flash is emulated by a file holding the encoded settings record
//! ([`beamshaper::config::Settings::encode`]); writes go to a temporary file that is renamed
//! over the old one, so an interrupted save leaves the previous record intact.

pub mod accel;
pub mod client;
pub mod plan;
pub mod rig;
pub mod session;
pub mod steps;

use beamshaper::config::Settings;
use beamshaper::console::{Action, Console, LineBuffer, LineError};
use beamshaper::protocol::{Refusal, LINE_TOO_LONG};
use beamshaper::runtime::{Runtime, TickInput};
use beamshaper::storage::StorageError;
use serialport::SerialPort;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why the virtual board cannot be served.
#[derive(Debug, Error)]
pub enum VboardError {
    /// `--time-scale` out of range ([`check_time_scale`]).
    #[error("{0}")]
    TimeScale(String),
    /// The pseudo-terminal cannot be created or has no name.
    #[error("cannot create a pseudo-terminal")]
    Pty(#[source] serialport::Error),
    /// The pseudo-terminal has no device name.
    #[error("pseudo-terminal has no name")]
    PtyName,
    /// The serial port failed.
    #[error("virtual board: serial {0}")]
    Serial(&'static str, #[source] std::io::Error),
}

/// An error and its causes, `: `-separated (what `{:#}` of an `anyhow` error shows).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

/// The core plus emulated flash.
pub struct VirtualBoard {
    rt: Box<Runtime>,
    console: Console,
    flash: Option<PathBuf>,
    lines: LineBuffer,
    rig: Option<rig::VirtualRig>,
    rig_error: Option<String>,
    ticks_since_poll: u32,
}

/// Reads the emulated flash: `Ok(None)` if there is no record; `Err(Version)` for an intact
/// record of another format version, `Err(Corrupt)` for a corrupt or invalid one,
/// `Err(Flash)` if the file cannot be read.
pub fn load_flash(path: &Path) -> std::result::Result<Option<Settings>, StorageError> {
    match std::fs::read(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(_) => Err(StorageError::Flash),
        Ok(bytes) => Ok(Some(Settings::decode(&bytes)?)),
    }
}

fn save_flash(path: &Path, s: &Settings) -> std::result::Result<(), String> {
    let mut buf = [0u8; beamshaper::config::SETTINGS_MAX_BYTES];
    let n = s.encode(&mut buf).map_err(|e| e.to_string())?;
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, &buf[..n]).map_err(|e| e.to_string())?;
    std::fs::rename(&tmp, path).map_err(|e| e.to_string())
}

impl VirtualBoard {
    /// Boots: loads the flash file (if given) and writes the boot messages to `out`.
    pub fn boot(flash: Option<PathBuf>, out: &mut impl std::fmt::Write) -> Self {
        let mut rt = Box::new(Runtime::new());
        let loaded = match &flash {
            Some(p) => load_flash(p),
            None => Ok(None),
        };
        let console = Console::boot(loaded, &mut *rt, 0, out);
        VirtualBoard {
            rt,
            console,
            flash,
            lines: LineBuffer::new(),
            rig: None,
            rig_error: None,
            ticks_since_poll: 0,
        }
    }

    /// Attaches a virtual rig to the setpoint output: from now on every tick drives it. With
    /// an accelerometer on it, the board's watch gets its samples (the only way the watch
    /// learns anything about the rig).
    pub fn attach_rig(&mut self, rig: rig::VirtualRig) {
        let accel = rig.accel_config();
        self.rig = Some(rig);
        if accel.is_some() {
            self.console.set_accel(accel, &mut *self.rt);
        }
    }

    /// The console (for inspection).
    pub fn console(&self) -> &Console {
        &self.console
    }

    /// Why the attached rig stopped (its sensor log could not be written), if it did.
    pub fn rig_error(&self) -> Option<&str> {
        self.rig_error.as_deref()
    }

    /// Feeds received bytes; returns the reply text of every completed line.
    pub fn receive(&mut self, bytes: &[u8]) -> String {
        let mut out = String::new();
        for &b in bytes {
            match self.lines.push(b) {
                Some(Ok(line)) => {
                    let action = self.console.handle_line(&line, &mut *self.rt, &mut out);
                    self.finish(action, &mut out);
                }
                Some(Err(LineError::TooLong)) => {
                    out.push_str(&format!("{LINE_TOO_LONG}\n"));
                }
                None => {}
            }
        }
        out
    }

    fn finish(&mut self, action: Action, out: &mut String) {
        match (action, &self.flash) {
            (Action::None, _) => {}
            (Action::Save, Some(p)) => {
                let r = save_flash(p, self.console.settings());
                self.console.finish_save(r, out);
            }
            (Action::Load, Some(p)) => {
                let r = load_flash(p);
                self.console.finish_load(r, &mut *self.rt, out);
            }
            (_, None) => {
                let no_flash =
                    Refusal::new("storage", "this virtual board has no flash file (--flash)");
                out.push_str(&format!("{no_flash}\n"))
            }
        }
    }

    /// Advances `n` ticks.
    pub fn tick(&mut self, n: u64) {
        for _ in 0..n {
            let out = self.rt.tick(&TickInput::default());
            if let Some(r) = self.rig.as_mut() {
                let step_nm = self.rt.params().step_nm.max(1) as i64;
                let steps = (out.setpoint_counts as i64).div_euclid(step_nm);
                let res = r.tick(
                    out.setpoint_counts as f64 * 1e-9,
                    (steps * step_nm) as f64 * 1e-9,
                );
                if let Err(e) = res {
                    self.rig_error = Some(error_chain(&e));
                    self.rig = None;
                    continue;
                }
                for ev in r.take_accel() {
                    self.console.watch_event(ev);
                }
            }
            // The firmware's sensor task polls the watch at its FIFO rate; here every 10 ticks.
            self.ticks_since_poll += 1;
            if self.ticks_since_poll >= 10 {
                self.ticks_since_poll = 0;
                self.console.watch_poll(&mut *self.rt);
            }
        }
    }

    /// The runtime (for inspection).
    pub fn runtime(&self) -> &Runtime {
        &self.rt
    }

    /// Serves the console on `port` forever (or until the peer closes it), ticking at the
    /// board's tick rate × `time_scale` of wall-clock time ([`TickClock`]: a tick-rate change
    /// takes effect from the moment it is applied, without a freeze or a burst).
    /// Errors: an invalid `time_scale` ([`check_time_scale`]), a serial error.
    pub fn serve(&mut self, port: &mut dyn SerialPort, time_scale: f64) -> Result<(), VboardError> {
        check_time_scale(time_scale).map_err(VboardError::TimeScale)?;
        let start = Instant::now();
        let mut clock = TickClock::new(0.0, self.rt.tick_rate_hz(), time_scale);
        let mut buf = [0u8; 256];
        port.set_timeout(Duration::from_millis(1))
            .map_err(|e| VboardError::Serial("timeout", e.into()))?;
        loop {
            match port.read(&mut buf) {
                Ok(0) => {}
                Ok(n) => {
                    let reply = self.receive(&buf[..n]);
                    if !reply.is_empty() {
                        port.write_all(reply.as_bytes())
                            .and_then(|_| port.flush())
                            .map_err(|e| VboardError::Serial("write", e))?;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(VboardError::Serial("read", e)),
            }
            let now_s = start.elapsed().as_secs_f64();
            for _ in 0..clock.due(now_s) {
                self.tick(1); // drives the attached rig too
                clock.ticked(now_s, self.rt.tick_rate_hz());
            }
        }
    }
}

/// Most ticks the virtual board catches up in one go; a larger backlog (a stalled host) is
/// dropped, so the console never freezes behind it.
pub const MAX_CATCH_UP_TICKS: u64 = 200_000;

/// Accepted `--time-scale` range: from one thousandth to a thousand times real time.
pub const TIME_SCALE_RANGE: (f64, f64) = (1e-3, 1e3);

/// Checks a virtual-board time scale: finite and within [`TIME_SCALE_RANGE`] (0, negative,
/// NaN, inf and tiny values would freeze the board or make it burst). Returns it.
pub fn check_time_scale(s: f64) -> std::result::Result<f64, String> {
    let (lo, hi) = TIME_SCALE_RANGE;
    if s.is_finite() && (lo..=hi).contains(&s) {
        Ok(s)
    } else {
        Err(format!(
            "time scale must be a number from {lo} to {hi} (times real time), got {s}"
        ))
    }
}

/// Schedules the virtual board's ticks on wall-clock time: ticks due = time since the last
/// tick-rate change × time scale × the rate in force since then (not since boot, which froze
/// the board after a rate decrease and burst after an increase), with the catch-up bounded
/// by [`MAX_CATCH_UP_TICKS`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickClock {
    /// Time (s) from which `rate_hz` counts.
    epoch_s: f64,
    rate_hz: u32,
    scale: f64,
    /// Ticks done since `epoch_s`.
    done: u64,
}

impl TickClock {
    /// A clock starting at `now_s` (s) at `rate_hz` × `scale`.
    pub fn new(now_s: f64, rate_hz: u32, scale: f64) -> Self {
        TickClock {
            epoch_s: now_s,
            rate_hz,
            scale,
            done: 0,
        }
    }

    /// Ticks to run now (≤ [`MAX_CATCH_UP_TICKS`]; an older backlog is dropped).
    pub fn due(&mut self, now_s: f64) -> u64 {
        let due = ((now_s - self.epoch_s).max(0.0) * self.scale * self.rate_hz as f64) as u64;
        if due > self.done + MAX_CATCH_UP_TICKS {
            self.done = due - MAX_CATCH_UP_TICKS;
        }
        due.saturating_sub(self.done)
    }

    /// Records one tick done at `now_s` after which the board's rate is `rate_hz`: a changed
    /// rate counts from `now_s` on.
    pub fn ticked(&mut self, now_s: f64, rate_hz: u32) {
        self.done += 1;
        if rate_hz != self.rate_hz {
            *self = TickClock::new(now_s, rate_hz, self.scale);
        }
    }

    /// Tick rate the clock schedules (Hz).
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }
}

#[cfg(test)]
mod flash_tests {
    use super::*;

    /// A flash file holding an intact record of another format version (here version 1, as
    /// the hand-written codec wrote it) boots with defaults, the console names the version,
    /// `load` refuses it with `err version:`, and `save` replaces it with a readable record.
    #[test]
    fn an_old_format_record_boots_with_defaults_and_the_console_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let flash = dir.path().join("flash.bin");
        // Magic, version 1, then a body; the CRC-32/ISO-HDLC of it all (valid).
        let mut v1 = b"BSH\x01".to_vec();
        v1.extend_from_slice(&[0u8; 40]);
        let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&v1);
        v1.extend_from_slice(&crc.to_le_bytes());
        std::fs::write(&flash, &v1).unwrap();
        assert_eq!(load_flash(&flash), Err(StorageError::Version(1)));
        let mut boot = String::new();
        let mut b = VirtualBoard::boot(Some(flash.clone()), &mut boot);
        assert!(
            boot.contains("stored settings are format version 1, this firmware reads version 4"),
            "{boot}"
        );
        assert!(
            boot.ends_with("# boot: using defaults\nok boot\n"),
            "{boot}"
        );
        assert_eq!(b.console.settings(), &Settings::DEFAULT);
        let r = b.receive(b"mode 1 zv 3 0.01\nload\n");
        assert!(r.contains("\nerr version: "), "{r}");
        assert!(
            b.console.settings().modes[0].is_some(),
            "load changed the settings"
        );
        assert!(b.receive(b"save\n").contains("ok save"));
        assert!(load_flash(&flash).unwrap().unwrap().modes[0].is_some());
    }
}

#[cfg(test)]
mod clock_tests {
    use super::*;

    /// Runs the clock like `serve` does, with the rate changing to `new_rate` once the board
    /// has ticked `change_after` times; returns the ticks done by each of `times`.
    fn run(times: &[f64], change_after: u64, new_rate: u32) -> Vec<u64> {
        let mut c = TickClock::new(0.0, 1000, 1.0);
        let mut rate = 1000;
        let mut total = 0u64;
        let mut out = vec![];
        for &t in times {
            for _ in 0..c.due(t) {
                total += 1;
                if total == change_after {
                    rate = new_rate;
                }
                c.ticked(t, rate);
            }
            out.push(total);
        }
        out
    }

    #[test]
    fn a_rate_decrease_does_not_freeze_the_board() {
        // 10 s at 1 kHz, then `rate 500`: 0.1 s later ~50 more ticks (the old code: none for
        // another 10 s).
        let times: Vec<f64> = (1..=101).map(|k| k as f64 * 0.1).collect();
        let done = run(&times, 10_000, 500);
        let at_10 = done[99];
        assert_eq!(at_10, 10_000);
        assert!(
            (49..=51).contains(&(done[100] - at_10)),
            "{}",
            done[100] - at_10
        );
    }

    #[test]
    fn a_rate_increase_does_not_burst() {
        // 10 s at 1 kHz, then `rate 10000`: 1 ms later ~10 ticks (the old code: 90 000).
        let times = [5.0, 10.0, 10.001, 10.002];
        let done = run(&times, 10_000, 10_000);
        assert_eq!(done[1], 10_000);
        assert!(
            done[2] - done[1] <= 11 && done[3] - done[2] <= 11,
            "{done:?}"
        );
    }

    #[test]
    fn a_stalled_host_catches_up_boundedly() {
        let mut c = TickClock::new(0.0, 10_000, 1.0);
        assert_eq!(c.due(1000.0), MAX_CATCH_UP_TICKS);
    }

    #[test]
    fn time_scales_that_would_freeze_or_burst_are_refused() {
        for s in [0.0, -1.0, f64::NAN, 1e-9, f64::INFINITY, 1e6] {
            assert!(check_time_scale(s).is_err(), "{s}");
        }
        for s in [1e-3, 0.5, 1.0, 10.0, 1e3] {
            assert_eq!(check_time_scale(s), Ok(s));
        }
    }
}

/// Creates a pseudo-terminal pair and serves a virtual board on its master side in a
/// background thread. Returns the slave device path (e.g. `/dev/pts/5`) to open with
/// [`client::BoardClient::open`], exactly like a real board's `/dev/ttyACM0`.
pub fn spawn_on_pty(flash: Option<PathBuf>, time_scale: f64) -> Result<String, VboardError> {
    spawn_on_pty_with_rig(flash, time_scale, None)
}

/// [`spawn_on_pty`] with a virtual rig attached to the board's setpoint output.
pub fn spawn_on_pty_with_rig(
    flash: Option<PathBuf>,
    time_scale: f64,
    rig: Option<rig::VirtualRig>,
) -> Result<String, VboardError> {
    let (mut master, slave) = serialport::TTYPort::pair().map_err(VboardError::Pty)?;
    let path = slave.name().ok_or(VboardError::PtyName)?;
    // Keep the slave side open for the lifetime of the thread so the master never sees EOF
    // between client connections.
    std::thread::spawn(move || {
        let _keep = slave;
        let mut boot = String::new();
        let mut board = VirtualBoard::boot(flash, &mut boot);
        if let Some(r) = rig {
            board.attach_rig(r);
        }
        let _ = master.write_all(boot.as_bytes());
        let _ = board.serve(&mut master, time_scale);
    });
    Ok(path)
}
