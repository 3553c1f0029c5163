//! The job store on the chip: flash sectors 6 to 11 (768 KiB at 0x0804_0000, see
//! memory.x). Erasing stalls every fetch from flash (the chip) for up to 2 s a sector at
//! the 32-bit width set here, so the link erases one sector per poll, only while nothing
//! moves and every valve is shut (`BoardLink` checks that), with the watchdog lengthened
//! around it. Every erase and every program runs with the outputs forced safe through the
//! registers (`SafeWhileFlashBusy`): while the flash is busy no interrupt can run (vector
//! table and handlers are in flash), so not even the e-stop could act; with the valves
//! shut and the drivers disabled beforehand it has nothing left to do. The data cache is
//! reset after each erase (RM0090 3.5.2), so no read returns the erased sector's old words.

use crate::{board, control, shared, wdg};
use core::sync::atomic::Ordering;
use dollop::device::JobStore;
use dollop::wire::StoreError;
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::pac;
use embassy_stm32::pac::flash::vals::Psize;

/// Offset of the store from the start of flash.
pub const BASE: u32 = 0x0004_0000;
/// Bytes in the store.
pub const LEN: u32 = 768 * 1024;
/// Sector size in the store's part of flash.
const SECTOR: u32 = 128 * 1024;
/// Flash word: writes go in whole words.
const WORD: usize = 4;

/// Job store on flash.
pub struct FlashStore {
    /// The flash, once `attach` gave it (the store is built at compile time).
    flash: Option<Flash<'static, Blocking>>,
    erase_to: u32,
    erased: u32,
}

impl FlashStore {
    /// A store with no flash yet.
    pub const fn new() -> Self {
        FlashStore {
            flash: None,
            erase_to: 0,
            erased: 0,
        }
    }

    /// Gives the store the chip's flash.
    pub fn attach(&mut self, flash: Flash<'static, Blocking>) {
        self.flash = Some(flash);
    }

    fn flash(&mut self) -> Result<&mut Flash<'static, Blocking>, StoreError> {
        self.flash.as_mut().ok_or(StoreError::Read)
    }
}

/// Sets the erase width to 32 bits (the board runs at 3.3 V), which halves a sector
/// erase against the 8-bit width left from reset (typically 1 s instead of 2 s, at most
/// 2 s instead of 4 s). embassy's erase keeps the width it finds; it sets 32 bits only
/// for writes. The control register must be unlocked for the write to take; embassy's
/// own unlock then sees it unlocked and leaves it so, and locks it after the erase.
fn erase_width_32() {
    let f = pac::FLASH;
    if f.cr().read().lock() {
        f.keyr().write_value(0x4567_0123);
        f.keyr().write_value(0xCDEF_89AB);
    }
    f.cr().modify(|w| w.set_psize(Psize::PSIZE32));
}

/// The outputs forced safe for the life of the guard: valves shut and drivers disabled
/// through the registers. On drop the drivers are enabled again only if the control loop
/// still commands them enabled (its last published snapshot) and no e-stop is latched:
/// an e-stop or a halt while the flash was busy keeps them off. The valves are not
/// reopened: `BoardLink` erases and writes only while every valve is shut. Nothing reopens
/// them meanwhile: only the control loop drives them, no job runs during an upload, and
/// the link, which would hand it orders, is the code that is busy here.
struct SafeWhileFlashBusy;

impl SafeWhileFlashBusy {
    fn new() -> Self {
        board::force_safe_raw();
        SafeWhileFlashBusy
    }
}

impl Drop for SafeWhileFlashBusy {
    fn drop(&mut self) {
        // One critical section: neither the control loop nor the e-stop can change the
        // answer between the test and the write.
        cortex_m::interrupt::free(|_| {
            if shared::drivers_commanded() && !control::ESTOP_LATCH.load(Ordering::Acquire) {
                board::write(board::DRIVERS_EN, false);
            }
        });
    }
}

/// Resets the flash data cache (RM0090 3.5.2: DCRST works only with the cache disabled),
/// then turns it on again: ST's HAL does the same after every erase; embassy's F4 driver
/// does it only on dual-bank parts.
fn reset_data_cache() {
    let f = pac::FLASH;
    f.acr().modify(|w| w.set_dcen(false));
    f.acr().modify(|w| w.set_dcrst(true));
    f.acr().modify(|w| w.set_dcrst(false));
    f.acr().modify(|w| w.set_dcen(true));
}

impl JobStore for FlashStore {
    fn capacity(&self) -> u32 {
        LEN
    }
    fn prepare(&mut self, len: u32) -> Result<(), StoreError> {
        if len > LEN {
            return Err(StoreError::OutOfRange);
        }
        self.erase_to = len.div_ceil(SECTOR) * SECTOR;
        self.erased = 0;
        Ok(())
    }
    fn prepare_step(&mut self) -> Result<bool, StoreError> {
        if self.erased >= self.erase_to {
            return Ok(true);
        }
        let from = BASE + self.erased;
        let flash = self.flash().map_err(|_| StoreError::Erase)?;
        wdg::lengthen();
        erase_width_32();
        let r = {
            let _safe = SafeWhileFlashBusy::new();
            let r = flash.blocking_erase(from, from + SECTOR);
            reset_data_cache();
            r
        };
        wdg::shorten();
        r.map_err(|_| StoreError::Erase)?;
        self.erased += SECTOR;
        Ok(self.erased >= self.erase_to)
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), StoreError> {
        let end = offset as u64 + data.len() as u64;
        if offset as usize % WORD != 0 || end > self.erased as u64 {
            return Err(StoreError::OutOfRange);
        }
        let flash = self.flash().map_err(|_| StoreError::Write)?;
        let _safe = SafeWhileFlashBusy::new();
        let whole = data.len() / WORD * WORD;
        if whole > 0 {
            flash
                .blocking_write(BASE + offset, &data[..whole])
                .map_err(|_| StoreError::Write)?;
        }
        if whole < data.len() {
            let mut tail = [0xFFu8; WORD];
            tail[..data.len() - whole].copy_from_slice(&data[whole..]);
            flash
                .blocking_write(BASE + offset + whole as u32, &tail)
                .map_err(|_| StoreError::Write)?;
        }
        Ok(())
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), StoreError> {
        if offset as u64 + buf.len() as u64 > LEN as u64 {
            return Err(StoreError::OutOfRange);
        }
        self.flash()?
            .blocking_read(BASE + offset, buf)
            .map_err(|_| StoreError::Read)
    }
}
