//! `dollop calibrate`: turns measurements (CSV tables, camera frames, syringe geometry)
//! into the config values the core uses, with confidence intervals, verdicts, plots and
//! TOML fragments. One module per calibration plus the shared pieces (CSV input, fitting,
//! smoothing, plotting, output); argument parsing lives in `cmd::calibrate`.

pub mod camera;
pub mod error;
pub mod fit;
pub mod flow;
pub mod format;
pub mod lag;
pub mod output;
pub mod plot;
pub mod rheology;
pub mod savgol;
pub mod syringe;
pub mod table;

pub use error::{CalError, CalOption, OptionError};
