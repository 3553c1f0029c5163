//! Designs to job commands: placement on the plate, the priming bead, boustrophedon rows
//! chained into continuous beads (rows joined by short connectors where they line up,
//! travel with the valves closed elsewhere), same-material collinear segments merged,
//! layers stacked. Material boundaries stay exactly where the design has them: the
//! firmware keys valves to volume, so no advance is applied here. Encoding is `job_file`'s.

use super::design::{Design, Layer, Run, TOUCH_MM};
use super::error::{OptionError, SliceError, SliceOption};
use dollop::config::Config;
use dollop::{Command, Machine};

/// How to lay out the toolpath.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathOptions {
    /// Lower-left corner of the design on the plate, mm. Default: the design and its
    /// priming bead centred in the travel area.
    pub origin_mm: Option<[f64; 2]>,
    /// Priming bead length, mm. Default: 2.5 transit lengths, at least 5 mm.
    pub prime_mm: Option<f64>,
    /// Rows whose ends are at most this far apart (mm) are joined by a printed connector
    /// instead of a travel; negative: never. Default: two line pitches.
    pub connect_mm: Option<f64>,
}

/// Counts describing a toolpath.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathStats {
    /// Layers with something printed.
    pub layers: usize,
    /// Continuous beads (including the priming bead).
    pub beads: usize,
    /// `Print` commands.
    pub print_segments: usize,
    /// `Travel` and `Layer` commands.
    pub travels: usize,
    /// Printed length, mm.
    pub print_mm: f64,
    /// Travelled length (XY and Z), mm.
    pub travel_mm: f64,
    /// Priming bead, mm.
    pub prime_mm: f64,
    /// Material changes along the printed path.
    pub switches: usize,
}

/// A planned job before encoding.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedPath {
    /// Commands, ending with `End`.
    pub commands: Vec<Command>,
    /// Where the head stands when the job begins (the priming bead's start), um.
    pub start_um: [i32; 3],
    /// Material the channel is primed with (the design's first).
    pub initial_material: u8,
    /// Counts.
    pub stats: PathStats,
}

/// The bead length (mm) between a valve and the plate: channel plus hanging filament
/// volume over the bead section. Boundaries closer than this to the job's start cannot be
/// placed, which is why the priming bead comes first.
pub fn transit_mm(machine: &Machine<f64, 4>) -> f64 {
    machine.v_transit().mm3::<f64>() / machine.bead_area
}

/// Millimetres to the jobs' integer micrometres (the one conversion, `dollop_sim::um`).
pub use dollop_sim::um;

/// Builds commands as integer micrometres from absolute targets, so rounding never drifts.
struct Emitter {
    cmds: Vec<Command>,
    at: [i32; 3],
    stats: PathStats,
    in_bead: bool,
}

impl Emitter {
    fn print_to(&mut self, x: f64, y: f64, material: u8) {
        let to = [um(x), um(y)];
        let (dx, dy) = (to[0] - self.at[0], to[1] - self.at[1]);
        if dx == 0 && dy == 0 {
            return;
        }
        if !self.in_bead {
            self.stats.beads += 1;
            self.in_bead = true;
        }
        self.at[0] = to[0];
        self.at[1] = to[1];
        self.stats.print_mm += ((dx as f64).powi(2) + (dy as f64).powi(2)).sqrt() * 1e-3;
        if dollop::command::extend_last_print(&mut self.cmds, dx, dy, material) {
            return;
        }
        self.cmds.push(Command::Print { dx, dy, material });
        self.stats.print_segments += 1;
    }

    fn travel_to(&mut self, x: f64, y: f64, z: f64) {
        let to = [um(x), um(y), um(z)];
        self.in_bead = false;
        if to == self.at && !self.cmds.is_empty() {
            return;
        }
        let d: f64 = (0..3)
            .map(|a| ((to[a] - self.at[a]) as f64).powi(2))
            .sum::<f64>()
            .sqrt();
        self.stats.travel_mm += d * 1e-3;
        self.stats.travels += 1;
        self.at = to;
        self.cmds.push(Command::Travel {
            x: to[0],
            y: to[1],
            z: to[2],
        });
    }

    fn layer(&mut self, z: f64) {
        let z = um(z);
        self.in_bead = false;
        if z == self.at[2] {
            return;
        }
        self.stats.travel_mm += (z - self.at[2]).abs() as f64 * 1e-3;
        self.stats.travels += 1;
        self.at[2] = z;
        self.cmds.push(Command::Layer { z });
    }
}

/// One row's stretch of touching runs: printed as one piece.
#[derive(Clone, Copy, Debug)]
struct Span {
    a: usize,
    b: usize,
    x0: f64,
    x1: f64,
}

/// Where the job sits on the plate: the design's lower-left corner, the priming bead and
/// the layers' heights.
#[derive(Clone, Copy, Debug)]
struct Placement {
    /// The design's lower-left corner, mm.
    ox: f64,
    oy: f64,
    /// The design's height, mm.
    h: f64,
    /// Row pitch, mm.
    pitch: f64,
    /// Priming bead: length, its row and its left end, mm.
    prime: f64,
    prime_y: f64,
    px0: f64,
    /// First layer's nozzle height and layer height, mm.
    z_first: f64,
    layer_h: f64,
}

impl Placement {
    /// Height of layer `k`, mm.
    fn z(&self, k: usize) -> f64 {
        self.z_first.max(self.layer_h * 0.5) + k as f64 * self.layer_h
    }
}

/// Places `design` on `machine`: refuses a priming bead shorter than twice the transit
/// and a job larger than the travel.
fn place(
    design: &Design,
    config: &Config,
    machine: &Machine<f64, 4>,
    opts: &PathOptions,
) -> Result<Placement, SliceError> {
    let pitch = design.pitch_mm;
    let [w, h] = design.size_mm;
    let layer_h = config.channel.layer_height_mm as f64;
    let z_first = config.channel.nozzle_height_mm as f64;
    let lo = machine.motion.min_mm;
    let hi = machine.motion.max_mm;
    let transit = transit_mm(machine);
    let prime = match opts.prime_mm {
        Some(p) if p.is_finite() && p >= 2.0 * transit => p,
        Some(p) => {
            return Err(SliceError::BadOption(OptionError::new(
                SliceOption::Prime,
                Some(p.to_string()),
                format!("is shorter than twice the {transit:.2} mm of bead between the valves and the plate"),
            )))
        }
        None => (2.5 * transit).ceil().max(5.0),
    };
    let gap = (3.0 * pitch).max(2.0);
    let half = pitch / 2.0;
    let mut at = Placement {
        ox: 0.0,
        oy: 0.0,
        h,
        pitch,
        prime,
        prime_y: 0.0,
        px0: 0.0,
        z_first,
        layer_h,
    };
    let top_z = at.z(design.layers.len().saturating_sub(1));
    let footprint = [w.max(prime) + pitch, h + gap + pitch, top_z];
    let span = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    if footprint[0] > span[0] || footprint[1] > span[1] || top_z > hi[2] {
        return Err(SliceError::TooLarge {
            what: design.name.clone(),
            size: footprint,
            travel: span,
        });
    }
    // Placement: the design's lower-left corner, and the priming bead's row below it (or
    // above it when an explicit origin leaves no room below).
    (at.ox, at.oy) = match opts.origin_mm {
        Some([x, y]) => (x, y),
        None => (
            (lo[0] + hi[0] - w) / 2.0,
            (lo[1] + hi[1] - (h + gap)) / 2.0 + gap,
        ),
    };
    at.prime_y = if at.oy - gap - half >= lo[1] {
        at.oy - gap
    } else {
        at.oy + h + gap
    };
    // The bead runs left to right and ends below the design's first row start, so the
    // first travel is short.
    let first_x = first_start(design).map_or(at.ox, |x| x + at.ox);
    at.px0 = (first_x - prime).clamp(lo[0] + half, (hi[0] - half - prime).max(lo[0] + half));
    Ok(at)
}

/// Plans the job for `design` on `machine` (validated from `config`).
pub fn plan(
    design: &Design,
    config: &Config,
    machine: &Machine<f64, 4>,
    opts: &PathOptions,
) -> Result<PlannedPath, SliceError> {
    let at = place(design, config, machine, opts)?;
    let mut e = Emitter {
        cmds: Vec::new(),
        at: [0; 3],
        stats: PathStats::default(),
        in_bead: false,
    };
    let connect = opts.connect_mm.unwrap_or(2.0 * at.pitch);
    if design.is_empty() {
        return Err(SliceError::EmptyDesign {
            what: design.name.clone(),
            why: "no layer prints anything".into(),
        });
    }
    // Primed with material 0 for now; set to the design's first material below.
    let initial = 0;
    let start = [um(at.px0), um(at.prime_y), um(at.z(0))];
    e.at = start;
    e.travel_to(at.px0, at.prime_y, at.z(0));
    e.print_to(at.px0 + at.prime, at.prime_y, initial);
    e.stats.prime_mm = at.prime;

    let mut rows = Rows::default();
    for (k, layer) in design.layers.iter().enumerate() {
        if layer.is_empty() {
            continue;
        }
        e.stats.layers += 1;
        let z = at.z(k);
        if k > 0 || e.at[2] != um(z) {
            e.layer(z);
        }
        rows.print_layer(&mut e, layer, z, &at, connect);
    }
    let initial = finish(&mut e, machine.motion.max_mm[2], initial);
    let tp = PlannedPath {
        commands: e.cmds,
        start_um: start,
        initial_material: initial,
        stats: e.stats,
    };
    check_travel(&tp, machine, &design.name)?;
    Ok(tp)
}

/// A layer's rows as spans of touching runs, kept across layers to reuse their memory.
#[derive(Default)]
struct Rows {
    spans: Vec<Span>,
    /// Per row in printing order: its spans' range in `spans`.
    row_spans: Vec<(usize, usize)>,
    /// Per span: printed already.
    done: Vec<bool>,
}

impl Rows {
    /// Prints `layer` at height `z`: beads started at the lowest unfinished row's span
    /// nearest the head, each continued into the next row while a span there starts
    /// within `connect`.
    fn print_layer(
        &mut self,
        e: &mut Emitter,
        layer: &Layer,
        z: f64,
        at: &Placement,
        connect: f64,
    ) {
        let Rows {
            spans,
            row_spans,
            done,
        } = self;
        let (ox, oy, pitch) = (at.ox, at.oy, at.pitch);
        spans.clear();
        row_spans.clear();
        // Rows are taken in order from the end nearer the head, so a layer starts where
        // the last one ended instead of travelling back across it.
        let rows = layer.rows();
        let head_y = e.at[1] as f64 * 1e-3;
        let top_down = rows > 1 && (head_y - (oy + at.h)).abs() < (head_y - oy).abs();
        let actual = |i: usize| if top_down { rows - 1 - i } else { i };
        for i in 0..rows {
            let r = actual(i);
            let first = spans.len();
            split_spans(layer.row(r), spans);
            row_spans.push((first, spans.len()));
        }
        done.clear();
        done.resize(spans.len(), false);
        let mut low_row = 0;
        let y_of = |i: usize| oy + (actual(i) as f64 + 0.5) * pitch;
        loop {
            while low_row < row_spans.len()
                && (row_spans[low_row].0..row_spans[low_row].1).all(|i| done[i])
            {
                low_row += 1;
            }
            if low_row == row_spans.len() {
                break;
            }
            // Start a bead at the unvisited span of the lowest row nearest the head.
            let here = [e.at[0] as f64 * 1e-3, e.at[1] as f64 * 1e-3];
            let (s0, s1) = row_spans[low_row];
            let mut best: Option<(f64, usize, bool)> = None;
            for i in (s0..s1).filter(|&i| !done[i]) {
                for forward in [true, false] {
                    let x = if forward { spans[i].x0 } else { spans[i].x1 } + ox;
                    let d = (x - here[0]).hypot(y_of(low_row) - here[1]);
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, i, forward));
                    }
                }
            }
            let Some((_, mut i, mut forward)) = best else {
                break;
            };
            let mut r = low_row;
            let sx = if forward { spans[i].x0 } else { spans[i].x1 } + ox;
            e.travel_to(sx, y_of(r), z);
            loop {
                done[i] = true;
                let runs = &layer.row(actual(r))[spans[i].a..spans[i].b];
                emit_span(e, runs, forward, ox, y_of(r));
                let end_x = if forward { spans[i].x1 } else { spans[i].x0 };
                // Continue into the next row when a span there starts close by.
                let Some(&(n0, n1)) = row_spans.get(r + 1) else {
                    break;
                };
                let mut next: Option<(f64, usize)> = None;
                for j in (n0..n1).filter(|&j| !done[j]) {
                    let start_x = if forward { spans[j].x1 } else { spans[j].x0 };
                    let d = (start_x - end_x).abs();
                    if d <= connect && next.is_none_or(|n| d < n.0) {
                        next = Some((d, j));
                    }
                }
                let Some((_, j)) = next else {
                    break;
                };
                let last = runs[if forward { runs.len() - 1 } else { 0 }].material;
                forward = !forward;
                let start_x = if forward { spans[j].x0 } else { spans[j].x1 };
                e.print_to(start_x + ox, y_of(r + 1), last);
                i = j;
                r += 1;
            }
        }
    }
}

/// Ends the job: lifts clear of the print (up to 5 mm, as far as `top_mm` allows),
/// primes with the design's first material (else `initial`), which it returns, and
/// counts the switches.
fn finish(e: &mut Emitter, top_mm: f64, initial: u8) -> u8 {
    // Lift clear of the print at the end, as far as the travel allows (up to 5 mm).
    let lift = (top_mm - e.at[2] as f64 * 1e-3).min(5.0);
    if lift > 0.01 {
        e.layer(e.at[2] as f64 * 1e-3 + lift);
    }
    e.cmds.push(Command::End);
    // The channel is primed with, and the priming bead prints, the design's first material.
    let initial = e.cmds[2..]
        .iter()
        .find_map(|c| match c {
            Command::Print { material, .. } => Some(*material),
            _ => None,
        })
        .unwrap_or(initial);
    if let Some(Command::Print { material, .. }) = e.cmds.get_mut(1) {
        *material = initial;
    }
    let mut last = initial;
    for c in &e.cmds {
        if let Command::Print { material, .. } = *c {
            e.stats.switches += usize::from(material != last);
            last = material;
        }
    }
    initial
}

/// Left end of the first run of the lowest printed row of the first printed layer.
fn first_start(design: &Design) -> Option<f64> {
    design
        .layers
        .iter()
        .find(|l| !l.is_empty())
        .and_then(|l| (0..l.rows()).find_map(|r| l.row(r).first().map(|x| x.x0)))
}

/// Splits a row's runs into spans of touching runs.
fn split_spans(row: &[Run], out: &mut Vec<Span>) {
    let mut a = 0;
    for b in 1..=row.len() {
        if b == row.len() || row[b].x0 - row[b - 1].x1 > TOUCH_MM {
            if b > a {
                out.push(Span {
                    a,
                    b,
                    x0: row[a].x0,
                    x1: row[b - 1].x1,
                });
            }
            a = b;
        }
    }
}

fn emit_span(e: &mut Emitter, runs: &[Run], forward: bool, ox: f64, y: f64) {
    if forward {
        for r in runs {
            e.print_to(r.x1 + ox, y, r.material);
        }
    } else {
        for r in runs.iter().rev() {
            e.print_to(r.x0 + ox, y, r.material);
        }
    }
}

/// Refuses a job that leaves the travel limits anywhere (an explicit origin can do that).
fn check_travel(tp: &PlannedPath, machine: &Machine<f64, 4>, what: &str) -> Result<(), SliceError> {
    let (lo, hi) = super::job_file::bounds(&tp.commands, tp.start_um);
    let axes = ["X", "Y", "Z"];
    for a in 0..3 {
        let (l, h) = (lo[a] as f64 * 1e-3, hi[a] as f64 * 1e-3);
        let (min, max) = (machine.motion.min_mm[a], machine.motion.max_mm[a]);
        if l < min - 1e-9 || h > max + 1e-9 {
            return Err(SliceError::OutsideTravel {
                what: what.to_string(),
                axis: axes[a],
                lo: l,
                hi: h,
                min,
                max,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::design::Layer;
    use super::*;

    fn seed() -> Config {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/seed-paper.toml"
        ))
        .unwrap();
        toml::from_str(&text).unwrap()
    }

    fn square(material: impl Fn(usize, usize) -> u8, n: usize) -> Design {
        let mut l = Layer::new();
        for r in 0..n {
            let mut row: Vec<Run> = (0..n)
                .map(|c| Run {
                    x0: c as f64,
                    x1: c as f64 + 1.0,
                    material: material(r, c),
                })
                .collect();
            l.push_row(&mut row, 0.0);
        }
        Design {
            name: "sq".into(),
            size_mm: [n as f64, n as f64 * 0.8],
            pitch_mm: 0.8,
            layers: vec![l.clone(), l],
        }
    }

    #[test]
    fn a_filled_square_is_one_bead_per_layer_with_merged_rows() {
        let c = seed();
        let m = c.validate::<f64, 4>().unwrap();
        let tp = plan(&square(|_, _| 0, 10), &c, &m, &PathOptions::default()).unwrap();
        // Prime + one serpentine bead per layer.
        assert_eq!(tp.stats.beads, 3, "{:?}", tp.commands);
        // Each layer: 10 rows + 9 connectors, merged into 19 segments.
        assert_eq!(tp.stats.print_segments, 1 + 2 * 19);
        assert_eq!(tp.stats.switches, 0);
        assert!(matches!(tp.commands[0], Command::Travel { .. }));
        assert!(matches!(tp.commands.last(), Some(Command::End)));
        // The prime is at least twice the transit length.
        let Command::Print { dx, .. } = tp.commands[1] else {
            panic!()
        };
        assert!(dx as f64 * 1e-3 >= 2.0 * transit_mm(&m));
    }

    #[test]
    fn material_changes_split_rows_exactly_at_the_design_boundary() {
        let c = seed();
        let m = c.validate::<f64, 4>().unwrap();
        let tp = plan(
            &square(|_, col| u8::from(col >= 4), 10),
            &c,
            &m,
            &PathOptions::default(),
        )
        .unwrap();
        // First row: forward, 4 mm of material 0 then 6 of material 1.
        let prints: Vec<_> = tp
            .commands
            .iter()
            .filter_map(|c| match c {
                Command::Print { dx, dy, material } => Some((*dx, *dy, *material)),
                _ => None,
            })
            .collect();
        assert_eq!(prints[1], (4000, 0, 0));
        assert_eq!(prints[2], (6000, 0, 1));
        assert_eq!(tp.stats.switches, 1 + 2 * 10 - 1);
    }

    #[test]
    fn too_large_and_misplaced_designs_are_refused() {
        let c = seed();
        let m = c.validate::<f64, 4>().unwrap();
        let mut d = square(|_, _| 0, 10);
        d.size_mm = [300.0, 8.0];
        let e = plan(&d, &c, &m, &PathOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("travel limits allow 200.0"), "{e}");
        let d = square(|_, _| 0, 10);
        let o = PathOptions {
            origin_mm: Some([195.0, 50.0]),
            ..Default::default()
        };
        let e = plan(&d, &c, &m, &o).unwrap_err().to_string();
        assert!(e.contains("on X"), "{e}");
    }
}
