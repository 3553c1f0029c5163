//! G-code from the executor's own run of a job. The job goes through the executor the
//! firmware runs (f32, in virtual time, on its own flow model); its head positions, speeds
//! and valve commands are sampled into straight moves of at most 0.25 mm, each at the mean
//! speed the executor moved along it, with the valves switched between moves where the
//! executor switched them and dwells where it stood. Valve dead time, pressure rise and
//! decay, the speed law and the corner fillets therefore carry over to any firmware that
//! runs the moves at their feed rates. The words of each dialect are `gcode_dialect`'s;
//! judging the result is `gcode_judge`'s.

use super::error::SliceError;
use super::gcode::{self, GcodeStats};
use super::gcode_dialect::{self, Dialect};
use super::gcode_ramps;
pub use super::gcode_step::Step;
use dollop::config::Config;
use dollop::{Command, Real, RunState};
use dollop_sim::{Job, RunOptions};

/// How the executor's run is cut into moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// Longest print move, mm.
    pub max_move_mm: f64,
    /// Largest distance between the executor's path and a move's chord, mm (corner fillets
    /// become chords short enough that a junction-deviation planner takes them at speed).
    pub chord_tol_mm: f64,
    /// Largest relative change of the executor's speed within one move: the bead section
    /// then stays within about half of it of S while the speed follows the flow.
    pub speed_step: f64,
    /// Shortest move the speed rule may cut, mm (firmwares drop moves of a step or two).
    pub min_move_mm: f64,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            max_move_mm: 0.25,
            chord_tol_mm: 0.002,
            speed_step: 0.04,
            min_move_mm: 0.02,
        }
    }
}

/// Where the head is in the sampler's view.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Print,
    Travel,
}

/// The move being gathered from the executor's cycles.
struct Gather {
    start: [f64; 3],
    t_start: f64,
    v_start: f64,
    kind: Kind,
    /// Points along the way, about every `max_move_mm / 16`, for the chord check.
    pts: Vec<[f64; 3]>,
}

/// Cuts the executor's per-cycle trace into steps.
pub struct Sampler {
    opt: Sampling,
    travel_speed: f64,
    steps: Vec<Step>,
    last: [f64; 3],
    t_last: f64,
    valves: u32,
    stand_s: f64,
    cur: Option<Gather>,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Distance from `p` to the segment `a`-`b`.
fn off_chord(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / len2)
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]])
}

impl Sampler {
    /// A sampler with the head at `start` (mm) at time 0.
    pub fn new(opt: Sampling, start: [f64; 3], travel_speed: f64) -> Self {
        Sampler {
            opt,
            travel_speed,
            steps: Vec::new(),
            last: start,
            t_last: 0.0,
            valves: 0,
            stand_s: 0.0,
            cur: None,
        }
    }

    /// Ends the move in progress at the last point seen.
    fn flush(&mut self) {
        let Some(g) = self.cur.take() else { return };
        let len = dist(g.start, self.last);
        let dt = self.t_last - g.t_start;
        if len <= 0.0 {
            return;
        }
        let (v, travel) = match g.kind {
            // The firmware plans travel itself; the executor's trapezoid is the same shape.
            Kind::Travel => (self.travel_speed, true),
            Kind::Print => (len / dt.max(1e-9), false),
        };
        self.steps.push(Step::Move {
            to: self.last,
            v,
            travel,
        });
    }

    fn flush_stand(&mut self) {
        if self.stand_s > 0.0 {
            self.steps.push(Step::Dwell(self.stand_s));
            self.stand_s = 0.0;
        }
    }

    /// One control cycle of `dt_s` that began at `t_s` with the valves as `valves` (set at
    /// the cycle's start) and ended with the head at `pos`, moving at `speed` along a bead.
    pub fn cycle(
        &mut self,
        t_s: f64,
        dt_s: f64,
        pos: [f64; 3],
        speed: f64,
        valves: u32,
        state: RunState,
    ) {
        if valves != self.valves {
            self.flush();
            self.flush_stand();
            self.steps.push(Step::Valves(valves));
            self.valves = valves;
        }
        let t_end = t_s + dt_s;
        let d = dist(pos, self.last);
        if d == 0.0 {
            // Standing (or slower than the f32 position resolves; the move then resumes
            // from here).
            self.flush();
            self.stand_s += dt_s;
            self.t_last = t_end;
            return;
        }
        self.flush_stand();
        let kind = if state == RunState::Travelling {
            Kind::Travel
        } else {
            Kind::Print
        };
        if let Some(g) = &self.cur {
            let cut = g.kind != kind
                || (kind == Kind::Print && {
                    let len = dist(g.start, pos);
                    let moved = dist(g.start, self.last);
                    len > self.opt.max_move_mm
                        || g.pts
                            .iter()
                            .chain(std::iter::once(&self.last))
                            .any(|&p| off_chord(p, g.start, pos) > self.opt.chord_tol_mm)
                        || (moved >= self.opt.min_move_mm
                            && (speed - g.v_start).abs()
                                > self.opt.speed_step * speed.max(g.v_start))
                });
            if cut {
                self.flush();
            }
        }
        let last = self.last;
        let t_last = self.t_last;
        let g = self.cur.get_or_insert_with(|| Gather {
            start: last,
            t_start: t_last,
            v_start: speed,
            kind,
            pts: Vec::new(),
        });
        let spacing = self.opt.max_move_mm / 16.0;
        let far = g.pts.last().map_or(dist(g.start, pos), |&p| dist(p, pos));
        if far >= spacing {
            g.pts.push(pos);
        }
        self.last = pos;
        self.t_last = t_end;
    }

    /// Ends the run and returns the steps.
    pub fn finish(mut self) -> Vec<Step> {
        self.flush();
        self.flush_stand();
        self.steps
    }
}

/// Runs `commands` through the executor on `config` and samples its run into steps.
/// Refuses a job naming a material the machine has no inlet for, and a job the executor
/// faults on (the fault named).
pub fn sample_run(
    config: &Config,
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
    opt: Sampling,
    progress: &mut dyn FnMut(u64),
) -> Result<Vec<Step>, SliceError> {
    gcode::check_materials(commands, initial, config.inlets.len())?;
    let mut cmds = commands.to_vec();
    if cmds.last() != Some(&Command::End) {
        cmds.push(Command::End);
    }
    let job = Job {
        start_um,
        initial_material: initial,
        commands: cmds,
    };
    let start = start_um.map(|v| v as f64 * 1e-3);
    let dt = 1.0 / config.control.rate_hz.max(1) as f64;
    let mut sampler = Sampler::new(opt, start, config.motion.travel_speed_mm_s as f64);
    let opts = RunOptions {
        plant: false,
        head_ramps: false,
        ..RunOptions::default()
    };
    let mut cycle = 0u64;
    let result = dollop_sim::run::<f32>(config, &job, &opts, |c| {
        // Every 0.1 s of the executor's time: often enough for a bar, rare enough to cost
        // nothing.
        if cycle.is_multiple_of(1000) {
            progress(c.report.command_index as u64);
        }
        cycle += 1;
        let p = c.report.position.map(|v| v.to_f64());
        sampler.cycle(
            c.t_s,
            dt,
            p,
            c.report.speed.to_f64(),
            c.outputs.valves,
            c.report.state,
        );
    })
    .map_err(|reason| SliceError::ExecutorRun { reason })?;
    if let Some(fault) = result.fault {
        return Err(SliceError::ExecutorFault { fault });
    }
    Ok(sampler.finish())
}

/// Options of the export from the executor's run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunExport {
    /// How the run is cut into moves.
    pub sampling: Sampling,
    /// The dialect written.
    pub dialect: Dialect,
    /// Refuse a job whose G-code would be larger, bytes (checked from the job before the
    /// executor runs, and on the text written).
    pub max_bytes: u64,
    /// The user's start and end G-code.
    pub host: gcode_dialect::HostText,
}

/// Default size limit of the G-code, bytes: 1 GiB, about 1.5 million print segments of
/// the bundled designs, a day of printing. The text is built in memory, several times its
/// size on the way.
pub const DEFAULT_MAX_BYTES: u64 = 1 << 30;

impl Default for RunExport {
    fn default() -> Self {
        RunExport {
            sampling: Sampling::default(),
            dialect: Dialect::default(),
            max_bytes: DEFAULT_MAX_BYTES,
            host: gcode_dialect::HostText::default(),
        }
    }
}

/// Fewest bytes a move takes in any dialect (`G1 X1.2345 Y1.2345\n`, with one coordinate
/// changing the line is shorter, but a bead's moves change X and Y or carry a feed).
const MIN_MOVE_BYTES: u64 = 14;

/// A lower bound of the G-code's size, bytes: every print move is at most
/// `max_move_mm` long, so the print path needs at least its length over that many moves.
pub fn min_bytes(commands: &[Command], max_move_mm: f64) -> u64 {
    let mut len_um = 0.0f64;
    let mut moves = 0u64;
    for c in commands {
        match *c {
            Command::Print { dx, dy, .. } => {
                len_um += (dx as f64).hypot(dy as f64);
                moves += 1;
            }
            Command::Travel { .. } | Command::Layer { .. } => moves += 1,
            Command::Dwell { .. } | Command::End | Command::Section { .. } => {}
        }
    }
    let cut = (len_um * 1e-3 / max_move_mm.max(1e-3)).ceil() as u64;
    cut.max(moves).saturating_mul(MIN_MOVE_BYTES)
}

fn too_large(bytes: u64, limit: u64, what: &str) -> SliceError {
    SliceError::GcodeTooLarge {
        what: what.to_string(),
        bytes,
        limit,
    }
}

/// Exports a job as G-code from the executor's run on `config` (see the module's doc).
pub fn export(
    config: &Config,
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
    material_names: &[String],
    opt: &RunExport,
) -> Result<(String, GcodeStats), SliceError> {
    export_with_progress(
        config,
        commands,
        start_um,
        initial,
        material_names,
        opt,
        &mut |_| {},
    )
}

/// [`export`], calling `progress` with the number of the job's commands done as the
/// executor runs through them (the run is nearly all of the time).
pub fn export_with_progress(
    config: &Config,
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
    material_names: &[String],
    opt: &RunExport,
    progress: &mut dyn FnMut(u64),
) -> Result<(String, GcodeStats), SliceError> {
    let least = min_bytes(commands, opt.sampling.max_move_mm);
    if least > opt.max_bytes {
        return Err(too_large(
            least,
            opt.max_bytes,
            "this job's would be at least",
        ));
    }
    let sampled = sample_run(config, commands, start_um, initial, opt.sampling, progress)?;
    let start = start_um.map(|v| v as f64 * 1e-3);
    let accel = config.motion.max_accel_mm_s2.map(|a| a as f64);
    // Each pass's input is dropped as soon as the next exists: a long job's steps run to
    // hundreds of megabytes, and a shadowed binding would keep all three alive.
    let centred = gcode_ramps::centre_jumps(&sampled, start, accel);
    drop(sampled);
    let steps = gcode_ramps::run_ups(&centred, start, accel);
    drop(centred);
    let (text, stats) = gcode_dialect::write(
        &steps,
        start,
        config,
        material_names,
        &opt.dialect,
        &opt.host,
    );
    if text.len() as u64 > opt.max_bytes {
        return Err(too_large(text.len() as u64, opt.max_bytes, "this job's is"));
    }
    Ok((text, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fillet_is_cut_into_chords_and_speed_changes_into_moves() {
        let opt = Sampling::default();
        let mut s = Sampler::new(opt, [0.0, 0.0, 1.0], 50.0);
        let dt = 1e-3;
        let mut t = 0.0;
        // A quarter circle of radius 1 mm at 10 mm/s, valve open.
        let n = 157;
        for i in 1..=n {
            let a = std::f64::consts::FRAC_PI_2 * i as f64 / n as f64;
            let p = [a.sin(), 1.0 - a.cos(), 1.0];
            s.cycle(t, dt, p, 10.0, 1, RunState::Printing);
            t += dt;
        }
        let steps = s.finish();
        assert_eq!(steps[0], Step::Valves(1));
        let mut from = [0.0, 0.0, 1.0];
        let mut moves = 0;
        for st in &steps[1..] {
            let Step::Move { to, v, travel } = *st else {
                panic!("{st:?}")
            };
            assert!(!travel);
            // A chord of a 1 mm circle within 2 um is at most sqrt(8 * 0.002) = 0.126 mm.
            let len = dist(from, to);
            assert!(len <= 0.127, "{len}");
            // Each move's feed is its length over the executor's time: chords are a
            // little shorter than the arc.
            assert!(v > 9.9 && v <= 10.01, "{v}");
            from = to;
            moves += 1;
        }
        assert!(moves >= 13, "{moves}");
        // A speed ramp is cut where the speed has changed by 4 %.
        let mut s = Sampler::new(opt, [0.0, 0.0, 1.0], 50.0);
        let mut x = 0.0;
        for i in 0..200 {
            let v = 5.0 + 0.05 * i as f64;
            x += v * dt;
            s.cycle(i as f64 * dt, dt, [x, 0.0, 1.0], v, 1, RunState::Printing);
        }
        let moves: Vec<f64> = s
            .finish()
            .iter()
            .filter_map(|st| match st {
                Step::Move { v, .. } => Some(*v),
                _ => None,
            })
            .collect();
        assert!(moves.len() >= 10, "{moves:?}");
        for w in moves.windows(2) {
            assert!(w[1] > w[0] && w[1] / w[0] < 1.06, "{moves:?}");
        }
    }

    #[test]
    fn standing_becomes_a_dwell_and_valves_split_moves() {
        let mut s = Sampler::new(Sampling::default(), [0.0; 3], 50.0);
        let dt = 1e-4;
        for i in 0..100 {
            s.cycle(i as f64 * dt, dt, [0.0; 3], 0.0, 1, RunState::Printing);
        }
        for i in 0..100 {
            let x = (i + 1) as f64 * 1e-3;
            let v = if i < 50 { 1 } else { 2 };
            s.cycle(
                (100 + i) as f64 * dt,
                dt,
                [x, 0.0, 0.0],
                10.0,
                v,
                RunState::Printing,
            );
        }
        let steps = s.finish();
        assert_eq!(steps[0], Step::Valves(1));
        let Step::Dwell(d) = steps[1] else {
            panic!("{steps:?}")
        };
        assert!((d - 0.01).abs() < 1e-12);
        let Step::Move { to, .. } = steps[2] else {
            panic!("{steps:?}")
        };
        // The valve change at the start of cycle 50 happens where cycle 49 ended.
        assert!((to[0] - 0.05).abs() < 1e-12, "{steps:?}");
        assert_eq!(steps[3], Step::Valves(2));
    }

    #[test]
    fn a_job_over_the_size_limit_is_refused_before_or_after_the_run() {
        let config: Config = toml::from_str(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../configs/seed-paper-valves.toml"
            ))
            .unwrap(),
        )
        .unwrap();
        // 20 beads of 10 mm: at least 800 moves of at most 0.25 mm.
        let mut cmds = vec![Command::Travel {
            x: 90_000,
            y: 90_000,
            z: 800,
        }];
        for r in 0..20 {
            let dx = if r % 2 == 0 { 10_000 } else { -10_000 };
            cmds.push(Command::Print {
                dx,
                dy: 0,
                material: (r % 2) as u8,
            });
            cmds.push(Command::Print {
                dx: 0,
                dy: 800,
                material: (r % 2) as u8,
            });
        }
        cmds.push(Command::End);
        let least = min_bytes(&cmds, 0.25);
        assert!(
            (800 * MIN_MOVE_BYTES..900 * MIN_MOVE_BYTES).contains(&least),
            "{least}"
        );
        let run = |max_bytes: u64, calls: &mut u32| {
            let opt = RunExport {
                max_bytes,
                ..RunExport::default()
            };
            export_with_progress(
                &config,
                &cmds,
                [90_000, 90_000, 800],
                0,
                &[],
                &opt,
                &mut |_| *calls += 1,
            )
        };
        // Below the lower bound: refused at once, the executor never runs.
        let mut calls = 0;
        let e = run(least - 1, &mut calls).unwrap_err();
        assert!(
            matches!(&e, SliceError::GcodeTooLarge { what, .. } if what.contains("would be at least")),
            "{e}"
        );
        assert_eq!(calls, 0);
        // Above the bound but below the text: refused after the run.
        let mut calls = 0;
        let (text, _) = run(DEFAULT_MAX_BYTES, &mut calls).unwrap();
        assert!(
            calls > 0 && text.len() as u64 > least,
            "{} vs {least}",
            text.len()
        );
        let mut calls = 0;
        let e = run(text.len() as u64 - 1, &mut calls)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("this job's is") && e.contains("over the limit"),
            "{e}"
        );
        assert!(run(text.len() as u64, &mut calls).is_ok());
    }
}
