//! The boot sequence up to a clocked chip with its peripherals (`start`), and what it
//! must settle on registers at the reset clock (HSI, 16 MHz) before embassy takes over:
//! the brown-out reset level in the option bytes, and the crystal, started here with a
//! bounded wait because embassy's clock set-up waits for HSERDY without one. Stops there:
//! the clock tree itself is embassy's (`board::clocks`), the pins are `board::parts`.

use crate::{board, wdg};
use dollop::device::ResetCause;
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_stm32::pac::flash::regs::Optcr;
use embassy_stm32::Peripherals;

/// Reset clock (HSI) the waits below are counted in.
const HSI_HZ: u32 = 16_000_000;

/// Longest wait for the crystal. The F405 datasheet gives the HSE oscillator's start-up
/// time as 2 ms typical (8 MHz crystal, VDD stable); ten times that is a crystal that is
/// not there, not fitted or not oscillating.
pub const HSE_WAIT_MS: u32 = 20;

/// FLASH_OPTCR fields (RM0090 3.9.10): BOR_LEV bits 3:2, 00 = level 3 (the chip is held
/// in reset unless VDD is in the 2.70-3.60 V range), 11 = off (the factory setting).
const OPTCR_OPTLOCK: u32 = 1 << 0;
const OPTCR_OPTSTRT: u32 = 1 << 1;
const OPTCR_BOR_MASK: u32 = 0b11 << 2;
const OPTCR_BOR_LEVEL3: u32 = 0b00 << 2;
/// The option-key sequence (RM0090 3.6.2).
const OPTKEY1: u32 = 0x0819_2A3B;
const OPTKEY2: u32 = 0x4C5D_6E7F;
/// FLASH_SR BSY.
const SR_BSY: u32 = 1 << 16;
/// Longest wait for the option-byte programming: it erases and rewrites the option
/// bytes' own sector; 4 s at the reset clock is well over any figure RM0090 or the
/// datasheet gives for an erase of the smallest sector.
const OPT_WAIT_LOOPS: u32 = 4 * HSI_HZ / 8;

/// From reset to a clocked chip: the valves closed and the drivers disabled since
/// `__pre_init` (preinit.rs); then the brown-out level (before the watchdog: the one-time
/// option-byte write may outlast its timeout), the watchdog (before the clocks: a clock
/// set-up that hangs resets the chip), the crystal, embassy's clocks. Returns the
/// peripherals and why the chip last reset.
pub fn start() -> (Peripherals, ResetCause) {
    let reset = if wdg::caused_reset() {
        ResetCause::Watchdog
    } else {
        ResetCause::PowerOn
    };
    let bor = brown_out_level_3();
    wdg::start();
    if !start_hse() {
        clock_fault();
    }
    let p = embassy_stm32::init(board::clocks());
    board::flash_accelerator_on();
    clock_security_on();
    // The time driver (TIM5) defaults to the top priority; it must not delay step edges.
    interrupt::TIM5.set_priority(Priority::P4);
    defmt::info!(
        "dollop firmware {} on {}",
        env!("CARGO_PKG_VERSION"),
        board::NAME
    );
    match bor {
        Bor::AlreadySet => defmt::info!("brown-out reset at level 3 (2.70 V)"),
        Bor::Written { was } => defmt::warn!(
            "brown-out reset set to level 3 (2.70 V) in the option bytes (was BOR_LEV {=u8})",
            was
        ),
        Bor::Failed { now } => defmt::error!(
            "brown-out level 3 not written: the option bytes still read BOR_LEV {=u8}",
            now
        ),
    }
    (p, reset)
}

/// What `brown_out_level_3` found and did.
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Bor {
    /// Level 3 was already set (every boot after the first).
    AlreadySet,
    /// It was another level (0-3 = 3, 2, 1, off), now level 3.
    Written { was: u8 },
    /// The write did not take: the option bytes still read this level.
    Failed { now: u8 },
}

/// BOR level 3: the chip held in reset below the 2.70 V that 168 MHz at 5 wait states and
/// 32-bit flash programming need (RM0090 3.5.1: the x32 parallelism is for 2.7-3.6 V). Written once:
/// the option bytes keep it, and later boots only read it. Runs before the watchdog is
/// started, since the option-byte programming can take longer than its timeout.
pub fn brown_out_level_3() -> Bor {
    let f = pac::FLASH;
    let optcr = f.optcr().read().0;
    if optcr & OPTCR_BOR_MASK == OPTCR_BOR_LEVEL3 {
        return Bor::AlreadySet;
    }
    let was = ((optcr & OPTCR_BOR_MASK) >> 2) as u8;
    if optcr & OPTCR_OPTLOCK != 0 {
        f.optkeyr().write_value(OPTKEY1);
        f.optkeyr().write_value(OPTKEY2);
    }
    wait_not_busy();
    let new = (f.optcr().read().0 & !OPTCR_BOR_MASK) | OPTCR_BOR_LEVEL3;
    f.optcr().write_value(Optcr(new));
    f.optcr().write_value(Optcr(new | OPTCR_OPTSTRT));
    wait_not_busy();
    f.optcr()
        .write_value(Optcr(f.optcr().read().0 | OPTCR_OPTLOCK));
    let now = f.optcr().read().0 & OPTCR_BOR_MASK;
    if now == OPTCR_BOR_LEVEL3 {
        Bor::Written { was }
    } else {
        Bor::Failed {
            now: (now >> 2) as u8,
        }
    }
}

fn wait_not_busy() {
    for _ in 0..OPT_WAIT_LOOPS {
        if pac::FLASH.sr().read().0 & SR_BSY == 0 {
            return;
        }
    }
}

/// Starts the crystal oscillator and waits for it at most `HSE_WAIT_MS`; false if it did
/// not start. embassy's clock set-up then finds it ready and does not wait.
pub fn start_hse() -> bool {
    let rcc = pac::RCC;
    rcc.cr().modify(|w| {
        w.set_hsebyp(false);
        w.set_hseon(true);
    });
    // About 10 us a poll at the reset clock (the delay's cycles plus the loop).
    const POLL_CYCLES: u32 = HSI_HZ / 100_000;
    for _ in 0..HSE_WAIT_MS * 100 {
        if rcc.cr().read().hserdy() {
            return true;
        }
        cortex_m::asm::delay(POLL_CYCLES);
    }
    rcc.cr().modify(|w| w.set_hseon(false));
    false
}

/// The clock security system: if the crystal stops after boot, the chip switches the
/// system clock to HSI and raises the NMI, whose handler (cortex-m-rt's default, this
/// firmware's `DefaultHandler`) forces the safe state and waits for the watchdog; the
/// next boot then finds no crystal and ends in `clock_fault`.
pub fn clock_security_on() {
    pac::RCC.cr().modify(|w| w.set_csson(true));
}

/// No crystal: the board cannot run (USB needs the crystal's accuracy, and the step and
/// control rates are derived from it). The outputs have been safe since `__pre_init`;
/// this flashes the status LED three times quickly (120 ms, shorter than the watchdog's
/// shortest timeout) and then waits, never feeding the watchdog, which was started
/// before the clocks: the chip resets (170-470 ms) and tries again. The lab sees bursts
/// of three flashes and no USB device (docs/bring-up.md).
#[inline(never)]
pub fn clock_fault() -> ! {
    board::force_safe_raw();
    board::led_raw_init();
    const MS: u32 = HSI_HZ / 1000;
    for _ in 0..3 {
        board::led_raw(true);
        cortex_m::asm::delay(15 * MS);
        board::led_raw(false);
        cortex_m::asm::delay(25 * MS);
    }
    loop {
        cortex_m::asm::nop();
    }
}
