//! Where an uploaded job's body is kept until it runs: the `JobStore` trait (flash sectors
//! on the board) and `RamStore`, a byte-slice store for host tests and simulation.

use crate::wire::StoreError;

/// Byte storage for one job body. Preparing may be slow (flash erase), so it runs in
/// steps the link spreads over its polls; writes come in order, at word-aligned offsets.
pub trait JobStore {
    /// Bytes it holds at most.
    fn capacity(&self) -> u32;
    /// Starts making room for `len` bytes (forgetting what it held).
    fn prepare(&mut self, len: u32) -> Result<(), StoreError>;
    /// Does the next piece of preparation; true when the store is ready for writes.
    fn prepare_step(&mut self) -> Result<bool, StoreError>;
    /// Writes `data` at `offset`. Every write but the last is a multiple of 4 bytes long.
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), StoreError>;
    /// Reads `buf.len()` bytes at `offset`.
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), StoreError>;
}

/// A store on any byte buffer (a `Vec` in tests, a static array elsewhere). Preparing
/// fills the prepared length with 0xFF, as erased flash reads.
pub struct RamStore<B> {
    buf: B,
    prepared: u32,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> RamStore<B> {
    /// A store on `buf`.
    pub fn new(buf: B) -> Self {
        RamStore { buf, prepared: 0 }
    }
    /// The bytes held.
    pub fn bytes(&self) -> &[u8] {
        self.buf.as_ref()
    }
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> JobStore for RamStore<B> {
    fn capacity(&self) -> u32 {
        self.buf.as_ref().len().min(u32::MAX as usize) as u32
    }
    fn prepare(&mut self, len: u32) -> Result<(), StoreError> {
        if len > self.capacity() {
            return Err(StoreError::OutOfRange);
        }
        self.prepared = len;
        Ok(())
    }
    fn prepare_step(&mut self) -> Result<bool, StoreError> {
        let n = self.prepared as usize;
        self.buf.as_mut()[..n].fill(0xFF);
        Ok(true)
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), StoreError> {
        let end = offset as usize + data.len();
        if end > self.prepared as usize {
            return Err(StoreError::OutOfRange);
        }
        self.buf.as_mut()[offset as usize..end].copy_from_slice(data);
        Ok(())
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), StoreError> {
        let end = offset as usize + buf.len();
        if end > self.buf.as_ref().len() {
            return Err(StoreError::OutOfRange);
        }
        buf.copy_from_slice(&self.buf.as_ref()[offset as usize..end]);
        Ok(())
    }
}
