//! An in-memory link to a simulated board (`dollop::device::SimBoard`) in virtual time,
//! with fault injection on every frame in both directions: drops, duplicates, corrupted
//! bits, reordering, truncation, stalls, and disconnects. For link tests and benchmarks;
//! the store logs every write so a test can prove each byte arrived once, in order.

use super::transport::{LinkError, Transport};
use dollop::device::{JobStore, RamStore, SimBoard};
use dollop::wire::StoreError;
use rand::{RngExt, SeedableRng};
use std::collections::VecDeque;
use std::time::Duration;

/// How often each fault strikes (probabilities per frame; 0 for a clean link).
#[derive(Clone, Copy, Debug, Default)]
pub struct Faults {
    /// Frame lost.
    pub drop: f64,
    /// Frame delivered twice.
    pub duplicate: f64,
    /// One bit of the frame flipped.
    pub corrupt: f64,
    /// Frame held back and delivered after the next one.
    pub reorder: f64,
    /// Frame cut short (its tail and delimiter lost).
    pub truncate: f64,
    /// Delivery to the board stops for `stall_ms` (per host frame).
    pub stall: f64,
    /// Length of a stall, ms.
    pub stall_ms: u64,
    /// The connection drops (per host frame).
    pub disconnect: f64,
}

impl Faults {
    /// A bit of everything.
    pub fn harsh() -> Self {
        Faults {
            drop: 0.02,
            duplicate: 0.02,
            corrupt: 0.02,
            reorder: 0.02,
            truncate: 0.01,
            stall: 0.001,
            stall_ms: 400,
            disconnect: 0.0005,
        }
    }
}

/// What the in-memory link did.
#[derive(Clone, Copy, Debug, Default)]
pub struct MemStats {
    /// Frames the host sent.
    pub host_frames: u64,
    /// Frames the board sent.
    pub board_frames: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Frames duplicated.
    pub duplicated: u64,
    /// Frames corrupted.
    pub corrupted: u64,
    /// Frames reordered.
    pub reordered: u64,
    /// Frames truncated.
    pub truncated: u64,
    /// Stalls.
    pub stalls: u64,
    /// Disconnects.
    pub disconnects: u64,
}

/// A `RamStore` that records every write (offset, bytes).
pub struct LogStore {
    inner: RamStore<Vec<u8>>,
    /// Every write, in order.
    pub writes: Vec<(u32, Vec<u8>)>,
    /// Make the next write fail (fault injection).
    pub fail_next_write: bool,
}

impl LogStore {
    /// A store of `capacity` bytes.
    pub fn new(capacity: usize) -> Self {
        LogStore {
            inner: RamStore::new(vec![0xFF; capacity]),
            writes: Vec::new(),
            fail_next_write: false,
        }
    }
    /// The bytes held.
    pub fn bytes(&self) -> &[u8] {
        self.inner.bytes()
    }
}

impl JobStore for LogStore {
    fn capacity(&self) -> u32 {
        self.inner.capacity()
    }
    fn prepare(&mut self, len: u32) -> Result<(), StoreError> {
        self.writes.clear();
        self.inner.prepare(len)
    }
    fn prepare_step(&mut self) -> Result<bool, StoreError> {
        self.inner.prepare_step()
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), StoreError> {
        if std::mem::take(&mut self.fail_next_write) {
            return Err(StoreError::Write);
        }
        self.writes.push((offset, data.to_vec()));
        self.inner.write(offset, data)
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), StoreError> {
        self.inner.read(offset, buf)
    }
}

/// Job store size of the simulated board: the firmware's (768 KiB of flash).
pub const SIM_STORE: usize = 768 * 1024;

/// The in-memory link.
pub struct MemLink {
    board: Box<SimBoard<LogStore>>,
    faults: Faults,
    rng: rand::rngs::StdRng,
    latency_us: u64,
    to_board: VecDeque<(u64, Vec<u8>)>,
    to_host: VecDeque<(u64, Vec<u8>)>,
    held_to_board: Option<Vec<u8>>,
    held_to_host: Option<Vec<u8>>,
    board_partial: Vec<u8>,
    host_rx: Vec<u8>,
    connected: bool,
    stalled_until: u64,
    /// Drop the connection when the host has sent this many frames.
    pub disconnect_at: Option<u64>,
    /// From this many host frames on, the link loses everything (a dead cable).
    pub dead_after: Option<u64>,
    /// What happened.
    pub stats: MemStats,
}

impl MemLink {
    /// A link to a freshly powered board; `seed` drives the faults.
    pub fn new(faults: Faults, seed: u64) -> Self {
        MemLink {
            board: Box::new(SimBoard::new(LogStore::new(SIM_STORE))),
            faults,
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            latency_us: 500,
            to_board: VecDeque::new(),
            to_host: VecDeque::new(),
            held_to_board: None,
            held_to_host: None,
            board_partial: Vec::new(),
            host_rx: Vec::new(),
            connected: true,
            stalled_until: 0,
            disconnect_at: None,
            dead_after: None,
            stats: MemStats::default(),
        }
    }

    /// The simulated board.
    pub fn board(&self) -> &SimBoard<LogStore> {
        &self.board
    }
    /// The simulated board, to change (press the e-stop, hang the loop ...).
    pub fn board_mut(&mut self) -> &mut SimBoard<LogStore> {
        &mut self.board
    }
    /// Changes the faults from now on.
    pub fn set_faults(&mut self, f: Faults) {
        self.faults = f;
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.rng.random_bool(p.min(1.0))
    }

    /// Applies the faults to one frame and queues what is left for delivery at `at`.
    fn inject(&mut self, mut frame: Vec<u8>, at: u64, to_board: bool) {
        if self.chance(self.faults.drop) {
            self.stats.dropped += 1;
            return;
        }
        if self.chance(self.faults.corrupt) && !frame.is_empty() {
            let i = self.rng.random_range(0..frame.len());
            let bit = self.rng.random_range(0..8);
            frame[i] ^= 1 << bit;
            self.stats.corrupted += 1;
        }
        if self.chance(self.faults.truncate) && frame.len() > 1 {
            let n = self.rng.random_range(0..frame.len() - 1);
            frame.truncate(n);
            self.stats.truncated += 1;
        }
        let dup = self.chance(self.faults.duplicate);
        let reorder = self.chance(self.faults.reorder);
        let (queue, held) = if to_board {
            (&mut self.to_board, &mut self.held_to_board)
        } else {
            (&mut self.to_host, &mut self.held_to_host)
        };
        if reorder && held.is_none() {
            *held = Some(frame);
            self.stats.reordered += 1;
            return;
        }
        if dup {
            queue.push_back((at, frame.clone()));
            self.stats.duplicated += 1;
        }
        queue.push_back((at, frame));
        if let Some(h) = held.take() {
            queue.push_back((at, h));
        }
    }

    /// One control period of virtual time: deliveries, the board's cycle, its replies.
    fn step(&mut self) {
        let now = self.board.now_us;
        if now >= self.stalled_until {
            while self.to_board.front().is_some_and(|(t, _)| *t <= now) {
                if let Some((_, f)) = self.to_board.pop_front() {
                    self.board.receive(&f);
                }
            }
        }
        self.board.advance(100);
        let mut buf = [0u8; 1024];
        loop {
            let n = self.board.take_tx(&mut buf);
            if n == 0 {
                break;
            }
            self.board_partial.extend_from_slice(&buf[..n]);
        }
        let at = self.board.now_us + self.latency_us;
        while let Some(end) = self.board_partial.iter().position(|&b| b == 0) {
            let frame: Vec<u8> = self.board_partial.drain(..=end).collect();
            if frame == [0] {
                self.to_host.push_back((at, frame));
                continue;
            }
            self.stats.board_frames += 1;
            if self.connected {
                self.inject(frame, at, false);
            }
        }
        let now = self.board.now_us;
        while self.to_host.front().is_some_and(|(t, _)| *t <= now) {
            if let Some((_, f)) = self.to_host.pop_front() {
                self.host_rx.extend_from_slice(&f);
            }
        }
    }

    fn drop_connection(&mut self) {
        self.connected = false;
        self.stats.disconnects += 1;
        self.to_board.clear();
        self.to_host.clear();
        self.held_to_board = None;
        self.held_to_host = None;
        self.host_rx.clear();
        self.board_partial.clear();
        self.board.disconnect();
    }
}

impl Transport for MemLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        if !self.connected {
            return Err(LinkError::Disconnected);
        }
        let planned = self.disconnect_at == Some(self.stats.host_frames);
        if planned {
            self.disconnect_at = None;
        }
        if planned || self.chance(self.faults.disconnect) {
            self.drop_connection();
            return Err(LinkError::Disconnected);
        }
        if self.chance(self.faults.stall) {
            self.stats.stalls += 1;
            self.stalled_until = self.board.now_us + self.faults.stall_ms * 1000;
        }
        let at = self.board.now_us + self.latency_us;
        for frame in bytes.split_inclusive(|&b| b == 0) {
            if frame == [0] {
                // The leading delimiter of the next frame.
                self.to_board.push_back((at, vec![0]));
                continue;
            }
            self.stats.host_frames += 1;
            if self.dead_after.is_some_and(|n| self.stats.host_frames > n) {
                self.stats.dropped += 1;
                continue;
            }
            self.inject(frame.to_vec(), at, true);
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let deadline = self.board.now_us + timeout.as_micros() as u64;
        loop {
            if !self.connected {
                return Err(LinkError::Disconnected);
            }
            if !self.host_rx.is_empty() {
                let n = buf.len().min(self.host_rx.len());
                buf[..n].copy_from_slice(&self.host_rx[..n]);
                self.host_rx.drain(..n);
                return Ok(n);
            }
            if self.board.now_us >= deadline {
                return Ok(0);
            }
            self.step();
        }
    }

    fn now(&self) -> Duration {
        Duration::from_micros(self.board.now_us)
    }

    fn sleep(&mut self, d: Duration) {
        let end = self.board.now_us + d.as_micros() as u64;
        while self.board.now_us < end {
            self.step();
        }
    }

    fn reconnect(&mut self) -> Result<(), LinkError> {
        // Re-enumeration takes a while on a real bus.
        self.connected = true;
        self.sleep(Duration::from_millis(50));
        Ok(())
    }
}
