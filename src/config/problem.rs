//! What a config check refuses: the field (`Field`), the kind of problem (`Problem`, which
//! names itself for the board's short refusals) and the two together (`ConfigError`,
//! whose `Display` is the message a person acts on). The checks themselves live with
//! their sections.

use core::fmt;

/// Where in the config a problem is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    /// Section: "channel", "motion", "control" or "inlet".
    pub section: &'static str,
    /// Inlet number or axis, where the key is per inlet or per axis.
    pub index: Option<u8>,
    /// The key.
    pub key: &'static str,
}

/// What is wrong with a value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Problem {
    /// NaN or infinite.
    NotFinite,
    /// Must be above zero.
    NotPositive(f32),
    /// Must be zero or more.
    Negative(f32),
    /// Outside the accepted range.
    OutOfRange {
        /// The value given.
        got: f32,
        /// Lowest accepted.
        min: f32,
        /// Highest accepted.
        max: f32,
    },
    /// More inlets than this build supports.
    TooManyInlets {
        /// Inlets configured.
        got: usize,
        /// Inlets this build supports.
        max: usize,
    },
    /// No inlet configured.
    NoInlets,
    /// `travel_min_mm` is not below `travel_max_mm`.
    EmptyTravel,
    /// The control rate does not give a whole number of microseconds.
    RateNotDivisor(u32),
    /// The fastest move would need more steps per second than the drivers take.
    StepRate {
        /// Steps/s the axis would need.
        needed: f32,
        /// Steps/s allowed, less one step per control cycle of rounding headroom.
        allowed: f32,
    },
    /// The flow can push the head faster than the print-speed cap.
    FlowTooFast {
        /// Speed the flow can reach, mm/s.
        speed: f32,
        /// Inlet whose pressure reaches it.
        inlet: u8,
        /// Material filling the channel when it does.
        through: u8,
    },
    /// A value that must not exceed another one does.
    Above {
        /// The value given.
        got: f32,
        /// The bound.
        limit: f32,
        /// What the bound is.
        what: &'static str,
    },
    /// `auto` pressure could not be computed (flow law gives no finite value).
    AutoPressure,
    /// Some inlets are syringes and some pneumatic; a machine is one or the other.
    MixedDrives,
    /// Ramping the head through the flow's largest step at this acceleration takes longer
    /// than the executor's ramp window holds.
    RampTooLong {
        /// The step of head speed, mm/s.
        step: f32,
        /// Time the ramp needs, ms.
        needed_ms: f32,
        /// Longest ramp the executor holds at this control rate, ms.
        max_ms: f32,
    },
}

impl Problem {
    /// The kind of problem in a few words, without numbers: what the board answers a
    /// config with (formatting floats costs the chip 15 KiB of flash; the host's own
    /// check names the values). Every kind has its own.
    pub fn name(&self) -> &'static str {
        match self {
            Problem::NotFinite => "not a finite number",
            Problem::NotPositive(_) => "must be above zero",
            Problem::Negative(_) => "must not be negative",
            Problem::OutOfRange { .. } => "outside the accepted range",
            Problem::TooManyInlets { .. } => "more inlets than this board supports",
            Problem::NoInlets => "at least one inlet is needed",
            Problem::EmptyTravel => "travel_min_mm must be below travel_max_mm",
            Problem::RateNotDivisor(_) => "the rate must divide 1000000",
            Problem::StepRate { .. } => "needs more steps/s than the drivers allow",
            Problem::FlowTooFast { .. } => "the flow can push the head past the print-speed cap",
            Problem::Above { .. } => "above its bound",
            Problem::AutoPressure => "\"auto\" pressure could not be computed",
            Problem::MixedDrives => "mixes syringe and pneumatic inlets",
            Problem::RampTooLong { .. } => {
                "the flow's speed ramp is longer than the executor holds"
            }
        }
    }
}

/// A config value that cannot print, naming the field and the reason.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigError {
    /// Where.
    pub field: Field,
    /// What.
    pub problem: Problem,
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.section, self.index) {
            ("inlet", Some(i)) => write!(f, "inlet[{i}].{}", self.key),
            (s, Some(i)) => write!(f, "{s}.{}[{i}]", self.key),
            (s, None) => write!(f, "{s}.{}", self.key),
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.field)?;
        match self.problem {
            Problem::NotFinite => write!(f, "must be a finite number"),
            Problem::NotPositive(v) => write!(f, "must be above zero (got {v})"),
            Problem::Negative(v) => write!(f, "must not be negative (got {v})"),
            Problem::OutOfRange { got, min, max } => {
                write!(f, "{got} is outside the accepted range {min} ..= {max}")
            }
            Problem::TooManyInlets { got, max } => write!(
                f,
                "{got} inlets configured but this build supports at most {max}"
            ),
            Problem::NoInlets => write!(f, "at least one inlet is needed"),
            Problem::EmptyTravel => write!(f, "travel_min_mm must be below travel_max_mm"),
            Problem::RateNotDivisor(r) => write!(
                f,
                "{r} Hz does not give a whole number of microseconds per cycle (try 10000)"
            ),
            Problem::StepRate { needed, allowed } => write!(
                f,
                "needs {needed:.0} steps/s at top speed but the drivers allow {allowed:.0} \
                 (max_step_rate_hz less one step per control cycle); lower the speed"
            ),
            Problem::FlowTooFast {
                speed,
                inlet,
                through,
            } => write!(
                f,
                "the flow can drive the head at {speed:.1} mm/s (inlet {inlet}'s pressure through a \
                 channel full of inlet {through}'s material), above this cap; raise the cap or \
                 lower that pressure"
            ),
            Problem::Above { got, limit, what } => {
                write!(f, "{got} is above {what} ({limit})")
            }
            Problem::AutoPressure => write!(f, "\"auto\" pressure could not be computed"),
            Problem::MixedDrives => write!(
                f,
                "mixes syringe and pneumatic inlets; make every inlet a syringe or none"
            ),
            Problem::RampTooLong {
                step,
                needed_ms,
                max_ms,
            } => write!(
                f,
                "the flow can change the head speed by {step} mm/s at once; a ramp within \
                 this acceleration takes {needed_ms} ms, longer than the {max_ms} ms the \
                 executor holds: raise it, lower the inlets' pressure_kpa (or the print \
                 speed, with \"auto\" pressure), or give the valves slower \
                 pressure_rise_ms and pressure_decay_ms"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind names itself, and no two alike: the board's refusal is all the host
    /// sees when it has no copy of the config to check.
    #[test]
    fn every_problem_has_its_own_name() {
        let all = [
            Problem::NotFinite,
            Problem::NotPositive(0.0),
            Problem::Negative(-1.0),
            Problem::OutOfRange {
                got: 0.0,
                min: 1.0,
                max: 2.0,
            },
            Problem::TooManyInlets { got: 5, max: 4 },
            Problem::NoInlets,
            Problem::EmptyTravel,
            Problem::RateNotDivisor(3),
            Problem::StepRate {
                needed: 2.0,
                allowed: 1.0,
            },
            Problem::FlowTooFast {
                speed: 1.0,
                inlet: 0,
                through: 1,
            },
            Problem::Above {
                got: 2.0,
                limit: 1.0,
                what: "it",
            },
            Problem::AutoPressure,
            Problem::MixedDrives,
            Problem::RampTooLong {
                step: 1.0,
                needed_ms: 60.0,
                max_ms: 51.1,
            },
        ];
        for (i, a) in all.iter().enumerate() {
            assert!(!a.name().is_empty());
            for b in &all[i + 1..] {
                assert_ne!(a.name(), b.name(), "{a:?} and {b:?}");
            }
        }
    }
}
