//! The independent watchdog on registers: started once, fed by the control loop only;
//! its timeout is lengthened around flash erases (the chip stalls for up to 2 s per
//! sector while the machine is idle and safe) and shortened again after.

use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};

/// Normal timeout: a control loop silent this long resets the chip (at LSI's nominal
/// 32 kHz; 170 ms to 470 ms over LSI's 17 to 47 kHz range).
pub const TIMEOUT_MS: u32 = 250;
/// Reload of the long timeout, in LSI / 256 counts: 8.2 s at LSI's fastest (47 kHz),
/// twice the worst sector erase even at the 8-bit width (4 s), 22.6 s at its slowest.
const LONG_RELOAD: u16 = 1500;

fn wait_updated() {
    let iwdg = pac::IWDG;
    while iwdg.sr().read().pvu() || iwdg.sr().read().rvu() {}
}

fn configure(pr: Pr, reload: u16) {
    // Wait until a previous update reached the watchdog's clock domain.
    wait_updated();
    // Unlock, prescaler, reload: with every interrupt masked, because the control loop's
    // feed (key 0xAAAA) between the unlock and the writes would lock the registers again
    // and drop the change without a word.
    cortex_m::interrupt::free(|_| {
        let iwdg = pac::IWDG;
        iwdg.kr().write(|w| w.set_key(Key::ENABLE));
        iwdg.pr().write(|w| w.set_pr(pr));
        iwdg.rlr().write(|w| w.set_rl(reload));
    });
    wait_updated();
}

/// Starts the watchdog with the normal timeout (LSI 32 kHz / 32 = 1 ms per count).
pub fn start() {
    // Halting the core in a debugger must not reset it.
    pac::DBGMCU.apb1fzr().modify(|w| w.set_iwdg(true));
    pac::IWDG.kr().write(|w| w.set_key(Key::START));
    configure(Pr::DIVIDE_BY32, TIMEOUT_MS as u16);
    feed();
}

/// Feeds it. Only the control loop calls this, and only when its tick was healthy.
pub fn feed() {
    pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
}

/// The long timeout, in force when this returns: the control loop's next feed reloads
/// the counter with it, and this waits 1 ms (ten control periods) for that feed. Nothing
/// else feeds: if the control loop is dead, the chip resets as it should.
pub fn lengthen() {
    configure(Pr::DIVIDE_BY256, LONG_RELOAD);
    cortex_m::asm::delay(crate::board::CORE_HZ / 1_000);
}

/// Back to the normal timeout from the control loop's next feed on.
pub fn shorten() {
    configure(Pr::DIVIDE_BY32, TIMEOUT_MS as u16);
}

/// True if the last reset came from this watchdog; clears the reset flags.
pub fn caused_reset() -> bool {
    let csr = pac::RCC.csr().read();
    let wd = csr.wdgrstf();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    wd
}
