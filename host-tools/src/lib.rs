//! Library side of the `dollop` command, so tests and benchmarks reach the same code the
//! command line runs.

pub mod calibrate;
pub mod cmd;
pub mod config_apply;
pub mod figure;
pub mod fixtures;
pub mod gcode_in;
pub mod inspect;
pub mod link;
pub mod serve;
pub mod simulate;
pub mod slicer;
