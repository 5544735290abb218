//! The operator's serial console: line assembly, parsing and execution (no heap, no panic).
//!
//! Protocol (115200 8N1, lines end in `\n`, `\r` or `\r\n`): every line, an empty one too,
//! gets one or more reply lines; informational lines start with `# `, and the **last line** is either
//! `ok <command> [key=value …]` or `err <code>: <message>`. Codes: `unknown`, `syntax`,
//! `range`, `shaper`, `too-long`, `busy`, `source`, `step-rate`, `budget`, `garbage`,
//! `line-too-long`,
//! `storage`, `corrupt`. On `err` nothing changes.
//!
//! Parameter changes are validated and their shaper is designed here, in thread context;
//! the runtime only receives a finished [`RunParams`] (see [`crate::runtime`] for when it
//! takes effect).

use crate::config::{ModeSetting, Settings, Source, MAX_CUSTOM_IMPULSES, MAX_MODES};
use crate::engine::NumericPath;
use crate::reference::SweepKind;
use crate::runtime::{RunParams, Runtime};
use crate::shaper::{residual_vibration, Impulse, ShaperKind};
use core::fmt::Write;

/// Longest accepted line (bytes, without the terminator).
pub const LINE_MAX: usize = 200;

/// One assembled line.
pub type Line = heapless::Vec<u8, LINE_MAX>;

/// A line that could not be assembled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// More than [`LINE_MAX`] bytes before the terminator (the whole line is discarded).
    TooLong,
}

/// Assembles bytes into lines. `\n`, `\r` and `\r\n` each end one line; an empty line is a
/// line too (it gets a reply, like every line).
#[derive(Clone, Debug, Default)]
pub struct LineBuffer {
    buf: Line,
    overflow: bool,
    after_cr: bool,
}

impl LineBuffer {
    /// An empty buffer.
    pub const fn new() -> Self {
        LineBuffer {
            buf: heapless::Vec::new(),
            overflow: false,
            after_cr: false,
        }
    }

    /// Feeds one byte; returns a complete line (or an over-long-line error) at a terminator.
    pub fn push(&mut self, byte: u8) -> Option<Result<Line, LineError>> {
        let after_cr = core::mem::replace(&mut self.after_cr, byte == b'\r');
        if byte == b'\n' && after_cr {
            return None; // the `\n` of a `\r\n`
        }
        if byte == b'\n' || byte == b'\r' {
            let overflow = core::mem::replace(&mut self.overflow, false);
            let line = core::mem::take(&mut self.buf);
            if overflow {
                return Some(Err(LineError::TooLong));
            }
            return Some(Ok(line));
        }
        if !self.overflow && self.buf.push(byte).is_err() {
            self.overflow = true;
            self.buf.clear();
        }
        None
    }
}

/// Access to the interrupt-owned [`Runtime`]: the firmware wraps it in a critical section,
/// the host calls it directly.
pub trait RuntimeAccess {
    /// Runs `f` with exclusive access to the runtime.
    fn with<T>(&mut self, f: impl FnOnce(&mut Runtime) -> T) -> T;
}

impl RuntimeAccess for Runtime {
    fn with<T>(&mut self, f: impl FnOnce(&mut Runtime) -> T) -> T {
        f(self)
    }
}

/// Work the glue must do after a command (flash access is async and platform-specific).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Nothing more.
    None,
    /// Store [`Console::settings`], then call [`Console::finish_save`].
    Save,
    /// Read the stored settings, then call [`Console::finish_load`].
    Load,
}

/// The console: owns the operator's [`Settings`].
#[derive(Clone, Debug)]
pub struct Console {
    settings: Settings,
}

/// A console error: code and message.
struct CmdErr(&'static str, &'static str);

type CmdResult = Result<(), CmdErr>;

const HELP: &[&str] = &[
    "help | status | shaper | config",
    "mode <1-4> <zv|zvd|zvdd|zvddd|mzv|ei|2hei|3hei|umzv> <freq_hz> <zeta> [v_tol]",
    "clear <1-4|all> | custom <a>@<t_s> ... | custom clear | shaping on|off | path fixed|f32",
    "move <target_mm> [speed_mm_s] [accel_mm_s2] | stop | zero | speed <mm_s> | accel <mm_s2>",
    "sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>   (about the present position)",
    "rate <tick_hz> | step <nm_per_step> | maxrate <steps_per_s> | input <nm_per_count>",
    "source internal|stepdir | save | load | defaults",
    "capture <every_n_ticks> | dump <first> <count<=32>   (setpoints in nm)",
];

impl Console {
    /// A console whose settings are `settings` (already applied to the runtime by the glue).
    pub fn new(settings: Settings) -> Self {
        Console { settings }
    }

    /// The settings in force (or pending in the runtime).
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Boot: applies `loaded` settings (or the defaults) to the runtime and says which on
    /// `out`. `loaded` is the storage result: `Ok(Some)` a record, `Ok(None)` no record,
    /// `Err` a corrupt or unreadable record.
    pub fn boot<E: core::fmt::Display>(
        loaded: Result<Option<Settings>, E>,
        rt: &mut impl RuntimeAccess,
        stepdir_count: u16,
        out: &mut impl Write,
    ) -> Console {
        let (settings, note): (Settings, &str) = match loaded {
            Ok(Some(s)) => (s, "settings loaded from flash"),
            Ok(None) => (Settings::DEFAULT, "no saved settings, using defaults"),
            Err(ref e) => {
                let _ = writeln!(out, "# boot: stored settings unusable ({e})");
                (Settings::DEFAULT, "using defaults")
            }
        };
        let params = match RunParams::from_settings(&settings) {
            Ok(p) => p,
            Err(_) => match RunParams::from_settings(&Settings::DEFAULT) {
                Ok(p) => p,
                Err(_) => return Console::new(Settings::DEFAULT),
            },
        };
        rt.with(|r| r.configure_at_boot(params, stepdir_count));
        let _ = writeln!(out, "# boot: {note}");
        let _ = writeln!(out, "ok boot");
        Console::new(settings)
    }

    /// Executes one line and writes the reply. Never panics; on `err` nothing changes.
    pub fn handle_line(
        &mut self,
        line: &[u8],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> Action {
        let text = match core::str::from_utf8(line) {
            Ok(t) if t.bytes().all(|b| b == b'\t' || (0x20..0x7f).contains(&b)) => t,
            _ => {
                let _ = writeln!(
                    out,
                    "err garbage: line contains non-printable or non-ASCII bytes"
                );
                return Action::None;
            }
        };
        let mut words = text.split_ascii_whitespace();
        let Some(cmd) = words.next() else {
            let _ = writeln!(out, "err syntax: empty line (try help)");
            return Action::None;
        };
        let mut args: heapless::Vec<&str, 24> = heapless::Vec::new();
        for w in words {
            if args.push(w).is_err() {
                let _ = writeln!(out, "err syntax: too many arguments");
                return Action::None;
            }
        }
        let mut action = Action::None;
        let takes_no_args = matches!(
            cmd,
            "help"
                | "status"
                | "shaper"
                | "config"
                | "zero"
                | "defaults"
                | "save"
                | "load"
                | "stop"
        );
        if takes_no_args && !args.is_empty() {
            let _ = writeln!(out, "err syntax: {cmd} takes no arguments");
            return Action::None;
        }
        let r = match cmd {
            "help" => self.help(out),
            "status" => self.status(rt, out),
            "shaper" => self.show_shaper(rt, out),
            "config" => self.show_config(out),
            "mode" => self.cmd_mode(&args, rt, out),
            "clear" => self.cmd_clear(&args, rt, out),
            "custom" => self.cmd_custom(&args, rt, out),
            "shaping" => self.cmd_shaping(&args, rt, out),
            "path" => self.cmd_path(&args, rt, out),
            "rate" | "step" | "maxrate" | "input" => self.cmd_uint(cmd, &args, rt, out),
            "speed" | "accel" => self.cmd_motion_default(cmd, &args, out),
            "source" => self.cmd_source(&args, rt, out),
            "move" => self.cmd_move(&args, rt, out),
            "sweep" => self.cmd_sweep(&args, rt, out),
            "stop" => self.cmd_stop(&args, rt, out),
            "capture" => self.cmd_capture(&args, rt, out),
            "dump" => self.cmd_dump(&args, rt, out),
            "zero" => rt
                .with(|r| r.zero())
                .map_err(|e| CmdErr(e.code(), e.message()))
                .map(|_| {
                    let _ = writeln!(out, "ok zero");
                }),
            "defaults" => self.commit(Settings::DEFAULT, rt, out, "defaults"),
            "save" | "load" => {
                action = if cmd == "save" {
                    Action::Save
                } else {
                    Action::Load
                };
                Ok(())
            }
            _ => Err(CmdErr("unknown", "unknown command (try help)")),
        };
        if let Err(CmdErr(code, msg)) = r {
            let _ = writeln!(out, "err {code}: {msg}");
            return Action::None;
        }
        action
    }

    /// Reports the outcome of a save the glue performed after [`Action::Save`].
    pub fn finish_save<E: core::fmt::Display>(&self, result: Result<(), E>, out: &mut impl Write) {
        let _ = match result {
            Ok(()) => writeln!(out, "ok save"),
            Err(e) => writeln!(out, "err storage: save failed ({e}); previous record kept"),
        };
    }

    /// Applies the settings the glue loaded after [`Action::Load`].
    pub fn finish_load<E: core::fmt::Display>(
        &mut self,
        result: Result<Option<Settings>, E>,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) {
        let r = match result {
            Ok(Some(s)) => self.commit(s, rt, out, "load"),
            Ok(None) => Err(CmdErr("storage", "no saved settings")),
            Err(e) => {
                let _ = writeln!(out, "# load: {e}");
                Err(CmdErr(
                    "corrupt",
                    "stored settings unusable; settings unchanged",
                ))
            }
        };
        if let Err(CmdErr(code, msg)) = r {
            let _ = writeln!(out, "err {code}: {msg}");
        }
    }

    /// Validates `new`, designs its taps and hands them to the runtime; then adopts `new`.
    /// The modes and custom list are validated even while shaping is off (so that a later
    /// `shaping on` cannot fail on them). The reply says when the change applies
    /// (`applies=next-tick` or `applies=when-still waiting=<what>`).
    fn commit(
        &mut self,
        new: Settings,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
        what: &str,
    ) -> CmdResult {
        let config_err = |e: crate::config::ConfigError, out: &mut dyn Write| {
            if let crate::config::ConfigError::Taps(_) = e {
                let _ = writeln!(out, "# {e} ({} Hz)", new.tick_rate_hz);
            }
            CmdErr(e.code(), config_message(&e))
        };
        if !new.shaping_enabled {
            let mut on = new.clone();
            on.shaping_enabled = true;
            on.tap_table(crate::runtime::HISTORY_LEN)
                .map_err(|e| config_err(e, out))?;
        }
        let params = RunParams::from_settings(&new).map_err(|e| config_err(e, out))?;
        let taps = params.taps.taps().len();
        let dur = params.taps.duration_ticks();
        let applies = rt.with(|r| {
            let in_flight = r.engine().taps_in_flight();
            r.request(params).map_err(|e| (e, in_flight))
        });
        let applies = match applies {
            Ok(a) => a,
            Err((e, in_flight)) => {
                if let crate::runtime::RuntimeError::Switch(_) = e {
                    let _ = writeln!(
                        out,
                        "# transition would run {} + {taps} taps per tick; the budget is {} \
                         (at most {} shapers in flight)",
                        in_flight,
                        crate::engine::TAP_BUDGET,
                        crate::engine::MAX_STAGES
                    );
                }
                return Err(CmdErr(e.code(), e.message()));
            }
        };
        self.settings = new;
        let _ = write!(
            out,
            "ok {what} taps={taps} duration_ticks={dur} applies={}",
            applies.name()
        );
        if applies == crate::runtime::Applies::WhenStill {
            let w = rt.with(|r| r.status().waiting);
            let _ = write!(out, " waiting={}", w.names());
        }
        let _ = writeln!(out);
        Ok(())
    }

    fn help(&self, out: &mut impl Write) -> CmdResult {
        for l in HELP {
            let _ = writeln!(out, "# {l}");
        }
        let _ = writeln!(out, "ok help");
        Ok(())
    }

    fn status(&self, rt: &mut impl RuntimeAccess, out: &mut impl Write) -> CmdResult {
        let s = rt.with(|r| r.status());
        let _ = writeln!(
            out,
            "ok status ticks={} reference_mm={} setpoint_mm={} emitted_steps={} moving={} pending={} \
             waiting={} stages={} taps_in_flight={} still_ticks={} step_rate_faults={} tick_hz={} \
             path={} taps={} duration_ticks={} source={} shaping={} changes={}",
            s.ticks,
            Num(s.reference_counts as f64 * 1e-6, 6),
            Num(s.setpoint_counts as f64 * 1e-6, 6),
            s.emitted_steps,
            s.moving as u8,
            s.pending as u8,
            s.waiting.names(),
            s.stages,
            s.taps_in_flight,
            s.still_ticks,
            s.step_rate_faults,
            s.tick_rate_hz,
            s.path.name(),
            s.taps,
            s.duration_ticks,
            s.source.name(),
            if self.settings.shaping_enabled { "on" } else { "off" },
            s.applied_changes,
        );
        Ok(())
    }

    /// `shaper`: the configured impulse table, its duration and V at ±10 % of each mode.
    fn show_shaper(&self, rt: &mut impl RuntimeAccess, out: &mut impl Write) -> CmdResult {
        let shaper = self
            .settings
            .shaper()
            .map_err(|e| CmdErr(e.code(), config_message(&e)))?;
        for (i, imp) in shaper.impulses().iter().enumerate() {
            let _ = writeln!(
                out,
                "# impulse {} amplitude={} time_s={}",
                i + 1,
                imp.amplitude,
                imp.time_s
            );
        }
        for (slot, m) in self.settings.modes.iter().enumerate() {
            if let Some(m) = m {
                let _ = writeln!(
                    out,
                    "# mode {} {} freq_hz={} zeta={} v_pct_at_-10pct={:.3} v_pct_at_0={:.3} v_pct_at_+10pct={:.3}",
                    slot + 1,
                    m.kind.name(),
                    m.freq_hz,
                    m.zeta,
                    100.0 * residual_vibration(&shaper, 0.9 * m.freq_hz, m.zeta),
                    100.0 * residual_vibration(&shaper, m.freq_hz, m.zeta),
                    100.0 * residual_vibration(&shaper, 1.1 * m.freq_hz, m.zeta),
                );
            }
        }
        let pending = rt.with(|r| r.pending().is_some());
        let _ = write!(
            out,
            "ok shaper n={} duration_s={} pending={} impulses=",
            shaper.len(),
            shaper.duration_s(),
            pending as u8
        );
        for (i, imp) in shaper.impulses().iter().enumerate() {
            let _ = write!(
                out,
                "{}{}@{}",
                if i == 0 { "" } else { "," },
                imp.amplitude,
                imp.time_s
            );
        }
        let _ = writeln!(out);
        Ok(())
    }

    fn show_config(&self, out: &mut impl Write) -> CmdResult {
        let s = &self.settings;
        for (slot, m) in s.modes.iter().enumerate() {
            match m {
                Some(m) => {
                    let _ = write!(
                        out,
                        "# mode {} {} {} {}",
                        slot + 1,
                        m.kind.name(),
                        m.freq_hz,
                        m.zeta
                    );
                    if let Some(v) = m.kind.v_tol() {
                        let _ = write!(out, " {v}");
                    }
                    let _ = writeln!(out);
                }
                None => {
                    let _ = writeln!(out, "# mode {} none", slot + 1);
                }
            }
        }
        let _ = writeln!(
            out,
            "ok config shaping={} path={} tick_hz={} step_nm={} maxrate={} input_nm={} source={} speed_mm_s={} \
             accel_mm_s2={} custom={}",
            if s.shaping_enabled { "on" } else { "off" },
            s.path.name(),
            s.tick_rate_hz,
            s.step_nm,
            s.max_step_rate_hz,
            s.input_nm_per_count,
            s.source.name(),
            Num(s.move_speed_mm_s as f64, 4),
            Num(s.move_accel_mm_s2 as f64, 4),
            s.custom.len()
        );
        Ok(())
    }

    fn cmd_mode(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        if !(4..=5).contains(&args.len()) {
            return Err(CmdErr(
                "syntax",
                "mode <1-4> <kind> <freq_hz> <zeta> [v_tol]",
            ));
        }
        let slot = parse_slot(args[0])?;
        let v_tol = match args.get(4) {
            Some(v) => parse_f64(v)?,
            None => crate::shaper::design::DEFAULT_V_TOL,
        };
        let kind =
            ShaperKind::from_name(args[1], v_tol).ok_or(CmdErr("syntax", "unknown shaper kind"))?;
        if args.len() == 5 && kind.v_tol().is_none() {
            return Err(CmdErr("syntax", "v_tol only applies to ei, 2hei, 3hei"));
        }
        let freq_hz = parse_f64(args[2])?;
        let zeta = parse_f64(args[3])?;
        // Design once here for a precise error before the combined shaper is checked.
        crate::shaper::design(kind, freq_hz, zeta).map_err(|e| CmdErr("range", e.message()))?;
        let mut new = self.settings.clone();
        new.modes[slot] = Some(ModeSetting {
            kind,
            freq_hz,
            zeta,
        });
        self.commit(new, rt, out, "mode")
    }

    fn cmd_clear(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        match args {
            ["all"] => new.modes = [None; MAX_MODES],
            [s] => new.modes[parse_slot(s)?] = None,
            _ => return Err(CmdErr("syntax", "clear <1-4|all>")),
        }
        self.commit(new, rt, out, "clear")
    }

    fn cmd_custom(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        new.custom.clear();
        if args != ["clear"] {
            if args.is_empty() || args.len() > MAX_CUSTOM_IMPULSES {
                return Err(CmdErr(
                    "syntax",
                    "custom <a>@<t_s> ... (1 to 16 impulses) | custom clear",
                ));
            }
            for a in args {
                let (amp, t) = a
                    .split_once('@')
                    .ok_or(CmdErr("syntax", "impulse must be <amplitude>@<time_s>"))?;
                let imp = Impulse {
                    amplitude: parse_f64(amp)?,
                    time_s: parse_f64(t)?,
                };
                if imp.time_s < 0.0 {
                    return Err(CmdErr("range", "impulse time must be >= 0"));
                }
                let _ = new.custom.push(imp);
            }
        }
        self.commit(new, rt, out, "custom")
    }

    fn cmd_shaping(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        new.shaping_enabled = match args {
            ["on"] => true,
            ["off"] => false,
            _ => return Err(CmdErr("syntax", "shaping on|off")),
        };
        self.commit(new, rt, out, "shaping")
    }

    fn cmd_path(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        new.path = match args {
            ["fixed"] => NumericPath::Fixed,
            ["f32"] => NumericPath::F32,
            _ => return Err(CmdErr("syntax", "path fixed|f32")),
        };
        self.commit(new, rt, out, "path")
    }

    fn cmd_source(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        new.source = match args {
            ["internal"] => Source::Internal,
            ["stepdir"] => Source::StepDir,
            _ => return Err(CmdErr("syntax", "source internal|stepdir")),
        };
        self.commit(new, rt, out, "source")
    }

    fn cmd_uint(
        &mut self,
        cmd: &str,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let [v] = args else {
            return Err(CmdErr("syntax", "expected one integer argument"));
        };
        let v: u32 = v
            .parse()
            .map_err(|_| CmdErr("syntax", "expected a non-negative integer"))?;
        let mut new = self.settings.clone();
        match cmd {
            "rate" => new.tick_rate_hz = v,
            "step" => new.step_nm = v,
            "maxrate" => new.max_step_rate_hz = v,
            _ => new.input_nm_per_count = v,
        }
        self.commit(new, rt, out, cmd)
    }

    fn cmd_motion_default(&mut self, cmd: &str, args: &[&str], out: &mut impl Write) -> CmdResult {
        let [v] = args else {
            return Err(CmdErr("syntax", "expected one number"));
        };
        let v = parse_f64(v)? as f32;
        let mut new = self.settings.clone();
        if cmd == "speed" {
            new.move_speed_mm_s = v;
        } else {
            new.move_accel_mm_s2 = v;
        }
        new.validate()
            .map_err(|e| CmdErr(e.code(), config_message(&e)))?;
        self.settings = new;
        let _ = writeln!(out, "ok {cmd}");
        Ok(())
    }

    fn cmd_capture(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let [d] = args else {
            return Err(CmdErr("syntax", "capture <every_n_ticks>"));
        };
        let d: u32 = d
            .parse()
            .map_err(|_| CmdErr("syntax", "expected a positive integer"))?;
        if !(1..=10_000).contains(&d) {
            return Err(CmdErr("range", "decimation must be 1..10000 ticks"));
        }
        let tick_hz = rt.with(|r| {
            r.arm_capture(d);
            r.tick_rate_hz()
        });
        let _ = writeln!(
            out,
            "ok capture every_ticks={d} sample_rate_hz={} capacity={}",
            tick_hz as f64 / d as f64,
            crate::runtime::CAPTURE_LEN
        );
        Ok(())
    }

    fn cmd_dump(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let [first, count] = args else {
            return Err(CmdErr("syntax", "dump <first> <count>"));
        };
        let first: usize = first
            .parse()
            .map_err(|_| CmdErr("syntax", "expected an integer"))?;
        let count: usize = count
            .parse()
            .map_err(|_| CmdErr("syntax", "expected an integer"))?;
        if count > 32 {
            return Err(CmdErr("range", "count must be <= 32"));
        }
        let mut vals = [0i32; 32];
        let (total, armed, n) = rt.with(|r| {
            let c = r.capture();
            let s = c.samples();
            let n = s.len().saturating_sub(first).min(count);
            if let (Some(src), Some(dst)) = (s.get(first..first + n), vals.get_mut(..n)) {
                dst.copy_from_slice(src);
            }
            (s.len(), c.armed(), n)
        });
        let _ = write!(
            out,
            "ok dump first={first} n={n} total={total} armed={} values=",
            armed as u8
        );
        for (i, v) in vals.iter().take(n).enumerate() {
            let _ = write!(out, "{}{v}", if i == 0 { "" } else { "," });
        }
        let _ = writeln!(out);
        Ok(())
    }

    fn cmd_move(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        if args.is_empty() || args.len() > 3 {
            return Err(CmdErr(
                "syntax",
                "move <target_mm> [speed_mm_s] [accel_mm_s2]",
            ));
        }
        let target_mm = parse_f64(args[0])?;
        let speed = match args.get(1) {
            Some(v) => parse_f64(v)?,
            None => self.settings.move_speed_mm_s as f64,
        };
        let accel = match args.get(2) {
            Some(v) => parse_f64(v)?,
            None => self.settings.move_accel_mm_s2 as f64,
        };
        if !(target_mm.abs() <= 1000.0) {
            return Err(CmdErr("range", "target outside +-1000 mm"));
        }
        if !(speed > 0.0 && speed <= 10_000.0 && accel > 0.0 && accel <= 1.0e6) {
            return Err(CmdErr(
                "range",
                "speed (0..10000 mm/s) and accel (0..1e6 mm/s^2) must be > 0",
            ));
        }
        let target = libm::round(target_mm * 1e6) as i32;
        let ticks = rt
            .with(|r| r.start_move(target, (speed * 1e6) as f32, (accel * 1e6) as f32))
            .map_err(|e| runtime_err(e, out))?;
        let _ = writeln!(out, "ok move target_mm={target_mm} ticks={ticks}");
        Ok(())
    }
}

/// A runtime refusal as a console error; a step-rate refusal first names the limit.
fn runtime_err(e: crate::runtime::RuntimeError, out: &mut impl Write) -> CmdErr {
    if let crate::runtime::RuntimeError::StepRate(x) = e {
        let _ = writeln!(
            out,
            "# shaped peak {} steps/s > maxrate {} steps/s; reference speed must stay <= {} mm/s",
            Num(x.shaped_peak_steps_s as f64, 0),
            x.max_step_rate_hz,
            Num(x.max_reference_speed_nm_s as f64 * 1e-6, 3),
        );
    }
    CmdErr(e.code(), e.message())
}

/// A number printed with at most `.1` decimals, trailing zeros removed (`68.04`, not
/// `68.03999999999999`; `1e-308` as `0`): the console's number format.
pub struct Num(pub f64, pub usize);

impl core::fmt::Display for Num {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
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

impl Console {
    fn cmd_sweep(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let [kind, f0, f1, amp, dur] = args else {
            return Err(CmdErr(
                "syntax",
                "sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>",
            ));
        };
        let kind = match *kind {
            "lin" => SweepKind::Linear,
            "exp" => SweepKind::Exponential,
            _ => return Err(CmdErr("syntax", "sweep kind must be lin or exp")),
        };
        let (f0, f1, amp, dur) = (
            parse_f64(f0)?,
            parse_f64(f1)?,
            parse_f64(amp)?,
            parse_f64(dur)?,
        );
        if !(amp > 0.0 && amp <= 1000.0) {
            return Err(CmdErr("range", "amplitude must be in (0, 1000] mm"));
        }
        let ticks = rt
            .with(|r| r.start_sweep(kind, f0, f1, amp * 1e6, dur))
            .map_err(|e| runtime_err(e, out))?;
        let _ = writeln!(
            out,
            "ok sweep kind={} f0_hz={} f1_hz={} amplitude_mm={} ticks={ticks}",
            kind.name(),
            Num(f0, 6),
            Num(f1, 6),
            Num(amp, 6)
        );
        Ok(())
    }

    fn cmd_stop(
        &mut self,
        args: &[&str],
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let _ = args;
        let ticks = rt.with(|r| r.stop());
        let _ = writeln!(out, "ok stop ticks_to_rest={ticks}");
        Ok(())
    }
}

fn parse_f64(s: &str) -> Result<f64, CmdErr> {
    let v: f64 = s
        .parse()
        .map_err(|_| CmdErr("syntax", "expected a number"))?;
    if !v.is_finite() {
        return Err(CmdErr("range", "number must be finite"));
    }
    Ok(v)
}

fn parse_slot(s: &str) -> Result<usize, CmdErr> {
    match s.parse::<usize>() {
        Ok(n) if (1..=MAX_MODES).contains(&n) => Ok(n - 1),
        _ => Err(CmdErr("range", "mode slot must be 1..4")),
    }
}

/// Static messages for configuration errors (the console cannot format into a `&'static`).
fn config_message(e: &crate::config::ConfigError) -> &'static str {
    use crate::config::ConfigError as C;
    use crate::engine::TapError;
    match e {
        C::Shaper(s) => s.message(),
        C::Taps(TapError::TooLong { .. }) => {
            "shaper longer than the history buffer allows at this tick rate"
        }
        C::Taps(TapError::TickRate) => "tick rate invalid",
        C::Taps(TapError::AmplitudeRange) => "sum of |amplitudes| above 3.9",
        C::Range(f) => f,
        C::Corrupt => "stored settings corrupt",
        C::Buffer => "buffer too small",
    }
}
