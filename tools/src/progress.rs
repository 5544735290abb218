//! Progress of long library steps, reported without printing.
//!
//! Library code (everything outside `cli/`) never prints, never draws a bar and never imports
//! `cli`. A long step takes a `&mut dyn Progress` and tells it what it is doing; `cli/` decides how
//! that is shown (an `indicatif` bar on a terminal, one line per stage otherwise, nothing in tests).
//!
//! Contract:
//! - [`Progress::stage`] is called once when a named stage begins ("calibrate", "fit servo_lag").
//! - [`Progress::advance`] reports `done` of `total` units of the current stage (`done ≤ total`);
//!   sinks must tolerate `total == 0` and repeated or skipped values.
//! - [`Progress::note`] carries a diagnostic sentence a user may want when something was skipped
//!   or failed inside a step that itself went on (e.g. a failed least-squares start).
//!
//! [`Silent`] ignores everything; it is what tests and library callers without a user pass.

/// Sink for progress of a long library step. See the module header for the contract.
pub trait Progress {
    /// A named stage begins.
    fn stage(&mut self, name: &str);
    /// `done` of `total` units of the current stage are finished.
    fn advance(&mut self, done: u64, total: u64) {
        let _ = (done, total);
    }
    /// A diagnostic sentence from inside a step that went on.
    fn note(&mut self, text: &str) {
        let _ = text;
    }
}

/// A [`Progress`] that shows nothing.
#[derive(Debug, Default, Clone, Copy)]
pub struct Silent;

impl Progress for Silent {
    fn stage(&mut self, _name: &str) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sink that records what it was told, to check the trait's defaults compose.
    #[derive(Default)]
    struct Log(Vec<String>);

    impl Progress for Log {
        fn stage(&mut self, name: &str) {
            self.0.push(name.to_string());
        }
    }

    #[test]
    fn defaults_ignore_advance_and_notes() {
        let mut log = Log::default();
        let p: &mut dyn Progress = &mut log;
        p.stage("calibrate");
        p.advance(1, 0);
        p.note("start 3 failed");
        p.stage("fit");
        assert_eq!(log.0, ["calibrate", "fit"]);
        let mut s = Silent;
        s.stage("x");
        s.advance(2, 1);
    }
}
