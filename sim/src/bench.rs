//! Simulation speed figures: simulated seconds per wall second on the 10 000-segment
//! chessboard job, executor alone and with the reference plant. Printed by
//! `cargo bench -p dollop-sim` and `dollop bench`; never asserted in tests.

use crate::designs::{boustrophedon, chessboard, Fill, Job};
use crate::{run, RunOptions};
use dollop::Config;
use std::time::Instant;

/// The benchmark job: a chessboard of 0.5 mm squares, 24 mm x 20 rows, 11 layers
/// (10 770 print segments, about 870 s of printing).
pub fn ten_thousand_segment_job() -> Job {
    let f = Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 24.0,
        rows: 20,
        pitch_mm: 0.8,
        layers: 11,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 12.0,
    };
    boustrophedon(&f, chessboard(0.5))
}

/// One measured run.
#[derive(Clone, Copy, Debug)]
pub struct Speed {
    /// Print segments.
    pub segments: usize,
    /// Simulated print time, s.
    pub simulated_s: f64,
    /// Wall time, s.
    pub wall_s: f64,
}

impl Speed {
    /// Simulated seconds per wall second.
    pub fn factor(&self) -> f64 {
        self.simulated_s / self.wall_s
    }
}

/// Runs `job` on `config` and times it (one thread).
pub fn measure(config: &Config, job: &Job, plant: bool) -> Result<Speed, crate::SimError> {
    let opts = RunOptions {
        plant,
        ..Default::default()
    };
    let t = Instant::now();
    let r = run::<f32>(config, job, &opts, |_| {})?;
    Ok(Speed {
        segments: r.segments,
        simulated_s: r.time_s,
        wall_s: t.elapsed().as_secs_f64(),
    })
}

/// The figures as text, one line each.
pub fn report(config: &Config) -> Result<String, crate::SimError> {
    let job = ten_thousand_segment_job();
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let exec = measure(config, &job, false)?;
    let plant = measure(config, &job, true)?;
    Ok(format!(
        "simulation, {} segments ({:.0} s of printing), one thread of {cores} cores:\n  \
         executor alone: {:.2} s wall, {:.0}x real time (goal >= 500x)\n  \
         executor + reference plant: {:.2} s wall, {:.0}x real time\n",
        exec.segments,
        exec.simulated_s,
        exec.wall_s,
        exec.factor(),
        plant.wall_s,
        plant.factor()
    ))
}
