//! What the chip does when the firmware itself fails: a panic, a HardFault, or an
//! interrupt nobody handles. Each drives the valves closed and the drivers off through the
//! registers (owning nothing), masks every interrupt so nothing can reopen a valve, and
//! waits for the watchdog, which nobody feeds any more, to reset the chip; it then starts
//! halted and tells the host why.

use crate::board;
use core::sync::atomic::{AtomicBool, Ordering};
use cortex_m_rt::exception;

/// Set on the first panic: a panic inside the panic handler's own log (defmt's logger is
/// taken when a log statement panics) must not log, and so recurse, again.
static PANICKING: AtomicBool = AtomicBool::new(false);

fn safe_and_wait() -> ! {
    cortex_m::interrupt::disable();
    board::force_safe_raw();
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    board::force_safe_raw();
    if !PANICKING.swap(true, Ordering::Relaxed) {
        // The location only: formatting the message would pull float formatting into flash.
        if let Some(l) = info.location() {
            defmt::error!("panic at {}:{}", l.file(), l.line());
        }
    }
    safe_and_wait()
}

// SAFETY (both handlers): cortex-m-rt requires these to be `unsafe fn`, because the
// runtime calls them directly from the vector table. They read nothing from the faulting
// context and touch only GPIO set/reset registers (single writes, valid from any context)
// and PRIMASK, so running them at any point is sound.
#[exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    safe_and_wait()
}

#[exception]
unsafe fn DefaultHandler(_irqn: i16) {
    safe_and_wait()
}
