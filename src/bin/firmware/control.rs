//! The control loop's context on the chip: `dollop::device::Control` with its pins.
//! Runs in a software interrupt that the step timer pends every 100 us; it never waits.

use crate::shared::ControlEnd;
use crate::{step, wdg};
use core::sync::atomic::{AtomicBool, Ordering};
use dollop::device::{Control, Inputs};
use dollop::{Axis, Outputs};
use embassy_stm32::gpio::{Input, Output};

/// Set by the e-stop interrupt; the next control tick halts on it.
pub static ESTOP_LATCH: AtomicBool = AtomicBool::new(false);

/// Valves and drivers on pins; steps go to the step generator.
pub struct PinOutputs {
    /// Valve pins, inlet order (high = open).
    pub valves: [Output<'static>; 4],
    /// Driver enable (low = enabled).
    pub enable: Output<'static>,
}

impl Outputs for PinOutputs {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        step::request(axis, forward, count);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        if let Some(v) = self.valves.get_mut(inlet as usize) {
            if open {
                v.set_high();
            } else {
                v.set_low();
            }
        }
    }
    fn drivers(&mut self, enabled: bool) {
        if enabled {
            self.enable.set_low();
        } else {
            self.enable.set_high();
        }
    }
}

/// Everything the control interrupt owns.
pub struct ControlCtx {
    /// The board-independent loop.
    pub control: Control,
    /// Its outputs.
    pub out: PinOutputs,
    /// Endstops X, Y, Z (low = triggered).
    pub endstops: [Input<'static>; 3],
    /// E-stop input (high = stop).
    pub estop: Input<'static>,
    last_ticks: u32,
    now_us: u64,
}

impl ControlCtx {
    /// The context; the outputs are already safe.
    pub fn new(
        control: Control,
        out: PinOutputs,
        endstops: [Input<'static>; 3],
        estop: Input<'static>,
    ) -> Self {
        ControlCtx {
            control,
            out,
            endstops,
            estop,
            last_ticks: step::TICKS.load(Ordering::Acquire),
            now_us: 0,
        }
    }

    /// One control period.
    pub fn on_period(&mut self) {
        let t = step::TICKS.load(Ordering::Acquire);
        self.now_us += t.wrapping_sub(self.last_ticks) as u64 * 10;
        self.last_ticks = t;
        let inputs = Inputs {
            estop: ESTOP_LATCH.swap(false, Ordering::AcqRel) || self.estop.is_high(),
            endstops: [
                self.endstops[0].is_low(),
                self.endstops[1].is_low(),
                self.endstops[2].is_low(),
            ],
        };
        let tick = self
            .control
            .tick(self.now_us, inputs, &mut ControlEnd, &mut self.out);
        if tick.feed_watchdog {
            wdg::feed();
        }
    }
}
