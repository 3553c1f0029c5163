//! `SliceError`: every way slicing, reading or writing a design, config, job, G-code or
//! preview can fail, each with a one-line message naming the file and the problem. Which
//! module raises which variant is theirs; this file only names and words them. An option
//! or limit a message points at is a `SliceOption` or `SliceLimit`, never a flag: the front
//! ends name them through `Names` (`cmd::slice`: the flags, `serve::error`: the page's
//! fields); `Display` uses the library's plain `Words`.

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
    #[error("{}", too_large(.what, .size, .travel, &Words))]
    TooLarge {
        /// The design.
        what: String,
        /// Size of everything the job visits, mm.
        size: [f64; 3],
        /// Travel span of the machine, mm.
        travel: [f64; 3],
    },
    /// The design, placed as asked, leaves the travel limits.
    #[error("{}", outside_travel(.what, .axis, [*.lo, *.hi], [*.min, *.max], &Words))]
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
    #[error("{what}: {found} materials but the machine has {inlets} inlet(s){}", .hint.text(&Words))]
    TooManyMaterials {
        /// The design.
        what: String,
        /// Colours or bodies found.
        found: usize,
        /// Inlets configured.
        inlets: usize,
        /// How to fix it.
        hint: MaterialsHint,
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
    /// No design file was given.
    #[error("no design file given")]
    NoDesign,
    /// Images are sliced one at a time (their colours are the materials).
    #[error("{}: give one image (its colours are the materials); {count} files given", .path.display())]
    ImageNotAlone {
        /// The first design file.
        path: PathBuf,
        /// Files given.
        count: usize,
    },
    /// A 3MF holds every material's body, so it comes alone.
    #[error("{}: a 3MF holds every material's body; give it alone (got {count} files)", .path.display())]
    ThreeMfNotAlone {
        /// The 3MF.
        path: PathBuf,
        /// Files given.
        count: usize,
    },
    /// A file that is not an STL among STL bodies.
    #[error("{}: cannot mix with STL bodies (give one STL per material, one image, or one 3MF)", .path.display())]
    MixedWithStl {
        /// The file that is not an STL.
        path: PathBuf,
    },
    /// The mesh slicer's line pitch or layer height is not above zero.
    #[error("pitch and layer height must be above zero")]
    NoSpacing,
    /// The image slicer's line pitch is not above zero.
    #[error("{what}: line pitch {pitch_mm} mm must be above 0")]
    LinePitch {
        /// The design.
        what: String,
        /// The pitch, mm.
        pitch_mm: f64,
    },
    /// An image would be sampled on more points than the slicer allows.
    #[error("{what}: {cols} x {rows} samples is too many; print it smaller or coarser")]
    TooManySamples {
        /// The design.
        what: String,
        /// Samples across.
        cols: usize,
        /// Rows.
        rows: usize,
    },
    /// A mesh would be cut into more rows than the slicer allows (a model in metres?).
    #[error("{what}: {rows} rows x {layers} layers is too many; check the model's units")]
    TooManyRows {
        /// The design.
        what: String,
        /// Rows a layer.
        rows: usize,
        /// Layers.
        layers: usize,
    },
    /// A job names a material the machine has no inlet for.
    #[error("the job uses material {material} but the machine has {inlets} inlet(s)")]
    MaterialBeyondInlets {
        /// The highest material the job uses.
        material: u8,
        /// Inlets configured.
        inlets: usize,
    },
    /// The executor's run of the job (for the G-code) could not happen.
    #[error("G-code: the executor's run failed: {reason}")]
    ExecutorRun {
        /// What the run said.
        reason: dollop_sim::run::SimError,
    },
    /// The executor's run of the job (for the G-code) ended in a fault.
    #[error("G-code: the executor stopped the job with a fault ({fault}); check the job against the config with `dollop simulate`")]
    ExecutorFault {
        /// The fault.
        fault: dollop::Fault,
    },
    /// An input is larger than a limit the front end sets; `what` says how large and the
    /// limit, the limit is named for the front end to word.
    #[error("{}", over_limit(.what, *.limit, *.or, &Words))]
    OverLimit {
        /// The input, how large it is and the limit (`logo.png: 20 x 10 = 200 exceeds the
        /// limit of 10 by 190`).
        what: String,
        /// The limit.
        limit: SliceLimit,
        /// An option that also brings the input within the limit.
        or: Option<SliceOption>,
    },
    /// The G-code would be larger than its limit.
    #[error("{}", gcode_too_large(.what, *.bytes, *.limit, &Words))]
    GcodeTooLarge {
        /// Which text, how sure (`this job's would be at least`).
        what: String,
        /// Its size, bytes.
        bytes: u64,
        /// The limit, bytes.
        limit: u64,
    },
    /// The corner markers cannot be added.
    #[error("{}", markers(.0, &Words))]
    Markers(MarkerError),
    /// A value of a `SliceRequest` that cannot work, naming the option as a `SliceOption`
    /// (front ends word it: a flag, a field).
    #[error("{}", .0.message(Words.option(.0.option)))]
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
    /// Images: printed width, mm.
    Width,
    /// Images: printed height, mm.
    Height,
    /// The design's printed size: its width or height (images).
    Size,
    /// Images: the grey level dividing the two materials.
    Threshold,
    /// The corner markers for `dollop inspect`.
    Markers,
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
            SliceOption::Width => "width (mm)",
            SliceOption::Height => "height (mm)",
            SliceOption::Size => "width/height",
            SliceOption::Threshold => "threshold",
            SliceOption::Markers => "markers",
        }
    }
}

/// A value of a `SliceRequest` that cannot work.
#[derive(Clone, Debug, PartialEq)]
pub struct OptionError {
    /// The design it was refused for, when the check needed the design (`logo.png`).
    pub design: Option<String>,
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
            design: None,
            option,
            value,
            problem,
        }
    }

    /// The same refusal, for the design `name`.
    pub(super) fn of(self, name: &str) -> Self {
        OptionError {
            design: Some(name.to_string()),
            ..self
        }
    }

    /// The message, with the option called `name`: `NAME VALUE PROBLEM` or `NAME: PROBLEM`,
    /// after `DESIGN: ` when it was refused for a design.
    pub fn message(&self, name: &str) -> String {
        let design = self
            .design
            .as_ref()
            .map(|d| format!("{d}: "))
            .unwrap_or_default();
        match &self.value {
            Some(v) => format!("{design}{name} {v} {}", self.problem),
            None => format!("{design}{name}: {}", self.problem),
        }
    }
}

impl std::fmt::Display for OptionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message(self.option.words()))
    }
}

/// A resource limit of a slice (`Limits`, and the G-code's size), as the library names it;
/// front ends word it (`cmd::slice`: the flag that sets it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceLimit {
    /// Image pixels.
    Pixels,
    /// Print runs in the whole design.
    Segments,
    /// Mesh triangles.
    Triangles,
    /// A 3MF's uncompressed model XML, MiB.
    ThreeMfSize,
    /// The G-code text, MiB.
    GcodeSize,
}

impl SliceLimit {
    /// Plain words for the limit, for a message with no front end to name it.
    pub fn words(self) -> &'static str {
        match self {
            SliceLimit::Pixels => "the pixel limit",
            SliceLimit::Segments => "the segment limit",
            SliceLimit::Triangles => "the triangle limit",
            SliceLimit::ThreeMfSize => "the 3MF size limit",
            SliceLimit::GcodeSize => "the G-code size limit",
        }
    }
}

/// How a front end names the options and limits that the slicer's messages point at
/// ([`SliceError::message`]): the command line by its flags, the dashboard by its fields.
pub trait Names {
    /// The name of an option.
    fn option(&self, o: SliceOption) -> &'static str;
    /// The name of a limit (what raises it).
    fn limit(&self, l: SliceLimit) -> &'static str;
}

/// The library's own plain words (what `Display` says).
pub struct Words;

impl Names for Words {
    fn option(&self, o: SliceOption) -> &'static str {
        o.words()
    }
    fn limit(&self, l: SliceLimit) -> &'static str {
        l.words()
    }
}

/// What to do about more materials than inlets, by where they came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialsHint {
    /// An image's colours, after its background and palette.
    Background,
    /// An image's colours with a palette given or picked (`auto`).
    Palette,
    /// The materials of a 3MF's objects.
    ThreeMfObjects,
    /// One STL per material.
    StlPerMaterial,
}

impl MaterialsHint {
    /// The hint, read after the counts (`; ...` or ` (...)`).
    pub fn text(self, names: &dyn Names) -> String {
        let o = |o| names.option(o);
        match self {
            MaterialsHint::Background => format!(
                "; use {} for the unprinted colour, or a config with more inlets",
                o(SliceOption::Background)
            ),
            MaterialsHint::Palette => format!(
                "; give {} with at most that many colours, {} for the unprinted one, or use {}",
                o(SliceOption::Palette),
                o(SliceOption::Background),
                o(SliceOption::Threshold)
            ),
            MaterialsHint::ThreeMfObjects => " (materials of the 3MF's objects)".into(),
            MaterialsHint::StlPerMaterial => " (one STL per material, in inlet order)".into(),
        }
    }
}

/// Why the corner markers cannot be added.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerError {
    /// The job prints nothing.
    NothingPrinted,
    /// The job prints more than one layer.
    Layers,
    /// A marker would lie outside the machine's travel.
    OutOfTravel,
}

impl MarkerError {
    /// The reason, with options named by `names`.
    pub fn message(self, names: &dyn Names) -> String {
        match self {
            MarkerError::NothingPrinted => "the job prints nothing to put markers about".into(),
            MarkerError::Layers => format!(
                "corner markers are for single-layer jobs (a photo sees only the top layer); slice with {} 1",
                names.option(SliceOption::Layers)
            ),
            MarkerError::OutOfTravel => format!(
                "the corner markers would lie outside the machine's travel; place the design further from its edges ({})",
                names.option(SliceOption::Origin)
            ),
        }
    }
}

impl std::fmt::Display for MarkerError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message(&Words))
    }
}

impl SliceError {
    /// The message with the options and limits it points at named by `names` (a front
    /// end's words); `Display` is this with the library's [`Words`].
    pub fn message(&self, names: &dyn Names) -> String {
        match self {
            SliceError::TooLarge { what, size, travel } => too_large(what, size, travel, names),
            SliceError::OutsideTravel {
                what,
                axis,
                lo,
                hi,
                min,
                max,
            } => outside_travel(what, axis, [*lo, *hi], [*min, *max], names),
            SliceError::TooManyMaterials {
                what,
                found,
                inlets,
                hint,
            } => format!(
                "{what}: {found} materials but the machine has {inlets} inlet(s){}",
                hint.text(names)
            ),
            SliceError::OverLimit { what, limit, or } => over_limit(what, *limit, *or, names),
            SliceError::GcodeTooLarge { what, bytes, limit } => {
                gcode_too_large(what, *bytes, *limit, names)
            }
            SliceError::Markers(m) => markers(m, names),
            SliceError::BadOption(o) => o.message(names.option(o.option)),
            e => e.to_string(),
        }
    }
}

fn too_large(what: &str, size: &[f64; 3], travel: &[f64; 3], names: &dyn Names) -> String {
    format!(
        "{what}: design is {:.1} x {:.1} x {:.1} mm (with priming line) but the travel limits allow {:.1} x {:.1} x {:.1} mm; scale it ({}) or move it ({})",
        size[0],
        size[1],
        size[2],
        travel[0],
        travel[1],
        travel[2],
        names.option(SliceOption::Size),
        names.option(SliceOption::Origin)
    )
}

fn outside_travel(
    what: &str,
    axis: &str,
    [lo, hi]: [f64; 2],
    [min, max]: [f64; 2],
    names: &dyn Names,
) -> String {
    format!(
        "{what}: placed at the given origin the job leaves the travel limits on {axis} ({lo:.2} .. {hi:.2} mm, allowed {min:.2} .. {max:.2}); change {}",
        names.option(SliceOption::Origin)
    )
}

fn over_limit(what: &str, limit: SliceLimit, or: Option<SliceOption>, names: &dyn Names) -> String {
    let or = or
        .map(|o| format!(" (or {})", names.option(o)))
        .unwrap_or_default();
    format!("{what} ({}{or} raises it)", names.limit(limit))
}

fn gcode_too_large(what: &str, bytes: u64, limit: u64, names: &dyn Names) -> String {
    let mb = |b: u64| b as f64 / (1u64 << 20) as f64;
    format!(
        "G-code: {what} {:.1} MiB, over the limit of {:.1} MiB ({}); raise the limit if the disk and memory allow (the text is built in memory), slice a smaller or coarser design, or send the job file to a dollop board, which needs no G-code",
        mb(bytes),
        mb(limit),
        names.limit(SliceLimit::GcodeSize)
    )
}

fn markers(m: &MarkerError, names: &dyn Names) -> String {
    format!(
        "{}: {}",
        names.option(SliceOption::Markers),
        m.message(names)
    )
}
