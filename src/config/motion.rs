//! `[motion]`: the drivers' step rate, each axis's steps, travel, speed and acceleration,
//! and the print and travel speeds, checked against each other and against the step rate
//! the control loop leaves. It stops at the motion system; whether the flow can push the
//! head past its cap is `flow.rs`'s check.

use super::check::{axis_check, Check};
use super::{ConfigError, MotionConfig, Problem};
use crate::real::Real;

/// The checked axes, X, Y, Z, in the core's real type.
pub(super) struct Axes<R> {
    pub(super) steps_per_mm: [R; 3],
    pub(super) min_mm: [R; 3],
    pub(super) max_mm: [R; 3],
    pub(super) max_speed: [R; 3],
    pub(super) max_accel: [R; 3],
}

/// The checked speeds.
pub(super) struct Speeds {
    /// Print speed the `auto` pressures aim for, mm/s.
    pub(super) print: f64,
    /// The print-speed cap, mm/s.
    pub(super) cap: f32,
    /// Travel speed, mm/s.
    pub(super) travel: f32,
    /// Flow counted as stopped, fraction of the highest flow.
    pub(super) stop_fraction: f32,
}

/// The drivers' step rate, steps/s: checked before the control rate, which must not
/// exceed it.
pub(super) fn step_rate(m: &MotionConfig) -> Result<f64, ConfigError> {
    Ok(
        Check::section("motion").positive_max("max_step_rate_hz", m.max_step_rate_hz, 5.0e6)?
            as f64,
    )
}

/// Checks the three axes for drivers that allow `allowed_rate` steps/s.
pub(super) fn axes<R: Real>(m: &MotionConfig, allowed_rate: f64) -> Result<Axes<R>, ConfigError> {
    let mut x = Axes {
        steps_per_mm: [R::ZERO; 3],
        min_mm: [R::ZERO; 3],
        max_mm: [R::ZERO; 3],
        max_speed: [R::ZERO; 3],
        max_accel: [R::ZERO; 3],
    };
    for a in 0..3 {
        let ac = axis_check("motion", a);
        let spm = ac.range("steps_per_mm", m.steps_per_mm[a], 1.0, 1.0e5)?;
        let lo = ac.range("travel_min_mm", m.travel_min_mm[a], -1e4, 1e4)?;
        let hi = ac.range("travel_max_mm", m.travel_max_mm[a], -1e4, 1e4)?;
        if lo >= hi {
            return Err(ac.err("travel_max_mm", Problem::EmptyTravel));
        }
        let vmax = ac.range("max_speed_mm_s", m.max_speed_mm_s[a], 0.1, 5e3)?;
        let amax = ac.range("max_accel_mm_s2", m.max_accel_mm_s2[a], 1.0, 1e6)?;
        let needed = vmax as f64 * spm as f64;
        if needed > allowed_rate {
            return Err(ac.err(
                "max_speed_mm_s",
                Problem::StepRate {
                    needed: needed as f32,
                    allowed: allowed_rate as f32,
                },
            ));
        }
        x.steps_per_mm[a] = R::of(spm as f64);
        x.min_mm[a] = R::of(lo as f64);
        x.max_mm[a] = R::of(hi as f64);
        x.max_speed[a] = R::of(vmax as f64);
        x.max_accel[a] = R::of(amax as f64);
    }
    Ok(x)
}

/// Checks the print, cap and travel speeds (after the axes: the cap must be within X/Y's
/// top speed) and the flow-stop fraction.
pub(super) fn speeds(m: &MotionConfig) -> Result<Speeds, ConfigError> {
    let mc = Check::section("motion");
    let v_xy_max = m.max_speed_mm_s[0].min(m.max_speed_mm_s[1]);
    let print = mc.range("print_speed_mm_s", m.print_speed_mm_s, 0.1, 5e3)? as f64;
    let cap = mc.range("print_speed_max_mm_s", m.print_speed_max_mm_s, 0.1, 5e3)?;
    if cap > v_xy_max {
        return Err(mc.err(
            "print_speed_max_mm_s",
            Problem::Above {
                got: cap,
                limit: v_xy_max,
                what: "the X/Y max_speed_mm_s",
            },
        ));
    }
    if print > cap as f64 {
        return Err(mc.err(
            "print_speed_mm_s",
            Problem::Above {
                got: print as f32,
                limit: cap,
                what: "print_speed_max_mm_s",
            },
        ));
    }
    let travel = mc.range("travel_speed_mm_s", m.travel_speed_mm_s, 0.1, 5e3)?;
    let stop_fraction = mc.range("flow_stop_fraction", m.flow_stop_fraction, 1e-5, 0.5)?;
    Ok(Speeds {
        print,
        cap,
        travel,
        stop_fraction,
    })
}
