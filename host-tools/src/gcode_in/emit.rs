//! Moves to job commands: absolute targets rounded to integer micrometres once (so
//! rounding never drifts), a travel inserted wherever a bead does not start where the head
//! stands, Z-only moves as `Layer`, collinear same-material segments merged, the limits on
//! print segments and commands enforced as the commands are made; what section each print
//! command's moves asked is kept beside it for `sections`. The priming bead goes in front
//! at the end (`finish`), once the part's extent is known.

use super::error::GcodeInError;
use super::sections::Asked;
use dollop::Command;
use std::collections::BTreeSet;

// Millimetres to micrometres (inputs are range-checked before they get here).
use dollop_sim::um;

/// Limits on what the import makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountLimits {
    /// Print segments (after merging).
    pub max_segments: u64,
    /// All commands.
    pub max_commands: u64,
}

/// Counts over the job body (the priming bead excluded).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyStats {
    /// Print commands.
    pub print_segments: u64,
    /// Travel and layer commands.
    pub travels: u64,
    /// Continuous beads.
    pub beads: u64,
    /// Distinct heights printed at, in the order met (a return to a lower Z counts again).
    pub layers: u64,
    /// Material changes along the printed path.
    pub switches: u64,
    /// Printed length, mm.
    pub print_mm: f64,
    /// Travelled length, mm.
    pub travel_mm: f64,
}

/// Builds the job body.
#[derive(Debug)]
pub struct Emitter {
    cmds: Vec<Command>,
    /// What each command's moves asked (zero for all but prints), beside `cmds`.
    asked: Vec<Asked>,
    /// Heights printed at, um: a print's layer is as thick as the gap to the one below.
    zs: BTreeSet<i32>,
    /// Where the head stands, um; None before the first command.
    at: Option<[i32; 3]>,
    in_bead: bool,
    last_material: Option<u8>,
    first_material: Option<u8>,
    last_print_z: Option<i32>,
    lo: [i32; 2],
    hi: [i32; 2],
    first_print_z: i32,
    limits: CountLimits,
    /// Counts.
    pub stats: BodyStats,
}

impl Emitter {
    /// An empty body under `limits`.
    pub fn new(limits: CountLimits) -> Self {
        Emitter {
            cmds: Vec::new(),
            asked: Vec::new(),
            zs: BTreeSet::new(),
            at: None,
            in_bead: false,
            last_material: None,
            first_material: None,
            last_print_z: None,
            lo: [i32::MAX; 2],
            hi: [i32::MIN; 2],
            first_print_z: 0,
            limits,
            stats: BodyStats::default(),
        }
    }

    fn push(&mut self, c: Command, line: usize) -> Result<(), GcodeInError> {
        if self.cmds.len() as u64 >= self.limits.max_commands {
            return Err(GcodeInError::TooMany {
                line,
                what: "job commands",
                limit: self.limits.max_commands,
                flag: "--max-segments",
            });
        }
        self.cmds.push(c);
        self.asked.push(Asked::default());
        Ok(())
    }

    /// A move with the valves closed to `to` (mm).
    pub fn travel(&mut self, to: [f64; 3], line: usize) -> Result<(), GcodeInError> {
        let t = [um(to[0]), um(to[1]), um(to[2])];
        self.in_bead = false;
        let cmd = match self.at {
            Some(a) if a == t => return Ok(()),
            Some(a) if a[0] == t[0] && a[1] == t[1] => Command::Layer { z: t[2] },
            _ => Command::Travel {
                x: t[0],
                y: t[1],
                z: t[2],
            },
        };
        if let Some(a) = self.at {
            self.stats.travel_mm += dist(a, t);
        }
        self.stats.travels += 1;
        self.at = Some(t);
        self.push(cmd, line)
    }

    /// A bead segment from `from` (mm, XYZ) to `to` (mm, XY) in `material`, asking bead
    /// section `section` (mm^2, from its E).
    pub fn print(
        &mut self,
        from: [f64; 3],
        to: [f64; 2],
        material: u8,
        section: f64,
        line: usize,
    ) -> Result<(), GcodeInError> {
        let f = [um(from[0]), um(from[1]), um(from[2])];
        if self.at != Some(f) {
            self.travel(from, line)?;
        }
        let t = [um(to[0]), um(to[1])];
        let (dx, dy) = (t[0] - f[0], t[1] - f[1]);
        if dx == 0 && dy == 0 {
            return Ok(());
        }
        if !self.in_bead {
            self.stats.beads += 1;
            self.in_bead = true;
        }
        if self.last_print_z != Some(f[2]) {
            self.stats.layers += 1;
            if self.last_print_z.is_none() {
                self.first_print_z = f[2];
            }
            self.last_print_z = Some(f[2]);
        }
        if self.last_material.is_some_and(|m| m != material) {
            self.stats.switches += 1;
        }
        self.last_material = Some(material);
        self.first_material.get_or_insert(material);
        for p in [f, [t[0], t[1], f[2]]] {
            for (a, v) in p.iter().take(2).enumerate() {
                self.lo[a] = self.lo[a].min(*v);
                self.hi[a] = self.hi[a].max(*v);
            }
        }
        let len = (dx as f64).hypot(dy as f64) * 1e-3;
        self.stats.print_mm += len;
        self.at = Some([t[0], t[1], f[2]]);
        self.zs.insert(f[2]);
        let below = self.zs.range(..f[2]).next_back().copied().unwrap_or(0);
        let h = (f[2] - below) as f64 * 1e-3;
        // A collinear move of another width stays a command of its own, so that it may
        // be laid at its own section (`sections::RUN_TOL`).
        let same_width = self.asked.last().is_some_and(|a| {
            a.len <= 0.0
                || (section - a.s_len / a.len).abs() <= 0.5 * super::sections::RUN_TOL * section
        });
        if same_width && dollop::command::extend_last_print(&mut self.cmds, dx, dy, material) {
            if let Some(a) = self.asked.last_mut() {
                a.add(len, section, h);
            }
            return Ok(());
        }
        if self.stats.print_segments >= self.limits.max_segments {
            return Err(GcodeInError::TooMany {
                line,
                what: "print segments",
                limit: self.limits.max_segments,
                flag: "--max-segments",
            });
        }
        self.stats.print_segments += 1;
        self.push(Command::Print { dx, dy, material }, line)?;
        if let Some(a) = self.asked.last_mut() {
            a.add(len, section, h);
        }
        Ok(())
    }

    /// A wait with the valves closed.
    pub fn dwell(&mut self, ms: f64, line: usize) -> Result<(), GcodeInError> {
        self.in_bead = false;
        let mut left = ms.max(0.0).round() as u64;
        while left > 0 {
            let chunk = left.min(dollop::command::MAX_DWELL_MS as u64);
            self.push(Command::Dwell { ms: chunk as u32 }, line)?;
            left -= chunk;
        }
        Ok(())
    }

    /// The printed extent (XY, um) and the first print's height, or None if nothing printed.
    pub fn extent(&self) -> Option<([i32; 2], [i32; 2], i32)> {
        self.first_material?;
        Some((self.lo, self.hi, self.first_print_z))
    }

    /// The first print's material.
    pub fn first_material(&self) -> Option<u8> {
        self.first_material
    }

    /// The body, ended, with its beads' sections (`sections::place`, for a config of
    /// section `config_mm2`); `prime` (start and end, um, at one height) goes in front,
    /// at the config's section.
    pub fn finish(
        mut self,
        prime: Option<([i32; 3], i32)>,
        config_mm2: f64,
        unit: super::sections::EUnit,
    ) -> Result<
        (
            Vec<Command>,
            [i32; 3],
            BodyStats,
            super::sections::SectionStats,
        ),
        GcodeInError,
    > {
        let material = self.first_material.unwrap_or(0);
        let body = std::mem::take(&mut self.cmds);
        let (body, sections) = super::sections::place(body, &self.asked, config_mm2, unit);
        if body.len() as u64 + 3 > self.limits.max_commands {
            return Err(GcodeInError::TooMany {
                line: 0,
                what: "job commands (with the bead sections)",
                limit: self.limits.max_commands,
                flag: "--max-segments",
            });
        }
        self.cmds = body;
        let mut cmds = Vec::with_capacity(self.cmds.len() + 3);
        let start = match prime {
            Some((s, x_end)) => {
                cmds.push(Command::Travel {
                    x: s[0],
                    y: s[1],
                    z: s[2],
                });
                cmds.push(Command::Print {
                    dx: x_end - s[0],
                    dy: 0,
                    material,
                });
                s
            }
            None => match self.cmds.first() {
                Some(Command::Travel { x, y, z }) => [*x, *y, *z],
                _ => self.at.unwrap_or([0; 3]),
            },
        };
        cmds.append(&mut self.cmds);
        cmds.push(Command::End);
        Ok((cmds, start, self.stats, sections))
    }
}

fn dist(a: [i32; 3], b: [i32; 3]) -> f64 {
    (0..3)
        .map(|i| ((b[i] - a[i]) as f64).powi(2))
        .sum::<f64>()
        .sqrt()
        * 1e-3
}
