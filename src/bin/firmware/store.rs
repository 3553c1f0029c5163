//! The job store on the chip: flash sectors 6 to 11 (768 KiB at 0x0804_0000, see
//! memory.x). Erasing stalls the chip for up to 2 s a sector, so it happens one sector
//! per link poll, only while nothing moves, with the watchdog lengthened around it.

use crate::wdg;
use dollop::device::JobStore;
use dollop::wire::StoreError;
use embassy_stm32::flash::{Blocking, Flash};

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
    flash: Flash<'static, Blocking>,
    erase_to: u32,
    erased: u32,
}

impl FlashStore {
    /// A store on the chip's flash.
    pub fn new(flash: Flash<'static, Blocking>) -> Self {
        FlashStore {
            flash,
            erase_to: 0,
            erased: 0,
        }
    }
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
        wdg::lengthen();
        // Let the control loop feed once, so the long timeout is in force.
        cortex_m::asm::delay(168_000_000 / 2_000);
        let from = BASE + self.erased;
        let r = self.flash.blocking_erase(from, from + SECTOR);
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
        let whole = data.len() / WORD * WORD;
        if whole > 0 {
            self.flash
                .blocking_write(BASE + offset, &data[..whole])
                .map_err(|_| StoreError::Write)?;
        }
        if whole < data.len() {
            let mut tail = [0xFFu8; WORD];
            tail[..data.len() - whole].copy_from_slice(&data[whole..]);
            self.flash
                .blocking_write(BASE + offset + whole as u32, &tail)
                .map_err(|_| StoreError::Write)?;
        }
        Ok(())
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), StoreError> {
        if offset as u64 + buf.len() as u64 > LEN as u64 {
            return Err(StoreError::OutOfRange);
        }
        self.flash
            .blocking_read(BASE + offset, buf)
            .map_err(|_| StoreError::Read)
    }
}
