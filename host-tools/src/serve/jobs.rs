//! A sliced job as the dashboard keeps it (config, job, toolpath, figures): what the
//! shared state stores and a board's worker sends. Data only; keeping and dropping them is
//! `state`'s, sending them `boards`'.

use super::design::{Figures, Toolpath};
use crate::slicer::Sliced;
use dollop::config::Config;

/// A sliced job.
pub struct JobEntry {
    /// Its number.
    pub id: u64,
    /// The machine config it was sliced for.
    pub config: Config,
    /// That config as TOML.
    pub config_text: String,
    /// The job.
    pub sliced: Sliced,
    /// The toolpath the pages draw.
    pub toolpath: Toolpath,
    /// Its figures.
    pub figures: Figures,
}
