//! The virtual board: the firmware's core (console + tick loop) running on the host, with the
//! console on a pseudo-terminal, so that everything can be tried without hardware and the
//! tools program it through the same serial-port code ([`client`]) as a real board.
//!
//! Flash is emulated by a file holding the encoded settings record
//! ([`beamshaper::config::Settings::encode`]); writes go to a temporary file that is renamed
//! over the old one, so an interrupted save leaves the previous record intact.

pub mod client;
pub mod plan;
pub mod rig;
pub mod session;

use anyhow::{Context, Result};
use beamshaper::config::Settings;
use beamshaper::console::{Action, Console, LineBuffer, LineError};
use beamshaper::runtime::{Runtime, TickInput};
use serialport::SerialPort;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The core plus emulated flash.
pub struct VirtualBoard {
    rt: Box<Runtime>,
    console: Console,
    flash: Option<PathBuf>,
    lines: LineBuffer,
    rig: Option<rig::VirtualRig>,
    rig_error: Option<String>,
}

/// Reads the emulated flash: `Ok(None)` if there is no record, `Err` if it is corrupt.
pub fn load_flash(path: &Path) -> std::result::Result<Option<Settings>, String> {
    match std::fs::read(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("cannot read {}: {e}", path.display())),
        Ok(bytes) => Settings::decode(&bytes)
            .map(Some)
            .map_err(|e| e.to_string()),
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
        }
    }

    /// Attaches a virtual rig to the setpoint output: from now on every tick drives it.
    pub fn attach_rig(&mut self, rig: rig::VirtualRig) {
        self.rig = Some(rig);
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
                    out.push_str("err line-too-long: line longer than 200 bytes discarded\n");
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
                out.push_str("err storage: this virtual board has no flash file (--flash)\n")
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
                let res = r.tick(out.setpoint_counts as f64 * 1e-9, (steps * step_nm) as f64 * 1e-9);
                if let Err(e) = res {
                    self.rig_error = Some(format!("{e:#}"));
                    self.rig = None;
                }
            }
        }
    }

    /// The runtime (for inspection).
    pub fn runtime(&self) -> &Runtime {
        &self.rt
    }

    /// Serves the console on `port` forever (or until the peer closes it), ticking at the
    /// board's tick rate × `time_scale` of wall-clock time.
    pub fn serve(&mut self, port: &mut dyn SerialPort, time_scale: f64) -> Result<()> {
        let start = Instant::now();
        let mut ticks_done: u64 = 0;
        let mut buf = [0u8; 256];
        port.set_timeout(Duration::from_millis(1))?;
        loop {
            match port.read(&mut buf) {
                Ok(0) => {}
                Ok(n) => {
                    let reply = self.receive(&buf[..n]);
                    if !reply.is_empty() {
                        port.write_all(reply.as_bytes())?;
                        port.flush()?;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(e).context("virtual board: serial read"),
            }
            let due =
                (start.elapsed().as_secs_f64() * time_scale * self.rt.tick_rate_hz() as f64) as u64;
            // Bounded catch-up so a stalled host does not freeze the console.
            let n = due.saturating_sub(ticks_done).min(200_000);
            self.tick(n);
            ticks_done += n;
            if due > ticks_done + 200_000 {
                ticks_done = due;
            }
        }
    }
}

/// Creates a pseudo-terminal pair and serves a virtual board on its master side in a
/// background thread. Returns the slave device path (e.g. `/dev/pts/5`) to open with
/// [`client::BoardClient::open`], exactly like a real board's `/dev/ttyACM0`.
pub fn spawn_on_pty(flash: Option<PathBuf>, time_scale: f64) -> Result<String> {
    spawn_on_pty_with_rig(flash, time_scale, None)
}

/// [`spawn_on_pty`] with a virtual rig attached to the board's setpoint output.
pub fn spawn_on_pty_with_rig(
    flash: Option<PathBuf>,
    time_scale: f64,
    rig: Option<rig::VirtualRig>,
) -> Result<String> {
    let (mut master, slave) =
        serialport::TTYPort::pair().context("cannot create a pseudo-terminal")?;
    let path = slave.name().context("pseudo-terminal has no name")?;
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
