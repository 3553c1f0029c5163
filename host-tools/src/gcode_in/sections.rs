//! Bead sections from the G-code's E: each extrusion move asks `S = E x filament area /
//! length` (E as volume after `M200 D<d>` or with `--volumetric`). Each bead of the job (a
//! run of print commands) is cut into runs of moves whose sections lie within
//! [`RUN_TOL`] of each other (a bead of one width is one run), each laid at its moves'
//! length-weighted mean, written as `Command::Section` before the run where it differs
//! from the section in force by more than [`SECTION_STEP`]: between beads, or inside one
//! (job format 2's per-segment sections; the executor changes the head's speed there at
//! constant flow over a short staircase). How far the moves ask from the section they are
//! laid at (and from their bead's mean, what one section a bead gave) is counted for the
//! summary. Sections under the config's (whose speeds the config was checked at) or over
//! `MAX_SECTION_RATIO` times it are laid at that limit, and counted. It stops at the
//! commands: reading E is the modal machine's.

use dollop::command::{section_limits, MAX_SECTION_RATIO};
use dollop::Command;
use std::fmt;

/// Relative change of section below which no `Section` is written: far inside the 2 %
/// the section is held to, and above E's rounding in slicer output (5 decimals of
/// filament, 0.1 % of a 0.05 mm move's volume).
pub const SECTION_STEP: f64 = 0.005;

/// Most a run's moves' sections may span, relative (largest over smallest, less one):
/// every move of a run is then laid within 1 % of its own section (the run's mean lies
/// between them), half the 2 % the section is held to, the other half left to laying it
/// (the plant measured within 0.1 % on a straight bead away from changes). A wider
/// tolerance would leave Arachne's tapers fewer, longer stairs at up to its own distance;
/// a narrower one would cut beads at E's rounding (0.1 %) and XY's (under 0.7 % over
/// [`SPREAD_MM`]).
pub const RUN_TOL: f64 = 0.01;

/// Shortest move whose section counts towards a bead's spread, mm: slicers round X and Y
/// to 1 um, which makes a 20 um move's section up to 5 % off what was meant (measured on
/// PrusaSlicer's cube shell + ball: every move off its bead's section by more than 2 % was
/// shorter than 0.05 mm); at 0.2 mm the rounding is under 0.7 %.
pub const SPREAD_MM: f64 = 0.2;

/// What one print command's moves asked, summed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Asked {
    /// Path length, mm.
    pub len: f64,
    /// Sum of section x length, mm^3.
    pub s_len: f64,
    /// Smallest and largest section of its moves of at least [`SPREAD_MM`], mm^2 (0
    /// while none).
    pub min: f64,
    /// Largest.
    pub max: f64,
    /// Sum of layer thickness x length, mm^2 (for the widths).
    pub h_len: f64,
}

impl Asked {
    /// Adds a move of `len` mm asking section `s` (mm^2) at layer thickness `h` (mm).
    /// Only moves of at least [`SPREAD_MM`] count towards the spread (`min`, `max`).
    pub fn add(&mut self, len: f64, s: f64, h: f64) {
        if len >= SPREAD_MM {
            if self.max <= 0.0 {
                self.min = s;
                self.max = s;
            }
            self.min = self.min.min(s);
            self.max = self.max.max(s);
        }
        self.len += len;
        self.s_len += s * len;
        self.h_len += h * len;
    }
    fn merge(&mut self, o: &Asked) {
        self.len += o.len;
        self.s_len += o.s_len;
        self.h_len += o.h_len;
        if o.max > 0.0 {
            if self.max > 0.0 {
                self.min = self.min.min(o.min);
                self.max = self.max.max(o.max);
            } else {
                (self.min, self.max) = (o.min, o.max);
            }
        }
    }
}

/// How E was read, for the summary.
#[derive(Clone, Debug, PartialEq)]
pub enum EUnit {
    /// E is filament length; the diameter and where it came from.
    Filament {
        /// mm.
        diameter_mm: f64,
        /// "PrusaSlicer's filament_diameter", "--filament-mm", "default".
        from: &'static str,
    },
    /// E is volume, mm^3 (`M200 D<d>` or `--volumetric`).
    Volume,
}

/// The sections the import wrote and how well the beads keep them.
#[derive(Clone, Debug, PartialEq)]
pub struct SectionStats {
    /// How E was read (the last mode in force).
    pub unit: EUnit,
    /// The config's section, mm^2 (the job's start, and its smallest).
    pub config_mm2: f64,
    /// Smallest and largest bead section asked (length-weighted mean per bead), mm^2.
    pub asked_mm2: (f64, f64),
    /// Their widths as a rounded bead (Slic3r's flow model: `(w - h) h + pi h^2 / 4`) and
    /// as a rectangle (`w h`, Cura's), mm: (rounded lo, hi), (rectangle lo, hi).
    pub widths_mm: ((f64, f64), (f64, f64)),
    /// `Section` commands written.
    pub commands: u64,
    /// Beads whose moves ask sections more than `SECTION_STEP` apart.
    pub mixed_beads: u64,
    /// Their length, mm.
    pub mixed_mm: f64,
    /// `Section` commands written inside beads (between two of a bead's print commands).
    pub in_bead: u64,
    /// Largest relative distance of a move's section from the section it is laid at, its
    /// run's (moves of at least [`SPREAD_MM`]).
    pub worst_dev: f64,
    /// Largest relative distance of a move's section from its bead's length-weighted mean:
    /// what laying each bead at one section would have left (moves of at least
    /// [`SPREAD_MM`]).
    pub worst_bead_dev: f64,
    /// Bead length asked under the config's section, laid at it, mm.
    pub below_mm: f64,
    /// Bead length asked over `MAX_SECTION_RATIO` times the config's, laid at that, mm.
    pub above_mm: f64,
    /// All bead length with E, mm.
    pub total_mm: f64,
}

impl fmt::Display for SectionStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = match &self.unit {
            EUnit::Filament { diameter_mm, from } => {
                format!("E as {diameter_mm} mm filament, {from}")
            }
            EUnit::Volume => "E as volume".to_string(),
        };
        if self.total_mm == 0.0 {
            return writeln!(f, "bead sections: none asked ({unit})");
        }
        let ((r0, r1), (q0, q1)) = self.widths_mm;
        writeln!(
            f,
            "bead sections from E ({unit}): {:.3} .. {:.3} mm^2 per bead, widths {r0:.2} .. {r1:.2} mm as a rounded bead ({q0:.2} .. {q1:.2} mm as a rectangle); {} Section command(s) where a bead's section changes by over {} %",
            self.asked_mm2.0,
            self.asked_mm2.1,
            self.commands,
            SECTION_STEP * 100.0
        )?;
        writeln!(
            f,
            "  {} bead(s) ({:.0} mm) mix sections, laid in runs within {} % with {} Section command(s) inside beads: a move (of 0.2 mm or more) at most {:.1} % from the section it is laid at ({:.1} % from its bead's mean)",
            self.mixed_beads,
            self.mixed_mm,
            RUN_TOL * 100.0,
            self.in_bead,
            self.worst_dev * 100.0,
            self.worst_bead_dev * 100.0
        )?;
        if self.below_mm > 0.0 || self.above_mm > 0.0 {
            writeln!(
                f,
                "  {:.0} mm of bead ({:.1} %) asks less than the config's {:.3} mm^2 and is laid at it, {:.0} mm more than {MAX_SECTION_RATIO} times it; set bead_area_mm2 to {:.3} to lay every bead as sliced",
                self.below_mm,
                100.0 * self.below_mm / self.total_mm,
                self.config_mm2,
                self.above_mm,
                self.asked_mm2.0
            )?;
        }
        Ok(())
    }
}

/// Widths of section `s` at layer thickness `h`: rounded bead, rectangle.
fn widths(s: f64, h: f64) -> (f64, f64) {
    if h <= 0.0 {
        return (f64::NAN, f64::NAN);
    }
    let round = (s - std::f64::consts::PI * h * h / 4.0) / h + h;
    (round, s / h)
}

/// Writes `Section`s before the beads of `cmds` (`asked[i]`: what command `i`'s moves
/// asked) for a config of section `config_mm2`; the job starts at the config's section.
pub fn place(
    cmds: Vec<Command>,
    asked: &[Asked],
    config_mm2: f64,
    unit: EUnit,
) -> (Vec<Command>, SectionStats) {
    let (lo_um2, hi_um2) = section_limits(config_mm2);
    let mut st = SectionStats {
        unit,
        config_mm2,
        asked_mm2: (f64::INFINITY, f64::NEG_INFINITY),
        widths_mm: (
            (f64::INFINITY, f64::NEG_INFINITY),
            (f64::INFINITY, f64::NEG_INFINITY),
        ),
        commands: 0,
        mixed_beads: 0,
        mixed_mm: 0.0,
        in_bead: 0,
        worst_dev: 0.0,
        worst_bead_dev: 0.0,
        below_mm: 0.0,
        above_mm: 0.0,
        total_mm: 0.0,
    };
    let mut out = Vec::with_capacity(cmds.len() + cmds.len() / 8);
    let mut now_um2 = lo_um2;
    let mut i = 0;
    while i < cmds.len() {
        if !matches!(cmds[i], Command::Print { .. }) {
            out.push(cmds[i]);
            i += 1;
            continue;
        }
        let end = (i..cmds.len())
            .find(|&k| !matches!(cmds[k], Command::Print { .. }))
            .unwrap_or(cmds.len());
        let mut bead = Asked::default();
        for a in asked.iter().take(end).skip(i) {
            bead.merge(a);
        }
        if bead.len > 0.0 {
            let mean = bead.s_len / bead.len;
            st.total_mm += bead.len;
            if bead.max > 0.0 {
                let dev = ((bead.max - mean) / mean).max((mean - bead.min) / mean);
                st.worst_bead_dev = st.worst_bead_dev.max(dev);
                if bead.max - bead.min > SECTION_STEP * mean {
                    st.mixed_beads += 1;
                    st.mixed_mm += bead.len;
                }
            }
        }
        let cut = match asked.get(i..end) {
            Some(a) => runs(a),
            None => vec![(0, end - i)],
        };
        for (k, (from, to)) in cut.into_iter().enumerate() {
            let mut run = Asked::default();
            for a in asked.get(i + from..i + to).unwrap_or(&[]) {
                run.merge(a);
            }
            if run.len > 0.0 {
                if let Some(um2) = lay_run(&run, (lo_um2, hi_um2), &mut st) {
                    if (um2 as f64 - now_um2 as f64).abs() > SECTION_STEP * now_um2 as f64 {
                        out.push(Command::Section { um2 });
                        st.commands += 1;
                        st.in_bead += (k > 0) as u64;
                        now_um2 = um2;
                    }
                }
            }
            out.extend_from_slice(&cmds[i + from..i + to]);
        }
        i = end;
    }
    (out, st)
}

/// Counts run `run` into `st` and returns the section it is laid at (um^2, within
/// `limits`), or None if it asks none.
fn lay_run(run: &Asked, limits: (u32, u32), st: &mut SectionStats) -> Option<u32> {
    if run.len <= 0.0 {
        return None;
    }
    let mean = run.s_len / run.len;
    let h = run.h_len / run.len;
    st.asked_mm2 = (st.asked_mm2.0.min(mean), st.asked_mm2.1.max(mean));
    let (r, q) = widths(mean, h);
    let w = &mut st.widths_mm;
    w.0 = (w.0 .0.min(r), w.0 .1.max(r));
    w.1 = (w.1 .0.min(q), w.1 .1.max(q));
    if run.max > 0.0 {
        let dev = ((run.max - mean) / mean).max((mean - run.min) / mean);
        st.worst_dev = st.worst_dev.max(dev);
    }
    let um2 = (mean * 1e6).round().clamp(0.0, u32::MAX as f64) as u32;
    if um2 < limits.0 {
        st.below_mm += run.len;
    } else if um2 > limits.1 {
        st.above_mm += run.len;
    }
    Some(um2.clamp(limits.0, limits.1))
}

/// Cuts one bead's print commands (`asked`: what each asked) into runs, as (first, end)
/// index ranges covering them in order: a run goes on while its moves' sections span at
/// most [`RUN_TOL`]. A command of at least [`SPREAD_MM`] is judged alone (its long moves'
/// sections and their mean), shorter ones in groups of at least that (a group's section,
/// its length-weighted mean, has XY's rounding within 0.7 %; a short move's alone may be
/// 5 % off), and those under that together (before a long command, at the bead's end)
/// as a group as well.
fn runs(asked: &[Asked]) -> Vec<(usize, usize)> {
    let mut cut = Cutter::default();
    // Short commands gathered into a group: its first, and what they asked.
    let mut group = (0usize, Asked::default());
    for (k, a) in asked.iter().enumerate() {
        if a.len >= SPREAD_MM {
            // A long command is a group of its own, after the short ones before it (under
            // `SPREAD_MM` together: judged as a group too, so that they cannot pull a
            // run's mean off its long moves; their own rounding may cut a short run).
            let (first, g) = std::mem::take(&mut group);
            cut.group(first, &g);
            cut.group(k, a);
            continue;
        }
        if group.1.len == 0.0 {
            group.0 = k;
        }
        group.1.merge(a);
        if group.1.len >= SPREAD_MM {
            let (first, g) = std::mem::take(&mut group);
            cut.group(first, &g);
        }
    }
    let (first, g) = std::mem::take(&mut group);
    cut.group(first, &g);
    cut.out.push((cut.run.map_or(0, |r| r.0), asked.len()));
    cut.out
}

/// `runs`' state: the runs closed, and the open one (first command, its groups' smallest
/// and largest section: each group's mean and its long moves').
#[derive(Default)]
struct Cutter {
    out: Vec<(usize, usize)>,
    run: Option<(usize, f64, f64)>,
}

impl Cutter {
    /// A group of at least `SPREAD_MM` starting at command `first`: it joins the open run
    /// if the run's sections still span at most `RUN_TOL` with it, else starts one.
    fn group(&mut self, first: usize, g: &Asked) {
        if g.len <= 0.0 {
            return;
        }
        let s = g.s_len / g.len;
        let (glo, ghi) = if g.max > 0.0 {
            (g.min.min(s), g.max.max(s))
        } else {
            (s, s)
        };
        self.run = match self.run {
            None => Some((0, glo, ghi)),
            Some((start, lo, hi)) => {
                let (nlo, nhi) = (lo.min(glo), hi.max(ghi));
                if nhi <= nlo * (1.0 + RUN_TOL) {
                    Some((start, nlo, nhi))
                } else {
                    self.out.push((start, first));
                    Some((first, glo, ghi))
                }
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn print(dx: i32) -> Command {
        Command::Print {
            dx,
            dy: 0,
            material: 0,
        }
    }
    fn travel() -> Command {
        Command::Travel { x: 0, y: 0, z: 600 }
    }
    fn asked(len: f64, s: f64) -> Asked {
        let mut a = Asked::default();
        a.add(len, s, 0.6);
        a
    }

    #[test]
    fn a_section_goes_before_each_bead_and_each_run_of_another_width_in_one() {
        // Bead 1 at the config's 0.40, bead 2 at 0.46 (a 0.9 mm perimeter), bead 3 mixing
        // 0.40 and 0.46 over equal lengths, bead 4 under the config's.
        let cmds = vec![
            travel(),
            print(1000),
            travel(),
            print(1000),
            print(1000),
            travel(),
            print(1000),
            print(1000),
            travel(),
            print(1000),
            Command::End,
        ];
        let a = [
            Asked::default(),
            asked(1.0, 0.40),
            Asked::default(),
            asked(1.0, 0.4627),
            asked(1.0, 0.4627),
            Asked::default(),
            asked(1.0, 0.40),
            asked(1.0, 0.46),
            Asked::default(),
            asked(1.0, 0.30),
            Asked::default(),
        ];
        let (out, st) = place(cmds, &a, 0.40, EUnit::Volume);
        let secs: Vec<_> = out
            .iter()
            .enumerate()
            .filter_map(|(i, c)| match c {
                Command::Section { um2 } => Some((i, *um2)),
                _ => None,
            })
            .collect();
        // Bead 3 in two runs: its second at 0.46, between its two print commands.
        assert_eq!(
            secs,
            [(3, 462_700), (7, 400_000), (9, 460_000), (12, 400_000)]
        );
        assert!(
            matches!(out[8], Command::Print { .. }) && matches!(out[10], Command::Print { .. })
        );
        for i in [3, 7, 12] {
            assert!(matches!(out[i - 1], Command::Travel { .. }));
        }
        assert_eq!((st.commands, st.in_bead, st.mixed_beads), (4, 1, 1));
        // Every move at its own section; one section a bead would have left 7 %.
        assert_eq!(st.worst_dev, 0.0);
        assert!(
            (st.worst_bead_dev - 0.03 / 0.43).abs() < 1e-9,
            "{}",
            st.worst_bead_dev
        );
        assert_eq!(st.below_mm, 1.0);
        assert_eq!(st.asked_mm2, (0.30, 0.4627));
        let ((r0, r1), (q0, q1)) = st.widths_mm;
        // Slic3r's 0.9 mm bead at 0.6 mm layers is 0.4627 mm^2.
        assert!((r1 - 0.9).abs() < 1e-3, "{r1}");
        assert!((q1 - 0.4627 / 0.6).abs() < 1e-9 && q0 < r0);
        assert!(
            st.to_string().contains("set bead_area_mm2 to 0.300"),
            "{st}"
        );
    }

    /// A taper (each 0.3 mm move 0.3 % wider than the one before, 0.40 to 0.48 mm^2) is
    /// cut into runs whose moves lie within `RUN_TOL` of each other, every move within
    /// it of its run's mean; short moves (0.05 mm, whose own sections are noisy) go in
    /// groups of at least `SPREAD_MM`; a bead of one width is one run.
    #[test]
    fn a_taper_is_cut_into_runs_within_the_tolerance() {
        let moves: Vec<Asked> = (0..62)
            .map(|k| asked(0.3, 0.40 * 1.003f64.powi(k)))
            .collect();
        let cut = runs(&moves);
        assert!(cut.len() > 10, "{cut:?}");
        assert_eq!((cut[0].0, cut.last().unwrap().1), (0, moves.len()));
        for w in cut.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
        for &(a, b) in &cut {
            let mut run = Asked::default();
            for m in &moves[a..b] {
                run.merge(m);
            }
            let mean = run.s_len / run.len;
            assert!(run.max <= run.min * (1.0 + RUN_TOL) + 1e-12);
            assert!((run.max / mean - 1.0).max(1.0 - run.min / mean) <= RUN_TOL);
        }
        // Short moves alternating 2 % either side of 0.40 (XY's rounding): one run.
        let noisy: Vec<Asked> = (0..40)
            .map(|k| asked(0.05, if k % 2 == 0 { 0.408 } else { 0.392 }))
            .collect();
        assert_eq!(runs(&noisy), [(0, 40)]);
        assert_eq!(runs(&[asked(1.0, 0.40), asked(2.0, 0.40)]), [(0, 2)]);
    }
}
