//! The drift watch's and the payload schedule's console words: `watch …` and `payload …`
//! ([`WatchCommand`], [`PayloadCommand`]) and the `ok watch …` report ([`WatchReply`]).

use super::{on_off, parse_f64, Refusal};
use crate::config::PAYLOAD_ENTRIES;
use crate::watch::{WatchReport, WatchState};
use core::fmt;

/// `watch …`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WatchCommand {
    /// `watch`: the report ([`WatchReply`]).
    Show,
    /// `watch on|off`.
    Enable(bool),
    /// `watch limits <lo_hz> <hi_hz>`: the range an automatic retune stays in (Hz).
    Limits(f32, f32),
    /// `watch auto on|off`.
    Auto(bool),
}

/// `payload …`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PayloadCommand {
    /// `payload`: the schedule.
    Show,
    /// `payload <n>`: installs entry n's frequencies (the mode slots it holds).
    Select(u8),
    /// `payload <n> store`: stores the shaper's mode frequencies as entry n.
    Store(u8),
}

const WATCH_USAGE: &str = "watch | watch on|off | watch limits <lo_hz> <hi_hz> | watch auto on|off";
const PAYLOAD_USAGE: &str = "payload | payload <0-7> | payload <0-7> store";

fn on_off_word(w: &str) -> Result<bool, Refusal> {
    match w {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(Refusal::new("syntax", WATCH_USAGE)),
    }
}

/// Parses the arguments of `watch`.
pub(crate) fn parse_watch(args: &[&str]) -> Result<WatchCommand, Refusal> {
    Ok(match args {
        [] => WatchCommand::Show,
        [w] => WatchCommand::Enable(on_off_word(w)?),
        ["auto", w] => WatchCommand::Auto(on_off_word(w)?),
        ["limits", lo, hi] => {
            let (lo, hi) = (parse_f64(lo)?, parse_f64(hi)?);
            if !(lo > 0.0 && lo < hi) {
                return Err(Refusal::new("range", "watch limits need 0 < lo_hz < hi_hz"));
            }
            WatchCommand::Limits(lo as f32, hi as f32)
        }
        _ => return Err(Refusal::new("syntax", WATCH_USAGE)),
    })
}

/// Parses the arguments of `payload`.
pub(crate) fn parse_payload(args: &[&str]) -> Result<PayloadCommand, Refusal> {
    let index = |s: &str| match s.parse::<u8>() {
        Ok(n) if (n as usize) < PAYLOAD_ENTRIES => Ok(n),
        _ => Err(Refusal::new("range", "payload index must be 0..7")),
    };
    Ok(match args {
        [] => PayloadCommand::Show,
        [n] => PayloadCommand::Select(index(n)?),
        [n, "store"] => PayloadCommand::Store(index(n)?),
        _ => return Err(Refusal::new("syntax", PAYLOAD_USAGE)),
    })
}

impl fmt::Display for WatchCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WatchCommand::Show => f.write_str("watch"),
            WatchCommand::Enable(on) => write!(f, "watch {}", on_off(*on)),
            WatchCommand::Limits(lo, hi) => write!(f, "watch limits {lo} {hi}"),
            WatchCommand::Auto(on) => write!(f, "watch auto {}", on_off(*on)),
        }
    }
}

impl fmt::Display for PayloadCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PayloadCommand::Show => f.write_str("payload"),
            PayloadCommand::Select(n) => write!(f, "payload {n}"),
            PayloadCommand::Store(n) => write!(f, "payload {n} store"),
        }
    }
}

/// `ok watch state=… f1_hz=… zeta1=… f2_hz=… zeta2=… band_lo_hz=… band_hi_hz=…
/// residual_rms_m_s2=… residual_ratio=… moves=… auto=… retunes=… shaper_f1_hz=…`: mode 1 and
/// 2 are the first two watched mode slots; `band_*` is mode 1's band; `-` = not known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchReply {
    /// State.
    pub state: WatchState,
    /// Measured natural frequency of watched mode 1 (Hz).
    pub f1_hz: Option<f64>,
    /// Its damping ratio.
    pub zeta1: Option<f64>,
    /// Measured natural frequency of watched mode 2 (Hz).
    pub f2_hz: Option<f64>,
    /// Its damping ratio.
    pub zeta2: Option<f64>,
    /// Mode 1's band, low edge (Hz).
    pub band_lo_hz: Option<f64>,
    /// Mode 1's band, high edge (Hz).
    pub band_hi_hz: Option<f64>,
    /// RMS tip acceleration about its mean after the last move (m/s²).
    pub residual_rms_m_s2: Option<f64>,
    /// That over the first moves' after `watch on`.
    pub residual_ratio: Option<f64>,
    /// Moves measured since `watch on`.
    pub moves: u32,
    /// Automatic retuning on.
    pub auto: bool,
    /// Automatic retunes since boot.
    pub retunes: u32,
    /// The installed shaper's frequency for watched mode 1 (Hz).
    pub shaper_f1_hz: Option<f64>,
}

impl WatchReply {
    /// The reply for a watch report.
    pub fn new(r: &WatchReport, auto: bool, retunes: u32) -> Self {
        let mut modes = r.modes.iter().flatten();
        let (m1, m2) = (modes.next(), modes.next());
        WatchReply {
            state: r.state,
            f1_hz: m1.and_then(|m| m.measured).map(|p| p.freq_hz),
            zeta1: m1.and_then(|m| m.measured).map(|p| p.zeta),
            f2_hz: m2.and_then(|m| m.measured).map(|p| p.freq_hz),
            zeta2: m2.and_then(|m| m.measured).map(|p| p.zeta),
            band_lo_hz: m1.map(|m| m.band_hz.0),
            band_hi_hz: m1.map(|m| m.band_hz.1),
            residual_rms_m_s2: r.residual_rms_m_s2,
            residual_ratio: r.residual_ratio,
            moves: r.moves,
            auto,
            retunes,
            shaper_f1_hz: m1.map(|m| m.shaper_freq_hz),
        }
    }

    /// Parses the `ok watch` line.
    pub fn parse(line: &str) -> Result<Self, super::ReplyError> {
        use super::{field, value, ReplyError};
        let opt = |key: &'static str| -> Result<Option<f64>, ReplyError> {
            match field(line, key) {
                Some("-") => Ok(None),
                Some(v) => v.parse().map(Some).map_err(|_| ReplyError {
                    key,
                    unreadable: true,
                }),
                None => Err(ReplyError {
                    key,
                    unreadable: false,
                }),
            }
        };
        let state = field(line, "state")
            .and_then(WatchState::from_name)
            .ok_or(ReplyError {
                key: "state",
                unreadable: true,
            })?;
        Ok(WatchReply {
            state,
            f1_hz: opt("f1_hz")?,
            zeta1: opt("zeta1")?,
            f2_hz: opt("f2_hz")?,
            zeta2: opt("zeta2")?,
            band_lo_hz: opt("band_lo_hz")?,
            band_hi_hz: opt("band_hi_hz")?,
            residual_rms_m_s2: opt("residual_rms_m_s2")?,
            residual_ratio: opt("residual_ratio")?,
            moves: value(line, "moves")?,
            auto: field(line, "auto") == Some("on"),
            retunes: value(line, "retunes")?,
            shaper_f1_hz: opt("shaper_f1_hz")?,
        })
    }
}

/// An optional number: its digits, or `-`.
struct Opt(Option<f64>, usize);

impl fmt::Display for Opt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(v) => write!(f, "{}", super::Num(v, self.1)),
            None => f.write_str("-"),
        }
    }
}

impl fmt::Display for WatchReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ok watch state={} f1_hz={} zeta1={} f2_hz={} zeta2={} band_lo_hz={} band_hi_hz={} \
             residual_rms_m_s2={} residual_ratio={} moves={} auto={} retunes={} shaper_f1_hz={}",
            self.state.name(),
            Opt(self.f1_hz, 5),
            Opt(self.zeta1, 5),
            Opt(self.f2_hz, 4),
            Opt(self.zeta2, 5),
            Opt(self.band_lo_hz, 4),
            Opt(self.band_hi_hz, 4),
            Opt(self.residual_rms_m_s2, 5),
            Opt(self.residual_ratio, 3),
            self.moves,
            on_off(self.auto),
            self.retunes,
            Opt(self.shaper_f1_hz, 5),
        )
    }
}
