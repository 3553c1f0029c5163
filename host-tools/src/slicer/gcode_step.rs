//! `Step`: one step of the executor's run as `gcode_exec` samples it (a move, a valve
//! change, a dwell), the vocabulary `gcode_ramps` fits to a firmware's acceleration and
//! `gcode_dialect` writes. Data only, so those three import it and not one another.

/// One step of the sampled run, before it is written in a dialect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Straight move to `to` (mm) at `v` mm/s; `travel` with every valve closed between
    /// beads (written as `G0`).
    Move {
        /// Target, mm.
        to: [f64; 3],
        /// Feed, mm/s.
        v: f64,
        /// A travel move.
        travel: bool,
    },
    /// The valves take this mask (bit i: inlet i open).
    Valves(u32),
    /// The head stands this long, s.
    Dwell(f64),
}
