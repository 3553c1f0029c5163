//! Host-side simulation of dollop jobs: an independent f64 reference plant of the
//! printhead's physics, a runner that drives the core's executor in virtual time, test
//! designs, and print-quality metrics. Used by the core's whole-job tests and by
//! `dollop simulate`; file formats and pictures belong to the host tools.

pub mod bench;
pub mod designs;
#[cfg(feature = "floor")]
pub mod floor;
pub mod metrics;
pub mod pause;
pub mod plant;
pub mod run;

pub use designs::{um, Job};
pub use metrics::Metrics;
pub use pause::{ParkRecord, PausePlan, PauseRecord};
pub use run::{run, run_paused, run_with_plant, Cycle, RunOptions, RunResult, SimError};
