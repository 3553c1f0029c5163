//! A whole board without hardware, for host tests and in-memory links: `Queues` is the
//! heapless stand-in for the firmware's embassy-sync channels and snapshot cell;
//! `SimBoard` runs `BoardLink` and `Control` in virtual time on `RecordingOutputs`, with
//! endstops at the travel limits, an e-stop input and a watchdog that resets the board.

use super::control::{Control, Inputs, ResetCause};
use super::link::{BoardInfo, BoardLink};
use super::safety::force_safe;
use super::store::JobStore;
use super::{BoardMachine, ControlOrder, FromLink, JobRecord, ToControl, JOB_QUEUE, ORDER_QUEUE};
use crate::outputs::RecordingOutputs;
use crate::wire::Snapshot;
use heapless::Deque;

/// The shared state between link and control loop, as plain queues.
pub struct Queues {
    orders: Deque<ControlOrder, ORDER_QUEUE>,
    commands: Deque<JobRecord, JOB_QUEUE>,
    config: Option<BoardMachine>,
    snapshot: Snapshot,
}

impl Default for Queues {
    fn default() -> Self {
        Queues {
            orders: Deque::new(),
            commands: Deque::new(),
            config: None,
            snapshot: Snapshot::POWER_UP,
        }
    }
}

impl ToControl for Queues {
    fn order(&mut self, order: ControlOrder) -> Result<(), ControlOrder> {
        self.orders.push_back(order)
    }
    fn command(&mut self, record: JobRecord) -> Result<(), JobRecord> {
        self.commands.push_back(record)
    }
    fn command_room(&self) -> usize {
        self.commands.capacity() - self.commands.len()
    }
    fn post_config(&mut self, machine: &BoardMachine) -> bool {
        if self.config.is_some() {
            return false;
        }
        self.config = Some(machine.clone());
        true
    }
    fn snapshot(&self) -> Snapshot {
        self.snapshot
    }
}

impl FromLink for Queues {
    fn next_order(&mut self) -> Option<ControlOrder> {
        self.orders.pop_front()
    }
    fn next_command(&mut self) -> Option<JobRecord> {
        self.commands.pop_front()
    }
    fn take_config(&mut self) -> Option<BoardMachine> {
        self.config.take()
    }
    fn publish(&mut self, snapshot: &Snapshot) {
        self.snapshot = *snapshot;
    }
}

/// Board info of the simulated board.
pub const SIM_INFO: BoardInfo = BoardInfo {
    name: "sim",
    firmware: env!("CARGO_PKG_VERSION"),
    max_step_hz: 50_000.0,
    control_hz: 10_000,
};

/// Watchdog timeout of the simulated board, us (the firmware's too).
pub const WATCHDOG_US: u64 = 250_000;

/// BoardLink and control loop on recorded outputs, in virtual time.
pub struct SimBoard<S: JobStore> {
    /// The link half.
    pub link: BoardLink<S>,
    /// The control half.
    pub control: Control,
    /// What they share.
    pub queues: Queues,
    /// The outputs as commanded.
    pub out: RecordingOutputs,
    /// E-stop input level.
    pub estop: bool,
    /// Where the machine really stands at power-up, mm (the endstops sit at the travel
    /// limit each axis homes to).
    pub start_mm: [f32; 3],
    /// Endstops never trigger (broken wiring).
    pub endstops_broken: bool,
    /// The control loop does not run (a hung interrupt): the watchdog will bite.
    pub control_hung: bool,
    /// Resets so far by the watchdog.
    pub watchdog_resets: u32,
    /// Virtual time, us.
    pub now_us: u64,
    last_feed: u64,
    period_us: u64,
}

impl<S: JobStore> SimBoard<S> {
    /// A board that just powered up, with `store` for jobs.
    pub fn new(store: S) -> Self {
        let mut out = RecordingOutputs {
            // Whatever the pins did before reset, power-up must leave them safe.
            valves: 0xFF,
            drivers: true,
            ..Default::default()
        };
        let mut control = Control::new(ResetCause::PowerOn);
        control.power_up(&mut out);
        SimBoard {
            link: BoardLink::new(store, SIM_INFO),
            control,
            queues: Queues::default(),
            out,
            estop: false,
            start_mm: [20.0, 20.0, 20.0],
            endstops_broken: false,
            control_hung: false,
            watchdog_resets: 0,
            now_us: 0,
            last_feed: 0,
            period_us: 100,
        }
    }

    /// Bytes from the host.
    pub fn receive(&mut self, bytes: &[u8]) {
        self.link.receive(bytes, self.now_us, &mut self.queues);
    }

    /// Bytes for the host; returns how many were put in `buf`.
    pub fn take_tx(&mut self, buf: &mut [u8]) -> usize {
        self.link.take_tx(buf)
    }

    /// The cable was pulled.
    pub fn disconnect(&mut self) {
        self.link.disconnected(&mut self.queues);
    }

    /// Runs control periods (and link polls) until `us` microseconds have passed.
    pub fn advance(&mut self, us: u64) {
        let end = self.now_us + us;
        while self.now_us + self.period_us <= end {
            self.now_us += self.period_us;
            self.cycle();
        }
        self.now_us = self.now_us.max(end);
    }

    /// One control period and one link poll.
    pub fn cycle(&mut self) {
        if !self.control_hung {
            let inputs = self.inputs();
            let t = self
                .control
                .tick(self.now_us, inputs, &mut self.queues, &mut self.out);
            if let Some(e) = self.control.executor() {
                self.period_us = e.machine().period_us as u64;
            }
            if t.feed_watchdog {
                self.last_feed = self.now_us;
            }
        }
        self.link.poll(self.now_us, &mut self.queues);
        if self.now_us.saturating_sub(self.last_feed) > WATCHDOG_US {
            self.watchdog_reset();
        }
    }

    /// What the independent watchdog does: a chip reset. Pins fall back to their reset
    /// state (made safe by the board's pull resistors: modelled as `force_safe`), RAM is
    /// lost except the job store, and the control loop starts halted, saying why.
    fn watchdog_reset(&mut self) {
        force_safe(&mut self.out);
        self.watchdog_resets += 1;
        self.control = Control::new(ResetCause::Watchdog);
        self.control.power_up(&mut self.out);
        self.queues = Queues::default();
        self.control_hung = false;
        self.last_feed = self.now_us;
        // The link restarts too (a new session is needed); the store keeps its bytes.
        self.link.reset();
    }

    /// The snapshot the control loop last published.
    pub fn snapshot(&self) -> Snapshot {
        self.queues.snapshot
    }

    /// The inputs as the board would sample them now.
    pub fn inputs(&self) -> Inputs {
        let mut endstops = [false; 3];
        if let (Some(e), false) = (self.control.executor(), self.endstops_broken) {
            let m = &e.machine().motion;
            let to_max = self.control.settings().home_to_max;
            for (a, hit) in endstops.iter_mut().enumerate() {
                let mm = self.out.position[a] as f32 / m.steps_per_mm[a] + self.start_mm[a];
                *hit = if to_max[a] {
                    mm >= m.max_mm[a]
                } else {
                    mm <= m.min_mm[a]
                };
            }
        }
        Inputs {
            estop: self.estop,
            endstops,
        }
    }
}
