//! Print-quality metrics from a simulated run: where each material boundary landed along
//! the executed path versus where the design has it, the bead cross-section cycle by
//! cycle, and volume deposited off the path. Fed cycle by cycle by the runner; knows
//! nothing of how the run was produced.

use dollop::command::{walk, MoveKind};
use dollop::Command;

/// The design's beads: for each polyline, its command range and material runs.
#[derive(Clone, Debug)]
pub struct DesignBead {
    /// Index of the first and last command of the bead.
    pub commands: (u32, u32),
    /// Material runs: (design point where the run starts, material). The first run starts
    /// at the bead's start.
    pub runs: Vec<([f64; 2], u8)>,
}

/// Splits a job into beads.
pub fn design_beads(commands: &[Command], start_um: [i32; 3]) -> Vec<DesignBead> {
    let mut beads = Vec::new();
    let mut cur: Option<DesignBead> = None;
    // The walk yields no dwell or end; a gap in the command indices is one, and ends a
    // bead as a travel or a layer change does.
    let mut next_index = 0;
    for m in walk(commands, start_um) {
        // A `Section` between two prints is no gap: it changes the bead's section there.
        let contiguous = m.index == next_index
            || commands.get(next_index..m.index).is_some_and(|between| {
                between.iter().all(|c| matches!(c, Command::Section { .. }))
            });
        next_index = m.index + 1;
        if !contiguous {
            beads.extend(cur.take());
        }
        let MoveKind::Print { material } = m.kind else {
            beads.extend(cur.take());
            continue;
        };
        if m.from == m.to {
            continue;
        }
        let i = m.index as u32;
        let here = [m.from[0] as f64 * 1e-3, m.from[1] as f64 * 1e-3];
        match cur.as_mut() {
            Some(b) => {
                b.commands.1 = i;
                if b.runs.last().map(|r| r.1) != Some(material) {
                    b.runs.push((here, material));
                }
            }
            None => {
                cur = Some(DesignBead {
                    commands: (i, i),
                    runs: vec![(here, material)],
                })
            }
        }
    }
    beads.extend(cur.take());
    beads
}

/// One boundary's placement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundary {
    /// Bead index.
    pub bead: usize,
    /// Design point of the boundary, mm.
    pub point: [f64; 2],
    /// Material after it.
    pub material: u8,
    /// Executed-path arc length where the design has it, mm.
    pub s_design: f64,
    /// Executed-path arc length where it landed, mm.
    pub s_landed: f64,
}

impl Boundary {
    /// Landed minus design, along the path, mm.
    pub fn error(&self) -> f64 {
        self.s_landed - self.s_design
    }
}

/// Everything measured.
#[derive(Clone, Debug, Default)]
pub struct Metrics {
    /// Boundaries matched between design and plate.
    pub boundaries: Vec<Boundary>,
    /// Beads whose landed material sequence differs from the design's (description).
    pub mismatches: Vec<String>,
    /// Smallest and largest cross-section / S over `SECTION_WINDOW_MM` windows of bead,
    /// S each move's own (its `Command::Section`, else the config's; a window over two
    /// moves against their length-weighted mean), away from the section's changes inside
    /// a bead (see `section_steps`).
    pub section_range: (f64, f64),
    /// Smallest and largest of the beads' own sections, mm^2 (NaN with no bead).
    pub bead_sections: (f64, f64),
    /// Windows measured.
    pub section_cycles: u64,
    /// Where the worst cross-section occurred (x, y), mm.
    pub section_worst_at: [f64; 2],
    /// Smallest and largest cross-section / S over every `SECTION_LONG_MM` of bead (a
    /// window sliding by `SECTION_WINDOW_MM`): what a speed ramp through a flow step
    /// costs the bead.
    pub section_long_range: (f64, f64),
    /// Where the worst long-window cross-section occurred (x, y), mm.
    pub section_long_worst_at: [f64; 2],
    /// As `section_long_range`, over the long windows away from turns only (the head's
    /// heading within `STRAIGHT_DEG` over the window): the issue's measure, "away from
    /// bead ends and turns". (1, 1) with none.
    pub section_straight_range: (f64, f64),
    /// Where the worst of those occurred (x, y), mm.
    pub section_straight_worst_at: [f64; 2],
    /// The control cycle (from the run's start) whose window is that worst.
    pub section_straight_worst_cycle: u64,
    /// Every cross-section / S over `SECTION_WINDOW_MM` windows, in bead order: for
    /// `section_band`, the issue's own measure (a percentile range, not the worst).
    pub section_samples: Vec<f64>,
    /// Every cross-section / S over `SECTION_LONG_MM`, as `section_samples`.
    pub section_long_samples: Vec<f64>,
    /// Those of `section_long_samples` away from turns (`section_straight_range`'s).
    pub section_straight_samples: Vec<f64>,
    /// Those of `section_samples` away from turns: each short window at the middle of a
    /// long one whose heading turns under `STRAIGHT_DEG` (`heading_cos`), so a fillet's arc
    /// and about 0.1 mm either side of it are left out.
    pub section_short_straight_samples: Vec<f64>,
    /// Changes of section between two print segments of one bead met (job format 2's
    /// mid-bead `Command::Section`, issue 26): the head's speed changes there at constant
    /// flow over its own ramp, and the long windows that come within `Meter::step_reach`
    /// of one are left out of the ranges above and kept here instead.
    pub section_steps: u64,
    /// Every long window within reach of a change of section, and beyond it in beads that
    /// change section: (distance from the window to the nearest change, mm, cross-section /
    /// S), for how far the change's ramp reaches.
    pub section_step_samples: Vec<(f64, f64)>,
    /// Volume landed while the head was not on a bead, mm^3.
    pub off_path_volume: f64,
    /// Landed material runs shorter than the sliver length, merged away.
    pub slivers: u64,
    /// Per bead (in order): bead-equivalent length of paste that landed at its start
    /// before the design's first material did, mm (0 when it started right). A bead that
    /// starts in another material than the last one ended in is where a G-code firmware
    /// lands the channel's old content; slivers are not merged away here.
    pub bead_starts: Vec<(usize, f64)>,
}

impl Metrics {
    /// Largest |landed - design| over all boundaries, mm (0 with none).
    pub fn worst_boundary(&self) -> f64 {
        self.boundaries
            .iter()
            .map(|b| b.error().abs())
            .fold(0.0, f64::max)
    }
    /// Largest |cross-section / S - 1|.
    pub fn worst_section(&self) -> f64 {
        (1.0 - self.section_range.0).max(self.section_range.1 - 1.0)
    }
    /// Largest |cross-section / S - 1| over `SECTION_LONG_MM` windows.
    pub fn worst_section_long(&self) -> f64 {
        (1.0 - self.section_long_range.0).max(self.section_long_range.1 - 1.0)
    }
    /// Largest |cross-section / S - 1| over `SECTION_LONG_MM` windows away from turns.
    pub fn worst_section_straight(&self) -> f64 {
        (1.0 - self.section_straight_range.0).max(self.section_straight_range.1 - 1.0)
    }
    /// The bead width band as issue 22 measures it: p99 - p1 of the cross-section / S
    /// (width / pitch at the layer height) over the 0.02 mm windows (`long`: 0.2 mm)
    /// away from bead ends; returns (p1, p99). (1, 1) with no windows.
    pub fn section_band(&self, long: bool) -> (f64, f64) {
        let v = if long {
            &self.section_long_samples
        } else {
            &self.section_samples
        };
        band(v)
    }

    /// As `section_band`, over the windows away from turns only (a long window whose
    /// heading stays within `STRAIGHT_DEG`; a short one at the middle of such a long
    /// one): the "away from bead ends and turns". The band over every window
    /// counts the row ends' U-turns too, where the head's slowing for the fillet meets
    /// the flow's change.
    pub fn section_band_straight(&self, long: bool) -> (f64, f64) {
        band(if long {
            &self.section_straight_samples
        } else {
            &self.section_short_straight_samples
        })
    }
}

/// The p1 and p99 of `v` (nearest rank; 1 for an empty `v`), sorted once.
fn band(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (1.0, 1.0);
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
    (at(0.01), at(0.99))
}

/// Path length over which one cross-section value is taken, mm. Per-cycle steps are
/// 1e-4 mm long, where the f32 head position's rounding (2e-6 mm at 20 mm) would be a 2 %
/// error; over 0.02 mm it is 1e-4, while a bulge or neck that a nozzle of 0.1 mm or more
/// lays down is still resolved.
pub const SECTION_WINDOW_MM: f64 = 0.02;

/// Most a long window's short windows' headings may turn from its chord and the window
/// still count as away from turns, degrees: a 0.2 mm window inside a 0.4 mm fillet (the
/// tightest row-end turn at 0.8 mm pitch) turns 29 degrees, one along a straight bead
/// only by the plant's step jitter.
pub const STRAIGHT_DEG: f64 = 10.0;

/// One short window of the long one in progress.
#[derive(Clone, Copy, Debug)]
struct Short {
    /// Volume landed, mm^3; path length, mm; where it ends (x, y), mm; length x each
    /// move's own section, mm^3.
    vol: f64,
    ds: f64,
    at: [f64; 2],
    sds: f64,
    /// Whether it is one of `section_samples` (not within a change of section's reach).
    counted: bool,
}

/// How straight the long window made of `recent`'s short windows runs: the least cosine
/// of a short window's chord against the whole one's (1 with none; minus infinity for a
/// window with no length, which is no straight). Straight at `STRAIGHT_DEG`
/// (`straight_at`); the short window at its middle counts as away from turns at half of
/// it, so that its heading turns by less than `STRAIGHT_DEG` over the 0.2 mm around it
/// (at the whole of it a window with 0.1 mm of a 0.4 mm fillet at one end passed, its
/// middle on the fillet).
fn heading_cos(recent: &std::collections::VecDeque<Short>) -> f64 {
    let (Some(first), Some(last)) = (recent.front(), recent.back()) else {
        return 1.0;
    };
    let chord = [last.at[0] - first.at[0], last.at[1] - first.at[1]];
    let n = chord[0].hypot(chord[1]);
    if n <= 0.0 {
        return f64::NEG_INFINITY;
    }
    recent
        .iter()
        .zip(recent.iter().skip(1))
        .filter_map(|(a, b)| {
            let d = [b.at[0] - a.at[0], b.at[1] - a.at[1]];
            let l = d[0].hypot(d[1]);
            (l > 0.0).then(|| (d[0] * chord[0] + d[1] * chord[1]) / (l * n))
        })
        .fold(1.0, f64::min)
}

/// Whether a `heading_cos` of `cos` runs within `deg` degrees.
fn straight_at(cos: f64, deg: f64) -> bool {
    cos >= deg.to_radians().cos()
}

/// Path length of the long cross-section window, mm (the issue's "every 0.2 mm of
/// bead"; `dollop::config::SECTION_WINDOW_MM`).
pub const SECTION_LONG_MM: f64 = dollop::config::SECTION_WINDOW_MM;

/// Runs of landed material shorter than this (mm of bead) are counted as slivers and
/// merged into their neighbours rather than treated as features.
pub const SLIVER_MM: f64 = 0.005;

/// Longest stretch of path between two stored samples of a bead's trajectory, mm. A
/// sample every cycle (0.1 to 2 um apart) would hold a long bead's every point: a 16 m
/// bead took 400 MB. Straight stretches lose nothing by fewer; where the path turns a
/// sample is kept whenever it does by more than `SAMPLE_TURN` (a chord of a 0.1 mm
/// fillet then strays 0.1 um from the arc).
pub const SAMPLE_MM: f64 = 0.05;
/// Largest turn between stored samples, rad.
pub const SAMPLE_TURN: f64 = 0.02;

/// Collects one bead's trajectory and landed runs while it prints.
#[derive(Clone, Debug, Default)]
struct BeadTrace {
    samples: Vec<[f64; 3]>,
    landed: Vec<(f64, u8)>,
    s: f64,
    /// Landed volume, path length and path length x each move's own section (mm^3) of
    /// the cross-section window in progress.
    window: (f64, f64, f64),
    /// The executed path's length less the design's at the start of the command the head
    /// is on (fillets cut corners), mm: where the design's changes of section lie on it.
    drift: f64,
    /// The command the head is on.
    command: Option<u32>,
    /// Bead-equivalent length of what landed while settling at the end, mm.
    extra: f64,
}

/// Accumulates metrics cycle by cycle.
#[derive(Clone, Debug)]
pub struct Meter {
    beads: Vec<DesignBead>,
    of_command: Vec<Option<usize>>,
    /// Each design bead's own section at its start (its `Command::Section`, else the
    /// config's), mm^2.
    bead_s: Vec<f64>,
    /// The section in force at each command, mm^2: each move is measured against its own.
    cmd_s: Vec<f64>,
    /// Each command's design path length from its bead's start, mm.
    cmd_at: Vec<f64>,
    /// Each design bead's changes of section: design path length from its start, and
    /// the sections before and after, mm^2.
    bead_steps: Vec<Steps>,
    /// How far a change of section's ramp reaches either side of it (`step_reach`).
    reach: StepReach,
    current: Option<(usize, BeadTrace)>,
    last_pos: [f64; 2],
    /// The current bead's latest short windows, at least `SECTION_LONG_MM` of them once
    /// the bead is that long.
    recent: std::collections::VecDeque<Short>,
    /// Cycles metered so far.
    cycles: u64,
    metrics: Metrics,
}

/// How far the head's change of speed at a change of section mid-bead reaches along the
/// bead: the executor's staircase (`dollop::section_taper`) after it, and the speed
/// ramps' window (if the machine has one) either side.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepReach {
    /// The flow's top, mm^3/s (`v_flow_max` through the config's section).
    pub q_max: f64,
    /// The staircase's mean acceleration at that flow, mm/s^2.
    pub accel: f64,
    /// Half the speed ramps' window at the flow's top speed, mm (0 without ramps).
    pub ring_mm: f64,
}

impl StepReach {
    /// The reach after a change from section `a` to `b` (mm^2), mm: the staircase's whole
    /// volume at the narrower section, and the ramps' half window.
    pub fn behind(&self, a: f64, b: f64) -> f64 {
        let taper = if self.accel > 0.0 {
            self.q_max * self.q_max * (1.0 / b - 1.0 / a).abs() / self.accel / a.min(b)
        } else {
            0.0
        };
        taper + self.ring_mm
    }
}

/// A bead's changes of section between two of its print segments: (design path length
/// from its start, mm, section before, after, mm^2).
type Steps = Vec<(f64, f64, f64)>;

/// Each command's design path length from its bead's start (mm), and each bead's changes
/// of section (`Steps`).
fn section_steps(
    commands: &[Command],
    beads: &[DesignBead],
    sections: &[f64],
) -> (Vec<f64>, Vec<Steps>) {
    let mut at = vec![0.0; commands.len()];
    let steps = beads
        .iter()
        .map(|b| {
            let mut steps = Vec::new();
            let (mut len, mut last) = (0.0, None::<f64>);
            for i in b.commands.0 as usize..=b.commands.1 as usize {
                at[i] = len;
                if let Command::Print { dx, dy, .. } = commands[i] {
                    let s = sections[i];
                    if last.is_some_and(|l| l != s) {
                        steps.push((len, last.unwrap_or(s), s));
                    }
                    last = Some(s);
                    len += (dx as f64).hypot(dy as f64) * 1e-3;
                }
            }
            steps
        })
        .collect();
    (at, steps)
}

/// One cycle's input to the meter.
#[derive(Clone, Copy, Debug)]
pub struct CycleIn<'a> {
    /// Bead the head is on (printing or settling at its end), if any.
    pub bead_command: Option<u32>,
    /// True while laying the bead (not settling at its end).
    pub printing: bool,
    /// Head position at the end of the cycle, mm.
    pub pos: [f64; 2],
    /// Volume landed during the cycle, mm^3.
    pub landed_volume: f64,
    /// Material landing at the start of the cycle.
    pub landing_before: u8,
    /// Changes during the cycle: (volume landed before the change, new material).
    pub changes: &'a [(f64, u8)],
}

impl BeadTrace {
    /// Records the head at `pos` (path length `self.s`), keeping only the samples that
    /// carry shape: the last stored one is moved forward while the path runs straight on
    /// from the one before it and stays within `SAMPLE_MM`.
    fn sample(&mut self, pos: [f64; 2]) {
        let here = [pos[0], pos[1], self.s];
        let n = self.samples.len();
        if n >= 2 {
            let (a, b) = (self.samples[n - 2], self.samples[n - 1]);
            let (u, v) = ([b[0] - a[0], b[1] - a[1]], [pos[0] - b[0], pos[1] - b[1]]);
            let turn = (u[0] * v[1] - u[1] * v[0])
                .atan2(u[0] * v[0] + u[1] * v[1])
                .abs();
            if self.s - a[2] <= SAMPLE_MM && turn <= SAMPLE_TURN {
                self.samples[n - 1] = here;
                return;
            }
        }
        self.samples.push(here);
    }
}

impl Meter {
    /// A meter for a job's commands, whose beads have section `bead_area` (mm^2) until a
    /// `Command::Section` gives them their own.
    pub fn new(commands: &[Command], start_um: [i32; 3], bead_area: f64) -> Self {
        let beads = design_beads(commands, start_um);
        let mut of_command = vec![None; commands.len()];
        for (i, b) in beads.iter().enumerate() {
            for c in b.commands.0..=b.commands.1 {
                of_command[c as usize] = Some(i);
            }
        }
        let sections = sections_of(commands, bead_area);
        let bead_s = beads
            .iter()
            .map(|b| {
                sections
                    .get(b.commands.0 as usize)
                    .copied()
                    .unwrap_or(bead_area)
            })
            .collect();
        let (cmd_at, bead_steps) = section_steps(commands, &beads, &sections);
        Meter {
            beads,
            of_command,
            bead_s,
            cmd_s: sections,
            cmd_at,
            bead_steps,
            reach: StepReach::default(),
            current: None,
            last_pos: [f64::NAN; 2],
            recent: Default::default(),
            cycles: 0,
            metrics: Metrics {
                section_range: (f64::INFINITY, f64::NEG_INFINITY),
                section_long_range: (f64::INFINITY, f64::NEG_INFINITY),
                section_straight_range: (f64::INFINITY, f64::NEG_INFINITY),
                ..Default::default()
            },
        }
    }

    /// Feeds one cycle.
    pub fn cycle(&mut self, c: CycleIn<'_>) {
        self.cycles += 1;
        let bead = c
            .bead_command
            .and_then(|i| self.of_command.get(i as usize).copied().flatten());
        if self.current.as_ref().map(|x| x.0) != bead {
            self.finish_bead();
            if let Some(b) = bead {
                let mut t = BeadTrace::default();
                t.samples.push([c.pos[0], c.pos[1], 0.0]);
                self.current = Some((b, t));
                self.last_pos = c.pos;
            }
        }
        // The section this cycle's move asks, and where its command starts on the design.
        let here = c.bead_command.map(|i| i as usize);
        let s_here = here.and_then(|i| self.cmd_s.get(i)).copied();
        let at_here = here.and_then(|i| self.cmd_at.get(i)).copied();
        let Some((bi, trace)) = self.current.as_mut() else {
            self.metrics.off_path_volume += c.landed_volume;
            self.last_pos = c.pos;
            return;
        };
        if trace.command != c.bead_command {
            trace.command = c.bead_command;
            if let Some(a) = at_here {
                trace.drift = trace.s - a;
            }
        }
        let ds =
            ((c.pos[0] - self.last_pos[0]).powi(2) + (c.pos[1] - self.last_pos[1]).powi(2)).sqrt();
        let s0 = trace.s + trace.extra;
        trace.s += ds;
        if ds > 0.0 {
            trace.sample(c.pos);
        }
        // Paste that lands while the head stands at the bead's end extends the bead's
        // material sequence as if the bead went on: a wrong material there counts by its
        // volume, not as nothing.
        let ds_runs = if c.printing {
            ds
        } else {
            let e = c.landed_volume / self.bead_s[*bi];
            trace.extra += e;
            e
        };
        if c.landed_volume > 0.0 {
            if trace.landed.is_empty() {
                trace.landed.push((s0, c.landing_before));
            }
            for &(v, m) in c.changes {
                let f = (v / c.landed_volume).clamp(0.0, 1.0);
                trace.landed.push((s0 + f * ds_runs, m));
            }
            if c.printing {
                trace.window.0 += c.landed_volume;
                trace.window.1 += ds;
                trace.window.2 += ds * s_here.unwrap_or(self.bead_s[*bi]);
            }
        }
        if let Some((_, trace)) = self.current.as_mut() {
            if trace.window.1 >= SECTION_WINDOW_MM {
                let w = std::mem::take(&mut trace.window);
                self.section(w, c.pos);
            }
        }
        self.last_pos = c.pos;
    }

    fn section(&mut self, (vol, ds, sds): (f64, f64, f64), at: [f64; 2]) {
        let ratio = vol / sds;
        // How near the short window and the long one ending here come to a change of
        // section (infinite in a bead without one).
        let ((_, near_short), (raw_long, near_long)) =
            (self.step_near(ds), self.step_near(SECTION_LONG_MM));
        let counted = near_short > 0.0 && near_long > 0.0;
        self.recent.push_back(Short {
            vol,
            ds,
            at,
            sds,
            counted,
        });
        while self.recent.len() > 1
            && self.recent.iter().skip(1).map(|w| w.ds).sum::<f64>() >= SECTION_LONG_MM
        {
            self.recent.pop_front();
        }
        let (v, l, sl) = self.recent.iter().fold((0.0, 0.0, 0.0), |a, w| {
            (a.0 + w.vol, a.1 + w.ds, a.2 + w.sds)
        });
        if raw_long.is_finite() && l >= SECTION_LONG_MM {
            self.metrics.section_step_samples.push((raw_long, v / sl));
        }
        if !counted {
            // Within a change's reach: kept in `section_step_samples` only.
            return;
        }
        let (lo, hi) = self.metrics.section_range;
        if (1.0 - ratio).abs() > (1.0 - lo).abs().max((hi - 1.0).abs()) || !lo.is_finite() {
            self.metrics.section_worst_at = at;
        }
        self.metrics.section_range = (lo.min(ratio), hi.max(ratio));
        self.metrics.section_cycles += 1;
        self.metrics.section_samples.push(ratio);
        if l >= SECTION_LONG_MM {
            let ratio = v / sl;
            let (lo, hi) = self.metrics.section_long_range;
            if (1.0 - ratio).abs() > (1.0 - lo).abs().max((hi - 1.0).abs()) || !lo.is_finite() {
                self.metrics.section_long_worst_at = at;
            }
            self.metrics.section_long_range = (lo.min(ratio), hi.max(ratio));
            self.metrics.section_long_samples.push(ratio);
            let cos = heading_cos(&self.recent);
            if straight_at(cos, STRAIGHT_DEG) {
                let (lo, hi) = self.metrics.section_straight_range;
                if (1.0 - ratio).abs() > (1.0 - lo).abs().max((hi - 1.0).abs()) || !lo.is_finite() {
                    self.metrics.section_straight_worst_at = at;
                    self.metrics.section_straight_worst_cycle = self.cycles - 1;
                }
                self.metrics.section_straight_range = (lo.min(ratio), hi.max(ratio));
                self.metrics.section_straight_samples.push(ratio);
                let mid = self.recent[self.recent.len() / 2];
                if mid.counted && straight_at(cos, STRAIGHT_DEG / 2.0) {
                    self.metrics
                        .section_short_straight_samples
                        .push(mid.vol / mid.sds);
                }
            }
        }
    }

    /// The section of design bead `i` (its `Command::Section`, else the config's), mm^2.
    pub fn bead_section(&self, i: usize) -> Option<f64> {
        self.bead_s.get(i).copied()
    }

    /// Finishes the run and returns the metrics.
    pub fn finish(mut self) -> Metrics {
        self.finish_bead();
        if self.metrics.section_cycles == 0 {
            self.metrics.section_range = (1.0, 1.0);
        }
        if !self.metrics.section_long_range.0.is_finite() {
            self.metrics.section_long_range = (1.0, 1.0);
        }
        if !self.metrics.section_straight_range.0.is_finite() {
            self.metrics.section_straight_range = (1.0, 1.0);
        }
        self.metrics.section_steps = self.bead_steps.iter().map(|s| s.len() as u64).sum();
        self.metrics.bead_sections = self
            .bead_s
            .iter()
            .fold((f64::NAN, f64::NAN), |(lo, hi), &s| (lo.min(s), hi.max(s)));
        self.metrics
    }

    /// The window of `len` mm ending where the head is against the current bead's changes
    /// of section: its distance from the nearest, mm, and how far it is outside the
    /// reach of every one (at most 0: within one's). Infinite in a bead without one.
    fn step_near(&self, len: f64) -> (f64, f64) {
        let Some((bi, t)) = self.current.as_ref() else {
            return (f64::INFINITY, f64::INFINITY);
        };
        let (start, end) = (t.s - len, t.s);
        let (mut raw, mut clear) = (f64::INFINITY, f64::INFINITY);
        for &(p, a, b) in &self.bead_steps[*bi] {
            let p = p + t.drift;
            // The change's staircase runs after it; the ramp's window either side.
            let (gap, reach) = if p > end {
                (p - end, self.reach.ring_mm)
            } else {
                ((start - p).max(0.0), self.reach.behind(a, b))
            };
            raw = raw.min(gap);
            clear = clear.min(gap - reach);
        }
        (raw, clear)
    }

    /// Sets how far a change of section's ramp reaches (the machine's; none by default:
    /// only the windows over a change are left out).
    pub fn set_step_reach(&mut self, reach: StepReach) {
        self.reach = reach;
    }

    fn finish_bead(&mut self) {
        let Some((bi, trace)) = self.current.take() else {
            return;
        };
        if trace.window.1 >= SECTION_WINDOW_MM / 4.0 {
            let at = trace
                .samples
                .last()
                .map(|p| [p[0], p[1]])
                .unwrap_or_default();
            self.section(trace.window, at);
        }
        self.recent.clear();
        let design = &self.beads[bi];
        let first = design.runs[0].1;
        let end = trace.s + trace.extra;
        if let Some(&(s0, _)) = trace.landed.first() {
            let right = trace
                .landed
                .iter()
                .find(|r| r.1 == first)
                .map_or(end, |r| r.0);
            self.metrics.bead_starts.push((bi, right - s0));
        }
        let (landed, start_boundary) = start_boundary(bi, design, &trace.landed);
        let (runs, slivers) = merge_slivers(&landed, end);
        self.metrics.slivers += slivers;
        let materials_landed: Vec<u8> = runs.iter().map(|r| r.1).collect();
        let materials_design: Vec<u8> = design.runs.iter().map(|r| r.1).collect();
        if materials_landed != materials_design {
            let m = mismatch(bi, design, &runs, end);
            self.metrics.mismatches.push(m);
            return;
        }
        self.metrics.boundaries.extend(start_boundary);
        let mut from = 0;
        for (k, &(point, m)) in design.runs.iter().enumerate().skip(1) {
            let (s_design, idx) = closest_s(&trace.samples, point, from);
            from = idx;
            self.metrics.boundaries.push(Boundary {
                bead: bi,
                point,
                material: m,
                s_design,
                s_landed: runs[k].0,
            });
        }
    }
}

/// A bead that starts in another material than the design's (its change fell across the
/// travel before it, the channel still holding the last bead's paste) has its boundary
/// at its start: that boundary, and what landed from it on (else all of `landed`, and
/// none), to compare as usual.
fn start_boundary(
    bi: usize,
    design: &DesignBead,
    landed: &[(f64, u8)],
) -> (Vec<(f64, u8)>, Option<Boundary>) {
    let first = design.runs[0].1;
    let mut landed = landed.to_vec();
    let mut start_boundary = None;
    if let (Some(&(s0, m0)), Some(k)) = (landed.first(), landed.iter().position(|r| r.1 == first)) {
        if m0 != first && landed[k].0 - s0 >= SLIVER_MM {
            start_boundary = Some(Boundary {
                bead: bi,
                point: design.runs[0].0,
                material: first,
                s_design: s0,
                s_landed: landed[k].0,
            });
            landed.drain(..k);
        }
    }
    (landed, start_boundary)
}

/// The runs of `landed` (a bead ending at `end` along the path) with the slivers merged
/// into their neighbours, and how many slivers there were.
fn merge_slivers(landed: &[(f64, u8)], end: f64) -> (Vec<(f64, u8)>, u64) {
    let mut slivers = 0;
    let mut runs: Vec<(f64, u8)> = Vec::new();
    for (k, &(s, m)) in landed.iter().enumerate() {
        let next_s = landed.get(k + 1).map(|r| r.0).unwrap_or(end);
        if next_s - s < SLIVER_MM && (k > 0 || landed.len() > 1) {
            slivers += 1;
            continue;
        }
        if runs.last().map(|r| r.1) == Some(m) {
            continue;
        }
        runs.push((s, m));
    }
    (runs, slivers)
}

/// What tells a person where bead `bi`'s landed material `runs` (the bead ending at `end`)
/// part from its design's.
fn mismatch(bi: usize, design: &DesignBead, runs: &[(f64, u8)], end: f64) -> String {
    let materials_landed: Vec<u8> = runs.iter().map(|r| r.1).collect();
    let materials_design: Vec<u8> = design.runs.iter().map(|r| r.1).collect();
    let first = materials_landed
        .iter()
        .zip(&materials_design)
        .position(|(a, b)| a != b)
        .unwrap_or(materials_landed.len().min(materials_design.len()));
    let lo = first.saturating_sub(2);
    // Alternating sequences hide where they part: name the shortest landed runs, the
    // likely blips.
    let mut short: Vec<(f64, f64, u8)> = runs
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let next = runs.get(k + 1).map(|n| n.0).unwrap_or(end);
            (next - r.0, r.0, r.1)
        })
        .collect();
    short.sort_by(|a, b| a.0.total_cmp(&b.0));
    short.truncate(3);
    format!(
        "bead {bi} (commands {}..={}): {} design runs, {} landed; first difference at run {first}: design {:?}, landed {:?}; shortest landed runs (length, s, material) {:?}",
        design.commands.0,
        design.commands.1,
        materials_design.len(),
        materials_landed.len(),
        &design.runs[lo..(first + 3).min(design.runs.len())],
        &runs[lo..(first + 3).min(runs.len())],
        short,
    )
}

/// How close the executed path must pass a design point to be taken as passing it: corner
/// fillets pass within r (sqrt 2 - 1) of the vertex, rows lie a pitch apart.
const NEAR_MM: f64 = 0.35;

/// Arc length along `samples` (x, y, s) of the point nearest `p`, searching forward from
/// index `from` to the first pass within `NEAR_MM`; returns (s, index).
fn closest_s(samples: &[[f64; 3]], p: [f64; 2], from: usize) -> (f64, usize) {
    let mut best = (f64::INFINITY, 0.0, from);
    for i in from..samples.len().saturating_sub(1) {
        let a = samples[i];
        let b = samples[i + 1];
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [a[0] + t * dx, a[1] + t * dy];
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if d < best.0 {
            best = (d, a[2] + t * (b[2] - a[2]), i);
        } else if best.0 < NEAR_MM && d > best.0 + NEAR_MM {
            // Past the first pass close by: later passes (the next row) are not it.
            break;
        }
    }
    (best.1, best.2)
}

/// The section in force at each command, mm^2: `initial` until a `Command::Section`.
pub fn sections_of(commands: &[Command], initial: f64) -> Vec<f64> {
    let mut s = initial;
    commands
        .iter()
        .map(|c| {
            if let Command::Section { um2 } = *c {
                s = um2 as f64 * 1e-6;
            }
            s
        })
        .collect()
}

#[cfg(test)]
mod tests {

    /// A window along a straight bead counts as away from turns; one through a 0.4 mm
    /// fillet (a row end's turn at 0.8 mm pitch) does not; one with no length does not.
    #[test]
    fn straight_windows_are_told_from_turns() {
        let short = |ds: f64, at: [f64; 2]| Short {
            vol: 0.0,
            ds,
            at,
            sds: 0.0,
            counted: true,
        };
        let line: std::collections::VecDeque<_> = (0..11)
            .map(|i| short(0.02, [i as f64 * 0.02, 1e-4 * (i % 2) as f64]))
            .collect();
        assert!(straight_at(heading_cos(&line), STRAIGHT_DEG));
        let arc: std::collections::VecDeque<_> = (0..11)
            .map(|i| {
                let a = i as f64 * 0.02 / 0.4;
                short(0.02, [0.4 * a.sin(), 0.4 * (1.0 - a.cos())])
            })
            .collect();
        assert!(!straight_at(heading_cos(&arc), STRAIGHT_DEG));
        let still: std::collections::VecDeque<_> = (0..3).map(|_| short(0.0, [1.0, 1.0])).collect();
        assert!(!straight_at(heading_cos(&still), STRAIGHT_DEG));
    }
    use super::*;

    /// A print move of `dx`, `dy` um in `material`.
    fn print(dx: i32, dy: i32, material: u8) -> Command {
        Command::Print { dx, dy, material }
    }

    #[test]
    fn beads_and_runs_follow_the_commands() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 600 },
            print(1000, 0, 0),
            print(1000, 0, 1),
            print(0, 800, 1),
            Command::Dwell { ms: 10 },
            Command::Travel {
                x: 5000,
                y: 0,
                z: 600,
            },
            print(1000, 0, 1),
            Command::End,
        ];
        let b = design_beads(&cmds, [0, 0, 0]);
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].commands, (1, 3));
        assert_eq!(b[0].runs, vec![([0.0, 0.0], 0), ([1.0, 0.0], 1)]);
        assert_eq!(b[1].runs, vec![([5.0, 0.0], 1)]);
    }

    /// The 0.02 mm windows away from turns leave a U-turn out: a bead that lays 10 %
    /// too much paste through its 0.4 mm fillet and exactly its section on the straights
    /// either side has that bulge in its band over every 0.02 mm and none away from turns.
    #[test]
    fn short_windows_away_from_turns_leave_a_fillet_out() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 600 },
            print(3000, 0, 0),
            Command::End,
        ];
        let mut m = Meter::new(&cmds, [0, 0, 0], 0.5);
        let step = 0.005;
        let arc = std::f64::consts::PI * 0.4;
        let n = ((2.0 + arc) / step) as usize;
        let mut last = [0.0, 0.0];
        for i in 0..=n {
            let s = i as f64 * step;
            let (pos, bulge) = if s <= 1.0 {
                ([s, 0.0], 1.0)
            } else if s <= 1.0 + arc {
                let a = (s - 1.0) / 0.4 - std::f64::consts::FRAC_PI_2;
                ([1.0 + 0.4 * a.cos(), 0.4 + 0.4 * a.sin()], 1.1)
            } else {
                ([1.0 - (s - 1.0 - arc), 0.8], 1.0)
            };
            let ds = (pos[0] - last[0]).hypot(pos[1] - last[1]);
            last = pos;
            m.cycle(CycleIn {
                bead_command: Some(1),
                printing: true,
                pos,
                landed_volume: 0.5 * ds * bulge,
                landing_before: 0,
                changes: &[],
            });
        }
        let r = m.finish();
        let (lo, hi) = r.section_range;
        assert!(hi > 1.09 && lo > 0.99, "{lo} .. {hi}");
        let short = &r.section_short_straight_samples;
        // Both straights but their last 0.1 mm before the fillet and first after it.
        assert!(short.len() > 70, "{}", short.len());
        assert!(
            short.iter().all(|&x| (x - 1.0).abs() < 1e-3),
            "{:?}",
            short
                .iter()
                .fold((2.0f64, 0.0f64), |a, &x| (a.0.min(x), a.1.max(x)))
        );
        let (p1, p99) = r.section_band_straight(false);
        assert!(p99 - p1 < 1e-3, "{p1} .. {p99}");
    }

    #[test]
    fn a_boundary_landing_late_is_measured_along_the_path() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 600 },
            print(1000, 0, 0),
            print(1000, 0, 1),
            Command::End,
        ];
        let mut m = Meter::new(&cmds, [0, 0, 0], 0.5);
        // 200 cycles of 0.01 mm; the change lands at x = 1.03.
        for i in 0..=200 {
            let x = i as f64 * 0.01;
            let changes: Vec<(f64, u8)> = if i == 103 { vec![(0.0, 1)] } else { vec![] };
            m.cycle(CycleIn {
                bead_command: Some(if x < 1.0 { 1 } else { 2 }),
                printing: true,
                pos: [x, 0.0],
                landed_volume: if i == 0 { 0.0 } else { 0.005 },
                landing_before: if i <= 103 { 0 } else { 1 },
                changes: &changes,
            });
        }
        let r = m.finish();
        assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
        assert_eq!(r.boundaries.len(), 1);
        assert!(
            (r.boundaries[0].error() - 0.02).abs() < 1e-9,
            "{:?}",
            r.boundaries
        );
        assert!((r.section_range.0 - 1.0).abs() < 1e-9);
    }
}
