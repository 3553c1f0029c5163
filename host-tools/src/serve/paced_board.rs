//! The dashboard's simulated board: the in-memory link to `dollop::device::SimBoard` (the
//! real board logic and executor, `link::MemLink`, no faults) with its virtual clock held
//! to the wall clock times a speed factor, so a print on it takes as long as on a printer
//! (or `speed` times less), and the reference plant of `dollop-sim` fed the board's valve
//! outputs as they change, so the flow and line pressures the page shows are the plant's
//! (what a printed part would get), not the executor's belief. Waiting on the link never
//! runs the board ahead of the wall clock's pace; the board's own motion happens as time
//! passes. Faults, pausing and the link's timing stay the board's and `MemLink`'s business.

use crate::link::{Faults, LinkError, MemLink, Transport};
use dollop::config::Config;
use dollop_sim::plant::Plant;
use std::time::{Duration, Instant};

/// The board runs in steps of one control period between looks at its valve outputs, so a
/// valve change reaches the plant at most this late (the job runner's own granularity).
const STEP: Duration = Duration::from_micros(100);

/// Plant integration step, s (the job runner's default; split further at valve events).
const PLANT_STEP_S: f64 = 1e-4;

/// The reference plant coupled to the board's outputs.
struct Coupled {
    plant: Plant,
    /// Board time at the plant's t = 0, us.
    t0_us: u64,
    /// Valve outputs last handed to the plant.
    valves: u32,
    inlets: usize,
}

/// What the plant shows now.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlantNow {
    /// Flow out of the nozzle, mm^3/s.
    pub q_mm3_s: f64,
    /// Pressure in each inlet's line, kPa (syringe inlets: 0).
    pub line_kpa: Vec<f64>,
}

/// A `MemLink` paced by the wall clock, with the reference plant on its valves.
pub struct PacedBoard {
    inner: MemLink,
    speed: f64,
    /// Wall time and board time at the last re-anchor.
    anchor: (Instant, Duration),
    plant: Option<Coupled>,
    /// Wall time each frame sent takes on its way (zero: none). Stands in for a slow link,
    /// so a test can catch an upload while it is under way.
    pub frame_delay: Duration,
}

impl PacedBoard {
    /// A freshly powered simulated board running `speed` times real time (no plant until
    /// a config is loaded: `set_plant`).
    pub fn new(speed: f64) -> Self {
        let inner = MemLink::new(Faults::default(), 1);
        let now = inner.now();
        PacedBoard {
            inner,
            speed,
            anchor: (Instant::now(), now),
            plant: None,
            frame_delay: Duration::ZERO,
        }
    }

    /// Couples a fresh plant built from `plant_config` (the machine as it really is; the
    /// dashboard passes the config it loaded on the board) with the channel full of
    /// `material` and the board's valve outputs as they stand.
    pub fn set_plant(&mut self, plant_config: &Config, material: u8) -> Result<(), String> {
        let plant = Plant::new(plant_config, material)
            .map_err(|e| format!("the reference plant refuses the config: {e}"))?;
        let mut c = Coupled {
            plant,
            t0_us: self.inner.board().now_us,
            valves: 0,
            inlets: plant_config.inlets.len(),
        };
        let v = self.inner.board().out.valves;
        c.command(v);
        self.plant = Some(c);
        Ok(())
    }

    /// The plant's flow and line pressures now (None before a config was loaded).
    pub fn plant_now(&self) -> Option<PlantNow> {
        self.plant.as_ref().map(|c| PlantNow {
            q_mm3_s: c.plant.q(),
            line_kpa: (0..c.inlets)
                .map(|i| c.plant.line_pa(i).unwrap_or(0.0) / 1e3)
                .collect(),
        })
    }

    /// Board time the wall clock says it should be.
    fn due(&self) -> Duration {
        self.anchor.1 + self.anchor.0.elapsed().mul_f64(self.speed)
    }

    /// Runs the board (and the plant with it) for at least `d` of board time, in whole
    /// control periods (as `MemLink::sleep` does: a part of one, even below the board
    /// clock's microsecond, runs a whole one, so every pass moves the clock).
    fn run_board(&mut self, d: Duration) {
        let end = self.inner.now() + d;
        while self.inner.now() < end {
            self.inner.sleep(STEP);
            self.couple();
        }
    }

    /// Advances the plant to the board's time, then hands it the valve outputs of the
    /// period that just ended (as `dollop_sim::run_with_plant` does each cycle).
    fn couple(&mut self) {
        let Some(c) = self.plant.as_mut() else {
            return;
        };
        let b = self.inner.board();
        let t = b.now_us.saturating_sub(c.t0_us) as f64 * 1e-6;
        c.plant.advance(t, PLANT_STEP_S);
        c.command(b.out.valves);
    }

    /// Runs the board up to the wall clock's time (at most a second of board time at once:
    /// after a stall the board does not race to catch up).
    pub fn catch_up(&mut self) {
        let due = self.due();
        let now = self.inner.now();
        if due > now {
            self.run_board((due - now).min(Duration::from_secs(1)));
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

impl Coupled {
    fn command(&mut self, valves: u32) {
        if valves == self.valves {
            return;
        }
        for i in 0..self.inlets {
            self.plant.command(i, valves & (1 << i) != 0);
        }
        self.valves = valves;
    }
}

impl Transport for PacedBoard {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        if !self.frame_delay.is_zero() {
            std::thread::sleep(self.frame_delay);
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        // Answers come in board time (fast); the board only runs ahead of the wall clock
        // while a reply is awaited, and `sleep` waits that back. One period at a time, so
        // the plant sees every valve change when it happens.
        let end = self.inner.now() + timeout;
        loop {
            let left = end.saturating_sub(self.inner.now());
            let n = self.inner.recv(buf, STEP)?;
            self.couple();
            if n > 0 || left <= STEP {
                return Ok(n);
            }
        }
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
                self.run_board(due.min(target) - now);
            } else {
                let wait = (now.min(target) - due)
                    .div_f64(self.speed)
                    .max(Duration::from_micros(200));
                std::thread::sleep(wait.min(Duration::from_millis(20)));
            }
        }
    }
    fn reconnect(&mut self) -> Result<(), LinkError> {
        self.inner.reconnect()?;
        self.couple();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plant_follows_the_boards_valves_in_board_time() {
        let cfg: Config = toml::from_str(crate::serve::design::BUNDLED[0].1).expect("config");
        let mut s = PacedBoard::new(1.0);
        assert_eq!(s.plant_now(), None);
        s.set_plant(&cfg, 0).expect("plant");
        let t0 = s.now();
        s.run_board(Duration::from_millis(1234));
        // Whole control periods, at least the time asked for.
        let ran = s.now() - t0;
        assert!(
            ran >= Duration::from_millis(1234) && ran < Duration::from_millis(1235),
            "{ran:?}"
        );
        let p = s.plant.as_ref().expect("coupled");
        assert!(
            (p.plant.time() - ran.as_secs_f64()).abs() < 1e-9,
            "{}",
            p.plant.time()
        );
        // No config on the board: its valves stay shut, and so the plant's.
        assert_eq!(s.plant_now().map(|p| p.q_mm3_s), Some(0.0));
    }
}
