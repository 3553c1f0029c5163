//! Simulation for the dashboard: runs a sliced job through the firmware's executor and the
//! reference plant (`dollop_sim::run`, as `dollop simulate` does) on a worker thread,
//! publishing its progress, and keeps what the pages show: the report text, the plate
//! heatmap, the CSV trace, and time series (head speed, flow, line pressures, valves)
//! thinned to a size a browser plots at once.

use crate::simulate::{report_text, section_floor, Bounds, Heatmap};
use dollop::config::Config;
use dollop::RunState;
use dollop_sim::{Job, PausePlan, RunOptions};
use serde::Serialize;
use std::io::{BufWriter, Write};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

/// Samples kept for the plots; past this the series is halved and sampled half as often.
const MAX_SAMPLES: usize = 8_000;

/// The time series the plots draw (columns of equal length).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Series {
    /// Time, s.
    pub t: Vec<f32>,
    /// Head speed along the path, mm/s.
    pub speed: Vec<f32>,
    /// Flow at the nozzle, mm³/s.
    pub flow: Vec<f32>,
    /// Line pressure per inlet, kPa (the reference plant's).
    pub pressure: Vec<Vec<f32>>,
    /// Valves commanded open, bit per inlet.
    pub valves: Vec<u32>,
    /// Material names, by inlet.
    pub materials: Vec<String>,
}

/// What a finished simulation leaves.
pub struct Outcome {
    /// The report as `dollop simulate` prints it.
    pub report: String,
    /// Short figures for the page.
    pub figures: SimFigures,
    /// The plots' data.
    pub series: Series,
    /// The plate heatmap, PNG.
    pub heatmap_png: Vec<u8>,
    /// The CSV trace (`t_s,x_mm,y_mm,z_mm,valve_mask`), kept in a temporary file.
    pub trace: tempfile::NamedTempFile,
}

/// Short figures of a finished simulation.
#[derive(Debug, Clone, Serialize)]
pub struct SimFigures {
    /// Simulated print time, s.
    pub time_s: f64,
    /// Material switches.
    pub switches: u64,
    /// Boundaries measured.
    pub boundaries: usize,
    /// Worst boundary error, mm (None: none measured).
    pub worst_boundary_mm: Option<f64>,
    /// Final state, in words.
    pub state: String,
    /// A fault, in plain words.
    pub fault: Option<String>,
    /// Material-sequence differences from the design.
    pub mismatches: usize,
}

/// Where a simulation is.
pub enum SimState {
    /// Running.
    Running,
    /// Finished (whatever its verdict).
    Done(Arc<Outcome>),
    /// Could not run.
    Failed(String),
}

/// One simulation run, shared between its worker and the handlers.
pub struct SimRun {
    /// Progress in thousandths of the job's commands.
    pub permille: AtomicU32,
    /// Its state.
    pub state: Mutex<SimState>,
}

impl SimRun {
    /// A run not started yet.
    pub fn new() -> Self {
        SimRun {
            permille: AtomicU32::new(0),
            state: Mutex::new(SimState::Running),
        }
    }

    /// The outcome, if finished; the failure message if it failed.
    pub fn outcome(&self) -> Result<Option<Arc<Outcome>>, String> {
        match &*self.state.lock().unwrap_or_else(|e| e.into_inner()) {
            SimState::Running => Ok(None),
            SimState::Done(o) => Ok(Some(o.clone())),
            SimState::Failed(m) => Err(m.clone()),
        }
    }
}

impl Default for SimRun {
    fn default() -> Self {
        Self::new()
    }
}

/// Runs the simulation (blocking) and stores the outcome in `run`.
pub fn simulate(run: &SimRun, config: &Config, job: &Job) {
    let result = simulate_inner(run, config, job);
    let mut st = run.state.lock().unwrap_or_else(|e| e.into_inner());
    *st = match result {
        Ok(o) => SimState::Done(Arc::new(o)),
        Err(e) => SimState::Failed(e),
    };
    run.permille.store(1000, Ordering::Relaxed);
}

fn simulate_inner(run: &SimRun, config: &Config, job: &Job) -> Result<Outcome, String> {
    let machine = config
        .validate::<f64, { crate::slicer::INLETS }>()
        .map_err(|e| format!("config: {e}"))?;
    let period_us = machine.period_us as u64;
    let every = (1000 / period_us).max(1);
    let inlets = config.inlets.len();
    let trace =
        tempfile::NamedTempFile::new().map_err(|e| format!("cannot create the trace file: {e}"))?;
    let mut w = BufWriter::new(trace.as_file());
    let mut io_error = writeln!(w, "t_s,x_mm,y_mm,z_mm,valve_mask").err();
    let mut heat = Heatmap::for_job(job, config);
    let mut series = Series {
        pressure: vec![Vec::new(); inlets],
        materials: crate::slicer::material_names(config),
        ..Default::default()
    };
    // Sampled every `sample_every` cycles, doubling whenever the series fills up.
    let mut sample_every = every * 10;
    let mut cycle = 0u64;
    let mut last_mask = u32::MAX;
    let total = job.commands.len().max(1) as u64;
    let t0 = std::time::Instant::now();
    let opts = RunOptions {
        plant: true,
        ..Default::default()
    };
    let result = dollop_sim::run::<f32>(config, job, &opts, |c| {
        let r = c.report;
        if io_error.is_none() && (cycle.is_multiple_of(every) || r.valves != last_mask) {
            io_error = writeln!(
                w,
                "{:.4},{:.4},{:.4},{:.4},{}",
                c.t_s, r.position[0], r.position[1], r.position[2], r.valves
            )
            .err();
        }
        if cycle.is_multiple_of(sample_every) || r.valves != last_mask {
            series.t.push(c.t_s as f32);
            series.speed.push(r.speed);
            series.flow.push(r.q);
            for (i, p) in series.pressure.iter_mut().enumerate() {
                let pa = c.plant.and_then(|pl| pl.line_pa(i)).unwrap_or(f64::NAN);
                p.push((pa * 1e-3) as f32);
            }
            series.valves.push(r.valves);
            if series.t.len() >= MAX_SAMPLES {
                thin(&mut series);
                sample_every *= 2;
            }
        }
        last_mask = r.valves;
        if c.landed_volume > 0.0 && matches!(r.state, RunState::Printing | RunState::Settling) {
            heat.paint(r.position[0] as f64, r.position[1] as f64, c.landing);
        }
        if cycle.is_multiple_of(1000) {
            run.permille.store(
                (r.command_index as u64 * 1000 / total).min(999) as u32,
                Ordering::Relaxed,
            );
        }
        cycle += 1;
    })
    .map_err(|e| e.to_string())?;
    if let Some(e) = io_error {
        return Err(format!("writing the trace: {e}"));
    }
    w.flush().map_err(|e| format!("writing the trace: {e}"))?;
    drop(w);
    heat.mark_boundaries(&result.metrics.boundaries);
    let png = crate::figure::png(&heat.figure()?)?;
    let m = &result.metrics;
    let figures = SimFigures {
        time_s: result.time_s,
        switches: result.switches,
        boundaries: m.boundaries.len(),
        worst_boundary_mm: (!m.boundaries.is_empty()).then(|| m.worst_boundary()),
        state: format!("{:?}", result.state),
        fault: result.fault.map(|f| f.to_string()),
        mismatches: m.mismatches.len(),
    };
    let mut report = report_text(&result, config, true, t0.elapsed());
    // Where the straight section leaves its bound: how near any head could come there
    // (`dollop simulate` prints the same line).
    let bound = Bounds::of(config).section;
    if let Some(f) = section_floor(config, job, &PausePlan::default(), true, &result, bound) {
        report.push_str(&f);
    }
    Ok(Outcome {
        report,
        figures,
        series,
        heatmap_png: png,
        trace,
    })
}

/// Keeps every other sample, and every sample where the valves change.
fn thin(s: &mut Series) {
    let keep: Vec<bool> = (0..s.t.len())
        .map(|i| i % 2 == 0 || (i > 0 && s.valves[i] != s.valves[i - 1]))
        .collect();
    fn sift<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
        let mut k = keep.iter();
        v.retain(|_| *k.next().unwrap_or(&true));
    }
    sift(&mut s.t, &keep);
    sift(&mut s.speed, &keep);
    sift(&mut s.flow, &keep);
    sift(&mut s.valves, &keep);
    for p in &mut s.pressure {
        sift(p, &keep);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dashboard's report carries the `section floor` line where the straight
    /// section leaves its bound, as `dollop simulate --report` does: 0.6 mm stripes on the
    /// soft real-valve machine at 500 mm/s^2.
    #[test]
    fn the_report_says_how_near_the_physics_allows() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/soft-real-valves.toml"
        );
        let text = std::fs::read_to_string(path).unwrap();
        let mut config: Config = toml::from_str(&text).unwrap();
        config.motion.max_accel_mm_s2[0] = 500.0;
        config.motion.max_accel_mm_s2[1] = 500.0;
        let job = dollop_sim::designs::short_stripes();
        let run = SimRun::new();
        let out = simulate_inner(&run, &config, &job).unwrap();
        assert!(
            out.report.contains("WARNING: the bead section"),
            "{}",
            out.report
        );
        let line = out
            .report
            .lines()
            .find(|l| l.starts_with("section floor"))
            .unwrap_or_else(|| panic!("no floor line:\n{}", out.report));
        assert!(line.contains("does better than"), "{line}");
    }
}
