//! The dashboard's simulated board: the in-memory link to `dollop::device::SimBoard` (the
//! real board logic and executor, `link::MemLink`, no faults) with its virtual clock held
//! to the wall clock times a speed factor, so a print on it takes as long as on a printer
//! (or `speed` times less). Waiting on the link never runs the board ahead of the wall
//! clock's pace; the board's own motion happens as time passes.

use crate::link::{Faults, LinkError, MemLink, Transport};
use std::time::{Duration, Instant};

/// A `MemLink` paced by the wall clock.
pub struct SimLink {
    inner: MemLink,
    speed: f64,
    /// Wall time and board time at the last re-anchor.
    anchor: (Instant, Duration),
}

impl SimLink {
    /// A freshly powered simulated board running `speed` times real time.
    pub fn new(speed: f64) -> Self {
        let inner = MemLink::new(Faults::default(), 1);
        let now = inner.now();
        SimLink {
            inner,
            speed,
            anchor: (Instant::now(), now),
        }
    }

    /// Board time the wall clock says it should be.
    fn due(&self) -> Duration {
        self.anchor.1 + self.anchor.0.elapsed().mul_f64(self.speed)
    }

    /// Runs the board up to the wall clock's time (at most a second of board time at once:
    /// after a stall the board does not race to catch up).
    pub fn catch_up(&mut self) {
        let due = self.due();
        let now = self.inner.now();
        if due > now {
            let step = (due - now).min(Duration::from_secs(1));
            self.inner.sleep(step);
        }
        if self.due() > self.inner.now() + Duration::from_secs(1) {
            self.anchor = (Instant::now(), self.inner.now());
        }
    }

    /// The simulated board.
    pub fn mem(&mut self) -> &mut MemLink {
        &mut self.inner
    }
}

impl Transport for SimLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        // Answers come in board time (fast); the board only runs ahead of the wall clock
        // while a reply is awaited, and `sleep` waits that back.
        self.inner.recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn sleep(&mut self, d: Duration) {
        let target = self.inner.now() + d;
        loop {
            let due = self.due();
            let now = self.inner.now();
            if now >= target {
                break;
            }
            if due > now {
                self.inner.sleep((due.min(target)) - now);
            } else {
                let wait = (now.min(target) - due)
                    .div_f64(self.speed)
                    .max(Duration::from_micros(200));
                std::thread::sleep(wait.min(Duration::from_millis(20)));
            }
        }
    }
    fn reconnect(&mut self) -> Result<(), LinkError> {
        self.inner.reconnect()
    }
}
