//! The executor: one control cycle per `tick(now, outputs)`. Volume is the clock: while a
//! bead is printed the head advances along the path by exactly the volume the flow model
//! says left the nozzle (divided by the bead section), and the valves follow a cursor that
//! runs ahead of the head by the channel and hanging-filament volume plus the predicted
//! volume that flows while a valve change takes effect. Every fault goes through one
//! `safe_state`. Job intake beyond `push`, and pins, belong to the caller.

use crate::command::{Command, CommandError, MAX_DWELL_MS, MAX_SEGMENT_UM};
use crate::config::{Config, ConfigError, Machine};
use crate::flow_model::channel::ChannelFull;
use crate::flow_model::predict::{Goal, Outcome, Prediction};
use crate::flow_model::FlowModel;
use crate::motion::{fillet, Fillet, Trapezoid, V2};
use crate::outputs::{Axis, Outputs};
use crate::ramp::{to_units, Frame, Ramp};
use crate::real::Real;
pub use crate::state::{Fault, Report, RunState};
use crate::step_gen::StepGen;
use crate::step_ramps::StepRamps;
use crate::vol::Vol;
use heapless::Deque;

mod park;
mod pause;
pub use park::{ParkStage, RefillError};
pub use pause::{PauseInfo, ResumeError};

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

/// A finalised print segment: the straight part, then the fillet into the next segment.
#[derive(Clone, Copy, Debug)]
struct Seg<R> {
    material: u8,
    start: V2<R>,
    dir: V2<R>,
    len: R,
    fillet: Option<Fillet<R>>,
    u_start: Vol,
    u_arc: Vol,
    u_end: Vol,
    last: bool,
    index: u32,
}

#[derive(Clone, Copy, Debug)]
enum Item<R> {
    Seg(Seg<R>),
    Travel { to: [R; 3], index: u32 },
    Dwell { cycles: u64, index: u32 },
    End { index: u32 },
}

/// The newest print segment, not final until the next command shows how it ends.
#[derive(Clone, Copy, Debug)]
struct Open<R> {
    material: u8,
    from: V2<R>,
    to: V2<R>,
    dir: V2<R>,
    length: R,
    /// Tangent length taken at the start by the previous segment's fillet.
    t_start: R,
    u_start: Vol,
    index: u32,
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

/// Tracks predictions of one kind and extrapolates their answer to the present.
#[derive(Clone, Debug)]
struct Tracker<R, const N: usize> {
    goal: Option<Goal>,
    pred: Prediction<R, N>,
    running: bool,
    last: Option<(u64, R)>,
    prev: Option<(u64, R)>,
    /// Change of the answer per cycle between the last two predictions (0 with one).
    slope: R,
}

impl<R: Real, const N: usize> Tracker<R, N> {
    const fn new() -> Self {
        Tracker {
            goal: None,
            pred: Prediction::new(),
            running: false,
            last: None,
            prev: None,
            slope: R::ZERO,
        }
    }
    /// Forgets everything; field by field, as moving the prediction is dearer than this.
    fn reset(&mut self) {
        self.goal = None;
        self.running = false;
        self.last = None;
        self.prev = None;
        self.slope = R::ZERO;
    }
    /// The current answer for `goal`: the last two predictions extrapolated to the
    /// present (a new goal forgets the old one's).
    fn answer(&mut self, model: &FlowModel<R, N>, goal: Goal) -> Option<R> {
        if self.goal != Some(goal) {
            self.reset();
            self.goal = Some(goal);
        }
        let (t1, v1) = self.last?;
        // A lead changes because time passes; it cannot change faster than the flow
        // itself, which bounds a slope taken across a jump in the state.
        let cap = model.q() * model.dt();
        let slope = self.slope.max(-cap).min(cap);
        let since = R::from_u32(cycles32(model.next_cycle() - t1));
        Some((v1 + slope * since).max(R::ZERO))
    }

    /// One unit of work (a restart or half a chunk) on the goal of the last `answer`.
    /// Done after the cycle's decision, so a cycle that acts on an answer (and so forgets
    /// the prediction) spends nothing on it.
    fn work(&mut self, model: &FlowModel<R, N>) {
        let Some(goal) = self.goal else { return };
        let now = model.next_cycle();
        if !self.running && self.last.is_none_or(|(t, _)| now >= t + PREDICT_INTERVAL) {
            self.pred.restart(model, goal);
            self.running = true;
        } else if self.running {
            if let Some(outcome) = self.pred.advance(model, PREDICT_BUDGET) {
                self.running = false;
                let at = self.pred.start_cycle();
                match outcome {
                    Outcome::Volume(v) => {
                        self.prev = self.last;
                        self.last = Some((at, v));
                        // The slope between the last two answers, worked out once here
                        // rather than in every cycle's `answer`.
                        self.slope = match self.prev {
                            Some((t0, v0)) if at > t0 => (v - v0) / R::from_u32(cycles32(at - t0)),
                            _ => R::ZERO,
                        };
                    }
                    Outcome::Never => {
                        self.prev = None;
                        self.last = None;
                        self.slope = R::ZERO;
                    }
                }
            }
        }
    }
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
    /// 1 / bead section.
    inv_s: R,
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
        self.inv_s = R::ONE / m.bead_area;
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
        self.hold_ramp();
    }

    /// The head at rest where the plan has it, valves as commanded: the whole ramp window
    /// that frame (after a job begins, a config loads, or the outputs went safe).
    fn hold_ramp(&mut self) {
        if self.ramped {
            let f = self.frame();
            let m = &self.machine;
            let per_unit = crate::ramp::frames_per_unit(step_ramp_accel(m), m.dt().to_f32());
            self.ramp
                .reset(m.ramp_cycles, f, &mut self.step_ramps, per_unit);
        }
    }

    /// Syringe plunger targets, steps.
    fn plunger_targets(&self) -> [i32; N] {
        let mut t = [0i32; N];
        if !self.machine.syringes {
            return t;
        }
        for (i, inlet) in self.machine.inlets.iter().enumerate() {
            if let Some(sy) = inlet.syringe {
                t[i] = plunger_steps(self.plunger_vol[i], sy.steps_per_mm3);
            }
        }
        t
    }

    /// This cycle as planned, for the ramp window.
    #[inline(always)]
    fn frame(&self) -> Frame<N> {
        Frame {
            pos: to_units(self.head_pos),
            valves: self.model.commanded(),
            state: self.model_state(),
            index: self.last_index,
            dv: self.last_dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            landing: self.model.channel().landing(),
            feeding: self.model.feeding(),
            slugs: self.model.channel().len().min(u8::MAX as usize) as u8,
            plunger: self.plunger_targets(),
        }
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
        self.want = None;
        self.switch.reset();
        self.stop.reset();
        self.lost = Vol::ZERO;
        self.cycle = 0;
        self.pause = pause::PauseState::NONE;
        self.pending_fault = None;
        self.last_index = 0;
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
        // One place is kept for the segment that `open` will become.
        (PLAN_CAPACITY - self.plan.len()).saturating_sub(1)
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

    /// Motion stops where the outputs are, not where the plan ran ahead to. Once per
    /// fault or abort: refilling the window is 24 KiB of stores.
    fn stop_ramp(&mut self) {
        if self.ramped {
            self.head_pos = self.ramp.position(&self.step_ramps);
            self.hold_ramp();
        }
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

    /// The outputs of a tick with speed ramps: the cycles just planned enter the window
    /// and the outputs show it. Out of line, so that machines without ramps run the tick
    /// they ran before ramps existed, plus one branch. A late tick's catch-up cycles enter
    /// as copies of the last (the window smooths the jump).
    #[inline(never)]
    fn ramped_outputs(
        &mut self,
        cycles: u64,
        total_dv: Vol,
        out: &mut impl Outputs,
    ) -> Result<Report<R>, Fault> {
        // One cycle a tick but for a late tick's catch-up: no 64-bit division then (a
        // software routine on the M4, 65 instructions).
        let dv = if cycles <= 1 {
            total_dv
        } else {
            Vol(total_dv.0 / cycles as i64)
        };
        for _ in 0..cycles {
            self.push_frame(dv);
        }
        let target = self.ramp.position(&self.step_ramps);
        if let Err(f) = self.move_head(target, cycles, out) {
            self.safe_state(f, out);
            return Err(f);
        }
        if let Err(f) = self.move_plungers(true, cycles, out) {
            self.safe_state(f, out);
            return Err(f);
        }
        self.set_valves(self.ramp.current().valves, out);
        Ok(self.ramped_report_at(target))
    }

    /// Steps for head position `target` over `cycles`.
    #[inline(always)]
    fn move_head(
        &mut self,
        target: [R; 3],
        cycles: u64,
        out: &mut impl Outputs,
    ) -> Result<(), Fault> {
        self.steps
            .move_over(target, cycles as u32, out)
            .map_err(|e| Fault::StepRate {
                axis: e.axis,
                steps: e.steps,
                max: e.max,
            })
    }

    /// Syringe plungers (E axes): to the ramp window's current frame (`ramped`) or to the
    /// volume displaced so far.
    #[inline(always)]
    fn move_plungers(
        &mut self,
        ramped: bool,
        cycles: u64,
        out: &mut impl Outputs,
    ) -> Result<(), Fault> {
        if !self.machine.syringes {
            return Ok(());
        }
        let max = self.machine.motion.max_steps_per_cycle as u64 * cycles;
        for (i, inlet) in self.machine.inlets.iter().enumerate() {
            let Some(sy) = inlet.syringe else { continue };
            let target = if ramped {
                self.ramp.current().plunger[i] as i64
            } else {
                plunger_steps(self.plunger_vol[i], sy.steps_per_mm3) as i64
            };
            let d = target - self.plunger_steps[i];
            if d.unsigned_abs() > max {
                return Err(Fault::StepRate {
                    axis: Axis::E(i as u8),
                    steps: d.unsigned_abs().min(u32::MAX as u64) as u32,
                    max: max as u32,
                });
            }
            if d != 0 {
                out.step(Axis::E(i as u8), d > 0, d.unsigned_abs() as u32);
                self.plunger_steps[i] = target;
            }
        }
        Ok(())
    }

    /// Valves as decided.
    #[inline(always)]
    fn set_valves(&mut self, mask: u32, out: &mut impl Outputs) {
        if mask != self.valves_out {
            for i in 0..self.machine.inlet_count() {
                let bit = 1u32 << i;
                if (mask ^ self.valves_out) & bit != 0 {
                    out.valve(i as u8, mask & bit != 0);
                }
            }
            self.valves_out = mask;
        }
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

    fn report(&self) -> Report<R> {
        if self.ramped {
            self.ramped_report()
        } else {
            self.plan_report()
        }
    }

    /// The report of a machine without ramps: the plan is what the outputs show.
    fn plan_report(&self) -> Report<R> {
        Report {
            state: self.model_state(),
            position: self.head_pos,
            valves: self.valves_out,
            feeding: self.model.feeding(),
            landing: self.model.channel().landing(),
            q: self.last_q,
            dv: self.last_dv,
            speed: self.speed(),
            plan_volume: self.head,
            command_index: self.last_index,
            slugs: self.model.channel().len().min(u8::MAX as usize) as u8,
        }
    }

    /// Head speed along the print path (plan), mm/s: the last cycle's mean flow over the
    /// bead section (a late tick's catch-up included, whose summed volume would overstate
    /// it; and without converting the volume again).
    #[inline(always)]
    fn speed(&self) -> R {
        if matches!(self.phase, Phase::Print { .. }) {
            self.last_q * self.inv_s
        } else {
            R::ZERO
        }
    }

    /// The report with speed ramps: what the outputs show, half a window behind the plan.
    /// Out of line, so that machines without ramps do not carry it in their tick.
    fn ramped_report(&self) -> Report<R> {
        self.ramped_report_at(self.ramp.position(&self.step_ramps))
    }

    /// `ramped_report` with the window's mean position already worked out (the tick has
    /// it: the mean of the window costs about 70 instructions).
    #[inline(never)]
    fn ramped_report_at(&self, position: [R; 3]) -> Report<R> {
        let f = self.ramp.current();
        Report {
            state: self.state(),
            position,
            valves: self.valves_out,
            feeding: f.feeding,
            landing: f.landing,
            q: self.last_q,
            dv: Vol(f.dv as i64),
            speed: self.speed(),
            plan_volume: self.head,
            command_index: f.index,
            slugs: f.slugs,
        }
    }

    /// The cycle just planned enters the ramp window; `dv` is its volume alone
    /// (`last_dv` sums a catch-up's cycles). Out of line, as `ramped_report`.
    #[inline(never)]
    fn push_frame(&mut self, dv: Vol) {
        if self.ramp.narrowing() {
            // In tail position: the usual path keeps its registers.
            return self.push_frame_narrow(dv);
        }
        let mut f = self.frame();
        f.dv = dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        self.ramp.push(f, &mut self.step_ramps);
    }

    /// `push_frame` while a valve decision's window narrows the ramp's mean.
    #[inline(never)]
    fn push_frame_narrow(&mut self, dv: Vol) {
        let mut f = self.frame();
        f.dv = dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        self.ramp.push_narrow(f, &mut self.step_ramps);
    }

    /// Model, head and valve decisions for one cycle. Returns the volume extruded.
    fn cycle_once(&mut self) -> Result<Vol, Fault> {
        self.cycle += 1;
        if self.machine.syringes {
            let running = self.model.commanded();
            for (i, v) in self.plunger_vol.iter_mut().enumerate() {
                if running & (1 << i) != 0 {
                    *v += self.plunger_per_cycle[i];
                }
            }
        }
        let flow = self.model.step()?;
        self.last_q = flow.q;
        let dv = flow.dv;
        // Phases may hand over to the next within a cycle (end of bead -> travel ...);
        // each hand-over consumes a plan item, so this is bounded by the plan's length.
        let mut dv_left = dv;
        for _ in 0..=PLAN_CAPACITY {
            match self.phase {
                Phase::Print { stopping } => {
                    self.head += dv_left;
                    dv_left = Vol::ZERO;
                    if !self.follow_path(stopping, flow.q)? {
                        break;
                    }
                }
                Phase::Settle { cycles } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    let flow_done = !self.machine.motion.wait_for_flow_decay
                        || (flow.q <= self.machine.q_stop && self.model.commanded() == 0);
                    // A pause asked for waits here until the flow is at its rest flow
                    // (never past the settle limit: that is the fault's business).
                    let settled = flow_done
                        && (!self.pause.requested
                            || cycles >= self.settle_limit
                            || self.rest_reached(flow.q));
                    if settled {
                        self.phase = Phase::Idle;
                        continue;
                    }
                    if cycles > self.settle_limit {
                        return Err(Fault::FlowDidNotStop);
                    }
                    self.phase = Phase::Settle { cycles: cycles + 1 };
                    break;
                }
                Phase::Travel {
                    from,
                    dir,
                    trap,
                    cycles,
                } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    let t = self.dt * R::from_u32(cycles32(cycles + 1));
                    let d = trap.distance(t);
                    for a in 0..3 {
                        self.head_pos[a] = from[a] + dir[a] * d;
                    }
                    if t >= trap.duration() {
                        self.plan.pop_front();
                        self.phase = Phase::Idle;
                        continue;
                    }
                    self.phase = Phase::Travel {
                        from,
                        dir,
                        trap,
                        cycles: cycles + 1,
                    };
                    break;
                }
                Phase::Dwell { left } => {
                    self.lost += dv_left;
                    if left <= 1 {
                        self.plan.pop_front();
                        self.phase = Phase::Idle;
                    } else {
                        self.phase = Phase::Dwell { left: left - 1 };
                    }
                    break;
                }
                Phase::Idle => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    if !self.start_next()? {
                        break;
                    }
                }
                Phase::Pausing => {
                    self.head += dv_left;
                    dv_left = Vol::ZERO;
                    if self.follow_pause(flow.q)? {
                        continue;
                    }
                    break;
                }
                // Paused, the head holds still: what little still trickles below the
                // stop threshold (micrometres of bead) stays at the pause point, unless
                // a park moves the head away and back (valves shut).
                Phase::Paused { .. } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    if self.pause.park.stage != park::ParkStage::None {
                        self.park_cycle();
                        // Back from a park between beads: the next item starts now.
                        if matches!(self.phase, Phase::Idle) {
                            continue;
                        }
                    }
                    break;
                }
                Phase::Done | Phase::Aborted | Phase::Faulted(_) => {
                    self.lost += dv_left;
                    break;
                }
            }
        }
        if self.pause.requested && matches!(self.phase, Phase::Print { stopping: false }) {
            self.pause_check();
        }
        if matches!(self.phase, Phase::Print { .. }) {
            self.decide_valves()?;
        }
        Ok(dv)
    }

    /// Takes the next plan item when idle. Returns true if a new phase began that should
    /// see this cycle too.
    fn start_next(&mut self) -> Result<bool, Fault> {
        if self.pause.requested {
            self.pause_between_beads();
            return Ok(false);
        }
        let Some(item) = self.plan.front().copied() else {
            if !self.begun || self.ended {
                self.phase = if self.ended { Phase::Done } else { Phase::Idle };
            }
            return Ok(false);
        };
        match item {
            Item::Seg(seg) => {
                self.last_index = seg.index;
                self.head = seg.u_start;
                self.phase = Phase::Print { stopping: false };
                // Open the valve of the material the cursor stands on.
                self.want = Some(self.entry_material);
                if self.sizing {
                    self.size_ramp(Some(self.entry_material));
                }
                self.model.command(1 << self.entry_material);
                self.stop.reset();
                self.switch.reset();
                Ok(false)
            }
            Item::Travel { to, index } => {
                self.last_index = index;
                let from = self.head_pos;
                let mut delta = [R::ZERO; 3];
                let mut len2 = R::ZERO;
                for a in 0..3 {
                    delta[a] = to[a] - from[a];
                    len2 += delta[a] * delta[a];
                }
                let len = len2.sqrt();
                if len <= R::of(1e-6) {
                    self.head_pos = to;
                    self.plan.pop_front();
                    return Ok(true);
                }
                let mut dir = [R::ZERO; 3];
                let mut v = self.machine.motion.travel_speed;
                let mut acc = R::of(1e9);
                for a in 0..3 {
                    dir[a] = delta[a] / len;
                    let c = dir[a].abs();
                    if c > R::of(1e-9) {
                        v = v.min(self.machine.motion.max_speed[a] / c);
                        acc = acc.min(self.machine.motion.max_accel[a] / c);
                    }
                }
                self.phase = Phase::Travel {
                    from,
                    dir,
                    trap: Trapezoid::new(len, v, acc),
                    cycles: 0,
                };
                Ok(false)
            }
            Item::Dwell { cycles, index } => {
                self.last_index = index;
                self.phase = Phase::Dwell { left: cycles };
                Ok(false)
            }
            Item::End { index } => {
                self.last_index = index;
                self.plan.pop_front();
                self.phase = Phase::Done;
                Ok(false)
            }
        }
    }

    /// Moves the head to plan volume `self.head` along the current bead. Returns true
    /// when the bead ended and the next phase should run this cycle. Inlined into the
    /// tick's print path (a pause's tail calls it too, out of line).
    #[inline(always)]
    fn follow_path(&mut self, stopping: bool, q: R) -> Result<bool, Fault> {
        let inv_s = self.inv_s;
        let q_stop = self.machine.q_stop;
        let shut = self.model.commanded() == 0;
        for _ in 0..PLAN_CAPACITY {
            let Some(Item::Seg(seg)) = self.plan.front() else {
                // Printing with no segment queued: the feeder fell behind.
                return Err(Fault::Underrun);
            };
            self.last_index = seg.index;
            let past = self.head >= seg.u_end;
            // A tail that ran out short of the end: the rest is within the stop threshold.
            let tail_done = seg.last && stopping && q <= q_stop && shut;
            if past || tail_done {
                if seg.last {
                    let seg = *seg;
                    self.end_bead(seg, stopping);
                    return Ok(true);
                }
                self.plan.pop_front();
                if self.plan.is_empty() {
                    return Err(Fault::Underrun);
                }
                continue;
            }
            let off = (self.head - seg.u_start).mm3::<R>() * inv_s;
            if off <= seg.len {
                self.head_pos[0] = seg.start[0] + seg.dir[0] * off;
                self.head_pos[1] = seg.start[1] + seg.dir[1] * off;
            } else if let Some(f) = &seg.fillet {
                let p = f.point((off - seg.len).min(f.length()));
                self.head_pos[0] = p[0];
                self.head_pos[1] = p[1];
            }
            return Ok(false);
        }
        Ok(false)
    }

    fn end_bead(&mut self, seg: Seg<R>, stopping: bool) {
        if !stopping || self.model.commanded() != 0 {
            self.model.command(0);
            self.want = None;
        }
        // Volume past the end stays where the head stops.
        if self.head > seg.u_end {
            self.lost += self.head - seg.u_end;
        }
        // The head stays where the paste ran out: a tail that delivered less than the
        // bead's rest leaves it a little short, rather than jumping the gap dry. The plan
        // clock moves on to the end so the next bead's boundaries keep their volumes.
        if self.head < seg.u_end {
            self.short = self.short.max(seg.u_end - self.head);
        }
        self.head = seg.u_end;
        self.ends.pop_front();
        self.plan.pop_front();
        self.switch.reset();
        self.stop.reset();
        self.phase = Phase::Settle { cycles: 0 };
    }

    /// Valve decisions while printing: switch material when the cursor (head + transit
    /// volume + predicted switch lead) reaches the next boundary; stop the flow when the
    /// head plus the predicted tail reaches the bead's end.
    fn decide_valves(&mut self) -> Result<(), Fault> {
        if !matches!(self.phase, Phase::Print { .. }) {
            return Ok(());
        }
        let entry = self.head + self.machine.v_transit();
        // Of several boundaries already behind the cursor only the last still matters.
        // They are in plan order, so while the first is ahead none is behind (the usual
        // case, checked without walking the queue).
        while self.boundaries.front().is_some_and(|b| b.0 <= entry)
            && self.boundaries.iter().nth(1).is_some_and(|b| b.0 <= entry)
        {
            self.boundaries.pop_front();
        }
        if let Some(known) = self.known_to {
            if known < entry + self.window {
                return Err(if self.room() == 0 {
                    Fault::LookaheadFull
                } else {
                    Fault::Underrun
                });
            }
        }
        // Material switch.
        let mut switched = false;
        if let Some(&(u_b, m)) = self.boundaries.front() {
            if m == self.entry_material {
                // Already the material entering: nothing to switch.
                if entry >= u_b {
                    self.boundaries.pop_front();
                }
            } else if entry + self.window >= u_b {
                // Behind the cursor already (job start, or a lead the prediction missed):
                // switch at once; otherwise when the predicted lead says so.
                let due = entry >= u_b
                    || self
                        .switch
                        .answer(&self.model, Goal::Switch(m))
                        .is_some_and(|lead| entry + Vol::from_mm3(lead) >= u_b);
                if !due && self.work(0) {
                    self.switch.work(&self.model);
                }
                if due {
                    if self.sizing {
                        self.size_ramp(Some(m));
                    }
                    self.model.command(1 << m);
                    self.want = Some(m);
                    self.entry_material = m;
                    self.boundaries.pop_front();
                    self.switch.reset();
                    self.stop.reset();
                    switched = true;
                }
            }
        }
        // End of the bead.
        if let Some(end) = self.bead_end() {
            if self.model.commanded() != 0 && self.head + self.window >= end {
                let due = self
                    .stop
                    .answer(&self.model, Goal::Stop)
                    .is_some_and(|tail| self.head + Vol::from_mm3(tail) >= end);
                if due {
                    if self.sizing {
                        self.size_ramp(None);
                    }
                    self.model.command(0);
                    self.want = None;
                    self.phase = Phase::Print { stopping: true };
                    self.stop.reset();
                } else if self.work(1) && !switched {
                    self.stop.work(&self.model);
                }
            }
        }
        Ok(())
    }

    /// Sizes the ramp window for the valve command about to be made (`opening` the inlet
    /// it opens, none to stop): once per decision, from the channel's contents now
    /// (`crate::switch_window`); the machine's window where those do not say.
    #[inline(never)]
    fn size_ramp(&mut self, opening: Option<u8>) {
        let (head, inv_s) = (self.head, self.inv_s);
        let seg = |i: &Item<R>| match i {
            Item::Seg(s) => Some(*s),
            _ => None,
        };
        let f2 = |v: V2<R>| [v[0].to_f32(), v[1].to_f32()];
        // The bead's turns ahead: each segment's fillet into the next, to the bead's end.
        let turns = (self.plan.iter().map_while(seg))
            .zip(self.plan.iter().skip(1).map_while(seg))
            .take_while(|(a, _)| !a.last)
            .filter_map(|(a, b)| {
                let f = a.fillet?;
                Some(crate::switch_window::Turn {
                    at: ((a.u_arc - head).mm3::<R>() * inv_s).to_f32(),
                    radius: f.radius.to_f32(),
                    from: f2(a.dir),
                    to: f2(b.dir),
                })
            });
        let h = crate::switch_window::switch_half(
            &self.machine,
            &self.model,
            self.model.commanded(),
            opening,
            turns,
        )
        .unwrap_or(self.machine.ramp_cycles / 2);
        self.ramp.set_goal(h);
    }

    /// Whether prediction work of the kind whose turn falls on cycles of `parity` runs
    /// this cycle. The kinds take turns; a cycle whose flow step took its slow path
    /// (a slug start crossing the exit or landing) does none, nor does one that
    /// commanded a switch or a stop, so that the dearest steps and a prediction unit never
    /// share a cycle. These come a few times per material change, so the predictions lose
    /// a unit or two per switch.
    fn work(&self, parity: u64) -> bool {
        self.cycle % 2 == parity && !self.model.crossed()
    }

    /// Plan volume where the current bead ends, if its last segment is planned.
    fn bead_end(&self) -> Option<Vol> {
        self.ends.front().copied()
    }

    fn check_limits(&self, p: [R; 3]) -> Result<(), Fault> {
        for (a, axis) in Axis::ALL.iter().enumerate() {
            if !(p[a] >= self.machine.motion.min_mm[a] && p[a] <= self.machine.motion.max_mm[a]) {
                return Err(Fault::Limit { axis: *axis });
            }
        }
        Ok(())
    }

    /// Turns a command into plan items and boundaries.
    fn plan_command(&mut self, cmd: Command) -> Result<(), Fault> {
        if self.ended {
            return Err(Fault::InvalidCommand(CommandError::AfterEnd));
        }
        let index = self.commands;
        match cmd {
            Command::Print { dx, dy, material } => {
                if material as usize >= self.machine.inlet_count() {
                    return Err(Fault::InvalidCommand(CommandError::NoSuchInlet {
                        material,
                        inlets: self.machine.inlet_count() as u8,
                    }));
                }
                let (dxl, dyl) = (dx as i64, dy as i64);
                if dxl.abs() > MAX_SEGMENT_UM || dyl.abs() > MAX_SEGMENT_UM {
                    return Err(Fault::InvalidCommand(CommandError::SegmentTooLong));
                }
                let from_um = self.design_um;
                let to_um = [
                    sat_i32(from_um[0] as i64 + dxl),
                    sat_i32(from_um[1] as i64 + dyl),
                    from_um[2],
                ];
                let to3 = [um(to_um[0]), um(to_um[1]), um(to_um[2])];
                self.check_limits(to3)?;
                if dx == 0 && dy == 0 {
                    return Ok(());
                }
                self.design_um = to_um;
                let from = [um::<R>(from_um[0]), um(from_um[1])];
                let to = [to3[0], to3[1]];
                let length = R::of(((dxl * dxl + dyl * dyl) as f64).sqrt() * 1e-3);
                let dir = [(to[0] - from[0]) / length, (to[1] - from[1]) / length];
                let (t_start, u_start) = match self.open.take() {
                    Some(prev) => {
                        let (seg, t) = self.finalise(prev, Some((dir, length)));
                        let _ = self.plan.push_back(Item::Seg(seg));
                        if seg.material != material {
                            let mid = seg.u_arc + Vol((seg.u_end - seg.u_arc).0 / 2);
                            let _ = self.boundaries.push_back((mid, material));
                        }
                        self.last_final = Some((seg.material, seg.u_end));
                        self.known_to = Some(seg.u_end);
                        (t, seg.u_end)
                    }
                    None => {
                        let (m, u) = self.last_final.unwrap_or((material, Vol::ZERO));
                        if m != material {
                            let _ = self.boundaries.push_back((u, material));
                        }
                        (R::ZERO, u)
                    }
                };
                self.open = Some(Open {
                    material,
                    from,
                    to,
                    dir,
                    length,
                    t_start,
                    u_start,
                    index,
                });
                Ok(())
            }
            Command::Travel { x, y, z } => {
                let to = [um(x), um(y), um(z)];
                self.check_limits(to)?;
                self.close_bead();
                self.design_um = [x, y, z];
                let _ = self.plan.push_back(Item::Travel { to, index });
                Ok(())
            }
            Command::Layer { z } => {
                let [x, y, _] = self.design_um;
                let to = [um(x), um(y), um(z)];
                self.check_limits(to)?;
                self.close_bead();
                self.design_um[2] = z;
                let _ = self.plan.push_back(Item::Travel { to, index });
                Ok(())
            }
            Command::Dwell { ms } => {
                if ms > MAX_DWELL_MS {
                    return Err(Fault::InvalidCommand(CommandError::DwellTooLong { ms }));
                }
                self.close_bead();
                let cycles = (ms as u64 * 1000).div_ceil(self.machine.period_us as u64);
                let _ = self.plan.push_back(Item::Dwell { cycles, index });
                Ok(())
            }
            Command::End => {
                self.close_bead();
                let _ = self.plan.push_back(Item::End { index });
                self.ended = true;
                self.known_to = None;
                Ok(())
            }
        }
    }

    /// Finalises the open segment as the last of its bead.
    fn close_bead(&mut self) {
        if let Some(prev) = self.open.take() {
            let (seg, _) = self.finalise(prev, None);
            let _ = self.plan.push_back(Item::Seg(seg));
            let _ = self.ends.push_back(seg.u_end);
            self.last_final = Some((seg.material, seg.u_end));
            self.known_to = Some(seg.u_end);
        }
    }

    /// Fixes an open segment's end: the fillet into `next` (direction, length), or the
    /// bead's end. Returns the segment and the tangent length the next one starts with.
    fn finalise(&self, o: Open<R>, next: Option<(V2<R>, R)>) -> (Seg<R>, R) {
        let s = self.machine.bead_area;
        let f = next.and_then(|(d2, l2)| {
            // This segment's fillet may use all of it that the previous fillet left; the next
            // segment keeps half for its own far end.
            let max_t = (o.length - o.t_start).min(l2 * R::HALF);
            fillet(o.to, o.dir, d2, self.machine.corner_radius, max_t)
        });
        let t_end = f.map(|f| f.tangent).unwrap_or(R::ZERO);
        let len = (o.length - o.t_start - t_end).max(R::ZERO);
        let start = [
            o.from[0] + o.dir[0] * o.t_start,
            o.from[1] + o.dir[1] * o.t_start,
        ];
        let u_arc = o.u_start + Vol::from_mm3(len * s);
        let u_end = u_arc
            + f.map(|f| Vol::from_mm3(f.length() * s))
                .unwrap_or(Vol::ZERO);
        (
            Seg {
                material: o.material,
                start,
                dir: o.dir,
                len,
                fillet: f,
                u_start: o.u_start,
                u_arc,
                u_end,
                last: next.is_none(),
                index: o.index,
            },
            t_end,
        )
    }
}

/// Cycles a bead's end may take to settle before the flow counts as not stopping.
fn settle_limit<R: Real, const N: usize>(machine: &Machine<R, N>) -> u64 {
    // Ten times the slowest line's dead time plus eight time constants, at least 1 s.
    let mut s = R::ONE;
    for i in machine.inlets.iter() {
        s = s.max(R::of(10.0) * (i.close_delay_s + R::of(8.0) * i.decay_s));
    }
    (s / machine.dt()).round_i64().max(1) as u64
}

/// A plunger's step target for the volume it displaced. Step counts fit i32 (2^31 steps
/// is a thousand litres); beyond, the saturated target becomes a step-rate fault.
#[inline]
fn plunger_steps<R: Real>(v: Vol, steps_per_mm3: R) -> i32 {
    (v.mm3::<R>() * steps_per_mm3).round_i32()
}

/// A cycle count as u32 for one-instruction conversion (saturates after 5 days at 10 kHz).
fn cycles32(c: u64) -> u32 {
    c.min(u32::MAX as u64) as u32
}

fn um<R: Real>(v: i32) -> R {
    R::of(v as f64 * 1e-3)
}

fn sat_i32(v: i64) -> i32 {
    v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

/// How far ahead of a boundary (as volume) predictions start: the most that can flow at
/// top speed during the slowest valve's dead time plus eight time constants (or a
/// syringe's time to 90 % response), plus 2 ms.
fn lead_window<R: Real, const N: usize>(m: &Machine<R, N>) -> Vol {
    let mut t = R::of(0.002);
    let mut worst = R::ZERO;
    for i in m.inlets.iter() {
        let d = match i.syringe.filter(|_| m.syringes) {
            // A syringe's switch and its tail are over well before 90 % of its response.
            Some(sy) => R::of(libm::pow(
                core::f64::consts::LN_10 / sy.lag_k.to_f64(),
                1.0 / sy.lag_n.to_f64(),
            )),
            None => i.open_delay_s.max(i.close_delay_s) + R::of(8.0) * i.rise_s.max(i.decay_s),
        };
        worst = worst.max(d);
    }
    t += worst;
    Vol::from_mm3(m.v_flow_max * m.bead_area * t)
}

/// Acceleration each step's own ramp may use (`crate::step_ramps`), mm/s^2: the ramps'
/// share of the X/Y limit, as the machine's window has, less what the flow's smooth
/// change under the ramp may add (the channel's contents changing as it flushes: the head
/// speed moves by at most `v_flow_max` over the channel's volume of bead, at up to
/// `v_flow_max`). The machine's one window, sized for the largest step, left that room
/// under every smaller step; a window sized to the step leaves none (measured: 2 064
/// mm/s^2 on a 2 000 machine at a bead's end just after a switch, without this).
pub fn step_ramp_accel<R: Real, const N: usize>(m: &Machine<R, N>) -> f32 {
    let a = m.motion.max_accel[0].min(m.motion.max_accel[1]).to_f32()
        * crate::config::RAMP_SHARE as f32;
    let v = m.v_flow_max.to_f32();
    let along = m.v_channel.mm3::<f32>() / m.bead_area.to_f32();
    let smooth = if along > 0.0 { v * v / along } else { 0.0 };
    // Under a quarter of the limit left: every step keeps the machine's window.
    if a - smooth > 0.25 * a {
        a - smooth
    } else {
        0.0
    }
}
