//! The console's reply lines: classification ([`ReplyLine`]), field access ([`field`],
//! [`value`]) and the typed replies the host reads, each written by the board (`Display`)
//! and parsed by the host (`parse`). See [`super`] for the syntax.

use super::num::Num;
use super::{on_off, parse_f64, parse_slot, ErrorCode, SweepArgs, PATHS, SOURCES};
use crate::config::{ModeSetting, Settings, Source, Verified};
use crate::engine::NumericPath;
use crate::reference::SweepKind;
use crate::runtime::{Status, Waiting};
use crate::shaper::{design::DEFAULT_V_TOL, Impulse, ShaperKind};
use core::fmt;
use core::str::FromStr;

/// One reply line, classified.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplyLine<'a> {
    /// `# <text>`: information (text without the `# `).
    Info(&'a str),
    /// `ok …`: the final line of a success (the whole line).
    Ok(&'a str),
    /// `err <code>: <message>`: the final line of a refusal. The code is `None` if it is not
    /// one of [`ErrorCode`]'s.
    Err(Option<ErrorCode>, &'a str),
    /// Anything else (malformed; an empty line is ignored by readers).
    Other(&'a str),
}

impl<'a> ReplyLine<'a> {
    /// Classifies `line` (without its terminator).
    pub fn parse(line: &'a str) -> ReplyLine<'a> {
        if let Some(info) = line.strip_prefix("# ") {
            ReplyLine::Info(info)
        } else if line == "ok" || line.starts_with("ok ") {
            ReplyLine::Ok(line)
        } else if let Some(e) = line.strip_prefix("err ") {
            let (code, message) = e.split_once(": ").unwrap_or((e, ""));
            ReplyLine::Err(ErrorCode::from_name(code), message)
        } else {
            ReplyLine::Other(line)
        }
    }
}

/// A reply field that is missing or does not parse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplyError {
    /// The key (`key=`).
    pub key: &'static str,
    /// True if present but unreadable, false if absent.
    pub unreadable: bool,
}

impl fmt::Display for ReplyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.unreadable {
            write!(f, "`{}=` unreadable", self.key)
        } else {
            write!(f, "no `{}=`", self.key)
        }
    }
}

/// The value of `key=` in an `ok` line.
pub fn field<'a>(ok_line: &'a str, key: &str) -> Option<&'a str> {
    ok_line
        .split_ascii_whitespace()
        .find_map(|w| w.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
}

/// The value of `key=` parsed as `T`.
pub fn value<T: FromStr>(ok_line: &str, key: &'static str) -> Result<T, ReplyError> {
    let v = field(ok_line, key).ok_or(ReplyError {
        key,
        unreadable: false,
    })?;
    v.parse().map_err(|_| ReplyError {
        key,
        unreadable: true,
    })
}

/// A `0|1` or `off|on` flag.
fn flag(ok_line: &str, key: &'static str) -> Result<bool, ReplyError> {
    match field(ok_line, key) {
        Some("1" | "on") => Ok(true),
        Some("0" | "off") => Ok(false),
        v => Err(ReplyError {
            key,
            unreadable: v.is_some(),
        }),
    }
}

/// A field whose text is one of `names`' (value, text) pairs.
fn named<T: Copy>(ok_line: &str, key: &'static str, names: &[(T, &str)]) -> Result<T, ReplyError> {
    let v = field(ok_line, key).ok_or(ReplyError {
        key,
        unreadable: false,
    })?;
    names
        .iter()
        .find(|(_, n)| *n == v)
        .map(|(t, _)| *t)
        .ok_or(ReplyError {
            key,
            unreadable: true,
        })
}

/// `ok status …`: the runtime's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatusReply {
    /// Ticks since start.
    pub ticks: u64,
    /// Reference (mm).
    pub reference_mm: f64,
    /// Shaped setpoint (mm).
    pub setpoint_mm: f64,
    /// Signed steps emitted.
    pub emitted_steps: i64,
    /// A move or sweep runs.
    pub moving: bool,
    /// A configuration change is pending.
    pub pending: bool,
    /// What of the pending change waits for standstill.
    pub waiting: Waiting,
    /// Shaper tables in flight.
    pub stages: usize,
    /// Taps evaluated per tick.
    pub taps_in_flight: usize,
    /// Ticks the reference has been still.
    pub still_ticks: u32,
    /// Ticks that needed more than the maximum step rate.
    pub step_rate_faults: u32,
    /// Tick rate in force (Hz).
    pub tick_hz: u32,
    /// Numeric path in force.
    pub path: NumericPath,
    /// Taps of the newest table.
    pub taps: usize,
    /// Duration of the newest table (ticks).
    pub duration_ticks: u32,
    /// Source in force.
    pub source: Source,
    /// Shaping on (the settings).
    pub shaping: bool,
    /// Configuration changes applied since start.
    pub changes: u32,
    /// How the installed shaper was checked (the settings' certificate); a board of an earlier
    /// firmware, whose `status` has no `verified=`, reads as [`Verified::Unknown`].
    pub verified: Verified,
}

impl StatusReply {
    /// The reply for the runtime's `status` with the operator's `settings`.
    pub fn new(s: &Status, settings: &Settings) -> Self {
        let shaping = settings.shaping_enabled;
        StatusReply {
            ticks: s.ticks,
            reference_mm: s.reference_counts as f64 * 1e-6,
            setpoint_mm: s.setpoint_counts as f64 * 1e-6,
            emitted_steps: s.emitted_steps,
            moving: s.moving,
            pending: s.pending,
            waiting: s.waiting,
            stages: s.stages,
            taps_in_flight: s.taps_in_flight,
            still_ticks: s.still_ticks,
            step_rate_faults: s.step_rate_faults,
            tick_hz: s.tick_rate_hz,
            path: s.path,
            taps: s.taps,
            duration_ticks: s.duration_ticks,
            source: s.source,
            shaping,
            changes: s.applied_changes,
            verified: settings.certificate.verified,
        }
    }

    /// Parses the `ok status` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(StatusReply {
            ticks: value(line, "ticks")?,
            reference_mm: value(line, "reference_mm")?,
            setpoint_mm: value(line, "setpoint_mm")?,
            emitted_steps: value(line, "emitted_steps")?,
            moving: flag(line, "moving")?,
            pending: flag(line, "pending")?,
            waiting: parse_waiting(line)?,
            stages: value(line, "stages")?,
            taps_in_flight: value(line, "taps_in_flight")?,
            still_ticks: value(line, "still_ticks")?,
            step_rate_faults: value(line, "step_rate_faults")?,
            tick_hz: value(line, "tick_hz")?,
            path: named(line, "path", &PATHS)?,
            taps: value(line, "taps")?,
            duration_ticks: value(line, "duration_ticks")?,
            source: named(line, "source", &SOURCES)?,
            shaping: flag(line, "shaping")?,
            changes: value(line, "changes")?,
            verified: match field(line, "verified") {
                None => Verified::Unknown,
                Some(v) => Verified::from_name(v).ok_or(ReplyError {
                    key: "verified",
                    unreadable: true,
                })?,
            },
        })
    }
}

/// `waiting=none` or `waiting=rate,path,…` ([`Waiting::names`]).
fn parse_waiting(line: &str) -> Result<Waiting, ReplyError> {
    let bad = ReplyError {
        key: "waiting",
        unreadable: true,
    };
    let v = field(line, "waiting").ok_or(ReplyError {
        unreadable: false,
        ..bad
    })?;
    let mut w = Waiting::default();
    if v == "none" {
        return Ok(w);
    }
    for name in v.split(',') {
        *match name {
            "rate" => &mut w.tick_rate,
            "path" => &mut w.path,
            "step" => &mut w.step,
            "source" => &mut w.source,
            "input" => &mut w.input,
            "shaper" => &mut w.shaper,
            _ => return Err(bad),
        } = true;
    }
    Ok(w)
}

impl fmt::Display for StatusReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok status ticks={} reference_mm={} setpoint_mm={} emitted_steps={} moving={} pending={} \
             waiting={} stages={} taps_in_flight={} still_ticks={} step_rate_faults={} tick_hz={} \
             path={} taps={} duration_ticks={} source={} shaping={} changes={} verified={}",
            self.ticks,
            Num(self.reference_mm, 6),
            Num(self.setpoint_mm, 6),
            self.emitted_steps,
            self.moving as u8,
            self.pending as u8,
            self.waiting.names(),
            self.stages,
            self.taps_in_flight,
            self.still_ticks,
            self.step_rate_faults,
            self.tick_hz,
            self.path.name(),
            self.taps,
            self.duration_ticks,
            self.source.name(),
            on_off(self.shaping),
            self.changes,
            self.verified.name(),
        )
    }
}

/// `# mode <slot> <kind> <freq_hz> <zeta> [v_tol]` or `# mode <slot> none` (a `config` info
/// line, without the `# `): one mode slot of the settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeLine {
    /// Slot, 1..=4.
    pub slot: usize,
    /// Its shaper, if set.
    pub mode: Option<ModeSetting>,
}

impl ModeLine {
    /// Parses the info line (without `# `); `None` if it is not a well-formed mode line.
    pub fn parse(text: &str) -> Option<ModeLine> {
        let mut w = text.split_ascii_whitespace();
        if w.next() != Some("mode") {
            return None;
        }
        let slot = parse_slot(w.next()?).ok()?;
        let kind = w.next()?;
        if kind == "none" {
            return w.next().is_none().then_some(ModeLine { slot, mode: None });
        }
        let freq_hz = parse_f64(w.next()?).ok()?;
        let zeta = parse_f64(w.next()?).ok()?;
        let v_tol = match w.next() {
            Some(v) => parse_f64(v).ok()?,
            None => DEFAULT_V_TOL,
        };
        let kind = ShaperKind::from_name(kind, v_tol)?;
        let mode = ModeSetting {
            kind,
            freq_hz,
            zeta,
        };
        w.next().is_none().then_some(ModeLine {
            slot,
            mode: Some(mode),
        })
    }
}

impl fmt::Display for ModeLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(m) = self.mode else {
            return write!(f, "mode {} none", self.slot);
        };
        write!(
            f,
            "mode {} {} {} {}",
            self.slot,
            m.kind.name(),
            m.freq_hz,
            m.zeta
        )?;
        match m.kind.v_tol() {
            Some(v) => write!(f, " {v}"),
            None => Ok(()),
        }
    }
}

/// `ok config …`: the scalar settings (the modes come as [`ModeLine`]s before it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigReply {
    /// Shaping on.
    pub shaping: bool,
    /// Numeric path.
    pub path: NumericPath,
    /// Tick rate (Hz).
    pub tick_hz: u32,
    /// nm per output step.
    pub step_nm: u32,
    /// Maximum output step rate (steps/s).
    pub max_step_rate_hz: u32,
    /// nm per upstream count.
    pub input_nm: u32,
    /// Reference source.
    pub source: Source,
    /// Default move speed (mm/s).
    pub speed_mm_s: f64,
    /// Default move acceleration (mm/s²).
    pub accel_mm_s2: f64,
    /// Impulses in the custom list.
    pub custom: usize,
    /// The settings' certificate (how the shaper was checked, the certified band per mode
    /// slot: `verified=… bands_hz=lo:hi,-,…`); absent on boards of an earlier firmware, read
    /// as [`crate::config::Certificate::NONE`].
    pub certificate: crate::config::Certificate,
}

impl ConfigReply {
    /// The reply for `s`.
    pub fn new(s: &crate::config::Settings) -> Self {
        ConfigReply {
            shaping: s.shaping_enabled,
            path: s.path,
            tick_hz: s.tick_rate_hz,
            step_nm: s.step_nm,
            max_step_rate_hz: s.max_step_rate_hz,
            input_nm: s.input_nm_per_count,
            source: s.source,
            speed_mm_s: s.move_speed_mm_s as f64,
            accel_mm_s2: s.move_accel_mm_s2 as f64,
            custom: s.custom.len(),
            certificate: s.certificate,
        }
    }

    /// Parses the `ok config` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(ConfigReply {
            shaping: flag(line, "shaping")?,
            path: named(line, "path", &PATHS)?,
            tick_hz: value(line, "tick_hz")?,
            step_nm: value(line, "step_nm")?,
            max_step_rate_hz: value(line, "maxrate")?,
            input_nm: value(line, "input_nm")?,
            source: named(line, "source", &SOURCES)?,
            speed_mm_s: value(line, "speed_mm_s")?,
            accel_mm_s2: value(line, "accel_mm_s2")?,
            custom: value(line, "custom")?,
            certificate: parse_certificate(line)?,
        })
    }
}

/// `verified=<name> bands_hz=<lo:hi|->,…` of a `config` reply (absent: no certificate).
fn parse_certificate(line: &str) -> Result<crate::config::Certificate, ReplyError> {
    let mut c = crate::config::Certificate::NONE;
    let bad = |key| ReplyError {
        key,
        unreadable: true,
    };
    if let Some(v) = field(line, "verified") {
        c.verified = Verified::from_name(v).ok_or(bad("verified"))?;
    }
    let Some(list) = field(line, "bands_hz") else {
        return Ok(c);
    };
    let mut items = list.split(',');
    for slot in c.band_hz.iter_mut() {
        *slot = match items.next().ok_or(bad("bands_hz"))? {
            "-" => None,
            pair => {
                let (lo, hi) = pair.split_once(':').ok_or(bad("bands_hz"))?;
                let num = |t: &str| t.parse::<f32>().map_err(|_| bad("bands_hz"));
                Some((num(lo)?, num(hi)?))
            }
        };
    }
    match items.next() {
        None => Ok(c),
        Some(_) => Err(bad("bands_hz")),
    }
}

impl fmt::Display for ConfigReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok config shaping={} path={} tick_hz={} step_nm={} maxrate={} input_nm={} source={} speed_mm_s={} \
             accel_mm_s2={} custom={} verified={} bands_hz=",
            on_off(self.shaping),
            self.path.name(),
            self.tick_hz,
            self.step_nm,
            self.max_step_rate_hz,
            self.input_nm,
            self.source.name(),
            Num(self.speed_mm_s, 4),
            Num(self.accel_mm_s2, 4),
            self.custom,
            self.certificate.verified.name(),
        )?;
        for (i, b) in self.certificate.band_hz.iter().enumerate() {
            let sep = if i == 0 { "" } else { "," };
            match b {
                Some((lo, hi)) => write!(f, "{sep}{lo}:{hi}")?,
                None => write!(f, "{sep}-")?,
            }
        }
        Ok(())
    }
}

/// `ok shaper n=… duration_s=… pending=… impulses=a@t,…`: the combined shaper (its
/// impulses follow the header in the same line; read them with [`ShaperReply::impulses`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShaperReply {
    /// Impulses.
    pub n: usize,
    /// Duration (s).
    pub duration_s: f64,
    /// A change is pending.
    pub pending: bool,
}

impl ShaperReply {
    /// Parses the header fields of the `ok shaper` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(ShaperReply {
            n: value(line, "n")?,
            duration_s: value(line, "duration_s")?,
            pending: flag(line, "pending")?,
        })
    }

    /// The impulses of an `ok shaper` line (exact: shortest round-trip text).
    pub fn impulses(
        line: &str,
    ) -> Result<impl Iterator<Item = Result<Impulse, ReplyError>> + '_, ReplyError> {
        let bad = ReplyError {
            key: "impulses",
            unreadable: true,
        };
        let list = field(line, "impulses").ok_or(ReplyError {
            unreadable: false,
            ..bad
        })?;
        Ok(list.split(',').map(move |p| {
            let (a, t) = p.split_once('@').ok_or(bad)?;
            Ok(Impulse {
                amplitude: a.parse().map_err(|_| bad)?,
                time_s: t.parse().map_err(|_| bad)?,
            })
        }))
    }
}

/// Writes the header of the `ok shaper` line; the impulses follow as `a@t` joined by `,`.
impl fmt::Display for ShaperReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok shaper n={} duration_s={} pending={} impulses=",
            self.n, self.duration_s, self.pending as u8
        )
    }
}

/// `ok move target_mm=… ticks=…`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveReply {
    /// Target (mm).
    pub target_mm: f64,
    /// Duration of the reference move (ticks, without the shaper).
    pub ticks: u32,
}

impl MoveReply {
    /// Parses the `ok move` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(MoveReply {
            target_mm: value(line, "target_mm")?,
            ticks: value(line, "ticks")?,
        })
    }
}

impl fmt::Display for MoveReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok move target_mm={} ticks={}",
            self.target_mm, self.ticks
        )
    }
}

/// `ok sweep kind=… f0_hz=… f1_hz=… amplitude_mm=… ticks=…`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepReply {
    /// The sweep (its duration is not echoed; `duration_s` is 0 when parsed).
    pub args: SweepArgs,
    /// Duration (ticks).
    pub ticks: u32,
}

impl SweepReply {
    /// Parses the `ok sweep` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(SweepReply {
            args: SweepArgs {
                kind: named(
                    line,
                    "kind",
                    &[(SweepKind::Linear, "lin"), (SweepKind::Exponential, "exp")],
                )?,
                f0_hz: value(line, "f0_hz")?,
                f1_hz: value(line, "f1_hz")?,
                amplitude_mm: value(line, "amplitude_mm")?,
                duration_s: 0.0,
            },
            ticks: value(line, "ticks")?,
        })
    }
}

impl fmt::Display for SweepReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok sweep kind={} f0_hz={} f1_hz={} amplitude_mm={} ticks={}",
            self.args.kind.name(),
            Num(self.args.f0_hz, 6),
            Num(self.args.f1_hz, 6),
            Num(self.args.amplitude_mm, 6),
            self.ticks
        )
    }
}

/// `ok capture every_ticks=… sample_rate_hz=… capacity=…`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureReply {
    /// Decimation (ticks per sample).
    pub every_ticks: u32,
    /// Sample rate (Hz).
    pub sample_rate_hz: f64,
    /// Samples the buffer holds.
    pub capacity: usize,
}

impl CaptureReply {
    /// Parses the `ok capture` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(CaptureReply {
            every_ticks: value(line, "every_ticks")?,
            sample_rate_hz: value(line, "sample_rate_hz")?,
            capacity: value(line, "capacity")?,
        })
    }
}

impl fmt::Display for CaptureReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok capture every_ticks={} sample_rate_hz={} capacity={}",
            self.every_ticks, self.sample_rate_hz, self.capacity
        )
    }
}

/// `ok dump first=… n=… total=… armed=… values=v,…` (setpoints in nm; the values follow the
/// header in the same line, read them with [`DumpReply::values`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DumpReply {
    /// First sample returned.
    pub first: usize,
    /// Samples returned.
    pub n: usize,
    /// Samples captured so far.
    pub total: usize,
    /// The capture is still running.
    pub armed: bool,
}

impl DumpReply {
    /// Parses the header fields of the `ok dump` line.
    pub fn parse(line: &str) -> Result<Self, ReplyError> {
        Ok(DumpReply {
            first: value(line, "first")?,
            n: value(line, "n")?,
            total: value(line, "total")?,
            armed: flag(line, "armed")?,
        })
    }

    /// The setpoints (nm) of an `ok dump` line.
    pub fn values(
        line: &str,
    ) -> Result<impl Iterator<Item = Result<i32, ReplyError>> + '_, ReplyError> {
        let bad = ReplyError {
            key: "values",
            unreadable: true,
        };
        let list = field(line, "values").ok_or(ReplyError {
            unreadable: false,
            ..bad
        })?;
        Ok(list
            .split(',')
            .filter(|v| !v.is_empty())
            .map(move |v| v.parse().map_err(|_| bad)))
    }
}

/// Writes the header of the `ok dump` line; the values follow joined by `,`.
impl fmt::Display for DumpReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok dump first={} n={} total={} armed={} values=",
            self.first, self.n, self.total, self.armed as u8
        )
    }
}
