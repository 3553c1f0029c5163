//! The byte pipe under the host's link client (a serial port, or the in-memory test link)
//! and the errors the link reports. Transports carry bytes and keep time; frames,
//! sequence numbers and retries are the client's.

use dollop::wire::{JobFailure, Refusal};
use std::time::Duration;

/// Why a link operation failed. Each message says what to do.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The connection went away (cable, board reset); the client reconnects.
    #[error("the connection to the board was lost")]
    Disconnected,
    /// No valid answer after all tries.
    #[error("the board did not answer after {tries} tries; is it powered, and is this its port?")]
    NoAnswer {
        /// Attempts made.
        tries: u32,
    },
    /// The upload made no progress for too long.
    #[error("the upload made no progress for {secs:.0} s; check the cable and run `dollop send` again (it continues where it stopped)")]
    Stalled {
        /// Seconds without progress.
        secs: f64,
    },
    /// Protocol versions differ.
    #[error("the board speaks link protocol version {device} but this dollop speaks version {host}; flash matching firmware or install the matching dollop")]
    Version {
        /// The board's.
        device: u16,
        /// Ours.
        host: u16,
    },
    /// The board has no session for us (it restarted); the client says hello again.
    #[error("the board forgot the session (it restarted?)")]
    NoSession,
    /// The board refused a request.
    #[error("{0}")]
    Refused(Refusal),
    /// The stored job failed its check on the board.
    #[error("the board rejected the uploaded job: {0}; upload it again")]
    JobFailed(JobFailure),
    /// The board lost the job it was receiving or checking.
    #[error("the board lost the job (it restarted?); upload it again")]
    JobLost,
    /// The board answered something that makes no sense here.
    #[error("unexpected answer from the board: {0}")]
    Protocol(String),
    /// No dollop board among the serial ports.
    #[error("{}", no_board(.usb, .present, None))]
    NoBoard {
        /// What a dollop board is on USB (`USB 1209:0001, "dollop controller"`).
        usb: String,
        /// The serial ports there are.
        present: Vec<String>,
    },
    /// Several dollop boards, and none named.
    #[error("{}", several_boards(.found, None))]
    SeveralBoards {
        /// Their ports.
        found: Vec<String>,
    },
    /// A port could not be listed or opened.
    #[error("{0}")]
    Port(String),
    /// The host gave up the operation because an Abort was asked for meanwhile.
    #[error("{0} cancelled by Abort")]
    Cancelled(Cancelled),
    /// Operating-system error on the port.
    #[error("serial port: {0}")]
    Io(#[from] std::io::Error),
}

impl LinkError {
    /// The message with the option that names a port given as `port` (the command line's
    /// `--port PATH`); `Display` names none.
    pub fn message(&self, port: Option<&str>) -> String {
        match self {
            LinkError::NoBoard { usb, present } => no_board(usb, present, port),
            LinkError::SeveralBoards { found } => several_boards(found, port),
            e => e.to_string(),
        }
    }
}

fn no_board(usb: &str, present: &[String], port: Option<&str>) -> String {
    let with = port.map(|p| format!(" with {p}")).unwrap_or_default();
    let present = if present.is_empty() {
        String::new()
    } else {
        format!(" (serial ports present: {})", present.join(", "))
    };
    format!("no dollop board found ({usb}); connect it, or name its port{with}{present}")
}

fn several_boards(found: &[String], port: Option<&str>) -> String {
    let how = port.map_or("by its port".to_string(), |p| format!("with {p}"));
    format!(
        "several dollop boards found ({}); choose one {how}",
        found.join(", ")
    )
}

/// What an Abort cut short.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cancelled {
    /// An upload, between two frames.
    Upload,
    /// The wait for homing before a job.
    Homing,
}

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Cancelled::Upload => "upload",
            Cancelled::Homing => "homing",
        })
    }
}

impl LinkError {
    /// True for errors a reconnect may cure.
    pub fn is_transient(&self) -> bool {
        matches!(
            self,
            LinkError::Disconnected | LinkError::NoSession | LinkError::NoAnswer { .. }
        )
    }
}

/// A byte pipe to the board with a clock.
pub trait Transport {
    /// Sends bytes (whole frames).
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError>;
    /// Receives what arrives within `timeout` into `buf`; `Ok(0)` if nothing did.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError>;
    /// Time on this transport's clock (virtual for in-memory links).
    fn now(&self) -> Duration;
    /// Waits (bytes that arrive meanwhile are kept for `recv`).
    fn sleep(&mut self, d: Duration);
    /// Opens the connection again after `Disconnected`.
    fn reconnect(&mut self) -> Result<(), LinkError>;
}
