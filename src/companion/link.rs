//! A planner's process and its socket: savsim listens on 127.0.0.1 (a port of the system's
//! choosing), starts the planner's command with the address in `SAVSIM_COMPANION`, waits for
//! it to connect, and then asks it frame by frame, waiting for each answer at most a deadline.
//! Whatever the planner does (exits, hangs, answers garbage, floods), savsim gets an error
//! naming it, and the planner's process is ended with the link.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::protocol::{self, Command, ReplyError};

/// Why the planner could not be asked.
#[derive(Debug, thiserror::Error)]
pub enum CompanionError {
    /// Its command could not be started.
    #[error("companion {command:?}: could not start: {why}")]
    Start {
        /// The command.
        command: String,
        /// Why.
        why: String,
    },
    /// It never connected.
    #[error(
        "companion {command:?}: did not connect to SAVSIM_COMPANION within {waited_s:.0} s{log}"
    )]
    NoConnect {
        /// The command.
        command: String,
        /// Wall seconds waited.
        waited_s: f64,
        /// Its last lines.
        log: String,
    },
    /// A signal stopped the run while savsim waited for it to connect.
    #[error("companion {command:?}: stopped while waiting for it to connect")]
    Stopped {
        /// The command.
        command: String,
    },
    /// It exited or closed the link.
    #[error("companion {command:?}: closed the link ({why}){log}")]
    Closed {
        /// The command.
        command: String,
        /// What was seen.
        why: String,
        /// Its last lines.
        log: String,
    },
    /// It did not answer in time.
    #[error("companion {command:?}: no answer to frame {seq} within {waited_s:.1} s of wall time")]
    Timeout {
        /// The command.
        command: String,
        /// The frame asked.
        seq: u64,
        /// Wall seconds waited.
        waited_s: f64,
    },
    /// It answered what the protocol does not allow.
    #[error("companion {command:?}: frame {seq}: {why}")]
    Reply {
        /// The command.
        command: String,
        /// The frame asked.
        seq: u64,
        /// What is wrong.
        why: ReplyError,
    },
}

/// A planner, connected.
pub struct Link {
    command: String,
    child: Child,
    stream: TcpStream,
    log: std::path::PathBuf,
    timeout: Duration,
    buffer: Vec<u8>,
}

impl std::fmt::Debug for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Link")
            .field("command", &self.command)
            .finish()
    }
}

/// How long a planner has to connect, wall time.
pub const CONNECT_WITHIN: Duration = Duration::from_secs(30);

impl Link {
    /// Start `command` (through `sh -c`, from savsim's working folder, its output to
    /// `dir/companion.log`) and wait for it to connect; each answer is then awaited at most
    /// `timeout`. A planner that exits or does not connect within [`CONNECT_WITHIN`] is ended
    /// and its error says so; so is one still connecting when `stop` is raised (a signal).
    pub fn start(
        command: &str,
        dir: &Path,
        timeout: Duration,
        stop: &AtomicBool,
    ) -> Result<Link, CompanionError> {
        let start_err = |why: String| CompanionError::Start {
            command: command.to_string(),
            why,
        };
        let listener = TcpListener::bind("127.0.0.1:0").map_err(|e| start_err(e.to_string()))?;
        let address = listener
            .local_addr()
            .map_err(|e| start_err(e.to_string()))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| start_err(e.to_string()))?;
        let log = dir.join("companion.log");
        let out = std::fs::File::create(&log)
            .map_err(|e| start_err(format!("{}: {e}", log.display())))?;
        let err = out.try_clone().map_err(|e| start_err(e.to_string()))?;
        let mut child = Process::new("sh")
            .arg("-c")
            .arg(command)
            .env("SAVSIM_COMPANION", address.to_string())
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .map_err(|e| start_err(e.to_string()))?;
        let began = Instant::now();
        let end = |child: &mut Child| {
            let _ = child.kill();
            let _ = child.wait();
        };
        let failed = |child: &mut Child, why: Option<String>| {
            let tail = log_tail(&log);
            end(child);
            match why {
                Some(why) => CompanionError::Closed {
                    command: command.to_string(),
                    why,
                    log: tail,
                },
                None => CompanionError::NoConnect {
                    command: command.to_string(),
                    waited_s: began.elapsed().as_secs_f64(),
                    log: tail,
                },
            }
        };
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nodelay(true).ok();
                    if let Err(e) = stream.set_nonblocking(false) {
                        return Err(failed(&mut child, Some(e.to_string())));
                    }
                    return Ok(Link {
                        command: command.to_string(),
                        child,
                        stream,
                        log,
                        timeout,
                        buffer: Vec::new(),
                    });
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if let Ok(Some(status)) = child.try_wait() {
                        return Err(failed(&mut child, Some(format!("it exited: {status}"))));
                    }
                    if began.elapsed() > CONNECT_WITHIN {
                        return Err(failed(&mut child, None));
                    }
                    if stop.load(Ordering::Relaxed) {
                        end(&mut child);
                        return Err(CompanionError::Stopped {
                            command: command.to_string(),
                        });
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => return Err(failed(&mut child, Some(e.to_string()))),
            }
        }
    }

    /// Its command.
    pub fn command(&self) -> &str {
        &self.command
    }

    /// A second handle on its socket: shutting it down wakes whoever waits on the link.
    pub fn stopper(&self) -> Option<TcpStream> {
        self.stream.try_clone().ok()
    }

    /// Send a message that asks no answer (`hello`).
    pub fn tell(&mut self, message: &[u8]) -> Result<(), CompanionError> {
        self.stream
            .write_all(message)
            .map_err(|e| self.closed(e.to_string()))
    }

    /// Send frame `seq` and wait for its commands.
    pub fn ask(&mut self, seq: u64, message: &[u8]) -> Result<Vec<Command>, CompanionError> {
        self.tell(message)?;
        let deadline = Instant::now() + self.timeout;
        let mut length = [0u8; 4];
        self.read_exact(&mut length, seq, deadline)?;
        let header_len = u32::from_le_bytes(length) as usize;
        if header_len > protocol::MAX_REPLY_HEADER {
            return Err(self.bad(
                seq,
                ReplyError::TooMuch(format!(
                    "a header of {header_len} bytes: at most {}",
                    protocol::MAX_REPLY_HEADER
                )),
            ));
        }
        let mut buffer = std::mem::take(&mut self.buffer);
        buffer.resize(header_len, 0);
        self.read_exact(&mut buffer, seq, deadline)?;
        let payload_len = protocol::reply_payload_len(&buffer).map_err(|e| self.bad(seq, e))?;
        let mut payload = vec![0u8; payload_len];
        self.read_exact(&mut payload, seq, deadline)?;
        let commands = protocol::commands(&buffer, &payload, seq).map_err(|e| self.bad(seq, e));
        self.buffer = buffer;
        commands
    }

    fn read_exact(
        &mut self,
        out: &mut [u8],
        seq: u64,
        deadline: Instant,
    ) -> Result<(), CompanionError> {
        let mut at = 0;
        while at < out.len() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(CompanionError::Timeout {
                    command: self.command.clone(),
                    seq,
                    waited_s: self.timeout.as_secs_f64(),
                });
            }
            self.stream.set_read_timeout(Some(left)).ok();
            match self.stream.read(&mut out[at..]) {
                Ok(0) => return Err(self.closed("end of stream".into())),
                Ok(n) => at += n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.closed(e.to_string())),
            }
        }
        Ok(())
    }

    fn bad(&self, seq: u64, why: ReplyError) -> CompanionError {
        CompanionError::Reply {
            command: self.command.clone(),
            seq,
            why,
        }
    }

    fn closed(&mut self, why: String) -> CompanionError {
        // Give an exiting planner a moment to say why.
        std::thread::sleep(Duration::from_millis(50));
        let why = match self.child.try_wait() {
            Ok(Some(status)) => format!("it exited: {status}"),
            _ => why,
        };
        CompanionError::Closed {
            command: self.command.clone(),
            why,
            log: log_tail(&self.log),
        }
    }
}

/// The last lines a planner wrote (its log's last 4 KiB), for an error.
fn log_tail(log: &Path) -> String {
    let text = crate::files::read(log, u64::MAX)
        .map(|b| String::from_utf8_lossy(&b[b.len().saturating_sub(4096)..]).into_owned())
        .unwrap_or_default();
    let lines: Vec<&str> = text.lines().rev().take(5).collect();
    if lines.is_empty() {
        return String::new();
    }
    let lines: Vec<&str> = lines.into_iter().rev().collect();
    format!("; it said: {}", lines.join(" | "))
}

impl Drop for Link {
    fn drop(&mut self) {
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
        // A planner that does not leave when its link closes is ended.
        let began = Instant::now();
        while began.elapsed() < Duration::from_millis(500) {
            if matches!(self.child.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
