//! The host UART's line errors: counted in the UART4 interrupt (no logging there), logged
//! from thread mode when they change. The interrupt handler here runs first in UART4's
//! vector (`bind_interrupts!` in main), ahead of embassy's buffered-UART handler, which
//! reads the data register and so clears the flags. Stops at counting: a byte lost to an
//! overrun, or corrupted, shows up as a bad frame that the link's CRC rejects and the
//! host retransmits.

use core::sync::atomic::{AtomicU32, Ordering};
use embassy_stm32::interrupt::typelevel::{Handler, UART4};
use embassy_stm32::pac;

/// Overruns (a byte arrived before the previous one was read: the interrupt was late).
pub static OVERRUN: AtomicU32 = AtomicU32::new(0);
/// Framing errors (no stop bit: a baud-rate mismatch, a break or a glitch).
pub static FRAMING: AtomicU32 = AtomicU32::new(0);
/// Noise detected by the oversampling.
pub static NOISE: AtomicU32 = AtomicU32::new(0);
/// Parity errors (the link uses no parity: only if a host is misconfigured).
pub static PARITY: AtomicU32 = AtomicU32::new(0);

/// USART_SR bits (RM0090 30.6.1).
const SR_PE: u32 = 1 << 0;
const SR_FE: u32 = 1 << 1;
const SR_NE: u32 = 1 << 2;
const SR_ORE: u32 = 1 << 3;

/// Counts the line errors UART4's status register shows. Reads SR only: on this USART,
/// reading SR does not clear a flag (the following data-register read does, in
/// embassy's handler). A flag raised between this read and embassy's is cleared uncounted;
/// the window is a few instructions against the 10 us a byte takes at 1 Mbaud.
pub struct CountErrors;

impl Handler<UART4> for CountErrors {
    unsafe fn on_interrupt() {
        let sr = pac::UART4.sr().read().0;
        for (bit, counter) in [
            (SR_ORE, &OVERRUN),
            (SR_FE, &FRAMING),
            (SR_NE, &NOISE),
            (SR_PE, &PARITY),
        ] {
            if sr & bit != 0 {
                counter.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

/// The counts as last logged.
pub struct Logged {
    last: [u32; 4],
}

impl Logged {
    /// Nothing logged yet.
    pub const fn new() -> Self {
        Logged { last: [0; 4] }
    }

    /// Logs the counts if any changed since the last call (thread mode only).
    pub fn log_changes(&mut self) {
        let now = counts();
        if now != self.last {
            self.last = now;
            defmt::warn!(
                "host UART line errors so far: overrun {}, framing {}, noise {}, parity {}",
                now[0],
                now[1],
                now[2],
                now[3]
            );
        }
    }
}

/// Overrun, framing, noise and parity counts since boot.
pub fn counts() -> [u32; 4] {
    [
        OVERRUN.load(Ordering::Relaxed),
        FRAMING.load(Ordering::Relaxed),
        NOISE.load(Ordering::Relaxed),
        PARITY.load(Ordering::Relaxed),
    ]
}
