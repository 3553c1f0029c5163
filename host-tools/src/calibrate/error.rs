//! The one error type of `dollop calibrate`: every way measurements, frames or arguments
//! can be unusable, each a one-line message that names the file (and line and column
//! where there is one). Turning these into exit codes is the command's job.

use std::path::PathBuf;

/// Why a calibration could not be done.
#[derive(Debug, thiserror::Error)]
pub enum CalError {
    /// A file or folder could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The CSV layer itself failed (bad quoting, invalid UTF-8).
    #[error("{path}: line {line}: not valid CSV: {message}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line, 0 when unknown.
        line: u64,
        /// What the CSV reader said.
        message: String,
    },
    /// The file holds no data rows (it may have a header or comments).
    #[error("{path}: no data rows")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// Too few rows to fit anything with a confidence interval.
    #[error("{path}: {rows} data row(s); at least {need} are needed")]
    TooFewRows {
        /// The file.
        path: PathBuf,
        /// Data rows found.
        rows: usize,
        /// Rows needed.
        need: usize,
    },
    /// Too few rows for one material of a multi-material table.
    #[error("{path}: material {material:?} has {rows} data row(s); at least {need} are needed")]
    TooFewRowsFor {
        /// The file.
        path: PathBuf,
        /// The material.
        material: String,
        /// Its rows.
        rows: usize,
        /// Rows needed.
        need: usize,
    },
    /// A row has fewer cells than the table needs.
    #[error("{path}: line {line}: {got} column(s), expected at least {need}")]
    MissingCells {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Cells found.
        got: usize,
        /// Cells needed.
        need: usize,
    },
    /// A cell that must hold a number does not.
    #[error("{path}: line {line}, column {column}: {text:?} is not a number")]
    NotNumeric {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based column, with its header name when there is one.
        column: String,
        /// The cell.
        text: String,
    },
    /// A value is below zero (or zero) where the physics forbids it.
    #[error("{path}: line {line}, column {column}: {value} must be {need}")]
    OutOfRange {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based column, with its header name when there is one.
        column: String,
        /// The value.
        value: f64,
        /// What it must be ("above zero", "zero or more").
        need: &'static str,
    },
    /// An input is larger than a stated limit; the option that raises it is named.
    #[error("{path}: {what}; raise the limit with {option} if this input is right")]
    OverLimit {
        /// The file or folder.
        path: PathBuf,
        /// How large it is, the limit and by how much it is over.
        what: String,
        /// The option that sets the limit.
        option: &'static str,
    },
    /// The data do not say what they are (unit, kind) and no option said either.
    #[error("{path}: {message}")]
    Unclear {
        /// The file.
        path: PathBuf,
        /// What is missing and which option supplies it.
        message: String,
    },
    /// The least-squares fit did not converge, or converged to something unusable.
    #[error("{path}: the {model} fit did not converge: {reason}")]
    NoConvergence {
        /// The data file.
        path: PathBuf,
        /// Model name.
        model: String,
        /// Why (optimizer's termination, runaway parameter, singular Jacobian).
        reason: String,
    },
    /// The folder holds no image files.
    #[error("{path}: no images (.png, .jpg, .jpeg, .bmp) in this folder")]
    NoImages {
        /// The folder.
        path: PathBuf,
    },
    /// Too few frames for optical flow.
    #[error("{path}: {frames} frame(s); at least {need} are needed")]
    TooFewFrames {
        /// The folder.
        path: PathBuf,
        /// Frames found.
        frames: usize,
        /// Frames needed.
        need: usize,
    },
    /// An image could not be decoded.
    #[error("{path}: cannot decode image: {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// A frame's size differs from the first frame's.
    #[error("{path}: frame is {got_w}x{got_h} px but the first frame is {want_w}x{want_h}")]
    FrameSize {
        /// The odd frame.
        path: PathBuf,
        /// Its width.
        got_w: u32,
        /// Its height.
        got_h: u32,
        /// The first frame's width.
        want_w: u32,
        /// The first frame's height.
        want_h: u32,
    },
    /// Nothing measurable in the frames (no filament edges, no trackable texture).
    #[error("{path}: {message}")]
    NotMeasurable {
        /// The folder.
        path: PathBuf,
        /// What could not be found.
        message: String,
    },
    /// The machine config could not be read or does not validate.
    #[error("{path}: {message}")]
    Config {
        /// The config file.
        path: PathBuf,
        /// Parse or validation message.
        message: String,
    },
    /// An option value is out of range, or options that belong together are missing.
    #[error("{0}")]
    Argument(String),
    /// The region of interest, clipped to the frames, leaves too few pixels to measure.
    /// The words name the input, not a flag: `dollop calibrate` says `--roi`, the
    /// dashboard its field.
    #[error("the region of interest leaves {w}x{h} px of the {frame_w}x{frame_h} frames; at least {min}x{min} are needed")]
    RoiTooSmall {
        /// Width left, px.
        w: u32,
        /// Height left, px.
        h: u32,
        /// Frame width, px.
        frame_w: u32,
        /// Frame height, px.
        frame_h: u32,
        /// The least width and height measured.
        min: u32,
    },
    /// The plot could not be drawn.
    #[error("{path}: cannot draw the plot: {message}")]
    Plot {
        /// The PNG file.
        path: PathBuf,
        /// What the drawing library said.
        message: String,
    },
}

impl CalError {
    /// Shorthand for [`CalError::Argument`].
    pub fn arg(message: impl Into<String>) -> Self {
        CalError::Argument(message.into())
    }
}
