//! Serial-console client for the board (real or virtual), on the `serialport` crate.
//!
//! Speaks the console protocol of [`beamshaper::protocol`]: one command line out, reply lines
//! back (classified by [`ReplyLine`]) until a final `ok …` or `err <code>: …` line. Every
//! failure is a [`ClientError`].

use beamshaper::protocol::ReplyLine;
use serialport::SerialPort;
use std::io::{Read, Write};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why a console exchange failed.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The port cannot be opened.
    #[error("cannot open serial port {port}")]
    Open {
        /// The port's path.
        port: String,
        /// Why.
        #[source]
        source: serialport::Error,
    },
    /// Writing the command failed.
    #[error("serial write")]
    Write(#[source] std::io::Error),
    /// No complete reply came back.
    #[error("waiting for the reply to `{command}`")]
    NoReply {
        /// The command sent.
        command: String,
        /// Why.
        #[source]
        source: LineError,
    },
    /// The board answered `err <code>: <message>`.
    #[error("board refused `{command}`: {reply}")]
    Refused {
        /// The command sent.
        command: String,
        /// The reply without `err `.
        reply: String,
    },
    /// The board printed its boot banner (`# boot: …` then `ok boot`) in the middle of a
    /// session: it restarted, so what it runs may no longer be what the host set.
    #[error("the board restarted while answering `{command}` ({notes})")]
    Restarted {
        /// The command sent.
        command: String,
        /// The boot banner's notes, joined.
        notes: String,
    },
    /// A reply line is neither `# …`, `ok …` nor `err …`.
    #[error("malformed reply to `{command}`: `{line}` (expected `# …`, `ok …` or `err …`)")]
    Malformed {
        /// The command sent.
        command: String,
        /// The line received.
        line: String,
    },
}

/// Why a reply line could not be read.
#[derive(Debug, Error)]
pub enum LineError {
    /// The bytes are not UTF-8.
    #[error("board sent non-UTF-8 bytes")]
    NotUtf8,
    /// Nothing complete within the timeout.
    #[error("board stopped answering (no complete reply within {0:?})")]
    Silent(Duration),
    /// The port failed.
    #[error("serial read")]
    Read(#[source] std::io::Error),
}

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
    /// A reply has been read since the port was opened (a boot banner before the first
    /// reply is the board starting late; after it, the board restarted).
    answered: bool,
    /// The notes of the last boot banner read (`# boot: …` lines, without `# `).
    boot_notes: Vec<String>,
}

impl BoardClient {
    /// Opens `path` at 115200 8N1 and drains any boot messages.
    pub fn open(path: &str) -> Result<Self, ClientError> {
        let port = serialport::new(path, 115_200)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|source| ClientError::Open {
                port: path.to_string(),
                source,
            })?;
        let mut c = BoardClient {
            port,
            pending: Vec::new(),
            timeout: Duration::from_secs(3),
            answered: false,
            boot_notes: Vec::new(),
        };
        c.drain(Duration::from_millis(100));
        Ok(c)
    }

    /// The notes of the boot banner read after the port was opened (empty if the banner came
    /// before the opening drain, or not at all).
    pub fn boot_notes(&self) -> &[String] {
        &self.boot_notes
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

    fn read_line(&mut self, deadline: Instant) -> Result<String, LineError> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=i).collect();
                let s = String::from_utf8(line).map_err(|_| LineError::NotUtf8)?;
                return Ok(s.trim_end_matches(['\r', '\n']).to_string());
            }
            if Instant::now() > deadline {
                return Err(LineError::Silent(self.timeout));
            }
            match self.port.read(&mut buf) {
                Ok(n) => self.pending.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(LineError::Read(e)),
            }
        }
    }

    /// Sends one command line and waits for its reply. A boot banner (`# boot: …`, `ok boot`)
    /// read before the first reply is the board starting later than the opening drain waited:
    /// it is set aside ([`Self::boot_notes`]) and the reply read after it. Errors: an `err`
    /// reply (code and message in the error), a malformed reply line, a boot banner after the
    /// first reply (the board restarted), or no reply within the timeout.
    pub fn command(&mut self, line: &str) -> Result<Reply, ClientError> {
        self.port
            .write_all(format!("{line}\n").as_bytes())
            .map_err(ClientError::Write)?;
        self.port.flush().ok();
        let deadline = Instant::now() + self.timeout;
        let mut info = Vec::new();
        loop {
            let l = self
                .read_line(deadline)
                .map_err(|source| ClientError::NoReply {
                    command: line.to_string(),
                    source,
                })?;
            match ReplyLine::parse(&l) {
                ReplyLine::Info(text) => info.push(text.to_string()),
                ReplyLine::Ok("ok boot") if !line.starts_with("boot") => {
                    if self.answered {
                        return Err(ClientError::Restarted {
                            command: line.to_string(),
                            notes: info.join("; "),
                        });
                    }
                    self.boot_notes = std::mem::take(&mut info);
                }
                ReplyLine::Ok(_) => {
                    self.answered = true;
                    return Ok(Reply { info, ok: l });
                }
                ReplyLine::Err(..) => {
                    return Err(ClientError::Refused {
                        command: line.to_string(),
                        reply: l.strip_prefix("err ").unwrap_or(&l).to_string(),
                    });
                }
                ReplyLine::Other("") => continue,
                ReplyLine::Other(_) => {
                    return Err(ClientError::Malformed {
                        command: line.to_string(),
                        line: l,
                    })
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A board on a PTY that answers each command line with `# info` and `ok <command>`, and
    /// prints its boot banner just before reply number `banner_before_reply` (0: the board
    /// started after the opening drain; 1 or more: it restarted between replies). The banner
    /// is tied to a command, not to a clock, so a loaded machine cannot move it into the
    /// opening drain (CI once saw the 400 ms timed banner arrive during the drain).
    fn late_board(banner_before_reply: usize) -> String {
        let (mut master, slave) = serialport::TTYPort::pair().unwrap();
        let path = slave.name().unwrap();
        std::thread::spawn(move || {
            let _keep = slave;
            let banner = b"# boot: no saved settings, using defaults\nok boot\n";
            master.set_timeout(Duration::from_millis(5)).unwrap();
            let (mut got, mut buf, mut replies) = (Vec::new(), [0u8; 64], 0);
            loop {
                match master.read(&mut buf) {
                    Ok(n) => got.extend_from_slice(&buf[..n]),
                    Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                    Err(_) => return,
                }
                while let Some(i) = got.iter().position(|&b| b == b'\n') {
                    let cmd: Vec<u8> = got.drain(..=i).collect();
                    let cmd = String::from_utf8_lossy(&cmd).trim().to_string();
                    if replies == banner_before_reply {
                        master.write_all(banner).unwrap();
                    }
                    replies += 1;
                    master
                        .write_all(format!("# info\nok {cmd}\n").as_bytes())
                        .unwrap();
                }
            }
        });
        path
    }

    /// A banner that comes after the opening drain is set aside, and the first command gets
    /// its own reply (CI once saw `# boot: …` parsed as a `config` mode line).
    #[test]
    fn a_late_boot_banner_is_not_taken_for_the_first_reply() {
        let mut c = BoardClient::open(&late_board(0)).unwrap();
        c.set_timeout(Duration::from_secs(30));
        let r = c.command("config").unwrap();
        assert_eq!(r.ok, "ok config");
        assert_eq!(r.info, vec!["info".to_string()]);
        assert_eq!(c.boot_notes(), ["boot: no saved settings, using defaults"]);
        assert_eq!(c.command("status").unwrap().ok, "ok status");
    }

    /// A banner between replies means the board restarted: an error that says so.
    #[test]
    fn a_boot_banner_after_a_reply_is_a_restart_error() {
        let mut c = BoardClient::open(&late_board(1)).unwrap();
        c.set_timeout(Duration::from_secs(30));
        assert_eq!(c.command("status").unwrap().ok, "ok status");
        let e = c.command("config").unwrap_err();
        assert!(matches!(e, ClientError::Restarted { .. }), "{e}");
        assert!(e.to_string().contains("restarted"), "{e}");
    }
}
