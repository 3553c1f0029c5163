//! Job commands the executor consumes: print segments with a material each, travel moves,
//! layer changes, dwells. Fixed-size, serde-ready for `postcard` without allocation; the
//! file/wire framing (headers, CRC, chunks) lives with the host tools and the USB link.

use serde::{Deserialize, Serialize};

pub mod walk;
pub use walk::{walk, Move, MoveKind};

/// Coordinates in jobs are integer micrometres: exact, compact as varints, and far finer
/// than the 0.05 mm the boundaries are held to.
pub type Micrometres = i32;

/// One job command. A run of consecutive `Print`s is one polyline (one continuous bead);
/// any other command ends it, and the valves close before the head travels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Command {
    /// Print a straight bead from the current point by (dx, dy) micrometres, in the
    /// material of inlet `material`. Zero-length segments are ignored.
    Print {
        /// X displacement, micrometres.
        dx: Micrometres,
        /// Y displacement, micrometres.
        dy: Micrometres,
        /// Inlet (material) index, 0-based.
        material: u8,
    },
    /// Move with the valves closed to an absolute point, micrometres.
    Travel {
        /// Absolute X, micrometres.
        x: Micrometres,
        /// Absolute Y, micrometres.
        y: Micrometres,
        /// Absolute Z, micrometres.
        z: Micrometres,
    },
    /// Change layer: move Z to the absolute height (micrometres), X and Y unchanged.
    Layer {
        /// Absolute Z, micrometres.
        z: Micrometres,
    },
    /// Wait in place with the valves closed.
    Dwell {
        /// Milliseconds.
        ms: u32,
    },
    /// End of job: finish the last bead, close the valves, stop.
    End,
}

/// Why a command cannot be executed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CommandError {
    /// The material index is not a configured inlet.
    NoSuchInlet {
        /// The index the command named.
        material: u8,
        /// How many inlets the machine has.
        inlets: u8,
    },
    /// A dwell longer than the executor accepts (one hour).
    DwellTooLong {
        /// The dwell asked for, ms.
        ms: u32,
    },
    /// A print segment longer than the executor accepts (10 m), a sign of corrupt data.
    SegmentTooLong,
    /// A print segment arrived with no travel before it to set the starting point.
    PrintBeforeStart,
    /// A command arrived after `End`.
    AfterEnd,
}

/// Longest dwell accepted, ms.
pub const MAX_DWELL_MS: u32 = 3_600_000;
/// Longest print segment accepted, micrometres.
pub const MAX_SEGMENT_UM: i64 = 10_000_000;

impl core::fmt::Display for CommandError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            CommandError::NoSuchInlet { material, inlets } => write!(
                f,
                "print segment uses material {material} but the machine has {inlets} inlet(s)"
            ),
            CommandError::DwellTooLong { ms } => {
                write!(
                    f,
                    "dwell of {ms} ms is longer than the 1 h the executor accepts"
                )
            }
            CommandError::SegmentTooLong => {
                write!(f, "print segment longer than 10 m (corrupt job?)")
            }
            CommandError::PrintBeforeStart => {
                write!(
                    f,
                    "print segment before any travel move set the start point"
                )
            }
            CommandError::AfterEnd => write!(f, "command after the end of the job"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn postcard_encodes_a_print_segment_in_a_few_bytes() {
        let mut buf = [0u8; 32];
        let c = Command::Print {
            dx: 800,
            dy: -200,
            material: 1,
        };
        let used = postcard::to_slice(&c, &mut buf).unwrap();
        assert!(used.len() <= 6, "{} bytes", used.len());
        let back: Command = postcard::from_bytes(used).unwrap();
        assert_eq!(back, c);
    }
}
