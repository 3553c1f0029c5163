//! Writing results: atomic file writes (a temporary file in the same folder, then a
//! rename, so an interrupted run never leaves half a fragment or plot), and loading the
//! machine config a calibration needs. What goes into the files is decided elsewhere.

use super::CalError;
use dollop::config::Config;
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CalError> {
    let wrap = |source: std::io::Error| CalError::Write {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(wrap)?;
    // Temporary files are private (0600); a fragment or plot is an ordinary file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(wrap)?;
    }
    tmp.write_all(bytes).map_err(wrap)?;
    tmp.as_file().sync_all().map_err(wrap)?;
    tmp.persist(path).map_err(|e| wrap(e.error))?;
    Ok(())
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
