//! A typed board session over the core's console protocol ([`beamshaper::protocol`]): commands
//! are the core's [`Command`] (the type the board parses), replies are parsed by the core's
//! reply types ([`StatusReply`], [`ConfigReply`], [`ModeLine`], [`ShaperReply`],
//! [`MoveReply`], [`SweepReply`], [`CaptureReply`], [`DumpReply`]) over the line transport of
//! [`super::client::BoardClient`]. No console text is written or read by hand on the host.

use super::client::{BoardClient, Reply};
use beamshaper::config::{Certificate, ModeSetting, Source, MAX_MODES};
pub use beamshaper::protocol::Command;
use beamshaper::protocol::{
    CaptureReply, ConfigReply, DumpReply, ModeLine, MoveReply, ReplyError, ShaperReply,
    StatusReply, SweepArgs, SweepReply, DUMP_MAX,
};
use beamshaper::shaper::Impulse;
use thiserror::Error;

/// Why a session step failed.
#[derive(Debug, Error)]
pub enum SessionError {
    /// The transport failed or the board answered `err` (the message says which).
    #[error(transparent)]
    Board(#[from] super::client::ClientError),
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

/// `status` reply (the core's type).
pub type Status = StatusReply;

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
    /// How the installed shaper was certified (none on a board of an earlier firmware).
    pub certificate: Certificate,
}

/// `capture` reply (the core's type).
pub type CaptureInfo = CaptureReply;

/// The session.
pub struct Session {
    client: BoardClient,
}

/// A reply field the core's parser refused, as a session error.
fn malformed(cmd: &Command, line: &str) -> impl Fn(ReplyError) -> SessionError {
    let (command, line) = (cmd.to_string(), line.to_string());
    move |e| SessionError::Malformed {
        command: command.clone(),
        what: e.to_string(),
        line: line.clone(),
    }
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
        StatusReply::parse(&r.ok).map_err(malformed(&c, &r.ok))
    }

    /// `config`: the mode lines and the `ok config` line.
    pub fn config(&mut self) -> Result<BoardConfig, SessionError> {
        let c = Command::Config;
        let r = self.send(&c)?;
        let mut modes = [None; MAX_MODES];
        for l in &r.info {
            let line = ModeLine::parse(l).ok_or_else(|| SessionError::Malformed {
                command: c.to_string(),
                what: "unreadable mode line".into(),
                line: l.clone(),
            })?;
            modes[line.slot - 1] = line.mode;
        }
        let cfg = ConfigReply::parse(&r.ok).map_err(malformed(&c, &r.ok))?;
        Ok(BoardConfig {
            modes,
            shaping: cfg.shaping,
            tick_hz: cfg.tick_hz,
            step_nm: cfg.step_nm,
            max_step_rate_hz: cfg.max_step_rate_hz,
            source_internal: cfg.source == Source::Internal,
            custom_len: cfg.custom,
            certificate: cfg.certificate,
        })
    }

    /// `shaper`: the board's combined impulse table.
    pub fn impulses(&mut self) -> Result<Vec<Impulse>, SessionError> {
        let c = Command::Shaper;
        let r = self.send(&c)?;
        let bad = malformed(&c, &r.ok);
        let impulses = ShaperReply::impulses(&r.ok)
            .map_err(&bad)?
            .map(|i| i.map_err(&bad))
            .collect();
        impulses
    }

    /// Programs exactly `modes` (slots 1..) and `custom`, with shaping on or off.
    pub fn program(
        &mut self,
        modes: &[ModeSetting],
        custom: &[Impulse],
        shaping: bool,
    ) -> Result<(), SessionError> {
        let list = heapless::Vec::from_slice(custom).map_err(|_| SessionError::Malformed {
            command: "custom".into(),
            what: format!("{} impulses, the board holds at most 16", custom.len()),
            line: String::new(),
        })?;
        self.send(&Command::Clear(None))?;
        self.send(&Command::Custom(heapless::Vec::new()))?;
        for (i, m) in modes.iter().enumerate() {
            self.send(&Command::Mode(i + 1, *m))?;
        }
        if !custom.is_empty() {
            self.send(&Command::Custom(list))?;
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
            speed_mm_s: Some(speed_mm_s),
            accel_mm_s2: Some(accel_mm_s2),
        };
        let r = self.send(&c)?;
        let reply = MoveReply::parse(&r.ok).map_err(malformed(&c, &r.ok))?;
        Ok(reply.ticks.into())
    }

    /// Starts a sweep; returns its duration in ticks.
    pub fn sweep(&mut self, plan: &crate::board::plan::SweepPlan) -> Result<u64, SessionError> {
        let c = Command::Sweep(SweepArgs {
            kind: plan.kind,
            f0_hz: plan.f0_hz,
            f1_hz: plan.f1_hz,
            amplitude_mm: plan.amplitude_mm,
            duration_s: plan.duration_s,
        });
        let r = self.send(&c)?;
        let reply = SweepReply::parse(&r.ok).map_err(malformed(&c, &r.ok))?;
        Ok(reply.ticks.into())
    }

    /// Arms the setpoint capture, one sample every `every` ticks.
    pub fn capture(&mut self, every: u32) -> Result<CaptureInfo, SessionError> {
        let c = Command::Capture(every);
        let r = self.send(&c)?;
        CaptureReply::parse(&r.ok).map_err(malformed(&c, &r.ok))
    }

    /// Captured setpoints so far (count).
    pub fn captured(&mut self) -> Result<usize, SessionError> {
        let c = Command::Dump { first: 0, count: 0 };
        let r = self.send(&c)?;
        Ok(DumpReply::parse(&r.ok).map_err(malformed(&c, &r.ok))?.total)
    }

    /// Reads back the captured setpoints (m), 32 per line; `progress(n)` after each chunk.
    pub fn dump_all(&mut self, mut progress: impl FnMut(usize)) -> Result<Vec<f64>, SessionError> {
        let mut out = Vec::new();
        loop {
            let c = Command::Dump {
                first: out.len(),
                count: DUMP_MAX,
            };
            let r = self.send(&c)?;
            let bad = malformed(&c, &r.ok);
            if DumpReply::parse(&r.ok).map_err(&bad)?.n == 0 {
                return Ok(out);
            }
            for nm in DumpReply::values(&r.ok).map_err(&bad)? {
                out.push(nm.map_err(&bad)? as f64 * 1e-9);
            }
            progress(out.len());
        }
    }

    /// `certify …`: records on the board how its installed shaper was checked and the band
    /// certified per mode slot (sent after programming; a new shaper voids it).
    pub fn certify(&mut self, c: &Certificate) -> Result<(), SessionError> {
        self.send(&Command::Certify(*c)).map(|_| ())
    }

    /// `payload <n> store`: the installed shaper's mode frequencies become entry `n` of the
    /// board's payload schedule (`payload n` selects it later).
    pub fn payload_store(&mut self, n: u8) -> Result<(), SessionError> {
        self.send(&Command::Payload(
            beamshaper::protocol::PayloadCommand::Store(n),
        ))
        .map(|_| ())
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
    use beamshaper::shaper::ShaperKind;

    /// Every command line this module writes is accepted by the core's console, and the
    /// `config` reply's mode lines read back as the modes set.
    #[test]
    fn commands_are_accepted_by_the_core_console() {
        let mut rt = Runtime::new();
        let mut con = Console::new(Settings::DEFAULT);
        let kind = ShaperKind::from_name("ei", 0.03).unwrap();
        let one = heapless::Vec::from_slice(&[Impulse {
            amplitude: 1.0,
            time_s: 0.0,
        }])
        .unwrap();
        let cmds = [
            Command::Status,
            Command::Config,
            Command::Clear(None),
            Command::Mode(
                1,
                ModeSetting {
                    kind,
                    freq_hz: 1.1,
                    zeta: 0.0074,
                },
            ),
            Command::Custom(one),
            Command::Custom(heapless::Vec::new()),
            Command::Shaping(false),
            Command::Shaper,
            Command::Capture(2),
            Command::Dump {
                first: 0,
                count: 32,
            },
            Command::Move {
                target_mm: -50.0,
                speed_mm_s: Some(150.0),
                accel_mm_s2: Some(2000.0),
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
        let line = ModeLine::parse(info[0]).unwrap();
        assert_eq!((line.slot, line.mode.unwrap().kind), (1, kind));
    }
}
