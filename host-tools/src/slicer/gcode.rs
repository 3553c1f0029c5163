//! The older G-code export for controllers that only know feed rates (RepRapFirmware
//! dialect: `G1 X Y Z F`, travel `G0`, valves as `M42 P<inlet> S<0|1>`, `G4` dwells). It approximates what the
//! firmware does with volume as the clock: each valve is switched ahead of its material
//! boundary by the advance distance `L_adv = V_transit / S` (plus the distance covered
//! during the valve's dead time), and wherever the channel holds more than one material
//! the head speed follows the flow, `v = Q / S`, in sub-segments of at most 0.25 mm.
//! The seed paper's coarser scheme (a handful of segments per switch) is here too, as the
//! baseline the tests compare against. Simulating G-code is `gcode_feed_judge`'s.

use super::error::SliceError;
use super::output::write_atomic;
use dollop::command::{walk, MoveKind};
use dollop::flow_model::solve;
use dollop::rheology::FlowLaw;
use dollop::{Command, Machine};
use std::fmt::Write as _;
use std::path::Path;

/// How finely the speed follows the flow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Style {
    /// Ours: the speed law applied per sub-segment no longer than `max_sub_mm` (finer
    /// where the flow changes by more than `FLOW_STEP` within one), for any number of slugs in the
    /// channel and any flow law; valves lead by the advance distance plus the dead time.
    Fine {
        /// Longest sub-segment while the flow changes, mm.
        max_sub_mm: f64,
    },
    /// The seed paper's: each switch's period `t0` split into `segments` equal times,
    /// speeds from the two-material closed form assuming the channel full of the old
    /// material at the switch; valves lead by the advance distance only.
    Coarse {
        /// Segments per switch.
        segments: usize,
    },
}

impl Default for Style {
    fn default() -> Self {
        Style::Fine { max_sub_mm: 0.25 }
    }
}

/// Counts describing an export.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GcodeStats {
    /// Bytes of G-code.
    pub bytes: usize,
    /// `G1` moves that print.
    pub print_moves: usize,
    /// Valve switches between materials.
    pub switches: usize,
}

/// One straight piece of the print path, on the concatenated print length `s` (mm).
#[derive(Clone, Copy, Debug)]
struct Seg {
    from: [f64; 2],
    to: [f64; 2],
    s0: f64,
    s1: f64,
}

#[derive(Clone, Copy, Debug)]
enum Item {
    Seg(Seg),
    Travel([f64; 3]),
    Layer(f64),
    Dwell(u32),
}

/// The job as geometry: items in order and the design's boundaries (s, new material).
struct Flat {
    items: Vec<Item>,
    boundaries: Vec<(f64, u8)>,
    total_s: f64,
    start: [f64; 3],
}

fn flatten(commands: &[Command], start_um: [i32; 3], initial: u8) -> Flat {
    let mm = |v: i32| v as f64 * 1e-3;
    let mut s = 0.0;
    let mut items = Vec::new();
    let mut boundaries = Vec::new();
    let mut mat = initial;
    // Nothing after `End` is the job's; the walk skips dwells, which are kept in place
    // from the commands between two moves.
    let body = &commands[..commands
        .iter()
        .position(|c| *c == Command::End)
        .unwrap_or(commands.len())];
    let dwells = |between: &[Command]| -> Vec<Item> {
        between
            .iter()
            .filter_map(|c| match *c {
                Command::Dwell { ms } => Some(Item::Dwell(ms)),
                _ => None,
            })
            .collect()
    };
    let mut next = 0;
    for m in walk(body, start_um) {
        items.extend(dwells(&body[next..m.index]));
        next = m.index + 1;
        match m.kind {
            MoveKind::Print { material } => {
                if m.from == m.to {
                    continue;
                }
                let [dx, dy] = [m.to[0] - m.from[0], m.to[1] - m.from[1]];
                let len = mm(dx).hypot(mm(dy));
                if material != mat {
                    boundaries.push((s, material));
                    mat = material;
                }
                items.push(Item::Seg(Seg {
                    from: [mm(m.from[0]), mm(m.from[1])],
                    to: [mm(m.to[0]), mm(m.to[1])],
                    s0: s,
                    s1: s + len,
                }));
                s += len;
            }
            MoveKind::Travel => items.push(Item::Travel(m.to.map(mm))),
            MoveKind::Layer => items.push(Item::Layer(mm(m.to[2]))),
        }
    }
    items.extend(dwells(&body[next..]));
    Flat {
        items,
        boundaries,
        total_s: s,
        start: start_um.map(mm),
    }
}

/// The design's material boundaries along the concatenated print path: (s mm, material
/// after). What a simulation compares landed boundaries with.
pub fn design_boundaries(commands: &[Command], start_um: [i32; 3], initial: u8) -> Vec<(f64, u8)> {
    flatten(commands, start_um, initial).boundaries
}

/// The printhead as the speed law sees it: plug flow of fed material, flow from the
/// feeding inlet's supply pressure through the channel's content.
pub struct Head {
    laws: Vec<FlowLaw<f64>>,
    supply: Vec<f64>,
    open_delay: Vec<f64>,
    close_delay: Vec<f64>,
    rise: Vec<f64>,
    decay: Vec<f64>,
    v_s: f64,
    v_transit: f64,
    s: f64,
    initial: u8,
    /// Feed switches: (volume coordinate u, mm^3 printed since the job began; material).
    switches: Vec<(f64, u8)>,
}

impl Head {
    /// A head for `machine`, primed with `initial`, no switches yet.
    pub fn new(machine: &Machine<f64, 4>, initial: u8) -> Self {
        Head {
            laws: machine.inlets.iter().map(|i| i.law).collect(),
            supply: machine.inlets.iter().map(|i| i.supply_pa).collect(),
            open_delay: machine.inlets.iter().map(|i| i.open_delay_s).collect(),
            close_delay: machine.inlets.iter().map(|i| i.close_delay_s).collect(),
            rise: machine.inlets.iter().map(|i| i.rise_s).collect(),
            decay: machine.inlets.iter().map(|i| i.decay_s).collect(),
            v_s: machine.v_channel.mm3(),
            v_transit: machine.v_transit().mm3(),
            s: machine.bead_area,
            initial,
            switches: Vec::new(),
        }
    }

    /// Material fed at volume coordinate `u`.
    pub fn feed_at(&self, u: f64) -> u8 {
        let i = self.switches.partition_point(|&(su, _)| su <= u);
        if i == 0 {
            self.initial
        } else {
            self.switches[i - 1].1
        }
    }

    /// Flow at `u`: the feeding inlet's supply through what it fed over `[u - V_s, u]`.
    pub fn flow_at(&self, u: f64) -> f64 {
        let mut vin = [0.0f64; 8];
        let lo = u - self.v_s;
        let mut i = self.switches.partition_point(|&(su, _)| su <= lo);
        let mut from = lo;
        let mut mat = if i == 0 {
            self.initial
        } else {
            self.switches[i - 1].1
        };
        while i < self.switches.len() && self.switches[i].0 < u {
            vin[mat as usize] += self.switches[i].0 - from;
            from = self.switches[i].0;
            mat = self.switches[i].1;
            i += 1;
        }
        vin[mat as usize] += u - from;
        let n = self.laws.len();
        let p = self.supply[self.feed_at(u) as usize];
        solve::flow(&self.laws, &vin[..n], p, 0.0)
    }

    /// Volume that still flows from `cur`'s line after the command to switch to `nxt`,
    /// until `nxt`'s line pressure overtakes `cur`'s at the junction (dead times, pressure
    /// decay and rise), starting from flow `q`. Zero with ideal valves.
    pub fn switch_lag_volume(&self, cur: u8, nxt: u8, q: f64) -> f64 {
        let (c, n) = (cur as usize, nxt as usize);
        let p_cur = self.supply[c];
        let p_old = |t: f64| {
            let t = t - self.close_delay[c];
            if t <= 0.0 {
                p_cur
            } else if self.decay[c] > 0.0 {
                p_cur * (-t / self.decay[c]).exp()
            } else {
                0.0
            }
        };
        let p_new = |t: f64| {
            let t = t - self.open_delay[n];
            if t < 0.0 {
                0.0
            } else if self.rise[n] > 0.0 {
                self.supply[n] * (1.0 - (-t / self.rise[n]).exp())
            } else {
                self.supply[n]
            }
        };
        // The old content's flow scales with its pressure as the flow law says.
        let inv_n = 1.0 / self.laws[c].n.max(0.1);
        let dt = 1e-4;
        let mut v = 0.0;
        let mut t = 0.0;
        while t < 5.0 && p_new(t) < p_old(t) {
            v += q * (p_old(t + 0.5 * dt) / p_cur).max(0.0).powf(inv_n) * dt;
            t += dt;
        }
        v
    }

    /// Flow with the channel full of `m` at its own supply pressure.
    pub fn flow_full(&self, m: u8) -> f64 {
        let mut vin = [0.0f64; 8];
        vin[m as usize] = self.v_s;
        solve::flow(
            &self.laws,
            &vin[..self.laws.len()],
            self.supply[m as usize],
            0.0,
        )
    }

    /// Mean head speed over the print path from volume `ua` to `ub` with no change of
    /// the flow's formula inside: `dt = integral of du / Q(u)`, by Simpson's rule, which
    /// is exact for Newtonian content (1/Q is then linear in u). For a two-material switch
    /// this equals the stable form `2 / (S (sqrt(2a(t+dt) + b^2) + sqrt(2at + b^2)))`,
    /// with no division by `a`, so equal viscosities (`a = 0`) need no special case.
    pub fn mean_speed(&self, ua: f64, ub: f64) -> f64 {
        let du = ub - ua;
        let eps = du * 1e-9;
        let inv = |u: f64| 1.0 / self.flow_at(u).max(1e-12);
        let dt = du / 6.0 * (inv(ua + eps) + 4.0 * inv(0.5 * (ua + ub)) + inv(ub - eps));
        du / self.s / dt
    }
}

/// The speed profile along the concatenated print path: from each `s` on, `v` (mm/s).
type Profile = Vec<(f64, f64)>;

fn plan_switches(head: &mut Head, flat: &Flat, style: Style) {
    let mut last_u = 0.0f64;
    for &(sb, m) in &flat.boundaries {
        let ub = sb * head.s;
        let mut u = ub - head.v_transit;
        if let Style::Fine { .. } = style {
            // The old material keeps coming until the new line's pressure overtakes the
            // old one's (dead times, decay, rise): lead by the volume that flows meanwhile.
            let at = u.max(0.0);
            let lag = head.switch_lag_volume(head.feed_at(at), m, head.flow_at(at));
            u -= lag;
        }
        let u = u.max(last_u).max(0.0);
        last_u = u;
        if head.feed_at(u) != m {
            head.switches.push((u, m));
        }
    }
}

fn fine_profile(head: &Head, total_s: f64, max_sub: f64) -> Profile {
    let s_area = head.s;
    let mut events: Vec<f64> = vec![0.0, total_s];
    for &(u, _) in &head.switches {
        for e in [u / s_area, (u + head.v_s) / s_area] {
            if e > 0.0 && e < total_s {
                events.push(e);
            }
        }
    }
    events.sort_by(f64::total_cmp);
    events.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let mut prof: Profile = Vec::new();
    for w in events.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b - a < 1e-9 {
            continue;
        }
        let (ua, ub) = (a * s_area, b * s_area);
        let eps = (ub - ua) * 1e-9;
        let qa = head.flow_at(ua + eps);
        let qb = head.flow_at(ub - eps);
        let qm = head.flow_at(0.5 * (ua + ub));
        let steady = (qa - qb).abs() <= 1e-9 * qa && (qm - qa).abs() <= 1e-9 * qa;
        if steady {
            prof.push((a, qa / s_area));
            continue;
        }
        let n = ((b - a) / max_sub).ceil().max(1.0) as usize;
        for i in 0..n {
            let pa = a + (b - a) * i as f64 / n as f64;
            let pb = a + (b - a) * (i + 1) as f64 / n as f64;
            refine(head, pa, pb, &mut prof, 0);
        }
    }
    prof
}

/// Largest relative change of the flow within one sub-segment: the bead section then
/// stays within about half of it of S (a constant speed against a flow that drifts).
pub const FLOW_STEP: f64 = 0.04;

/// Splits [a, b] until the flow changes by at most `FLOW_STEP` inside (or pieces reach
/// 20 um).
fn refine(head: &Head, a: f64, b: f64, prof: &mut Profile, depth: u32) {
    let s = head.s;
    let eps = (b - a) * s * 1e-9;
    let qa = head.flow_at(a * s + eps);
    let qb = head.flow_at(b * s - eps);
    if (qa - qb).abs() > FLOW_STEP * qa.max(qb) && b - a > 0.04 && depth < 8 {
        let m = 0.5 * (a + b);
        refine(head, a, m, prof, depth + 1);
        refine(head, m, b, prof, depth + 1);
    } else {
        prof.push((a, head.mean_speed(a * s, b * s)));
    }
}

fn coarse_profile(head: &Head, total_s: f64, segments: usize) -> Profile {
    let s_area = head.s;
    let v_s = head.v_s;
    // The paper's closed form is Newtonian: use each material's effective coefficient,
    // the one that gives its full-channel flow at its pressure.
    let alpha = |m: u8| {
        let law = &head.laws[m as usize];
        if law.linear {
            law.a
        } else {
            head.supply[m as usize] / (v_s * head.flow_full(m).max(1e-12))
        }
    };
    let mut prof: Profile = vec![(0.0, head.flow_full(head.initial) / s_area)];
    let mut cur = head.initial;
    for (j, &(u, nxt)) in head.switches.iter().enumerate() {
        let s0 = u / s_area;
        let limit = head
            .switches
            .get(j + 1)
            .map_or(total_s, |&(un, _)| un / s_area);
        let p = head.supply[nxt as usize];
        let a = (alpha(nxt) - alpha(cur)) / p;
        let b = alpha(cur) * v_s / p;
        let t0 = b * v_s + a * v_s * v_s / 2.0;
        let k = segments.max(1);
        let dt = t0 / k as f64;
        let mut s = s0;
        for i in 0..k {
            let (t1, t2) = (i as f64 * dt, (i + 1) as f64 * dt);
            let v =
                2.0 / (s_area * ((2.0 * a * t2 + b * b).sqrt() + (2.0 * a * t1 + b * b).sqrt()));
            if s < limit {
                prof.push((s, v));
            }
            s += v * dt;
        }
        if s < limit {
            prof.push((s, head.flow_full(nxt) / s_area));
        }
        cur = nxt;
    }
    prof.sort_by(|a, b| a.0.total_cmp(&b.0));
    prof
}

/// Refuses a job (its commands and the material it starts primed with) that names a
/// material the machine has no inlet for.
pub(super) fn check_materials(
    commands: &[Command],
    initial: u8,
    inlets: usize,
) -> Result<(), SliceError> {
    let worst = commands
        .iter()
        .filter_map(|c| match c {
            Command::Print { material, .. } => Some(*material),
            _ => None,
        })
        .chain([initial])
        .max()
        .unwrap_or(0);
    if worst as usize >= inlets {
        return Err(SliceError::MaterialBeyondInlets {
            material: worst,
            inlets,
        });
    }
    Ok(())
}

/// Formats a coordinate or feed rate: fixed decimals, trailing zeros dropped.
pub(super) fn num(out: &mut String, v: f64, decimals: usize) {
    let start = out.len();
    let _ = write!(out, "{:.*}", decimals, v);
    if out[start..].contains('.') {
        while out.ends_with('0') {
            out.pop();
        }
        if out.ends_with('.') {
            out.pop();
        }
    }
    if &out[start..] == "-0" {
        out.truncate(start);
        out.push('0');
    }
}

struct Writer {
    out: String,
    pos: [f64; 3],
    f: f64,
    stats: GcodeStats,
}

impl Writer {
    fn move_to(&mut self, to: [f64; 3], f_mm_s: f64, printing: bool) {
        let r = |v: f64| (v * 1000.0).round() / 1000.0;
        let to = to.map(r);
        if to == self.pos {
            return;
        }
        // Travel (valves closed, off the beads) as G0, so a judge can tell it apart.
        self.out.push_str(if printing { "G1" } else { "G0" });
        for (a, name) in ["X", "Y", "Z"].iter().enumerate() {
            if to[a] != self.pos[a] {
                self.out.push(' ');
                self.out.push_str(name);
                num(&mut self.out, to[a], 3);
            }
        }
        let f = (f_mm_s * 60.0 * 10.0).round() / 10.0;
        if f != self.f {
            self.out.push_str(" F");
            num(&mut self.out, f, 1);
            self.f = f;
        }
        self.out.push('\n');
        self.pos = to;
        if printing {
            self.stats.print_moves += 1;
        }
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        let _ = writeln!(self.out, "M42 P{inlet} S{}", u8::from(open));
    }
}

/// Exports a job as G-code in `style`. Refuses a job naming a material the machine has
/// no inlet for (a job read from a file may).
pub fn export(
    commands: &[Command],
    start_um: [i32; 3],
    initial: u8,
    machine: &Machine<f64, 4>,
    material_names: &[String],
    style: Style,
) -> Result<(String, GcodeStats), SliceError> {
    check_materials(commands, initial, machine.inlets.len())?;
    let flat = flatten(commands, start_um, initial);
    let mut head = Head::new(machine, initial);
    plan_switches(&mut head, &flat, style);
    let prof = match style {
        Style::Fine { max_sub_mm } => fine_profile(&head, flat.total_s, max_sub_mm.max(0.01)),
        Style::Coarse { segments } => coarse_profile(&head, flat.total_s, segments),
    };
    let mut w = Writer {
        out: String::with_capacity(commands.len() * 24),
        pos: [f64::NAN; 3],
        f: f64::NAN,
        stats: GcodeStats::default(),
    };
    preamble(&mut w, style, &head, machine, material_names, flat.start);
    let travel_f = machine.motion.travel_speed;
    let z_f = machine.motion.max_speed[2];
    let close_wait_ms = machine
        .inlets
        .iter()
        .map(|i| i.close_delay_s + 5.0 * i.decay_s)
        .fold(0.0f64, f64::max)
        * 1e3;

    let s_area = head.s;
    let mut open: Option<u8> = None;
    let mut sw = 0usize; // next switch not yet emitted
    let mut pi = 0usize; // profile entry in force
    let speed_at = |pi: &mut usize, s: f64| {
        while *pi + 1 < prof.len() && prof[*pi + 1].0 <= s + 1e-9 {
            *pi += 1;
        }
        prof.get(*pi).map_or(1.0, |p| p.1).max(1e-3)
    };
    let n = flat.items.len();
    for (idx, item) in flat.items.iter().enumerate() {
        match *item {
            Item::Seg(seg) => {
                let u0 = seg.s0 * s_area;
                if open.is_none() {
                    // A bead starts: switches up to here are already in the channel's
                    // feed history; open the inlet feeding now.
                    while sw < head.switches.len() && head.switches[sw].0 / s_area <= seg.s0 + 1e-9
                    {
                        sw += 1;
                    }
                    let m = head.feed_at(u0);
                    w.valve(m, true);
                    open = Some(m);
                    // Nothing flows until the valve has opened: wait rather than print
                    // the bead's start thin (the firmware's volume clock does the same).
                    let wait_ms = (head.open_delay[m as usize] * 1e3).round();
                    if matches!(style, Style::Fine { .. }) && wait_ms >= 1.0 {
                        let _ = writeln!(w.out, "G4 P{wait_ms}");
                    }
                }
                let cuts = cuts(&prof[pi..], &head.switches[sw..], s_area, [seg.s0, seg.s1]);
                let len = seg.s1 - seg.s0;
                let mut s = seg.s0;
                let z = w.pos[2];
                for (cs, switch) in cuts {
                    if cs > s + 1e-9 {
                        let v = speed_at(&mut pi, s);
                        let f = if len > 0.0 { (cs - seg.s0) / len } else { 1.0 };
                        let p = [
                            seg.from[0] + (seg.to[0] - seg.from[0]) * f,
                            seg.from[1] + (seg.to[1] - seg.from[1]) * f,
                            z,
                        ];
                        w.move_to(p, v, true);
                        s = cs;
                    }
                    if let Some(m) = switch {
                        if let Some(o) = open {
                            if o != m {
                                w.valve(o, false);
                                w.valve(m, true);
                                w.stats.switches += 1;
                            }
                        }
                        open = Some(m);
                        sw += 1;
                    }
                }
                let bead_ends = !matches!(flat.items.get(idx + 1), Some(Item::Seg(_)));
                if bead_ends || idx + 1 == n {
                    if let Some(o) = open.take() {
                        w.valve(o, false);
                        if close_wait_ms > 0.5 {
                            let _ = writeln!(w.out, "G4 P{}", close_wait_ms.ceil() as u64);
                        }
                    }
                }
            }
            Item::Travel(p) => w.move_to(p, travel_f, false),
            Item::Layer(z) => w.move_to([w.pos[0], w.pos[1], z], z_f, false),
            Item::Dwell(ms) => {
                let _ = writeln!(w.out, "G4 P{ms}");
            }
        }
    }
    w.out.push_str("M400\n; end of job\n");
    w.stats.bytes = w.out.len();
    Ok((w.out, w.stats))
}

/// Where a segment from `s0` to `s1` (path mm) is cut: at the profile breakpoints and the
/// switches inside it (a switch with its material), then at its end, in path order.
/// `prof` and `switches` start at the entries still ahead; switches are by volume, so
/// they are divided by `s_area`.
fn cuts(
    prof: &[(f64, f64)],
    switches: &[(f64, u8)],
    s_area: f64,
    [s0, s1]: [f64; 2],
) -> Vec<(f64, Option<u8>)> {
    let mut cuts: Vec<(f64, Option<u8>)> = prof
        .iter()
        .take_while(|p| p.0 < s1 - 1e-9)
        .filter(|p| p.0 > s0 + 1e-9)
        .map(|p| (p.0, None))
        .collect();
    cuts.extend(
        switches
            .iter()
            .take_while(|w| w.0 / s_area < s1 - 1e-9)
            .map(|w| (w.0 / s_area, Some(w.1))),
    );
    cuts.push((s1, None));
    cuts.sort_by(|a, b| a.0.total_cmp(&b.0));
    cuts
}

/// The export's comments, units and closed valves, then the move to `start`: Z first,
/// then X and Y.
fn preamble(
    w: &mut Writer,
    style: Style,
    head: &Head,
    machine: &Machine<f64, 4>,
    material_names: &[String],
    start: [f64; 3],
) {
    let _ = writeln!(
        w.out,
        "; dollop G-code (RepRapFirmware dialect), {} style",
        match style {
            Style::Fine { .. } => "fine",
            Style::Coarse { .. } => "coarse (seed paper)",
        }
    );
    let _ = writeln!(
        w.out,
        "; bead section S = {:.4} mm^2, advance distance L_adv = {:.3} mm; valves switch L_adv ahead of each boundary",
        head.s, head.v_transit / head.s
    );
    for (i, name) in material_names.iter().enumerate() {
        let _ = writeln!(w.out, "; valve of inlet {i} ({name}) is GPIO port P{i} (configure it with M950 P{i} C\"...\")");
    }
    w.out.push_str("G21\nG90\n");
    for i in 0..machine.inlets.len() {
        w.valve(i as u8, false);
    }
    let travel_f = machine.motion.travel_speed;
    let z_f = machine.motion.max_speed[2];
    // To the start: Z first, then X and Y.
    w.out.push_str("G0 Z");
    num(&mut w.out, start[2], 3);
    w.out.push_str(" F");
    num(&mut w.out, (z_f * 600.0).round() / 10.0, 1);
    w.out.push('\n');
    w.pos[2] = (start[2] * 1000.0).round() / 1000.0;
    w.f = (z_f * 600.0).round() / 10.0;
    w.move_to(start, travel_f, false);
}

/// Writes G-code atomically.
pub fn write_gcode(path: &Path, text: &str) -> Result<(), SliceError> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dollop::config::Config;

    fn seed() -> Machine<f64, 4> {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/seed-paper.toml"
        ))
        .unwrap();
        let c: Config = toml::from_str(&text).unwrap();
        c.validate().unwrap()
    }

    /// The architecture's stable form of the seed paper's per-interval mean speed.
    fn stable(a: f64, b: f64, s: f64, t: f64, dt: f64) -> f64 {
        2.0 / (s * ((2.0 * a * (t + dt) + b * b).sqrt() + (2.0 * a * t + b * b).sqrt()))
    }

    #[test]
    fn mean_speed_matches_the_seed_papers_switch_law_including_equal_viscosities() {
        let m = seed();
        for equal in [false, true] {
            let mut head = Head::new(&m, 0);
            if equal {
                head.laws[1] = head.laws[0];
                head.supply[1] = head.supply[0];
            }
            head.switches.push((10.0, 1));
            let (ac, an) = (head.laws[0].a, head.laws[1].a);
            let p = head.supply[1];
            let a = (an - ac) / p;
            let b = ac * head.v_s / p;
            // Time to feed V: t(V) = b V + a V^2 / 2.
            let t_of = |v: f64| b * v + a * v * v / 2.0;
            for (v1, v2) in [(0.0, 0.1), (0.3, 0.45), (1.0, 1.2)] {
                let got = head.mean_speed(10.0 + v1, 10.0 + v2);
                let want = stable(a, b, head.s, t_of(v1), t_of(v2) - t_of(v1));
                assert!((got / want - 1.0).abs() < 1e-9, "{equal}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn valves_lead_boundaries_by_the_advance_distance() {
        let m = seed();
        let cmds = [
            Command::Travel {
                x: 10_000,
                y: 10_000,
                z: 800,
            },
            Command::Print {
                dx: 10_000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 10_000,
                dy: 0,
                material: 1,
            },
            Command::End,
        ];
        let (g, st) = export(&cmds, [10_000, 10_000, 800], 0, &m, &[], Style::default()).unwrap();
        assert_eq!(st.switches, 1);
        let l_adv = m.v_transit().mm3::<f64>() / m.bead_area;
        // The move before the switch ends L_adv before the boundary at x = 20.
        let before = g.split("M42 P0 S0\nM42 P1 S1").next().unwrap();
        let last = before.lines().last().unwrap();
        let x: f64 = last
            .split_whitespace()
            .find(|t| t.starts_with('X'))
            .unwrap()[1..]
            .parse()
            .unwrap();
        assert!(
            (x - (20.0 - l_adv)).abs() < 1.5e-3,
            "{x} vs {}",
            20.0 - l_adv
        );
        // Sub-segments while the channel holds two materials are at most 0.25 mm.
        let mut xs = g
            .lines()
            .filter(|l| l.starts_with("G1 X"))
            .map(|l| {
                l.split_whitespace().nth(1).unwrap()[1..]
                    .parse::<f64>()
                    .unwrap()
            })
            .collect::<Vec<_>>();
        xs.dedup();
        let window: Vec<_> = xs
            .windows(2)
            .filter(|w| w[0] >= x - 1e-6 && w[1] <= x + 2.0)
            .collect();
        assert!(window.len() >= 8, "{window:?}");
        assert!(window.iter().all(|w| w[1] - w[0] <= 0.2501), "{window:?}");
    }
}
