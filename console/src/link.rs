//! The serial link to the board: a real serial port (the board's USB-UART, or the simulated
//! board's pseudo-terminal: the same code path), lines in and out, every line logged.
//!
//! A reader thread splits the received bytes into lines and hands them over a channel; the
//! guide sends one command at a time and collects its reply (data lines, then one `ok …` or
//! `err <code>: …` line, as `docs/protocol.md` promises). `event …` and `stream …` lines that
//! arrive meanwhile are kept for the guide in order. A closed port or a read error is a
//! disconnect, reported as [`LinkError::Disconnected`].

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use odocal::protocol::record::parse_version;
use odocal::protocol::reply::{self, FinalLine};
use odocal::protocol::token::{self, EventTag};
use odocal::protocol::{Command, ErrorCode};

use crate::log::SessionLog;

/// Baud rate of the board's console (USART2, 115200 8N1).
pub const BAUD: u32 = 115_200;

/// Why a command got no reply.
#[derive(Debug)]
pub enum LinkError {
    /// The port closed or failed (cable pulled, board powered off, simulator ended).
    Disconnected(String),
    /// No final line within the time limit.
    Timeout(String),
    /// The operator pressed Ctrl-C.
    Interrupted,
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkError::Disconnected(why) => write!(f, "lost the connection to the board ({why})"),
            LinkError::Timeout(cmd) => write!(f, "no reply from the board to `{cmd}`"),
            LinkError::Interrupted => f.write_str("interrupted (Ctrl-C)"),
        }
    }
}

/// A command's reply.
#[derive(Clone, Debug, Default)]
pub struct Reply {
    /// Data lines before the final line, with their leading two spaces removed.
    pub data: Vec<String>,
    /// The final line (`ok …` or `err <code>: …`).
    pub last: String,
}

impl Reply {
    /// The final line as the protocol reads it (`None` never happens for a reply [`Link`] made).
    pub fn last(&self) -> Option<FinalLine<'_>> {
        FinalLine::parse(&self.last)
    }
    /// Whether the final line is `ok …`.
    pub fn ok(&self) -> bool {
        self.last().is_some_and(FinalLine::is_ok)
    }
    /// Whether the final line is the error `code`.
    pub fn is_err(&self, code: ErrorCode) -> bool {
        self.last().is_some_and(|l| l.is_err(code))
    }
    /// The text after `ok ` (empty for a bare `ok`), or the message after `err <code>: `.
    pub fn text(&self) -> &str {
        self.last().map_or("", FinalLine::text)
    }
}

enum Incoming {
    Line(String),
    Closed(String),
}

/// An open link to a board.
pub struct Link {
    port: Box<dyn serialport::SerialPort>,
    rx: Receiver<Incoming>,
    /// `event …` and `stream …` lines not yet taken by the guide.
    pending: VecDeque<String>,
    /// Session log: every line both ways.
    pub log: SessionLog,
    /// Port path, for messages.
    pub path: String,
    closed: Option<String>,
}

/// Candidate serial ports (USB-UART adapters, ST-LINK virtual COM ports), for the operator to
/// choose from when no `--port` is given.
pub fn candidate_ports() -> Vec<String> {
    let mut ports: Vec<String> = serialport::available_ports()
        .map(|p| p.into_iter().map(|p| p.port_name).collect())
        .unwrap_or_default();
    ports.retain(|p| p.contains("USB") || p.contains("ACM") || p.contains("usbserial"));
    ports.sort();
    ports
}

/// Whether `path` is a pseudo-terminal's slave (`/dev/pts/N`, links followed).
pub fn is_pty(path: &str) -> bool {
    std::fs::canonicalize(path).is_ok_and(|p| p.starts_with("/dev/pts"))
}

/// The other processes that have the serial device `path` open, as `name (pid N)`, from
/// `/proc/<pid>/fd` (Linux; elsewhere, or for processes this user may not inspect, none are
/// found and the port's own lock is the only guard). For a pseudo-terminal `/dev/pts/<n>`, the
/// process that holds its master side (`/dev/ptmx` with `tty-index: <n>`: the simulated board)
/// is its other end, not a competitor, and is not counted.
pub fn port_holders(path: &str) -> Vec<String> {
    let Ok(device) = std::fs::canonicalize(path) else {
        return Vec::new();
    };
    let pty_index = device
        .strip_prefix("/dev/pts")
        .ok()
        .and_then(|n| n.to_str())
        .map(|n| format!("tty-index:\t{n}"));
    let me = std::process::id().to_string();
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut found = Vec::new();
    for entry in procs.flatten() {
        let pid = entry.file_name().to_string_lossy().into_owned();
        if pid == me || !pid.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let Ok(fds) = std::fs::read_dir(entry.path().join("fd")) else {
            continue;
        };
        let (mut holds, mut master) = (false, false);
        for fd in fds.flatten() {
            let Ok(target) = std::fs::read_link(fd.path()) else {
                continue;
            };
            holds |= target == device;
            if let Some(index) = &pty_index
                && target.ends_with("ptmx")
            {
                let info = entry.path().join("fdinfo").join(fd.file_name());
                master |= std::fs::read_to_string(info)
                    .is_ok_and(|text| text.lines().any(|l| l == index));
            }
        }
        if holds && !master {
            let name = std::fs::read_to_string(entry.path().join("comm")).unwrap_or_default();
            found.push(format!("{} (pid {pid})", name.trim()));
        }
    }
    found.sort();
    found
}

impl Link {
    /// Opens `path` at 115200 8N1 and starts the reader.
    ///
    /// # Errors
    /// The port cannot be opened, as text.
    pub fn open(path: &str, log: SessionLog) -> Result<Link, String> {
        // A terminal program on the same port would take part of every reply: refused, whether
        // or not it locked the port (screen does not; root opens a locked port anyway).
        let holders = port_holders(path);
        if !holders.is_empty() {
            return Err(format!(
                "cannot open {path}: {} has it open: quit it first (two programs on one port \
                 each get part of the board's replies)",
                holders.join(", ")
            ));
        }
        let mut port = serialport::new(path, BAUD)
            .timeout(Duration::from_millis(100))
            .open_native()
            .map_err(|e| {
                // serialport locks the port (TIOCEXCL); so does picocom.
                let text = e.to_string();
                let busy = if text.contains("exclusive lock") || text.contains("resource busy") {
                    " (another program has it open: quit picocom, screen or another console first)"
                } else {
                    ""
                };
                format!("cannot open {path}: {e}{busy}")
            })?;
        // A pseudo-terminal (the simulated board) lives as long as its master, and so would the
        // kernel's exclusive flag of a console that was killed: every later open by a user who
        // is not root would fail. There the holder check above is the lock; a real port's flag
        // ends with its last close.
        if is_pty(path) {
            port.set_exclusive(false)
                .map_err(|e| format!("cannot open {path}: {e}"))?;
        }
        let port: Box<dyn serialport::SerialPort> = Box::new(port);
        let mut reader = port
            .try_clone()
            .map_err(|e| format!("cannot read {path}: {e}"))?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            let mut line = Vec::new();
            loop {
                match reader.read(&mut buf) {
                    Ok(0) => {
                        let _ = tx.send(Incoming::Closed("end of file".into()));
                        return;
                    }
                    Ok(n) => {
                        for &b in &buf[..n] {
                            if b == b'\n' || b == b'\r' {
                                if !line.is_empty() {
                                    let text = String::from_utf8_lossy(&line).into_owned();
                                    line.clear();
                                    if tx.send(Incoming::Line(text)).is_err() {
                                        return;
                                    }
                                }
                            } else {
                                line.push(b);
                            }
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        let _ = tx.send(Incoming::Closed(e.to_string()));
                        return;
                    }
                }
            }
        });
        Ok(Link {
            port,
            rx,
            pending: VecDeque::new(),
            log,
            path: path.to_string(),
            closed: None,
        })
    }

    fn write_raw(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.port
            .write_all(bytes)
            .and_then(|()| self.port.flush())
            .map_err(|e| LinkError::Disconnected(e.to_string()))
    }

    /// Sends Ctrl-C: the board stops any motion at once, before any queued line.
    ///
    /// # Errors
    /// A disconnect.
    pub fn stop_key(&mut self) -> Result<(), LinkError> {
        self.log.tx("^C");
        self.write_raw(&[0x03])
    }

    /// Sends one command line without waiting for its reply (the reply, when it comes, is
    /// dropped like any other stray line).
    ///
    /// # Errors
    /// A disconnect.
    pub fn send_line(&mut self, line: &str) -> Result<(), LinkError> {
        self.log.tx(line);
        self.write_raw(format!("{line}\r\n").as_bytes())
    }

    /// Receives one line within `timeout` (`None` if none came), logged.
    fn recv(&mut self, timeout: Duration) -> Result<Option<String>, LinkError> {
        if let Some(why) = &self.closed {
            return Err(LinkError::Disconnected(why.clone()));
        }
        match self.rx.recv_timeout(timeout) {
            Ok(Incoming::Line(l)) => {
                self.log.rx(&l);
                Ok(Some(l))
            }
            Ok(Incoming::Closed(why)) => {
                self.closed = Some(why.clone());
                Err(LinkError::Disconnected(why))
            }
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                let why = "reader ended".to_string();
                self.closed = Some(why.clone());
                Err(LinkError::Disconnected(why))
            }
        }
    }

    /// Sends one command line and waits up to `timeout` for its final line. Unsolicited
    /// lines are kept for [`Link::next_unsolicited`]; anything else that is not a data line (an
    /// echo) is ignored. Ctrl-C pressed meanwhile ends the wait with [`LinkError::Interrupted`].
    ///
    /// # Errors
    /// [`LinkError`].
    pub fn command(&mut self, line: &str, timeout: Duration) -> Result<Reply, LinkError> {
        self.log.tx(line);
        self.write_raw(format!("{line}\r\n").as_bytes())?;
        let deadline = Instant::now() + timeout;
        let mut reply = Reply::default();
        loop {
            if crate::interrupted() {
                return Err(LinkError::Interrupted);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout(line.to_string()));
            }
            let Some(l) = self.recv(left.min(Duration::from_millis(100)))? else {
                continue;
            };
            if FinalLine::parse(&l).is_some() {
                reply.last = l;
                return Ok(reply);
            }
            if l.starts_with(token::EVENT) || l.starts_with(token::STREAM) {
                self.pending.push_back(l);
            } else if let Some(data) = reply::data(&l) {
                reply.data.push(data.to_string());
            }
        }
    }

    /// The next `event …` or `stream …` line, waiting up to `timeout`; other lines (stray
    /// echo, a late reply) are dropped.
    ///
    /// # Errors
    /// A disconnect.
    pub fn next_unsolicited(&mut self, timeout: Duration) -> Result<Option<String>, LinkError> {
        if let Some(l) = self.pending.pop_front() {
            return Ok(Some(l));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.recv(left)? {
                Some(l) if l.starts_with(token::EVENT) || l.starts_with(token::STREAM) => {
                    return Ok(Some(l));
                }
                Some(_) => {}
                None => return Ok(None),
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    /// Takes the first unsolicited line received so far (while waiting for replies) that
    /// `wanted` accepts, if any; the others stay queued.
    pub fn take_pending(&mut self, wanted: impl Fn(&str) -> bool) -> Option<String> {
        let i = self.pending.iter().position(|l| wanted(l))?;
        self.pending.remove(i)
    }

    /// Drops unsolicited lines received so far (stream lines of an earlier run); returns the
    /// last boot line among them (`event boot: …`: the board was reset meanwhile).
    pub fn drain(&mut self) -> Result<Option<String>, LinkError> {
        let mut boot = None;
        let mut keep = |l: String| {
            if matches!(EventTag::parse(&l), Some((EventTag::Boot, _))) {
                boot = Some(l);
            }
        };
        self.pending.drain(..).for_each(&mut keep);
        while let Some(l) = self.recv(Duration::from_millis(0))? {
            keep(l);
        }
        Ok(boot)
    }

    /// Ends a half-typed line, turns the echo off and checks what answers: an odocal board of a
    /// known protocol version. Returns the `version` reply text.
    ///
    /// # Errors
    /// No reply, another device, or an unknown protocol version, as text.
    pub fn handshake(&mut self) -> Result<String, String> {
        self.write_raw(b"\r").map_err(|e| e.to_string())?;
        // Whatever the board sent before (a boot line, replies to another program, an error for
        // a half-typed line) is not a reply to this tool.
        let quiet = Instant::now() + Duration::from_millis(300);
        while Instant::now() < quiet {
            self.recv(Duration::from_millis(50))
                .map_err(|e| e.to_string())?;
        }
        self.pending.clear();
        let wait = Duration::from_secs(5);
        let echo = self
            .command(&Command::Echo { on: false }.to_string(), wait)
            .map_err(|e| format!("{e}: is this an odocal board at 115200 8N1?"))?;
        if !echo.ok() {
            return Err(format!("unexpected reply to `echo off`: {}", echo.last));
        }
        let v = self
            .command(&Command::Version.to_string(), wait)
            .map_err(|e| e.to_string())?;
        let text = v.text().to_string();
        let Some(version) = v.ok().then(|| parse_version(&text)).flatten() else {
            return Err(format!(
                "the device on {} is not an odocal board this tool knows (`version`: {}); \
                 update its firmware",
                self.path, v.last
            ));
        };
        let protocol = version.protocol;
        if protocol != Some(odocal::protocol::record::PROTOCOL_VERSION) {
            return Err(format!(
                "the board speaks protocol {} but this tool speaks {}: update the firmware or \
                 the tool",
                protocol.map_or("?".into(), |p| p.to_string()),
                odocal::protocol::record::PROTOCOL_VERSION
            ));
        }
        Ok(text)
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::port_holders;

    #[test]
    fn another_process_holding_the_port_is_named() {
        let dir = std::env::temp_dir().join(format!("odocal-holders-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let device = dir.join("ttyFAKE");
        std::fs::write(&device, b"").unwrap();
        let path = device.to_str().unwrap();
        assert!(port_holders(path).is_empty(), "nobody holds it yet");
        let mut child = std::process::Command::new("sleep")
            .arg("30")
            .stdin(std::fs::File::open(&device).unwrap())
            .spawn()
            .unwrap();
        // Also through a symbolic link to it (as /dev/serial/by-id/… names an adapter).
        let link = dir.join("by-id");
        std::os::unix::fs::symlink(&device, &link).unwrap();
        let holders = port_holders(path);
        let via_link = port_holders(link.to_str().unwrap());
        let _ = child.kill();
        let _ = child.wait();
        let expected = [format!("sleep (pid {})", child.id())];
        assert_eq!(holders, expected);
        assert_eq!(via_link, expected);
        assert!(port_holders(path).is_empty(), "the holder has quit");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
