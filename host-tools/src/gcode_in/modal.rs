//! The modal machine: reads lexed lines in order and keeps G-code's state (position with
//! `G92` offsets, absolute/relative axes and E, millimetres/inches, E as filament or as
//! volume, the current tool's inlet, the purge region), turning moves into prints (with
//! the section their E asks), travels, layers and dwells for the [`Emitter`]. What each command means is decided here; everything it does not use is
//! counted by name for the summary. It stops at the commands: priming and the job
//! header are `mod.rs`'s.

use super::arcs;
use super::emit::{CountLimits, Emitter};
use super::error::GcodeInError;
use super::lexer::{lex, Code, Words};
use super::purge::{region, Region};
use super::sections::EUnit;
use super::tools::{pin_number, ToolMap};
use std::collections::BTreeMap;

/// Largest coordinate magnitude accepted before the travel check, mm: beyond any
/// printer, and far inside what integer micrometres hold.
pub const MAX_COORD_MM: f64 = 100_000.0;
/// Largest E magnitude accepted (absolute E grows over a print; a day of paste is far less).
pub const MAX_E: f64 = 1e9;
/// E change below which a move does not extrude (slicers write E to 5 decimals).
const E_EPS: f64 = 1e-7;

/// How to read the file.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Tool (valve) number to inlet.
    pub tools: ToolMap,
    /// Largest distance between an arc and its segments, mm.
    pub chord_mm: f64,
    /// Drop purge blocks instead of refusing them.
    pub strip_purge: bool,
    /// Machine travel, mm (X, Y, Z).
    pub min_mm: [f64; 3],
    /// Machine travel, mm.
    pub max_mm: [f64; 3],
    /// Limits on the job made.
    pub limits: CountLimits,
    /// Filament diameter, mm (`--filament-mm`): before the slicer's own setting.
    pub filament_mm: Option<f64>,
    /// E is volume, mm^3, from the start (`--volumetric`), as after `M200 D<d>`.
    pub volumetric: bool,
}

/// Filament diameter assumed where neither the command line nor the file gives one, mm.
pub const DEFAULT_FILAMENT_MM: f64 = 1.75;

/// The filament diameters a slicer wrote in its settings block, by tool (PrusaSlicer,
/// SuperSlicer and OrcaSlicer: `; filament_diameter = 1.75,1.75`, at the file's end).
pub fn slicer_filament(text: &str) -> Option<Vec<f64>> {
    let line = text.lines().rev().find(|l| {
        l.trim_start_matches([';', ' '])
            .starts_with("filament_diameter =")
    })?;
    let (_, v) = line.split_once('=')?;
    let d: Vec<f64> = v
        .split([',', ';'])
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()?;
    (!d.is_empty() && d.iter().all(|x| x.is_finite() && *x > 0.0 && *x < 100.0)).then_some(d)
}

/// What was dropped with `--strip-purge`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PurgeStats {
    /// Purge blocks met.
    pub blocks: u64,
    /// Their extrusion path, mm.
    pub print_mm: f64,
}

/// Counts for the summary.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Counts {
    /// Lines read.
    pub lines: u64,
    /// G0/G1 moves.
    pub moves: u64,
    /// G2/G3 arcs and the segments they became.
    pub arcs: u64,
    /// Segments the arcs became.
    pub arc_segments: u64,
    /// Tool changes and valve commands that selected a material.
    pub tool_changes: u64,
    /// Moves with E but no XY (retract/unretract).
    pub e_only: u64,
    /// G4 dwells.
    pub dwells: u64,
    /// Commands skipped, by name.
    pub skipped: BTreeMap<String, u64>,
    /// Purge blocks dropped.
    pub purge: PurgeStats,
}

/// The modal state.
pub struct Modal {
    set: Settings,
    /// Head position, machine mm.
    pos: [f64; 3],
    /// Whether each axis's position is known (a move or G92 set it).
    known: [bool; 3],
    /// Logical = machine - offset (G92).
    offset: [f64; 3],
    e: f64,
    abs_xyz: bool,
    abs_e: bool,
    unit: f64,
    inlet: u8,
    /// The tool (valve) selected, for its filament diameter.
    tool: u32,
    /// E is volume (`M200 D<d>`, `--volumetric`), else filament length.
    e_volume: bool,
    /// Filament diameters by tool, mm, and where they came from.
    filament: (Vec<f64>, &'static str),
    purge: Option<(Region, String, usize)>,
    /// The output.
    pub out: Emitter,
    /// The counts.
    pub counts: Counts,
}

impl Modal {
    /// A machine in G-code's power-on state (absolute, mm, tool 0).
    pub fn new(set: Settings) -> Result<Self, GcodeInError> {
        let inlet = set.tools.inlet(0, 0)?;
        let filament = match set.filament_mm {
            Some(d) => (vec![d], "--filament-mm"),
            None => (vec![DEFAULT_FILAMENT_MM], "assumed, --filament-mm to set"),
        };
        let e_volume = set.volumetric;
        Ok(Modal {
            out: Emitter::new(set.limits),
            set,
            pos: [0.0; 3],
            // Z starts at 0 (a file that never sets it prints on the plate); X and Y are
            // unknown until a move or G92 gives them.
            known: [false, false, true],
            offset: [0.0; 3],
            e: 0.0,
            abs_xyz: true,
            abs_e: true,
            unit: 1.0,
            inlet,
            tool: 0,
            e_volume,
            filament,
            purge: None,
            counts: Counts::default(),
        })
    }

    /// Reads a whole text, line by line.
    pub fn run(&mut self, text: &str) -> Result<(), GcodeInError> {
        if self.set.filament_mm.is_none() {
            if let Some(d) = slicer_filament(text) {
                self.filament = (d, "the slicer's filament_diameter");
            }
        }
        for (i, l) in text.lines().enumerate() {
            self.line(l, i + 1)?;
        }
        Ok(())
    }

    fn skip(&mut self, name: String) {
        *self.counts.skipped.entry(name).or_insert(0) += 1;
    }

    /// Reads one line (`n`: its 1-based number).
    pub fn line(&mut self, text: &str, n: usize) -> Result<(), GcodeInError> {
        self.counts.lines += 1;
        let l = lex(text, n)?;
        if let Some(c) = l.comment {
            if let Some((r, kind)) = region(c) {
                self.enter(r, kind, n)?;
            }
        }
        let Some(code) = l.code else { return Ok(()) };
        let w = Words::new(l.rest, n);
        match code {
            Code::G(0 | 1, None) => self.linear(&w, n),
            Code::G(g @ (2 | 3), None) => self.arc(&w, g == 2, n),
            Code::G(4, None) => {
                let ms = match (w.get('P')?, w.get('S')?) {
                    (Some(p), _) => p,
                    (None, Some(s)) => s * 1000.0,
                    _ => 0.0,
                };
                if ms > 0.0 {
                    self.counts.dwells += 1;
                    self.out.dwell(ms.min(1e9), n)?;
                }
                Ok(())
            }
            Code::G(20, None) => {
                self.unit = 25.4;
                Ok(())
            }
            Code::G(21, None) => {
                self.unit = 1.0;
                Ok(())
            }
            Code::G(90, None) => {
                self.abs_xyz = true;
                self.abs_e = true;
                Ok(())
            }
            Code::G(91, None) => {
                self.abs_xyz = false;
                self.abs_e = false;
                Ok(())
            }
            Code::G(92, None) => self.set_position(&w, n),
            Code::M(82, None) => {
                self.abs_e = true;
                Ok(())
            }
            Code::M(83, None) => {
                self.abs_e = false;
                Ok(())
            }
            Code::M(200, None) if w.has('D') => {
                // Marlin's and RepRapFirmware's volumetric extrusion: on with a diameter,
                // off with D0.
                self.e_volume = w.get('D')?.unwrap_or(0.0) > 0.0;
                Ok(())
            }
            Code::T(t) => {
                self.inlet = self.set.tools.inlet(t, n)?;
                self.tool = t;
                self.counts.tool_changes += 1;
                Ok(())
            }
            Code::M(42, None) => match (w.get('P')?, w.get('S')?) {
                (Some(p), Some(s)) => self.valve(p, s > 0.0, n),
                _ => {
                    self.skip("M42".into());
                    Ok(())
                }
            },
            Code::M(106, None) if w.has('P') => {
                let p = w.get('P')?.unwrap_or(0.0);
                let s = w.get('S')?.unwrap_or(255.0);
                self.valve(p, s > 0.0, n)
            }
            Code::M(107, None) if w.has('P') => {
                // Closing a valve: the extrusion words already say where paste stops.
                w.get('P')?;
                Ok(())
            }
            Code::Ext(name) if name.eq_ignore_ascii_case("SET_PIN") => {
                let pin = w.param("PIN").and_then(pin_number);
                let value = w.param("VALUE").and_then(|v| v.parse::<f64>().ok());
                match (pin, value) {
                    (Some(p), Some(v)) => self.valve(p as f64, v > 0.0, n),
                    _ => {
                        self.skip("SET_PIN".into());
                        Ok(())
                    }
                }
            }
            Code::G(g, sub) => {
                self.skip(name('G', g, sub));
                Ok(())
            }
            Code::M(m, sub) => {
                self.skip(name('M', m, sub));
                Ok(())
            }
            Code::Ext(s) | Code::Other(s) => {
                let s: String = s.chars().take(24).collect();
                self.skip(s.to_ascii_uppercase());
                Ok(())
            }
        }
    }

    fn enter(&mut self, r: Region, kind: &str, n: usize) -> Result<(), GcodeInError> {
        match r {
            Region::Part => self.purge = None,
            Region::Purge { what, setting } => {
                if !self.set.strip_purge {
                    return Err(GcodeInError::Purge {
                        line: n,
                        kind: kind.chars().take(40).collect(),
                        what,
                        setting,
                    });
                }
                if self.purge.is_none() {
                    self.counts.purge.blocks += 1;
                }
                self.purge = Some((r, kind.to_string(), n));
            }
        }
        Ok(())
    }

    /// A valve command: opening valve `p` selects its tool's inlet.
    fn valve(&mut self, p: f64, open: bool, n: usize) -> Result<(), GcodeInError> {
        if open {
            if !(0.0..=1e6).contains(&p) || p.fract() != 0.0 {
                return Err(GcodeInError::BadNumber {
                    line: n,
                    letter: 'P',
                    word: p.to_string(),
                });
            }
            self.inlet = self.set.tools.inlet(p as u32, n)?;
            self.tool = p as u32;
            self.counts.tool_changes += 1;
        }
        Ok(())
    }

    /// A coordinate word as machine mm, range-checked.
    /// A coordinate word's value in mm (G20/G21), refused beyond [`MAX_COORD_MM`].
    fn in_mm(&self, v: f64, letter: char, n: usize) -> Result<f64, GcodeInError> {
        let v = v * self.unit;
        if v.abs() > MAX_COORD_MM {
            return Err(GcodeInError::OutOfRange {
                line: n,
                axis: letter,
                value: v,
                limit: MAX_COORD_MM,
            });
        }
        Ok(v)
    }

    fn coord(&self, w: &Words, axis: usize, n: usize) -> Result<Option<f64>, GcodeInError> {
        let letter = ['X', 'Y', 'Z'][axis];
        let Some(v) = w.get(letter)? else {
            return Ok(None);
        };
        let v = self.in_mm(v, letter, n)?;
        Ok(Some(if self.abs_xyz {
            v + self.offset[axis]
        } else {
            self.pos[axis] + v
        }))
    }

    /// The move's target (machine mm) and E change.
    fn target(&mut self, w: &Words, n: usize) -> Result<([f64; 3], f64, [bool; 3]), GcodeInError> {
        let mut to = self.pos;
        let mut given = [false; 3];
        for (a, t) in to.iter_mut().enumerate() {
            if let Some(v) = self.coord(w, a, n)? {
                *t = v;
                given[a] = true;
            }
        }
        let mut de = 0.0;
        if let Some(e) = w.get('E')? {
            let e = e * self.unit;
            if e.abs() > MAX_E {
                return Err(GcodeInError::OutOfRange {
                    line: n,
                    axis: 'E',
                    value: e,
                    limit: MAX_E,
                });
            }
            if self.abs_e {
                de = e - self.e;
                self.e = e;
            } else {
                de = e;
                self.e += e;
            }
            if self.e.abs() > MAX_E {
                return Err(GcodeInError::OutOfRange {
                    line: n,
                    axis: 'E',
                    value: self.e,
                    limit: MAX_E,
                });
            }
        }
        Ok((to, de, given))
    }

    fn check_travel(&self, to: [f64; 3], given: [bool; 3], n: usize) -> Result<(), GcodeInError> {
        for a in 0..3 {
            if given[a] {
                let (min, max) = (self.set.min_mm[a], self.set.max_mm[a]);
                if !(to[a] >= min - 1e-9 && to[a] <= max + 1e-9) {
                    return Err(GcodeInError::OutsideTravel {
                        line: n,
                        axis: ['X', 'Y', 'Z'][a],
                        value: to[a],
                        min,
                        max,
                    });
                }
            }
        }
        Ok(())
    }

    fn linear(&mut self, w: &Words, n: usize) -> Result<(), GcodeInError> {
        self.counts.moves += 1;
        // RepRapFirmware's `G1 .. P<bitmap>`: the ports switch with this move.
        if let Some(p) = w.get('P')? {
            if p >= 1.0 && p < 2f64.powi(31) && p.fract() == 0.0 {
                self.valve((p as u32).trailing_zeros() as f64, true, n)?;
            }
        }
        let (to, de, given) = self.target(w, n)?;
        self.check_travel(to, given, n)?;
        self.step(to, de, given, n)
    }

    /// One straight piece from the current position to `to` with `de` of E.
    fn step(
        &mut self,
        to: [f64; 3],
        de: f64,
        given: [bool; 3],
        n: usize,
    ) -> Result<(), GcodeInError> {
        let from = self.pos;
        let moved_xy = given[0] || given[1];
        let xy = (to[0] - from[0]).hypot(to[1] - from[1]);
        let dz = to[2] - from[2];
        let start_known = self.known[0] && self.known[1] && self.known[2];
        for (k, g) in self.known.iter_mut().zip(given) {
            *k |= g;
        }
        self.pos = to;
        if de > E_EPS && moved_xy && xy > 0.0 && start_known {
            if dz.abs() > 1e-6 {
                return Err(GcodeInError::ExtrudingZ { line: n });
            }
            if self.purge.is_some() {
                self.counts.purge.print_mm += xy;
                return Ok(());
            }
            let section = de * self.e_area() / xy;
            return self.out.print(from, [to[0], to[1]], self.inlet, section, n);
        }
        if !moved_xy && !given[2] {
            if de.abs() > E_EPS {
                self.counts.e_only += 1;
            }
            return Ok(());
        }
        if self.known[0] && self.known[1] && self.known[2] && self.purge.is_none() {
            self.out.travel(to, n)?;
        }
        Ok(())
    }

    /// Paste per unit of E, mm^3: 1 for E as volume, else the tool's filament section.
    fn e_area(&self) -> f64 {
        if self.e_volume {
            return 1.0;
        }
        let d = &self.filament.0;
        let d = d.get(self.tool as usize).or(d.last()).copied();
        let d = d.unwrap_or(DEFAULT_FILAMENT_MM);
        std::f64::consts::PI * d * d / 4.0
    }

    /// How E is read now, for the summary.
    pub fn e_unit(&self) -> EUnit {
        if self.e_volume {
            return EUnit::Volume;
        }
        let d = &self.filament.0;
        EUnit::Filament {
            diameter_mm: d
                .get(self.tool as usize)
                .or(d.last())
                .copied()
                .unwrap_or(DEFAULT_FILAMENT_MM),
            from: self.filament.1,
        }
    }

    fn arc(&mut self, w: &Words, clockwise: bool, n: usize) -> Result<(), GcodeInError> {
        self.counts.arcs += 1;
        let from = self.pos;
        let (to, de, given) = self.target(w, n)?;
        self.check_travel(to, given, n)?;
        let bad = |reason: String| GcodeInError::BadArc { line: n, reason };
        let center = match (w.get('I')?, w.get('J')?, w.get('R')?) {
            (None, None, Some(r)) => arcs::center_from_radius(
                [from[0], from[1]],
                [to[0], to[1]],
                r * self.unit,
                clockwise,
            )
            .map_err(bad)?,
            (None, None, None) => return Err(bad("arc with neither I/J nor R".into())),
            (i, j, _) => {
                let (i, j) = (i.unwrap_or(0.0) * self.unit, j.unwrap_or(0.0) * self.unit);
                if i.abs() > MAX_COORD_MM || j.abs() > MAX_COORD_MM {
                    return Err(bad(format!("arc centre offset ({i}, {j}) mm out of range")));
                }
                [from[0] + i, from[1] + j]
            }
        };
        if !(self.known[0] && self.known[1]) {
            return Err(bad("arc before any move set the position".into()));
        }
        let pts = arcs::points(
            [from[0], from[1]],
            [to[0], to[1]],
            center,
            clockwise,
            self.set.chord_mm,
        )
        .map_err(bad)?;
        self.counts.arc_segments += pts.len() as u64;
        let k = pts.len() as f64;
        for (i, p) in pts.iter().enumerate() {
            let f = (i + 1) as f64 / k;
            let z = from[2] + (to[2] - from[2]) * f;
            let p = [p[0], p[1], z];
            self.check_travel(p, [true; 3], n)?;
            self.step(p, de / k, [true, true, given[2]], n)?;
        }
        Ok(())
    }

    fn set_position(&mut self, w: &Words, n: usize) -> Result<(), GcodeInError> {
        let any = ['X', 'Y', 'Z', 'E'].iter().any(|&c| w.has(c));
        for (a, letter) in ['X', 'Y', 'Z'].into_iter().enumerate() {
            let v = if any { w.get(letter)? } else { Some(0.0) };
            if let Some(v) = v {
                let v = self.in_mm(v, letter, n)?;
                self.offset[a] = self.pos[a] - v;
                self.known[a] = true;
            }
        }
        let e = if any { w.get('E')? } else { Some(0.0) };
        if let Some(e) = e {
            if e.abs() > MAX_E {
                return Err(GcodeInError::OutOfRange {
                    line: n,
                    axis: 'E',
                    value: e,
                    limit: MAX_E,
                });
            }
            self.e = e * self.unit;
        }
        Ok(())
    }
}

fn name(letter: char, n: u32, sub: Option<u32>) -> String {
    match sub {
        Some(s) => format!("{letter}{n}.{s}"),
        None => format!("{letter}{n}"),
    }
}
