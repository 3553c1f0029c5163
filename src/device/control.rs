//! The control loop's logic, one `tick` per control period: takes orders and job records
//! from the link, runs the executor (jobs), homing, jogs and the valve test, watches the
//! e-stop input, and publishes a snapshot. Every halt goes through `halt`, which drives
//! the outputs to the safe state. Timers, pins and the watchdog itself are the board's.

use super::safety::{force_safe, Commanded, Tracked};
use super::{BoardMachine, ControlOrder, FromLink, LEAD_IN};
use crate::command::Command;
use crate::config::Config;
use crate::executor::{Executor, Fault, Report, RunState};
use crate::motion::Trapezoid;
use crate::outputs::{Axis, Outputs};
use crate::wire::{Halt, LinkLossPolicy, Mode, Settings, Snapshot};

/// The executor the board runs: f32 (the M4's FPU), four inlets.
pub type Exec = Executor<f32, { crate::DEFAULT_INLETS }>;

/// The executor, built at compile time with no machine, and whether a config has been
/// loaded into it. It is never moved or rebuilt: configs load in place.
struct ExecSlot {
    exec: Exec,
    loaded: bool,
}

impl ExecSlot {
    fn as_ref(&self) -> Option<&Exec> {
        self.loaded.then_some(&self.exec)
    }
    fn as_mut(&mut self) -> Option<&mut Exec> {
        self.loaded.then_some(&mut self.exec)
    }
    fn is_none(&self) -> bool {
        !self.loaded
    }
}

/// Orders taken per tick: orders are rare, and each may cost a whole plan's reset.
pub const ORDERS_PER_TICK: usize = 2;
/// Job commands planned per tick (each is a few microseconds of planning); 8 per 100 us
/// refills the 256-item plan in 3 ms, far faster than any bead consumes it.
pub const PUSHES_PER_TICK: usize = 8;
/// Stale job records (of an aborted job) dropped per tick.
pub const DISCARDS_PER_TICK: usize = 64;
/// Longest gap between two ticks (us) after which a tick does not feed the watchdog:
/// a control loop that lost this much time is not healthy.
pub const HEALTHY_GAP_US: u64 = 10_000;

/// Inputs the board samples for every tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inputs {
    /// Emergency stop active (pin level, or latched by its interrupt).
    pub estop: bool,
    /// Endstop triggered, per axis.
    pub endstops: [bool; 3],
}

/// Why the board last started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// Power-on, reset pin or a requested reset.
    PowerOn,
    /// The independent watchdog expired (the control loop stopped, or a panic).
    Watchdog,
}

/// What a tick tells the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tick {
    /// The loop is healthy: feed the watchdog.
    pub feed_watchdog: bool,
}

#[derive(Clone, Copy, Debug)]
enum HomePhase {
    /// Moving off an endstop that was already triggered.
    Release,
    /// Moving towards the endstop.
    Seek,
    /// Moving back off it after it triggered.
    Backoff { left: u32 },
}

#[derive(Clone, Copy, Debug)]
struct Homing {
    index: usize,
    phase: HomePhase,
    moved: u32,
    frac: f32,
}

#[derive(Clone, Copy, Debug)]
struct Jog {
    axis: Axis,
    from_mm: f32,
    sign: f32,
    trap: Trapezoid<f32>,
    cycles: u32,
}

#[derive(Clone, Copy, Debug)]
enum Active {
    Idle,
    Homing(Homing),
    Jog(Jog),
    ValveTest,
    Job,
    Halted,
}

/// What the loop does first after `reset`: idle, or halted saying the watchdog bit.
const fn start_state(reset: ResetCause) -> (Active, Option<Halt>) {
    match reset {
        ResetCause::PowerOn => (Active::Idle, None),
        ResetCause::Watchdog => (Active::Halted, Some(Halt::Fault(Fault::Watchdog))),
    }
}

/// The control loop.
pub struct Control {
    exec: ExecSlot,
    settings: Settings,
    active: Active,
    halt: Option<Halt>,
    homed: bool,
    cmd: Commanded,
    last_now: Option<u64>,
    exec_now: u64,
    exec_ticking: bool,
    epoch: u8,
    held: Option<Command>,
    report: Option<Report<f32>>,
    estop: bool,
}

impl Control {
    /// The control loop after a reset: nothing configured, outputs to be made safe by
    /// `power_up`. After a watchdog reset it starts halted, so the user learns why.
    pub const fn new(reset: ResetCause) -> Self {
        let (active, halt) = start_state(reset);
        Control {
            exec: ExecSlot {
                exec: Exec::unconfigured(),
                loaded: false,
            },
            settings: Settings::DEFAULT,
            active,
            halt,
            homed: false,
            cmd: Commanded::ZERO,
            last_now: None,
            exec_now: 0,
            exec_ticking: false,
            epoch: 0,
            held: None,
            report: None,
            estop: false,
        }
    }

    /// Records why the board started, for a `Control` built before it was known (the
    /// board's is built at compile time): after a watchdog reset it starts halted.
    pub fn set_reset_cause(&mut self, reset: ResetCause) {
        (self.active, self.halt) = start_state(reset);
    }

    /// Drives the outputs to the safe state; the board calls this before anything else.
    pub fn power_up(&mut self, out: &mut impl Outputs) {
        force_safe(&mut Tracked {
            out,
            state: &mut self.cmd,
        });
    }

    /// Loads a config directly (boards with a built-in config; the link uses the
    /// mailbox). Refused while anything moves.
    pub fn load_config(&mut self, config: &Config, out: &mut impl Outputs) -> Result<(), Halt> {
        match config.validate::<f32, { crate::DEFAULT_INLETS }>() {
            Ok(m) => {
                self.load_machine(m);
                Ok(())
            }
            Err(_) if !self.exec.loaded => {
                // Nothing was configured, so nothing is wrong with the machine: just refused.
                Err(Halt::Fault(Fault::InvalidConfig))
            }
            Err(_) => {
                // The machine it was told about is wrong: safe state until cleared.
                let h = Halt::Fault(Fault::InvalidConfig);
                self.halt_with(h, out);
                Err(h)
            }
        }
    }

    /// Loads a validated machine (what the link hands over: it validates in thread mode,
    /// so the control interrupt only fills the model's tables, in place). Ignored while
    /// anything moves.
    pub fn load_machine(&mut self, machine: BoardMachine) {
        if !matches!(self.active, Active::Idle | Active::Halted) {
            return;
        }
        if self.exec.exec.load_machine(machine).is_ok() {
            self.exec.loaded = true;
            // New steps per mm or limits: the old position means nothing.
            self.homed = false;
        }
    }

    /// What the loop is doing (the snapshot's `mode`, without the rest of it).
    pub fn mode(&self) -> Mode {
        match (self.exec.as_ref(), self.active) {
            (_, Active::Halted) => Mode::Halted,
            (None, _) => Mode::Unconfigured,
            (_, Active::Idle) => Mode::Idle,
            (_, Active::Homing(_)) => Mode::Homing,
            (_, Active::Jog(_)) => Mode::Jogging,
            (_, Active::ValveTest) => Mode::ValveTest,
            (_, Active::Job) => Mode::Job,
        }
    }

    /// The snapshot as of the last tick.
    pub fn snapshot(&self) -> Snapshot {
        let mode = self.mode();
        let (run, command, speed, q) = match (&self.report, self.exec.as_ref()) {
            (Some(r), Some(e)) => (
                e.status_state(),
                r.command_index.saturating_sub(LEAD_IN),
                r.speed,
                r.q,
            ),
            (None, Some(e)) => (e.status_state(), 0, 0.0, 0.0),
            _ => (RunState::Idle, 0, 0.0, 0.0),
        };
        let mut position_um = [0i32; 3];
        if let Some(e) = self.exec.as_ref() {
            let spm = e.machine().motion.steps_per_mm;
            for a in 0..3 {
                let mm = self.cmd.steps[a] as f32 / spm[a];
                position_um[a] = libm::roundf(mm * 1000.0) as i32;
            }
        }
        Snapshot {
            mode,
            run,
            halt: self.halt,
            homed: self.homed,
            estop: self.estop,
            drivers: self.cmd.drivers,
            valves: (self.cmd.valves & 0xFF) as u8,
            position_um,
            command,
            epoch: self.epoch,
            speed_mm_s: speed,
            q_mm3_s: q,
            pause_point_um: self.exec.as_ref().and_then(|e| e.pause_point_um()),
        }
    }

    /// What the outputs were last commanded to.
    pub fn commanded(&self) -> Commanded {
        self.cmd
    }

    /// The board settings in force.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The executor, once a config is loaded.
    pub fn executor(&self) -> Option<&Exec> {
        self.exec.as_ref()
    }

    /// One control period at `now_us` (the board's microsecond clock).
    pub fn tick(
        &mut self,
        now_us: u64,
        inputs: Inputs,
        link: &mut impl FromLink,
        out: &mut impl Outputs,
    ) -> Tick {
        let gap = self.last_now.map(|p| now_us.saturating_sub(p));
        self.last_now = Some(now_us);
        let healthy = gap.is_none_or(|g| g <= HEALTHY_GAP_US);

        self.estop = inputs.estop;
        if inputs.estop && self.halt != Some(Halt::Fault(Fault::EStop)) {
            self.halt_with(Halt::Fault(Fault::EStop), out);
        }
        if let Some(machine) = link.take_config() {
            self.load_machine(machine);
        }
        for _ in 0..ORDERS_PER_TICK {
            let Some(order) = link.next_order() else {
                break;
            };
            self.order(order, inputs, out);
        }
        self.run(gap, inputs, link, out);
        if !self.cmd.drivers {
            // Motors without holding current can be pushed: the position is gone.
            self.homed = false;
        }
        link.publish(&self.snapshot());
        Tick {
            feed_watchdog: healthy,
        }
    }

    /// The one way into the safe state: executor faulted (if any), valves closed,
    /// drivers off, mode halted until `ClearFault`.
    fn halt_with(&mut self, why: Halt, out: &mut impl Outputs) {
        let mut t = Tracked {
            out,
            state: &mut self.cmd,
        };
        if let Some(e) = self.exec.as_mut() {
            match why {
                Halt::Fault(f) => e.fault(f, &mut t),
                // The executor knows nothing of homing; stopping it is what matters.
                Halt::HomingFailed { .. } => e.abort(&mut t),
            }
        }
        force_safe(&mut t);
        self.active = Active::Halted;
        self.halt = Some(why);
        self.held = None;
        self.exec_ticking = false;
    }

    fn order(&mut self, order: ControlOrder, inputs: Inputs, out: &mut impl Outputs) {
        let halted = matches!(self.active, Active::Halted);
        match order {
            ControlOrder::EStop => self.halt_with(Halt::Fault(Fault::EStop), out),
            ControlOrder::ClearFault => {
                if halted && !inputs.estop {
                    if let Some(e) = self.exec.as_mut() {
                        e.clear_fault();
                    }
                    self.halt = None;
                    self.active = Active::Idle;
                }
            }
            ControlOrder::LoadConfig => {}
            ControlOrder::Settings(s) => {
                if s.check().is_ok() && !matches!(self.active, Active::Homing(_)) {
                    self.settings = s;
                }
            }
            _ if halted || self.exec.is_none() => {}
            ControlOrder::Abort => self.abort(out),
            ControlOrder::Pause => {
                if let (Active::Job, Some(e)) = (self.active, self.exec.as_mut()) {
                    e.pause();
                }
            }
            ControlOrder::Park => {
                if let (Active::Job, Some(e)) = (self.active, self.exec.as_mut()) {
                    e.park();
                }
            }
            // Refused by the executor when not parked or not a syringe machine; the
            // link has checked that a job is paused.
            ControlOrder::Refill => {
                if let (Active::Job, Some(e)) = (self.active, self.exec.as_mut()) {
                    let _ = e.refill();
                }
            }
            ControlOrder::Resume => {
                if let (Active::Job, Some(e)) = (self.active, self.exec.as_mut()) {
                    // The link refuses a resume with nothing paused; one racing the
                    // pause's end changes nothing.
                    let _ = e.resume();
                }
            }
            ControlOrder::LinkLost(policy) => match self.active {
                Active::Job => match policy {
                    LinkLossPolicy::Pause => {
                        if let Some(e) = self.exec.as_mut() {
                            e.pause();
                        }
                    }
                    LinkLossPolicy::Stop => self.halt_with(Halt::Fault(Fault::LinkLost), out),
                },
                // Hand moves and valve tests need someone watching.
                Active::Homing(_) | Active::Jog(_) | Active::ValveTest => self.abort(out),
                _ => {}
            },
            ControlOrder::Home => {
                if matches!(self.active, Active::Idle) {
                    Tracked {
                        out,
                        state: &mut self.cmd,
                    }
                    .drivers(true);
                    self.homed = false;
                    self.active = Active::Homing(Homing {
                        index: 0,
                        phase: HomePhase::Release,
                        moved: 0,
                        frac: 0.0,
                    });
                }
            }
            ControlOrder::Jog { axis, um } => self.start_jog(axis, um, out),
            ControlOrder::Valve { inlet, open } => {
                let inlets = self.exec.as_ref().map_or(0, |e| e.machine().inlet_count());
                if matches!(self.active, Active::Idle | Active::ValveTest)
                    && (inlet as usize) < inlets
                {
                    let mut t = Tracked {
                        out,
                        state: &mut self.cmd,
                    };
                    t.valve(inlet, open);
                    self.active = if self.cmd.valves != 0 {
                        Active::ValveTest
                    } else {
                        Active::Idle
                    };
                }
            }
            ControlOrder::Start {
                epoch,
                start_um,
                initial_material,
            } => self.start(epoch, start_um, initial_material, out),
        }
    }

    /// Abort: stop whatever runs, valves closed, drivers off; back to idle (not halted).
    fn abort(&mut self, out: &mut impl Outputs) {
        let mut t = Tracked {
            out,
            state: &mut self.cmd,
        };
        if let Some(e) = self.exec.as_mut() {
            if matches!(self.active, Active::Job) {
                e.abort(&mut t);
                e.clear_fault();
            }
        }
        force_safe(&mut t);
        self.held = None;
        self.exec_ticking = false;
        self.active = Active::Idle;
    }

    fn position_mm(&self, axis: usize) -> f32 {
        match self.exec.as_ref() {
            Some(e) => self.cmd.steps[axis] as f32 / e.machine().motion.steps_per_mm[axis],
            None => 0.0,
        }
    }

    fn start_jog(&mut self, axis: Axis, um: i32, out: &mut impl Outputs) {
        let Some(e) = self.exec.as_ref() else { return };
        if !matches!(self.active, Active::Idle) || !self.homed || um == 0 {
            return;
        }
        let m = &e.machine().motion;
        let a = axis.index();
        if a >= 3 {
            // Plungers move only in a job (the link refuses such jogs by name).
            return;
        }
        let from = self.position_mm(a);
        let to = from + um as f32 * 1e-3;
        // The link refuses such jogs with the numbers; this is the last line of defence.
        if !(to >= m.min_mm[a] && to <= m.max_mm[a]) {
            return;
        }
        let v = m.travel_speed.min(m.max_speed[a]);
        let trap = Trapezoid::new((to - from).abs(), v, m.max_accel[a]);
        Tracked {
            out,
            state: &mut self.cmd,
        }
        .drivers(true);
        self.active = Active::Jog(Jog {
            axis,
            from_mm: from,
            sign: if to >= from { 1.0 } else { -1.0 },
            trap,
            cycles: 0,
        });
    }

    fn start(&mut self, epoch: u8, start_um: [i32; 3], material: u8, out: &mut impl Outputs) {
        let Some(e) = self.exec.as_mut() else { return };
        if !matches!(self.active, Active::Idle) || !self.homed {
            return;
        }
        let spm = e.machine().motion.steps_per_mm;
        let mut here = [0i32; 3];
        for a in 0..3 {
            here[a] = libm::roundf(self.cmd.steps[a] as f32 / spm[a] * 1000.0) as i32;
        }
        if let Err(f) = e.begin(here, material) {
            self.halt_with(Halt::Fault(f), out);
            return;
        }
        // Lead-in: up to the higher of the two heights, across, down onto the start.
        let z = here[2].max(start_um[2]);
        let lead = [
            Command::Travel {
                x: here[0],
                y: here[1],
                z,
            },
            Command::Travel {
                x: start_um[0],
                y: start_um[1],
                z,
            },
            Command::Travel {
                x: start_um[0],
                y: start_um[1],
                z: start_um[2],
            },
        ];
        for c in lead {
            if e.push(c).is_err() {
                // The start point lies outside the travel: the executor latched the fault.
                break;
            }
        }
        self.epoch = epoch;
        self.held = None;
        self.report = None;
        self.exec_ticking = false;
        self.active = Active::Job;
    }

    fn run(
        &mut self,
        gap: Option<u64>,
        inputs: Inputs,
        link: &mut impl FromLink,
        out: &mut impl Outputs,
    ) {
        match self.active {
            Active::Job => self.run_job(gap, link, out),
            Active::Homing(h) => {
                self.discard_stale(link);
                self.run_homing(h, inputs, out);
            }
            Active::Jog(j) => {
                self.discard_stale(link);
                self.run_jog(j, out);
            }
            Active::Halted => {
                self.discard_stale(link);
                // Hold the safe state every cycle, whatever else touched the pins.
                force_safe(&mut Tracked {
                    out,
                    state: &mut self.cmd,
                });
            }
            Active::Idle | Active::ValveTest => self.discard_stale(link),
        }
    }

    /// Drops job records that belong to no running job (an aborted one's tail).
    fn discard_stale(&mut self, link: &mut impl FromLink) {
        for _ in 0..DISCARDS_PER_TICK {
            if link.next_command().is_none() {
                break;
            }
        }
    }

    fn run_job(&mut self, gap: Option<u64>, link: &mut impl FromLink, out: &mut impl Outputs) {
        let Some(e) = self.exec.as_mut() else { return };
        for _ in 0..PUSHES_PER_TICK {
            if e.room() == 0 {
                break;
            }
            let cmd = match self.held.take() {
                Some(c) => c,
                None => {
                    let mut found = None;
                    for _ in 0..DISCARDS_PER_TICK {
                        match link.next_command() {
                            Some(r) if r.epoch == self.epoch => {
                                found = Some(r.cmd);
                                break;
                            }
                            Some(_) => continue,
                            None => break,
                        }
                    }
                    match found {
                        Some(c) => c,
                        None => break,
                    }
                }
            };
            match e.push(cmd) {
                Ok(()) => {}
                Err(crate::executor::PushError::Full) => {
                    self.held = Some(cmd);
                    break;
                }
                // Latched: the executor faults on this tick.
                Err(crate::executor::PushError::Rejected(_)) => break,
            }
        }
        // The executor's clock runs only while it has a job, so time spent idle (flash
        // erases stall the chip) is not lateness; during a job every real microsecond
        // counts, and a late loop faults.
        let period = e.machine().period_us as u64;
        self.exec_now += match (self.exec_ticking, gap) {
            (true, Some(g)) => g,
            _ => period,
        };
        self.exec_ticking = true;
        let mut t = Tracked {
            out,
            state: &mut self.cmd,
        };
        match e.tick(self.exec_now, &mut t) {
            Ok(r) => {
                self.report = Some(r);
                if matches!(r.state, RunState::Done | RunState::Aborted) {
                    self.active = Active::Idle;
                    self.exec_ticking = false;
                }
            }
            Err(f) => self.halt_with(Halt::Fault(f), out),
        }
    }

    fn run_homing(&mut self, mut h: Homing, inputs: Inputs, out: &mut impl Outputs) {
        let Some(e) = self.exec.as_ref() else { return };
        let m = &e.machine().motion;
        let dt = e.machine().dt();
        let axis = self.settings.home_order[h.index.min(2)];
        let a = axis.index();
        let spm = m.steps_per_mm[a];
        let to_max = self.settings.home_to_max[a];
        let per_cycle =
            (self.settings.home_speed_mm_s * spm * dt).min(m.max_steps_per_cycle as f32);
        h.frac += per_cycle;
        let n = libm::floorf(h.frac) as u32;
        h.frac -= n as f32;
        let travel = (m.max_mm[a] - m.min_mm[a]) * 1.25 + 10.0;
        let seek_limit = (travel * spm) as u32;
        let release_limit = ((self.settings.home_backoff_mm * 4.0 + 5.0) * spm) as u32;
        let hit = inputs.endstops[a];
        let mut t = Tracked {
            out,
            state: &mut self.cmd,
        };
        match h.phase {
            HomePhase::Release => {
                if !hit {
                    h.phase = HomePhase::Seek;
                    h.moved = 0;
                } else if h.moved > release_limit {
                    self.halt_with(Halt::HomingFailed { axis }, out);
                    return;
                } else if n > 0 {
                    t.step(axis, !to_max, n);
                    h.moved += n;
                }
            }
            HomePhase::Seek => {
                if hit {
                    let home_mm = if to_max { m.max_mm[a] } else { m.min_mm[a] };
                    t.state.steps[a] = libm::roundf(home_mm * spm) as i64;
                    let left = (self.settings.home_backoff_mm * spm) as u32;
                    h.phase = HomePhase::Backoff { left };
                } else if h.moved > seek_limit {
                    self.halt_with(Halt::HomingFailed { axis }, out);
                    return;
                } else if n > 0 {
                    t.step(axis, to_max, n);
                    h.moved += n;
                }
            }
            HomePhase::Backoff { left } => {
                let k = n.min(left);
                if k > 0 {
                    t.step(axis, !to_max, k);
                }
                if left - k == 0 {
                    h = Homing {
                        index: h.index + 1,
                        phase: HomePhase::Release,
                        moved: 0,
                        frac: 0.0,
                    };
                    if h.index >= 3 {
                        self.homed = true;
                        self.active = Active::Idle;
                        return;
                    }
                } else {
                    h.phase = HomePhase::Backoff { left: left - k };
                }
            }
        }
        self.active = Active::Homing(h);
    }

    fn run_jog(&mut self, mut j: Jog, out: &mut impl Outputs) {
        let Some(e) = self.exec.as_ref() else { return };
        let m = &e.machine().motion;
        let a = j.axis.index();
        j.cycles += 1;
        let t = e.machine().dt() * j.cycles as f32;
        let d = j.trap.distance(t.min(j.trap.duration()));
        let target = libm::roundf((j.from_mm + j.sign * d) * m.steps_per_mm[a]) as i64;
        let delta = target - self.cmd.steps[a];
        if delta != 0 {
            Tracked {
                out,
                state: &mut self.cmd,
            }
            .step(j.axis, delta > 0, delta.unsigned_abs() as u32);
        }
        self.active = if t >= j.trap.duration() {
            Active::Idle
        } else {
            Active::Jog(j)
        };
    }
}
