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
    /// The photo is larger than the limit (`Options::max_pixels`).
    #[error("{path}: {w} x {h} = {px} pixels, over the limit of {limit} by {over}; scale the photo down or raise the limit")]
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
    /// The resolution asked for (`Options::px_per_mm`) is outside what is measured.
    #[error("a resolution of {px_per_mm} px per mm: it must be from {min} to {max}")]
    Resolution {
        /// What was asked, px per mm.
        px_per_mm: f64,
        /// The least, px per mm.
        min: f64,
        /// The most, px per mm.
        max: f64,
    },
    /// The design, drawn at the resolution asked for, would be too large a picture.
    #[error("the design frame would be {w} x {h} px; lower the resolution (px per mm)")]
    FrameTooLarge {
        /// Width, px.
        w: u32,
        /// Height, px.
        h: u32,
    },
    /// Writing an output failed.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}
