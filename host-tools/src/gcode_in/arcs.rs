//! G2/G3 arcs (XY plane) as straight segments whose sagitta (the largest distance between
//! the arc and its chord) is at most a stated chord error. Centres come from I/J offsets
//! or from R; the caller spreads E and Z over the points.

use std::f64::consts::TAU;

/// Most segments one arc may become (a 10 m radius at 0.001 mm chord error needs about
/// 7 000): bounds the work a single line can cause.
pub const MAX_ARC_SEGMENTS: usize = 20_000;

/// Radius below which an arc is drawn as its chord, mm.
const TINY_RADIUS_MM: f64 = 1e-6;

/// The points after `start` along the arc to `end` about `center`, clockwise for G2,
/// `end` last. Start equal to end is a full circle. `Err` says what is wrong.
pub fn points(
    start: [f64; 2],
    end: [f64; 2],
    center: [f64; 2],
    clockwise: bool,
    chord_err_mm: f64,
) -> Result<Vec<[f64; 2]>, String> {
    let r0 = (start[0] - center[0]).hypot(start[1] - center[1]);
    let r1 = (end[0] - center[0]).hypot(end[1] - center[1]);
    if !(r0.is_finite() && r1.is_finite()) {
        return Err("arc centre is not finite".into());
    }
    if r0 < TINY_RADIUS_MM {
        return Ok(vec![end]);
    }
    // Slicers round centres to 3 decimals: the two radii differ by that much.
    if (r0 - r1).abs() > 0.01_f64.max(r0 * 1e-3) {
        return Err(format!(
            "arc end is {r1:.4} mm from the centre but its start {r0:.4} mm (wrong I/J?)"
        ));
    }
    let a0 = (start[1] - center[1]).atan2(start[0] - center[0]);
    let a1 = (end[1] - center[1]).atan2(end[0] - center[0]);
    let mut sweep = a1 - a0;
    if clockwise {
        if sweep >= 0.0 {
            sweep -= TAU;
        }
    } else if sweep <= 0.0 {
        sweep += TAU;
    }
    // Start equal to end: a full circle; a hair apart, the small arc the numbers say.
    let r = 0.5 * (r0 + r1);
    let step = if chord_err_mm >= r {
        std::f64::consts::PI
    } else {
        2.0 * (1.0 - chord_err_mm / r).acos()
    };
    let n = (sweep.abs() / step).ceil().max(1.0);
    if n > MAX_ARC_SEGMENTS as f64 {
        return Err(format!(
            "arc of radius {r:.1} mm needs {n} segments at the chord error, more than {MAX_ARC_SEGMENTS} (raise --chord-mm)"
        ));
    }
    let n = n as usize;
    let mut out = Vec::with_capacity(n);
    for k in 1..n {
        let a = a0 + sweep * k as f64 / n as f64;
        // The radius eases from start to end so the last point meets `end` exactly.
        let rk = r0 + (r1 - r0) * k as f64 / n as f64;
        out.push([center[0] + rk * a.cos(), center[1] + rk * a.sin()]);
    }
    out.push(end);
    Ok(out)
}

/// The centre of the arc of radius `r` from `start` to `end` (negative `r`: the larger
/// arc, as G-code's R form says).
pub fn center_from_radius(
    start: [f64; 2],
    end: [f64; 2],
    r: f64,
    clockwise: bool,
) -> Result<[f64; 2], String> {
    let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
    let d = dx.hypot(dy);
    if d == 0.0 {
        return Err("R-form arc with its end at its start (use I/J for a full circle)".into());
    }
    let half = d / 2.0;
    if r.abs() < half - 1e-6 {
        return Err(format!(
            "arc radius {:.4} mm is shorter than half the {d:.4} mm chord",
            r.abs()
        ));
    }
    let h = (r * r - half * half).max(0.0).sqrt();
    // Left of the chord for a counter-clockwise short arc; the sign of R and the direction
    // flip it.
    let mut side = if clockwise { -1.0 } else { 1.0 };
    if r < 0.0 {
        side = -side;
    }
    let mid = [start[0] + dx / 2.0, start[1] + dy / 2.0];
    Ok([mid[0] - side * h * dy / d, mid[1] + side * h * dx / d])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest distance from the true circle to any chord's midpoint.
    fn sagitta(pts: &[[f64; 2]], start: [f64; 2], c: [f64; 2], r: f64) -> f64 {
        let mut prev = start;
        let mut worst: f64 = 0.0;
        for p in pts {
            let m = [(prev[0] + p[0]) / 2.0, (prev[1] + p[1]) / 2.0];
            worst = worst.max(r - (m[0] - c[0]).hypot(m[1] - c[1]));
            prev = *p;
        }
        worst
    }

    #[test]
    fn quarter_and_full_circles_stay_within_the_chord_error() {
        for &(err, cw) in &[(0.01, false), (0.001, true), (0.05, false)] {
            let pts = points([10.0, 0.0], [0.0, 10.0], [0.0, 0.0], cw, err).unwrap();
            assert!(sagitta(&pts, [10.0, 0.0], [0.0, 0.0], 10.0) <= err + 1e-12);
            assert_eq!(*pts.last().unwrap(), [0.0, 10.0]);
            // Clockwise from (10,0) to (0,10) goes three quarters round.
            let far = pts.iter().any(|p| p[1] < -5.0);
            assert_eq!(far, cw);
        }
        let full = points([5.0, 0.0], [5.0, 0.0], [0.0, 0.0], false, 0.01).unwrap();
        assert!(full.len() > 20);
        assert!(full.iter().any(|p| p[0] < -4.9));
    }

    #[test]
    fn radius_form_and_bad_arcs() {
        let c = center_from_radius([0.0, 0.0], [10.0, 0.0], 5.0, false).unwrap();
        assert!((c[0] - 5.0).abs() < 1e-9 && c[1].abs() < 1e-9);
        assert!(center_from_radius([0.0, 0.0], [10.0, 0.0], 4.0, false).is_err());
        assert!(points([10.0, 0.0], [0.0, 3.0], [0.0, 0.0], false, 0.01).is_err());
        assert!(points([1e7, 0.0], [0.0, 1e7], [0.0, 0.0], false, 1e-6).is_err());
    }
}
