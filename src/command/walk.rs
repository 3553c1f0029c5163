//! Walking a job's commands as head moves: `walk(commands, start)` yields each move with
//! its command index, where it starts and ends (µm), its layer and what kind it is, so the
//! host's previews, exporters and judges stop keeping the position and the layer count by
//! hand. No heap (an iterator over the slice). Where it stops: timing, speeds and valves
//! are the executor's; dwells and `End` move nothing and are not yielded.

use super::{Command, Micrometres};

/// What a move does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKind {
    /// A bead in the material of this inlet (`Command::Print`).
    Print {
        /// Inlet index.
        material: u8,
    },
    /// Valves closed, to an absolute point (`Command::Travel`).
    Travel,
    /// Z only, X and Y unchanged (`Command::Layer`).
    Layer,
}

/// One head move of a job.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Move {
    /// Index of its command in the job.
    pub index: usize,
    /// Where the head starts, µm.
    pub from: [Micrometres; 3],
    /// Where it ends, µm (a print's end saturates at the `i32` range rather than wrap).
    pub to: [Micrometres; 3],
    /// Layer: 0 from the start, one more each time a move first rises above every height
    /// reached before it (a travel or layer change going down, then back up, is no new
    /// layer).
    pub layer: u32,
    /// What it does.
    pub kind: MoveKind,
}

/// The moves of `commands` from `start` (µm).
pub fn walk(commands: &[Command], start: [Micrometres; 3]) -> Walk<'_> {
    Walk {
        commands,
        next: 0,
        at: start,
        top_z: start[2],
        layer: 0,
    }
}

/// The iterator `walk` returns.
#[derive(Clone, Debug)]
pub struct Walk<'a> {
    commands: &'a [Command],
    next: usize,
    at: [Micrometres; 3],
    top_z: Micrometres,
    layer: u32,
}

impl Walk<'_> {
    /// Where the head stands after the moves yielded so far, µm.
    pub fn position(&self) -> [Micrometres; 3] {
        self.at
    }

    /// Layers begun so far (the layer of the last move yielded).
    pub fn layer(&self) -> u32 {
        self.layer
    }

    fn rise_to(&mut self, z: Micrometres) {
        if z > self.top_z {
            self.layer += 1;
            self.top_z = z;
        }
    }
}

impl Iterator for Walk<'_> {
    type Item = Move;

    fn next(&mut self) -> Option<Move> {
        while let Some(&c) = self.commands.get(self.next) {
            let index = self.next;
            self.next += 1;
            let from = self.at;
            let (to, kind) = match c {
                Command::Print { dx, dy, material } => (
                    [
                        from[0].saturating_add(dx),
                        from[1].saturating_add(dy),
                        from[2],
                    ],
                    MoveKind::Print { material },
                ),
                Command::Travel { x, y, z } => {
                    self.rise_to(z);
                    ([x, y, z], MoveKind::Travel)
                }
                Command::Layer { z } => {
                    self.rise_to(z);
                    ([from[0], from[1], z], MoveKind::Layer)
                }
                Command::Dwell { .. } | Command::End | Command::Section { .. } => continue,
            };
            self.at = to;
            return Some(Move {
                index,
                from,
                to,
                layer: self.layer,
                kind,
            });
        }
        None
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (0, Some(self.commands.len() - self.next))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const JOB: [Command; 8] = [
        Command::Travel {
            x: 1000,
            y: 1000,
            z: 800,
        },
        Command::Print {
            dx: 2000,
            dy: 0,
            material: 0,
        },
        Command::Dwell { ms: 5 },
        Command::Print {
            dx: 0,
            dy: -500,
            material: 1,
        },
        Command::Layer { z: 1400 },
        Command::Travel {
            x: 0,
            y: 0,
            z: 1000,
        },
        Command::Travel {
            x: 0,
            y: 0,
            z: 2000,
        },
        Command::End,
    ];

    #[test]
    fn moves_carry_index_positions_layer_and_kind() {
        let mut w = walk(&JOB, [0, 0, 800]);
        let all: [Option<Move>; 6] = core::array::from_fn(|_| w.next());
        assert!(w.next().is_none());
        assert_eq!(w.position(), [0, 0, 2000]);
        let m = all.map(|m| m.expect("six moves"));
        // Dwell (2) and End (7) move nothing.
        assert_eq!(m.map(|m| m.index), [0, 1, 3, 4, 5, 6]);
        assert_eq!(m[1].from, [1000, 1000, 800]);
        assert_eq!(m[1].to, [3000, 1000, 800]);
        assert_eq!(m[2].to, [3000, 500, 800]);
        assert_eq!(m[2].kind, MoveKind::Print { material: 1 });
        assert_eq!(m[3].to, [3000, 500, 1400]);
        assert_eq!(m[3].kind, MoveKind::Layer);
        // Down to 1.0 mm is no new layer; up to 2.0 mm, above 1.4 mm, is one.
        assert_eq!(m.map(|m| m.layer), [0, 0, 0, 1, 1, 2]);
    }

    #[test]
    fn a_print_saturates_instead_of_wrapping() {
        let job = [Command::Print {
            dx: i32::MAX,
            dy: i32::MIN,
            material: 0,
        }];
        let m = walk(&job, [10, -10, 0]).next().expect("one move");
        assert_eq!(m.to, [i32::MAX, i32::MIN, 0]);
    }

    #[test]
    fn an_empty_job_has_no_moves() {
        assert!(walk(&[], [0; 3]).next().is_none());
        assert!(walk(&[Command::End], [0; 3]).next().is_none());
    }
}
