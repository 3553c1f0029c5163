//! What the chip does when the firmware itself fails: a panic, a HardFault, or an
//! interrupt nobody handles. Each drives the valves closed and the drivers off through the
//! registers (owning nothing), masks every interrupt so nothing can reopen a valve, and
//! waits for the watchdog, which nobody feeds any more, to reset the chip; it then starts
//! halted and tells the host why.
//!
//! A stack overflow is a HardFault too: the stack fills the CCM from its top down, and
//! the first push below 0x1000_0000 (reserved: a bus error) faults. The HardFault handler
//! cannot run on that stack, so its entry (assembly, no push) first moves the stack
//! pointer to a small stack of its own in SRAM, then runs the safe state.

use crate::board;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
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

/// Words in the HardFault handler's own stack: the safe state through the registers needs
/// well under 100 bytes (`.ci/firmware-stack` prints HardFault's worst path); 512 bytes
/// leave room for the exception frame of a fault inside it.
const FAULT_STACK_WORDS: usize = 128;

/// The HardFault handler's stack (zero-initialised, in `.bss`). Atomics only so the static
/// is `Sync` without `unsafe`: no Rust code reads or writes it; the handler's entry points
/// the stack pointer at its top and never returns.
#[repr(align(8))]
struct FaultStack {
    _words: [AtomicU32; FAULT_STACK_WORDS],
}
static FAULT_STACK: FaultStack = FaultStack {
    _words: [const { AtomicU32::new(0) }; FAULT_STACK_WORDS],
};

// HardFault's entry in the vector table (cortex-m-rt's link.x lets the application provide
// `HardFault`): no push, so it runs even when the stack pointer is below the stack's end;
// sets MSP to the top of FAULT_STACK and branches to the handler, which never returns,
// so nothing of the faulting context's stack is needed again.
core::arch::global_asm!(
    ".section .text.HardFault, \"ax\"",
    ".global HardFault",
    ".type HardFault, %function",
    ".thumb_func",
    "HardFault:",
    "ldr r0, ={stack}+{size}",
    "msr msp, r0",
    "isb",
    "b {handler}",
    ".ltorg",
    stack = sym FAULT_STACK,
    size = const FAULT_STACK_WORDS * 4,
    handler = sym hard_fault_on_own_stack,
);

extern "C" fn hard_fault_on_own_stack() -> ! {
    safe_and_wait()
}

// SAFETY: cortex-m-rt requires this to be `unsafe fn`, because the runtime calls it
// directly from the vector table. It reads nothing from the faulting context and touches
// only GPIO set/reset registers (single writes, valid from any context) and PRIMASK, so
// running it at any point is sound.
#[exception]
unsafe fn DefaultHandler(_irqn: i16) {
    safe_and_wait()
}
