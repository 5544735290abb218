//! A typed board session: console commands built from the core's own types
//! ([`beamshaper::config::ModeSetting`], [`beamshaper::shaper::ShaperKind`],
//! [`beamshaper::shaper::Impulse`], [`beamshaper::config::Source`]) and replies parsed into
//! typed values, over the line transport of [`super::client::BoardClient`].
//!
//! The console syntax is the one of [`beamshaper::console`] (its `HELP` lines); this module is
//! the single place on the host that writes or reads it.

use super::client::{BoardClient, Reply};
use beamshaper::config::{ModeSetting, MAX_MODES};
use beamshaper::shaper::{Impulse, ShaperKind};
use std::fmt;
use thiserror::Error;

/// A console command (one line).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `status`.
    Status,
    /// `config`.
    Config,
    /// `shaper`: the combined impulse table.
    Shaper,
    /// `mode <slot 1-4> <kind> <freq_hz> <zeta> [v_tol]`.
    Mode(usize, ModeSetting),
    /// `clear all`.
    ClearAll,
    /// `custom <a>@<t> …`; empty = `custom clear`.
    Custom(Vec<Impulse>),
    /// `shaping on|off`.
    Shaping(bool),
    /// `move <target_mm> <speed_mm_s> <accel_mm_s2>`.
    Move {
        /// Absolute target (mm).
        target_mm: f64,
        /// Peak speed (mm/s).
        speed_mm_s: f64,
        /// Acceleration (mm/s²).
        accel_mm_s2: f64,
    },
    /// `sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>` about the present position.
    Sweep(crate::board::plan::SweepPlan),
    /// `capture <every_n_ticks>`.
    Capture(u32),
    /// `dump <first> <count ≤ 32>`.
    Dump(usize, usize),
    /// `save`.
    Save,
    /// `load`.
    Load,
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Status => write!(f, "status"),
            Command::Config => write!(f, "config"),
            Command::Shaper => write!(f, "shaper"),
            Command::Mode(slot, m) => {
                write!(f, "mode {slot} {} {} {}", m.kind.name(), m.freq_hz, m.zeta)?;
                match m.kind.v_tol() {
                    Some(v) => write!(f, " {v}"),
                    None => Ok(()),
                }
            }
            Command::ClearAll => write!(f, "clear all"),
            Command::Custom(imps) if imps.is_empty() => write!(f, "custom clear"),
            Command::Custom(imps) => {
                write!(f, "custom")?;
                imps.iter()
                    .try_for_each(|i| write!(f, " {}@{}", i.amplitude, i.time_s))
            }
            Command::Shaping(on) => write!(f, "shaping {}", if *on { "on" } else { "off" }),
            Command::Move {
                target_mm,
                speed_mm_s,
                accel_mm_s2,
            } => write!(f, "move {target_mm} {speed_mm_s} {accel_mm_s2}"),
            Command::Sweep(p) => write!(
                f,
                "sweep {} {} {} {} {}",
                p.kind.name(),
                p.f0_hz,
                p.f1_hz,
                p.amplitude_mm,
                p.duration_s
            ),
            Command::Capture(d) => write!(f, "capture {d}"),
            Command::Dump(first, n) => write!(f, "dump {first} {n}"),
            Command::Save => write!(f, "save"),
            Command::Load => write!(f, "load"),
        }
    }
}

/// Why a session step failed.
#[derive(Debug, Error)]
pub enum SessionError {
    /// The transport failed or the board answered `err` (the message says which).
    #[error(transparent)]
    Board(#[from] anyhow::Error),
    /// A reply lacks a field or a field does not parse.
    #[error("malformed reply to `{command}`: {what} in `{line}`")]
    Malformed {
        /// The command sent.
        command: String,
        /// What was wrong.
        what: String,
        /// The reply's final line.
        line: String,
    },
}

/// `status` reply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Status {
    /// Ticks since boot.
    pub ticks: u64,
    /// Shaped setpoint (mm).
    pub setpoint_mm: f64,
    /// A move is running.
    pub moving: bool,
    /// A configuration change waits for the shaper's history to be still.
    pub pending: bool,
    /// Ticks the reference has been still.
    pub still_ticks: u64,
    /// Duration of the active shaper (ticks).
    pub duration_ticks: u64,
    /// Tick rate (Hz).
    pub tick_hz: f64,
    /// Ticks that needed more than the maximum step rate.
    pub step_rate_faults: u64,
}

/// `config` reply: the settings that matter to the host.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardConfig {
    /// Mode slots.
    pub modes: [Option<ModeSetting>; MAX_MODES],
    /// Shaping on.
    pub shaping: bool,
    /// Tick rate (Hz).
    pub tick_hz: u32,
    /// nm per output step.
    pub step_nm: u32,
    /// Maximum output step rate (steps/s).
    pub max_step_rate_hz: u32,
    /// Reference source is the console's own moves.
    pub source_internal: bool,
    /// Impulses in the custom list.
    pub custom_len: usize,
}

/// `capture` reply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureInfo {
    /// Setpoints the buffer holds.
    pub capacity: usize,
    /// Capture sample rate (Hz).
    pub sample_rate_hz: f64,
}

/// The session.
pub struct Session {
    client: BoardClient,
}

fn field<'a>(r: &'a Reply, cmd: &Command, key: &str) -> Result<&'a str, SessionError> {
    r.field(key).ok_or_else(|| SessionError::Malformed {
        command: cmd.to_string(),
        what: format!("no `{key}=`"),
        line: r.ok.clone(),
    })
}

fn num<T: std::str::FromStr>(r: &Reply, cmd: &Command, key: &str) -> Result<T, SessionError> {
    let v = field(r, cmd, key)?;
    v.parse().map_err(|_| SessionError::Malformed {
        command: cmd.to_string(),
        what: format!("`{key}={v}` is not a number"),
        line: r.ok.clone(),
    })
}

/// Parses `# mode <slot> <kind> <freq> <zeta> [v_tol]` / `# mode <slot> none` info lines.
fn parse_mode_line(l: &str) -> Option<(usize, Option<ModeSetting>)> {
    let w: Vec<&str> = l.split_whitespace().collect();
    if w.first() != Some(&"mode") {
        return None;
    }
    let slot: usize = w.get(1)?.parse().ok()?;
    if !(1..=MAX_MODES).contains(&slot) {
        return None;
    }
    if w.get(2) == Some(&"none") {
        return Some((slot, None));
    }
    let v_tol = match w.get(5) {
        Some(v) => v.parse().ok()?,
        None => beamshaper::shaper::design::DEFAULT_V_TOL,
    };
    let kind = ShaperKind::from_name(w.get(2)?, v_tol)?;
    Some((
        slot,
        Some(ModeSetting {
            kind,
            freq_hz: w.get(3)?.parse().ok()?,
            zeta: w.get(4)?.parse().ok()?,
        }),
    ))
}

impl Session {
    /// Opens the board's serial port (real or PTY).
    pub fn open(port: &str) -> Result<Self, SessionError> {
        Ok(Session {
            client: BoardClient::open(port)?,
        })
    }

    /// Wraps an open client.
    pub fn new(client: BoardClient) -> Self {
        Session { client }
    }

    /// Sets the reply timeout.
    pub fn set_timeout(&mut self, t: std::time::Duration) {
        self.client.set_timeout(t);
    }

    /// Sends `cmd`, returns the raw reply.
    pub fn send(&mut self, cmd: &Command) -> Result<Reply, SessionError> {
        Ok(self.client.command(&cmd.to_string())?)
    }

    /// `status`.
    pub fn status(&mut self) -> Result<Status, SessionError> {
        let c = Command::Status;
        let r = self.send(&c)?;
        Ok(Status {
            ticks: num(&r, &c, "ticks")?,
            setpoint_mm: num(&r, &c, "setpoint_mm")?,
            moving: num::<u8>(&r, &c, "moving")? != 0,
            pending: num::<u8>(&r, &c, "pending")? != 0,
            still_ticks: num(&r, &c, "still_ticks")?,
            duration_ticks: num(&r, &c, "duration_ticks")?,
            tick_hz: num(&r, &c, "tick_hz")?,
            step_rate_faults: num(&r, &c, "step_rate_faults")?,
        })
    }

    /// `config`.
    pub fn config(&mut self) -> Result<BoardConfig, SessionError> {
        let c = Command::Config;
        let r = self.send(&c)?;
        let mut modes = [None; MAX_MODES];
        for l in &r.info {
            let (slot, m) = parse_mode_line(l).ok_or_else(|| SessionError::Malformed {
                command: c.to_string(),
                what: "unreadable mode line".into(),
                line: l.clone(),
            })?;
            modes[slot - 1] = m;
        }
        Ok(BoardConfig {
            modes,
            shaping: field(&r, &c, "shaping")? == "on",
            tick_hz: num(&r, &c, "tick_hz")?,
            step_nm: num(&r, &c, "step_nm")?,
            max_step_rate_hz: num(&r, &c, "maxrate")?,
            source_internal: field(&r, &c, "source")? == "internal",
            custom_len: num(&r, &c, "custom")?,
        })
    }

    /// `shaper`: the board's combined impulse table.
    pub fn impulses(&mut self) -> Result<Vec<Impulse>, SessionError> {
        let c = Command::Shaper;
        let r = self.send(&c)?;
        let bad = |what: String| SessionError::Malformed {
            command: c.to_string(),
            what,
            line: r.ok.clone(),
        };
        field(&r, &c, "impulses")?
            .split(',')
            .map(|p| {
                let (a, t) = p
                    .split_once('@')
                    .ok_or_else(|| bad(format!("impulse `{p}` is not <amplitude>@<time_s>")))?;
                Ok(Impulse {
                    amplitude: a.parse().map_err(|_| bad(format!("amplitude `{a}`")))?,
                    time_s: t.parse().map_err(|_| bad(format!("time `{t}`")))?,
                })
            })
            .collect()
    }

    /// Programs exactly `modes` (slots 1..) and `custom`, with shaping on or off.
    pub fn program(
        &mut self,
        modes: &[ModeSetting],
        custom: &[Impulse],
        shaping: bool,
    ) -> Result<(), SessionError> {
        self.send(&Command::ClearAll)?;
        self.send(&Command::Custom(Vec::new()))?;
        for (i, m) in modes.iter().enumerate() {
            self.send(&Command::Mode(i + 1, *m))?;
        }
        if !custom.is_empty() {
            self.send(&Command::Custom(custom.to_vec()))?;
        }
        self.send(&Command::Shaping(shaping))?;
        Ok(())
    }

    /// Starts a move; returns its duration in ticks (without the shaper).
    pub fn start_move(
        &mut self,
        target_mm: f64,
        speed_mm_s: f64,
        accel_mm_s2: f64,
    ) -> Result<u64, SessionError> {
        let c = Command::Move {
            target_mm,
            speed_mm_s,
            accel_mm_s2,
        };
        let r = self.send(&c)?;
        num(&r, &c, "ticks")
    }

    /// Starts a sweep; returns its duration in ticks.
    pub fn sweep(&mut self, plan: &crate::board::plan::SweepPlan) -> Result<u64, SessionError> {
        let c = Command::Sweep(*plan);
        let r = self.send(&c)?;
        num(&r, &c, "ticks")
    }

    /// Arms the setpoint capture, one sample every `every` ticks.
    pub fn capture(&mut self, every: u32) -> Result<CaptureInfo, SessionError> {
        let c = Command::Capture(every);
        let r = self.send(&c)?;
        Ok(CaptureInfo {
            capacity: num(&r, &c, "capacity")?,
            sample_rate_hz: num(&r, &c, "sample_rate_hz")?,
        })
    }

    /// Captured setpoints so far (count).
    pub fn captured(&mut self) -> Result<usize, SessionError> {
        let c = Command::Dump(0, 0);
        let r = self.send(&c)?;
        num(&r, &c, "total")
    }

    /// Reads back the captured setpoints (m), 32 per line; `progress(n)` after each chunk.
    pub fn dump_all(&mut self, mut progress: impl FnMut(usize)) -> Result<Vec<f64>, SessionError> {
        let mut out = Vec::new();
        loop {
            let c = Command::Dump(out.len(), 32);
            let r = self.send(&c)?;
            let n: usize = num(&r, &c, "n")?;
            if n == 0 {
                return Ok(out);
            }
            for v in field(&r, &c, "values")?.split(',') {
                let nm: i64 = v.parse().map_err(|_| SessionError::Malformed {
                    command: c.to_string(),
                    what: format!("setpoint `{v}`"),
                    line: r.ok.clone(),
                })?;
                out.push(nm as f64 * 1e-9);
            }
            progress(out.len());
        }
    }

    /// `save` (the board stores its running configuration).
    pub fn save(&mut self) -> Result<(), SessionError> {
        self.send(&Command::Save).map(|_| ())
    }

    /// `load` (the board re-applies its stored configuration).
    pub fn load(&mut self) -> Result<(), SessionError> {
        self.send(&Command::Load).map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use beamshaper::config::Settings;
    use beamshaper::console::Console;
    use beamshaper::runtime::Runtime;

    /// Every command line this module writes is accepted by the core's console.
    #[test]
    fn commands_are_accepted_by_the_core_console() {
        let mut rt = Runtime::new();
        let mut con = Console::new(Settings::DEFAULT);
        let kind = ShaperKind::from_name("ei", 0.03).unwrap();
        let cmds = [
            Command::Status,
            Command::Config,
            Command::ClearAll,
            Command::Mode(
                1,
                ModeSetting {
                    kind,
                    freq_hz: 1.1,
                    zeta: 0.0074,
                },
            ),
            Command::Custom(vec![Impulse {
                amplitude: 1.0,
                time_s: 0.0,
            }]),
            Command::Custom(vec![]),
            Command::Shaping(false),
            Command::Shaper,
            Command::Capture(2),
            Command::Dump(0, 32),
            Command::Move {
                target_mm: -50.0,
                speed_mm_s: 150.0,
                accel_mm_s2: 2000.0,
            },
        ];
        for c in cmds {
            let mut out = String::new();
            con.handle_line(c.to_string().as_bytes(), &mut rt, &mut out);
            assert!(out.lines().last().unwrap().starts_with("ok "), "{c}: {out}");
        }
        let mut out = String::new();
        con.handle_line(b"config", &mut rt, &mut out);
        let info: Vec<&str> = out.lines().filter_map(|l| l.strip_prefix("# ")).collect();
        let (slot, m) = parse_mode_line(info[0]).unwrap();
        assert_eq!((slot, m.unwrap().kind), (1, kind));
    }
}
