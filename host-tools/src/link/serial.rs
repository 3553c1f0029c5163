//! The board's byte transports: a serial port (USB CDC-ACM found by the board's VID/PID, or
//! named by the user: the USB port, or a host serial port wired to the board's UART at
//! `UART_BAUD`), or a TCP socket (`tcp:HOST:PORT`: an emulated board's UART, a serial
//! server); with timeouts, and reopening after the board re-enumerates or reconnects.

use super::transport::{LinkError, Transport};
use dollop::wire::{USB_PID, USB_PRODUCT, USB_VID};
use serialport::{SerialPort, SerialPortType};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// Baud rate of the board's host UART (the firmware's `board::HOST_UART_BAUD`); USB
/// CDC-ACM ignores it.
pub const UART_BAUD: u32 = 1_000_000;
/// The `--port` prefix of a TCP connection.
const TCP_PREFIX: &str = "tcp:";

/// An open connection to the board.
enum Port {
    Serial(Box<dyn SerialPort>),
    Tcp(TcpStream),
}

impl Port {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        match self {
            Port::Serial(p) => p.set_timeout(t).map_err(std::io::Error::from),
            Port::Tcp(s) => s.set_read_timeout(Some(t)),
        }
    }
}

impl Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self {
            Port::Serial(p) => p.read(buf),
            Port::Tcp(s) => s.read(buf),
        }
    }
}

impl Write for Port {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Port::Serial(p) => p.write(buf),
            Port::Tcp(s) => s.write(buf),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Port::Serial(p) => p.flush(),
            Port::Tcp(s) => s.flush(),
        }
    }
}

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
        0 => Err(LinkError::NoBoard {
            usb: format!("USB {USB_VID:04x}:{USB_PID:04x}, \"{USB_PRODUCT}\""),
            present: ports.iter().map(|p| p.port_name.clone()).collect(),
        }),
        _ => Err(LinkError::SeveralBoards { found }),
    }
}

/// Connects to `HOST:PORT` (the part of `--port tcp:HOST:PORT` after the prefix).
fn open_tcp(addr: &str) -> Result<TcpStream, LinkError> {
    let bad = |why: String| {
        LinkError::Port(format!(
            "cannot connect to {TCP_PREFIX}{addr}: {why} (the form is {TCP_PREFIX}HOST:PORT, e.g. {TCP_PREFIX}127.0.0.1:4444)"
        ))
    };
    let addrs: Vec<_> = addr
        .to_socket_addrs()
        .map_err(|e| bad(e.to_string()))?
        .collect();
    let mut last = None;
    for a in addrs {
        match TcpStream::connect_timeout(&a, Duration::from_secs(5)) {
            Ok(s) => {
                // Frames are small and latency-bound: no Nagle delay.
                let _ = s.set_nodelay(true);
                return Ok(s);
            }
            Err(e) => last = Some(e),
        }
    }
    Err(bad(last.map_or("no address".into(), |e| e.to_string())))
}

/// A serial-port or TCP transport.
pub struct SerialLink {
    path: String,
    /// Found by VID/PID: after a reconnect look again (the OS may rename it).
    detected: bool,
    port: Option<Port>,
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

    fn open_port(&self) -> Result<Port, LinkError> {
        if let Some(addr) = self.path.strip_prefix(TCP_PREFIX) {
            return open_tcp(addr).map(Port::Tcp);
        }
        // CDC-ACM ignores the baud rate, the board's UART runs at this one; DTR tells the
        // board a USB host is there.
        let mut p = serialport::new(&self.path, UART_BAUD)
            .timeout(Duration::from_millis(50))
            .open()
            .map_err(|e| LinkError::Port(format!("cannot open {}: {e}", self.path)))?;
        let _ = p.write_data_terminal_ready(true);
        Ok(Port::Serial(p))
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
