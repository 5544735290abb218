//! Serial-console client for the board (real or virtual), on the `serialport` crate.
//!
//! Speaks the console protocol of [`beamshaper::protocol`]: one command line out, reply lines
//! back (classified by [`ReplyLine`]) until a final `ok …` or `err <code>: …` line.

use anyhow::{anyhow, bail, Context, Result};
use beamshaper::protocol::ReplyLine;
use serialport::SerialPort;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// A reply: the informational `# ` lines and the final `ok …` line (read its fields with the
/// core's reply types, [`beamshaper::protocol`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Reply {
    /// Informational lines (without the `# `).
    pub info: Vec<String>,
    /// The final line, starting with `ok `.
    pub ok: String,
}

/// A console connection.
pub struct BoardClient {
    port: Box<dyn SerialPort>,
    pending: Vec<u8>,
    timeout: Duration,
}

impl BoardClient {
    /// Opens `path` at 115200 8N1 and drains any boot messages.
    pub fn open(path: &str) -> Result<Self> {
        let port = serialport::new(path, 115_200)
            .timeout(Duration::from_millis(20))
            .open()
            .with_context(|| format!("cannot open serial port {path}"))?;
        let mut c = BoardClient {
            port,
            pending: Vec::new(),
            timeout: Duration::from_secs(3),
        };
        c.drain(Duration::from_millis(100));
        Ok(c)
    }

    /// Sets how long to wait for a reply before declaring the board silent.
    pub fn set_timeout(&mut self, t: Duration) {
        self.timeout = t;
    }

    fn drain(&mut self, for_: Duration) {
        let end = Instant::now() + for_;
        let mut buf = [0u8; 256];
        while Instant::now() < end {
            if let Ok(n) = self.port.read(&mut buf) {
                if n == 0 {
                    break;
                }
            }
        }
        self.pending.clear();
    }

    fn read_line(&mut self, deadline: Instant) -> Result<String> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=i).collect();
                let s =
                    String::from_utf8(line).map_err(|_| anyhow!("board sent non-UTF-8 bytes"))?;
                return Ok(s.trim_end_matches(['\r', '\n']).to_string());
            }
            if Instant::now() > deadline {
                bail!(
                    "board stopped answering (no complete reply within {:?})",
                    self.timeout
                );
            }
            match self.port.read(&mut buf) {
                Ok(n) => self.pending.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(e).context("serial read"),
            }
        }
    }

    /// Sends one command line and waits for its reply. Errors: an `err` reply (code and
    /// message in the error), a malformed reply line, or no reply within the timeout.
    pub fn command(&mut self, line: &str) -> Result<Reply> {
        self.port
            .write_all(format!("{line}\n").as_bytes())
            .context("serial write")?;
        self.port.flush().ok();
        let deadline = Instant::now() + self.timeout;
        let mut info = Vec::new();
        loop {
            let l = self
                .read_line(deadline)
                .with_context(|| format!("waiting for the reply to `{line}`"))?;
            match ReplyLine::parse(&l) {
                ReplyLine::Info(text) => info.push(text.to_string()),
                ReplyLine::Ok(_) => return Ok(Reply { info, ok: l }),
                ReplyLine::Err(..) => {
                    let e = l.strip_prefix("err ").unwrap_or(&l);
                    bail!("board refused `{line}`: {e}");
                }
                ReplyLine::Other("") => continue,
                ReplyLine::Other(_) => {
                    bail!("malformed reply to `{line}`: `{l}` (expected `# …`, `ok …` or `err …`)")
                }
            }
        }
    }
}
