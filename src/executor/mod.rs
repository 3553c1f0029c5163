//! The executor: one control cycle per `tick(now, outputs)`. Volume is the clock: while a
//! bead is printed the head advances along the path by exactly the volume the flow model
//! says left the nozzle (divided by the bead section), and the valves follow a cursor that
//! runs ahead of the head by the channel and hanging-filament volume plus the predicted
//! volume that flows while a valve change takes effect. Every fault goes through one
//! `safe_state`. Job intake beyond `push`, and pins, belong to the caller.
//!
//! This file holds the state, its set-up, the public API and `tick`; the rest is cut by
//! what it does: `plan` (commands into plan items), `drive` (one cycle through the
//! phases, and the step outputs), `valves` (switch and stop decisions), `sizing` (a
//! decision's ramp window, over the cycles after it), `ramp` (the speed-ramp window's
//! side), `turns` (slowing at tight fillets), `report`, `pause` and `park`.

use crate::command::{Command, CommandError};
use crate::config::{Config, ConfigError, Machine};
use crate::flow_model::channel::ChannelFull;
use crate::flow_model::FlowModel;
use crate::motion::Trapezoid;
use crate::outputs::Outputs;
use crate::ramp::Ramp;
use crate::real::Real;
pub use crate::state::{Fault, Report, RunState};
use crate::step_gen::StepGen;
use crate::step_ramps::StepRamps;
use crate::vol::Vol;
use heapless::Deque;

mod drive;
mod park;
mod pause;
mod plan;
mod ramp;
mod report;
mod sizing;
mod turns;
mod valves;
use drive::settle_limit;
pub use park::{ParkStage, RefillError};
pub use pause::{PauseInfo, ResumeError};
use plan::{Item, Open};
pub use ramp::step_ramp_accel;
use valves::{lead_window, Tracker};

pub use crate::capacity::{BOUNDARY_CAPACITY, PLAN_CAPACITY};
/// Cycles a late `tick` may catch up at once before it is a fault.
pub const MAX_CATCH_UP: u64 = 4;
/// Prediction chunks integrated per unit of prediction work. The two kinds of prediction
/// (switch, stop) take turns, one unit (a restart or a chunk) each on alternate cycles, so
/// a cycle never carries more than one.
pub const PREDICT_BUDGET: u32 = 1;
/// Cycles between the starts of successive predictions of one kind (2 ms at 10 kHz);
/// in between, the last two answers are extrapolated.
pub const PREDICT_INTERVAL: u64 = 20;

impl From<ChannelFull> for Fault {
    fn from(_: ChannelFull) -> Self {
        Fault::ChannelFull
    }
}

/// Why `push` did not take a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushError {
    /// No room now; push again after a few ticks.
    Full,
    /// The command is invalid; the executor will go to the safe state on the next tick.
    Rejected(Fault),
}

/// Why `load_config` did not load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LoadError {
    /// The config does not validate (the executor went to the safe state).
    Invalid(ConfigError),
    /// A job is under way; finish or abort it first.
    Busy,
}

impl core::fmt::Display for LoadError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LoadError::Invalid(e) => write!(f, "{e}"),
            LoadError::Busy => write!(f, "a job is running; abort or finish it first"),
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Phase<R> {
    Idle,
    Print {
        stopping: bool,
    },
    Settle {
        cycles: u64,
    },
    Travel {
        from: [R; 3],
        dir: [R; 3],
        trap: Trapezoid<R>,
        cycles: u64,
    },
    Dwell {
        left: u64,
    },
    /// Valves shut for a pause; the head follows the tail along the bead.
    Pausing,
    /// Paused; `on_bead`: mid-bead, the head following what little still flows.
    Paused {
        on_bead: bool,
    },
    Done,
    Aborted,
    Faulted(Fault),
}

/// The volume-clocked executor for a machine with up to `N` inlets, computing in `R`.
pub struct Executor<R: Real, const N: usize = { crate::DEFAULT_INLETS }> {
    machine: Machine<R, N>,
    model: FlowModel<R, N>,
    steps: StepGen<R>,
    plan: Deque<Item<R>, PLAN_CAPACITY>,
    boundaries: Deque<(Vol, u8), BOUNDARY_CAPACITY>,
    /// Plan volume where each planned bead ends, in order (the head's bead first).
    ends: Deque<Vol, PLAN_CAPACITY>,
    open: Option<Open<R>>,
    /// Material and plan volume at the end of the last finalised print segment.
    last_final: Option<(u8, Vol)>,
    /// Where the plan is known to, as print volume; None once the job's end is queued.
    known_to: Option<Vol>,
    design_um: [i32; 3],
    commands: u32,
    ended: bool,
    begun: bool,
    phase: Phase<R>,
    head: Vol,
    head_pos: [R; 3],
    entry_material: u8,
    want: Option<u8>,
    switch: Tracker<R, N>,
    stop: Tracker<R, N>,
    window: Vol,
    /// Cycles a bead's end may take to settle (`settle_limit`), worked out once.
    settle_limit: u64,
    /// Largest shortfall of a bead's end (paste ran out before it), as volume.
    short: Vol,
    dt: R,
    /// 1 / the section of the segment the head is on (set as each segment starts).
    inv_s: R,
    /// Section the beads planned next take (`Command::Section`), mm^2, and its inverse.
    plan_s: (R, R),
    /// The section the plan lays now, and a change mid-bead under way.
    taper: crate::section_taper::Taper<R>,
    /// Sections a `Command::Section` may ask, um^2 (`command::section_limits`).
    section_um2: (u32, u32),
    lost: Vol,
    last_now: Option<u64>,
    cycle: u64,
    drivers_on: bool,
    valves_out: u32,
    pause: pause::PauseState<R>,
    pending_fault: Option<Fault>,
    last_dv: Vol,
    last_q: R,
    last_index: u32,
    /// Syringe plungers: volume displaced so far, steps emitted, volume per cycle.
    plunger_vol: [Vol; N],
    plunger_steps: [i64; N],
    plunger_per_cycle: [Vol; N],
    /// The cycles planned but not yet shown by the outputs, when the head ramps through
    /// flow steps (`Machine::ramp_cycles` > 1).
    ramp: Ramp<N>,
    /// The steps of the plan's velocity the ramp window re-ramps over their own windows.
    step_ramps: StepRamps,
    ramped: bool,
    /// Ramped, and the valves' flow changes are first-order ones that
    /// `crate::switch_window` sizes a window for at each decision.
    sizing: bool,
    /// A valve decision's sizing of the ramp window, under way (`sizing`).
    sizer: Option<sizing::Pending<R>>,
    /// How far (as volume) the head lags the volume clock after slowing for a tight
    /// fillet (`crate::turn_slow`, `turns`): `follow_path` places it there.
    lag: Vol,
    /// The plan's moves over the ring's windows while the flow's follower runs
    /// (`crate::window_sums`).
    sums: crate::window_sums::WindowSums,
    turn_slow: crate::turn_slow::TurnSlow<R>,
    /// Half the ring mean's window the last decision headed for, frames (the machine's
    /// window's before any), and the cap (squared, mm^2/s^2) worked out for the fillet
    /// starting at a plan volume with that half (`turns`).
    mean_half: u32,
    /// Cycles the head holds at a bead's start after a travel that reverses along an
    /// axis (`drive::travel_cycle`), on machines whose bead starts step the head's speed.
    start_hold: u32,
    /// Cycles the travel under way still holds the head before it moves (`end_hold`).
    travel_hold: u32,
    cap_cache: ((Vol, u32), R),
    /// A bead start's widening of the ramp's mean, put off to this plan cycle
    /// (`sizing::widen_when_due`): (cycle, half window).
    deferred: Option<(u64, u32)>,
    /// The head's follower of a valve decision's flow change (`crate::flow_follow`), about
    /// 3 KiB: last, so that the fields the tick reads keep their short offsets (the
    /// slowing's lag behind it cost every machine's tick an instruction or more).
    follow: crate::flow_follow::FlowFollow,
}

impl<R: Real, const N: usize> Executor<R, N> {
    /// An executor of no machine (`Machine::UNCONFIGURED`); `load_config` gives it one.
    /// A constant constructor: the board keeps its executor (41 KiB in f32 with four
    /// inlets) in a static built at compile time, never on its 64 KiB stack.
    pub const fn unconfigured() -> Self {
        Executor {
            machine: Machine::UNCONFIGURED,
            model: FlowModel::unconfigured(),
            steps: StepGen::idle(),
            plan: Deque::new(),
            boundaries: Deque::new(),
            ends: Deque::new(),
            open: None,
            last_final: None,
            known_to: None,
            design_um: [0; 3],
            commands: 0,
            ended: false,
            begun: false,
            phase: Phase::Idle,
            head: Vol::ZERO,
            head_pos: [R::ZERO; 3],
            entry_material: 0,
            want: None,
            switch: Tracker::new(),
            stop: Tracker::new(),
            window: Vol::ZERO,
            settle_limit: 0,
            short: Vol::ZERO,
            dt: R::ZERO,
            inv_s: R::ZERO,
            plan_s: (R::ZERO, R::ZERO),
            taper: crate::section_taper::Taper::new(),
            section_um2: (0, 0),
            lost: Vol::ZERO,
            last_now: None,
            cycle: 0,
            drivers_on: false,
            valves_out: 0,
            pause: pause::PauseState::NONE,
            pending_fault: None,
            last_dv: Vol::ZERO,
            last_q: R::ZERO,
            last_index: 0,
            plunger_vol: [Vol::ZERO; N],
            plunger_steps: [0; N],
            plunger_per_cycle: [Vol::ZERO; N],
            ramp: Ramp::new(),
            step_ramps: StepRamps::new(),
            ramped: false,
            sizing: false,
            sizer: None,
            follow: crate::flow_follow::FlowFollow::new(),
            lag: Vol::ZERO,
            sums: crate::window_sums::WindowSums::new(),
            turn_slow: crate::turn_slow::TurnSlow::off(),
            mean_half: 0,
            start_hold: 0,
            travel_hold: 0,
            deferred: None,
            cap_cache: ((Vol::ZERO, 0), R::ZERO),
        }
    }

    /// An idle executor for `machine`.
    pub fn new(machine: Machine<R, N>) -> Self {
        let mut e = Self::unconfigured();
        e.configure(machine);
        e
    }

    /// Makes this the idle executor `new(machine)` builds, in place (the board does this
    /// in its control interrupt, where a 41 KiB temporary would overflow the stack).
    fn configure(&mut self, machine: Machine<R, N>) {
        self.machine = machine;
        let m = &self.machine;
        self.model.reset(m, 0);
        self.steps = StepGen::new(m.motion.steps_per_mm, m.motion.max_steps_per_cycle, [0; 3]);
        self.window = lead_window(m);
        self.settle_limit = settle_limit(m);
        self.dt = m.dt();
        self.section_um2 = crate::command::section_limits(m.bead_area.to_f64());
        self.plunger_per_cycle = core::array::from_fn(|i| {
            m.inlets
                .get(i)
                .and_then(|inlet| inlet.syringe)
                .filter(|_| m.syringes)
                .map(|sy| Vol::from_mm3(sy.rate * m.dt()))
                .unwrap_or(Vol::ZERO)
        });
        self.clear_job();
        self.last_final = None;
        self.design_um = [0; 3];
        self.begun = false;
        self.head_pos = [R::ZERO; 3];
        self.entry_material = 0;
        self.short = Vol::ZERO;
        self.last_now = None;
        self.drivers_on = false;
        self.valves_out = 0;
        self.last_dv = Vol::ZERO;
        self.last_q = R::ZERO;
        self.plunger_vol = [Vol::ZERO; N];
        self.plunger_steps = [0; N];
        self.ramped = self.machine.ramp_cycles > 1;
        self.sizing = self.ramped
            && self
                .machine
                .inlets
                .iter()
                .all(|i| i.syringe.is_none() && i.rise_s > R::ZERO && i.decay_s > R::ZERO);
        // The ramps' share of the X/Y limit, on the machines whose windows are sized per
        // decision (narrowed for a switch, they leave tight fillets to `turn_slow`).
        let a = if self.sizing {
            self.machine.motion.max_accel[0].min(self.machine.motion.max_accel[1])
                * R::of(crate::config::RAMP_SHARE)
        } else {
            R::ZERO
        };
        self.turn_slow.reset(a);
        self.mean_half = self.machine.ramp_cycles / 2;
        self.start_hold = drive::start_hold(&self.machine);
        self.cap_cache = ((Vol(-1), 0), R::ZERO);
        self.hold_ramp();
    }

    /// Forgets the plan and the run's progress: what `configure` and `begin` both reset.
    fn clear_job(&mut self) {
        self.plan.clear();
        self.boundaries.clear();
        self.ends.clear();
        self.open = None;
        self.known_to = Some(Vol::ZERO);
        self.commands = 0;
        self.ended = false;
        self.phase = Phase::Idle;
        self.head = Vol::ZERO;
        self.lag = Vol::ZERO;
        self.cap_cache = ((Vol(-1), 0), R::ZERO);
        self.want = None;
        self.switch.reset();
        self.stop.reset();
        self.lost = Vol::ZERO;
        self.cycle = 0;
        self.pause = pause::PauseState::NONE;
        self.pending_fault = None;
        self.last_index = 0;
        // Every job starts at the config's section; `Command::Section` changes it.
        let s = self.machine.bead_area;
        self.inv_s = R::ONE / s;
        self.plan_s = (s, R::ONE / s);
        self.taper.set(s, R::ONE / s);
    }

    /// The machine this executor runs.
    pub fn machine(&self) -> &Machine<R, N> {
        &self.machine
    }
    /// The flow model (read-only).
    pub fn model(&self) -> &FlowModel<R, N> {
        &self.model
    }
    /// Current run state, as the outputs show it: with speed ramps, the plan runs half a
    /// ramp window ahead, and the job is done when the head has stopped.
    pub fn state(&self) -> RunState {
        match self.phase {
            Phase::Faulted(_) | Phase::Aborted => self.model_state(),
            // Once resumed, the window still shows the paused frames for half a window;
            // a host asking then must not be told the print is (still) paused.
            _ if self.ramped => match self.ramp.state() {
                RunState::Paused | RunState::Pausing
                    if !matches!(self.phase, Phase::Paused { .. } | Phase::Pausing) =>
                {
                    self.model_state()
                }
                s => s,
            },
            _ => self.model_state(),
        }
    }

    /// Run state of the plan.
    fn model_state(&self) -> RunState {
        match self.phase {
            Phase::Idle => RunState::Idle,
            Phase::Print { .. } => RunState::Printing,
            Phase::Settle { .. } => RunState::Settling,
            Phase::Travel { .. } => RunState::Travelling,
            Phase::Dwell { .. } => RunState::Dwelling,
            Phase::Pausing => RunState::Pausing,
            Phase::Paused { .. } => RunState::Paused,
            Phase::Done => RunState::Done,
            Phase::Aborted => RunState::Aborted,
            Phase::Faulted(_) => RunState::Faulted,
        }
    }
    /// The fault that stopped the executor, if any.
    pub fn fault_cause(&self) -> Option<Fault> {
        match self.phase {
            Phase::Faulted(f) => Some(f),
            _ => self.pending_fault,
        }
    }

    /// Begins a job with the head at `head_um` (micrometres) and the channel and filament
    /// full of `initial_material` (primed). The job's commands follow through `push`.
    pub fn begin(&mut self, head_um: [i32; 3], initial_material: u8) -> Result<(), Fault> {
        if matches!(self.phase, Phase::Faulted(_)) {
            return Err(self.fault_cause().unwrap_or(Fault::NotReady));
        }
        if initial_material as usize >= self.machine.inlet_count() {
            return Err(Fault::InvalidCommand(CommandError::NoSuchInlet {
                material: initial_material,
                inlets: self.machine.inlet_count() as u8,
            }));
        }
        let mut pos = [R::ZERO; 3];
        for (a, p) in pos.iter_mut().enumerate() {
            *p = um(head_um[a]);
        }
        self.check_limits(pos)?;
        // The machine is the same: keep its tables, restart the state only.
        self.model.restart(&self.machine, initial_material);
        self.steps = StepGen::new(
            self.machine.motion.steps_per_mm,
            self.machine.motion.max_steps_per_cycle,
            self.steps.target(pos),
        );
        self.clear_job();
        self.last_final = Some((initial_material, Vol::ZERO));
        self.design_um = head_um;
        self.begun = true;
        self.head_pos = pos;
        self.entry_material = initial_material;
        self.hold_ramp();
        Ok(())
    }

    /// Free places in the plan queue. A feeder keeps it topped up while a job runs.
    pub fn room(&self) -> usize {
        // One place is kept for the segment that `open` will become, and one a stair
        // while a section's change is under way (its segments split at each).
        (PLAN_CAPACITY - self.plan.len()).saturating_sub(1 + self.taper_room())
    }

    /// Queues the next job command. Invalid commands are refused and latch a fault that
    /// the next `tick` acts on through the safe state.
    pub fn push(&mut self, cmd: Command) -> Result<(), PushError> {
        if !self.begun {
            return Err(PushError::Rejected(Fault::NotReady));
        }
        if let Some(f) = self.fault_cause() {
            return Err(PushError::Rejected(f));
        }
        if self.room() == 0 || self.boundaries.is_full() {
            return Err(PushError::Full);
        }
        match self.plan_command(cmd) {
            Ok(()) => {
                self.commands = self.commands.wrapping_add(1);
                Ok(())
            }
            Err(f) => {
                self.pending_fault = Some(f);
                Err(PushError::Rejected(f))
            }
        }
    }

    /// Loads a new machine config between jobs. An invalid config is a fault: the
    /// executor goes to the safe state, because the machine it was told about is wrong.
    /// While a job runs the config is refused and nothing changes.
    pub fn load_config(
        &mut self,
        config: &Config,
        out: &mut impl Outputs,
    ) -> Result<(), LoadError> {
        match config.validate::<R, N>() {
            Err(e) => {
                self.safe_state(Fault::InvalidConfig, out);
                Err(LoadError::Invalid(e))
            }
            Ok(m) => self.load_machine(m),
        }
    }

    /// Loads an already validated machine between jobs, in place (the board validates a
    /// config in thread mode and hands the machine to its control interrupt). While a job
    /// runs it is refused and nothing changes.
    pub fn load_machine(&mut self, m: Machine<R, N>) -> Result<(), LoadError> {
        if self.busy() {
            return Err(LoadError::Busy);
        }
        let position = self.steps.position();
        let last_now = self.last_now;
        self.configure(m);
        self.steps = StepGen::new(
            self.machine.motion.steps_per_mm,
            self.machine.motion.max_steps_per_cycle,
            position,
        );
        self.last_now = last_now;
        Ok(())
    }

    /// True while a job is under way (printing, moving, settling, dwelling or paused).
    pub fn busy(&self) -> bool {
        matches!(
            self.phase,
            Phase::Print { .. }
                | Phase::Settle { .. }
                | Phase::Travel { .. }
                | Phase::Dwell { .. }
                | Phase::Pausing
                | Phase::Paused { .. }
        ) || (self.begun
            && !self.plan.is_empty()
            && !matches!(self.phase, Phase::Done | Phase::Aborted | Phase::Faulted(_)))
    }

    /// Acknowledges a fault or an abort: back to idle with no job, outputs still safe
    /// until the next job begins.
    pub fn clear_fault(&mut self) {
        if matches!(self.phase, Phase::Faulted(_) | Phase::Aborted) {
            self.phase = Phase::Idle;
            self.begun = false;
            self.pending_fault = None;
            self.plan.clear();
            self.boundaries.clear();
            self.ends.clear();
            self.open = None;
        }
    }

    /// Stops now: valves closed, motion stopped, drivers off.
    pub fn abort(&mut self, out: &mut impl Outputs) {
        self.safe_outputs(out);
        self.stop_ramp();
        if !matches!(self.phase, Phase::Faulted(_)) {
            self.phase = Phase::Aborted;
        }
    }
    /// An outside fault (e-stop, watchdog, link loss): straight to the safe state.
    pub fn fault(&mut self, fault: Fault, out: &mut impl Outputs) {
        self.safe_state(fault, out);
    }

    /// The one path to the safe state: every valve closed, motion stopped, drivers off.
    fn safe_state(&mut self, fault: Fault, out: &mut impl Outputs) {
        self.safe_outputs(out);
        self.stop_ramp();
        self.phase = Phase::Faulted(fault);
        self.pending_fault = None;
    }

    /// The outputs' one safe state (`outputs::force_safe`: every valve a config can
    /// name, not only this machine's inlets), and the executor's record of them. Out of
    /// line: a printing cycle never runs it, and inlined it cost every cycle of
    /// bench-m4 one to five instructions.
    #[cold]
    #[inline(never)]
    fn safe_outputs(&mut self, out: &mut impl Outputs) {
        crate::outputs::force_safe(out);
        self.valves_out = 0;
        self.model.command(0);
        self.want = None;
        self.drivers_on = false;
    }

    /// One control cycle at time `now_us`. One call per period; a call less than half a
    /// period after the previous one is ignored, a late one catches up to `MAX_CATCH_UP`
    /// cycles.
    pub fn tick(&mut self, now_us: u64, out: &mut impl Outputs) -> Result<Report<R>, Fault> {
        if let Phase::Faulted(f) = self.phase {
            // Hold the safe state every cycle, whatever else may have touched the pins.
            self.safe_outputs(out);
            return Err(f);
        }
        if let Some(f) = self.pending_fault.take() {
            self.safe_state(f, out);
            return Err(f);
        }
        let period = self.machine.period_us as u64;
        let cycles = match self.last_now {
            None => 1,
            Some(prev) => {
                let el = now_us.saturating_sub(prev);
                if el * 2 < period {
                    return Ok(self.report());
                }
                // The usual case without a 64-bit division (software on the M4).
                if el * 2 < period * 3 {
                    1
                } else {
                    (el + period / 2) / period
                }
            }
        };
        if cycles > MAX_CATCH_UP {
            let f = Fault::Late { periods: cycles };
            self.safe_state(f, out);
            return Err(f);
        }
        // At most `MAX_CATCH_UP` from here: counted in 32 bits (a u64 loop counter and
        // its compares are two words each on the M4).
        let cycles = cycles as u32;
        self.last_now = Some(now_us);
        if !self.drivers_on && self.begun {
            out.drivers(true);
            self.drivers_on = true;
        }
        let mut total_dv = Vol::ZERO;
        for _ in 0..cycles {
            match self.cycle_once() {
                Ok(dv) => total_dv += dv,
                Err(f) => {
                    self.safe_state(f, out);
                    return Err(f);
                }
            }
        }
        self.last_dv = total_dv;
        if self.ramped {
            return self.ramped_outputs(cycles, total_dv, out);
        }
        // Steps for where the head now is.
        if let Err(f) = self.move_head(self.head_pos, cycles, out) {
            self.safe_state(f, out);
            return Err(f);
        }
        if let Err(f) = self.move_plungers(false, cycles, out) {
            self.safe_state(f, out);
            return Err(f);
        }
        self.set_valves(self.model.commanded(), out);
        Ok(self.plan_report())
    }

    /// Section of the bead the head is on, mm^2 (off the tick's path: the pause's slack).
    fn bead_s(&self) -> R {
        R::ONE / self.inv_s
    }

    /// Volume that left the nozzle off the print path so far (between beads).
    pub fn lost_volume(&self) -> Vol {
        self.lost
    }
    /// Largest distance by which a bead ended short of its planned end, mm (the flow's
    /// tail delivered less than predicted).
    pub fn shortfall_mm(&self) -> R {
        self.short.mm3::<R>() * self.inv_s
    }
    /// Cycles run since the job began.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }
    /// Commanded step position per axis.
    pub fn step_position(&self) -> [i64; 3] {
        self.steps.position()
    }

    /// The state as of the last cycle, without running one.
    pub fn report_snapshot(&self) -> Report<R> {
        self.report()
    }
}

/// A cycle count as u32 for one-instruction conversion (saturates after 5 days at 10 kHz).
fn cycles32(c: u64) -> u32 {
    c.min(u32::MAX as u64) as u32
}

fn um<R: Real>(v: i32) -> R {
    R::of(v as f64 * 1e-3)
}
