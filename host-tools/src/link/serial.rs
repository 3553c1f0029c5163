//! The USB CDC-ACM transport: a `serialport` port found by the board's USB VID/PID (or
//! named by the user), with timeouts, and reopening after the board re-enumerates.

use super::transport::{LinkError, Transport};
use dollop::wire::{USB_PID, USB_PRODUCT, USB_VID};
use serialport::{SerialPort, SerialPortType};
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

/// How long a reconnect waits for the board to come back.
const REOPEN_WAIT: Duration = Duration::from_secs(10);

/// Finds the board's port: a USB serial port with dollop's VID/PID (and, when the OS
/// reports one, its product string). Errors name what was found instead.
pub fn detect() -> Result<String, LinkError> {
    let ports = serialport::available_ports()
        .map_err(|e| LinkError::Port(format!("cannot list serial ports: {e}")))?;
    let mut found = Vec::new();
    for p in &ports {
        if let SerialPortType::UsbPort(u) = &p.port_type {
            let product_ok = u.product.as_deref().is_none_or(|s| s.contains("dollop"));
            if u.vid == USB_VID && u.pid == USB_PID && product_ok {
                found.push(p.port_name.clone());
            }
        }
    }
    match found.len() {
        1 => Ok(found.remove(0)),
        0 => Err(LinkError::Port(format!(
            "no dollop board found (USB {USB_VID:04x}:{USB_PID:04x}, \"{USB_PRODUCT}\"); connect it, or name its port with --port PATH{}",
            if ports.is_empty() {
                String::new()
            } else {
                format!(
                    " (serial ports present: {})",
                    ports
                        .iter()
                        .map(|p| p.port_name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ))),
        _ => Err(LinkError::Port(format!(
            "several dollop boards found ({}); choose one with --port PATH",
            found.join(", ")
        ))),
    }
}

/// A serial-port transport.
pub struct SerialLink {
    path: String,
    /// Found by VID/PID: after a reconnect look again (the OS may rename it).
    detected: bool,
    port: Option<Box<dyn SerialPort>>,
    start: Instant,
}

impl SerialLink {
    /// Opens `path`, or the auto-detected board if None.
    pub fn open(path: Option<&str>) -> Result<Self, LinkError> {
        let (path, detected) = match path {
            Some(p) => (p.to_string(), false),
            None => (detect()?, true),
        };
        let mut s = SerialLink {
            path,
            detected,
            port: None,
            start: Instant::now(),
        };
        s.port = Some(s.open_port()?);
        Ok(s)
    }

    /// The port's path.
    pub fn path(&self) -> &str {
        &self.path
    }

    fn open_port(&self) -> Result<Box<dyn SerialPort>, LinkError> {
        // CDC-ACM ignores the baud rate; DTR tells the board a host is there.
        let mut p = serialport::new(&self.path, 115_200)
            .timeout(Duration::from_millis(50))
            .open()
            .map_err(|e| LinkError::Port(format!("cannot open {}: {e}", self.path)))?;
        let _ = p.write_data_terminal_ready(true);
        Ok(p)
    }

    fn lost(&mut self, e: std::io::Error) -> LinkError {
        match e.kind() {
            ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted => {
                LinkError::Io(e)
            }
            _ => {
                self.port = None;
                LinkError::Disconnected
            }
        }
    }
}

impl Transport for SerialLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let Some(p) = &mut self.port else {
            return Err(LinkError::Disconnected);
        };
        let r = p.write_all(bytes).and_then(|()| p.flush());
        r.map_err(|e| self.lost(e))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let Some(p) = &mut self.port else {
            return Err(LinkError::Disconnected);
        };
        let _ = p.set_timeout(timeout.max(Duration::from_millis(1)));
        match p.read(buf) {
            Ok(0) => {
                // End of file on a tty: the device went away.
                self.port = None;
                Err(LinkError::Disconnected)
            }
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => Ok(0),
            Err(e) if e.kind() == ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(self.lost(e)),
        }
    }

    fn now(&self) -> Duration {
        self.start.elapsed()
    }

    fn sleep(&mut self, d: Duration) {
        std::thread::sleep(d);
    }

    fn reconnect(&mut self) -> Result<(), LinkError> {
        self.port = None;
        let until = Instant::now() + REOPEN_WAIT;
        loop {
            if self.detected {
                if let Ok(p) = detect() {
                    self.path = p;
                }
            }
            match self.open_port() {
                Ok(p) => {
                    self.port = Some(p);
                    return Ok(());
                }
                Err(e) if Instant::now() >= until => return Err(e),
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
        }
    }
}
