//! The board's application logic, independent of any board: `BoardLink` (USB requests, job
//! upload into a `JobStore`, feeding the running job) and `Control` (the control loop:
//! executor, homing, jog, valve test, e-stop, faults, one path to the safe state). They
//! share only what `ToControl`/`FromLink` carry: a queue of orders, a queue of job
//! records, a one-slot config mailbox, and the status snapshot. Pins, clocks, USB and
//! interrupts are the firmware's; `SimBoard` wires both halves together for host tests.

pub mod control;
pub mod link;
pub mod safety;
pub mod serve;
pub mod sim_board;
pub mod store;

pub use control::{Control, Inputs, ResetCause, Tick};
pub use link::{BoardInfo, BoardLink};
pub use safety::{force_safe, EStopGuard, Latch};
pub use serve::{serve, HostPort, Pace, PortClosed};
pub use sim_board::{Queues, SimBoard};
pub use store::{JobStore, RamStore};

use crate::command::Command;
use crate::config::Machine;
use crate::outputs::Axis;
use crate::wire::{LineErrors, LinkLossPolicy, Settings, Snapshot};

/// The machine the board runs: f32 (the M4's FPU), four inlets. The link validates a
/// config into one in thread mode; the control loop only loads it.
pub type BoardMachine = Machine<f32, { crate::DEFAULT_INLETS }>;

/// Orders in the control queue it holds (an order is answered before the next one is
/// taken, so a handful covers every burst the link makes).
pub const ORDER_QUEUE: usize = 8;
/// Job records in the job queue: 64 commands of 16 bytes, 1 KiB. The link refills it every
/// poll; the control loop drains it into the executor's 256-item plan.
pub const JOB_QUEUE: usize = 64;
/// Commands the injected lead-in puts before a job's body: lift to the safe height, move
/// over the start point, lower onto it.
pub const LEAD_IN: u32 = 3;

/// What the link asks of the control loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControlOrder {
    /// Begin job number `epoch`; its commands follow in the job queue.
    Start {
        /// Job number; job records of other numbers are dropped.
        epoch: u8,
        /// Where the job begins, micrometres.
        start_um: [i32; 3],
        /// Material the channel is primed with.
        initial_material: u8,
    },
    /// Finish the bead, then hold.
    Pause,
    /// Continue.
    Resume,
    /// Stop now, drivers off.
    Abort,
    /// Emergency stop from the host.
    EStop,
    /// Acknowledge a halt.
    ClearFault,
    /// Home all axes.
    Home,
    /// Move one axis by hand.
    Jog {
        /// The axis.
        axis: Axis,
        /// Distance, micrometres.
        um: i32,
    },
    /// Valve test.
    Valve {
        /// Inlet.
        inlet: u8,
        /// Open or close.
        open: bool,
    },
    /// The host link was lost.
    LinkLost(LinkLossPolicy),
    /// New board settings.
    Settings(Settings),
    /// A validated machine waits in the mailbox.
    LoadConfig,
    /// Pause, then park (`Executor::park`).
    Park,
    /// Retract the plungers for a refill while parked (`Executor::refill`).
    Refill,
}

/// One job command for the control loop, tagged with its job number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JobRecord {
    /// Job number (`ControlOrder::Start::epoch`).
    pub epoch: u8,
    /// The command.
    pub cmd: Command,
}

/// The link's end of what it shares with the control loop.
pub trait ToControl {
    /// Queues an order; gives it back when the queue is full.
    fn order(&mut self, order: ControlOrder) -> Result<(), ControlOrder>;
    /// Queues a job command; gives it back when the queue is full.
    fn command(&mut self, record: JobRecord) -> Result<(), JobRecord>;
    /// Free places in the job queue.
    fn command_room(&self) -> usize;
    /// Puts a validated machine in the mailbox; false if the previous one was not taken
    /// yet.
    fn post_config(&mut self, machine: &BoardMachine) -> bool;
    /// The control loop's latest snapshot.
    fn snapshot(&self) -> Snapshot;
    /// The board's serial-line receive errors so far, for the status (none by default:
    /// boards without a UART, the simulator).
    fn line_errors(&self) -> LineErrors {
        LineErrors::default()
    }
}

/// The control loop's end.
pub trait FromLink {
    /// The next order, if any.
    fn next_order(&mut self) -> Option<ControlOrder>;
    /// The next job command, if any.
    fn next_command(&mut self) -> Option<JobRecord>;
    /// The machine in the mailbox, if any.
    fn take_config(&mut self) -> Option<BoardMachine>;
    /// Publishes the snapshot.
    fn publish(&mut self, snapshot: &Snapshot);
}
