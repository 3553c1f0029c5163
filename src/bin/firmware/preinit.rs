//! The safe state at the very first instruction after reset: `__pre_init`, which
//! cortex-m-rt's reset handler calls before it zeroes `.bss` and copies `.data` (the
//! 64 KiB of statics take milliseconds at the reset clock). It drives the valves low
//! and the driver enable high and makes them outputs, through registers only. Stops there:
//! clocks, watchdog and everything else come later (`boot`, `main`).
//!
//! Written in assembly on purpose: before RAM is initialised no Rust code may run (a
//! promoted constant or any static would be read from uninitialised RAM; cortex-m-rt's
//! `#[pre_init]` attribute is deprecated for that reason). The routine uses only r0-r3
//! (caller-saved, so the reset handler's `bl __pre_init` needs nothing saved), no stack and
//! no memory but the RCC and GPIO registers; every constant is an immediate or a literal
//! computed at compile time from `board`'s pin map, so a board with other pins gets the
//! right routine without editing it.

use crate::board::{RawPin, DRIVERS_EN, VALVES};

const RCC_AHB1ENR: u32 = 0x4002_3830;
const GPIO_BASE: u32 = 0x4002_0000;
const GPIO_STRIDE: u32 = 0x400;
const MODER: u32 = 0x00;
const BSRR: u32 = 0x18;

const fn port_base(p: RawPin) -> u32 {
    GPIO_BASE + p.port as u32 * GPIO_STRIDE
}

/// Every valve on one port (the routine writes one BSRR and one MODER for them all).
const fn valves_one_port() -> bool {
    let mut i = 1;
    while i < VALVES.len() {
        if VALVES[i].port != VALVES[0].port {
            return false;
        }
        i += 1;
    }
    true
}
const _: () = assert!(
    valves_one_port(),
    "pre_init drives the valves through one port"
);

const fn valve_mask() -> u32 {
    let mut m = 0;
    let mut i = 0;
    while i < VALVES.len() {
        m |= 1 << VALVES[i].pin;
        i += 1;
    }
    m
}

/// MODER bits of the pins in `mask`: both bits (to clear) or the low bit (output).
const fn moder_bits(mask: u32, both: bool) -> u32 {
    let mut m = 0;
    let mut pin = 0;
    while pin < 16 {
        if mask & (1 << pin) != 0 {
            m |= (if both { 3 } else { 1 }) << (2 * pin);
        }
        pin += 1;
    }
    m
}

const VALVE_PORT: u32 = port_base(VALVES[0]);
const VALVE_MASK: u32 = valve_mask();
const EN_PORT: u32 = port_base(DRIVERS_EN);
const EN_MASK: u32 = 1 << DRIVERS_EN.pin;
/// GPIO port clocks: the valves' and the enable pin's.
const PORT_CLOCKS: u32 = (1 << VALVES[0].port) | (1 << DRIVERS_EN.port);

// Order: port clocks on (a read-back so the clock is running before the first GPIO
// write), then the output levels (BSRR: valves reset, enable set = drivers disabled),
// then the pins made outputs, so each pin switches from input straight to its safe level.
core::arch::global_asm!(
    ".section .text.__pre_init, \"ax\"",
    ".global __pre_init",
    ".type __pre_init, %function",
    ".thumb_func",
    "__pre_init:",
    "ldr r0, ={ahb1enr}",
    "ldr r1, [r0]",
    "ldr r2, ={clocks}",
    "orrs r1, r2",
    "str r1, [r0]",
    "ldr r1, [r0]",
    "ldr r0, ={valve_port}",
    "ldr r1, ={valve_reset}",
    "str r1, [r0, #{bsrr}]",
    "ldr r0, ={en_port}",
    "ldr r1, ={en_set}",
    "str r1, [r0, #{bsrr}]",
    "ldr r0, ={valve_port}",
    "ldr r1, [r0, #{moder}]",
    "ldr r2, ={valve_moder_clear}",
    "bics r1, r2",
    "ldr r2, ={valve_moder_out}",
    "orrs r1, r2",
    "str r1, [r0, #{moder}]",
    "ldr r0, ={en_port}",
    "ldr r1, [r0, #{moder}]",
    "ldr r2, ={en_moder_clear}",
    "bics r1, r2",
    "ldr r2, ={en_moder_out}",
    "orrs r1, r2",
    "str r1, [r0, #{moder}]",
    "bx lr",
    ".ltorg",
    ahb1enr = const RCC_AHB1ENR,
    clocks = const PORT_CLOCKS,
    valve_port = const VALVE_PORT,
    valve_reset = const VALVE_MASK << 16,
    en_port = const EN_PORT,
    en_set = const EN_MASK,
    bsrr = const BSRR,
    moder = const MODER,
    valve_moder_clear = const moder_bits(VALVE_MASK, true),
    valve_moder_out = const moder_bits(VALVE_MASK, false),
    en_moder_clear = const moder_bits(EN_MASK, true),
    en_moder_out = const moder_bits(EN_MASK, false),
);
