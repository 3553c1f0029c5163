//! The host link's transports and pace on the chip, for `dollop::device::serve`: USB
//! CDC-ACM packets and the host UART's bytes as `HostPort`s (served by one link through
//! `dollop::device::serve::EitherPort`), and a millisecond
//! pace counted by the control loop (not embassy-time's alarms, so the link's progress
//! depends only on the step timer's update interrupt, which every emulator and every
//! board has).

use crate::{line, step};
use core::future::poll_fn;
use core::sync::atomic::{AtomicU32, Ordering};
use core::task::Poll;
use dollop::device::{HostPort, Pace, PortClosed};
use embassy_stm32::usart::BufferedUart;
use embassy_sync::waitqueue::AtomicWaker;
use embassy_usb::class::cdc_acm::CdcAcmClass;
use embassy_usb::driver::Driver;

/// Milliseconds counted by the control loop.
static MILLIS: AtomicU32 = AtomicU32::new(0);
static MILLIS_WAKER: AtomicWaker = AtomicWaker::new();

/// Called by the control loop once a millisecond: wakes the link.
pub fn millisecond() {
    MILLIS.fetch_add(1, Ordering::Release);
    MILLIS_WAKER.wake();
}

/// The link's pace: the control loop's milliseconds, and the step clock for time.
pub struct Millis {
    clock: step::Clock,
}

impl Millis {
    /// A pace starting now.
    pub fn new() -> Self {
        Millis {
            clock: step::Clock::new(),
        }
    }
}

impl Pace for Millis {
    fn now_us(&mut self) -> u64 {
        self.clock.now_us()
    }
    async fn tick(&mut self) {
        let start = MILLIS.load(Ordering::Acquire);
        poll_fn(|cx| {
            if MILLIS.load(Ordering::Acquire) != start {
                return Poll::Ready(());
            }
            MILLIS_WAKER.register(cx.waker());
            if MILLIS.load(Ordering::Acquire) != start {
                Poll::Ready(())
            } else {
                Poll::Pending
            }
        })
        .await
    }
}

/// USB CDC-ACM as the host port.
pub struct UsbPort<D: Driver<'static>> {
    class: CdcAcmClass<'static, D>,
}

impl<D: Driver<'static>> UsbPort<D> {
    /// The port on `class`.
    pub fn new(class: CdcAcmClass<'static, D>) -> Self {
        UsbPort { class }
    }
}

impl<D: Driver<'static>> HostPort for UsbPort<D> {
    fn is_open(&mut self) -> bool {
        // DTR: a host program has the port open (cleared on bus reset and unplug).
        self.class.dtr()
    }
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortClosed> {
        self.class.read_packet(buf).await.map_err(|_| PortClosed)
    }
    async fn write(&mut self, data: &[u8]) -> Result<(), PortClosed> {
        self.class.write_packet(data).await.map_err(|_| PortClosed)
    }
    fn needs_zero_length_end(&self) -> bool {
        true
    }
}

/// The host UART as the host port: always open (a UART has no connection state; a silent
/// host is the link's timeout to notice). Its line errors are counted in the interrupt
/// (`line`) and logged here, in thread mode, when they change.
pub struct UartPort {
    uart: BufferedUart<'static>,
    errors: line::Logged,
}

impl UartPort {
    /// The port on `uart`.
    pub fn new(uart: BufferedUart<'static>) -> Self {
        UartPort {
            uart,
            errors: line::Logged::new(),
        }
    }
}

impl HostPort for UartPort {
    fn is_open(&mut self) -> bool {
        true
    }
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortClosed> {
        let r = embedded_io_async::Read::read(&mut self.uart, buf).await;
        self.errors.log_changes();
        r.map_err(|_| PortClosed)
    }
    async fn write(&mut self, data: &[u8]) -> Result<(), PortClosed> {
        embedded_io_async::Write::write_all(&mut self.uart, data)
            .await
            .map_err(|_| PortClosed)
    }
    fn needs_zero_length_end(&self) -> bool {
        false
    }
}
