//! One module per `dollop` subcommand (or family of them).

pub mod bench;
pub mod calibrate;
pub mod config;
pub mod demo;
pub mod inspect;
pub mod link;
pub mod simulate;
pub mod slice;
