//! The operator's serial console: line assembly and execution (no heap, no panic).
//!
//! Transport: 115200 8N1, lines end in `\n`, `\r` or `\r\n`; every line, an empty one too,
//! gets one or more reply lines. The commands and the reply lines are those of
//! [`crate::protocol`] (parsed by [`Command::parse`], replies written by its reply types):
//! informational lines start with `# `, and the **last line** is either
//! `ok <command> [key=value …]` or `err <code>: <message>` (codes:
//! [`crate::protocol::ErrorCode`]). On `err` nothing changes.
//!
//! Parameter changes are validated and their shaper is designed here, in thread context;
//! the runtime only receives a finished [`RunParams`] (see [`crate::runtime`] for when it
//! takes effect).

use crate::config::{Settings, MAX_MODES};
pub use crate::protocol::Num;
use crate::protocol::{
    CaptureReply, Command, ConfigReply, DumpReply, ModeLine, MoveReply, Refusal, StatusReply,
    SweepArgs, SweepReply, DUMP_MAX,
};
use crate::protocol::{PayloadCommand, WatchCommand, WatchReply};
use crate::runtime::{RunParams, Runtime};
use crate::sensor::{AccelConfig, SensorEvent};
use crate::shaper::residual_vibration;
use crate::storage::StorageError;
use crate::watch::{Watch, WatchState, QUEUE_LEN};
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

/// The console: owns the operator's [`Settings`], and remembers a stored record that was
/// refused (at boot or by `load`) until a `save` replaces it, so that `status` can say so.
#[derive(Clone, Debug)]
pub struct Console {
    settings: Settings,
    refused_record: Option<StorageError>,
    watch: Watch,
    /// Tick rate the watch was configured for (Hz).
    watch_tick_hz: u32,
    /// Automatic retunes since boot.
    retunes: u32,
    /// What the watch did on its own since the last `watch` (reported then).
    notes: heapless::Vec<WatchNote, 8>,
}

/// Something the watch did between two `watch` queries.
#[derive(Clone, Copy, Debug, PartialEq)]
enum WatchNote {
    /// Mode slot (0-based) retuned from, to (Hz).
    Retuned(usize, f64, f64),
    /// Mode slot measured at (Hz) outside the limits: not retuned.
    OutsideLimits(usize, f64),
    /// The retune was refused by the runtime (e.g. the tap budget of a transition in flight).
    Refused(&'static str),
}

/// A writer that drops everything (the reply of a change the watch makes on its own).
struct Discard;

impl Write for Discard {
    fn write_str(&mut self, _: &str) -> core::fmt::Result {
        Ok(())
    }
}
/// The result of executing one command.
type CmdResult = Result<(), Refusal>;

const HELP: &[&str] = &[
    "help | status | shaper | config",
    "mode <1-4> <zv|zvd|zvdd|zvddd|mzv|ei|2hei|3hei|umzv> <freq_hz> <zeta> [v_tol]",
    "clear <1-4|all> | custom <a>@<t_s> ... | custom clear | shaping on|off | path fixed|f32",
    "certify unknown | certify measured|predicted [<lo_hz> <hi_hz> ...]   (set by tune)",
    "move <target_mm> [speed_mm_s] [accel_mm_s2] | stop | zero | speed <mm_s> | accel <mm_s2>",
    "sweep lin|exp <f0_hz> <f1_hz> <amplitude_mm> <duration_s>   (about the present position)",
    "rate <tick_hz> | step <nm_per_step> | maxrate <steps_per_s> | input <nm_per_count>",
    "source internal|stepdir | save | load | defaults",
    "capture <every_n_ticks> | dump <first> <count<=32>   (setpoints in nm)",
    "watch | watch on|off | watch limits <lo_hz> <hi_hz> | watch auto on|off",
    "payload | payload <0-7> | payload <0-7> store",
];

impl Console {
    /// A console whose settings are `settings` (already applied to the runtime by the glue).
    pub fn new(settings: Settings) -> Self {
        Console {
            settings,
            refused_record: None,
            watch: Watch::new(),
            watch_tick_hz: 0,
            retunes: 0,
            notes: heapless::Vec::new(),
        }
    }

    /// The drift watch.
    pub fn watch(&self) -> &Watch {
        &self.watch
    }

    /// The sensor driver found a chip configured as `accel` (or none: `None`); the watch uses
    /// it from now on.
    pub fn set_accel(&mut self, accel: Option<AccelConfig>, rt: &mut impl RuntimeAccess) {
        self.watch.set_accel(accel);
        self.configure_watch(rt);
    }

    /// One event from the sensor driver, in order (thread mode; a few additions).
    pub fn watch_event(&mut self, event: SensorEvent) {
        self.watch.push(event);
    }

    /// Advances the watch with the setpoints the tick recorded (copied out of the runtime in
    /// one short critical section; the fit runs outside it). After a move that drifted, with
    /// `watch auto on`, retunes. Call at least every 0.2 s while watching (64 queued block
    /// means: 0.256 s at the highest rate, 250 Hz). Returns the state
    /// when a move was just measured.
    pub fn watch_poll(&mut self, rt: &mut impl RuntimeAccess) -> Option<WatchState> {
        let from = self.watch.next_setpoint();
        let mut buf = [0i32; QUEUE_LEN];
        let mut steps = [0i32; QUEUE_LEN];
        let (n, first, written, tick_hz) = rt.with(|r| {
            let ring = r.watch_ring();
            let (n, first) = ring.copy_since(from, &mut buf, &mut steps);
            (n, first, ring.written(), r.tick_rate_hz())
        });
        if tick_hz != self.watch_tick_hz {
            self.configure_watch(rt);
            return None;
        }
        let state = self.watch.poll(
            buf.get(..n).unwrap_or(&[]),
            steps.get(..n).unwrap_or(&[]),
            first,
            written,
        );
        if state == Some(WatchState::Drift) && self.settings.watch.auto {
            self.auto_retune(rt);
        }
        state
    }

    /// Configures the watch for the settings and tick rate in force and arms the tick's ring.
    fn configure_watch(&mut self, rt: &mut impl RuntimeAccess) {
        let tick_hz = rt.with(|r| r.tick_rate_hz());
        let decimation = self.watch.configure(&self.settings, tick_hz);
        self.watch_tick_hz = tick_hz;
        rt.with(|r| r.arm_watch_ring(decimation));
    }

    /// Retunes each drifted mode to its measured frequency (the mean of its last two
    /// measurements, when they agree within [`crate::watch::CONFIRM_FRACTION`]) if it lies
    /// within the limits,
    /// through [`Console::commit`] (the shaper change the engine applies at the next tick by
    /// superposition: no setpoint jump). The certificate, issued for the old shaper, is cleared.
    fn auto_retune(&mut self, rt: &mut impl RuntimeAccess) {
        let Some((lo, hi)) = self.settings.watch.limits() else {
            return;
        };
        let mut new = self.settings.clone();
        let mut changed: heapless::Vec<WatchNote, MAX_MODES> = heapless::Vec::new();
        for m in self.watch.report().modes.iter().flatten() {
            // A drifted mode whose last two measurements confirm each other.
            let Some(f) = m.confirmed_hz().filter(|_| m.drifted()) else {
                continue;
            };
            if !(lo as f64..=hi as f64).contains(&f) {
                let _ = self.notes.push(WatchNote::OutsideLimits(m.slot, f));
                continue;
            }
            if let Some(Some(mode)) = new.modes.get_mut(m.slot) {
                let _ = changed.push(WatchNote::Retuned(m.slot, mode.freq_hz, f));
                mode.freq_hz = f;
            }
        }
        if changed.is_empty() {
            return;
        }
        new.certificate = crate::config::Certificate::NONE;
        match self.commit(new, rt, &mut Discard, "retune") {
            Ok(()) => {
                self.retunes = self.retunes.saturating_add(changed.len() as u32);
                for n in changed {
                    let _ = self.notes.push(n);
                }
            }
            Err(r) => {
                let _ = self.notes.push(WatchNote::Refused(r.message));
            }
        }
    }

    /// Why the stored record was refused (at boot or by the last `load`), until a successful
    /// `save` replaces it; `None` when it was accepted or there is none.
    pub fn refused_record(&self) -> Option<StorageError> {
        self.refused_record
    }

    /// The settings in force (or pending in the runtime).
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Boot: applies `loaded` settings (or the defaults) to the runtime and says which on
    /// `out`. `loaded` is the storage result: `Ok(Some)` a record, `Ok(None)` no record,
    /// `Err` a corrupt, unreadable or old-format record (named in a `# boot:` line).
    pub fn boot(
        loaded: Result<Option<Settings>, StorageError>,
        rt: &mut impl RuntimeAccess,
        stepdir_count: u16,
        out: &mut impl Write,
    ) -> Console {
        let refused = loaded.as_ref().err().copied();
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
        let mut console = Console::new(settings);
        console.refused_record = refused;
        console.configure_watch(rt);
        console
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
        match Command::parse(text).and_then(|c| self.execute(c, rt, out)) {
            Ok(action) => action,
            Err(refusal) => {
                let _ = writeln!(out, "{refusal}");
                Action::None
            }
        }
    }

    /// Executes a parsed command; the glue's work for `save` and `load`.
    fn execute(
        &mut self,
        command: Command,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> Result<Action, Refusal> {
        match command {
            Command::Help => self.help(out),
            Command::Status => self.status(rt, out),
            Command::Shaper => self.show_shaper(rt, out),
            Command::Config => self.show_config(out),
            Command::Speed(v) => self.cmd_motion_default(Some(v), None, out),
            Command::Accel(v) => self.cmd_motion_default(None, Some(v), out),
            Command::Move {
                target_mm,
                speed_mm_s,
                accel_mm_s2,
            } => self.cmd_move(target_mm, speed_mm_s, accel_mm_s2, rt, out),
            Command::Sweep(a) => self.cmd_sweep(&a, rt, out),
            Command::Stop => {
                let ticks = rt.with(|r| r.stop());
                let _ = writeln!(out, "ok stop ticks_to_rest={ticks}");
                Ok(())
            }
            Command::Zero => rt
                .with(|r| r.zero())
                .map_err(|e| Refusal::new(e.code(), e.message()))
                .map(|_| {
                    let _ = writeln!(out, "ok zero");
                }),
            Command::Capture(every) => self.cmd_capture(every, rt, out),
            Command::Dump { first, count } => self.cmd_dump(first, count, rt, out),
            Command::Save => return Ok(Action::Save),
            Command::Load => return Ok(Action::Load),
            Command::Defaults => self.commit(Settings::DEFAULT, rt, out, "defaults"),
            Command::Watch(w) => self.cmd_watch(w, rt, out),
            Command::Payload(p) => self.cmd_payload(p, rt, out),
            change => self.change_settings(change, rt, out),
        }
        .map(|()| Action::None)
    }

    /// The commands that edit the settings: a copy is edited, then committed.
    fn change_settings(
        &mut self,
        command: Command,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        // A certificate describes the shaper it was issued for: a new shaper voids it.
        if matches!(
            command,
            Command::Mode(..) | Command::Clear(_) | Command::Custom(_)
        ) {
            new.certificate = crate::config::Certificate::NONE;
        }
        let slot_range = || Refusal::new("range", "mode slot must be 1..4");
        let what = match command {
            Command::Mode(slot, m) => {
                // Design once here for a precise error before the combined shaper is checked.
                crate::shaper::design(m.kind, m.freq_hz, m.zeta)
                    .map_err(|e| Refusal::new("range", e.message()))?;
                *new.modes
                    .get_mut(slot.wrapping_sub(1))
                    .ok_or_else(slot_range)? = Some(m);
                "mode"
            }
            Command::Clear(None) => {
                new.modes = [None; MAX_MODES];
                "clear"
            }
            Command::Clear(Some(slot)) => {
                *new.modes
                    .get_mut(slot.wrapping_sub(1))
                    .ok_or_else(slot_range)? = None;
                "clear"
            }
            Command::Custom(list) => {
                new.custom = list;
                "custom"
            }
            Command::Certify(c) => {
                new.certificate = c;
                "certify"
            }
            Command::Shaping(on) => {
                new.shaping_enabled = on;
                "shaping"
            }
            Command::Path(p) => {
                new.path = p;
                "path"
            }
            Command::Source(src) => {
                new.source = src;
                "source"
            }
            Command::Rate(v) => {
                new.tick_rate_hz = v;
                "rate"
            }
            Command::Step(v) => {
                new.step_nm = v;
                "step"
            }
            Command::MaxRate(v) => {
                new.max_step_rate_hz = v;
                "maxrate"
            }
            Command::Input(v) => {
                new.input_nm_per_count = v;
                "input"
            }
            _ => return Err(Refusal::new("unknown", "unknown command (try help)")),
        };
        self.commit(new, rt, out, what)
    }

    /// Reports the outcome of a save the glue performed after [`Action::Save`].
    /// A successful save replaces a refused record (`status` no longer reports it).
    pub fn finish_save<E: core::fmt::Display>(
        &mut self,
        result: Result<(), E>,
        out: &mut impl Write,
    ) {
        let _ = match result {
            Ok(()) => {
                self.refused_record = None;
                writeln!(out, "ok save")
            }
            Err(e) => writeln!(out, "err storage: save failed ({e}); previous record kept"),
        };
    }

    /// Applies the settings the glue loaded after [`Action::Load`] (and remembers whether the
    /// stored record was refused, for `status`). A refused record leaves
    /// the settings in force and answers `err corrupt:`, `err version:` (another format
    /// version) or `err storage:`, after a `# load:` line naming the problem.
    pub fn finish_load(
        &mut self,
        result: Result<Option<Settings>, StorageError>,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) {
        self.refused_record = result.as_ref().err().copied();
        let r = match result {
            Ok(Some(s)) => self.commit(s, rt, out, "load"),
            Ok(None) => Err(Refusal::new("storage", "no saved settings")),
            Err(e) => {
                let _ = writeln!(out, "# load: {e}");
                Err(Refusal::new(
                    e.code(),
                    "stored settings unusable; settings unchanged",
                ))
            }
        };
        if let Err(refusal) = r {
            let _ = writeln!(out, "{refusal}");
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
            Refusal::new(e.code(), config_message(&e))
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
                return Err(Refusal::new(e.code(), e.message()));
            }
        };
        self.settings = new;
        self.configure_watch(rt);
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

    /// `status`: a `# stored settings refused (…)` line while the stored record is refused,
    /// then the [`StatusReply`].
    fn status(&self, rt: &mut impl RuntimeAccess, out: &mut impl Write) -> CmdResult {
        let s = rt.with(|r| r.status());
        if let Some(e) = self.refused_record {
            let _ = writeln!(
                out,
                "# stored record refused: {e}; not in use until `save` replaces it"
            );
        }
        let _ = writeln!(out, "{}", StatusReply::new(&s, &self.settings));
        Ok(())
    }

    /// `shaper`: the configured impulse table, its duration and V at ±10 % of each mode.
    fn show_shaper(&self, rt: &mut impl RuntimeAccess, out: &mut impl Write) -> CmdResult {
        let shaper = self
            .settings
            .shaper()
            .map_err(|e| Refusal::new(e.code(), config_message(&e)))?;
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
        for (i, mode) in self.settings.modes.iter().enumerate() {
            let line = ModeLine {
                slot: i + 1,
                mode: *mode,
            };
            let _ = writeln!(out, "# {line}");
        }
        let _ = writeln!(out, "{}", ConfigReply::new(&self.settings));
        Ok(())
    }

    fn cmd_motion_default(
        &mut self,
        speed_mm_s: Option<f64>,
        accel_mm_s2: Option<f64>,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        if let Some(v) = speed_mm_s {
            new.move_speed_mm_s = v as f32;
        }
        if let Some(v) = accel_mm_s2 {
            new.move_accel_mm_s2 = v as f32;
        }
        new.validate()
            .map_err(|e| Refusal::new(e.code(), config_message(&e)))?;
        self.settings = new;
        let what = if speed_mm_s.is_some() {
            "speed"
        } else {
            "accel"
        };
        let _ = writeln!(out, "ok {what}");
        Ok(())
    }

    fn cmd_capture(
        &mut self,
        every: u32,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let tick_hz = rt.with(|r| {
            r.arm_capture(every);
            r.tick_rate_hz()
        });
        let reply = CaptureReply {
            every_ticks: every,
            sample_rate_hz: tick_hz as f64 / every.max(1) as f64,
            capacity: crate::runtime::CAPTURE_LEN,
        };
        let _ = writeln!(out, "{reply}");
        Ok(())
    }

    fn cmd_dump(
        &mut self,
        first: usize,
        count: usize,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut vals = [0i32; DUMP_MAX];
        let count = count.min(DUMP_MAX);
        let (total, armed, n) = rt.with(|r| {
            let c = r.capture();
            let s = c.samples();
            let n = s.len().saturating_sub(first).min(count);
            if let (Some(src), Some(dst)) = (s.get(first..first + n), vals.get_mut(..n)) {
                dst.copy_from_slice(src);
            }
            (s.len(), c.armed(), n)
        });
        let reply = DumpReply {
            first,
            n,
            total,
            armed,
        };
        let _ = write!(out, "{reply}");
        for (i, v) in vals.iter().take(n).enumerate() {
            let _ = write!(out, "{}{v}", if i == 0 { "" } else { "," });
        }
        let _ = writeln!(out);
        Ok(())
    }

    fn cmd_move(
        &mut self,
        target_mm: f64,
        speed_mm_s: Option<f64>,
        accel_mm_s2: Option<f64>,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let speed = speed_mm_s.unwrap_or(self.settings.move_speed_mm_s as f64);
        let accel = accel_mm_s2.unwrap_or(self.settings.move_accel_mm_s2 as f64);
        if !(target_mm.abs() <= 1000.0) {
            return Err(Refusal::new("range", "target outside +-1000 mm"));
        }
        if !(speed > 0.0 && speed <= 10_000.0 && accel > 0.0 && accel <= 1.0e6) {
            return Err(Refusal::new(
                "range",
                "speed (0..10000 mm/s) and accel (0..1e6 mm/s^2) must be > 0",
            ));
        }
        let target = libm::round(target_mm * 1e6) as i32;
        let ticks = rt
            .with(|r| r.start_move(target, (speed * 1e6) as f32, (accel * 1e6) as f32))
            .map_err(|e| runtime_err(e, out))?;
        let _ = writeln!(out, "{}", MoveReply { target_mm, ticks });
        Ok(())
    }

    fn cmd_sweep(
        &mut self,
        a: &SweepArgs,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let ticks = rt
            .with(|r| r.start_sweep(a.kind, a.f0_hz, a.f1_hz, a.amplitude_mm * 1e6, a.duration_s))
            .map_err(|e| runtime_err(e, out))?;
        let _ = writeln!(out, "{}", SweepReply { args: *a, ticks });
        Ok(())
    }
}

/// The drift watch's and the payload schedule's commands.
impl Console {
    /// Adopts `new` (validated) without touching the runtime's shaper; reconfigures the watch.
    fn adopt(&mut self, new: Settings, rt: &mut impl RuntimeAccess) -> CmdResult {
        new.validate()
            .map_err(|e| Refusal::new(e.code(), config_message(&e)))?;
        self.settings = new;
        self.configure_watch(rt);
        Ok(())
    }

    fn cmd_watch(
        &mut self,
        command: WatchCommand,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        match command {
            WatchCommand::Show => {
                for note in core::mem::take(&mut self.notes) {
                    let _ = match note {
                        WatchNote::Retuned(slot, from, to) => writeln!(
                            out,
                            "# watch: retuned mode {} from {} Hz to {} Hz (next tick, by superposition)",
                            slot + 1,
                            Num(from, 5),
                            Num(to, 5)
                        ),
                        WatchNote::OutsideLimits(slot, f) => writeln!(
                            out,
                            "# watch: mode {} measured at {} Hz, outside the limits: not retuned",
                            slot + 1,
                            Num(f, 5)
                        ),
                        WatchNote::Refused(why) => writeln!(out, "# watch: retune refused: {why}"),
                    };
                }
                let reply =
                    WatchReply::new(self.watch.report(), self.settings.watch.auto, self.retunes);
                let _ = writeln!(out, "{reply}");
                return Ok(());
            }
            WatchCommand::Enable(on) => new.watch.enabled = on,
            WatchCommand::Limits(lo, hi) => new.watch.limits_hz = (lo, hi),
            WatchCommand::Auto(on) => new.watch.auto = on,
        }
        let restart = matches!(command, WatchCommand::Enable(true));
        self.adopt(new, rt)?;
        if restart {
            self.watch.restart();
        }
        let w = self.settings.watch;
        if w.auto {
            let _ = writeln!(
                out,
                "# watch auto: drifted modes retuned between moves within the limits, next tick \
                 by superposition: no setpoint jump"
            );
        }
        let _ = write!(
            out,
            "ok watch enabled={} auto={} state={} limits_hz=",
            crate::protocol::on_off(w.enabled),
            crate::protocol::on_off(w.auto),
            self.watch.report().state.name()
        );
        let _ = match w.limits() {
            Some((lo, hi)) => writeln!(out, "{lo}:{hi}"),
            None => writeln!(out, "-"),
        };
        Ok(())
    }

    fn cmd_payload(
        &mut self,
        command: PayloadCommand,
        rt: &mut impl RuntimeAccess,
        out: &mut impl Write,
    ) -> CmdResult {
        let mut new = self.settings.clone();
        match command {
            PayloadCommand::Show => {
                let mut entries = 0;
                for (n, e) in self.settings.watch.schedule.iter().enumerate() {
                    if e.iter().all(|&f| f == 0.0) {
                        continue;
                    }
                    entries += 1;
                    let _ = write!(out, "# payload {n} f_hz=");
                    write_freqs(out, e);
                    let _ = writeln!(out);
                }
                let _ = match self.settings.watch.payload {
                    Some(p) => writeln!(out, "ok payload selected={p} entries={entries}"),
                    None => writeln!(out, "ok payload selected=- entries={entries}"),
                };
                Ok(())
            }
            PayloadCommand::Store(n) => {
                let mut entry = [0.0f32; MAX_MODES];
                for (e, m) in entry.iter_mut().zip(self.settings.modes.iter()) {
                    *e = m.map_or(0.0, |m| m.freq_hz as f32);
                }
                if entry.iter().all(|&f| f == 0.0) {
                    return Err(Refusal::new("range", "no mode set: nothing to store"));
                }
                if let Some(slot) = new.watch.schedule.get_mut(n as usize) {
                    *slot = entry;
                }
                new.watch.payload = Some(n);
                self.adopt(new, rt)?;
                let _ = write!(out, "ok payload n={n} stored f_hz=");
                write_freqs(out, &entry);
                let _ = writeln!(out);
                Ok(())
            }
            PayloadCommand::Select(n) => {
                let entry = new
                    .watch
                    .schedule
                    .get(n as usize)
                    .copied()
                    .unwrap_or_default();
                if entry.iter().all(|&f| f == 0.0) {
                    return Err(Refusal::new(
                        "range",
                        "payload entry empty (payload <n> store)",
                    ));
                }
                for (m, &f) in new.modes.iter_mut().zip(entry.iter()) {
                    if let (Some(m), true) = (m.as_mut(), f > 0.0) {
                        if m.freq_hz != f as f64 {
                            m.freq_hz = f as f64;
                            new.certificate = crate::config::Certificate::NONE;
                        }
                    }
                }
                new.watch.payload = Some(n);
                self.commit(new, rt, out, "payload")
            }
        }
    }
}

/// `f1,f2,-,-` (Hz) of a schedule entry (0 = none: `-`).
fn write_freqs(out: &mut impl Write, e: &[f32; MAX_MODES]) {
    for (i, &f) in e.iter().enumerate() {
        let sep = if i == 0 { "" } else { "," };
        let _ = if f > 0.0 {
            write!(out, "{sep}{f}")
        } else {
            write!(out, "{sep}-")
        };
    }
}

/// A runtime refusal as a console error; a step-rate refusal first names the limit.
fn runtime_err(e: crate::runtime::RuntimeError, out: &mut impl Write) -> Refusal {
    if let crate::runtime::RuntimeError::StepRate(x) = e {
        let _ = writeln!(
            out,
            "# shaped peak {} steps/s > maxrate {} steps/s; reference speed must stay <= {} mm/s",
            Num(x.shaped_peak_steps_s as f64, 0),
            x.max_step_rate_hz,
            Num(x.max_reference_speed_nm_s as f64 * 1e-6, 3),
        );
    }
    Refusal::new(e.code(), e.message())
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
        C::Version { .. } => "stored settings of another format version",
        C::Buffer => "buffer too small",
    }
}
