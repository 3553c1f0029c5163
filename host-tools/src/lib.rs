//! Library side of the `dollop` command, so tests and benchmarks reach the same code the
//! command line runs.

pub mod cmd;
