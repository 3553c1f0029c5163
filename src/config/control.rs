//! `[control]`: the control loop's rate, checked against itself (a whole number of
//! microseconds) and against the drivers' step rate (`[motion]`'s, checked first), and
//! turned into the cycle's timing. It stops at timing; what a cycle does is the executor's.

use super::check::Check;
use super::{ConfigError, ControlConfig, Problem};

/// The control cycle's timing.
pub(super) struct Timing {
    /// Cycle period, us.
    pub(super) period_us: u32,
    /// Steps/s an axis may need: the drivers' rate less one step per cycle of rounding.
    pub(super) allowed_rate: f64,
    /// Most steps one cycle may carry on one axis.
    pub(super) max_steps_per_cycle: u32,
}

/// Checks `[control]` for drivers taking `step_rate` steps/s.
pub(super) fn check(control: &ControlConfig, step_rate: f64) -> Result<Timing, ConfigError> {
    let cc = Check::section("control");
    let rate = control.rate_hz;
    if !(100..=100_000).contains(&rate) {
        return Err(cc.err(
            "rate_hz",
            Problem::OutOfRange {
                got: rate as f32,
                min: 100.0,
                max: 100_000.0,
            },
        ));
    }
    if 1_000_000 % rate != 0 {
        return Err(cc.err("rate_hz", Problem::RateNotDivisor(rate)));
    }
    let period_us = 1_000_000 / rate;
    let allowed_rate = step_rate - rate as f64;
    let max_steps_per_cycle = (step_rate / rate as f64) as u32;
    if max_steps_per_cycle < 1 || allowed_rate <= 0.0 {
        // The drivers' key is at fault as much as the rate; it names the step rate.
        return Err(Check::section("motion").err(
            "max_step_rate_hz",
            Problem::Above {
                got: rate as f32,
                limit: step_rate as f32,
                what: "the step rate (control.rate_hz must not exceed it)",
            },
        ));
    }
    Ok(Timing {
        period_us,
        allowed_rate,
        max_steps_per_cycle,
    })
}
