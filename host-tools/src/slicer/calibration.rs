//! The calibration pattern (`dollop slice --calibration-pattern`): a single-layer design
//! whose boundaries let `dollop inspect --suggest` tell the channel's volume, the valves'
//! dead time and each paste's viscosity apart. Every row is its own bead (no connectors),
//! so the flow starts from rest at each row; for every ordered pair of the config's
//! materials there are rows whose first switch lies at a set of distances from the row's
//! start about the transit length (the bead between valves and plate). A boundary closer
//! to its row's start than the transit length is switched at the valves while the head is
//! still finishing the row before, where the flow is dying away; one at the transit length
//! while the flow is rising again; one further on at full speed. A wrong dead time moves
//! each boundary by what flows during it, so by amounts that differ with the flow at its
//! switch; a wrong channel volume moves them all alike; a wrong viscosity moves only the
//! switches into and out of that paste. Each row switches back at its middle, at full
//! speed, so both directions of every pair are measured. Slicing it is `toolpath`'s.

use super::design::{Design, Layer, Run};
use super::toolpath::PathOptions;

/// Distances of a row's first switch from the row's start, relative to the transit
/// length, mm (kept at least `MIN_FIRST_MM` from the start).
pub const FIRST_SWITCH_MM: [f64; 7] = [-0.6, -0.3, 0.0, 0.3, 0.6, 1.2, 2.4];

/// The earliest a row's first switch may lie, mm from its start: a channel 20 % shorter
/// than configured lands boundaries over a millimetre early, and one that lands before
/// its row starts, or within a pitch of it, cannot be placed on the photo.
pub const MIN_FIRST_MM: f64 = 2.0;

/// Rows are this many transit lengths long, at least `MIN_ROW_MM`: the flow reaches full
/// speed well before the middle switch.
pub const ROW_TRANSITS: f64 = 5.0;

/// Shortest row, mm.
pub const MIN_ROW_MM: f64 = 14.0;

/// `base` laid out for the pattern: every row its own bead (rows never joined), so the
/// flow starts from rest at each.
pub fn path_options(base: PathOptions) -> PathOptions {
    PathOptions {
        connect_mm: Some(-1.0),
        ..base
    }
}

/// The pattern for `materials` inlets, beads `pitch` wide, `transit` mm of bead between
/// valves and plate. Rows are listed in print order and laid out so that the toolpath,
/// which runs them back and forth starting from the left, prints each row's runs in the
/// order given here.
pub fn pattern(materials: usize, pitch: f64, transit: f64) -> Design {
    let len = (ROW_TRANSITS * transit).max(MIN_ROW_MM);
    let first: Vec<f64> = FIRST_SWITCH_MM
        .iter()
        .map(|d| (transit + d).max(MIN_FIRST_MM).max(1.25 * pitch))
        .collect();
    // Rows in print order: (runs along the print direction as (from, to, material)).
    let mut rows: Vec<Vec<(f64, f64, u8)>> = Vec::new();
    let mut last: Option<u8> = None;
    for a in 0..materials as u8 {
        for b in 0..materials as u8 {
            if a == b {
                continue;
            }
            // A row that hands over from the previous pair's material to `a` first, so
            // each measured row starts in the material the channel holds.
            if let Some(l) = last.filter(|&l| l != a) {
                rows.push(vec![(0.0, len / 2.0, l), (len / 2.0, len, a)]);
            }
            for &s in &first {
                rows.push(vec![(0.0, s, a), (s, len / 2.0, b), (len / 2.0, len, a)]);
            }
            last = Some(a);
        }
    }
    let mut layer = Layer::new();
    for (k, row) in rows.iter().enumerate() {
        // Odd rows are printed right to left.
        let mut runs: Vec<Run> = row
            .iter()
            .map(|&(s0, s1, m)| {
                if k % 2 == 0 {
                    Run {
                        x0: s0,
                        x1: s1,
                        material: m,
                    }
                } else {
                    Run {
                        x0: len - s1,
                        x1: len - s0,
                        material: m,
                    }
                }
            })
            .collect();
        runs.sort_by(|p, q| p.x0.total_cmp(&q.x0));
        layer.push_row(&mut runs, 0.0);
    }
    Design {
        name: "calibration pattern".into(),
        size_mm: [len, rows.len() as f64 * pitch],
        pitch_mm: pitch,
        layers: vec![layer],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_ordered_pair_switches_at_every_distance() {
        let d = pattern(3, 0.8, 2.7);
        let l = &d.layers[0];
        // 6 ordered pairs of 7 rows, and a hand-over row where the first material changes
        // (0->1, 0->2 | 1->0, 1->2 | 2->0, 2->1): two.
        assert_eq!(l.rows(), 6 * 7 + 2);
        assert_eq!(d.size_mm, [14.0, 44.0 * 0.8]);
        // Row 1 is printed right to left: its first switch, 2.4 mm from its start (2.7 -
        // 0.3), lies 2.4 mm from its right end.
        let r = l.row(1);
        assert_eq!(r.len(), 3);
        assert!((r[2].x0 - 11.6).abs() < 1e-9 && r[2].material == 0, "{r:?}");
        assert!((r[0].x1 - 7.0).abs() < 1e-9 && r[0].material == 0);
        assert_eq!(r[1].material, 1);
        // The closest switch is kept 2 mm from the row's start.
        let d = pattern(2, 0.8, 1.0);
        assert!((d.layers[0].row(0)[0].x1 - 2.0).abs() < 1e-9);
    }
}
