//! `dollop simulate`: maps the command line onto the `simulate` library (runs a job in
//! virtual time, writes the CSV trace and the plate heatmap, prints the report), and its
//! errors onto the flag names.

use crate::simulate::{
    report_text, section_floor, simulate_job, warnings, Bounds, Heatmap, Recording,
};
use crate::slicer::{self, output};
use anyhow::Context;
use dollop_sim::{Job, PausePlan};
use std::path::PathBuf;

/// Arguments of `dollop simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Job file (.dlp) to run.
    pub job: PathBuf,
    /// Machine config (TOML) to run it on.
    #[arg(long)]
    pub config: PathBuf,
    /// Write a CSV trace `t_s,x_mm,y_mm,z_mm,valve_mask`: a row every millisecond of
    /// simulated time and one at every valve change (bit i: inlet i commanded open).
    #[arg(long, value_name = "TRACE.csv")]
    pub trace: Option<PathBuf>,
    /// Draw the plate: the material deposited in each cell, and every material boundary
    /// as a dot coloured by its error (green 0, yellow 0.025 mm, red 0.05 mm and beyond).
    #[arg(long, value_name = "OUT.png")]
    pub heatmap: Option<PathBuf>,
    /// Print the report: print time, material switches, worst boundary error, bead
    /// cross-section range, peak step rate per axis (printed anyway without other outputs).
    #[arg(long)]
    pub report: bool,
    /// Meter the executor's own flow model instead of the independent reference plant:
    /// faster, but it cannot disagree with the executor.
    #[arg(long)]
    pub model_only: bool,
    /// Give up (with an error) after this much simulated print time, s [default: no limit;
    /// long jobs show a progress bar on a terminal].
    #[arg(long, value_name = "S")]
    pub max_seconds: Option<f64>,
    /// Request a pause at each of these virtual times (s from the job's start); the
    /// report then gives, per pause, the pause point, the latencies and the seam. A time
    /// that falls while an earlier pause holds is requested right after its resume.
    #[arg(long, value_name = "T1,T2,...", value_delimiter = ',')]
    pub pause_at: Vec<f64>,
    /// Resume each pause this long after the head came to rest, s of virtual time.
    #[arg(long, value_name = "S", default_value_t = 1.0, requires = "pause_at")]
    pub pause_for: f64,
    /// Resume the pauses at these virtual times instead (s from the job's start, one per
    /// `--pause-at`; a pause still running out then resumes once its head rests): replays
    /// a board's pause, as the firmware-in-the-loop check does.
    #[arg(
        long,
        value_name = "T1,T2,...",
        value_delimiter = ',',
        requires = "pause_at"
    )]
    pub resume_at: Vec<f64>,
    /// Park each pause: once the head rests, lift Z and move to the config's park
    /// position (`[pause]`); the resume comes back, lowers and restarts the flow. The
    /// report adds the park moves and their times.
    #[arg(long, requires = "pause_at")]
    pub park: bool,
    /// With `--park` on a syringe machine: refill at the park position (plungers back to
    /// where their fill began, their count restarting there).
    #[arg(long, requires = "park")]
    pub refill: bool,
}

/// Runs `dollop simulate`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let config = slicer::load_config(&a.config)?;
    let job = load_job(&a, &config)?;
    let (max_seconds, plan) = limits_and_pauses(&a)?;
    let job_name = a.job.display().to_string();
    let mut heat = a.heatmap.as_ref().map(|_| Heatmap::for_job(&job, &config));
    let plant = !a.model_only;
    let t = std::time::Instant::now();
    // Trace and heatmap are staged and renamed together at the end: an interrupted or
    // failed run leaves neither (Ctrl-C removes the temporary files).
    let mut staged = output::StagedFiles::new();
    let run_it = |out: Recording<'_>| {
        simulate_job(&config, &job, plant, out).with_context(|| job_name.clone())
    };

    let result = match &a.trace {
        Some(path) => {
            let mut res = None;
            let mut failure = None;
            output::stage(&mut staged, path, |w| {
                match run_it(Recording {
                    trace: Some(w),
                    heatmap: heat.as_mut(),
                    progress: true,
                    max_seconds,
                    pauses: Some(&plan),
                }) {
                    Ok(r) => {
                        res = Some(r);
                        Ok(())
                    }
                    Err(e) => {
                        failure = Some(e);
                        Err(std::io::Error::other("simulation failed"))
                    }
                }
            })
            .map_err(|e| match failure.take() {
                Some(f) => f,
                None => anyhow::anyhow!("{e}"),
            })?;
            res.context("simulation produced no result")?
        }
        None => run_it(Recording {
            trace: None,
            heatmap: heat.as_mut(),
            progress: true,
            max_seconds,
            pauses: Some(&plan),
        })?,
    };
    let wall = t.elapsed();
    if let (Some(path), Some(h)) = (&a.heatmap, heat.as_mut()) {
        h.mark_boundaries(&result.metrics.boundaries);
        h.stage(&mut staged, path)?;
    }
    output::commit(staged)?;
    for path in [&a.trace, &a.heatmap].into_iter().flatten() {
        println!("wrote {}", path.display());
    }
    let bounds = Bounds::of(&config);
    let floor = || section_floor(&config, &job, &plan, plant, &result, bounds.section);
    if a.report || (a.trace.is_none() && a.heatmap.is_none()) {
        print!("{}", report_text(&result, &config, plant, wall));
        if let Some(f) = floor() {
            print!("{f}");
        }
    } else {
        for w in warnings(&result, &config, &bounds) {
            eprintln!("dollop: WARNING: {w}");
        }
        if let Some(f) = floor() {
            eprint!("{f}");
        }
    }
    if let Some(f) = result.fault {
        anyhow::bail!("{job_name}: the job ended in a fault: {f}");
    }
    if let Some(first) = result.metrics.mismatches.first() {
        anyhow::bail!(
            "{job_name}: the material sequence on the plate differs from the design ({} difference(s); first: {first})",
            result.metrics.mismatches.len()
        );
    }
    Ok(())
}

/// The job `a` names, with a note on stderr when it was sliced for another config than
/// `config`.
fn load_job(a: &Args, config: &dollop::config::Config) -> anyhow::Result<Job> {
    let (header, commands) = slicer::job_file::read_job(&a.job)?;
    let hash = dollop::job::config_hash(config);
    if header.config_hash != hash {
        eprintln!(
            "dollop: note: {} was sliced for another config (hash {:08x}, {} has {:08x}); simulating anyway",
            a.job.display(),
            header.config_hash,
            a.config.display(),
            hash
        );
    }
    Ok(Job {
        start_um: header.start_um,
        initial_material: header.initial_material,
        commands,
    })
}

/// `--max-seconds` (infinite when not given) and the pauses `--pause-at`, `--pause-for`,
/// `--resume-at`, `--park` and `--refill` ask for, each time checked.
fn limits_and_pauses(a: &Args) -> anyhow::Result<(f64, PausePlan)> {
    let max_seconds = match a.max_seconds {
        None => f64::INFINITY,
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => anyhow::bail!("--max-seconds {v} must be a number of seconds above 0"),
    };
    if let Some(bad) = a.pause_at.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        anyhow::bail!("--pause-at {bad}: each time must be a number of seconds, 0 or more");
    }
    if !(a.pause_for.is_finite() && a.pause_for >= 0.0) {
        anyhow::bail!(
            "--pause-for {}: must be a number of seconds, 0 or more",
            a.pause_for
        );
    }
    if let Some(bad) = a.resume_at.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        anyhow::bail!("--resume-at {bad}: each time must be a number of seconds, 0 or more");
    }
    if !a.resume_at.is_empty() && a.resume_at.len() != a.pause_at.len() {
        anyhow::bail!(
            "--resume-at gives {} times for {} --pause-at times; give one for each",
            a.resume_at.len(),
            a.pause_at.len()
        );
    }
    let mut plan = PausePlan::uniform(&a.pause_at, a.pause_for);
    plan.resume_at = a.resume_at.clone();
    plan.park = a.park;
    plan.refill = a.refill;
    Ok((max_seconds, plan))
}
