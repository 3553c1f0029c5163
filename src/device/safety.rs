//! The one safe state of the outputs (every valve closed, drivers disabled), and an
//! `Outputs` wrapper that remembers what was commanded (step position, valves, drivers)
//! so the control loop knows where the machine is whoever moved it.

use crate::config::MAX_CONFIG_INLETS;
use crate::outputs::{Axis, Outputs};

/// Drives `out` to the safe state: every valve a config can name closed, drivers off.
/// Idempotent; the firmware's panic handler calls it too, on an `Outputs` that writes the
/// pins' registers directly.
pub fn force_safe(out: &mut impl Outputs) {
    for i in 0..MAX_CONFIG_INLETS {
        out.valve(i as u8, false);
    }
    out.drivers(false);
}

/// What has been commanded on the outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Commanded {
    /// Net steps per axis since power-up (or since homing set them).
    pub steps: [i64; 3],
    /// Valves open, bit per inlet.
    pub valves: u32,
    /// Drivers enabled.
    pub drivers: bool,
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
        let a = axis.index();
        let n = count as i64;
        self.state.steps[a] += if forward { n } else { -n };
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
