//! Job commands the executor consumes: print segments with a material each, travel moves,
//! layer changes, dwells, bead sections (job format 2). Fixed-size, serde-ready for
//! `postcard` without allocation; the file/wire framing (headers, CRC, chunks) lives with
//! the host tools and the USB link.

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
    /// The bead section S for the print segments that follow, square micrometres (job
    /// format 2): the head runs at `v = Q / S` along them. Between beads it holds from
    /// the next bead's start; between two print segments of one bead, from the next
    /// segment's start, where the head's speed changes at constant flow over a short
    /// staircase (`crate::section_taper`). Within [`section_limits`] of the machine's
    /// section. Appended last so that the postcard indices of the version 1 commands stay.
    Section {
        /// Bead cross-section, um^2 (1 mm^2 = 1 000 000).
        um2: u32,
    },
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
    /// A bead section outside what the machine accepts: at least its configured section
    /// (whose speeds the config was checked at: a narrower bead at the same flow would
    /// drive the head faster) and at most `MAX_SECTION_RATIO` times it.
    SectionOutOfRange {
        /// The section asked for, um^2.
        um2: u32,
        /// Smallest accepted, um^2.
        min_um2: u32,
        /// Largest accepted, um^2.
        max_um2: u32,
    },
    /// A `Section` between two print segments of one bead, which boards before issue 26's
    /// per-segment sections refused. No longer raised: kept so that a host still reads
    /// such a board's fault (and the variant indices stay).
    SectionInBead,
}

/// Longest dwell accepted, ms.
pub const MAX_DWELL_MS: u32 = 3_600_000;
/// Longest print segment accepted, micrometres.
pub const MAX_SEGMENT_UM: i64 = 10_000_000;
/// Widest bead section a job may ask, as a multiple of the machine's configured one. A
/// wider bead at the same flow only runs the head slower, so every speed limit the config
/// was checked at still holds; eight times is already a bead wider than any nozzle lays
/// (0.8 mm at 0.6 mm layers: 3.8 mm^2), past it the number is more likely corrupt.
pub const MAX_SECTION_RATIO: f64 = 8.0;

/// Sections a job may ask of a machine whose configured section is `bead_mm2`, um^2
/// (lowest, highest): from the configured one up to `MAX_SECTION_RATIO` times it.
pub fn section_limits(bead_mm2: f64) -> (u32, u32) {
    let um2 = |mm2: f64| libm::round(mm2 * 1e6).clamp(1.0, u32::MAX as f64) as u32;
    (um2(bead_mm2), um2(bead_mm2 * MAX_SECTION_RATIO))
}

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
            CommandError::SectionOutOfRange {
                um2,
                min_um2,
                max_um2,
            } => write!(
                f,
                "bead section of {:.4} mm^2 is outside {:.4} .. {:.4} mm^2 (the config's \
                 bead_area_mm2 up to {MAX_SECTION_RATIO} times it); lower bead_area_mm2 to \
                 the job's narrowest bead, or re-slice",
                um2 as f64 * 1e-6,
                min_um2 as f64 * 1e-6,
                max_um2 as f64 * 1e-6
            ),
            CommandError::SectionInBead => write!(
                f,
                "bead section changed between two print segments of one bead, which this \
                 board's firmware does not accept (update it)"
            ),
        }
    }
}

/// Lengthens the last command when it is a print segment that `(dx, dy)` in `material`
/// continues: same material, same line, same direction (exact in integers). True when it
/// did, so the caller pushes nothing. Shared by the job writers (the raster slicer, the
/// G-code importer), which keep one print segment per straight run.
pub fn extend_last_print(cmds: &mut [Command], dx: i32, dy: i32, material: u8) -> bool {
    if let Some(Command::Print {
        dx: pdx,
        dy: pdy,
        material: pm,
    }) = cmds.last_mut()
    {
        let cross = *pdx as i64 * dy as i64 - *pdy as i64 * dx as i64;
        let dot = *pdx as i64 * dx as i64 + *pdy as i64 * dy as i64;
        if *pm == material && cross == 0 && dot > 0 {
            *pdx += dx;
            *pdy += dy;
            return true;
        }
    }
    false
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

    #[test]
    fn version_1_commands_keep_their_bytes_and_a_section_comes_after_them() {
        // The postcard variant index is the first byte: the version 1 commands keep theirs.
        let mut buf = [0u8; 16];
        let first = |c: Command, buf: &mut [u8; 16]| postcard::to_slice(&c, buf).unwrap()[0];
        assert_eq!(first(Command::Dwell { ms: 1 }, &mut buf), 3);
        assert_eq!(first(Command::End, &mut buf), 4);
        let s = Command::Section { um2: 480_000 };
        let used = postcard::to_slice(&s, &mut buf).unwrap();
        assert_eq!(used, [5, 0x80, 0xA6, 0x1D]);
        assert!(used.len() <= crate::job::MAX_COMMAND_LEN);
    }

    #[test]
    fn section_limits_run_from_the_config_section_to_eight_times_it() {
        assert_eq!(section_limits(0.48), (480_000, 3_840_000));
        // Never zero, never past u32.
        assert_eq!(section_limits(0.0).0, 1);
        assert_eq!(section_limits(1e9).1, u32::MAX);
    }
}
