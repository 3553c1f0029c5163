//! The link's main loop, independent of the transport and the executor: packets in from a
//! `HostPort` (USB CDC-ACM, a UART), replies out, and the link's background work
//! (`BoardLink::poll`: store writes, job feeding, the silent-host timeout) at least once per
//! `Pace` tick; `EitherPort` serves two transports (USB and a UART) through one link, with
//! the same rules on either. Every path through the loop awaits the pace or the port, so it always
//! yields to the rest of the board; every write has a deadline, so a host that stops
//! reading cannot hold `poll` (and the link-loss policy) back. The board supplies the
//! port and the pace; host tests drive the same loop with doubles.

use super::link::BoardLink;
use super::store::JobStore;
use super::ToControl;
use embassy_futures::select::{select, Either};

/// Packet buffers of the loop, bytes (a USB full-speed bulk packet).
pub const PACKET: usize = 64;
/// Longest a write may wait for the host to take it, in pace ticks (ms): a host that
/// takes nothing for this long is treated as gone, and the link-loss policy applies.
pub const WRITE_TIMEOUT_TICKS: u32 = 50;

/// The port closed under a read or a write (cable pulled, host closed it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PortClosed;

/// A byte or packet transport to the host.
#[allow(async_fn_in_trait)] // used by concrete types only, on a single-threaded executor
pub trait HostPort {
    /// True while a host holds the port open (USB: configured with DTR set; a UART: always).
    fn is_open(&mut self) -> bool;
    /// Waits for bytes from the host and puts up to `buf.len()` of them in `buf`.
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortClosed>;
    /// Sends `data` (at most `PACKET` bytes).
    async fn write(&mut self, data: &[u8]) -> Result<(), PortClosed>;
    /// True for USB-style packets: a transfer that ends on a full packet needs an empty
    /// one after it.
    fn needs_zero_length_end(&self) -> bool;
}

/// The loop's clock and pace.
#[allow(async_fn_in_trait)]
pub trait Pace {
    /// Microseconds since start, never going back.
    fn now_us(&mut self) -> u64;
    /// Waits for the next tick (1 ms on the board). It must really wait: it returns only
    /// after yielding to the executor at least once.
    async fn tick(&mut self);
}

/// Serves the host on `port` for ever: the board's link task.
pub async fn serve<S: JobStore>(
    port: &mut impl HostPort,
    pace: &mut impl Pace,
    link: &mut BoardLink<S>,
    control: &mut impl ToControl,
) -> ! {
    let mut rx = [0u8; PACKET];
    let mut open = false;
    loop {
        if open {
            let got = match select(port.read(&mut rx), pace.tick()).await {
                Either::First(r) => Some(r),
                Either::Second(()) => None,
            };
            match got {
                Some(Ok(n)) => {
                    let now = pace.now_us();
                    link.receive(&rx[..n.min(PACKET)], now, control);
                }
                Some(Err(PortClosed)) => open = false,
                None => {}
            }
            open = open && port.is_open() && flush(port, pace, link).await;
            if !open {
                link.disconnected(control);
            }
        } else {
            // A port that is not open may report "ready" at once (a configured USB device
            // without DTR does): wait for the pace, never for the port, or this loop
            // would spin without yielding and starve the USB stack that would open it.
            pace.tick().await;
            open = port.is_open();
        }
        let now = pace.now_us();
        link.poll(now, control);
    }
}

/// Sends every reply the link has queued; false if the port closed or the host stopped
/// taking data.
async fn flush<S: JobStore>(
    port: &mut impl HostPort,
    pace: &mut impl Pace,
    link: &mut BoardLink<S>,
) -> bool {
    let mut tx = [0u8; PACKET];
    let mut last = 0;
    loop {
        let n = link.take_tx(&mut tx);
        if n == 0 {
            break;
        }
        last = n;
        if !write_within(port, pace, &tx[..n]).await {
            return false;
        }
    }
    if last == PACKET && port.needs_zero_length_end() {
        return write_within(port, pace, &[]).await;
    }
    true
}

async fn write_within(port: &mut impl HostPort, pace: &mut impl Pace, data: &[u8]) -> bool {
    let deadline = async {
        for _ in 0..WRITE_TIMEOUT_TICKS {
            pace.tick().await;
        }
    };
    matches!(
        select(port.write(data), deadline).await,
        Either::First(Ok(()))
    )
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    A,
    B,
}

/// Two ports served as one: reads from whichever has bytes, replies to the one the last
/// request came from. When that one closes, the link sees it close once (and applies its
/// link-loss rule), then listens on both again.
pub struct EitherPort<A: HostPort, B: HostPort> {
    a: A,
    b: B,
    current: Side,
    spare: [u8; PACKET],
}

impl<A: HostPort, B: HostPort> EitherPort<A, B> {
    /// Both ports; replies go to `a` until a request comes from `b`.
    pub fn new(a: A, b: B) -> Self {
        EitherPort {
            a,
            b,
            current: Side::A,
            spare: [0; PACKET],
        }
    }
}

impl<A: HostPort, B: HostPort> HostPort for EitherPort<A, B> {
    fn is_open(&mut self) -> bool {
        let open = match self.current {
            Side::A => self.a.is_open(),
            Side::B => self.b.is_open(),
        };
        if !open {
            // Reported closed once; from now on whichever speaks first is current.
            self.current = if self.current == Side::A {
                Side::B
            } else {
                Side::A
            };
        }
        open
    }
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortClosed> {
        // Only open sides are listened to: a USB endpoint that no host configured fails a
        // read at once, which would end the wait for the other side's bytes.
        let spare = &mut self.spare;
        let (side, r) = match (self.a.is_open(), self.b.is_open()) {
            (true, true) => match select(self.a.read(buf), self.b.read(spare)).await {
                Either::First(r) => (Side::A, r),
                Either::Second(r) => (Side::B, r),
            },
            (true, false) => (Side::A, self.a.read(buf).await),
            (false, true) => (Side::B, self.b.read(spare).await),
            (false, false) => return Err(PortClosed),
        };
        let n = match r {
            Ok(n) => n,
            // The side the link talks to closed: the link must hear of it.
            Err(e) if side == self.current => return Err(e),
            // The other side closed: nothing the current host sent is lost.
            Err(_) => return Ok(0),
        };
        self.current = side;
        if side == Side::B {
            let n = n.min(buf.len()).min(spare.len());
            buf[..n].copy_from_slice(&spare[..n]);
            return Ok(n);
        }
        Ok(n)
    }
    async fn write(&mut self, data: &[u8]) -> Result<(), PortClosed> {
        match self.current {
            Side::A => self.a.write(data).await,
            Side::B => self.b.write(data).await,
        }
    }
    fn needs_zero_length_end(&self) -> bool {
        match self.current {
            Side::A => self.a.needs_zero_length_end(),
            Side::B => self.b.needs_zero_length_end(),
        }
    }
}
