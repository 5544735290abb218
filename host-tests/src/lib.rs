//! Host-side helpers shared by the tests and benchmarks of the beamshaper core.
//!
//! The reference implementations here are deliberately independent of the core's
//! optimised code paths: plain f64 arithmetic straight from the definitions.

use beamshaper::console::{Action, Console};
use beamshaper::runtime::{Runtime, TickInput};
use beamshaper::shaper::Shaper;

/// Exact f64 convolution of integer reference samples with a shaper sampled by linear
/// interpolation between ticks: `y[n] = Σ_i A_i · x((n − t_i·f_tick))`, with `x` linear
/// between samples and `x[k] = x[0]` for k < 0.
pub fn shaped_f64(shaper: &Shaper, tick_rate_hz: f64, x: &[i32]) -> Vec<f64> {
    let at = |pos: f64| -> f64 {
        if pos <= 0.0 {
            return x[0] as f64;
        }
        let k = pos.floor() as usize;
        let frac = pos - k as f64;
        let a = x[k.min(x.len() - 1)] as f64;
        let b = x[(k + 1).min(x.len() - 1)] as f64;
        a + frac * (b - a)
    };
    (0..x.len())
        .map(|n| {
            shaper
                .impulses()
                .iter()
                .map(|i| i.amplitude * at(n as f64 - i.time_s * tick_rate_hz))
                .sum()
        })
        .collect()
}

/// A console and its runtime, as the firmware glue wires them (host side).
pub struct Board {
    /// The runtime.
    pub rt: Box<Runtime>,
    /// The console.
    pub console: Console,
}

impl Default for Board {
    fn default() -> Self {
        Self::new()
    }
}

impl Board {
    /// Boots with defaults.
    pub fn new() -> Self {
        let mut rt = Box::new(Runtime::new());
        let mut boot = String::new();
        let console = Console::boot(Ok(None), &mut *rt, 0, &mut boot);
        assert!(boot.contains("no saved settings, using defaults"), "{boot}");
        Board { rt, console }
    }

    /// Sends one line; the reply and the action.
    pub fn cmd(&mut self, line: &str) -> (String, Action) {
        let mut out = String::new();
        let a = self
            .console
            .handle_line(line.as_bytes(), &mut *self.rt, &mut out);
        (out, a)
    }

    /// Sends a line that must answer `ok`.
    pub fn ok(&mut self, line: &str) -> String {
        let (out, _) = self.cmd(line);
        let last = out.lines().last().unwrap_or("");
        assert!(last.starts_with("ok "), "`{line}` -> {out}");
        out
    }

    /// Sends a line that must answer `err <code>` and change nothing.
    pub fn err(&mut self, line: &str, code: &str) {
        let before = (
            self.console.settings().clone(),
            self.rt.pending().cloned(),
            self.rt.status(),
        );
        let (out, a) = self.cmd(line);
        let last = out.lines().last().unwrap_or("");
        assert!(
            last.starts_with(&format!("err {code}:")),
            "`{line}` -> {out}"
        );
        assert_eq!(a, Action::None);
        let after = (
            self.console.settings().clone(),
            self.rt.pending().cloned(),
            self.rt.status(),
        );
        assert_eq!(before, after, "state changed on err for `{line}`");
    }

    /// Runs `ticks` ticks.
    pub fn run(&mut self, ticks: usize) {
        for _ in 0..ticks {
            self.rt.tick(&TickInput::default());
        }
    }
}
