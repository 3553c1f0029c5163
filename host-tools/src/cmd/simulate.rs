//! `dollop simulate`: runs a job through the same executor the firmware runs, in virtual
//! time, metered by the reference plant (or the executor's own model); writes the CSV
//! trace and the plate heatmap and prints the report. Slicing and file formats are the
//! slicer's; the physics and the metrics are `dollop-sim`'s.

use crate::slicer::{self, output};
use anyhow::Context;
use dollop::config::Config;
use dollop::RunState;
use dollop_sim::metrics::Boundary;
use dollop_sim::{Job, PausePlan, RunOptions, RunResult};
use std::io::Write;
use std::path::{Path, PathBuf};

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

/// What `simulate_job` should produce besides the result.
pub struct Outputs<'a> {
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
    out: Outputs<'_>,
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
    let Outputs {
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

/// The report, as printed.
pub fn report_text(
    r: &RunResult,
    config: &Config,
    plant: bool,
    wall: std::time::Duration,
) -> String {
    let m = &r.metrics;
    let limit = config.motion.max_step_rate_hz;
    let mut s = String::new();
    s.push_str(&format!(
        "state             {:?}{}\n",
        r.state,
        r.fault.map(|f| format!(": {f}")).unwrap_or_default()
    ));
    s.push_str(&format!(
        "print time        {:.1} s ({} print segments; simulated in {:.2?})\n",
        r.time_s, r.segments, wall
    ));
    s.push_str(&format!("material switches {}\n", r.switches));
    if m.boundaries.is_empty() {
        // A worst of nothing is no figure: say there was nothing to measure.
        s.push_str("boundaries        none measured\n");
    } else {
        s.push_str(&format!(
            "boundaries        {} measured, worst {:.4} mm from the design along the path\n",
            m.boundaries.len(),
            m.worst_boundary()
        ));
    }
    for line in m.mismatches.iter().take(3) {
        s.push_str(&format!("  material sequence differs: {line}\n"));
    }
    if m.mismatches.len() > 3 {
        s.push_str(&format!(
            "  ... and {} more differences\n",
            m.mismatches.len() - 3
        ));
    }
    s.push_str(&format!(
        "bead section      {:.4} .. {:.4} of S = {:.3} mm^2 (over every 0.02 mm of bead)\n",
        m.section_range.0, m.section_range.1, r.bead_area
    ));
    let bounds = Bounds::of(config);
    let bound = bounds.section;
    s.push_str(&format!(
        "section 0.2 mm    {:.4} .. {:.4} of S over every {} mm of bead (bound: within {:.2} %)\n",
        m.section_long_range.0,
        m.section_long_range.1,
        dollop::config::SECTION_WINDOW_MM,
        bound * 100.0
    ));
    let (b, bl) = (m.section_band(false), m.section_band(true));
    s.push_str(&format!(
        "section band      p99 - p1 {:.4} over 0.02 mm ({:.4} .. {:.4}), {:.4} over 0.2 mm\n",
        b.1 - b.0,
        b.0,
        b.1,
        bl.1 - bl.0
    ));
    s.push_str(&format!(
        "axis accel        X {:.0}, Y {:.0} mm/s^2 at most while a valve is open (1 ms differences; limits X {}, Y {})\n",
        r.axis_accel[0], r.axis_accel[1], config.motion.max_accel_mm_s2[0], config.motion.max_accel_mm_s2[1]
    ));
    s.push_str(&format!(
        "peak step rate    X {:.0}, Y {:.0}, Z {:.0} steps/s (drivers take {:.0})\n",
        r.peak_step_rate[0], r.peak_step_rate[1], r.peak_step_rate[2], limit
    ));
    s.push_str(&format!(
        "corner accel      {:.0} mm/s^2 at most on beads\n",
        r.peak_accel
    ));
    s.push_str(&format!(
        "off the path      {:.4} mm^3 landed between beads\n",
        m.off_path_volume
    ));
    for w in warnings(r, config, &bounds) {
        s.push_str(&format!("WARNING: {w}\n"));
    }
    pause_lines(&mut s, r, &bounds);
    s.push_str(&format!(
        "metered by        {}\n",
        if plant {
            "the reference plant (independent f64 physics)"
        } else {
            "the executor's own flow model"
        }
    ));
    s
}

/// What the report holds a run to, from one validation of its config (a syringe
/// machine's walks its lag curves): the section bound over `SECTION_WINDOW_MM`
/// (`Machine::section_bound`: 1 %, or what its ramps through the flow's steps force) and
/// the machine's top flow (fastest bead speed times the section, mm^3/s). A config that
/// does not validate (the run would not have happened) gets 1 % and no top flow.
pub struct Bounds {
    section: f64,
    top_flow: f64,
}

impl Bounds {
    pub fn of(config: &Config) -> Self {
        match config.validate::<f64, { slicer::INLETS }>() {
            Ok(m) => Bounds {
                section: m.section_bound(),
                top_flow: m.v_flow_max * m.bead_area,
            },
            Err(_) => Bounds {
                section: dollop::config::SECTION_BAND,
                top_flow: 0.0,
            },
        }
    }
}

/// Slack on the X/Y acceleration limit for the measurement: 1 ms second differences of
/// an f32 position 50 mm from the origin carry a few mm/s^2 of rounding.
pub const ACCEL_SLACK: f64 = 1.02;

/// What left its bound, as sentences: the bead section over every
/// `SECTION_WINDOW_MM` of bead against `Machine::section_bound`, the corner acceleration
/// against the X/Y limit, and each axis's acceleration (1 ms differences while a valve is
/// open) against its limit. The report
/// prints each after `WARNING:`; the exit status stays 0 (as for a boundary far off:
/// a fault or a wrong material sequence is what fails a run).
pub fn warnings(r: &RunResult, config: &Config, bounds: &Bounds) -> Vec<String> {
    let mut w = Vec::new();
    let m = &r.metrics;
    let bound = bounds.section;
    let off = m.worst_section_long();
    if off > bound {
        w.push(format!(
            "the bead section leaves its bound: {:.2} % off over {} mm of bead (at x {:.2}, y {:.2} mm), bound {:.2} %",
            off * 100.0,
            dollop::config::SECTION_WINDOW_MM,
            m.section_long_worst_at[0],
            m.section_long_worst_at[1],
            bound * 100.0
        ));
    }
    let a_xy = config.motion.max_accel_mm_s2[0].min(config.motion.max_accel_mm_s2[1]) as f64;
    if r.peak_accel > a_xy * ACCEL_SLACK {
        w.push(format!(
            "a corner turns the head at {:.0} mm/s^2, over the X/Y limit of {a_xy} mm/s^2 (a fillet the segments leave too little room for, met at speed)",
            r.peak_accel
        ));
    }
    for (a, axis) in ["X", "Y"].iter().enumerate() {
        let limit = config.motion.max_accel_mm_s2[a] as f64;
        if r.axis_accel[a] > limit * ACCEL_SLACK {
            w.push(format!(
                "{axis} accelerates at {:.0} mm/s^2 (at {:.3} s), over its limit of {limit} mm/s^2",
                r.axis_accel[a], r.axis_accel_at[a]
            ));
        }
    }
    w
}

/// Runs `dollop simulate`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let config = slicer::load_config(&a.config)?;
    let (header, commands) = slicer::job_file::read_job(&a.job)?;
    let hash = dollop::job::config_hash(&config);
    if header.config_hash != hash {
        eprintln!(
            "dollop: note: {} was sliced for another config (hash {:08x}, {} has {:08x}); simulating anyway",
            a.job.display(),
            header.config_hash,
            a.config.display(),
            hash
        );
    }
    let job = Job {
        start_um: header.start_um,
        initial_material: header.initial_material,
        commands,
    };
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
    let job_name = a.job.display().to_string();
    let mut heat = a.heatmap.as_ref().map(|_| Heatmap::for_job(&job, &config));
    let plant = !a.model_only;
    let t = std::time::Instant::now();
    // Trace and heatmap are staged and renamed together at the end: an interrupted or
    // failed run leaves neither (Ctrl-C removes the temporary files).
    let mut staged = output::Outputs::new();
    let run_it = |out: Outputs<'_>| {
        simulate_job(&config, &job, plant, out).with_context(|| job_name.clone())
    };

    let result = match &a.trace {
        Some(path) => {
            let mut res = None;
            let mut failure = None;
            output::stage(&mut staged, path, |w| {
                match run_it(Outputs {
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
        None => run_it(Outputs {
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
    if a.report || (a.trace.is_none() && a.heatmap.is_none()) {
        print!("{}", report_text(&result, &config, plant, wall));
    } else {
        for w in warnings(&result, &config, &Bounds::of(&config)) {
            eprintln!("dollop: WARNING: {w}");
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

/// The report's lines for each pause: request, pause point, latencies, seam, flow.
fn pause_lines(s: &mut String, r: &RunResult, bounds: &Bounds) {
    let top = bounds.top_flow;
    let f = |t: Option<f64>| t.map_or("never".to_string(), |t| format!("{:.1} ms", t * 1e3));
    for (k, p) in r.pauses.iter().enumerate() {
        s.push_str(&format!(
            "pause {}           requested at {:.4} s, head at {:.3} mm along the print path\n",
            k + 1,
            p.t_request,
            p.s_request_mm
        ));
        s.push_str(&format!(
            "  pause point     {:.3} mm along the path ({:.3} mm on from the request{}), at ({:.3}, {:.3}) mm\n",
            p.s_point_mm,
            p.distance_mm(),
            if p.at_bead_end { ", at a bead's end" } else { ", mid-bead" },
            p.point_xy[0],
            p.point_xy[1]
        ));
        s.push_str(&format!(
            "  latency         valves shut (pins) {}, head at rest {}; resumed at {}\n",
            f(p.shut_latency()),
            f(p.rest_latency()),
            p.t_resume
                .map_or("never".to_string(), |t| format!("{t:.4} s"))
        ));
        if p.seam_measured {
            s.push_str(&format!(
                "  seam            longest uncovered gap {:.3} mm; section over 0.2 mm {:.3} .. {:.3} of S\n",
                p.seam_gap_mm, p.seam_section.0, p.seam_section.1
            ));
        } else {
            s.push_str("  seam            not measured (pause between beads, or job over)\n");
        }
        if let Some(k) = &p.park {
            park_lines(s, k);
        }
        let pct = |q: f64| {
            if q > 0.0 {
                100.0 * p.q_rested_max / q
            } else {
                0.0
            }
        };
        s.push_str(&format!(
            "  flow at rest    {:.4} mm^3/s at most: {:.3} % of the machine's top flow, {:.3} % of the flow at the request\n",
            p.q_rested_max,
            pct(top),
            pct(p.q_print)
        ));
    }
}

/// A parked pause's lines: the excursion and its times.
fn park_lines(s: &mut String, k: &dollop_sim::ParkRecord) {
    let t = |x: Option<f64>| x.map_or("never".to_string(), |x| format!("{x:.4} s"));
    s.push_str(&format!(
        "  park            left the pause point at {:.4} s, Z up {:.3} mm, to ({:.3}, {:.3}) mm by {} (plan), back on the point at {} ({:.3} s away)
",
        k.t_left,
        k.lift_mm,
        k.far_xy[0],
        k.far_xy[1],
        t(k.t_parked),
        t(k.t_back),
        k.t_back.map_or(0.0, |b| b - k.t_left)
    ));
    if k.refilled {
        s.push_str(&format!(
            "  refill          plungers retracted {} steps to the start of their fill, counting from 0 again
",
            k.retract_steps
        ));
    }
}

/// Material colours on the plate, by inlet: the same as the toolpath preview's.
pub const PALETTE: [[u8; 3]; 8] = slicer::preview::MATERIAL_COLOURS;

/// The plate as a picture: deposited material per cell, boundary errors as coloured dots.
pub struct Heatmap {
    x0: f64,
    y1: f64,
    px_per_mm: f64,
    img: image::RgbImage,
    radius: i64,
    last: Option<(i64, i64, u8)>,
}

/// Largest heatmap side, pixels.
const MAX_SIDE: f64 = 4000.0;

impl Heatmap {
    /// A blank plate covering the job's extent with a margin.
    pub fn for_job(job: &Job, config: &Config) -> Self {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut p = [job.start_um[0] as f64 * 1e-3, job.start_um[1] as f64 * 1e-3];
        let mut grow = |p: [f64; 2]| {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        };
        grow(p);
        for c in &job.commands {
            match *c {
                dollop::Command::Print { dx, dy, .. } => {
                    p[0] += dx as f64 * 1e-3;
                    p[1] += dy as f64 * 1e-3;
                }
                dollop::Command::Travel { x, y, .. } => p = [x as f64 * 1e-3, y as f64 * 1e-3],
                _ => {}
            }
            grow(p);
        }
        let margin = 2.0;
        let (w_mm, h_mm) = (hi[0] - lo[0] + 2.0 * margin, hi[1] - lo[1] + 2.0 * margin);
        let px_per_mm = (20.0f64).min(MAX_SIDE / w_mm.max(h_mm).max(1.0));
        let w = (w_mm * px_per_mm).ceil().max(1.0) as u32;
        let h = (h_mm * px_per_mm).ceil().max(1.0) as u32;
        let pitch = config.channel.line_pitch_mm as f64;
        Heatmap {
            x0: lo[0] - margin,
            y1: hi[1] + margin,
            px_per_mm,
            img: image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255])),
            radius: ((pitch * 0.5 * px_per_mm).round() as i64).max(1),
            last: None,
        }
    }

    fn to_px(&self, x: f64, y: f64) -> (i64, i64) {
        (
            ((x - self.x0) * self.px_per_mm).round() as i64,
            ((self.y1 - y) * self.px_per_mm).round() as i64,
        )
    }

    fn disk(&mut self, cx: i64, cy: i64, r: i64, colour: [u8; 3]) {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy > r * r {
                    continue;
                }
                let (x, y) = (cx + dx, cy + dy);
                if x >= 0
                    && y >= 0
                    && (x as u32) < self.img.width()
                    && (y as u32) < self.img.height()
                {
                    self.img.put_pixel(x as u32, y as u32, image::Rgb(colour));
                }
            }
        }
    }

    /// Paint bead of `material` where the head stands.
    pub fn paint(&mut self, x: f64, y: f64, material: u8) {
        let (px, py) = self.to_px(x, y);
        if self.last == Some((px, py, material)) {
            return;
        }
        self.last = Some((px, py, material));
        let colour = PALETTE[material as usize % PALETTE.len()];
        self.disk(px, py, self.radius, colour);
    }

    /// Dots for every boundary, coloured by its error along the path.
    pub fn mark_boundaries(&mut self, boundaries: &[Boundary]) {
        let r = (self.radius / 2).max(2);
        for b in boundaries {
            let (px, py) = self.to_px(b.point[0], b.point[1]);
            self.disk(px, py, r + 1, [0, 0, 0]);
            self.disk(px, py, r, error_colour(b.error().abs()));
        }
        // Legend: the error scale from 0 (left) to 0.05 mm (right) along the top edge.
        let w = (self.img.width() / 3).max(10);
        for x in 0..w.min(self.img.width()) {
            let c = error_colour(0.05 * x as f64 / w as f64);
            for y in 0..6.min(self.img.height()) {
                self.img.put_pixel(x, y, image::Rgb(c));
            }
        }
    }

    /// Writes the PNG atomically.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let mut staged = output::Outputs::new();
        self.stage(&mut staged, path)?;
        output::commit(staged)?;
        Ok(())
    }

    /// Stages the PNG in `staged` (renamed into place when it is committed).
    pub fn stage(&self, staged: &mut output::Outputs, path: &Path) -> anyhow::Result<()> {
        use image::ImageEncoder;
        output::stage(staged, path, |w| {
            image::codecs::png::PngEncoder::new(w)
                .write_image(
                    self.img.as_raw(),
                    self.img.width(),
                    self.img.height(),
                    image::ExtendedColorType::Rgb8,
                )
                .map_err(std::io::Error::other)
        })?;
        Ok(())
    }

    /// The picture.
    pub fn image(&self) -> &image::RgbImage {
        &self.img
    }
}

/// Green at 0, yellow at 0.025 mm, red at 0.05 mm and beyond.
fn error_colour(e: f64) -> [u8; 3] {
    let f = (e / 0.05).clamp(0.0, 1.0);
    if f < 0.5 {
        [(510.0 * f) as u8, 190, 40]
    } else {
        [255, (190.0 * (1.0 - f) * 2.0) as u8, 40]
    }
}
