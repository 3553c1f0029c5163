//! The words of each G-code dialect for a sampled executor run (`gcode_step::Step`s):
//! `plain` (`G0`/`G1`/`M42`/`G4`, what any firmware accepts), `reprap` (RepRapFirmware's
//! `G1 ... P<bitmap>` with the ports mapped by `M670`), `klipper` (`SET_PIN`, which
//! Klipper schedules with the moves), `marlin` (`M106`/`M107` on fan outputs, which Marlin
//! built with `LASER_SYNCHRONOUS_M106_M107` queues with the moves) and `marlin-m42`
//! (`M400` then `M42 P<pin> S0|255`, for stock builds). What each assumes of the firmware
//! is on `Kind`. Only formatting lives here: where moves and valve changes fall is decided
//! before.

use super::gcode::{num, GcodeStats};
use super::gcode_step::Step;
use dollop::config::Config;
use std::fmt::Write as _;

/// How valve changes are written, and the port (or pin) of each inlet's valve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Dialect {
    /// The words used.
    pub kind: Kind,
    /// Port (`plain`, `reprap`), `output_pin` number (`klipper`), fan index (`marlin`) or
    /// board pin (`marlin-m42`) of each inlet's valve, inlet 0 first; inlet i uses i where
    /// the list is shorter.
    pub ports: Vec<u32>,
}

/// The dialects.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Kind {
    /// `M42 P<port> S<0|1>` between the moves, exactly where the executor switched.
    /// Assumes the firmware runs `M42` in its place in the move sequence (when the head
    /// gets there) without stopping the head, as firmwares that queue output changes with
    /// the moves do. A firmware that runs `M42` as soon as it reads the line switches the
    /// valves early by whatever its planner holds: use `RepRap` or `Marlin` there.
    #[default]
    Plain,
    /// RepRapFirmware 3: `M670 P<port list> T0` maps bit i of `G1`'s `P` parameter to the
    /// port of inlet i; a valve change while moving rides on the next move as
    /// `G1 ... P<bitmap>`, which the firmware sets as that move starts (`T0`: no advance,
    /// the executor's run already leads each valve by its dead time). A change while the
    /// head stands is `M400` (nothing moves, so it costs no time) then `M42 P<port> S<0|1>`.
    /// Assumes the ports were created with `M950 P<port> C"<pin>"` in the machine's config.
    RepRap,
    /// Klipper: `SET_PIN PIN=dollop_valve<port> VALUE=<0|1>` between the moves, exactly
    /// where the executor switched. Klipper schedules an `output_pin`'s `SET_PIN` at the
    /// print time the moves queued before it end (through the toolhead's look-ahead), so
    /// the valve switches where the head is, without stopping it: the same timing as
    /// `Plain`. Assumes `[output_pin dollop_valve<port>]` sections for the valves' pins
    /// in `printer.cfg`, and `minimum_cruise_ratio: 0` (Klipper's default 0.5 lowers the
    /// peak of a move that would speed up and at once slow down; the moves here mostly
    /// hold their speed, but the judge's planner has no such rule).
    Klipper,
    /// Marlin 2 with each valve on a fan output: `M106 P<fan> S255` opens, `M107 P<fan>`
    /// closes, between the moves, exactly where the executor switched. Built with
    /// `LASER_SYNCHRONOUS_M106_M107`, Marlin queues a fan change as a sync block among the
    /// moves: the stepper interrupt sets the fans when it reaches that block, and the
    /// planner's look-ahead passes over it, so the valve switches where the head is,
    /// without stopping it (the same timing as `Plain`). Assumes that option, `FAN_COUNT`
    /// covering the fan indices used (0 to 7), no auto-fan or controller-fan on those
    /// outputs, and a fan PWM whose period is short against the valves' dead time (S255 is
    /// full on, so kick-start and minimum PWM do not matter). Without the option Marlin
    /// still sets fans from the block it is executing, but in its idle loop, milliseconds
    /// late: use `MarlinM42` there.
    Marlin,
    /// Marlin's `M42`, for builds without synchronous fans: `M400` then
    /// `M42 P<pin> S<0|255>` for every valve change. Marlin runs `M42` when it reads the
    /// line, ahead of the moves still queued, so `M400` holds it until the head arrives:
    /// the head comes to a full stop at every valve change made while moving (what that
    /// costs shows in `gcode_judge`'s figures). Assumes the pins are free (not claimed by a
    /// heater, fan or endstop).
    MarlinM42,
}

impl Kind {
    /// Every dialect, in the order `--help` lists them.
    pub const ALL: [Kind; 5] = [
        Kind::Plain,
        Kind::RepRap,
        Kind::Klipper,
        Kind::Marlin,
        Kind::MarlinM42,
    ];
    /// Name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Plain => "plain",
            Kind::RepRap => "reprap",
            Kind::Klipper => "klipper",
            Kind::Marlin => "marlin",
            Kind::MarlinM42 => "marlin-m42",
        }
    }
    /// The dialect the command line's `name` spells, if any.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl Dialect {
    /// A dialect with ports 0, 1, ..
    pub fn new(kind: Kind) -> Self {
        Dialect {
            kind,
            ports: Vec::new(),
        }
    }
    /// The port (or pin) number of inlet `i`.
    pub fn port(&self, i: usize) -> u32 {
        self.ports.get(i).copied().unwrap_or(i as u32)
    }
    /// Name as the command line spells it.
    pub fn name(&self) -> &'static str {
        self.kind.name()
    }
    /// The highest port number the dialect can address: Marlin has at most eight fans.
    pub fn max_port(kind: Kind) -> u32 {
        match kind {
            Kind::Marlin => 7,
            _ => 65_535,
        }
    }
}

/// Prefix of the `output_pin` names the `klipper` dialect switches (`dollop_valve0`, ..).
pub const KLIPPER_PIN: &str = "dollop_valve";

struct Writer<'a> {
    out: String,
    pos: [f64; 3],
    f: f64,
    stats: GcodeStats,
    dialect: &'a Dialect,
    inlets: usize,
    valves: u32,
    last_opened: Option<u32>,
    /// Dwell time not yet written, s (whole milliseconds are written, the rest goes on the
    /// next print move's time).
    dwell_carry_s: f64,
}

impl Writer<'_> {
    fn move_to(&mut self, to: [f64; 3], v: f64, travel: bool, p_word: Option<u32>) {
        // 0.1 um: short pieces keep their direction (see `gcode_ramps`).
        let r = |v: f64| (v * 10_000.0).round() / 10_000.0;
        let to = to.map(r);
        if to == self.pos && p_word.is_none() {
            return;
        }
        self.flush_dwell();
        // What the whole-millisecond dwell left out (or added) goes on this move's time,
        // so the head stays on the executor's clock.
        let mut v = v;
        if !travel {
            let len = ((to[0] - self.pos[0]).powi(2)
                + (to[1] - self.pos[1]).powi(2)
                + (to[2] - self.pos[2]).powi(2))
            .sqrt();
            if len > 0.0 && v > 0.0 {
                let t = len / v;
                v = len / (t + self.dwell_carry_s).max(0.5 * t);
            }
        }
        self.dwell_carry_s = 0.0;
        self.out.push_str(if travel { "G0" } else { "G1" });
        for (a, name) in ["X", "Y", "Z"].iter().enumerate() {
            if to[a] != self.pos[a] {
                self.out.push(' ');
                self.out.push_str(name);
                num(&mut self.out, to[a], 4);
            }
        }
        let f = (v * 60.0 * 10.0).round() / 10.0;
        if f != self.f {
            self.out.push_str(" F");
            num(&mut self.out, f, 1);
            self.f = f;
        }
        if let Some(bits) = p_word {
            let _ = write!(self.out, " P{bits}");
        }
        self.out.push('\n');
        self.pos = to;
        if !travel {
            self.stats.print_moves += 1;
        }
    }

    /// Counts a switch when `opened` (the valves just opened) names another inlet than the
    /// last one opened.
    fn count_switch(&mut self, opened: u32) {
        if opened != 0 {
            let inlet = opened.trailing_zeros();
            if self.last_opened.is_some_and(|l| l != inlet) {
                self.stats.switches += 1;
            }
            self.last_opened = Some(inlet);
        }
    }

    /// The dialect's output command for each changed valve, closes first.
    fn m42(&mut self, mask: u32) {
        let (on, off) = match self.dialect.kind {
            Kind::MarlinM42 => (255, 0),
            _ => (1, 0),
        };
        let changed = mask ^ self.valves;
        for opening in [false, true] {
            for i in 0..self.inlets {
                if changed & (1 << i) != 0 && (mask & (1 << i) != 0) == opening {
                    let port = self.dialect.port(i);
                    let s = if opening { on } else { off };
                    let _ = match self.dialect.kind {
                        Kind::Klipper => {
                            writeln!(self.out, "SET_PIN PIN={KLIPPER_PIN}{port} VALUE={s}")
                        }
                        Kind::Marlin if opening => writeln!(self.out, "M106 P{port} S255"),
                        Kind::Marlin => writeln!(self.out, "M107 P{port}"),
                        _ => writeln!(self.out, "M42 P{port} S{s}"),
                    };
                }
            }
        }
        self.valves = mask;
    }

    fn dwell(&mut self, s: f64) {
        self.dwell_carry_s += s;
    }

    /// Writes the dwell to the nearest millisecond (firmwares differ on fractions); the
    /// remainder, within half a millisecond either way, stays in `dwell_carry_s`.
    fn flush_dwell(&mut self) {
        let ms = (self.dwell_carry_s * 1e3).round();
        if ms >= 1.0 {
            let _ = writeln!(self.out, "G4 P{ms}");
            self.dwell_carry_s -= ms * 1e-3;
        }
    }
}

/// What a print host reads besides the moves: the user's start and end G-code (written
/// as given), and whether to write progress (`M73`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HostText {
    /// Write `M73 P<percent> R<minutes left>` at each whole percent of the run's time
    /// (`dollop slice` does; off by default so that a bare export is moves only).
    pub progress: bool,
    /// Written after the header comments, before the first move (homing, heating...).
    pub start: Option<String>,
    /// Written after the last move and the valves' closing, before `; end of job`.
    pub end: Option<String>,
}

/// The run's duration at the steps' own speeds, s (what the executor took; the firmware's
/// acceleration, fitted in by `gcode_ramps`, is already in the steps).
pub fn estimated_seconds(steps: &[Step], start: [f64; 3]) -> f64 {
    let mut at = start;
    let mut t = 0.0;
    for st in steps {
        match *st {
            Step::Move { to, v, .. } => {
                let len = (0..3).map(|a| (to[a] - at[a]).powi(2)).sum::<f64>().sqrt();
                if v > 0.0 {
                    t += len / v;
                }
                at = to;
            }
            Step::Dwell(d) => t += d.max(0.0),
            Step::Valves(_) => {}
        }
    }
    t
}

/// `1h 2m 3s`, as PrusaSlicer writes its estimate (hosts parse this form).
fn hms(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    let (h, m, sec) = (s / 3600, (s / 60) % 60, s % 60);
    match (h, m) {
        (0, 0) => format!("{sec}s"),
        (0, _) => format!("{m}m {sec}s"),
        _ => format!("{h}h {m}m {sec}s"),
    }
}

/// Heights of the layers that hold beads (moves with a valve open), mm (rounded as
/// written), in order.
fn layer_heights(steps: &[Step]) -> Vec<f64> {
    let round = |v: f64| (v * 10_000.0).round() / 10_000.0;
    let mut open = 0u32;
    let mut zs: Vec<f64> = steps
        .iter()
        .filter_map(|st| match *st {
            Step::Valves(mask) => {
                open = mask;
                None
            }
            Step::Move {
                to, travel: false, ..
            } if open != 0 => Some(round(to[2])),
            _ => None,
        })
        .collect();
    zs.sort_by(f64::total_cmp);
    zs.dedup();
    zs
}

/// Writes `steps` (head starting at `start`, mm) in `dialect`, with the header, layer
/// comments and progress print hosts read (`; estimated printing time`, `;TIME:`,
/// `;LAYER_COUNT:`, `;LAYER:n`, `M73 P R`) and the user's start and end G-code.
pub fn write(
    steps: &[Step],
    start: [f64; 3],
    config: &Config,
    material_names: &[String],
    dialect: &Dialect,
    host: &HostText,
) -> (String, GcodeStats) {
    let mut w = Writer {
        out: String::with_capacity(steps.len() * 24),
        pos: [f64::NAN; 3],
        f: f64::NAN,
        stats: GcodeStats::default(),
        dialect,
        inlets: config.inlets.len(),
        valves: 0,
        last_opened: None,
        dwell_carry_s: 0.0,
    };
    let total_s = estimated_seconds(steps, start);
    let layers = layer_heights(steps);
    w.header(total_s, layers.len(), material_names, host);
    w.go_to_start(config, start, !layers.is_empty());
    let mut walk = Walk {
        pending: None,
        counted: 0,
        exact: start,
        elapsed: 0.0,
        percent: 0,
        total_s,
        progress: host.progress,
        layers: &layers,
        next_layer: 1,
    };
    if host.progress {
        let _ = writeln!(w.out, "M73 P0 R{}", (total_s / 60.0).ceil() as u64);
    }
    for st in steps {
        walk.progress(&mut w);
        walk.clock(&mut w, st);
        walk.write(&mut w, st);
    }
    if let Some(mask) = walk.pending.take() {
        w.m42_at_rest(mask);
    }
    w.end(host)
}

impl Writer<'_> {
    /// The header comments (dialect, estimated time, layer count, each valve's output),
    /// the user's start G-code, units and absolute positioning, and RepRapFirmware's port
    /// map.
    fn header(&mut self, total_s: f64, layers: usize, material_names: &[String], host: &HostText) {
        let dialect = self.dialect;
        let _ = writeln!(
            self.out,
            "; dollop G-code ({} dialect), sampled from the executor's run: moves of at most 0.25 mm at the speeds the executor used, valves where it switched them, dwells where it stood",
            dialect.name()
        );
        // PrusaSlicer's and Cura's forms, which OctoPrint, Moonraker and DWC read.
        let _ = writeln!(
            self.out,
            "; estimated printing time (normal mode) = {}\n;TIME:{}\n;LAYER_COUNT:{}",
            hms(total_s),
            total_s.round() as u64,
            layers
        );
        for i in 0..self.inlets {
            let name = material_names.get(i).map_or("", |s| s.as_str());
            let port = dialect.port(i);
            let what = match dialect.kind {
                Kind::Marlin => format!(
                    "fan P{port} (M106/M107, queued with the moves: needs LASER_SYNCHRONOUS_M106_M107)"
                ),
                Kind::MarlinM42 => format!("board pin {port}"),
                Kind::Klipper => format!("[output_pin {KLIPPER_PIN}{port}]"),
                _ => format!("GPIO port {port}"),
            };
            let _ = writeln!(self.out, "; valve of inlet {i} ({name}) is {what}");
        }
        if let Some(text) = &host.start {
            self.out.push_str("; start G-code (the user's)\n");
            self.out.push_str(text.trim_end());
            self.out.push_str("\n; end of start G-code\n");
        }
        self.out.push_str("G21\nG90\n");
        if dialect.kind == Kind::RepRap {
            self.out.push_str("M670 P");
            for i in 0..self.inlets {
                if i > 0 {
                    self.out.push(':');
                }
                let _ = write!(self.out, "{}", dialect.port(i));
            }
            self.out.push_str(" T0\n");
        }
    }

    /// Every valve closed, whatever the firmware had, then to the start: Z first, then X
    /// and Y, at the travel speed (Z's top speed for Z). The first layer (if `layered`)
    /// begins with this move.
    fn go_to_start(&mut self, config: &Config, start: [f64; 3], layered: bool) {
        self.valves = ((1u64 << self.inlets.min(32)) - 1) as u32;
        self.m42(0);
        let z_f = config.motion.max_speed_mm_s[2] as f64;
        let travel_f = config.motion.travel_speed_mm_s as f64;
        let mut zs = [f64::NAN, f64::NAN, start[2]];
        // The first layer begins with the move to the start; the others where Z reaches them.
        if layered {
            self.out.push_str(";LAYER:0\n");
        }
        self.out.push_str("G0 Z");
        num(&mut self.out, start[2], 4);
        self.out.push_str(" F");
        num(&mut self.out, (z_f * 600.0).round() / 10.0, 1);
        self.out.push('\n');
        zs[2] = (start[2] * 10_000.0).round() / 10_000.0;
        self.pos = zs;
        self.f = (z_f * 600.0).round() / 10.0;
        self.move_to(start, travel_f, true, None);
    }

    /// A valve change made while the head stands: `M400` (nothing moves, so it costs no
    /// time), then the change.
    fn m42_at_rest(&mut self, mask: u32) {
        self.flush_dwell();
        self.out.push_str("M400\n");
        self.m42(mask);
    }

    /// The last dwell, every valve closed, the user's end G-code and `; end of job`.
    fn end(mut self, host: &HostText) -> (String, GcodeStats) {
        self.flush_dwell();
        if self.valves != 0 {
            self.m42(0);
        }
        self.out.push_str("M400\n");
        if host.progress {
            self.out.push_str("M73 P100 R0\n");
        }
        if let Some(text) = &host.end {
            self.out.push_str("; end G-code (the user's)\n");
            self.out.push_str(text.trim_end());
            self.out.push('\n');
        }
        self.out.push_str("; end of job\n");
        self.stats.bytes = self.out.len();
        (self.out, self.stats)
    }
}

/// The walk through the steps: where the run is in its time and its layers, where the
/// steps have the head, and what waits to be written.
struct Walk<'a> {
    /// RepRapFirmware: a valve change waiting for the next move's `P` word.
    pending: Option<u32>,
    /// The valves as the steps last set them (switches are counted from them).
    counted: u32,
    /// The head where the steps put it, unrounded.
    exact: [f64; 3],
    /// The run's time so far, s.
    elapsed: f64,
    /// The last progress written, %.
    percent: u32,
    total_s: f64,
    /// Write progress (`M73`).
    progress: bool,
    /// Heights of the layers that hold beads, mm.
    layers: &'a [f64],
    /// The next layer to mark.
    next_layer: usize,
}

impl Walk<'_> {
    /// Progress by the run's time: M73 at each whole percent, R in minutes left.
    fn progress(&mut self, w: &mut Writer) {
        if self.progress && self.total_s > 0.0 {
            let p = ((self.elapsed / self.total_s) * 100.0).floor().min(99.0) as u32;
            if p > self.percent {
                self.percent = p;
                let left = ((self.total_s - self.elapsed) / 60.0).ceil().max(0.0) as u64;
                let _ = writeln!(w.out, "M73 P{p} R{left}");
            }
        }
    }

    /// Marks a layer where a move reaches its height, and counts the step's time.
    fn clock(&mut self, w: &mut Writer, st: &Step) {
        let round = |v: f64| (v * 10_000.0).round() / 10_000.0;
        match *st {
            Step::Move { to, v, .. } => {
                if let Some(&z) = self.layers.get(self.next_layer) {
                    if round(to[2]) >= z {
                        w.flush_dwell();
                        let _ = writeln!(w.out, ";LAYER:{}", self.next_layer);
                        self.next_layer += 1;
                    }
                }
                let len = (0..3)
                    .map(|a| (to[a] - self.exact[a]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                if v > 0.0 {
                    self.elapsed += len / v;
                }
            }
            Step::Dwell(d) => self.elapsed += d.max(0.0),
            Step::Valves(_) => {}
        }
    }

    /// Writes the step in the dialect's words.
    fn write(&mut self, w: &mut Writer, st: &Step) {
        let round = |v: f64| (v * 10_000.0).round() / 10_000.0;
        match *st {
            Step::Move { to, v, travel } => {
                let exact = self.exact;
                let len = ((to[0] - exact[0]).powi(2)
                    + (to[1] - exact[1]).powi(2)
                    + (to[2] - exact[2]).powi(2))
                .sqrt();
                self.exact = to;
                if to.map(round) == w.pos {
                    // Shorter than the written precision: the executor's time there is
                    // standing time.
                    if !travel && v > 0.0 {
                        w.dwell(len / v);
                    }
                    return;
                }
                let p = self.pending.take();
                w.move_to(to, v, travel, p);
                if let Some(mask) = p {
                    w.valves = mask;
                }
            }
            Step::Valves(mask) => {
                let opened = mask & !self.counted;
                self.counted = mask;
                w.count_switch(opened);
                match w.dialect.kind {
                    Kind::RepRap => self.pending = Some(mask),
                    Kind::Plain | Kind::Klipper | Kind::Marlin => {
                        w.flush_dwell();
                        w.m42(mask);
                    }
                    Kind::MarlinM42 => w.m42_at_rest(mask),
                }
            }
            Step::Dwell(s) => {
                // The head stands: a waiting change is made now, as it stands.
                if let Some(mask) = self.pending.take() {
                    w.m42_at_rest(mask);
                }
                w.dwell(s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dialect_is_found_by_its_name() {
        for k in Kind::ALL {
            assert_eq!(Kind::from_name(k.name()), Some(k));
        }
        assert_eq!(Kind::from_name("marlin2"), None);
    }

    fn config() -> Config {
        toml::from_str(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../configs/seed-paper-valves.toml"
            ))
            .unwrap(),
        )
        .unwrap()
    }

    fn steps() -> Vec<Step> {
        vec![
            Step::Valves(1),
            Step::Dwell(0.0104),
            Step::Move {
                to: [1.0, 0.0, 0.6],
                v: 10.0,
                travel: false,
            },
            Step::Valves(2),
            Step::Move {
                to: [1.25, 0.0, 0.6],
                v: 12.5,
                travel: false,
            },
            Step::Valves(0),
            Step::Dwell(0.0301),
            Step::Move {
                to: [5.0, 5.0, 0.6],
                v: 80.0,
                travel: true,
            },
        ]
    }

    #[test]
    fn each_dialect_writes_its_words() {
        let c = config();
        let (plain, st) = write(
            &steps(),
            [0.0, 0.0, 0.6],
            &c,
            &[],
            &Dialect::default(),
            &HostText::default(),
        );
        assert_eq!(st.switches, 1);
        assert_eq!(st.print_moves, 2);
        // The 0.4 ms the dwell leaves out goes on the next move: 1 mm in 0.1004 s.
        assert!(
            plain.contains("M42 P0 S1\nG4 P10\nG1 X1 F597.6\nM42 P0 S0\nM42 P1 S1\nG1 X1.25 F750\nM42 P1 S0\nG4 P30\nG0 X5 Y5 F4800\n"),
            "{plain}"
        );
        let rrf = Dialect {
            kind: Kind::RepRap,
            ports: vec![3, 4],
        };
        let (g, _) = write(
            &steps(),
            [0.0, 0.0, 0.6],
            &c,
            &[],
            &rrf,
            &HostText::default(),
        );
        assert!(g.contains("M670 P3:4 T0\n"), "{g}");
        // Standing: M400 and M42; moving: the bitmap on the next move.
        assert!(
            g.contains(
                "M400\nM42 P3 S1\nG4 P10\nG1 X1 F597.6\nG1 X1.25 F750 P2\nM400\nM42 P4 S0\n"
            ),
            "{g}"
        );
        let (g, _) = write(
            &steps(),
            [0.0, 0.0, 0.6],
            &c,
            &[],
            &Dialect::new(Kind::Klipper),
            &HostText::default(),
        );
        assert!(
            g.contains("SET_PIN PIN=dollop_valve0 VALUE=1\nG4 P10\nG1 X1 F597.6\nSET_PIN PIN=dollop_valve0 VALUE=0\nSET_PIN PIN=dollop_valve1 VALUE=1\nG1 X1.25 F750\n"),
            "{g}"
        );
        assert!(!g.contains("M42"), "{g}");
        let (g, _) = write(
            &steps(),
            [0.0, 0.0, 0.6],
            &c,
            &[],
            &Dialect::new(Kind::MarlinM42),
            &HostText::default(),
        );
        assert!(
            g.contains("G1 X1 F597.6\nM400\nM42 P0 S0\nM42 P1 S255\nG1 X1.25"),
            "{g}"
        );
        // Synchronous fans: in the move sequence, no M400 between moves.
        let (g, _) = write(
            &steps(),
            [0.0, 0.0, 0.6],
            &c,
            &[],
            &Dialect::new(Kind::Marlin),
            &HostText::default(),
        );
        assert!(
            g.contains("M106 P0 S255\nG4 P10\nG1 X1 F597.6\nM107 P0\nM106 P1 S255\nG1 X1.25 F750\nM107 P1\nG4 P30\n"),
            "{g}"
        );
        assert!(!g.contains("M42") && g.contains("fan P1 (M106/M107"), "{g}");
    }
}
