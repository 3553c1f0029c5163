//! `GcodeInError`: every way importing G-code can fail, each a one-line message naming the
//! line and what to change (in the file, the slicer or the flags). Raised by the lexer, the
//! modal machine and the emitter; the command line maps nothing further.

/// Why a G-code file was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GcodeInError {
    /// The file is larger than the import limit (checked from its size, before reading).
    #[error("G-code file of {bytes} bytes is larger than the {limit} bytes the import reads (raise --max-gcode-in-mb if it is genuine)")]
    FileTooLarge {
        /// Size of the file.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A line longer than `MAX_LINE_BYTES`: not G-code (a binary file?).
    #[error("line {line}: {len} bytes long, more than the {limit} a G-code line may have (is this a binary file?)")]
    LineTooLong {
        /// 1-based line number.
        line: usize,
        /// Its length.
        len: usize,
        /// The limit.
        limit: usize,
    },
    /// A word whose value is not a decimal number.
    #[error("line {line}: `{word}` is not a number after {letter}")]
    BadNumber {
        /// 1-based line number.
        line: usize,
        /// The word's letter.
        letter: char,
        /// What followed it.
        word: String,
    },
    /// NaN or infinity (written out, or a number too long for a double).
    #[error("line {line}: {letter} is not a finite number")]
    NotFinite {
        /// 1-based line number.
        line: usize,
        /// The word's letter.
        letter: char,
    },
    /// A coordinate (or E) beyond any printer: a corrupt file or a unit mix-up.
    #[error("line {line}: {axis} = {value} mm is beyond the {limit} mm the import accepts (G20 inches where the file means millimetres?)")]
    OutOfRange {
        /// 1-based line number.
        line: usize,
        /// The axis.
        axis: char,
        /// The value, mm.
        value: f64,
        /// The limit, mm.
        limit: f64,
    },
    /// A move leaves the machine's travel.
    #[error("line {line}: {axis} = {value:.3} mm is outside the machine's travel {min} .. {max} mm (set the slicer's bed shape to the config's [motion] limits, or move the part)")]
    OutsideTravel {
        /// 1-based line number.
        line: usize,
        /// The axis.
        axis: char,
        /// Where the move goes, mm.
        value: f64,
        /// Travel minimum, mm.
        min: f64,
        /// Travel maximum, mm.
        max: f64,
    },
    /// A tool (or valve) with no inlet in the tool map.
    #[error("line {line}: tool {tool} has no inlet: --tools maps {mapped} tool(s) onto the machine's {inlets} inlet(s) (give --tools with an inlet for every tool the file uses)")]
    NoInlet {
        /// 1-based line number.
        line: usize,
        /// The tool (or valve) number.
        tool: u32,
        /// How many tools the map names.
        mapped: usize,
        /// The machine's inlets.
        inlets: usize,
    },
    /// The tool map itself is wrong.
    #[error("--tools {text}: {reason}")]
    BadToolMap {
        /// The flag's value.
        text: String,
        /// What is wrong.
        reason: String,
    },
    /// A wipe tower, prime tower or other purge block, and `--strip-purge` not given.
    #[error("line {line}: {what} (`;TYPE:{kind}`): dollop needs no purge; turn off {setting} in the slicer, or give --strip-purge to drop it")]
    Purge {
        /// 1-based line number.
        line: usize,
        /// The block's type as the file names it.
        kind: String,
        /// What it is.
        what: &'static str,
        /// The slicer setting that makes it.
        setting: &'static str,
    },
    /// An arc the import cannot place.
    #[error("line {line}: {reason}")]
    BadArc {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Z changes during an extrusion move (spiral vase): job print segments are flat.
    #[error("line {line}: Z changes while extruding (spiral vase or Z-hop while printing?); dollop's beads are flat: turn off spiralize/vase mode")]
    ExtrudingZ {
        /// 1-based line number.
        line: usize,
    },
    /// Nothing is extruded anywhere in the file.
    #[error("the G-code extrudes nothing (no move with positive E): nothing to print")]
    NoExtrusion,
    /// More print segments or commands than the limits allow.
    #[error("line {line}: more than {limit} {what}; the job would be too large (raise {flag} if it is genuine)")]
    TooMany {
        /// 1-based line number where the limit was passed.
        line: usize,
        /// What was counted.
        what: &'static str,
        /// The limit.
        limit: u64,
        /// The flag that raises it.
        flag: &'static str,
    },
    /// A priming bead length that is not a length.
    #[error("--prime-mm {value}: give a length in mm, or 0 for no priming bead")]
    BadPrime {
        /// What was given.
        value: f64,
    },
    /// A filament diameter that is not one.
    #[error("--filament-mm {value}: give the filament's diameter in mm (0 to 100), or --volumetric when E is volume")]
    BadFilament {
        /// What was given.
        value: f64,
    },
    /// No room on the plate for the priming bead.
    #[error("no room for the {len:.1} mm priming bead below or above the part within the machine's travel (move the part, or give --prime-mm 0 if the G-code primes itself)")]
    NoRoomForPrime {
        /// The bead's length, mm.
        len: f64,
    },
}

/// Why importing a G-code file failed: reading it, or its content. The message names the
/// file and leaves the cause to the error's source, so a chain printed with `{:#}` (as the
/// command line does) says the cause once.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be read.
    #[error("{}: cannot read", .path.display())]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The content was refused.
    #[error("{}", .path.display())]
    Gcode {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        source: GcodeInError,
    },
}
