//! The job runner: drives the core's executor tick by tick in virtual time with recording
//! outputs, feeds its valve commands to the reference plant, and meters what lands where.
//! Writing traces or pictures is the caller's business (through the per-cycle callback).

use crate::designs::Job;
use crate::metrics::{CycleIn, Meter, Metrics};
use crate::pause::{Action, PausePlan, PauseRecord, Pauser, Seen};
use crate::plant::Plant;
use dollop::config::Config;
use dollop::executor::{ParkStage, PushError};
use dollop::{Executor, Fault, Real, RecordingOutputs, Report, RunState};

/// How to run.
#[derive(Clone, Copy, Debug)]
pub struct RunOptions {
    /// Run the reference plant alongside and meter its physics (slower). Without it the
    /// executor's own model is metered.
    pub plant: bool,
    /// Plant RK4 step, s (split further at valve events).
    pub plant_step_s: f64,
    /// Give up after this much simulated time, s (infinite: run until the job ends; the
    /// executor always ends a job, since every command finishes or faults).
    pub max_time_s: f64,
    /// Let the executor ramp the head's speed through flow steps (`Machine::ramp_cycles`),
    /// as the firmware does. Off, the head follows the flow as it is, jumps and all: what
    /// the G-code export samples, since a firmware's own planner ramps its moves at the
    /// full acceleration limit, and ramping twice would lay the paste twice as far off.
    pub head_ramps: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            plant: true,
            plant_step_s: 1e-4,
            max_time_s: f64::INFINITY,
            head_ramps: true,
        }
    }
}

/// Why a run could not happen at all.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The config does not validate.
    #[error("config: {0}")]
    Config(dollop::ConfigError),
    /// The job could not begin.
    #[error("job cannot begin: {0}")]
    Begin(Fault),
    /// Simulated time ran out before the job finished.
    #[error("job did not finish within {0} s of simulated time (raise --max-seconds)")]
    Timeout(f64),
}

/// One cycle as seen by an observer.
#[derive(Clone, Copy, Debug)]
pub struct Cycle<'a, R> {
    /// Simulated time, s.
    pub t_s: f64,
    /// The executor's report (or its fault).
    pub report: &'a Report<R>,
    /// What the outputs hold after the cycle.
    pub outputs: &'a RecordingOutputs,
    /// Volume the plant (or the model) landed this cycle, mm^3.
    pub landed_volume: f64,
    /// Material landing at the end of the cycle.
    pub landing: u8,
    /// The reference plant, when it meters the run (its line pressures, for plots).
    pub plant: Option<&'a Plant>,
}

/// The outcome of a run.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Simulated time from begin to the end (Done or fault), s.
    pub time_s: f64,
    /// Cycles run.
    pub cycles: u64,
    /// State at the end.
    pub state: RunState,
    /// The fault, if the run ended in one.
    pub fault: Option<Fault>,
    /// Outputs at the end.
    pub outputs: RecordingOutputs,
    /// Quality metrics (from the plant if it ran, else from the executor's model).
    pub metrics: Metrics,
    /// Valve changes commanded.
    pub valve_changes: u64,
    /// Material switches: a valve opened for another material than the last one opened.
    pub switches: u64,
    /// Highest step rate per axis (steps/s), over 2 ms windows.
    pub peak_step_rate: [f64; 3],
    /// Largest distance between the commanded step position and the planned position,
    /// in microsteps, over all cycles and axes.
    pub worst_step_error: f64,
    /// Largest centripetal acceleration on print moves, mm/s^2 (the head's speed over
    /// points 0.02 mm apart, squared, times the curvature through them).
    pub peak_accel: f64,
    /// Most material slugs in the channel and filament at once while printing.
    pub max_slugs: u8,
    /// Largest acceleration per axis (X, Y, Z) while a valve is open, mm/s^2: 1 ms central
    /// differences of the commanded head position (the step generator's target).
    pub axis_accel: [f64; 3],
    /// Where (s of simulated time) each axis's largest acceleration was measured.
    pub axis_accel_at: [f64; 3],
    /// Largest acceleration per axis over the whole run, travels and holds too, mm/s^2:
    /// the same differences, less what an f32 position's rounding can put in them (four
    /// of its units in the last place, 61 mm/s^2 at 130 mm from the origin), so that a
    /// number over the limit is the head's and not the arithmetic's. A travel's braking
    /// and a bead's first ramp meet with the valves still shut.
    pub axis_accel_moving: [f64; 3],
    /// Where (s) each axis's `axis_accel_moving` was measured.
    pub axis_accel_moving_at: [f64; 3],
    /// `axis_accel` less the same rounding: what the report's warning weighs. The
    /// random pattern with the food pastes at 500 mm/s^2 read X 511 there at x 115 mm,
    /// 481 without the rounding's 30.
    pub axis_accel_open_net: [f64; 3],
    /// Where (s) each axis's `axis_accel_open_net` was measured.
    pub axis_accel_open_net_at: [f64; 3],
    /// Bead section S, mm^2.
    pub bead_area: f64,
    /// Print segments in the job.
    pub segments: usize,
    /// The pauses of a [`run_paused`] run, in order.
    pub pauses: Vec<PauseRecord>,
}

/// Runs `job` on `config` with the executor computing in `R`, calling `observe` every
/// cycle.
pub fn run<R: Real>(
    config: &Config,
    job: &Job,
    opts: &RunOptions,
    observe: impl FnMut(&Cycle<'_, R>),
) -> Result<RunResult, SimError> {
    run_with_plant(config, config, job, opts, observe)
}

/// [`run`] with the plant built from `plant_config` instead: a machine whose physics
/// differ from what the executor was told (a channel longer than configured, a slower
/// valve, a thicker paste), as a miscalibrated printer prints.
pub fn run_with_plant<R: Real>(
    config: &Config,
    plant_config: &Config,
    job: &Job,
    opts: &RunOptions,
    observe: impl FnMut(&Cycle<'_, R>),
) -> Result<RunResult, SimError> {
    run_paused(
        config,
        plant_config,
        job,
        opts,
        &PausePlan::default(),
        observe,
    )
}

/// [`run_with_plant`] with pauses requested and resumed as `pauses` says; each one's
/// figures are in `RunResult::pauses`.
pub fn run_paused<R: Real>(
    config: &Config,
    plant_config: &Config,
    job: &Job,
    opts: &RunOptions,
    pauses: &PausePlan,
    mut observe: impl FnMut(&Cycle<'_, R>),
) -> Result<RunResult, SimError> {
    let mut run = Runner::new(config, plant_config, job, opts, pauses)?;
    // Saturates to u64::MAX for an infinite limit (and to 0 for a NaN one).
    let max_cycles = (opts.max_time_s / run.dt) as u64;
    loop {
        run.feed();
        let now = run.cycle * run.period_us;
        let t = now as f64 * 1e-6;
        let report = match run.exec.tick(now, &mut run.out) {
            Ok(r) => r,
            Err(_) => return Ok(run.faulted(now, t)),
        };
        let (landed_volume, landing) = run.land(&report, t);
        let head = run.meter_cycle(&report, landed_volume, landing);
        run.valves_changed();
        run.motion.cycle(run.cycle, &report, &run.out, &head, t);
        if !pauses.requests.is_empty() {
            run.steer_pauses(&report, &head, landed_volume, t);
        }
        observe(&Cycle {
            t_s: t,
            report: &report,
            outputs: &run.out,
            landed_volume,
            landing,
            plant: run.plant.as_ref(),
        });
        run.cycle += 1;
        if matches!(report.state, RunState::Done | RunState::Aborted) {
            return Ok(run.finish(report.state, None, t));
        }
        if run.cycle > max_cycles {
            return Err(SimError::Timeout(opts.max_time_s));
        }
    }
}

/// What one run's cycles share: the executor and its outputs, the plant, the meters, and
/// the figures gathered so far.
struct Runner<'a, R: Real> {
    config: &'a Config,
    job: &'a Job,
    opts: &'a RunOptions,
    pauses: &'a PausePlan,
    exec: Executor<R>,
    out: RecordingOutputs,
    plant: Option<Plant>,
    meter: Meter,
    pauser: Pauser,
    park_view: ParkView,
    refill: Refill,
    valves: ValveWatch,
    motion: Motion,
    period_us: u64,
    dt: f64,
    bead_area: f64,
    /// The next of the job's commands to push.
    next_cmd: usize,
    cycle: u64,
    /// Material landing at the start of the cycle.
    landing_prev: u8,
    /// This cycle's material changes as they landed (kept for its allocation).
    changes: Vec<(f64, u8)>,
}

/// Where the head is this cycle, as the meters and the pause steering see it.
struct Head {
    /// On a bead: laying it, or pausing or paused on it.
    printing: bool,
    /// The planned position, mm.
    raw: [f64; 3],
    /// Where the meters see the head: the pause point during a park.
    pos: [f64; 2],
    /// A park has the head off the pause point.
    off_point: bool,
}

impl<'a, R: Real> Runner<'a, R> {
    /// The executor begun on `job`, the plant (if `opts` asks for it) built from
    /// `plant_config`, nothing metered yet.
    fn new(
        config: &'a Config,
        plant_config: &Config,
        job: &'a Job,
        opts: &'a RunOptions,
        pauses: &'a PausePlan,
    ) -> Result<Self, SimError> {
        let mut machine = config
            .validate::<R, { dollop::DEFAULT_INLETS }>()
            .map_err(SimError::Config)?;
        if !opts.head_ramps {
            machine.ramp_cycles = 1;
        }
        let period_us = machine.period_us as u64;
        let dt = period_us as f64 * 1e-6;
        let spm: [f64; 3] = [
            machine.motion.steps_per_mm[0].to_f64(),
            machine.motion.steps_per_mm[1].to_f64(),
            machine.motion.steps_per_mm[2].to_f64(),
        ];
        let bead_area = machine.bead_area.to_f64();
        let pauser = Pauser::new(pauses, bead_area, machine.q_stop.to_f64() / bead_area);
        let mut meter = Meter::new(&job.commands, job.start_um, bead_area);
        let v_max = machine.v_flow_max.to_f64();
        let a_xy = machine.motion.max_accel[0]
            .min(machine.motion.max_accel[1])
            .to_f64();
        meter.set_step_reach(crate::metrics::StepReach {
            q_max: v_max * bead_area,
            accel: a_xy * dollop::section_taper::TAPER_SHARE,
            ring_mm: (machine.ramp_cycles / 2) as f64 * dt * v_max,
        });
        let mut exec: Executor<R> = Executor::new(machine);
        exec.begin(job.start_um, job.initial_material)
            .map_err(SimError::Begin)?;
        let plant = if opts.plant {
            Some(Plant::new(plant_config, job.initial_material).map_err(SimError::Config)?)
        } else {
            None
        };
        Ok(Runner {
            config,
            job,
            opts,
            pauses,
            exec,
            out: RecordingOutputs::default(),
            plant,
            meter,
            pauser,
            park_view: ParkView::default(),
            refill: Refill::default(),
            valves: ValveWatch::default(),
            motion: Motion::new(dt, spm, job.start_um),
            period_us,
            dt,
            bead_area,
            next_cmd: 0,
            cycle: 0,
            landing_prev: job.initial_material,
            changes: Vec::new(),
        })
    }

    /// Pushes the job's next commands while the executor has room; a rejected one ends
    /// the feeding (the executor faults on it).
    fn feed(&mut self) {
        let commands = &self.job.commands;
        while self.next_cmd < commands.len() && self.exec.room() > 0 {
            match self.exec.push(commands[self.next_cmd]) {
                Ok(()) => self.next_cmd += 1,
                Err(PushError::Full) => break,
                Err(PushError::Rejected(_)) => {
                    self.next_cmd = commands.len();
                    break;
                }
            }
        }
    }

    /// What landed during the cycle that just ended (from the plant, else the
    /// executor's model): its volume, the material landing at its end, and each change
    /// of material into `changes`.
    fn land(&mut self, report: &Report<R>, t: f64) -> (f64, u8) {
        self.changes.clear();
        match self.plant.as_mut() {
            Some(p) => {
                let l = p.advance(t, self.opts.plant_step_s);
                self.changes.extend_from_slice(&l.changes);
                (l.volume, l.material)
            }
            None => {
                let m = report.landing;
                if m != self.landing_prev {
                    self.changes.push((report.dv.mm3::<f64>(), m));
                }
                (report.dv.mm3::<f64>(), m)
            }
        }
    }

    /// Meters the cycle and says where the head is.
    fn meter_cycle(&mut self, report: &Report<R>, landed_volume: f64, landing: u8) -> Head {
        // A pause's tail and what trickles while paused land on the bead, the head
        // standing or creeping: counted as printing, so a blob at the seam shows.
        let printing = matches!(
            report.state,
            RunState::Printing | RunState::Pausing | RunState::Paused
        );
        let on_bead = printing || report.state == RunState::Settling;
        let raw = [
            report.position[0].to_f64(),
            report.position[1].to_f64(),
            report.position[2].to_f64(),
        ];
        // A park's excursion is no path: the meters see the head stay on the pause point.
        let off_point = self.park_view.cycle(self.exec.parked_off_point(), raw);
        let pos = [self.park_view.point[0], self.park_view.point[1]];
        self.meter.cycle(CycleIn {
            bead_command: on_bead.then_some(report.command_index),
            printing,
            pos,
            landed_volume,
            landing_before: self.landing_prev,
            changes: &self.changes,
        });
        self.landing_prev = landing;
        Head {
            printing,
            raw,
            pos,
            off_point,
        }
    }

    /// Valve changes go to the plant at this instant.
    fn valves_changed(&mut self) {
        let valves = self.out.valves;
        if valves == self.valves.prev {
            return;
        }
        self.valves.count(valves);
        if let Some(p) = self.plant.as_mut() {
            set_valves(p, valves, self.config.inlets.len());
        }
    }

    /// Shows the pauser this cycle, asks a refill where it is due, and makes the pause or
    /// resume the pauser asks for.
    fn steer_pauses(&mut self, report: &Report<R>, head: &Head, landed_volume: f64, t: f64) {
        let seen = Seen {
            t,
            state: report.state,
            pos: head.pos,
            plan_mm: report.plan_volume.mm3::<f64>() / self.bead_area,
            valves: self.out.valves,
            landed: landed_volume,
            q_plant: self.plant.as_ref().map_or(report.q.to_f64(), |p| p.q()),
            off_point: head.off_point,
            raw: head.raw,
            point_z: self.park_view.point[2],
            parked: self.exec.park_stage() == ParkStage::Parked,
        };
        self.refill.cycle(
            &mut self.exec,
            self.pauses.refill,
            &self.out,
            &mut self.pauser,
        );
        match self.pauser.cycle(&seen, self.dt) {
            Action::Pause if self.pauses.park => self.exec.park(),
            Action::Pause => self.exec.pause(),
            Action::Resume => {
                // Refused only if the job ended meanwhile; the record shows it.
                let _ = self.exec.resume();
            }
            Action::None => {}
        }
        if report.state == RunState::Paused && self.pauser.holding() {
            self.pauser.executor_says(self.exec.pause_info());
        }
    }

    /// The run ended in a fault at `now`: the outputs are already safe; the executor
    /// reports once more for the record, and the plant gets the valves as they stand.
    fn faulted(mut self, now: u64, t: f64) -> RunResult {
        let r = self.exec.tick(now + self.period_us, &mut self.out).err();
        let fault = self.exec.fault_cause().or(r);
        if let Some(p) = self.plant.as_mut() {
            set_valves(p, self.out.valves, self.config.inlets.len());
        }
        let state = self.exec.state();
        self.finish(state, fault, t)
    }

    /// The figures of a run that ended at `t` in `state`.
    fn finish(self, state: RunState, fault: Option<Fault>, t: f64) -> RunResult {
        let m = self.motion;
        RunResult {
            time_s: t,
            cycles: self.cycle,
            state,
            fault,
            valve_changes: self.out.valve_changes,
            peak_step_rate: m.peak_rate,
            outputs: self.out,
            metrics: self.meter.finish(),
            switches: self.valves.switches,
            worst_step_error: m.worst_step_error,
            peak_accel: m.peak_accel,
            max_slugs: m.max_slugs,
            axis_accel: m.axis_accel.peak.v,
            axis_accel_at: m.axis_accel.peak.at,
            axis_accel_moving: m.axis_accel.moving.v,
            axis_accel_moving_at: m.axis_accel.moving.at,
            axis_accel_open_net: m.axis_accel.open_net.v,
            axis_accel_open_net_at: m.axis_accel.open_net.at,
            bead_area: self.bead_area,
            segments: self.job.print_segments(),
            pauses: self.pauser.finish(),
        }
    }
}

/// Commands each of the first `inlets` of the plant's valves as `valves` has it.
fn set_valves(plant: &mut Plant, valves: u32, inlets: usize) {
    for i in 0..inlets {
        plant.command(i, valves & (1 << i) != 0);
    }
}

/// The valves as last commanded, and the material switches counted from them.
#[derive(Default)]
struct ValveWatch {
    prev: u32,
    /// Valves opened for another material than the last one opened.
    switches: u64,
    last_opened: Option<u8>,
}

impl ValveWatch {
    /// Takes `valves`, changed from `prev`.
    fn count(&mut self, valves: u32) {
        let opened = valves & !self.prev;
        if opened != 0 {
            let inlet = opened.trailing_zeros() as u8;
            if self.last_opened.is_some_and(|l| l != inlet) {
                self.switches += 1;
            }
            self.last_opened = Some(inlet);
        }
        self.prev = valves;
    }
}

/// The motion figures gathered cycle by cycle: peak step rates, the step generator's
/// worst error, axis and corner accelerations, and the most slugs at once.
struct Motion {
    dt: f64,
    spm: [f64; 3],
    /// The recording counts steps from zero; the executor's step positions are absolute.
    origin: [i64; 3],
    // Step rate over windows of RATE_WINDOW cycles: a per-cycle count of 1 would read as
    // 10 000 steps/s at 10 kHz however slowly the axis moves.
    rate_base: [u64; 3],
    peak_rate: [f64; 3],
    worst_step_error: f64,
    peak_accel: f64,
    axis_accel: AxisAccel,
    /// The last three points `[x, y, t]` the curvature is taken from.
    hist: [[f64; 3]; 3],
    max_slugs: u8,
}

impl Motion {
    fn new(dt: f64, spm: [f64; 3], start_um: [i32; 3]) -> Self {
        let mut origin = [0i64; 3];
        for a in 0..3 {
            origin[a] = (start_um[a] as f64 * 1e-3 * spm[a]).round() as i64;
        }
        Motion {
            dt,
            spm,
            origin,
            rate_base: [0u64; 3],
            peak_rate: [0.0f64; 3],
            worst_step_error: 0.0f64,
            peak_accel: 0.0f64,
            axis_accel: AxisAccel::new(dt),
            hist: [[f64::NAN; 3]; 3],
            max_slugs: 0u8,
        }
    }

    fn cycle<R: Real>(
        &mut self,
        cycle: u64,
        report: &Report<R>,
        out: &RecordingOutputs,
        head: &Head,
        t: f64,
    ) {
        if cycle.is_multiple_of(RATE_WINDOW) {
            for a in 0..3 {
                let n = out.pulses[a] - self.rate_base[a];
                self.peak_rate[a] =
                    self.peak_rate[a].max(n as f64 / (RATE_WINDOW as f64 * self.dt));
                self.rate_base[a] = out.pulses[a];
            }
        }
        self.axis_accel.cycle(head.raw, out.valves != 0, t);
        for a in 0..3 {
            let planned = report.position[a].to_f64() * self.spm[a];
            let commanded = (out.position[a] + self.origin[a]) as f64;
            self.worst_step_error = self.worst_step_error.max((commanded - planned).abs());
        }
        if head.printing {
            // Curvature from points ACCEL_BASE_MM apart: per-cycle steps are too short
            // for the f32 position's rounding.
            let (pos, hist) = (head.pos, &mut self.hist);
            let d = ((pos[0] - hist[2][0]).powi(2) + (pos[1] - hist[2][1]).powi(2)).sqrt();
            if hist[2][0].is_nan() || d >= ACCEL_BASE_MM {
                *hist = [hist[1], hist[2], [pos[0], pos[1], t]];
                // The head's own speed over the three points: with speed ramps the
                // report's (the plan's) runs half a window ahead of the position.
                let speed = path_speed(hist);
                self.peak_accel = self.peak_accel.max(speed * speed * curvature(hist));
                self.max_slugs = self.max_slugs.max(report.slugs);
            }
        } else {
            self.hist = [[f64::NAN; 3]; 3];
        }
    }
}

/// The pause point while a park has the head off it (else where the head is).
#[derive(Default)]
struct ParkView {
    point: [f64; 3],
    off: bool,
}

impl ParkView {
    /// Feeds the outputs' position and whether the plan is off the point; true while off.
    /// The executor holds the head still for a ramp window at each end of a park, so the
    /// outputs are on the point (exactly) the cycle before the plan leaves it and when
    /// it says it is back.
    fn cycle(&mut self, off: bool, raw: [f64; 3]) -> bool {
        if !off {
            self.point = raw;
        }
        self.off = off;
        self.off
    }
}

/// A refill asked at each park position (syringe machines), and its retraction measured.
#[derive(Default)]
struct Refill {
    asked: bool,
    /// This park's refill is over.
    done: bool,
    e_at_ask: Vec<i64>,
    done_before: u32,
}

impl Refill {
    fn cycle<R: Real>(
        &mut self,
        exec: &mut Executor<R>,
        wanted: bool,
        out: &RecordingOutputs,
        pauser: &mut Pauser,
    ) {
        if !wanted {
            return;
        }
        let e = || out.position[3..].to_vec();
        if !self.asked
            && !self.done
            && exec.park_stage() == ParkStage::Parked
            && exec.refill().is_ok()
        {
            self.asked = true;
            self.e_at_ask = e();
            self.done_before = exec.refills();
        } else if self.asked && exec.refills() > self.done_before {
            let now = e();
            let back = self
                .e_at_ask
                .iter()
                .zip(now.iter())
                .map(|(a, b)| a - b)
                .max()
                .unwrap_or(0);
            pauser.refilled(back);
            self.asked = false;
            self.done = true;
        }
        if exec.park_stage() == ParkStage::None {
            self.done = false;
        }
    }
}

/// Cycles over which the peak step rate is averaged (2 ms at 10 kHz).
const RATE_WINDOW: u64 = 20;

/// Spacing of the points the path curvature is taken from, mm.
const ACCEL_BASE_MM: f64 = 0.02;

/// Mean speed (mm/s) along three timed points `[x, y, t]`; 0 where undefined.
fn path_speed(h: &[[f64; 3]; 3]) -> f64 {
    let dt = h[2][2] - h[0][2];
    if h.iter().any(|p| p[0].is_nan()) || dt <= 0.0 {
        return 0.0;
    }
    let a = ((h[1][0] - h[0][0]).powi(2) + (h[1][1] - h[0][1]).powi(2)).sqrt();
    let b = ((h[2][0] - h[1][0]).powi(2) + (h[2][1] - h[1][1]).powi(2)).sqrt();
    (a + b) / dt
}

/// Curvature (1/mm) of the circle through three points; 0 where undefined.
fn curvature(h: &[[f64; 3]; 3]) -> f64 {
    if h.iter().any(|p| p[0].is_nan()) {
        return 0.0;
    }
    let a = ((h[1][0] - h[0][0]).powi(2) + (h[1][1] - h[0][1]).powi(2)).sqrt();
    let b = ((h[2][0] - h[1][0]).powi(2) + (h[2][1] - h[1][1]).powi(2)).sqrt();
    let c = ((h[2][0] - h[0][0]).powi(2) + (h[2][1] - h[0][1]).powi(2)).sqrt();
    let cross =
        (h[1][0] - h[0][0]) * (h[2][1] - h[0][1]) - (h[1][1] - h[0][1]) * (h[2][0] - h[0][0]);
    if a * b * c <= 0.0 {
        return 0.0;
    }
    2.0 * cross.abs() / (a * b * c)
}

/// Per-axis acceleration by central differences over `k` cycles each side, counted where
/// a valve is open at the centre, and over every cycle less the f32 rounding (`moving`).
struct AxisAccel {
    k: usize,
    h: f64,
    hist: std::collections::VecDeque<([f64; 3], bool, f64)>,
    peak: Peak,
    moving: Peak,
    open_net: Peak,
}

/// The largest figure per axis so far, and where (s) it was measured.
#[derive(Default)]
struct Peak {
    v: [f64; 3],
    at: [f64; 3],
}

impl Peak {
    fn note(&mut self, a: usize, x: f64, t: f64) {
        if x > self.v[a] {
            self.v[a] = x;
            self.at[a] = t;
        }
    }
}

/// Units in the last place of an f32 position at `x` mm.
fn f32_ulp(x: f64) -> f64 {
    let v = (x as f32).abs();
    if !v.is_finite() {
        return 0.0;
    }
    (f32::from_bits(v.to_bits() + 1) - v) as f64
}

impl AxisAccel {
    fn new(dt: f64) -> Self {
        let k = ((1e-3 / dt).round() as usize).max(1);
        AxisAccel {
            k,
            h: k as f64 * dt,
            hist: Default::default(),
            peak: Peak::default(),
            moving: Peak::default(),
            open_net: Peak::default(),
        }
    }
    fn cycle(&mut self, pos: [f64; 3], valve_open: bool, t: f64) {
        self.hist.push_back((pos, valve_open, t));
        if self.hist.len() > 2 * self.k + 1 {
            self.hist.pop_front();
        }
        if self.hist.len() == 2 * self.k + 1 {
            let (p0, p1, p2) = (self.hist[0].0, self.hist[self.k], self.hist[2 * self.k].0);
            let h2 = self.h * self.h;
            for a in 0..3 {
                let acc = ((p2[a] - 2.0 * p1.0[a] + p0[a]) / h2).abs();
                if p1.1 {
                    self.peak.note(a, acc, p1.2);
                }
                // Each position rounded to half a unit, and the arithmetic before it: four
                // units over the three, the largest of them.
                let far = p0[a].abs().max(p1.0[a].abs()).max(p2[a].abs());
                let net = acc - 4.0 * f32_ulp(far) / h2;
                self.moving.note(a, net, p1.2);
                if p1.1 {
                    self.open_net.note(a, net, p1.2);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A head braking at 480 mm/s^2 near x 115 mm, its position rounded to f32 as the
    /// executor's is: the 1 ms differences read more (the rounding's up to 30 mm/s^2
    /// there), the figures less the rounding never do, with a valve open or not.
    #[test]
    fn the_net_figures_take_out_the_rounding() {
        let dt = 1.0e-4;
        let mut m = AxisAccel::new(dt);
        for i in 0..2000 {
            let t = i as f64 * dt;
            let x = (115.0 + 10.0 * t - 240.0 * t * t) as f32 as f64;
            m.cycle([x, 0.0, 0.0], i < 1000, t);
        }
        let (raw, open, moving) = (m.peak.v[0], m.open_net.v[0], m.moving.v[0]);
        assert!(raw > 480.0, "{raw}");
        assert!(open <= 480.0 + 1e-6, "{open}");
        assert!(moving <= 480.0 + 1e-6, "{moving}");
        assert!(open > 440.0 && moving >= open);
    }
}
