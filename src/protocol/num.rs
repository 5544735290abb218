//! The console's number format: at most a given number of decimals, trailing zeros removed.
//! Its own module because the settings' error messages print numbers too (`config` uses it,
//! and the protocol uses `config`).

use core::fmt;

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
