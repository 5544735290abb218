//! The console's wire language, defined once for the board and the host: a [`Command`] is
//! parsed from a line by the board ([`Command::parse`]) and written as a line by the host
//! (`Display`); the replies the host reads are typed ([`StatusReply`], [`ConfigReply`],
//! [`ModeLine`], [`ShaperReply`], [`MoveReply`], [`SweepReply`], [`CaptureReply`],
//! [`DumpReply`]), written by the board (`Display`) and parsed by the host (`parse`).
//!
//! Syntax: a command is a name and arguments separated by blanks (at most
//! [`MAX_ARGUMENTS`]); numbers are Rust's `f64`/integer text (the host writes floats in the
//! shortest text that reads back to the same `f64`). A reply is zero or more `# …` lines and a
//! last line `ok <command> [key=value …]` or `err <code>: <message>` ([`ErrorCode`]). Values
//! contain no blanks; lists are comma separated (`impulses=a@t,…`, `values=v,…`).
//!
//! No heap: lists are `heapless`, parsing borrows the line. Parsing never panics.

use crate::config::{ModeSetting, Source, MAX_CUSTOM_IMPULSES, MAX_MODES};
use crate::engine::NumericPath;
use crate::reference::SweepKind;
use crate::runtime::{Status, Waiting};
use crate::shaper::{design::DEFAULT_V_TOL, Impulse, ShaperKind};
use core::fmt;
use core::str::FromStr;

/// Most arguments a command line may have.
pub const MAX_ARGUMENTS: usize = 24;
/// Most setpoints one `dump` returns.
pub const DUMP_MAX: usize = 32;
/// Capture decimations `capture` accepts (ticks).
pub const CAPTURE_EVERY_RANGE: (u32, u32) = (1, 10_000);

/// A console command (one line).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `help`.
    Help,
    /// `status`: [`StatusReply`].
    Status,
    /// `shaper`: the combined impulse table, [`ShaperReply`].
    Shaper,
    /// `config`: [`ModeLine`]s and [`ConfigReply`].
    Config,
    /// `mode <slot 1-4> <kind> <freq_hz> <zeta> [v_tol]` (v_tol for the EI kinds only).
    Mode(usize, ModeSetting),
    /// `clear <1-4>` (`Some(slot)`) or `clear all` (`None`).
    Clear(Option<usize>),
    /// `custom <a>@<t_s> …` (1 to 16 impulses); empty = `custom clear`.
    Custom(heapless::Vec<Impulse, MAX_CUSTOM_IMPULSES>),
    /// `shaping on|off`.
    Shaping(bool),
    /// `path fixed|f32`.
    Path(NumericPath),
    /// `source internal|stepdir`.
    Source(Source),
    /// `rate <tick_hz>`.
    Rate(u32),
    /// `step <nm_per_step>`.
    Step(u32),
    /// `maxrate <steps_per_s>`.
    MaxRate(u32),
    /// `input <nm_per_count>`.
    Input(u32),
    /// `speed <mm_s>`: default move speed.
    Speed(f64),
    /// `accel <mm_s2>`: default move acceleration.
    Accel(f64),
    /// `move <target_mm> [speed_mm_s] [accel_mm_s2]` (the defaults where absent; a given
    /// acceleration needs a given speed): [`MoveReply`].
    Move {
        /// Absolute target (mm).
        target_mm: f64,
        /// Peak speed (mm/s).
        speed_mm_s: Option<f64>,
        /// Acceleration (mm/s²).
        accel_mm_s2: Option<f64>,
    },
    /// `sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>` about the present
    /// position: [`SweepReply`].
    Sweep(SweepArgs),
    /// `stop`.
    Stop,
    /// `zero`.
    Zero,
    /// `capture <every_n_ticks>`: [`CaptureReply`].
    Capture(u32),
    /// `dump <first> <count ≤ 32>`: [`DumpReply`].
    Dump {
        /// First sample.
        first: usize,
        /// Samples wanted.
        count: usize,
    },
    /// `save`.
    Save,
    /// `load`.
    Load,
    /// `defaults`.
    Defaults,
}

/// Arguments of `sweep` (paper eqs. 33–34).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepArgs {
    /// Frequency law.
    pub kind: SweepKind,
    /// Start frequency (Hz).
    pub f0_hz: f64,
    /// End frequency (Hz).
    pub f1_hz: f64,
    /// Amplitude about the present position (mm), in (0, 1000].
    pub amplitude_mm: f64,
    /// Duration (s).
    pub duration_s: f64,
}

/// Why the console refused a line: the reply `err <code>: [<subject> ]<message>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// Error code (one of [`ErrorCode`]'s names).
    pub code: &'static str,
    /// What is wrong.
    pub message: &'static str,
    /// The command it concerns, printed before the message ("" for none).
    pub subject: &'static str,
}

impl Refusal {
    /// A refusal with `code` and `message`.
    pub const fn new(code: &'static str, message: &'static str) -> Self {
        Refusal {
            code,
            message,
            subject: "",
        }
    }
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "err {}: ", self.code)?;
        if !self.subject.is_empty() {
            write!(f, "{} ", self.subject)?;
        }
        f.write_str(self.message)
    }
}

const fn syntax(message: &'static str) -> Refusal {
    Refusal::new("syntax", message)
}

/// The error codes of `err <code>: …` replies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorCode {
    /// `unknown`: no such command.
    Unknown,
    /// `syntax`: wrong arguments.
    Syntax,
    /// `range`: a value out of its range.
    Range,
    /// `shaper`: the shaper cannot be designed or combined.
    Shaper,
    /// `too-long`: the shaper is longer than the history at this tick rate.
    TooLong,
    /// `busy`: a move runs or the reference is not still.
    Busy,
    /// `source`: not possible on the step/direction source.
    Source,
    /// `step-rate`: the shaped motion would exceed the maximum step rate.
    StepRate,
    /// `budget`: the transition would exceed the tap budget.
    Budget,
    /// `garbage`: non-printable bytes.
    Garbage,
    /// `line-too-long`: more than 200 bytes.
    LineTooLong,
    /// `storage`: flash error, or no saved settings.
    Storage,
    /// `corrupt`: the stored settings are corrupt.
    Corrupt,
    /// `version`: the stored settings are of another format version.
    Version,
}

const ERROR_CODES: [(ErrorCode, &str); 14] = [
    (ErrorCode::Unknown, "unknown"),
    (ErrorCode::Syntax, "syntax"),
    (ErrorCode::Range, "range"),
    (ErrorCode::Shaper, "shaper"),
    (ErrorCode::TooLong, "too-long"),
    (ErrorCode::Busy, "busy"),
    (ErrorCode::Source, "source"),
    (ErrorCode::StepRate, "step-rate"),
    (ErrorCode::Budget, "budget"),
    (ErrorCode::Garbage, "garbage"),
    (ErrorCode::LineTooLong, "line-too-long"),
    (ErrorCode::Storage, "storage"),
    (ErrorCode::Corrupt, "corrupt"),
    (ErrorCode::Version, "version"),
];

impl ErrorCode {
    /// The code as written in a reply.
    pub fn name(self) -> &'static str {
        ERROR_CODES
            .iter()
            .find(|(c, _)| *c == self)
            .map_or("unknown", |(_, n)| n)
    }

    /// The code named `name`, if any.
    pub fn from_name(name: &str) -> Option<ErrorCode> {
        ERROR_CODES
            .iter()
            .find(|(_, n)| *n == name)
            .map(|(c, _)| *c)
    }
}

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

const PATHS: [(NumericPath, &str); 2] = [(NumericPath::Fixed, "fixed"), (NumericPath::F32, "f32")];
const SOURCES: [(Source, &str); 2] = [(Source::Internal, "internal"), (Source::StepDir, "stepdir")];

/// A finite number, or a refusal (`syntax` if not a number, `range` if not finite).
fn parse_f64(s: &str) -> Result<f64, Refusal> {
    let v: f64 = s.parse().map_err(|_| syntax("expected a number"))?;
    if !v.is_finite() {
        return Err(Refusal::new("range", "number must be finite"));
    }
    Ok(v)
}

/// A mode slot `1..=4`.
fn parse_slot(s: &str) -> Result<usize, Refusal> {
    match s.parse::<usize>() {
        Ok(n) if (1..=MAX_MODES).contains(&n) => Ok(n),
        _ => Err(Refusal::new("range", "mode slot must be 1..4")),
    }
}

/// A word among `choices`, else a `syntax` refusal with `usage`.
fn choice<T: Copy>(
    args: &[&str],
    choices: &[(T, &str)],
    usage: &'static str,
) -> Result<T, Refusal> {
    match args {
        [w] => choices
            .iter()
            .find(|(_, n)| n == w)
            .map(|(t, _)| *t)
            .ok_or(syntax(usage)),
        _ => Err(syntax(usage)),
    }
}

/// One integer argument.
fn one_u32(args: &[&str]) -> Result<u32, Refusal> {
    let [v] = args else {
        return Err(syntax("expected one integer argument"));
    };
    v.parse()
        .map_err(|_| syntax("expected a non-negative integer"))
}

/// The command named `name` if it takes no arguments, with its name as a `'static` text.
fn without_arguments(name: &str) -> Option<(&'static str, Command)> {
    Some(match name {
        "help" => ("help", Command::Help),
        "status" => ("status", Command::Status),
        "shaper" => ("shaper", Command::Shaper),
        "config" => ("config", Command::Config),
        "zero" => ("zero", Command::Zero),
        "defaults" => ("defaults", Command::Defaults),
        "save" => ("save", Command::Save),
        "load" => ("load", Command::Load),
        "stop" => ("stop", Command::Stop),
        _ => return None,
    })
}

impl Command {
    /// Parses one line (printable ASCII; the console checks that first). Errors: the
    /// refusal the console answers (`syntax`, `range` or `unknown`).
    pub fn parse(line: &str) -> Result<Command, Refusal> {
        let mut words = line.split_ascii_whitespace();
        let name = words.next().ok_or(syntax("empty line (try help)"))?;
        let mut args: heapless::Vec<&str, MAX_ARGUMENTS> = heapless::Vec::new();
        for w in words {
            args.push(w).map_err(|_| syntax("too many arguments"))?;
        }
        if let Some((name, command)) = without_arguments(name) {
            if !args.is_empty() {
                return Err(Refusal {
                    subject: name,
                    ..syntax("takes no arguments")
                });
            }
            return Ok(command);
        }
        Self::parse_with_arguments(name, &args)
    }

    fn parse_with_arguments(name: &str, args: &[&str]) -> Result<Command, Refusal> {
        Ok(match name {
            "mode" => parse_mode(args)?,
            "clear" => match args {
                ["all"] => Command::Clear(None),
                [s] => Command::Clear(Some(parse_slot(s)?)),
                _ => return Err(syntax("clear <1-4|all>")),
            },
            "custom" => Command::Custom(parse_custom(args)?),
            "shaping" => Command::Shaping(choice(
                args,
                &[(true, "on"), (false, "off")],
                "shaping on|off",
            )?),
            "path" => Command::Path(choice(args, &PATHS, "path fixed|f32")?),
            "source" => Command::Source(choice(args, &SOURCES, "source internal|stepdir")?),
            "rate" => Command::Rate(one_u32(args)?),
            "step" => Command::Step(one_u32(args)?),
            "maxrate" => Command::MaxRate(one_u32(args)?),
            "input" => Command::Input(one_u32(args)?),
            "speed" | "accel" => {
                let [v] = args else {
                    return Err(syntax("expected one number"));
                };
                let v = parse_f64(v)?;
                if name == "speed" {
                    Command::Speed(v)
                } else {
                    Command::Accel(v)
                }
            }
            "move" => parse_move(args)?,
            "sweep" => Command::Sweep(parse_sweep(args)?),
            "capture" => Command::Capture(parse_capture(args)?),
            "dump" => parse_dump(args)?,
            _ => return Err(Refusal::new("unknown", "unknown command (try help)")),
        })
    }
}

fn parse_mode(args: &[&str]) -> Result<Command, Refusal> {
    if !(4..=5).contains(&args.len()) {
        return Err(syntax("mode <1-4> <kind> <freq_hz> <zeta> [v_tol]"));
    }
    let slot = parse_slot(args[0])?;
    let v_tol = match args.get(4) {
        Some(v) => parse_f64(v)?,
        None => DEFAULT_V_TOL,
    };
    let kind = ShaperKind::from_name(args[1], v_tol).ok_or(syntax("unknown shaper kind"))?;
    if args.len() == 5 && kind.v_tol().is_none() {
        return Err(syntax("v_tol only applies to ei, 2hei, 3hei"));
    }
    let freq_hz = parse_f64(args[2])?;
    let zeta = parse_f64(args[3])?;
    Ok(Command::Mode(
        slot,
        ModeSetting {
            kind,
            freq_hz,
            zeta,
        },
    ))
}

fn parse_custom(args: &[&str]) -> Result<heapless::Vec<Impulse, MAX_CUSTOM_IMPULSES>, Refusal> {
    let mut list = heapless::Vec::new();
    if args == ["clear"] {
        return Ok(list);
    }
    if args.is_empty() || args.len() > MAX_CUSTOM_IMPULSES {
        return Err(syntax(
            "custom <a>@<t_s> ... (1 to 16 impulses) | custom clear",
        ));
    }
    for a in args {
        let (amp, t) = a
            .split_once('@')
            .ok_or(syntax("impulse must be <amplitude>@<time_s>"))?;
        let imp = Impulse {
            amplitude: parse_f64(amp)?,
            time_s: parse_f64(t)?,
        };
        if imp.time_s < 0.0 {
            return Err(Refusal::new("range", "impulse time must be >= 0"));
        }
        list.push(imp).map_err(|_| syntax("too many impulses"))?;
    }
    Ok(list)
}

fn parse_move(args: &[&str]) -> Result<Command, Refusal> {
    if args.is_empty() || args.len() > 3 {
        return Err(syntax("move <target_mm> [speed_mm_s] [accel_mm_s2]"));
    }
    let optional = |i: usize| args.get(i).map(|v| parse_f64(v)).transpose();
    Ok(Command::Move {
        target_mm: parse_f64(args[0])?,
        speed_mm_s: optional(1)?,
        accel_mm_s2: optional(2)?,
    })
}

fn parse_sweep(args: &[&str]) -> Result<SweepArgs, Refusal> {
    let [kind, f0, f1, amp, dur] = args else {
        return Err(syntax(
            "sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>",
        ));
    };
    let kind = match *kind {
        "lin" => SweepKind::Linear,
        "exp" => SweepKind::Exponential,
        _ => return Err(syntax("sweep kind must be lin or exp")),
    };
    let a = SweepArgs {
        kind,
        f0_hz: parse_f64(f0)?,
        f1_hz: parse_f64(f1)?,
        amplitude_mm: parse_f64(amp)?,
        duration_s: parse_f64(dur)?,
    };
    if !(a.amplitude_mm > 0.0 && a.amplitude_mm <= 1000.0) {
        return Err(Refusal::new("range", "amplitude must be in (0, 1000] mm"));
    }
    Ok(a)
}

fn parse_capture(args: &[&str]) -> Result<u32, Refusal> {
    let [d] = args else {
        return Err(syntax("capture <every_n_ticks>"));
    };
    let d: u32 = d
        .parse()
        .map_err(|_| syntax("expected a positive integer"))?;
    let (lo, hi) = CAPTURE_EVERY_RANGE;
    if !(lo..=hi).contains(&d) {
        return Err(Refusal::new("range", "decimation must be 1..10000 ticks"));
    }
    Ok(d)
}

fn parse_dump(args: &[&str]) -> Result<Command, Refusal> {
    let [first, count] = args else {
        return Err(syntax("dump <first> <count>"));
    };
    let int = |s: &str| {
        s.parse::<usize>()
            .map_err(|_| syntax("expected an integer"))
    };
    let (first, count) = (int(first)?, int(count)?);
    if count > DUMP_MAX {
        return Err(Refusal::new("range", "count must be <= 32"));
    }
    Ok(Command::Dump { first, count })
}

fn on_off(on: bool) -> &'static str {
    if on {
        "on"
    } else {
        "off"
    }
}

/// The command line (without terminator), e.g. `mode 1 zvd 1.1 0.0074`; floats in the
/// shortest text that parses back to the same `f64`.
impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Help => f.write_str("help"),
            Command::Status => f.write_str("status"),
            Command::Shaper => f.write_str("shaper"),
            Command::Config => f.write_str("config"),
            Command::Zero => f.write_str("zero"),
            Command::Defaults => f.write_str("defaults"),
            Command::Save => f.write_str("save"),
            Command::Load => f.write_str("load"),
            Command::Stop => f.write_str("stop"),
            Command::Mode(slot, m) => {
                write!(f, "mode {slot} {} {} {}", m.kind.name(), m.freq_hz, m.zeta)?;
                match m.kind.v_tol() {
                    Some(v) => write!(f, " {v}"),
                    None => Ok(()),
                }
            }
            Command::Clear(None) => f.write_str("clear all"),
            Command::Clear(Some(slot)) => write!(f, "clear {slot}"),
            Command::Custom(imps) if imps.is_empty() => f.write_str("custom clear"),
            Command::Custom(imps) => {
                f.write_str("custom")?;
                imps.iter()
                    .try_for_each(|i| write!(f, " {}@{}", i.amplitude, i.time_s))
            }
            Command::Shaping(on) => write!(f, "shaping {}", on_off(*on)),
            Command::Path(p) => write!(f, "path {}", p.name()),
            Command::Source(s) => write!(f, "source {}", s.name()),
            Command::Rate(v) => write!(f, "rate {v}"),
            Command::Step(v) => write!(f, "step {v}"),
            Command::MaxRate(v) => write!(f, "maxrate {v}"),
            Command::Input(v) => write!(f, "input {v}"),
            Command::Speed(v) => write!(f, "speed {v}"),
            Command::Accel(v) => write!(f, "accel {v}"),
            Command::Move {
                target_mm,
                speed_mm_s,
                accel_mm_s2,
            } => {
                write!(f, "move {target_mm}")?;
                // An acceleration is only meaningful after a speed (positional arguments).
                if let Some(v) = speed_mm_s {
                    write!(f, " {v}")?;
                    if let Some(a) = accel_mm_s2 {
                        write!(f, " {a}")?;
                    }
                }
                Ok(())
            }
            Command::Sweep(a) => write!(
                f,
                "sweep {} {} {} {} {}",
                a.kind.name(),
                a.f0_hz,
                a.f1_hz,
                a.amplitude_mm,
                a.duration_s
            ),
            Command::Capture(d) => write!(f, "capture {d}"),
            Command::Dump { first, count } => write!(f, "dump {first} {count}"),
        }
    }
}

/// A number printed with at most `.1` decimals, trailing zeros removed (`68.04`, not
/// `68.03999999999999`; `1e-308` as `0`): the console's number format.
pub struct Num(pub f64, pub usize);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use fmt::Write;
        let mut buf: heapless::String<48> = heapless::String::new();
        let v = self.0;
        if !v.is_finite() {
            return write!(f, "{v}");
        }
        if v.abs() >= 1e15 {
            // m·10^e with 1 ≤ |m| < 10, by repeated division (≤ 308 steps, no log table).
            let (mut m, mut e) = (v, 0u32);
            while m.abs() >= 10.0 {
                m /= 10.0;
                e += 1;
            }
            return write!(f, "{}e{e}", Num(m, 3));
        }
        if write!(buf, "{:.*}", self.1.min(12), v).is_err() {
            return write!(f, "{v}");
        }
        let mut t: &str = &buf;
        if t.contains('.') {
            t = t.trim_end_matches('0').trim_end_matches('.');
        }
        if t == "-0" {
            t = "0";
        }
        f.write_str(t)
    }
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
}

impl StatusReply {
    /// The reply for the runtime's `status` with shaping `shaping`.
    pub fn new(s: &Status, shaping: bool) -> Self {
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
             path={} taps={} duration_ticks={} source={} shaping={} changes={}",
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
        })
    }
}

impl fmt::Display for ConfigReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok config shaping={} path={} tick_hz={} step_nm={} maxrate={} input_nm={} source={} speed_mm_s={} \
             accel_mm_s2={} custom={}",
            on_off(self.shaping),
            self.path.name(),
            self.tick_hz,
            self.step_nm,
            self.max_step_rate_hz,
            self.input_nm,
            self.source.name(),
            Num(self.speed_mm_s, 4),
            Num(self.accel_mm_s2, 4),
            self.custom
        )
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
