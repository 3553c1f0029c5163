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
    #[error("{path}: {what}; raise the {option} if this input is right")]
    OverLimit {
        /// The file or folder.
        path: PathBuf,
        /// How large it is, the limit and by how much it is over.
        what: String,
        /// The option that sets the limit.
        option: CalOption,
    },
    /// The flow column's unit is not in its header and none was given.
    #[error("{path}: the flow column's unit is not in its header (mm3/s, ul/s, ml/min, mg/s, g/s, g/min); put it there")]
    RateUnitUnclear {
        /// The file.
        path: PathBuf,
    },
    /// Flows measured by mass and no density to turn them into volume.
    #[error("{path}: flows are in {unit}: give the density (g/ml) to turn them into volume")]
    NeedsDensity {
        /// The file.
        path: PathBuf,
        /// The table's mass-flow unit.
        unit: &'static str,
    },
    /// The header does not tell a rotational from an oscillatory test and no kind was given.
    #[error("{path}: cannot tell from the header {header:?} whether this is a rotational or an oscillatory test; say which kind it is, rotational or oscillatory")]
    KindUnclear {
        /// The file.
        path: PathBuf,
        /// The first column's header.
        header: String,
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
    /// An option's value refused, or options that belong together not given together,
    /// named in plain words; the front ends name them as their flags or fields
    /// ([`OptionError::message`]).
    #[error("{}", .0.message(CalOption::words))]
    Option(OptionError),
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

/// An input of a calibration that a front end names: the library names none of them as a
/// flag or a field (`dollop calibrate` maps each to its flag, the dashboard to its field).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalOption {
    /// The syringe's bore, mm.
    Diameter,
    /// The lead screw's lead, mm per turn.
    Lead,
    /// Motor full steps per turn.
    StepsPerRev,
    /// Microsteps per full step.
    Microsteps,
    /// Gear ratio between motor and screw.
    GearRatio,
    /// A measured mass per step, mg.
    MgPerStep,
    /// The paste's density, g/ml.
    Density,
    /// The shape factor of the bead.
    Shape,
    /// The head speed, mm/s.
    Speed,
    /// The volume flow, mm^3/s.
    Flow,
    /// The step rate, Hz.
    StepRate,
    /// The frames' rate, fps.
    Fps,
    /// The frames' scale, mm per pixel.
    MmPerPx,
    /// The line width to lay, mm.
    TargetWidth,
    /// The nozzle's diameter, mm.
    NozzleDiameter,
    /// The most frames read.
    MaxFrames,
    /// The most pixels over all frames.
    MaxPixels,
    /// The largest CSV file, MiB.
    MaxCsvMb,
    /// The most data rows.
    MaxRows,
}

impl CalOption {
    /// Its name in plain words (what a message says when no front end renamed it).
    pub fn words(self) -> &'static str {
        match self {
            CalOption::Diameter => "syringe diameter",
            CalOption::Lead => "lead",
            CalOption::StepsPerRev => "steps per turn",
            CalOption::Microsteps => "microsteps",
            CalOption::GearRatio => "gear ratio",
            CalOption::MgPerStep => "mass per step",
            CalOption::Density => "density",
            CalOption::Shape => "shape factor",
            CalOption::Speed => "speed",
            CalOption::Flow => "flow",
            CalOption::StepRate => "step rate",
            CalOption::Fps => "frame rate",
            CalOption::MmPerPx => "scale",
            CalOption::TargetWidth => "target line width",
            CalOption::NozzleDiameter => "nozzle diameter",
            CalOption::MaxFrames => "frame limit",
            CalOption::MaxPixels => "pixel limit",
            CalOption::MaxCsvMb => "file size limit",
            CalOption::MaxRows => "row limit",
        }
    }
}

impl std::fmt::Display for CalOption {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.words())
    }
}

/// What is wrong with the options given, whatever names them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OptionError {
    /// The option's value is not above zero (or not a number).
    NotPositive {
        /// The option.
        option: CalOption,
        /// Its value.
        value: f64,
    },
    /// The syringe's bore without the lead screw, or the reverse.
    HalfGeometry,
    /// A mass per step without the density.
    MassWithoutDensity,
    /// Neither the syringe's geometry nor a measurement.
    NoSyringeScale,
}

impl OptionError {
    /// The message, with each option called `name(option)`.
    pub fn message(&self, name: impl Fn(CalOption) -> &'static str) -> String {
        use CalOption::{Density, Diameter, Lead, MgPerStep};
        match *self {
            OptionError::NotPositive { option, value } => {
                format!("{} {value} must be above zero", name(option))
            }
            OptionError::HalfGeometry => format!(
                "{} and {} go together (syringe bore and lead screw)",
                name(Diameter),
                name(Lead)
            ),
            OptionError::MassWithoutDensity => format!(
                "{} needs {} (g/ml) to become a volume",
                name(MgPerStep),
                name(Density)
            ),
            OptionError::NoSyringeScale => format!(
                "give the syringe geometry ({} and {}) or a measurement ({} and {})",
                name(Diameter),
                name(Lead),
                name(MgPerStep),
                name(Density)
            ),
        }
    }
}

/// `value` if it is a number above zero, else the option's error.
pub fn positive(option: CalOption, value: f64) -> Result<f64, CalError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(CalError::Option(OptionError::NotPositive { option, value }))
    }
}

impl CalError {
    /// Shorthand for [`CalError::Argument`].
    pub fn arg(message: impl Into<String>) -> Self {
        CalError::Argument(message.into())
    }
}
