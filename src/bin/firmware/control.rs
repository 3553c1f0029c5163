//! The control loop's context on the chip: `dollop::device::Control` with its pins.
//! Runs in a software interrupt that the step timer pends every 100 us; it never waits.
//! Also the e-stop's latch and its input filter, the endstops' filter, the status LED and
//! the link's millisecond.
//!
//! Input filtering (noisy wiring must not halt a print or fake a homing hit): the e-stop
//! interrupt acts only if the pin reads high on three samples 1 us apart (2 us added to
//! its latency; a shorter spike is ignored), and the control loop takes the e-stop or an
//! endstop as changed only when two consecutive periods agree (100 us added; so a missed
//! e-stop edge is still acted on within 200 us, and at a 20 mm/s homing speed an endstop
//! is seen 2 um later).

use crate::shared::ControlEnd;
use crate::{board, host, step, wdg};
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use dollop::device::{Control, EStopGuard, Inputs};
use dollop::wire::Mode;
use dollop::{Axis, Outputs};
use embassy_stm32::gpio::{Input, Output};
use embassy_stm32::pac;

/// Set by the e-stop interrupt after it forced the safe state; the control loop's outputs
/// read it after every opening write (so a tick it preempted cannot reopen a valve), and
/// the next tick halts on it.
pub static ESTOP_LATCH: AtomicBool = AtomicBool::new(false);

/// Control periods run since start (the emulator harness reads it to check the rate).
pub static PERIODS: AtomicU32 = AtomicU32::new(0);

/// The e-stop interrupt's work: straight to the safe state through the registers, then
/// the latch.
pub fn estop_tripped() {
    board::force_safe_raw();
    ESTOP_LATCH.store(true, Ordering::Release);
}

/// The e-stop pin's level (high = stop), read from the register: shared by the e-stop
/// interrupt and the control loop. Out of line for the emulator harness, which rewrites
/// this load with the modelled level (see `ControlCtx::read_pins`).
#[inline(never)]
pub fn estop_pin() -> bool {
    let p = board::ESTOP;
    board::port(p).idr().read().idr(p.pin as usize) == pac::gpio::vals::Idr::HIGH
}

/// Samples the e-stop interrupt takes, 1 us apart: all must read high.
const ESTOP_SAMPLES: u32 = 3;

/// Whether an e-stop edge is real: the pin high on `ESTOP_SAMPLES` samples 1 us apart.
pub fn estop_confirmed() -> bool {
    for i in 0..ESTOP_SAMPLES {
        if i > 0 {
            cortex_m::asm::delay(board::CORE_HZ / 1_000_000);
        }
        if !estop_pin() {
            return false;
        }
    }
    true
}

/// A two-sample filter: the output changes only when two consecutive samples agree on
/// the new level.
#[derive(Clone, Copy)]
struct Filter {
    out: bool,
    last: bool,
}

impl Filter {
    const fn new(level: bool) -> Self {
        Filter {
            out: level,
            last: level,
        }
    }

    fn sample(&mut self, level: bool) -> bool {
        if level == self.last {
            self.out = level;
        }
        self.last = level;
        self.out
    }
}

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

/// Control periods per status LED half-blink: 1 Hz when all is well, 5 Hz when halted.
const BLINK_SLOW: u32 = board::CONTROL_HZ / 2;
const BLINK_FAST: u32 = board::CONTROL_HZ / 10;
/// Control periods per link millisecond.
const PERIODS_PER_MS: u32 = board::CONTROL_HZ / 1000;

/// Everything the control interrupt owns.
pub struct ControlCtx {
    /// The board-independent loop (in a static of its own).
    pub control: &'static mut Control,
    /// Its outputs.
    pub out: PinOutputs,
    /// Endstops X, Y, Z (low = triggered).
    pub endstops: [Input<'static>; 3],
    /// E-stop input (high = stop): owned here so it stays an input with its pull-up;
    /// read through the register (`estop_pin`), which the e-stop interrupt shares.
    pub _estop: Input<'static>,
    /// Status LED (high = on).
    pub led: Output<'static>,
    clock: step::Clock,
    periods: u32,
    blink: u32,
    estop_filter: Filter,
    endstop_filters: [Filter; 3],
}

impl ControlCtx {
    /// The context; the outputs are already safe.
    pub fn new(
        control: &'static mut Control,
        out: PinOutputs,
        endstops: [Input<'static>; 3],
        estop: Input<'static>,
        led: Output<'static>,
    ) -> Self {
        ControlCtx {
            control,
            out,
            endstops,
            _estop: estop,
            led,
            clock: step::Clock::new(),
            periods: 0,
            blink: 0,
            estop_filter: Filter::new(false),
            endstop_filters: [Filter::new(false); 3],
        }
    }

    /// The e-stop and endstop pins (GPIOC). Out of line so that each pin's load is
    /// followed by this function's own code up to its return: the emulator harness
    /// (scripts/emulator/fil.py) rewrites these loads with the modelled levels, which it
    /// can do only where the condition flags are dead after them, and a flag-setting
    /// comparison of the caller scheduled past an inlined load made one such load a
    /// debugger stop every period, too slow for the host tool's timeouts.
    #[inline(never)]
    fn read_pins(&self) -> (bool, [bool; 3]) {
        (
            estop_pin(),
            [
                self.endstops[0].is_low(),
                self.endstops[1].is_low(),
                self.endstops[2].is_low(),
            ],
        )
    }

    /// One control period.
    pub fn on_period(&mut self) {
        let now_us = self.clock.now_us();
        let (estop, endstops) = self.read_pins();
        let estop = self.estop_filter.sample(estop);
        let mut filtered = [false; 3];
        for ((f, raw), out) in self
            .endstop_filters
            .iter_mut()
            .zip(endstops)
            .zip(filtered.iter_mut())
        {
            *out = f.sample(raw);
        }
        let inputs = Inputs {
            estop: ESTOP_LATCH.swap(false, Ordering::AcqRel) || estop,
            endstops: filtered,
        };
        let mut out = EStopGuard {
            out: &mut self.out,
            latch: &ESTOP_LATCH,
        };
        let tick = self.control.tick(now_us, inputs, &mut ControlEnd, &mut out);
        if tick.feed_watchdog {
            wdg::feed();
        }
        PERIODS.fetch_add(1, Ordering::Relaxed);
        self.periods = self.periods.wrapping_add(1);
        if self.periods % PERIODS_PER_MS == 0 {
            host::millisecond();
        }
        self.blink += 1;
        let halted = self.control.mode() == Mode::Halted;
        if self.blink >= if halted { BLINK_FAST } else { BLINK_SLOW } {
            self.blink = 0;
            self.led.toggle();
        }
    }
}
