//! Simulating a job as the board would run it: the same executor the firmware runs, in
//! virtual time, metered by the reference plant (or the executor's own model), streaming
//! a CSV trace and painting the plate heatmap (`heatmap`), and the report's text
//! (`report`). No argument parsing and no flag names: `cmd::simulate` (the command line)
//! and `serve::simulate_page` (the dashboard) are the front ends. The physics and the metrics
//! are `dollop-sim`'s.

pub mod floor_note;
pub mod heatmap;
pub mod report;

pub use floor_note::section_floor;
pub use heatmap::{Heatmap, PALETTE};
pub use report::{report_text, warnings, Bounds, ACCEL_SLACK};

use crate::slicer::{self, output};
use anyhow::Context;
use dollop::config::Config;
use dollop::RunState;
use dollop_sim::{Job, PausePlan, RunOptions, RunResult};
use std::io::Write;

/// What a run records besides its result (trace rows, the plate heatmap, a progress bar)
/// and when it gives up: `simulate_job`'s `out`.
pub struct Recording<'a> {
    /// Trace rows go here.
    pub trace: Option<&'a mut dyn Write>,
    /// Paint the plate.
    pub heatmap: Option<&'a mut Heatmap>,
    /// Show a progress bar on a terminal.
    pub progress: bool,
    /// Simulated seconds after which the run gives up (infinite: none).
    pub max_seconds: f64,
    /// Pauses to request and resume (none: an empty plan).
    pub pauses: Option<&'a PausePlan>,
}

/// Runs `job` on `config`, streaming the trace and painting the heatmap.
pub fn simulate_job(
    config: &Config,
    job: &Job,
    plant: bool,
    out: Recording<'_>,
) -> anyhow::Result<RunResult> {
    let machine = config
        .validate::<f64, { slicer::INLETS }>()
        .map_err(|e| anyhow::anyhow!("config: {e}"))?;
    let period_us = machine.period_us as u64;
    // A trace row every millisecond (and at valve changes).
    let every = (1000 / period_us).max(1);
    let bar = if out.progress {
        output::progress(job.commands.len() as u64, "simulating")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let Recording {
        mut trace,
        mut heatmap,
        max_seconds,
        pauses,
        ..
    } = out;
    let no_pauses = PausePlan::default();
    let mut io_error: Option<std::io::Error> = None;
    if let Some(w) = trace.as_deref_mut() {
        if let Err(e) = writeln!(w, "t_s,x_mm,y_mm,z_mm,valve_mask") {
            io_error = Some(e);
        }
    }
    let mut cycle = 0u64;
    let mut last_mask = u32::MAX;
    let opts = RunOptions {
        plant,
        max_time_s: max_seconds,
        ..Default::default()
    };
    let plan = pauses.unwrap_or(&no_pauses);
    let result = dollop_sim::run_paused::<f32>(config, config, job, &opts, plan, |c| {
        let r = c.report;
        if let Some(w) = trace.as_deref_mut() {
            if io_error.is_none() && (cycle.is_multiple_of(every) || r.valves != last_mask) {
                if let Err(e) = writeln!(
                    w,
                    "{:.4},{:.4},{:.4},{:.4},{}",
                    c.t_s, r.position[0], r.position[1], r.position[2], r.valves
                ) {
                    io_error = Some(e);
                }
            }
        }
        last_mask = r.valves;
        if let Some(h) = heatmap.as_deref_mut() {
            if c.landed_volume > 0.0
                && matches!(
                    r.state,
                    RunState::Printing | RunState::Settling | RunState::Pausing | RunState::Paused
                )
            {
                h.paint(r.position[0] as f64, r.position[1] as f64, c.landing);
            }
        }
        if cycle.is_multiple_of(1000) {
            bar.set_position(r.command_index as u64);
        }
        cycle += 1;
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    bar.finish_and_clear();
    if let Some(e) = io_error {
        return Err(e).context("writing the trace");
    }
    Ok(result)
}
