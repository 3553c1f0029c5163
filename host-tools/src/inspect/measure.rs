//! Measuring the classified photo against the design, in the design's frame: the design
//! painted as pixels, the pattern error (share of the design's area showing the wrong
//! material or none), each boundary's signed offset along its bead (a step fitted to the
//! materials sampled along the centre line), and the bead width across the path.

use super::classify::PLATE;
use super::design::{Bead, Plan};
use super::frame::DesignFrame;

/// Paints material `m` into `px` (frame pixels) where a bead of half-width `r_mm` covers
/// it: the strip across the path from `a` to `b` (mm), or with `disk` the disk about `a`.
/// Paste lands under the nozzle and stays, so a stretch of path paints only the strip
/// across it: a disk's front half would paint paste ahead of the nozzle.
pub fn stamp(
    px: &mut [u8],
    frame: &DesignFrame,
    a: [f64; 2],
    b: [f64; 2],
    r_mm: f64,
    m: u8,
    disk: bool,
) {
    let (w, h) = frame.size();
    let (qa, qb) = (frame.to_px(a), frame.to_px(b));
    let r = r_mm * frame.px_per_mm;
    let d = [qb[0] - qa[0], qb[1] - qa[1]];
    let len = d[0].hypot(d[1]);
    let u = if len > 0.0 {
        [d[0] / len, d[1] / len]
    } else {
        [1.0, 0.0]
    };
    let (x0, x1) = (qa[0].min(qb[0]) - r - 1.0, qa[0].max(qb[0]) + r + 1.0);
    let (y0, y1) = (qa[1].min(qb[1]) - r - 1.0, qa[1].max(qb[1]) + r + 1.0);
    for y in (y0.floor().max(0.0) as i64)..=(y1.ceil().min(h as f64 - 1.0) as i64) {
        for x in (x0.floor().max(0.0) as i64)..=(x1.ceil().min(w as f64 - 1.0) as i64) {
            let (rx, ry) = (x as f64 + 0.5 - qa[0], y as f64 + 0.5 - qa[1]);
            let inside = if disk {
                rx * rx + ry * ry <= r * r
            } else {
                let t = rx * u[0] + ry * u[1];
                // One pixel further than the stretch: on a curve the strips fan out and
                // would leave wedges of plate on the outer side; the next strip paints
                // over the extra pixel on a straight.
                (0.0..len + 1.0).contains(&t) && (rx * u[1] - ry * u[0]).abs() <= r
            };
            if inside {
                px[(y * w as i64 + x) as usize] = m;
            }
        }
    }
}

/// The design as frame pixels: the material whose bead covers each pixel, `PLATE` where
/// none does. Beads are `pitch` wide with round ends, painted as the nozzle lays them.
pub fn paint(plan: &Plan, frame: &DesignFrame) -> Vec<u8> {
    let (w, h) = frame.size();
    let mut img = vec![PLATE; (w * h) as usize];
    let r = plan.pitch / 2.0;
    let step = 0.5 / frame.px_per_mm;
    for b in &plan.beads {
        let len = b.length();
        let n = (len / step).ceil().max(1.0) as usize;
        let first = b.material_at(0.0);
        stamp(&mut img, frame, b.at(0.0).0, b.at(0.0).0, r, first, true);
        for i in 0..n {
            let (s0, s1) = (i as f64 * step, ((i + 1) as f64 * step).min(len));
            let m = b.material_at(0.5 * (s0 + s1));
            stamp(&mut img, frame, b.at(s0).0, b.at(s1).0, r, m, false);
        }
        let end = b.at(len).0;
        stamp(&mut img, frame, end, end, r, b.material_at(len), true);
    }
    img
}

/// Share of the design's printed pixels where the photo shows another material or the
/// plate.
pub fn pattern_error(design: &[u8], seen: &[u8]) -> f64 {
    let (mut n, mut wrong) = (0u64, 0u64);
    for (&d, &s) in design.iter().zip(seen) {
        if d != PLATE {
            n += 1;
            if s != d {
                wrong += 1;
            }
        }
    }
    wrong as f64 / n.max(1) as f64
}

/// The pattern error in its two parts: shares of the design's printed pixels showing
/// another material, and showing the plate.
pub fn pattern_error_parts(design: &[u8], seen: &[u8]) -> (f64, f64) {
    let (mut n, mut other, mut plate) = (0u64, 0u64, 0u64);
    for (&d, &s) in design.iter().zip(seen) {
        if d != PLATE {
            n += 1;
            other += u64::from(s != d && s != PLATE);
            plate += u64::from(s == PLATE);
        }
    }
    let n = n.max(1) as f64;
    (other as f64 / n, plate as f64 / n)
}

/// One boundary as the photo shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    /// Index in the plan's boundaries.
    pub index: usize,
    /// Landed minus design along the bead, mm (positive: late).
    pub offset: f64,
    /// Share of the samples the fitted step explains.
    pub fit: f64,
    /// Landed within a pitch of a turn, where the bead's direction is not the one at its
    /// design place: `drift` leaves it out.
    pub beside_turn: bool,
}

/// Half the bead's width on the short stretch between the turns at `a` and `b`, as the
/// photo shows it: from the stretch's middle out along the way the bead came in, to the
/// plate; between a quarter and a whole pitch.
pub fn half_width_between_turns(
    bead: &Bead,
    (a, b): (f64, f64),
    frame: &DesignFrame,
    seen: &[u8],
    pitch: f64,
) -> f64 {
    let (p, _) = bead.at(0.5 * (a + b));
    let (_, u) = bead.at(a - 0.5 * pitch);
    let step = 0.25 / frame.px_per_mm;
    let mut d = 0.0;
    while d < pitch {
        let q = [p[0] + u[0] * (d + step), p[1] + u[1] * (d + step)];
        if label_at(seen, frame, q) == PLATE {
            break;
        }
        d += step;
    }
    (d + 0.5 * step).clamp(0.25 * pitch, pitch)
}

/// Half-width at a turn, as a share of the pitch, over which a boundary landing on the
/// short stretch between two rows is not read (see `boundaries`). Measured on the test
/// photos: boundaries there were read within 0.05 mm of the plant's with the bead's half
/// width at the turn up to 0.65 pitch, and 0.11 to 0.14 mm off from 0.75 pitch (a channel
/// 20 % short: more flow, wider beads).
pub const MAX_TURN_HALF_WIDTH: f64 = 0.7;

/// The label seen at design point `p` (mm), `PLATE` outside the frame.
fn label_at(seen: &[u8], frame: &DesignFrame, p: [f64; 2]) -> u8 {
    let (w, h) = frame.size();
    let c = frame.to_px(p);
    let (x, y) = (c[0].floor(), c[1].floor());
    if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
        return PLATE;
    }
    seen[(y as u32 * w + x as u32) as usize]
}

/// Materials seen along the bead of `b` from `s0` to `s1` every `step` mm (three samples
/// across the bead, the majority counted).
fn along(
    plan: &Plan,
    frame: &DesignFrame,
    seen: &[u8],
    bead: usize,
    s0: f64,
    s1: f64,
    step: f64,
) -> Vec<(f64, u8)> {
    let bead = &plan.beads[bead];
    let across = plan.pitch * 0.2;
    let n = ((s1 - s0) / step).floor().max(0.0) as usize;
    (0..=n)
        .map(|i| {
            let s = s0 + i as f64 * step;
            let (p, u) = bead.at(s);
            let nn = [-u[1], u[0]];
            let l: [u8; 3] = std::array::from_fn(|k| {
                let o = (k as f64 - 1.0) * across;
                label_at(seen, frame, [p[0] + nn[0] * o, p[1] + nn[1] * o])
            });
            (s, if l[0] == l[2] { l[0] } else { l[1] })
        })
        .collect()
}

/// The step from `from` to `to` that best explains `labels`: (split position, share of
/// samples it explains). The middle of equally good splits.
fn step_fit(labels: &[(f64, u8)], from: u8, to: u8) -> Option<(f64, f64)> {
    let total = labels.len();
    if total < 4 {
        return None;
    }
    let mut bad_after: Vec<usize> = vec![0; total + 1];
    for i in (0..total).rev() {
        bad_after[i] = bad_after[i + 1] + usize::from(labels[i].1 != to);
    }
    let mut bad_before = 0usize;
    let mut best = (usize::MAX, 0usize, 0usize);
    for i in 0..=total {
        if i > 0 {
            bad_before += usize::from(labels[i - 1].1 != from);
        }
        let e = bad_before + bad_after[i];
        if e < best.0 {
            best = (e, i, i);
        } else if e == best.0 {
            best.2 = i;
        }
    }
    // A split at i lies between samples i-1 and i.
    let s_at = |i: usize| -> f64 {
        let i = i.clamp(1, total - 1);
        0.5 * (labels[i - 1].0 + labels[i].0)
    };
    Some((
        0.5 * (s_at(best.1) + s_at(best.2)),
        1.0 - best.0 as f64 / total as f64,
    ))
}

/// Largest shift of all boundaries of one switch direction searched for, mm.
pub const MAX_SHIFT_MM: f64 = 4.0;

/// Every boundary of `plan` located in `seen` (labels per frame pixel). Boundaries can
/// land further from the design than the design's own runs are long (a channel 20 %
/// longer than configured puts them a millimetre late), so first the shift of each
/// switch direction as a whole is found (the one under which the design's runs agree
/// best with the photo along the beads), then each boundary in a window about its
/// shifted place. A boundary whose best step explains less than 70 % of its samples, or
/// that lands on the short stretch between two rows where the bead is wider than
/// `MAX_TURN_HALF_WIDTH` allows, is not found (left out).
pub fn boundaries(plan: &Plan, frame: &DesignFrame, seen: &[u8]) -> Vec<Found> {
    let step = 0.5 / frame.px_per_mm;
    let mut kinds: Vec<(u8, u8)> = plan.boundaries.iter().map(|b| (b.from, b.to)).collect();
    kinds.sort_unstable();
    kinds.dedup();
    let mut shift = std::collections::HashMap::new();
    for &kind in &kinds {
        // Agreement of the photo with the design's step at s + d, summed over this kind's
        // boundaries, for d every 0.05 mm.
        let bs: Vec<_> = plan
            .boundaries
            .iter()
            .filter(|b| (b.from, b.to) == kind)
            .collect();
        let lines: Vec<(f64, Vec<(f64, u8)>)> = bs
            .iter()
            .map(|b| {
                let len = plan.beads[b.bead].length();
                let (lo, hi) = (
                    (b.s - MAX_SHIFT_MM - b.room.0).max(0.0),
                    (b.s + MAX_SHIFT_MM + b.room.1).min(len),
                );
                (b.s, along(plan, frame, seen, b.bead, lo, hi, 2.0 * step))
            })
            .collect();
        let mut best = (0.0f64, i64::MIN);
        let n = (MAX_SHIFT_MM / 0.05) as i64;
        for k in -n..=n {
            let d = k as f64 * 0.05;
            let mut score = 0i64;
            for ((s, l), b) in lines.iter().zip(&bs) {
                for &(x, m) in l {
                    let rel = x - s - d;
                    if rel < -b.room.0 || rel > b.room.1 {
                        continue;
                    }
                    let want = if rel < 0.0 { kind.0 } else { kind.1 };
                    score += if m == want { 1 } else { -1 };
                }
            }
            if score > best.1 || (score == best.1 && d.abs() < best.0.abs()) {
                best = (d, score);
            }
        }
        shift.insert(kind, best.0);
    }
    let mut out = Vec::new();
    for (index, b) in plan.boundaries.iter().enumerate() {
        let d = shift.get(&(b.from, b.to)).copied().unwrap_or(0.0);
        let bead = &plan.beads[b.bead];
        let len = bead.length();
        let (s0, s1) = ((b.s + d - b.room.0).max(0.0), (b.s + d + b.room.1).min(len));
        let labels = along(plan, frame, seen, b.bead, s0, s1, step);
        let Some((landed, fit)) = step_fit(&labels, b.from, b.to) else {
            continue;
        };
        if fit < 0.7 {
            continue;
        }
        // On the short stretch between two rows the centre line is an arc tighter than
        // the bead is wide: paste laid across it reaches past its centre, and where the
        // bead there is wider than its pitch the stretch's far part lies under its near
        // part, so a boundary landing there is not read.
        let between = bead
            .turns
            .windows(2)
            .find(|w| w[1] - w[0] < 1.5 * plan.pitch && w[0] < landed && landed < w[1]);
        if let Some(w) = between {
            let half = half_width_between_turns(bead, (w[0], w[1]), frame, seen, plan.pitch);
            if half > MAX_TURN_HALF_WIDTH * plan.pitch {
                continue;
            }
        }
        let near_turn = bead.turns.iter().any(|&t| (landed - t).abs() < plan.pitch);
        out.push(Found {
            index,
            offset: landed - b.s,
            fit,
            beside_turn: near_turn,
        });
    }
    out
}

/// Bead width across the path every `every_mm`, mm: the run of printed pixels through
/// the centre line, perpendicular to it. Where neighbouring beads touch, the run would
/// span them, so it is cut at 0.75 pitch each side: widths at or over 1.5 pitch say only
/// "touching". Samples within a pitch of a bead end are skipped.
pub fn widths(
    plan: &Plan,
    frame: &DesignFrame,
    seen: &[u8],
    every_mm: f64,
) -> Vec<(usize, f64, f64)> {
    let step = 0.25 / frame.px_per_mm;
    let reach = 0.75 * plan.pitch;
    let mut out = Vec::new();
    for (bi, bead) in plan.beads.iter().enumerate() {
        let n = (bead.length() / every_mm).floor() as usize;
        for i in 0..=n {
            let s = i as f64 * every_mm;
            if s < plan.pitch || s > bead.length() - plan.pitch {
                continue;
            }
            if let Some(w) = width_at(bead, s, frame, seen, step, reach) {
                out.push((bi, s, w));
            }
        }
    }
    out
}

fn width_at(
    bead: &Bead,
    s: f64,
    frame: &DesignFrame,
    seen: &[u8],
    step: f64,
    reach: f64,
) -> Option<f64> {
    let (p, u) = bead.at(s);
    let n = [-u[1], u[0]];
    if label_at(seen, frame, p) == PLATE {
        return Some(0.0);
    }
    let side = |sign: f64| {
        let mut t = 0.0;
        while t < reach {
            let q = [
                p[0] + n[0] * sign * (t + step),
                p[1] + n[1] * sign * (t + step),
            ];
            if label_at(seen, frame, q) == PLATE {
                break;
            }
            t += step;
        }
        t + 0.5 * step
    };
    Some(side(1.0) + side(-1.0))
}

/// `plan` with each of `found`'s boundaries moved to where it landed.
pub fn moved(plan: &Plan, found: &[Found]) -> Plan {
    let mut moved = plan.clone();
    for f in found {
        let b = plan.boundaries[f.index];
        if let Some(run) = moved.beads[b.bead].runs.iter_mut().find(|r| r.0 == b.s) {
            run.0 = (b.s + f.offset).max(0.0);
        }
    }
    for bead in &mut moved.beads {
        bead.runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    moved
}

/// One material's bead width away from its switches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialWidth {
    /// The material.
    pub material: u8,
    /// Median width of its samples, mm (1.5 pitch: its beads touch their neighbours).
    pub median: f64,
    /// Samples.
    pub samples: usize,
}

/// How far from a boundary as it landed a width sample must lie to count for its
/// material, mm: the flow settles over about the transit after a switch.
pub const CLEAR_OF_SWITCH_MM: f64 = 1.0;

/// Each material's median bead width over the samples of `widths` (as `widths` gives them)
/// that lie more than `CLEAR_OF_SWITCH_MM` from every boundary of `moved` (the plan with
/// each found boundary moved to where it landed) and more than `design::WINDOW_MM` from
/// every boundary that was not found. A paste whose flow is off (its viscosity or its
/// supply pressure) prints its whole run narrower or wider, not only after a switch.
pub fn width_by_material(
    plan: &Plan,
    moved: &Plan,
    found: &[Found],
    widths: &[(usize, f64, f64)],
) -> Vec<MaterialWidth> {
    let mut by: std::collections::BTreeMap<u8, Vec<f64>> = Default::default();
    for &(bi, s, w) in widths {
        let near_landed = moved.beads[bi]
            .runs
            .iter()
            .skip(1)
            .any(|r| (s - r.0).abs() < CLEAR_OF_SWITCH_MM);
        let near_unfound = plan.boundaries.iter().enumerate().any(|(i, b)| {
            b.bead == bi
                && (s - b.s).abs() < super::design::WINDOW_MM
                && !found.iter().any(|f| f.index == i)
        });
        if !near_landed && !near_unfound {
            by.entry(moved.beads[bi].material_at(s))
                .or_default()
                .push(w);
        }
    }
    by.into_iter()
        .map(|(material, v)| MaterialWidth {
            material,
            median: quantile(&v, 0.5),
            samples: v.len(),
        })
        .collect()
}

/// The `q` quantile of `v` (0..1), by sorting a copy; 0 for none.
pub fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

/// A bead's centre line as the photo shows it: content that belongs at design point `at`
/// shows displaced by `d` mm along the unit normal `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    /// Design point on the bead's centre line, mm.
    pub at: [f64; 2],
    /// Unit normal of the bead there.
    pub n: [f64; 2],
    /// Displacement along `n`, mm.
    pub d: f64,
}

/// The beads' centre lines as `seen` shows them, every `every_mm` along each bead, away
/// from its ends and turns: the middle between the bead's two sides, where both show
/// (against the plate or another material) within three quarters of a pitch. A bead
/// wider or narrower than its pitch moves both sides alike, so not its middle.
/// Along-path offsets cannot see a misregistration across the rows, which these can: rows
/// that all run along x leave y to them.
pub fn edges(
    plan: &Plan,
    frame: &DesignFrame,
    design: &[u8],
    seen: &[u8],
    every_mm: f64,
) -> Vec<Edge> {
    let step = 0.25 / frame.px_per_mm;
    let reach = 0.75 * plan.pitch;
    let mut out = Vec::new();
    for bead in &plan.beads {
        let len = bead.length();
        let n = (len / every_mm).floor() as usize;
        for i in 0..=n {
            let s = i as f64 * every_mm;
            if s < plan.pitch
                || s > len - plan.pitch
                || bead.turns.iter().any(|&t| (s - t).abs() < plan.pitch)
            {
                continue;
            }
            let (p, u) = bead.at(s);
            let nn = [-u[1], u[0]];
            let mine = label_at(seen, frame, p);
            if mine == PLATE || label_at(design, frame, p) == PLATE {
                continue;
            }
            // Distance out to the side on `sign`'s side, if it shows within reach.
            let side = |sign: f64| {
                let mut t = 0.0;
                while t < reach {
                    let q = [
                        p[0] + nn[0] * sign * (t + step),
                        p[1] + nn[1] * sign * (t + step),
                    ];
                    if label_at(seen, frame, q) != mine {
                        return Some(t + 0.5 * step);
                    }
                    t += step;
                }
                None
            };
            if let (Some(a), Some(b)) = (side(1.0), side(-1.0)) {
                out.push(Edge {
                    at: p,
                    n: nn,
                    d: 0.5 * (a - b),
                });
            }
        }
    }
    out
}

/// A registration error as the boundaries show it: content that belongs at design point
/// `p` appears displaced by an affine function of `p - c`, mm. (Quadratic terms, for the
/// bending a misjudged perspective adds, were tried: they also soak up the real variation
/// of offsets along a row, and measured worse against the plant.)
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Drift {
    /// Per axis: coefficients of 1, dx, dy (d = p - c).
    pub k: [[f64; 3]; 2],
    /// Centre it is taken about, mm.
    pub c: [f64; 2],
    /// Per axis: boundaries run along it but nothing measured a shift along it (every
    /// switch direction runs one way along it, and no beads' sides face it), so the
    /// offsets along it keep whatever shift the registration left.
    pub unpinned: [bool; 2],
}

impl Drift {
    fn basis(&self, p: [f64; 2]) -> [f64; 3] {
        [1.0, p[0] - self.c[0], p[1] - self.c[1]]
    }
    /// Displacement at design point `p`, mm.
    pub fn at(&self, p: [f64; 2]) -> [f64; 2] {
        let b = self.basis(p);
        std::array::from_fn(|a| (0..3).map(|j| self.k[a][j] * b[j]).sum())
    }
    /// The displacement seen along unit direction `u` at `p`, mm.
    pub fn along(&self, p: [f64; 2], u: [f64; 2]) -> f64 {
        let d = self.at(p);
        d[0] * u[0] + d[1] * u[1]
    }
}

/// Where the field's terms are centred: the mean of the found boundaries, or the middle
/// of the design when none was found.
fn centre(plan: &Plan, found: &[Found]) -> [f64; 2] {
    let n = found.len();
    let mut c = [0.0; 2];
    for f in found {
        let p = plan.boundaries[f.index].at;
        c[0] += p[0] / n.max(1) as f64;
        c[1] += p[1] / n.max(1) as f64;
    }
    if n == 0 {
        c = [
            0.5 * (plan.lo[0] + plan.hi[0]),
            0.5 * (plan.lo[1] + plan.hi[1]),
        ];
    }
    c
}

/// The registration error that `found` reveals. Anything the machine does moves a
/// boundary along its bead the same way whichever way the bead runs; a misregistered
/// photo moves it along a fixed direction on the plate, so beads running opposite ways
/// see it with opposite signs. Fitting each switch direction's own offset plus a
/// displacement field seen through each bead's direction separates the two, wholly along
/// an axis where some switch direction has beads running both ways along it, and in how it
/// changes across the print where none has.
///
/// The beads' sides (`edges`) add what the path cannot: a displacement across the beads,
/// read on its own (no switch direction's offset in it). Sides that a bead narrower or
/// wider than its pitch moved are let go after a first fit: those more than three
/// median misfits (and a quarter pixel) off it.
pub fn drift(plan: &Plan, found: &[Found], edges: &[Edge], px_mm: f64) -> Drift {
    let found: Vec<Found> = found.iter().filter(|f| !f.beside_turn).copied().collect();
    let found = &found[..];
    let kind = |f: &Found| (plan.boundaries[f.index].from, plan.boundaries[f.index].to);
    let mut kinds: Vec<(u8, u8)> = found.iter().map(kind).collect();
    kinds.sort_unstable();
    kinds.dedup();
    let dir = |f: &Found| {
        let b = plan.boundaries[f.index];
        plan.beads[b.bead].at(b.s).1
    };
    let both_ways = |axis: usize| {
        kinds.iter().any(|&k| {
            let of_kind = || found.iter().filter(|f| kind(f) == k);
            of_kind().filter(|f| dir(f)[axis] > 0.5).count() >= 2
                && of_kind().filter(|f| dir(f)[axis] < -0.5).count() >= 2
        })
    };
    // An axis is also seen from the sides of beads running across it, on both sides.
    let sides = |axis: usize| {
        edges.iter().filter(|e| e.n[axis] > 0.5).count() >= 8
            && edges.iter().filter(|e| e.n[axis] < -0.5).count() >= 8
    };
    // The field's terms fitted, (axis, term): all three where the axis is seen from both
    // ways or from the sides; where every switch direction runs one way along it (a
    // chessboard of three or more materials in a boustrophedon ties each switch to one
    // way), a shift along it looks exactly like each switch direction's own offset, so
    // only how the field changes across the print (its dx and dy terms) is fitted.
    let mut cols: Vec<(usize, usize)> = Vec::new();
    for a in 0..2 {
        if both_ways(a) || sides(a) {
            cols.extend((0..3).map(|t| (a, t)));
        } else if found.iter().filter(|f| dir(f)[a].abs() > 0.5).count() >= 8 {
            cols.extend((1..3).map(|t| (a, t)));
        }
    }
    let n = found.len();
    let c = centre(plan, found);
    let out = Drift {
        c,
        unpinned: std::array::from_fn(|a| {
            !cols.contains(&(a, 0)) && found.iter().any(|f| dir(f)[a].abs() > 0.5)
        }),
        ..Default::default()
    };
    let unknowns = kinds.len() + cols.len();
    if cols.is_empty() || n + edges.len() < unknowns + 3 {
        return out;
    }
    // Rows: the found boundaries (a switch direction's offset plus the field along the
    // path), then the sides kept (the field along their normal). `None` when the rows do
    // not determine every unknown (the least-norm answer would then move the field by
    // whatever made the switch directions' offsets smallest).
    let solve = |keep: &[bool]| -> Option<nalgebra::DVector<f64>> {
        let rows = n + keep.iter().filter(|&&k| k).count();
        let mut m = nalgebra::DMatrix::<f64>::zeros(rows, unknowns);
        let mut y = nalgebra::DVector::<f64>::zeros(rows);
        let basis = |p: [f64; 2]| [1.0, p[0] - c[0], p[1] - c[1]];
        for (i, f) in found.iter().enumerate() {
            let b = plan.boundaries[f.index];
            let u = dir(f);
            let k = kinds.iter().position(|&k| k == kind(f)).unwrap_or(0);
            m[(i, k)] = 1.0;
            let basis = basis(b.at);
            for (j, &(a, t)) in cols.iter().enumerate() {
                m[(i, kinds.len() + j)] = u[a] * basis[t];
            }
            y[i] = f.offset;
        }
        for (i, e) in edges
            .iter()
            .zip(keep)
            .filter(|x| *x.1)
            .map(|x| x.0)
            .enumerate()
        {
            let basis = basis(e.at);
            for (j, &(a, t)) in cols.iter().enumerate() {
                m[(n + i, kinds.len() + j)] = e.n[a] * basis[t];
            }
            y[n + i] = e.d;
        }
        let svd = m.svd(true, true);
        let sv = &svd.singular_values;
        if sv.min() <= 1e-9 * sv.max() {
            return None;
        }
        svd.solve(&y, 1e-12).ok()
    };
    let field = |sol: &nalgebra::DVector<f64>| {
        let mut d = out;
        for (j, &(a, t)) in cols.iter().enumerate() {
            d.k[a][t] = sol[kinds.len() + j];
        }
        d
    };
    let mut keep = vec![true; edges.len()];
    let Some(first) = solve(&keep) else {
        return out;
    };
    let rough = field(&first);
    let misfit: Vec<f64> = edges
        .iter()
        .map(|e| (e.d - rough.along(e.at, e.n)).abs())
        .collect();
    let cut = (3.0 * quantile(&misfit, 0.5)).max(0.25 / px_mm);
    for (k, m) in keep.iter_mut().zip(&misfit) {
        *k = *m <= cut;
    }
    match solve(&keep) {
        Some(sol) => field(&sol),
        None => rough,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inspect::design::{Bead, Boundary};

    /// One straight 10 mm bead, material 0 then 1 from s = 5 mm.
    fn line() -> Plan {
        Plan {
            beads: vec![Bead {
                points: vec![[0.0, 0.0], [10.0, 0.0]],
                s: vec![0.0, 10.0],
                runs: vec![(0.0, 0), (5.0, 1)],
                turns: Vec::new(),
            }],
            boundaries: vec![Boundary {
                bead: 0,
                s: 5.0,
                at: [5.0, 0.0],
                from: 0,
                to: 1,
                room: (2.5, 2.5),
            }],
            pitch: 0.8,
            lo: [0.0, -0.4],
            hi: [10.0, 0.4],
            materials: vec![0, 1],
            layers: 1,
            markers: None,
        }
    }

    #[test]
    fn widths_by_material_keep_clear_of_where_the_switch_landed() {
        let plan = line();
        let mut moved = plan.clone();
        moved.beads[0].runs[1].0 = 6.0;
        let found = [Found {
            index: 0,
            offset: 1.0,
            fit: 1.0,
            beside_turn: false,
        }];
        // 0.8 mm wide up to where the switch landed, 0.6 after, with a neck at 6.5 that
        // the switch explains and must not count.
        let widths: Vec<(usize, f64, f64)> = (0..=20)
            .map(|i| {
                let s = i as f64 * 0.5;
                (
                    0,
                    s,
                    if s == 6.5 {
                        0.1
                    } else if s < 6.0 {
                        0.8
                    } else {
                        0.6
                    },
                )
            })
            .collect();
        let got = width_by_material(&plan, &moved, &found, &widths);
        // Material 0: s = 0 to 5 (11 samples; 5.5 lies within 1 mm of 6); material 1:
        // s = 7 to 10 (7 samples).
        assert_eq!(
            got,
            vec![
                MaterialWidth {
                    material: 0,
                    median: 0.8,
                    samples: 11
                },
                MaterialWidth {
                    material: 1,
                    median: 0.6,
                    samples: 7
                }
            ]
        );
        // Not found: everything within the search window of the design's place is left out.
        let got = width_by_material(&plan, &plan, &[], &widths);
        assert_eq!(got.iter().map(|m| m.samples).collect::<Vec<_>>(), [6, 6]);
    }
}
