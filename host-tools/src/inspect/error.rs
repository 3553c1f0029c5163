//! Why `dollop inspect` refuses a photo or cannot measure it: each a one-line message
//! naming the file and what to do.

use std::path::PathBuf;

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum InspectError {
    /// The photo could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The photo could not be decoded.
    #[error("{path}: cannot decode the photo: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// The photo is larger than the limit.
    #[error("{path}: {w} x {h} = {px} pixels, over the limit of {limit} by {over} (--max-pixels); scale the photo down or raise the limit")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Width.
        w: u32,
        /// Height.
        h: u32,
        /// Pixels.
        px: u64,
        /// The limit.
        limit: u64,
        /// By how much.
        over: u64,
    },
    /// The photo cannot be measured as it is (too dark, no print, the wrong job...).
    #[error("{path}: {message}")]
    Photo {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
    /// The job cannot be inspected (no beads, no boundaries, several layers...).
    #[error("{path}: {message}")]
    Job {
        /// The job file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// An option is out of range.
    #[error("{0}")]
    Argument(String),
    /// Writing an output failed.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}
