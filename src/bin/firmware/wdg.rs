//! The independent watchdog on registers: started once, fed by the control loop only;
//! its timeout is lengthened around flash erases (the chip stalls for up to 2 s per
//! sector while the machine is idle and safe) and shortened again after.

use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};

/// Normal timeout: a control loop silent this long resets the chip.
pub const TIMEOUT_MS: u32 = 250;

fn configure(pr: Pr, reload: u16) {
    let iwdg = pac::IWDG;
    // Wait until a previous update reached the watchdog's clock domain.
    while iwdg.sr().read().pvu() || iwdg.sr().read().rvu() {}
    iwdg.kr().write(|w| w.set_key(Key::ENABLE));
    iwdg.pr().write(|w| w.set_pr(pr));
    iwdg.rlr().write(|w| w.set_rl(reload));
    while iwdg.sr().read().pvu() || iwdg.sr().read().rvu() {}
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

/// 4 s timeout (LSI / 256 = 8 ms per count) from the control loop's next feed on.
pub fn lengthen() {
    configure(Pr::DIVIDE_BY256, 500);
}

/// Back to the normal timeout from the next feed on.
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
