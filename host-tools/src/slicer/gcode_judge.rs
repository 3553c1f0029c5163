//! A stricter judge of G-code: runs it the way a conventional firmware would and measures
//! the print on the reference plant (`dollop_sim::plant`, independent of the executor's
//! own flow model). The firmware model: each move at its own feed (capped by each axis's
//! top speed), trapezoids at the configured acceleration, planned over the moves between
//! two full stops with a look-ahead over all of them; a junction is taken at the lower of
//! the two feeds if the junction-deviation rule allows that speed there, otherwise the
//! head comes to a full stop (a real planner would slow to the rule's speed instead: this
//! is harsher); `M42` (and Marlin's synchronous `M106`/`M107`, Klipper's `SET_PIN`) takes
//! effect when the head reaches it in the move sequence, with no stall; `M400` and `G4` stop the head; `G1 ... P<bitmap>` sets the ports mapped by
//! `M670 P` as that move starts, `M670 T` ms early. Valve dead time and pressure rise and
//! decay are the plant's, as configured. Measures where each material boundary lands along
//! the path the G-code traced against the design, and the bead section over every
//! `SECTION_MM` of bead. Parsing reads only the words dollop writes; others are skipped.

use super::gcode_feed_judge::{move_word, statements};
use dollop::command::{walk, MoveKind};
use dollop::config::Config;
use dollop::Command;
use dollop_sim::plant::Plant;

/// One G-code operation the judge understands.
#[derive(Clone, Debug, PartialEq)]
pub enum Op {
    /// Straight move, mm at mm/s; `travel` for `G0`; `bits` is `G1`'s `P` word.
    Move {
        /// Target, mm.
        to: [f64; 3],
        /// Feed, mm/s.
        v: f64,
        /// Written as `G0`.
        travel: bool,
        /// RepRapFirmware's `P<bitmap>`.
        bits: Option<u32>,
    },
    /// `M42 P<port> S<value>` (any value above 0 opens).
    Valve {
        /// Port or pin.
        port: u32,
        /// Open.
        on: bool,
    },
    /// `G4`, s.
    Dwell(f64),
    /// `M400`.
    Sync,
    /// `M670 P<ports> T<ms>`.
    PortMap {
        /// Port of each bit of `G1`'s `P` word.
        ports: Vec<u32>,
        /// `T`, s.
        advance_s: f64,
    },
}

/// Parses the G-code words the judge runs; lines and words it does not know are skipped.
pub fn parse(text: &str) -> Vec<Op> {
    let mut ops = Vec::new();
    let mut pos = [0.0f64; 3];
    let mut f = 1.0f64;
    for (cmd, words) in statements(text) {
        // Words with non-finite numbers are skipped, as unknown words are.
        let word = |w: &str| super::gcode_feed_judge::word(w).filter(|v| v.1.is_finite());
        match cmd.as_str() {
            c @ ("G0" | "G1") => {
                let mut to = pos;
                let mut bits = None;
                for (c, v) in words.filter_map(word) {
                    if !move_word(c, v, &mut to, &mut f)
                        && c == 'P'
                        && (0.0..=u32::MAX as f64).contains(&v)
                    {
                        bits = Some(v as u32)
                    }
                }
                ops.push(Op::Move {
                    to,
                    v: f,
                    travel: c == "G0",
                    bits,
                });
                pos = to;
            }
            "M42" => {
                let (mut p, mut s) = (None, None);
                for w in words {
                    match word(w) {
                        Some(('P', v)) if (0.0..=u32::MAX as f64).contains(&v) => {
                            p = Some(v as u32)
                        }
                        Some(('S', v)) => s = Some(v > 0.0),
                        _ => {}
                    }
                }
                if let (Some(port), Some(on)) = (p, s) {
                    ops.push(Op::Valve { port, on });
                }
            }
            // Marlin's fans with `LASER_SYNCHRONOUS_M106_M107`: queued with the moves, as
            // `M42` is here. `P` defaults to fan 0, `M106`'s `S` to full on.
            c @ ("M106" | "M107") => {
                let (mut port, mut on) = (0, c == "M106");
                for w in words {
                    match word(w) {
                        Some(('P', v)) if (0.0..=u32::MAX as f64).contains(&v) => port = v as u32,
                        Some(('S', v)) if c == "M106" => on = v > 0.0,
                        _ => {}
                    }
                }
                ops.push(Op::Valve { port, on });
            }
            "G4" => {
                let mut t = 0.0;
                for w in words {
                    match word(w) {
                        Some(('P', v)) if v > 0.0 => t += v * 1e-3,
                        Some(('S', v)) if v > 0.0 => t += v,
                        _ => {}
                    }
                }
                ops.push(Op::Dwell(t));
            }
            "M400" => ops.push(Op::Sync),
            // Klipper's `SET_PIN PIN=<name><port> VALUE=<v>`: the valve ports are the
            // number ending the `output_pin` name (`gcode_dialect::KLIPPER_PIN`).
            "SET_PIN" => {
                let (mut p, mut s) = (None, None);
                for w in words {
                    let Some((key, val)) = w.split_once('=') else {
                        continue;
                    };
                    if key.eq_ignore_ascii_case("PIN") {
                        let digits =
                            val.len() - val.trim_end_matches(|c: char| c.is_ascii_digit()).len();
                        p = val[val.len() - digits..].parse::<u32>().ok();
                    } else if key.eq_ignore_ascii_case("VALUE") {
                        s = val
                            .parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite())
                            .map(|v| v > 0.0);
                    }
                }
                if let (Some(port), Some(on)) = (p, s) {
                    ops.push(Op::Valve { port, on });
                }
            }
            "M670" => {
                let mut ports = Vec::new();
                let mut advance_s = 0.0;
                for w in words {
                    if let Some(list) = w.strip_prefix(['P', 'p']) {
                        ports = list.split(':').filter_map(|p| p.parse().ok()).collect();
                    } else if let Some(('T', v)) = word(w) {
                        advance_s = v.max(0.0) * 1e-3;
                    }
                }
                ops.push(Op::PortMap { ports, advance_s });
            }
            _ => {}
        }
    }
    ops
}

/// The firmware's motion limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Firmware {
    /// Top speed per axis, mm/s.
    pub max_speed: [f64; 3],
    /// Acceleration per axis, mm/s^2.
    pub max_accel: [f64; 3],
    /// Junction deviation, mm (Marlin's default 0.013 mm).
    pub junction_deviation_mm: f64,
}

impl Firmware {
    /// The machine config's limits and Marlin's default junction deviation.
    pub fn from_config(config: &Config) -> Self {
        Firmware {
            max_speed: config.motion.max_speed_mm_s.map(|v| v as f64),
            max_accel: config.motion.max_accel_mm_s2.map(|v| v as f64),
            junction_deviation_mm: 0.013,
        }
    }

    /// Klipper's planner: its `square_corner_velocity` (mm/s) is a junction deviation of
    /// `scv^2 (sqrt(2) - 1) / a` at the X/Y acceleration limit `a`.
    pub fn with_square_corner_velocity(mut self, scv: f64) -> Self {
        let a = self.max_accel[0].min(self.max_accel[1]).max(1e-9);
        self.junction_deviation_mm = scv * scv * (core::f64::consts::SQRT_2 - 1.0) / a;
        self
    }

    /// Highest speed at which the junction from direction `a` into `b` (unit vectors) is
    /// taken: `v^2 = A d sin(t/2) / (1 - sin(t/2))`, `t` the angle between `-a` and `b`.
    fn junction_speed(&self, a: [f64; 3], b: [f64; 3], accel: f64) -> f64 {
        let cos = -(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        if cos < -0.999_999 {
            return f64::INFINITY;
        }
        if cos > 0.999_999 {
            return 0.0;
        }
        let sin_half = (0.5 * (1.0 - cos)).sqrt();
        (accel * self.junction_deviation_mm * sin_half / (1.0 - sin_half)).sqrt()
    }
}

/// A design boundary: where the material changes along the print path (mm) and to what.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DesignBoundary {
    /// Point of the change, mm (z: the layer).
    pub at: [f64; 3],
    /// Material after it.
    pub material: u8,
}

/// The design's material changes along the concatenated print path, bead starts included
/// (a bead that starts in another material than the last one ended in).
pub fn design_boundaries(
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
) -> Vec<DesignBoundary> {
    let mut mat = initial;
    let mut out = Vec::new();
    // Nothing after `End` is the job's.
    let end = commands
        .iter()
        .position(|c| *c == Command::End)
        .unwrap_or(commands.len());
    for m in walk(&commands[..end], start_um) {
        match m.kind {
            MoveKind::Print { material } if m.from != m.to && material != mat => {
                out.push(DesignBoundary {
                    at: m.from.map(|v| v as f64 * 1e-3),
                    material,
                });
                mat = material;
            }
            _ => {}
        }
    }
    out
}

/// Bead length over which one section value is taken, mm.
pub const SECTION_MM: f64 = 0.2;

/// What the judge measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verdict {
    /// Design boundaries.
    pub boundaries: usize,
    /// Material changes that landed.
    pub landed: usize,
    /// |landed - design| along the path, mm: 95th percentile, largest and mean (each
    /// design boundary against the nearest landed change to the same material).
    pub p95_mm: f64,
    /// Largest.
    pub worst_mm: f64,
    /// Mean.
    pub mean_mm: f64,
    /// Smallest and largest section / S over `SECTION_MM` windows of bead (a bead's last
    /// window shorter than half of it is merged into the one before).
    pub section_range: (f64, f64),
    /// Largest |section / S - 1|.
    pub worst_section: f64,
    /// Where the worst section was, mm.
    pub worst_section_at: [f64; 3],
    /// Section windows measured.
    pub windows: usize,
    /// Junctions inside a run of moves where the head had to stop.
    pub full_stops: usize,
    /// Material changes that landed off the beads (during travel).
    pub changes_off_path: usize,
    /// Volume landed off the beads (during travel), mm^3.
    pub off_path_mm3: f64,
    /// Time of the print, s.
    pub time_s: f64,
}

/// Why the judge could not run.
#[derive(Debug, thiserror::Error)]
pub enum JudgeError {
    /// The config does not validate.
    #[error("config: {0}")]
    Config(dollop::ConfigError),
    /// The G-code runs longer than the limit.
    #[error("the G-code runs {0:.0} s, longer than the {1:.0} s limit")]
    TooLong(f64, f64),
}

/// A move as planned.
#[derive(Clone, Copy, Debug)]
struct Block {
    from: [f64; 3],
    dir: [f64; 3],
    len: f64,
    t0: f64,
    vi: f64,
    vc: f64,
    a: f64,
    ta: f64,
    tc: f64,
    td: f64,
    travel: bool,
    /// Path length of the beads before this block (G1 moves only), mm.
    s0: f64,
}

impl Block {
    fn end(&self) -> f64 {
        self.t0 + self.ta + self.tc + self.td
    }
    /// Distance along the block at time `t`.
    fn d_at(&self, t: f64) -> f64 {
        let t = (t - self.t0).max(0.0);
        if t <= self.ta {
            return self.vi * t + 0.5 * self.a * t * t;
        }
        let da = self.vi * self.ta + 0.5 * self.a * self.ta * self.ta;
        let t = t - self.ta;
        if t <= self.tc {
            return da + self.vc * t;
        }
        let t = (t - self.tc).min(self.td);
        (da + self.vc * self.tc + self.vc * t - 0.5 * self.a * t * t).min(self.len)
    }
}

/// A move waiting to be planned with the others of its run.
#[derive(Clone, Copy, Debug)]
struct Pending {
    from: [f64; 3],
    dir: [f64; 3],
    len: f64,
    v: f64,
    a: f64,
    travel: bool,
}

/// The G-code as a timeline: moves, stands and valve events.
struct Timeline {
    blocks: Vec<Block>,
    /// (time, inlet, open), in time order.
    events: Vec<(f64, usize, bool)>,
    full_stops: usize,
    end: f64,
}

/// A move from `from` to `to` at `v` as the planner limits it (each axis's speed and
/// acceleration along its direction); `None` when it does not move.
fn pending(fw: &Firmware, from: [f64; 3], to: [f64; 3], v: f64, travel: bool) -> Option<Pending> {
    let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if len < 1e-9 {
        return None;
    }
    let dir = d.map(|c| c / len);
    let mut vmax = v.max(1e-3);
    let mut a = f64::INFINITY;
    for (ax, c) in dir.iter().map(|c| c.abs()).enumerate() {
        if c > 1e-12 {
            vmax = vmax.min(fw.max_speed[ax] / c);
            a = a.min(fw.max_accel[ax] / c);
        }
    }
    Some(Pending {
        from,
        dir,
        len,
        v: vmax,
        a,
        travel,
    })
}

/// Plans the moves queued since the last sync: junction limits, the backward and forward
/// passes, then one trapezoid block each from time `*t` (print length from `*s`), and
/// the valve changes at their moves' starts (less their advance). Empties both queues.
fn end_run(
    fw: &Firmware,
    run: &mut Vec<Pending>,
    marks: &mut Vec<(usize, f64, usize, bool)>,
    t: &mut f64,
    s: &mut f64,
    tl: &mut Timeline,
) {
    let n = run.len();
    // Junction limits, then the backward and forward passes.
    let mut entry = vec![0.0f64; n + 1];
    for k in 1..n {
        let (p, q) = (run[k - 1], run[k]);
        let want = p.v.min(q.v);
        let jd = fw.junction_speed(p.dir, q.dir, p.a.min(q.a));
        entry[k] = if jd >= want {
            want
        } else {
            tl.full_stops += usize::from(!p.travel && !q.travel);
            0.0
        };
    }
    for k in (0..n).rev() {
        let reach = (entry[k + 1].powi(2) + 2.0 * run[k].a * run[k].len).sqrt();
        entry[k] = entry[k].min(reach);
    }
    for k in 0..n {
        let reach = (entry[k].powi(2) + 2.0 * run[k].a * run[k].len).sqrt();
        entry[k + 1] = entry[k + 1].min(reach);
    }
    let mut starts = Vec::with_capacity(n + 1);
    for (k, m) in run.iter().enumerate() {
        starts.push(*t);
        let (vi, vo, a) = (entry[k], entry[k + 1], m.a);
        let peak = ((2.0 * a * m.len + vi * vi + vo * vo) / 2.0).sqrt();
        let vc = m.v.min(peak).max(vi).max(vo);
        let da = (vc * vc - vi * vi) / (2.0 * a);
        let dd = (vc * vc - vo * vo) / (2.0 * a);
        let tc = if vc > 0.0 {
            ((m.len - da - dd) / vc).max(0.0)
        } else {
            0.0
        };
        let b = Block {
            from: m.from,
            dir: m.dir,
            len: m.len,
            t0: *t,
            vi,
            vc,
            a,
            ta: (vc - vi) / a,
            tc,
            td: (vc - vo) / a,
            travel: m.travel,
            s0: *s,
        };
        *t = b.end();
        if !m.travel {
            *s += m.len;
        }
        tl.blocks.push(b);
    }
    starts.push(*t);
    for &(k, early, inlet, open) in marks.iter() {
        tl.events.push(((starts[k] - early).max(0.0), inlet, open));
    }
    run.clear();
    marks.clear();
}

fn build(ops: &[Op], fw: &Firmware, ports: &[u32], start: [f64; 3]) -> Timeline {
    let inlet_of = |port: u32| ports.iter().position(|&p| p == port);
    let mut tl = Timeline {
        blocks: Vec::new(),
        events: Vec::new(),
        full_stops: 0,
        end: 0.0,
    };
    let mut pos = start;
    let mut run: Vec<Pending> = Vec::new();
    // Valve changes inside the run: (moves before, time offset, inlet, open).
    let mut marks: Vec<(usize, f64, usize, bool)> = Vec::new();
    let mut bit_ports: Vec<u32> = ports.to_vec();
    let mut advance = 0.0;
    let mut t = 0.0;
    let mut s = 0.0;
    let mut valves = vec![false; ports.len()];
    for op in ops {
        match op {
            Op::Move {
                to,
                v,
                travel,
                bits,
            } => {
                if let Some(b) = bits {
                    for (i, &port) in ports.iter().enumerate() {
                        if let Some(j) = bit_ports.iter().position(|&p| p == port) {
                            let open = j < 32 && b & (1 << j) != 0;
                            if open != valves[i] {
                                valves[i] = open;
                                marks.push((run.len(), advance, i, open));
                            }
                        }
                    }
                }
                let Some(p) = pending(fw, pos, *to, *v, *travel) else {
                    continue;
                };
                run.push(p);
                pos = *to;
            }
            Op::Valve { port, on } => {
                if let Some(i) = inlet_of(*port) {
                    if valves[i] != *on {
                        valves[i] = *on;
                        marks.push((run.len(), 0.0, i, *on));
                    }
                }
            }
            Op::Dwell(d) => {
                end_run(fw, &mut run, &mut marks, &mut t, &mut s, &mut tl);
                tl.blocks.push(Block {
                    from: pos,
                    dir: [0.0; 3],
                    len: 0.0,
                    t0: t,
                    vi: 0.0,
                    vc: 0.0,
                    a: 1.0,
                    ta: 0.0,
                    tc: *d,
                    td: 0.0,
                    travel: false,
                    s0: s,
                });
                t += d;
            }
            Op::Sync => end_run(fw, &mut run, &mut marks, &mut t, &mut s, &mut tl),
            Op::PortMap {
                ports: p,
                advance_s,
            } => {
                bit_ports.clone_from(p);
                advance = *advance_s;
            }
        }
    }
    end_run(fw, &mut run, &mut marks, &mut t, &mut s, &mut tl);
    tl.events.sort_by(|a, b| a.0.total_cmp(&b.0));
    tl.end = t;
    tl
}

/// The judge's settings.
#[derive(Clone, Debug)]
pub struct Setup<'a> {
    /// The machine (valves and pastes as the plant sees them).
    pub config: &'a Config,
    /// Motion limits.
    pub firmware: Firmware,
    /// Port (or pin) of each inlet's valve as the G-code names it.
    pub ports: Vec<u32>,
    /// Material the channel is primed with.
    pub initial: u8,
    /// Where the head stands before the first move, mm.
    pub start: [f64; 3],
    /// Refuse G-code running longer than this, s.
    pub max_time_s: f64,
}

impl<'a> Setup<'a> {
    /// Ports 0, 1, .., the config's limits, no time limit.
    pub fn new(config: &'a Config, initial: u8, start: [f64; 3]) -> Self {
        Setup {
            config,
            firmware: Firmware::from_config(config),
            ports: (0..config.inlets.len() as u32).collect(),
            initial,
            start,
            max_time_s: f64::INFINITY,
        }
    }
}

/// Accumulates what landed over one judge step, across valve events inside it.
#[derive(Default)]
struct StepLanded {
    volume: f64,
    changes: Vec<(f64, u8)>,
}

impl StepLanded {
    /// Runs `plant` to `t1` (steps of `h`), acting on the valve events of `events` from
    /// `*ev` on that fall by then, and keeps what landed over the step.
    fn advance(
        &mut self,
        plant: &mut Plant,
        events: &[(f64, usize, bool)],
        ev: &mut usize,
        t1: f64,
        h: f64,
    ) {
        self.volume = 0.0;
        self.changes.clear();
        while *ev < events.len() && events[*ev].0 <= t1 {
            let (te, inlet, open) = events[*ev];
            if te > plant.time() {
                let l = plant.advance(te, h);
                self.changes
                    .extend(l.changes.iter().map(|&(x, m)| (self.volume + x, m)));
                self.volume += l.volume;
            }
            plant.command(inlet, open);
            *ev += 1;
        }
        let l = plant.advance(t1, h);
        self.changes
            .extend(l.changes.iter().map(|&(x, m)| (self.volume + x, m)));
        self.volume += l.volume;
    }
}

/// The section windows of the bead in progress, closed into the verdict's figures at
/// the bead's end.
struct Sections {
    /// Bead section the G-code means, mm^2.
    area: f64,
    /// Windows of the bead in progress: (volume, length, where).
    windows: Vec<(f64, f64, [f64; 3])>,
    /// The window filling: (volume, length).
    cur: (f64, f64),
}

impl Sections {
    /// Adds a step's `volume` over `ds` of bead, closing the window at `at` when full.
    fn add(&mut self, volume: f64, ds: f64, at: [f64; 3]) {
        self.cur.0 += volume;
        self.cur.1 += ds;
        if self.cur.1 >= SECTION_MM {
            self.windows.push((self.cur.0, self.cur.1, at));
            self.cur = (0.0, 0.0);
        }
    }

    /// Ends the bead at `at`: its last window (merged into the one before when shorter
    /// than half of `SECTION_MM`), and every window's section / S into `v`.
    fn close_bead(&mut self, at: [f64; 3], v: &mut Verdict) {
        let cur = self.cur;
        if cur.1 > 0.0 {
            if cur.1 < 0.5 * SECTION_MM {
                if let Some(last) = self.windows.last_mut() {
                    last.0 += cur.0;
                    last.1 += cur.1;
                } else if cur.1 >= 0.25 * SECTION_MM {
                    self.windows.push((cur.0, cur.1, at));
                }
            } else {
                self.windows.push((cur.0, cur.1, at));
            }
        }
        for &(vol, len, at) in self.windows.iter() {
            let r = vol / (self.area * len);
            if (r - 1.0).abs() > v.worst_section {
                v.worst_section = (r - 1.0).abs();
                v.worst_section_at = at;
            }
            v.section_range = (v.section_range.0.min(r), v.section_range.1.max(r));
            v.windows += 1;
        }
        self.windows.clear();
        self.cur = (0.0, 0.0);
    }
}

/// The head along the timeline's blocks, time running forward.
struct Head<'t> {
    blocks: &'t [Block],
    /// Where it stands before the first block.
    start: [f64; 3],
    /// The block it is in.
    bi: usize,
}

impl Head<'_> {
    /// (path length of the beads so far, position) at `t`.
    fn at(&mut self, t: f64) -> (f64, [f64; 3]) {
        while self.bi + 1 < self.blocks.len() && self.blocks[self.bi].end() <= t {
            self.bi += 1;
        }
        let Some(b) = self.blocks.get(self.bi) else {
            return (0.0, self.start);
        };
        let d = b.d_at(t);
        let p = [
            b.from[0] + b.dir[0] * d,
            b.from[1] + b.dir[1] * d,
            b.from[2] + b.dir[2] * d,
        ];
        (b.s0 + if b.travel { 0.0 } else { d }, p)
    }
}

/// Runs `gcode` as the firmware model would and measures it against `design`.
pub fn judge(
    gcode: &str,
    setup: &Setup<'_>,
    design: &[DesignBoundary],
) -> Result<Verdict, JudgeError> {
    let ops = parse(gcode);
    let tl = build(&ops, &setup.firmware, &setup.ports, setup.start);
    if tl.end > setup.max_time_s {
        return Err(JudgeError::TooLong(tl.end, setup.max_time_s));
    }
    let mut plant = Plant::new(setup.config, setup.initial).map_err(JudgeError::Config)?;
    let area = setup
        .config
        .channel
        .bead_area_mm2
        .map(|a| a as f64)
        .unwrap_or(
            setup.config.channel.line_pitch_mm as f64 * setup.config.channel.layer_height_mm as f64,
        );
    let mut v = Verdict {
        section_range: (f64::INFINITY, f64::NEG_INFINITY),
        full_stops: tl.full_stops,
        time_s: tl.end,
        ..Verdict::default()
    };
    let landed_at = land(&tl, &mut plant, area, setup.start, &mut v);
    if v.windows == 0 {
        v.section_range = (1.0, 1.0);
    }
    v.landed = landed_at.len();
    v.boundaries = design.len();
    let errors = boundary_errors(&tl, &landed_at, design);
    if !errors.is_empty() {
        let n = errors.len();
        v.worst_mm = errors[n - 1];
        v.mean_mm = errors.iter().sum::<f64>() / n as f64;
        let k = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        v.p95_mm = errors[k];
    }
    Ok(v)
}

/// Runs the plant along the timeline `tl` (head from `start`, beads of section `area`)
/// until the last of the flow has landed: the sections, the changes off the beads and
/// the volume landed there go into `v`; returns where each material change landed
/// (path length of the beads, mm; material).
fn land(
    tl: &Timeline,
    plant: &mut Plant,
    area: f64,
    start: [f64; 3],
    v: &mut Verdict,
) -> Vec<(f64, u8)> {
    let h = 1e-4;
    // Let the last of the flow land after the end (5 s covers any config's decay).
    let t_stop = tl.end + 5.0;
    let mut ev = 0usize;
    let mut landed_at: Vec<(f64, u8)> = Vec::new();
    let mut in_bead = false;
    let mut standing_vol = 0.0f64;
    let mut sections = Sections {
        area,
        windows: Vec::new(),
        cur: (0.0, 0.0),
    };
    let mut head = Head {
        blocks: &tl.blocks,
        start,
        bi: 0,
    };
    let mut t = 0.0f64;
    let (mut s_prev, _) = head.at(0.0);
    let mut step = StepLanded::default();
    while t < t_stop {
        let t1 = (t + h).min(t_stop);
        step.advance(plant, &tl.events, &mut ev, t1, h);
        let blk_before = head.bi;
        let (s1, p1) = head.at(t1);
        // A G1 block starts a bead; a G0 block ends it.
        if t1 <= tl.end {
            for b in &tl.blocks[blk_before..=head.bi] {
                if b.len > 0.0 {
                    if b.travel && in_bead {
                        sections.close_bead(p1, v);
                        in_bead = false;
                    } else if !b.travel {
                        in_bead = true;
                    }
                }
            }
        }
        let ds = s1 - s_prev;
        for &(x, m) in &step.changes {
            let f = if step.volume > 0.0 {
                (x / step.volume).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let s = if ds > 0.0 {
                s_prev + f * ds
            } else {
                s1 + (standing_vol + f * step.volume) / area
            };
            // Off the beads (during travel) a change counts where the path is: at the end
            // of the last bead, which is where the next one starts along it.
            if !in_bead {
                v.changes_off_path += 1;
            }
            landed_at.push((s, m));
        }
        if in_bead {
            if ds > 0.0 {
                standing_vol = 0.0;
            } else {
                standing_vol += step.volume;
            }
            sections.add(step.volume, ds, p1);
        } else {
            v.off_path_mm3 += step.volume;
        }
        s_prev = s1;
        t = t1;
    }
    sections.close_bead([f64::NAN; 3], v);
    landed_at
}

/// Per design boundary, sorted: |landed - design| along the path, mm, against the
/// nearest change to the same material in `landed_at`.
fn boundary_errors(tl: &Timeline, landed_at: &[(f64, u8)], design: &[DesignBoundary]) -> Vec<f64> {
    // The path the G1 moves traced, for placing the design's points on it.
    let path: Vec<&Block> = tl
        .blocks
        .iter()
        .filter(|b| !b.travel && b.len > 0.0)
        .collect();
    let mut by_material: Vec<Vec<f64>> = vec![Vec::new(); 256];
    for &(s, m) in landed_at {
        by_material[m as usize].push(s);
    }
    for list in by_material.iter_mut() {
        list.sort_by(f64::total_cmp);
    }
    let mut errors = Vec::with_capacity(design.len());
    let mut from = 0usize;
    for d in design {
        let (s_design, k) = closest_on_path(&path, d.at, from);
        from = k;
        let list = &by_material[d.material as usize];
        let i = list.partition_point(|&x| x < s_design);
        let near = [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|j| list.get(j))
            .map(|x| (x - s_design).abs())
            .fold(f64::INFINITY, f64::min);
        errors.push(near);
    }
    errors.sort_by(f64::total_cmp);
    errors
}

/// How close the path must pass a design point to be taken as passing it, mm (corner
/// fillets pass within r (sqrt 2 - 1) of the vertex; rows lie a pitch apart).
const NEAR_MM: f64 = 0.35;

/// Path length at the point of `path` nearest `p` in `p`'s layer, searching forward from
/// block `from` to the first pass within `NEAR_MM`; returns (s, block index).
fn closest_on_path(path: &[&Block], p: [f64; 3], from: usize) -> (f64, usize) {
    let mut best = (f64::INFINITY, 0.0, from);
    for (i, b) in path.iter().enumerate().skip(from) {
        let end_z = b.from[2] + b.dir[2] * b.len;
        if (b.from[2] - p[2]).abs() > 1e-3 && (end_z - p[2]).abs() > 1e-3 {
            if best.0 < NEAR_MM {
                break;
            }
            continue;
        }
        let t = ((p[0] - b.from[0]) * b.dir[0] + (p[1] - b.from[1]) * b.dir[1]).clamp(0.0, b.len);
        let q = [b.from[0] + t * b.dir[0], b.from[1] + t * b.dir[1]];
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if d < best.0 {
            best = (d, b.s0 + t, i);
        } else if best.0 < NEAR_MM && d > best.0 + NEAR_MM {
            break;
        }
    }
    (best.1, best.2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsing_reads_every_dialects_words_and_survives_garbage() {
        let ops =
            parse("G21\nM670 P3:4 T5\nG0 X1 Y2 F600 ; go\nM42 P1 S255\nG4 P250\nG1 X3 P2\nM400\n");
        assert_eq!(
            ops,
            vec![
                Op::PortMap {
                    ports: vec![3, 4],
                    advance_s: 0.005
                },
                Op::Move {
                    to: [1.0, 2.0, 0.0],
                    v: 10.0,
                    travel: true,
                    bits: None
                },
                Op::Valve { port: 1, on: true },
                Op::Dwell(0.25),
                Op::Move {
                    to: [3.0, 2.0, 0.0],
                    v: 10.0,
                    travel: false,
                    bits: Some(2)
                },
                Op::Sync,
            ]
        );
        assert_eq!(
            parse("SET_PIN PIN=dollop_valve12 VALUE=1\nset_pin pin=dollop_valve0 value=0.0\n"),
            vec![
                Op::Valve { port: 12, on: true },
                Op::Valve { port: 0, on: false }
            ]
        );
        assert_eq!(
            parse("M106 P3 S255\nM107 P3\nm106\nM106 P1 S0\nM107\n"),
            vec![
                Op::Valve { port: 3, on: true },
                Op::Valve { port: 3, on: false },
                Op::Valve { port: 0, on: true },
                Op::Valve { port: 1, on: false },
                Op::Valve { port: 0, on: false }
            ]
        );
        let ops = parse("G1 Ä5 X\u{e9} Xinf\nM42 P-1 S1\nM42 P\nG4 Pxyz\n\u{1F600}\nM670 P:x:\nSET_PIN PIN=valve VALUE=1\nSET_PIN PIN=v1 VALUE=nan\nSET_PIN PIN=v9999999999999 VALUE=1\nSET_PIN PIN==\u{e9}1 VALUE\n");
        assert!(ops.iter().all(|o| !matches!(o, Op::Valve { .. })));
    }

    fn fw() -> Firmware {
        Firmware {
            max_speed: [100.0; 3],
            max_accel: [1000.0; 3],
            junction_deviation_mm: 0.013,
        }
    }

    #[test]
    fn trapezoids_join_collinear_moves_and_stop_at_sharp_corners() {
        let ops = parse("G1 X10 F600\nG1 X20 F1200\nG1 X20 Y10\n");
        let tl = build(&ops, &fw(), &[0], [0.0; 3]);
        assert_eq!(tl.blocks.len(), 3);
        let b = &tl.blocks;
        // From rest to 10 mm/s at 1000 mm/s^2, the junction at 10, then up to 20.
        assert!((b[0].vi - 0.0).abs() < 1e-12 && (b[1].vi - 10.0).abs() < 1e-9);
        assert!((b[1].vi - 10.0).abs() < 1e-9 && (b[1].vc - 20.0).abs() < 1e-9);
        // A right angle at 20 mm/s: JD allows sqrt(1000 * 0.013 * 0.707 / 0.293) = 5.6 mm/s:
        // a full stop.
        assert_eq!(b[2].vi, 0.0);
        assert_eq!(tl.full_stops, 1);
        // Time of the first move: 0.05 s to accelerate over 0.05 mm, then 9.95 mm at 10.
        assert!(
            (b[0].end() - (0.01 + 9.95 / 10.0)).abs() < 1e-9,
            "{}",
            b[0].end()
        );
        for blk in b {
            assert!((blk.d_at(blk.end()) - blk.len).abs() < 1e-9);
        }
    }

    #[test]
    fn m42_acts_where_it_stands_and_g1_p_early_by_m670_t() {
        let ops = parse("G1 X10 F600\nM42 P0 S1\nG1 X20\nM670 P0 T20\nG1 X30 P0\n");
        let tl = build(&ops, &fw(), &[0], [0.0; 3]);
        assert_eq!(tl.events.len(), 2);
        // M42 at the end of the first move, with no stop: the second block enters at 10.
        assert!((tl.events[0].0 - tl.blocks[0].end()).abs() < 1e-12);
        assert!(tl.events[0].2);
        assert!((tl.blocks[1].vi - 10.0).abs() < 1e-9);
        // P0 closes port 0 20 ms before the third move starts.
        assert!((tl.events[1].0 - (tl.blocks[2].t0 - 0.02)).abs() < 1e-12);
        assert!(!tl.events[1].2);
    }
}
