//! A time-based simulation of G-code on the core's flow model, to judge G-code the way a
//! feed-rate controller would print it: the head follows the `G1` moves at their feed
//! rates (no acceleration), `M42` commands the valves of `dollop::flow_model::FlowModel`,
//! which is stepped once per control cycle. Measures where material boundaries land along
//! the print path against the design and the bead cross-section. Not a model of the
//! firmware (that is the `dollop-sim` crate's), only of the G-code.

use dollop::flow_model::FlowModel;
use dollop::Machine;

/// One G-code operation the simulation understands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    /// Straight move at a feed rate, mm and mm/s.
    Move {
        /// Target, mm.
        to: [f64; 3],
        /// Speed, mm/s.
        v: f64,
    },
    /// Valve (M42 port) on or off.
    Valve {
        /// Port = inlet.
        port: u8,
        /// Open.
        on: bool,
    },
    /// Dwell, s.
    Dwell(f64),
}

/// A G-code word (`X12.5`): its letter, upper-cased, and its number.
pub(super) fn word(w: &str) -> Option<(char, f64)> {
    let c = w.chars().next()?;
    w[c.len_utf8()..]
        .parse::<f64>()
        .ok()
        .map(|v| (c.to_ascii_uppercase(), v))
}

/// A move's word: X, Y or Z sets that coordinate of `to`, F (mm/min, above zero) the
/// feed rate `f` (mm/s). False for any other word, left to the caller.
pub(super) fn move_word(c: char, v: f64, to: &mut [f64; 3], f: &mut f64) -> bool {
    match c {
        'X' => to[0] = v,
        'Y' => to[1] = v,
        'Z' => to[2] = v,
        'F' if v > 0.0 => *f = v / 60.0,
        _ => return false,
    }
    true
}

/// Each G-code line's command word (upper case) and the words after it; comments (from
/// `;`) and blank lines are skipped. Both judges read their G-code through it.
pub(super) fn statements(
    text: &str,
) -> impl Iterator<Item = (String, std::str::SplitWhitespace<'_>)> {
    text.lines().filter_map(|line| {
        let mut words = line.split(';').next().unwrap_or("").split_whitespace();
        words.next().map(|cmd| (cmd.to_ascii_uppercase(), words))
    })
}

/// Parses the subset of RepRapFirmware G-code that `gcode::export` writes. Unknown lines
/// and words are skipped.
pub fn parse(text: &str) -> Vec<Op> {
    let mut ops = Vec::new();
    let mut pos = [0.0f64; 3];
    let mut f = 1.0f64;
    for (cmd, words) in statements(text) {
        match cmd.as_str() {
            "G0" | "G1" => {
                let mut to = pos;
                for (c, v) in words.filter_map(word) {
                    move_word(c, v, &mut to, &mut f);
                }
                ops.push(Op::Move { to, v: f });
                pos = to;
            }
            "M42" => {
                let (mut p, mut s) = (None, None);
                for w in words {
                    match word(w) {
                        // Only ports that are inlets of a 32-bit valve mask count.
                        Some(('P', v)) if (0.0..32.0).contains(&v) => p = Some(v as u8),
                        Some(('S', v)) => s = Some(v > 0.0),
                        _ => {}
                    }
                }
                if let (Some(port), Some(on)) = (p, s) {
                    ops.push(Op::Valve { port, on });
                }
            }
            "G4" => {
                let mut t = 0.0;
                for w in words {
                    match word(w) {
                        Some(('P', v)) => t += v * 1e-3,
                        Some(('S', v)) => t += v,
                        _ => {}
                    }
                }
                ops.push(Op::Dwell(t));
            }
            _ => {}
        }
    }
    ops
}

/// What a simulated G-code print measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Figures {
    /// Design boundaries.
    pub boundaries: usize,
    /// Material changes that landed.
    pub landed: usize,
    /// Largest |landed - design| along the path, mm (each design boundary against the
    /// nearest landed change to the same material).
    pub worst_boundary_mm: f64,
    /// Mean |landed - design|, mm.
    pub mean_boundary_mm: f64,
    /// Smallest and largest cross-section / S over windows of `WINDOW_MM` of bead.
    pub section_range: (f64, f64),
    /// Largest |cross-section / S - 1|.
    pub worst_section: f64,
    /// Simulated print time, s.
    pub time_s: f64,
}

/// Bead length over which one cross-section value is taken, mm.
pub const WINDOW_MM: f64 = 0.05;

/// Runs `gcode` on `machine`'s flow model with the channel primed with `initial`, and
/// compares landed boundaries with `design` ((s, material) along the print path, as
/// `gcode::design_boundaries` gives). Stops after `max_time_s` of simulated time.
pub fn simulate(
    gcode: &str,
    machine: &Machine<f64, 4>,
    initial: u8,
    design: &[(f64, u8)],
    max_time_s: f64,
) -> Figures {
    let ops = parse(gcode);
    let mut model: FlowModel<f64, 4> = FlowModel::new(machine, initial);
    let dt = machine.dt();
    let mut head = Head {
        ops: &ops,
        oi: 0,
        pos: [f64::NAN; 3],
        mask: 0,
        dwell_left: 0.0,
        s_print: 0.0,
    };
    let mut landing = model.channel().landing();
    let mut landed: Vec<(f64, u8)> = Vec::new();
    let mut section = Section {
        area: machine.bead_area,
        window: (0.0, 0.0),
        range: (f64::INFINITY, f64::NEG_INFINITY),
    };
    let mut t = 0.0;
    loop {
        head.valves_ahead(&mut model);
        if head.oi >= ops.len() && model.q() <= 0.0 && t > 0.0 || t > max_time_s {
            break;
        }
        let flow = match model.step() {
            Ok(f) => f,
            Err(_) => break,
        };
        let dv: f64 = flow.dv.mm3();
        let s_before = head.s_print;
        let mixed = head.cycle(dt, &mut model);
        t += dt;
        let now = model.channel().landing();
        if now != landing {
            landed.push((0.5 * (s_before + head.s_print), now));
            landing = now;
        }
        section.cycle(dv, head.s_print - s_before, mixed);
    }
    let (worst, sum) = boundary_errors(design, &landed);
    let range = section.range;
    Figures {
        boundaries: design.len(),
        landed: landed.len(),
        worst_boundary_mm: worst,
        mean_boundary_mm: if design.is_empty() {
            0.0
        } else {
            sum / design.len() as f64
        },
        section_range: range,
        worst_section: (1.0 - range.0).max(range.1 - 1.0),
        time_s: t,
    }
}

/// The head following the G-code's operations, and the valves as they command them.
struct Head<'a> {
    ops: &'a [Op],
    /// The next operation.
    oi: usize,
    /// Where the head is, mm (NaN until the first move puts it somewhere).
    pos: [f64; 3],
    /// The valves commanded.
    mask: u32,
    /// What is left of the dwell under way, s.
    dwell_left: f64,
    /// Path length moved with a valve open, mm.
    s_print: f64,
}

impl Head<'_> {
    /// Valve commands act from the start of the next cycle, like the firmware's: those
    /// next in line go to `model` before it steps.
    fn valves_ahead(&mut self, model: &mut FlowModel<f64, 4>) {
        let mut changed = false;
        while let Some(Op::Valve { port, on }) = self.ops.get(self.oi) {
            if *on {
                self.mask |= 1 << port;
            } else {
                self.mask &= !(1 << port);
            }
            changed = true;
            self.oi += 1;
        }
        if changed {
            model.command(self.mask);
        }
    }

    /// Moves for one cycle of `dt`, through as many operations as it takes. True when the
    /// cycle mixed printing with standing (a dwell, a valve change, a bead's start or end).
    fn cycle(&mut self, dt: f64, model: &mut FlowModel<f64, 4>) -> bool {
        let mut budget = dt;
        let mut mixed = false;
        let printing_at_start = self.mask != 0;
        while budget > 0.0 && self.oi < self.ops.len() {
            match self.ops[self.oi] {
                Op::Move { to, v } => {
                    let pos = &mut self.pos;
                    if pos[0].is_nan() {
                        *pos = to;
                        self.oi += 1;
                        continue;
                    }
                    let d = ((to[0] - pos[0]).powi(2)
                        + (to[1] - pos[1]).powi(2)
                        + (to[2] - pos[2]).powi(2))
                    .sqrt();
                    let need = d / v.max(1e-6);
                    let printing = self.mask != 0;
                    if printing != printing_at_start {
                        mixed = true;
                    }
                    if need <= budget {
                        budget -= need;
                        *pos = to;
                        if printing {
                            self.s_print += d;
                        }
                        self.oi += 1;
                    } else {
                        let f = budget * v / d;
                        for a in 0..3 {
                            pos[a] += (to[a] - pos[a]) * f;
                        }
                        if printing {
                            self.s_print += budget * v;
                        }
                        budget = 0.0;
                    }
                }
                Op::Dwell(s) => {
                    if self.dwell_left <= 0.0 {
                        self.dwell_left = s;
                    }
                    let used = self.dwell_left.min(budget);
                    self.dwell_left -= used;
                    budget -= used;
                    mixed = true;
                    if self.dwell_left <= 1e-12 {
                        self.dwell_left = 0.0;
                        self.oi += 1;
                    }
                }
                Op::Valve { port, on } => {
                    // Takes effect next cycle; the head keeps moving.
                    if on {
                        self.mask |= 1 << port;
                    } else {
                        self.mask &= !(1 << port);
                    }
                    model.command(self.mask);
                    mixed = true;
                    self.oi += 1;
                }
            }
        }
        mixed
    }
}

/// The bead's cross-section over windows of `WINDOW_MM`, against the section `area`.
struct Section {
    area: f64,
    /// Volume and length in the window so far, mm^3 and mm.
    window: (f64, f64),
    /// Smallest and largest cross-section / S over the windows.
    range: (f64, f64),
}

impl Section {
    /// Takes a cycle that landed `dv` over `ds` of print path; `mixed`, see `Head::cycle`.
    fn cycle(&mut self, dv: f64, ds: f64, mixed: bool) {
        // Cross-section over whole cycles on a bead only: a cycle that starts or ends a
        // bead mixes printing and standing and says nothing about the bead.
        if ds > 0.0 && !mixed {
            self.window.0 += dv;
            self.window.1 += ds;
            if self.window.1 >= WINDOW_MM {
                let r = self.window.0 / (self.area * self.window.1);
                self.range = (self.range.0.min(r), self.range.1.max(r));
                self.window = (0.0, 0.0);
            }
        } else {
            self.window = (0.0, 0.0);
        }
    }
}

/// Each design boundary against the nearest landed change to the same material: the
/// largest distance and the sum of them, mm.
fn boundary_errors(design: &[(f64, u8)], landed: &[(f64, u8)]) -> (f64, f64) {
    let mut by_material: Vec<Vec<f64>> = vec![Vec::new(); 256];
    for &(s, m) in landed {
        by_material[m as usize].push(s);
    }
    for v in by_material.iter_mut() {
        v.sort_by(f64::total_cmp);
    }
    let mut worst = 0.0f64;
    let mut sum = 0.0;
    for &(s, m) in design {
        let v = &by_material[m as usize];
        let k = v.partition_point(|&x| x < s);
        let near = [k.checked_sub(1), Some(k)]
            .into_iter()
            .flatten()
            .filter_map(|i| v.get(i))
            .map(|x| (x - s).abs())
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(near);
        sum += near;
    }
    (worst, sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsing_reads_moves_valves_and_dwells_and_survives_garbage() {
        let ops = parse("G21\nG1 X1 Y2 F600 ; go\nM42 P1 S1\nG4 P250\nG1 X3\n");
        assert_eq!(
            ops,
            vec![
                Op::Move {
                    to: [1.0, 2.0, 0.0],
                    v: 10.0
                },
                Op::Valve { port: 1, on: true },
                Op::Dwell(0.25),
                Op::Move {
                    to: [3.0, 2.0, 0.0],
                    v: 10.0
                },
            ]
        );
        // Multibyte words, huge ports, missing values: skipped, never a panic.
        let ops = parse("G1 Ä5 X\u{e9}\nM42 P200 S1\nM42 P\nG4 Pxyz\n\u{1F600}\n");
        assert!(ops.iter().all(|o| !matches!(o, Op::Valve { .. })));
    }
}
