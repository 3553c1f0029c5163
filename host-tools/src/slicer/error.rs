//! `SliceError`: every way slicing, reading or writing a design, config, job, G-code or
//! preview can fail, each with a one-line message naming the file and the problem. Which
//! module raises which variant is theirs; this file only names and words them (and a
//! refused request option, `OptionError`, by a `SliceOption` the front ends word).

use std::path::{Path, PathBuf};

/// Why a slice (or a job/G-code/preview read or write) did not happen.
#[derive(Debug, thiserror::Error)]
pub enum SliceError {
    /// A picture could not be drawn (or was asked for beyond the job).
    #[error("preview: {message}")]
    Picture {
        /// What went wrong, in words.
        message: String,
    },
    /// The file does not exist.
    #[error("{}: no such file", .path.display())]
    NotFound {
        /// The file.
        path: PathBuf,
    },
    /// The file exists but could not be read.
    #[error("{}: cannot read: {source}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An output could not be written (nothing was left at `path`).
    #[error("{}: cannot write: {source}", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The extension is neither an image nor a mesh format this build reads.
    #[error("{}: unknown design format (expected .png, .jpg, .jpeg, .bmp, .stl, .3mf, or G-code: .gcode)", .path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The image could not be decoded.
    #[error("{}: unreadable image: {reason}", .path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        reason: String,
    },
    /// The STL could not be parsed.
    #[error("{}: unreadable STL: {reason}", .path.display())]
    Stl {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        reason: String,
    },
    /// The 3MF could not be read, or describes no printable body.
    #[error("{}: unusable 3MF: {reason}", .path.display())]
    ThreeMf {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The STL holds no triangle.
    #[error("{}: STL has no triangles", .path.display())]
    NoTriangles {
        /// The file.
        path: PathBuf,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("{}: triangle {triangle} has a NaN or infinite vertex", .path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 0-based triangle index in the file.
        triangle: usize,
    },
    /// Some edges are not shared by exactly two triangles: the body is open or non-manifold.
    #[error(
        "{}: not a closed manifold body: {edges} edge(s) not shared by exactly two triangles (first near ({:.3}, {:.3}, {:.3}) mm); repair the mesh",
        .path.display(), .at[0], .at[1], .at[2]
    )]
    NonManifold {
        /// The file.
        path: PathBuf,
        /// Offending edges.
        edges: usize,
        /// A point on the first offending edge, model mm.
        at: [f64; 3],
    },
    /// Two triangles of an edge run along it the same way: part of the body faces inward.
    #[error(
        "{}: faces not consistently oriented: {edges} edge(s) where two triangles run the same way, so some face inward and some outward (first near ({:.3}, {:.3}, {:.3}) mm); repair the mesh (unify or recalculate its normals)",
        .path.display(), .at[0], .at[1], .at[2]
    )]
    Misoriented {
        /// The file.
        path: PathBuf,
        /// Edges shared by two triangles running the same way.
        edges: usize,
        /// A point on the first such edge, model mm.
        at: [f64; 3],
    },
    /// Two material bodies claim the same volume.
    #[error(
        "{} and {} overlap near ({:.2}, {:.2}, {:.2}) mm (model coordinates); each point may belong to one material only",
        .a.display(), .b.display(), .at[0], .at[1], .at[2]
    )]
    Overlap {
        /// First body's file.
        a: PathBuf,
        /// Second body's file.
        b: PathBuf,
        /// Where, model mm.
        at: [f64; 3],
    },
    /// Nothing in the design would be printed.
    #[error("{what}: empty design: nothing to print ({why})")]
    EmptyDesign {
        /// The design (file names).
        what: String,
        /// Why nothing is left.
        why: String,
    },
    /// The design and its priming line do not fit the machine's travel.
    #[error(
        "{what}: design is {:.1} x {:.1} x {:.1} mm (with priming line) but the travel limits allow {:.1} x {:.1} x {:.1} mm; scale it (--width-mm/--height-mm) or move it (--origin)",
        .size[0], .size[1], .size[2], .travel[0], .travel[1], .travel[2]
    )]
    TooLarge {
        /// The design.
        what: String,
        /// Size of everything the job visits, mm.
        size: [f64; 3],
        /// Travel span of the machine, mm.
        travel: [f64; 3],
    },
    /// The design, placed as asked, leaves the travel limits.
    #[error("{what}: placed at the given origin the job leaves the travel limits on {axis} ({lo:.2} .. {hi:.2} mm, allowed {min:.2} .. {max:.2}); change --origin")]
    OutsideTravel {
        /// The design.
        what: String,
        /// "X", "Y" or "Z".
        axis: &'static str,
        /// Lowest coordinate visited, mm.
        lo: f64,
        /// Highest coordinate visited, mm.
        hi: f64,
        /// Travel minimum, mm.
        min: f64,
        /// Travel maximum, mm.
        max: f64,
    },
    /// More colours (or material bodies) than the machine has inlets.
    #[error("{what}: {found} materials but the machine has {inlets} inlet(s){hint}")]
    TooManyMaterials {
        /// The design.
        what: String,
        /// Colours or bodies found.
        found: usize,
        /// Inlets configured.
        inlets: usize,
        /// How to fix it.
        hint: &'static str,
    },
    /// The config file does not parse.
    #[error("{}: config does not parse: {reason}", .path.display())]
    ConfigParse {
        /// The file.
        path: PathBuf,
        /// The parser's message (first line).
        reason: String,
    },
    /// The config parses but does not validate.
    #[error("{}: invalid config: {problem}", .path.display())]
    ConfigInvalid {
        /// The file.
        path: PathBuf,
        /// The failing field and why (the core's error has no `std::error::Error`).
        problem: dollop::ConfigError,
    },
    /// A job file is corrupt or of another version.
    #[error("{}: {problem}", .path.display())]
    Job {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: dollop::job::JobError,
    },
    /// An option value that cannot work (named in the message).
    #[error("{0}")]
    Option(String),
    /// A value of a `SliceRequest` that cannot work, naming the option as a `SliceOption`
    /// (front ends word it: a flag, a field).
    #[error("{0}")]
    BadOption(OptionError),
}

impl SliceError {
    /// The error for failing to open or read `path`.
    pub fn read(path: &Path, source: std::io::Error) -> Self {
        if source.kind() == std::io::ErrorKind::NotFound {
            SliceError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            SliceError::Read {
                path: path.to_path_buf(),
                source,
            }
        }
    }
}

/// An option of a slice request, as the library names it; front ends map it to their own
/// words (`cmd::slice`: the flag, `serve::design`: the form's field).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceOption {
    /// The colours that pick materials (`auto` or a list).
    Palette,
    /// The colour not printed.
    Background,
    /// How near a pixel must be to the background colour to count as it.
    BackgroundTolerance,
    /// Shortest material run kept, mm.
    MinRun,
    /// The design's lower-left corner on the plate, mm.
    Origin,
    /// Layers to stack or print.
    Layers,
    /// Rows joined within this distance, mm.
    Connect,
    /// Priming bead length, mm.
    Prime,
    /// The valves' ports in the G-code.
    GcodePorts,
}

impl SliceOption {
    /// Plain words for the option, for a message with no front end to name it.
    pub fn words(self) -> &'static str {
        match self {
            SliceOption::Palette => "palette",
            SliceOption::Background => "background colour",
            SliceOption::BackgroundTolerance => "background tolerance",
            SliceOption::MinRun => "shortest run (mm)",
            SliceOption::Origin => "origin",
            SliceOption::Layers => "layers",
            SliceOption::Connect => "row joining distance (mm)",
            SliceOption::Prime => "priming bead (mm)",
            SliceOption::GcodePorts => "G-code valve ports",
        }
    }
}

/// A value of a `SliceRequest` that cannot work.
#[derive(Clone, Debug, PartialEq)]
pub struct OptionError {
    /// Which option.
    pub option: SliceOption,
    /// The value as given, when the problem is about it as a whole (`-1`, `"1,x"`).
    pub value: Option<String>,
    /// What is wrong and what would do: reads after the option's name (and value).
    pub problem: String,
}

impl OptionError {
    pub(super) fn new(option: SliceOption, value: Option<String>, problem: String) -> Self {
        OptionError {
            option,
            value,
            problem,
        }
    }

    /// The message, with the option called `name`: `NAME VALUE PROBLEM` or `NAME: PROBLEM`.
    pub fn message(&self, name: &str) -> String {
        match &self.value {
            Some(v) => format!("{name} {v} {}", self.problem),
            None => format!("{name}: {}", self.problem),
        }
    }
}

impl std::fmt::Display for OptionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message(self.option.words()))
    }
}
