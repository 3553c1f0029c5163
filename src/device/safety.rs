//! The device's side of the safe state: an `Outputs` wrapper that remembers what was
//! commanded (step position, valves, drivers) so the control loop knows where the
//! machine is whoever moved it, and one that never undoes an e-stop. The safe state
//! itself (every valve closed, drivers disabled) is defined once, below the executor,
//! as `outputs::force_safe`: the executor's faults and the device's halts both use it.

pub use crate::outputs::force_safe;
use crate::outputs::{Axis, Outputs, AXES};

/// What has been commanded on the outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Commanded {
    /// Net steps per axis since power-up (or since homing set them), in `Axis::index`
    /// order: X, Y, Z, then the syringe plungers.
    pub steps: [i64; AXES],
    /// Valves open, bit per inlet.
    pub valves: u32,
    /// Drivers enabled.
    pub drivers: bool,
}

impl Commanded {
    /// Nothing commanded yet.
    pub const ZERO: Commanded = Commanded {
        steps: [0; AXES],
        valves: 0,
        drivers: false,
    };
}

/// Passes commands on to `out` and records them in `state`.
pub struct Tracked<'a, O: Outputs> {
    /// The real outputs.
    pub out: &'a mut O,
    /// What was commanded.
    pub state: &'a mut Commanded,
}

impl<O: Outputs> Outputs for Tracked<'_, O> {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        let n = count as i64;
        // An axis past the table (a plunger no config can have) is not tracked; it is
        // still passed on, and the board's step generator drops what it has no pins for.
        if let Some(s) = self.state.steps.get_mut(axis.index()) {
            *s += if forward { n } else { -n };
        }
        self.out.step(axis, forward, count);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        let bit = 1u32 << (inlet as u32 & 31);
        if open {
            self.state.valves |= bit;
        } else {
            self.state.valves &= !bit;
        }
        self.out.valve(inlet, open);
    }
    fn drivers(&mut self, enabled: bool) {
        self.state.drivers = enabled;
        self.out.drivers(enabled);
    }
}

/// What the e-stop leaves behind for code it preempted: a flag set by the e-stop's own
/// interrupt after it has forced the safe state.
pub trait Latch {
    /// True once the e-stop has tripped (until the control loop takes it over).
    fn tripped(&self) -> bool;
}

impl Latch for core::sync::atomic::AtomicBool {
    fn tripped(&self) -> bool {
        self.load(core::sync::atomic::Ordering::Acquire)
    }
}

/// `Outputs` that never undo an e-stop: the control loop may be preempted by the e-stop
/// between deciding to open a valve (or enable the drivers) and writing the pin. The
/// write goes out, then the latch is read: if the e-stop tripped at any point before that
/// read, the write is taken back here; if it trips after, its own handler closes
/// everything. Either way the safe state wins with no window between.
pub struct EStopGuard<'a, O: Outputs, L: Latch> {
    /// The outputs guarded.
    pub out: &'a mut O,
    /// The e-stop's latch.
    pub latch: &'a L,
}

impl<O: Outputs, L: Latch> Outputs for EStopGuard<'_, O, L> {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        // Harmless: the e-stop disabled the drivers, and this one takes them back too.
        self.out.step(axis, forward, count);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        self.out.valve(inlet, open);
        if open && self.latch.tripped() {
            self.out.valve(inlet, false);
        }
    }
    fn drivers(&mut self, enabled: bool) {
        self.out.drivers(enabled);
        if enabled && self.latch.tripped() {
            self.out.drivers(false);
        }
    }
}
