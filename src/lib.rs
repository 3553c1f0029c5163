//! dollop's planning core: configuration, flow model, volume-clock executor and step
//! generation for single-nozzle multi-material DIW printers. `no_std`, no heap, no HAL:
//! the same code runs on the STM32 and in host tests; board glue lives elsewhere.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// `$e`, its instructions counted into `crate::probe` section `$i` with the `probe`
/// feature (bench-m4's map of the tick); `$e` alone without.
macro_rules! probe {
    ($i:ident, $e:expr) => {{
        #[cfg(feature = "probe")]
        let start = crate::probe::now();
        let r = $e;
        #[cfg(feature = "probe")]
        crate::probe::add(crate::probe::$i, start);
        r
    }};
}
#[cfg(feature = "probe")]
pub mod probe;

pub mod capacity;
pub mod command;
pub mod config;
pub mod device;
pub mod executor;
mod fast;
pub mod flow_follow;
pub mod flow_model;
mod fmt;
pub mod follow_trail;
pub mod job;
pub mod motion;
pub mod outputs;
mod poly;
pub mod ramp;
pub mod real;
pub mod rheology;
pub mod section_taper;
pub mod state;
pub mod step_gen;
pub mod step_ramps;
pub mod switch_window;
pub mod turn_slow;
pub mod vol;
pub mod width_blend;
pub mod window_sums;
pub mod wire;

pub use capacity::DEFAULT_INLETS;
pub use command::Command;
pub use config::{Config, ConfigError, Machine};
pub use executor::{Executor, Fault, Report, RunState};
pub use outputs::{Axis, Outputs, RecordingOutputs};
pub use real::Real;
pub use vol::Vol;
