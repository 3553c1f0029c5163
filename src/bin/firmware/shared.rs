//! What the control loop (interrupt) and the link (thread mode) share: two fixed-size
//! embassy-sync channels (orders, job records), a one-slot mailbox of validated machines and the status
//! snapshot. Every access is a short critical section; nobody waits.

use core::cell::{Cell, RefCell};
use dollop::device::{
    BoardMachine, ControlOrder, FromLink, JobRecord, ToControl, JOB_QUEUE, ORDER_QUEUE,
};
use dollop::wire::{LineErrors, Snapshot};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;

static ORDERS: Channel<CriticalSectionRawMutex, ControlOrder, ORDER_QUEUE> = Channel::new();
static COMMANDS: Channel<CriticalSectionRawMutex, JobRecord, JOB_QUEUE> = Channel::new();
static CONFIG: Mutex<CriticalSectionRawMutex, RefCell<Option<BoardMachine>>> =
    Mutex::new(RefCell::new(None));
static SNAPSHOT: Mutex<CriticalSectionRawMutex, Cell<Snapshot>> =
    Mutex::new(Cell::new(Snapshot::POWER_UP));

/// The link's end.
pub struct LinkEnd;
/// The control loop's end.
pub struct ControlEnd;

impl ToControl for LinkEnd {
    fn order(&mut self, order: ControlOrder) -> Result<(), ControlOrder> {
        ORDERS.try_send(order).map_err(|e| match e {
            embassy_sync::channel::TrySendError::Full(o) => o,
        })
    }
    fn command(&mut self, record: JobRecord) -> Result<(), JobRecord> {
        COMMANDS.try_send(record).map_err(|e| match e {
            embassy_sync::channel::TrySendError::Full(r) => r,
        })
    }
    fn command_room(&self) -> usize {
        COMMANDS.free_capacity()
    }
    fn post_config(&mut self, machine: &BoardMachine) -> bool {
        CONFIG.lock(|c| {
            let mut c = c.borrow_mut();
            if c.is_some() {
                return false;
            }
            *c = Some(machine.clone());
            true
        })
    }
    fn snapshot(&self) -> Snapshot {
        SNAPSHOT.lock(|s| s.get())
    }
    fn line_errors(&self) -> LineErrors {
        let [overrun, framing, noise, parity] = crate::line::counts();
        LineErrors {
            overrun,
            framing,
            noise,
            parity,
        }
    }
}

/// Whether the control loop's last published snapshot has the drivers enabled (read by
/// the job store to put them back after a flash operation).
pub fn drivers_commanded() -> bool {
    SNAPSHOT.lock(|s| s.get().drivers)
}

impl FromLink for ControlEnd {
    fn next_order(&mut self) -> Option<ControlOrder> {
        ORDERS.try_receive().ok()
    }
    fn next_command(&mut self) -> Option<JobRecord> {
        COMMANDS.try_receive().ok()
    }
    fn take_config(&mut self) -> Option<BoardMachine> {
        CONFIG.lock(|c| c.borrow_mut().take())
    }
    fn publish(&mut self, snapshot: &Snapshot) {
        SNAPSHOT.lock(|s| s.set(*snapshot));
    }
}
