//! The one narrow interface from the core to the machine: step/dir per axis, valve per
//! inlet, driver enable. The firmware implements it on pins; `RecordingOutputs` records
//! what was commanded for tests and simulation.

use crate::capacity::MAX_CONFIG_INLETS;
use serde::{Deserialize, Serialize};

/// A motion axis: the head's X, Y, Z, or the plunger of syringe inlet i (`E(i)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Axis {
    /// X
    X,
    /// Y
    Y,
    /// Z
    Z,
    /// Plunger of syringe inlet i.
    E(u8),
}

/// Axes an `Outputs` may see: X, Y, Z and one plunger per possible inlet.
pub const AXES: usize = 3 + MAX_CONFIG_INLETS;

/// Drives `out` to the one safe state: every valve a config can name closed (not only
/// the inlets of the machine loaded: a valve past them may have been opened by an
/// earlier config, a valve test or a stray write), drivers off. Idempotent. The
/// executor's faults and aborts come here, and so do the device's power-up, e-stop and
/// halts (`device::force_safe`) and the firmware's panic handler, on an `Outputs` that
/// writes the pins' registers directly.
pub fn force_safe(out: &mut impl Outputs) {
    for i in 0..MAX_CONFIG_INLETS {
        out.valve(i as u8, false);
    }
    out.drivers(false);
}

impl Axis {
    /// The head's axes in index order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];
    /// 0, 1, 2 for X, Y, Z; 3 + i for `E(i)`.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
            Axis::E(i) => 3 + i as usize,
        }
    }
}

/// What one control cycle commands. Calls come once per cycle per axis that moves, and
/// only on change for valves and drivers.
pub trait Outputs {
    /// Emit `count` (>= 1) step pulses on `axis` in direction `forward`, spread over the
    /// next control period. The direction is set before the first pulse.
    fn step(&mut self, axis: Axis, forward: bool, count: u32);
    /// Open or close the valve of `inlet`.
    fn valve(&mut self, inlet: u8, open: bool);
    /// Enable or disable all stepper drivers.
    fn drivers(&mut self, enabled: bool);
}

/// An `Outputs` that keeps the commanded state and counters instead of driving pins.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecordingOutputs {
    /// Net step position per axis (forward minus backward).
    pub position: [i64; AXES],
    /// Pulses emitted per axis, either direction.
    pub pulses: [u64; AXES],
    /// Direction changes per axis (between pulses; the first direction is not a change).
    pub reversals: [u64; AXES],
    /// Largest pulse count in one cycle, per axis.
    pub max_per_cycle: [u32; AXES],
    /// Current direction per axis (true: forward).
    pub forward: [bool; AXES],
    /// Valve state, bit i for inlet i.
    pub valves: u32,
    /// Valve state changes commanded.
    pub valve_changes: u64,
    /// Drivers enabled.
    pub drivers: bool,
}

impl Default for RecordingOutputs {
    fn default() -> Self {
        RecordingOutputs {
            position: [0; AXES],
            pulses: [0; AXES],
            reversals: [0; AXES],
            max_per_cycle: [0; AXES],
            forward: [false; AXES],
            valves: 0,
            valve_changes: 0,
            drivers: false,
        }
    }
}

impl Outputs for RecordingOutputs {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        let a = axis.index().min(AXES - 1);
        if forward != self.forward[a] {
            if self.pulses[a] > 0 {
                self.reversals[a] += 1;
            }
            self.forward[a] = forward;
        }
        self.position[a] += if forward {
            count as i64
        } else {
            -(count as i64)
        };
        self.pulses[a] += count as u64;
        self.max_per_cycle[a] = self.max_per_cycle[a].max(count);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        let bit = 1u32 << (inlet as u32 & 31);
        let was = self.valves & bit != 0;
        if was != open {
            self.valve_changes += 1;
        }
        if open {
            self.valves |= bit;
        } else {
            self.valves &= !bit;
        }
    }
    fn drivers(&mut self, enabled: bool) {
        self.drivers = enabled;
    }
}

impl<O: Outputs + ?Sized> Outputs for &mut O {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        (**self).step(axis, forward, count)
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        (**self).valve(inlet, open)
    }
    fn drivers(&mut self, enabled: bool) {
        (**self).drivers(enabled)
    }
}
