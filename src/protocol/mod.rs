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

use crate::config::{Certificate, ModeSetting, Source, Verified, MAX_CUSTOM_IMPULSES, MAX_MODES};
use crate::engine::NumericPath;
use crate::reference::SweepKind;
use crate::shaper::{design::DEFAULT_V_TOL, Impulse, ShaperKind};
use core::fmt;

pub mod num;
mod reply;
mod watch;
pub use num::Num;
pub use reply::{
    field, value, CaptureReply, ConfigReply, DumpReply, ModeLine, MoveReply, ReplyError, ReplyLine,
    ShaperReply, StatusReply, SweepReply,
};
pub use watch::{PayloadCommand, WatchCommand, WatchReply};

/// Most arguments a command line may have.
pub const MAX_ARGUMENTS: usize = 24;
/// Most setpoints one `dump` returns.
pub const DUMP_MAX: usize = 32;
/// Capture decimations `capture` accepts (ticks).
pub const CAPTURE_EVERY_RANGE: (u32, u32) = (1, 10_000);

/// A console command (one line). One lives on the console's stack per line; the custom list
/// is inline (no heap), hence the large variant.
#[allow(clippy::large_enum_variant)]
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
    /// `certify unknown` or `certify measured|predicted [<lo_hz> <hi_hz> …]`: how the installed
    /// shaper was checked and the band (Hz) certified for each mode slot in order (at most
    /// [`MAX_MODES`] pairs); `tune` sends it after programming the shaper.
    Certify(Certificate),
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
    /// `watch …`: the drift watch ([`WatchCommand`], [`WatchReply`]).
    Watch(WatchCommand),
    /// `payload …`: the payload schedule ([`PayloadCommand`]).
    Payload(PayloadCommand),
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

/// The reply to a line longer than [`crate::console::LINE_MAX`] bytes (discarded whole; the
/// line assembly, not the parser, detects it).
pub const LINE_TOO_LONG: Refusal =
    Refusal::new("line-too-long", "line longer than 200 bytes discarded");

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

pub(crate) const PATHS: [(NumericPath, &str); 2] =
    [(NumericPath::Fixed, "fixed"), (NumericPath::F32, "f32")];
pub(crate) const SOURCES: [(Source, &str); 2] =
    [(Source::Internal, "internal"), (Source::StepDir, "stepdir")];

/// A finite number, or a refusal (`syntax` if not a number, `range` if not finite).
///
/// Decimal text `[+-]digits[.digits][(e|E)[+-]digits]` (or `inf`/`nan`, refused as not finite),
/// read without core's float parser, whose 128-bit power tables cost ~13 kB of flash
/// ([`decimal_f64`]).
pub(crate) fn parse_f64(s: &str) -> Result<f64, Refusal> {
    let v = decimal_f64(s).ok_or(syntax("expected a number"))?;
    if !v.is_finite() {
        return Err(Refusal::new("range", "number must be finite"));
    }
    Ok(v)
}

/// Exact powers of ten as doubles (10²² is the largest).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// A decimal's significand (its first 19 significant digits, trailing zeros removed) and power
/// of ten: the text is ±`m` × 10^`e`.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Decimal {
    m: u64,
    e: i64,
}

/// The value of decimal text. Where the significand m < 2⁵³ and |e| ≤ 22 both are exact doubles
/// and one IEEE multiplication or division rounds correctly (Clinger 1990's fast path). Beyond
/// it, the double near m·10^e ([`SCALE10_ULP`]) whose shortest representation (`{:e}`, what this
/// firmware and every host print) is the text's decimal is the correctly rounded value, since
/// that decimal lies in its rounding interval; text no double prints that way is read within a
/// few ulp. `None`: not a number.
fn decimal_f64(s: &str) -> Option<f64> {
    let (neg, body) = match s.as_bytes().first()? {
        b'-' => (true, &s[1..]),
        b'+' => (false, &s[1..]),
        _ => (false, s),
    };
    let lower = |w: &str| body.eq_ignore_ascii_case(w);
    if lower("inf") || lower("infinity") || lower("nan") {
        return Some(f64::INFINITY);
    }
    let d = decimal(body)?;
    let x = scale10(d.m as f64, d.e);
    let v = if (d.m < 1 << 53 && d.e.abs() <= 22) || x == 0.0 || !x.is_finite() {
        x
    } else {
        shortest_match(x, d).unwrap_or(x)
    };
    Some(if neg { -v } else { v })
}

/// Ulp between `scale10`'s result and m·10^e at most: one rounding of m and one per factor
/// (at most 15 factors of 10²² to 10³⁰⁸), half an ulp each.
const SCALE10_ULP: u64 = 16;

/// Among the doubles within [`SCALE10_ULP`] of `x`, the one whose shortest representation is
/// `d`.
fn shortest_match(x: f64, d: Decimal) -> Option<f64> {
    use core::fmt::Write as _;
    let bits = x.to_bits();
    (0..=2 * SCALE10_ULP).find_map(|i| {
        let b = bits.checked_add(i)?.checked_sub(SCALE10_ULP)?;
        let y = f64::from_bits(b);
        let mut text: heapless::String<32> = heapless::String::new();
        write!(text, "{y:e}").ok()?;
        (decimal(&text)? == d).then_some(y)
    })
}

/// The unsigned decimal `body` (see [`parse_f64`]); `None` when it is not one.
fn decimal(body: &str) -> Option<Decimal> {
    let (mant, exp_txt) = match body.find(['e', 'E']) {
        Some(i) => (&body[..i], Some(&body[i + 1..])),
        None => (body, None),
    };
    let (int, frac) = mant.split_once('.').unwrap_or((mant, ""));
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    let (mut m, mut e, mut digits) = (0u64, 0i64, 0u32);
    let marked = int.bytes().map(|c| (c, false));
    for (c, fractional) in marked.chain(frac.bytes().map(|c| (c, true))) {
        let d = c.checked_sub(b'0').filter(|d| *d <= 9)?;
        if m == 0 && d == 0 {
            // a leading zero: no significance, only its place
            e -= i64::from(fractional);
        } else if digits < 19 {
            m = m * 10 + u64::from(d);
            digits += 1;
            e -= i64::from(fractional);
        } else if !fractional {
            // an integer digit beyond the 19 kept
            e += 1;
        }
    }
    if let Some(t) = exp_txt {
        let (eneg, et) = match t.as_bytes().first()? {
            b'-' => (true, &t[1..]),
            b'+' => (false, &t[1..]),
            _ => (false, t),
        };
        if et.is_empty() {
            return None;
        }
        let mut x = 0i64;
        for c in et.bytes() {
            x = (x * 10 + i64::from(c.checked_sub(b'0').filter(|d| *d <= 9)?)).min(100_000);
        }
        e += if eneg { -x } else { x };
    }
    while m != 0 && m % 10 == 0 {
        m /= 10;
        e += 1;
    }
    if m == 0 {
        e = 0;
    }
    Some(Decimal { m, e })
}

/// `x` × 10^`e` by exact powers of ten (one rounding where |e| ≤ 22).
fn scale10(mut x: f64, mut e: i64) -> f64 {
    if x == 0.0 {
        return 0.0;
    }
    while e > 22 && x.is_finite() {
        x *= POW10[22];
        e -= 22;
    }
    while e < -22 && x != 0.0 {
        x /= POW10[22];
        e += 22;
    }
    // |e| ≤ 22 here unless x over- or underflowed on the way (then x is ∞ or 0 and stays so)
    let p = POW10[e.unsigned_abs().min(22) as usize];
    if e >= 0 {
        x * p
    } else {
        x / p
    }
}

/// A mode slot `1..=4`.
pub(crate) fn parse_slot(s: &str) -> Result<usize, Refusal> {
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
            "certify" => Command::Certify(parse_certify(args)?),
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
            "watch" => Command::Watch(watch::parse_watch(args)?),
            "payload" => Command::Payload(watch::parse_payload(args)?),
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

fn parse_certify(args: &[&str]) -> Result<Certificate, Refusal> {
    const USAGE: &str = "certify unknown | certify measured|predicted [<lo_hz> <hi_hz> ...]";
    let (word, bands) = args.split_first().ok_or(syntax(USAGE))?;
    let verified = Verified::from_name(word).ok_or(syntax(USAGE))?;
    if bands.len() % 2 != 0 || bands.len() > 2 * MAX_MODES {
        return Err(syntax(USAGE));
    }
    let mut c = Certificate {
        verified,
        band_hz: [None; MAX_MODES],
    };
    for (slot, pair) in c.band_hz.iter_mut().zip(bands.chunks_exact(2)) {
        *slot = Some((parse_f64(pair[0])? as f32, parse_f64(pair[1])? as f32));
    }
    Ok(c)
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

pub(crate) fn on_off(on: bool) -> &'static str {
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
            Command::Certify(c) => {
                write!(f, "certify {}", c.verified.name())?;
                c.band_hz
                    .iter()
                    .map_while(|b| *b)
                    .try_for_each(|(lo, hi)| write!(f, " {lo} {hi}"))
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
            Command::Watch(w) => write!(f, "{w}"),
            Command::Payload(p) => write!(f, "{p}"),
        }
    }
}
