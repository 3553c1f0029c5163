//! Corner markers for photographing a print (`dollop slice --markers`): an L-shaped bead
//! outside each corner of what the job prints (the design and its priming bead), one of
//! them with longer legs so that a photo's turn is unambiguous. They are ordinary beads
//! appended after the design in the material the channel holds by then, so the job format
//! is unchanged and `inspect` recognises them by their shape ([`recognise`]). Finding them
//! in a photo is `inspect`'s business.

pub use super::error::MarkerError;
use super::toolpath::um;
use dollop::command::{walk, MoveKind};
use dollop::Command;

/// One marker: a bead from `ends[0]` to `corner` to `ends[1]`, legs at a right angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marker {
    /// The L's corner (centre line), mm.
    pub corner: [f64; 2],
    /// The ends of its two legs, mm.
    pub ends: [[f64; 2]; 2],
}

impl Marker {
    /// Length of each leg, mm.
    pub fn leg(&self) -> f64 {
        let d = |e: [f64; 2]| (e[0] - self.corner[0]).hypot(e[1] - self.corner[1]);
        0.5 * (d(self.ends[0]) + d(self.ends[1]))
    }
    /// Unit direction of leg `k` from the corner.
    pub fn dir(&self, k: usize) -> [f64; 2] {
        let e = self.ends[k];
        let d = [e[0] - self.corner[0], e[1] - self.corner[1]];
        let l = d[0].hypot(d[1]).max(1e-12);
        [d[0] / l, d[1] / l]
    }
}

/// Leg of the ordinary markers for beads `pitch` wide, mm: long enough that the middle
/// of each leg, away from its ends and the corner, gives its centre line.
pub fn leg_mm(pitch: f64) -> f64 {
    (5.0 * pitch).max(3.0)
}

/// The distinctive marker's legs over the others'.
pub const LONG: f64 = 1.6;

/// Centre line of a marker's legs from the edge of what the job prints, in pitches.
pub const GAP_PITCHES: f64 = 2.0;

/// The four markers about the box from `lo` to `hi` (bead edges, mm), top-left first
/// and clockwise as seen from above; the top-left one has the long legs.
pub fn layout(lo: [f64; 2], hi: [f64; 2], pitch: f64) -> [Marker; 4] {
    let g = GAP_PITCHES * pitch;
    let a = leg_mm(pitch);
    // Corner, and the signs of the legs' directions (along x, along y).
    let at = [
        ([lo[0] - g, hi[1] + g], [1.0, -1.0], LONG * a),
        ([hi[0] + g, hi[1] + g], [-1.0, -1.0], a),
        ([hi[0] + g, lo[1] - g], [-1.0, 1.0], a),
        ([lo[0] - g, lo[1] - g], [1.0, 1.0], a),
    ];
    at.map(|(c, s, len)| Marker {
        corner: c,
        ends: [[c[0] + s[0] * len, c[1]], [c[0], c[1] + s[1] * len]],
    })
}

/// `commands` (starting at `start_um`, ending with `End`) with the four markers printed
/// right after the last bead, at its height and in its material, for beads `pitch`
/// wide; each marker must lie within `travel` (lower-left and upper-right, mm).
pub fn add(
    commands: &[Command],
    start_um: [i32; 3],
    pitch: f64,
    travel: ([f64; 2], [f64; 2]),
) -> Result<Vec<Command>, MarkerError> {
    let mut zs: Vec<i32> = Vec::new();
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut material = None;
    for m in walk(commands, start_um) {
        let MoveKind::Print { material: printed } = m.kind else {
            continue;
        };
        for p in [m.from, m.to] {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a] as f64 * 1e-3);
                hi[a] = hi[a].max(p[a] as f64 * 1e-3);
            }
        }
        material = Some(printed);
        if zs.last() != Some(&m.from[2]) {
            zs.push(m.from[2]);
        }
    }
    let Some(material) = material else {
        return Err(MarkerError::NothingPrinted);
    };
    zs.sort_unstable();
    zs.dedup();
    if zs.len() > 1 {
        return Err(MarkerError::Layers);
    }
    let half = pitch / 2.0;
    let markers = layout(
        [lo[0] - half, lo[1] - half],
        [hi[0] + half, hi[1] + half],
        pitch,
    );
    let inside = |p: [f64; 2]| {
        (0..2).all(|a| p[a] - half >= travel.0[a] - 1e-9 && p[a] + half <= travel.1[a] + 1e-9)
    };
    if !markers
        .iter()
        .all(|m| inside(m.corner) && m.ends.iter().all(|&e| inside(e)))
    {
        return Err(MarkerError::OutOfTravel);
    }
    // Right after the last bead, at its height: what follows it (a lift, `End`) follows
    // the markers.
    let mut out: Vec<Command> = commands.to_vec();
    let last = out
        .iter()
        .rposition(|c| matches!(c, Command::Print { .. }))
        .map_or(out.len(), |i| i + 1);
    let mut tail = out.split_off(last);
    if tail.last() != Some(&Command::End) {
        tail.push(Command::End);
    }
    let z = zs[0];
    for m in &markers {
        let [a, c, b] = [m.ends[0], m.corner, m.ends[1]].map(|p| [um(p[0]), um(p[1])]);
        out.push(Command::Travel {
            x: a[0],
            y: a[1],
            z,
        });
        out.push(Command::Print {
            dx: c[0] - a[0],
            dy: c[1] - a[1],
            material,
        });
        out.push(Command::Print {
            dx: b[0] - c[0],
            dy: b[1] - c[1],
            material,
        });
    }
    out.extend(tail);
    Ok(out)
}

/// The markers among a job's beads (each bead's corner points, mm, and its number of
/// material runs, in print order), if the last four are markers: one material each, two
/// legs at a right angle, three with legs of one length and one with legs `LONG` times as
/// long, each where [`add`] puts it about the beads before them for beads `pitch` wide.
pub fn recognise(beads: &[(Vec<[f64; 2]>, usize)], pitch: f64) -> Option<[Marker; 4]> {
    if beads.len() < 5 {
        return None;
    }
    let tail = &beads[beads.len() - 4..];
    let mut out = [Marker {
        corner: [0.0; 2],
        ends: [[0.0; 2]; 2],
    }; 4];
    for (k, (pts, runs)) in tail.iter().enumerate() {
        if pts.len() != 3 || *runs != 1 {
            return None;
        }
        let m = Marker {
            corner: pts[1],
            ends: [pts[0], pts[2]],
        };
        let (u, v) = (m.dir(0), m.dir(1));
        let l0 = (pts[0][0] - pts[1][0]).hypot(pts[0][1] - pts[1][1]);
        let l1 = (pts[2][0] - pts[1][0]).hypot(pts[2][1] - pts[1][1]);
        if (u[0] * v[0] + u[1] * v[1]).abs() > 0.01 || (l0 - l1).abs() > 0.01 || l0 < 2.0 * pitch {
            return None;
        }
        out[k] = m;
    }
    let legs: Vec<f64> = out.iter().map(Marker::leg).collect();
    let short = legs.iter().copied().fold(f64::INFINITY, f64::min);
    let long = legs.iter().filter(|&&l| l > 1.3 * short).count();
    if long != 1
        || legs
            .iter()
            .any(|&l| l > 1.3 * short && (l / short - LONG).abs() > 0.05)
    {
        return None;
    }
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in beads[..beads.len() - 4].iter().flat_map(|b| &b.0) {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    // Confirmed against the job: exactly where `add` puts markers about the beads before
    // them (to the micrometre the job stores), so a design that happens to end in four Ls
    // elsewhere is not taken for markers.
    let half = pitch / 2.0;
    let want = layout(
        [lo[0] - half, lo[1] - half],
        [hi[0] + half, hi[1] + half],
        pitch,
    );
    let near =
        |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() <= 2e-3 && (a[1] - b[1]).abs() <= 2e-3;
    out.iter()
        .zip(&want)
        .all(|(m, w)| {
            near(m.corner, w.corner) && near(m.ends[0], w.ends[0]) && near(m.ends[1], w.ends[1])
        })
        .then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job() -> Vec<Command> {
        vec![
            Command::Travel { x: 0, y: 0, z: 600 },
            Command::Print {
                dx: 8000,
                dy: 0,
                material: 0,
            },
            Command::Travel {
                x: 2000,
                y: 3000,
                z: 600,
            },
            Command::Print {
                dx: 5000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 3000,
                dy: 0,
                material: 1,
            },
            Command::End,
        ]
    }

    /// The beads of `cmds` as (points, runs), as inspect sees them.
    fn beads(cmds: &[Command]) -> Vec<(Vec<[f64; 2]>, usize)> {
        let mut out: Vec<(Vec<[f64; 2]>, Vec<u8>)> = Vec::new();
        let mut pos = [0i64; 2];
        let mut open = false;
        for c in cmds {
            match *c {
                Command::Print { dx, dy, material } => {
                    let p = |q: [i64; 2]| [q[0] as f64 * 1e-3, q[1] as f64 * 1e-3];
                    if !open {
                        out.push((vec![p(pos)], Vec::new()));
                        open = true;
                    }
                    pos = [pos[0] + dx as i64, pos[1] + dy as i64];
                    let b = out.last_mut().unwrap();
                    b.0.push(p(pos));
                    if b.1.last() != Some(&material) {
                        b.1.push(material);
                    }
                }
                Command::Travel { x, y, .. } => {
                    pos = [x as i64, y as i64];
                    open = false;
                }
                _ => open = false,
            }
        }
        out.into_iter().map(|(p, r)| (p, r.len())).collect()
    }

    #[test]
    fn markers_surround_the_print_and_are_recognised() {
        let cmds = add(&job(), [0, 0, 600], 0.8, ([-50.0; 2], [50.0; 2])).unwrap();
        assert_eq!(cmds.last(), Some(&Command::End));
        assert_eq!(cmds.len(), job().len() + 12);
        // In the last material, at the print's z.
        assert!(cmds[5..17].iter().all(|c| match *c {
            Command::Print { material, .. } => material == 1,
            Command::Travel { z, .. } => z == 600,
            _ => false,
        }));
        let b = beads(&cmds);
        let m = recognise(&b, 0.8).expect("recognised");
        // The box of the beads is (-0.4, -0.4)..(10.4, 3.4); corners 1.6 mm out.
        assert_eq!(m[0].corner, [-2.0, 5.0]);
        assert_eq!(m[2].corner, [12.0, -2.0]);
        assert!((m[0].leg() - 6.4).abs() < 1e-9 && (m[1].leg() - 4.0).abs() < 1e-9);
        assert_eq!(m[1].dir(0), [-1.0, 0.0]);
        // A job without markers has none, and neither has one whose last beads are not Ls.
        assert!(recognise(&beads(&job()), 0.8).is_none());
        let mut cut = cmds.clone();
        cut.remove(cut.len() - 2);
        assert!(recognise(&beads(&cut), 0.8).is_none());
        // Four Ls of the markers' shape that a design happens to end with, a millimetre
        // from where `add` puts markers, are not taken for markers; nor are the markers
        // read for another pitch.
        let mut moved = cmds.clone();
        for c in &mut moved {
            // The markers' travels (the design's lie at y 0 and 3 mm).
            if let Command::Travel { x, y, .. } = c {
                if *y < 0 || *y > 3400 {
                    *x += 1000;
                }
            }
        }
        assert_ne!(beads(&moved), b);
        assert!(recognise(&beads(&moved), 0.8).is_none());
        assert!(recognise(&b, 0.9).is_none());
    }

    #[test]
    fn markers_are_refused_outside_the_travel_and_for_several_layers() {
        assert_eq!(
            add(&job(), [0, 0, 600], 0.8, ([-1.0; 2], [50.0; 2])),
            Err(MarkerError::OutOfTravel)
        );
        let mut two = job();
        two.insert(5, Command::Layer { z: 1200 });
        two.insert(
            6,
            Command::Print {
                dx: -1000,
                dy: 0,
                material: 1,
            },
        );
        assert!(matches!(
            add(&two, [0, 0, 600], 0.8, ([-50.0; 2], [50.0; 2])),
            Err(MarkerError::Layers)
        ));
    }
}
