//! Writing results: atomic file writes (a temporary file in the same folder, then a
//! rename, so an interrupted run never leaves half a fragment or plot; fragment and plot
//! staged together so a failure on one leaves neither), and loading the machine config a
//! calibration needs. What goes into the files is decided elsewhere.

use super::CalError;
pub use crate::slicer::output::StagedFiles;
use dollop::config::Config;
use std::path::Path;

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename
/// (the slicer's atomic write, with this module's error).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CalError> {
    crate::slicer::output::write_file_atomically(path, |w| w.write_all(bytes)).map_err(|source| {
        CalError::Write {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// Stages `bytes` for `path` in `out` (renamed into place when `out` is committed).
pub fn stage(out: &mut StagedFiles, path: &Path, bytes: &[u8]) -> Result<(), CalError> {
    out.stage(path, |w| w.write_all(bytes))
        .map_err(|source| CalError::Write {
            path: path.to_path_buf(),
            source,
        })
}

/// Renames everything staged in `out` into place; on failure names the output.
pub fn commit(out: StagedFiles) -> Result<(), CalError> {
    out.commit()
        .map_err(|(path, source)| CalError::Write { path, source })
}

/// Reads and validates a machine config (TOML) for the build's inlet count.
pub fn load_config(path: &Path) -> Result<Config, CalError> {
    let text = std::fs::read_to_string(path).map_err(|source| CalError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let config: Config = toml::from_str(&text).map_err(|e| CalError::Config {
        path: path.to_path_buf(),
        // toml's message spans several lines (it quotes the source); keep the first.
        message: e
            .message()
            .lines()
            .next()
            .unwrap_or("invalid TOML")
            .to_string(),
    })?;
    config
        .validate::<f64, { dollop::config::MAX_CONFIG_INLETS }>()
        .map_err(|e| CalError::Config {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    Ok(config)
}
