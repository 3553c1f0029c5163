//! What the photo is compared with: the job's top layer as bead centre lines (the
//! priming bead set apart) with their corners rounded as the executor rounds them, each
//! material boundary with its place along its bead, and the footprint the beads cover.
//! Reading the photo is the other modules' business.

pub use crate::slicer::markers::Marker;
use dollop::command::{walk, MoveKind};
use dollop::Command;

/// One bead of the design: its centre line and where its material changes.
#[derive(Clone, Debug)]
pub struct Bead {
    /// Corners of the centre line, mm.
    pub points: Vec<[f64; 2]>,
    /// Path length at each corner, mm.
    pub s: Vec<f64>,
    /// Material runs: (path length where the run starts, material).
    pub runs: Vec<(f64, u8)>,
    /// Path lengths of the corners where the bead turns by more than 20 degrees.
    pub turns: Vec<f64>,
}

impl Bead {
    /// Length of the centre line, mm.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// The point at path length `s` (clamped to the bead) and the unit direction there.
    pub fn at(&self, s: f64) -> ([f64; 2], [f64; 2]) {
        let s = s.clamp(0.0, self.length());
        let k = match self.s.iter().position(|&v| v > s) {
            Some(0) | None => self.points.len().saturating_sub(1).max(1),
            Some(k) => k,
        };
        let (a, b) = (self.points[k - 1], self.points[k]);
        let len = self.s[k] - self.s[k - 1];
        let d = [b[0] - a[0], b[1] - a[1]];
        let u = if len > 0.0 {
            [d[0] / len, d[1] / len]
        } else {
            [1.0, 0.0]
        };
        let t = s - self.s[k - 1];
        ([a[0] + u[0] * t, a[1] + u[1] * t], u)
    }

    /// Material the design has at path length `s`.
    pub fn material_at(&self, s: f64) -> u8 {
        self.runs
            .iter()
            .take_while(|r| r.0 <= s)
            .last()
            .or(self.runs.first())
            .map_or(0, |r| r.1)
    }
}

/// A material boundary of the design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundary {
    /// Index of its bead.
    pub bead: usize,
    /// Path length along the bead, mm.
    pub s: f64,
    /// Where the design has it (the command's point, before corners are rounded), mm.
    pub at: [f64; 2],
    /// Material before and after it.
    pub from: u8,
    /// Material after it.
    pub to: u8,
    /// Path length on either side that belongs to this boundary alone (half the way to the
    /// next boundary or the whole way to the bead's end, at most `WINDOW_MM`), mm.
    pub room: (f64, f64),
}

/// Longest stretch of bead on either side of a boundary searched for it, mm.
pub const WINDOW_MM: f64 = 2.5;

/// The design as the photo should show it.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Beads of the top layer, priming bead excluded.
    pub beads: Vec<Bead>,
    /// Boundaries of those beads, bead by bead in path order.
    pub boundaries: Vec<Boundary>,
    /// Bead width (the line pitch), mm.
    pub pitch: f64,
    /// Lower-left and upper-right corners of what the beads cover, mm.
    pub lo: [f64; 2],
    /// Upper-right corner.
    pub hi: [f64; 2],
    /// Materials the beads print, ascending.
    pub materials: Vec<u8>,
    /// Layers in the job (only the top one is seen from above).
    pub layers: usize,
    /// The corner markers `dollop slice --markers` printed after the design, if any (not
    /// among `beads`).
    pub markers: Option<[Marker; 4]>,
}

impl Plan {
    /// Lower-left and upper-right of the footprint with the markers, if any, mm.
    pub fn extent(&self) -> ([f64; 2], [f64; 2]) {
        let (mut lo, mut hi) = (self.lo, self.hi);
        let half = self.pitch / 2.0;
        for m in self.markers.iter().flatten() {
            for p in [m.corner, m.ends[0], m.ends[1]] {
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a] - half);
                    hi[a] = hi[a].max(p[a] + half);
                }
            }
        }
        (lo, hi)
    }
}

/// The plan of `commands` (starting at `start_um`) for beads `pitch` mm wide whose
/// corners the executor rounds to `corner_radius` mm.
pub fn plan(commands: &[Command], start_um: [i32; 3], pitch: f64, corner_radius: f64) -> Plan {
    let beads = beads_of(commands, start_um);
    let mut zs: Vec<i64> = beads.iter().map(|b| b.0).collect();
    zs.sort_unstable();
    zs.dedup();
    let layers = zs.len();
    let top = zs.last().copied().unwrap_or(0);
    // The slicer's priming bead comes first, a straight single-material bead apart from
    // the design; it is not part of what is measured.
    let first_is_prime =
        beads.len() > 1 && beads[0].1.points.len() == 2 && beads[0].1.runs.len() == 1;
    let on_top: Vec<(Vec<[f64; 2]>, usize)> = beads
        .iter()
        .filter(|b| b.0 == top)
        .map(|b| (b.1.points.clone(), b.1.runs.len()))
        .collect();
    let markers = crate::slicer::markers::recognise(&on_top, pitch);
    let mut beads: Vec<Bead> = beads
        .into_iter()
        .enumerate()
        .filter(|(i, b)| b.0 == top && !(*i == 0 && first_is_prime))
        .map(|(_, b)| b.1)
        .collect();
    if markers.is_some() {
        beads.truncate(beads.len().saturating_sub(4));
    }
    let mut raw = beads;
    for b in &mut raw {
        b.turns = turns(b);
    }
    let beads: Vec<Bead> = raw.iter().map(|b| rounded(b, corner_radius)).collect();
    let (lo, hi) = extent(&beads, pitch);
    let mut materials: Vec<u8> = beads
        .iter()
        .flat_map(|b| b.runs.iter().map(|r| r.1))
        .collect();
    materials.sort_unstable();
    materials.dedup();
    let boundaries = boundaries(&beads, &raw);
    Plan {
        beads,
        boundaries,
        pitch,
        lo,
        hi,
        materials,
        layers,
        markers,
    }
}

/// The beads `commands` (starting at `start_um`) lay, each with the height it lies at,
/// um, in the order laid.
fn beads_of(commands: &[Command], start_um: [i32; 3]) -> Vec<(i64, Bead)> {
    let mut beads: Vec<(i64, Bead)> = Vec::new();
    let mut cur: Option<Bead> = None;
    let mm = |p: [i32; 3]| [p[0] as f64 * 1e-3, p[1] as f64 * 1e-3];
    // The walk yields no dwell or end; a gap in the command indices is one, and ends a
    // bead as a travel or a layer change does.
    let (mut next_index, mut z) = (0, start_um[2] as i64);
    for m in walk(commands, start_um) {
        let contiguous = m.index == next_index;
        next_index = m.index + 1;
        z = m.to[2] as i64;
        let MoveKind::Print { material } = m.kind else {
            beads.extend(cur.take().map(|b| (m.from[2] as i64, b)));
            continue;
        };
        if !contiguous {
            beads.extend(cur.take().map(|b| (z, b)));
        }
        if m.from == m.to {
            continue;
        }
        let b = cur.get_or_insert_with(|| Bead {
            points: vec![mm(m.from)],
            s: vec![0.0],
            runs: vec![(0.0, material)],
            turns: Vec::new(),
        });
        let s0 = b.length();
        if b.runs.last().map(|r| r.1) != Some(material) {
            b.runs.push((s0, material));
        }
        let [dx, dy] = [m.to[0] - m.from[0], m.to[1] - m.from[1]];
        let len = ((dx as f64).hypot(dy as f64)) * 1e-3;
        b.points.push(mm(m.to));
        b.s.push(s0 + len);
    }
    beads.extend(cur.take().map(|b| (z, b)));
    beads
}

/// The lowest and highest corner of what `beads` (`pitch` mm wide) cover, mm.
fn extent(beads: &[Bead], pitch: f64) -> ([f64; 2], [f64; 2]) {
    let half = pitch / 2.0;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in beads.iter().flat_map(|b| &b.points) {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a] - half);
            hi[a] = hi[a].max(p[a] + half);
        }
    }
    (lo, hi)
}

/// The material boundaries along `beads` (the corners rounded) with the room each has
/// before and after; `raw` (the same beads unrounded) places them.
fn boundaries(beads: &[Bead], raw: &[Bead]) -> Vec<Boundary> {
    let mut boundaries = Vec::new();
    for (bi, b) in beads.iter().enumerate() {
        for k in 1..b.runs.len() {
            let s = b.runs[k].0;
            let prev = if k >= 2 { b.runs[k - 1].0 } else { 0.0 };
            let before = if k >= 2 { (s - prev) / 2.0 } else { s - prev };
            let after = match b.runs.get(k + 1) {
                Some(n) => (n.0 - s) / 2.0,
                None => b.length() - s,
            };
            boundaries.push(Boundary {
                bead: bi,
                s,
                at: raw[bi].at(raw[bi].runs[k].0).0,
                from: b.runs[k - 1].1,
                to: b.runs[k].1,
                room: (before.min(WINDOW_MM), after.min(WINDOW_MM)),
            });
        }
    }
    boundaries
}

/// `b` with its corners filleted as the executor does (`dollop::motion::fillet`, each
/// using at most what the previous fillet left of its segment and half of the next), arcs
/// as chords of at most 3 degrees; runs re-placed at the nearest point of the new path.
fn rounded(b: &Bead, radius: f64) -> Bead {
    if radius <= 0.0 || b.points.len() < 3 {
        return b.clone();
    }
    let mut pts = vec![b.points[0]];
    let mut t_start = 0.0;
    for i in 1..b.points.len() - 1 {
        let (a, v, c) = (b.points[i - 1], b.points[i], b.points[i + 1]);
        let (l1, l2) = (b.s[i] - b.s[i - 1], b.s[i + 1] - b.s[i]);
        if l1 <= 0.0 || l2 <= 0.0 {
            continue;
        }
        let u1 = [(v[0] - a[0]) / l1, (v[1] - a[1]) / l1];
        let u2 = [(c[0] - v[0]) / l2, (c[1] - v[1]) / l2];
        let max_t = (l1 - t_start).min(l2 * 0.5);
        match dollop::motion::fillet(v, u1, u2, radius, max_t.max(0.0)) {
            Some(f) => {
                let n = ((f.sweep.abs().to_degrees() / 3.0).ceil() as usize).max(1);
                for k in 0..=n {
                    pts.push(f.point(f.length() * k as f64 / n as f64));
                }
                t_start = f.tangent;
            }
            None => {
                pts.push(v);
                t_start = 0.0;
            }
        }
    }
    pts.push(*b.points.last().unwrap_or(&[0.0, 0.0]));
    let mut s = vec![0.0];
    for k in 1..pts.len() {
        let d = (pts[k][0] - pts[k - 1][0]).hypot(pts[k][1] - pts[k - 1][1]);
        s.push(s[k - 1] + d);
    }
    let mut out = Bead {
        points: pts,
        s,
        runs: Vec::new(),
        turns: Vec::new(),
    };
    out.runs = b
        .runs
        .iter()
        .map(|&(s0, m)| {
            (
                if s0 <= 0.0 {
                    0.0
                } else {
                    out.nearest(b.at(s0).0)
                },
                m,
            )
        })
        .collect();
    out.turns = b.turns.iter().map(|&t| out.nearest(b.at(t).0)).collect();
    out
}

/// Path lengths of `b`'s corners that turn by more than 20 degrees.
fn turns(b: &Bead) -> Vec<f64> {
    (1..b.points.len().saturating_sub(1))
        .filter(|&i| {
            let (a, v, c) = (b.points[i - 1], b.points[i], b.points[i + 1]);
            let (u1, u2) = ([v[0] - a[0], v[1] - a[1]], [c[0] - v[0], c[1] - v[1]]);
            let (n1, n2) = (u1[0].hypot(u1[1]), u2[0].hypot(u2[1]));
            n1 > 0.0
                && n2 > 0.0
                && (u1[0] * u2[0] + u1[1] * u2[1]) / (n1 * n2) < 20f64.to_radians().cos()
        })
        .map(|i| b.s[i])
        .collect()
}

impl Bead {
    /// Path length of the point of the bead nearest to `p`.
    pub fn nearest(&self, p: [f64; 2]) -> f64 {
        let mut best = (f64::INFINITY, 0.0);
        for k in 1..self.points.len() {
            let (a, b) = (self.points[k - 1], self.points[k]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            let t = if len2 > 0.0 {
                (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = [a[0] + d[0] * t, a[1] + d[1] * t];
            let e = (p[0] - q[0]).hypot(p[1] - q[1]);
            if e < best.0 {
                best = (e, self.s[k - 1] + t * len2.sqrt());
            }
        }
        best.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beads_boundaries_and_the_priming_bead() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 600 },
            Command::Print {
                dx: 8000,
                dy: 0,
                material: 0,
            },
            Command::Travel {
                x: 0,
                y: 3000,
                z: 600,
            },
            Command::Print {
                dx: 2000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 1000,
                dy: 0,
                material: 1,
            },
            Command::Print {
                dx: 0,
                dy: 800,
                material: 1,
            },
            Command::Print {
                dx: -3000,
                dy: 0,
                material: 0,
            },
            Command::End,
        ];
        let p = plan(&cmds, [0, 0, 600], 0.8, 0.0);
        assert_eq!(p.beads.len(), 1, "the priming bead is set apart");
        assert_eq!(p.materials, vec![0, 1]);
        assert_eq!(p.boundaries.len(), 2);
        let b = p.boundaries[0];
        assert_eq!((b.from, b.to), (0, 1));
        assert!((b.s - 2.0).abs() < 1e-12 && b.at == [2.0, 3.0]);
        // Before: the whole 2 mm run; after: half the way to the next boundary.
        assert!((b.room.0 - 2.0).abs() < 1e-12 && (b.room.1 - 0.9).abs() < 1e-12);
        let b = p.boundaries[1];
        assert!((b.s - 3.8).abs() < 1e-12, "{b:?}");
        assert!(
            (b.at[0] - 3.0).abs() < 1e-12 && (b.at[1] - 3.8).abs() < 1e-12,
            "{b:?}"
        );
        assert_eq!(p.beads[0].material_at(3.5), 1);
        assert_eq!(p.beads[0].material_at(1.0), 0);
        let (pt, u) = p.beads[0].at(3.4);
        assert!((pt[0] - 3.0).abs() < 1e-12 && (pt[1] - 3.4).abs() < 1e-12);
        assert!(u[0].abs() < 1e-12 && (u[1] - 1.0).abs() < 1e-12, "{u:?}");
        assert!((p.lo[0] + 0.4).abs() < 1e-12 && (p.hi[1] - 4.2).abs() < 1e-12);
        assert_eq!(p.beads[0].turns.len(), 2);

        // Corners rounded as the executor rounds them: two quarter arcs of 0.25 mm make the
        // path 2 (2 - pi/2) 0.25 mm shorter. The boundary at the second corner is placed
        // at its arc's middle (the nearest point): after the first arc's saving, the
        // straight up to the arc and half the arc. The design point stays the command's.
        let r = plan(&cmds, [0, 0, 600], 0.8, 0.25);
        let b = r.boundaries[1];
        let short = 2.0 * (2.0 - std::f64::consts::FRAC_PI_2) * 0.25;
        assert!(
            (r.beads[0].length() - (6.8 - short)).abs() < 2e-3,
            "{}",
            r.beads[0].length()
        );
        let want = 3.8 - short / 2.0 - 0.25 + std::f64::consts::FRAC_PI_4 * 0.25;
        assert!((b.s - want).abs() < 2e-3, "{b:?} vs {want}");
        assert!((b.at[0] - 3.0).abs() < 1e-12 && (b.at[1] - 3.8).abs() < 1e-12);
    }
}
