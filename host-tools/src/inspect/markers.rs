//! Registering a photo by the job's corner markers (`dollop slice --markers`): the four
//! L-shaped regions apart from the print are picked by size and shape, put in order
//! around their centre starting from the one with long legs, and matched to the design's
//! markers; a homography from their centres is then refined from each L's corner, found
//! where the centre lines of its two legs cross (each leg's middle, away from its ends
//! and the corner, so neither a bead's start nor its width moves it). Registration by the
//! print's outline is `register`'s.

use super::design::{Marker, Plan};
use super::frame::DesignFrame;
use super::photo::{Blob, Photo};
use imageproc::geometric_transformations::Projection;

/// Frame pixel to design point, mm.
fn to_mm(frame: &DesignFrame, q: [f64; 2]) -> [f64; 2] {
    [
        q[0] / frame.px_per_mm - frame.margin_mm + frame.lo[0],
        frame.hi[1] + frame.margin_mm - q[1] / frame.px_per_mm,
    ]
}

fn apply(p: &Projection, q: [f64; 2]) -> [f64; 2] {
    let (x, y) = *p * (q[0] as f32, q[1] as f32);
    [x as f64, y as f64]
}

/// Centre of the area a marker's bead covers (`pitch` wide, round ends), mm, and that
/// area, mm^2, by sampling a 0.02 mm grid.
fn centre(m: &Marker, pitch: f64) -> ([f64; 2], f64) {
    let r = pitch / 2.0;
    let pts = [m.ends[0], m.corner, m.ends[1]];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in pts {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a] - r);
            hi[a] = hi[a].max(p[a] + r);
        }
    }
    let near = |q: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let d = [b[0] - a[0], b[1] - a[1]];
        let l2 = (d[0] * d[0] + d[1] * d[1]).max(1e-12);
        let t = (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / l2).clamp(0.0, 1.0);
        (q[0] - a[0] - t * d[0]).hypot(q[1] - a[1] - t * d[1]) <= r
    };
    let step = 0.02;
    let (mut c, mut n) = ([0.0f64; 2], 0.0f64);
    let mut y = lo[1] + step / 2.0;
    while y < hi[1] {
        let mut x = lo[0] + step / 2.0;
        while x < hi[0] {
            if near([x, y], pts[0], pts[1]) || near([x, y], pts[1], pts[2]) {
                c[0] += x;
                c[1] += y;
                n += 1.0;
            }
            x += step;
        }
        y += step;
    }
    ([c[0] / n.max(1.0), c[1] / n.max(1.0)], n * step * step)
}

/// Indices of `pts` in order of angle about their mean (frame or photo pixels, y down:
/// clockwise as seen), starting from `first`.
fn around(pts: &[[f64; 2]; 4], first: usize) -> [usize; 4] {
    let c = [
        pts.iter().map(|p| p[0]).sum::<f64>() / 4.0,
        pts.iter().map(|p| p[1]).sum::<f64>() / 4.0,
    ];
    let ang = |i: usize| (pts[i][1] - c[1]).atan2(pts[i][0] - c[0]);
    let mut idx = [0, 1, 2, 3];
    idx.sort_by(|&a, &b| ang(a).total_cmp(&ang(b)));
    let k = idx.iter().position(|&i| i == first).unwrap_or(0);
    std::array::from_fn(|j| idx[(k + j) % 4])
}

/// The photo's positions of the footprint's corners (`frame.corners()` order, no turn
/// left to decide), registered by the markers; `None` when the plan has no markers or the
/// photo does not show four regions that look like them.
pub fn register(photo: &Photo, plan: &Plan, frame: &DesignFrame) -> Option<[[f64; 2]; 4]> {
    let markers = plan.markers?;
    let pitch = plan.pitch;
    // Photo pixels per mm^2, from the print's area against the design's.
    let design_mm2: f64 = plan.beads.iter().map(|b| b.length() * pitch).sum();
    let px_per_mm2 = photo.print_px as f64 / design_mm2.max(1e-9);
    let short = markers
        .iter()
        .map(Marker::leg)
        .fold(f64::INFINITY, f64::min);
    let want = 2.0 * short * pitch * px_per_mm2;
    let found: Vec<&Blob> = photo
        .blobs
        .iter()
        .filter(|b| {
            let a = b.px.len() as f64;
            (0.35 * want..=3.0 * want).contains(&a) && b.elongation() < 10.0
        })
        .collect();
    if found.len() != 4 {
        return None;
    }
    // Which one has the long legs: perspective can make a near marker look as large, so
    // each region's area is taken back to the design's scale through the homography that
    // each of the four choices gives, and the choice under which the areas agree best with
    // the design's (up to a common factor: the beads may be wider or narrower) wins.
    let photo_c: [[f64; 2]; 4] = std::array::from_fn(|i| found[i].centroid());
    let design: [([f64; 2], f64); 4] = std::array::from_fn(|i| centre(&markers[i], pitch));
    let design_c: [[f64; 2]; 4] = std::array::from_fn(|i| frame.to_px(design[i].0));
    let long_design = (0..4).max_by(|&a, &b| markers[a].leg().total_cmp(&markers[b].leg()))?;
    let dorder = around(&design_c, long_design);
    let mut best: Option<(f64, [usize; 4], Projection)> = None;
    let mut scores = Vec::new();
    for first in 0..4 {
        let po = around(&photo_c, first);
        let from: [[f64; 2]; 4] = std::array::from_fn(|j| photo_c[po[j]]);
        let to: [[f64; 2]; 4] = std::array::from_fn(|j| design_c[dorder[j]]);
        let Some(proj) = homography(from, to) else {
            continue;
        };
        let logs: Vec<f64> = (0..4)
            .map(|j| {
                let seen = found[po[j]].px.len() as f64 * jacobian(&proj, from[j]);
                let want = design[dorder[j]].1 * frame.px_per_mm * frame.px_per_mm;
                (seen / want.max(1e-9)).max(1e-9).ln()
            })
            .collect();
        let mean = logs.iter().sum::<f64>() / 4.0;
        let score: f64 = logs.iter().map(|l| (l - mean).powi(2)).sum();
        scores.push(score);
        if best.as_ref().is_none_or(|b| score < b.0) {
            best = Some((score, po, proj));
        }
    }
    let (score, po, mut proj) = best?;
    // The long legs must stand out: the next best choice fits clearly worse.
    scores.sort_by(f64::total_cmp);
    if scores.len() < 2 || scores[1] < 4.0 * score.max(1e-4) {
        return None;
    }
    // Refine from the corners of the Ls, read through the projection so far.
    for _ in 0..3 {
        let inv = proj.invert();
        let mut from = [[0.0; 2]; 4];
        let mut to = [[0.0; 2]; 4];
        for j in 0..4 {
            let m = &markers[dorder[j]];
            let blob = found[po[j]];
            let seen = leg_corner(m, blob, &proj, frame, pitch)?;
            from[j] = apply(&inv, frame.to_px(seen));
            to[j] = frame.to_px(m.corner);
        }
        proj = homography(from, to)?;
    }
    let inv = proj.invert();
    Some(frame.corners().map(|q| apply(&inv, q)))
}

/// Area scale of `proj` at photo point `p`: frame px^2 per photo px^2.
fn jacobian(proj: &Projection, p: [f64; 2]) -> f64 {
    let h = 2.0;
    let a = apply(proj, [p[0] - h, p[1]]);
    let b = apply(proj, [p[0] + h, p[1]]);
    let c = apply(proj, [p[0], p[1] - h]);
    let d = apply(proj, [p[0], p[1] + h]);
    let (dx, dy) = (
        [(b[0] - a[0]) / (2.0 * h), (b[1] - a[1]) / (2.0 * h)],
        [(d[0] - c[0]) / (2.0 * h), (d[1] - c[1]) / (2.0 * h)],
    );
    (dx[0] * dy[1] - dx[1] * dy[0]).abs()
}

fn homography(from: [[f64; 2]; 4], to: [[f64; 2]; 4]) -> Option<Projection> {
    Projection::from_control_points(
        from.map(|p| (p[0] as f32, p[1] as f32)),
        to.map(|p| (p[0] as f32, p[1] as f32)),
    )
}

/// Where the photo, read through `proj` (photo to frame pixels), shows marker `m`'s
/// corner, mm: each leg's centre line is the mean offset of its pixels between a pitch
/// from the corner and a pitch from its end.
fn leg_corner(
    m: &Marker,
    blob: &Blob,
    proj: &Projection,
    frame: &DesignFrame,
    pitch: f64,
) -> Option<[f64; 2]> {
    let u = [m.dir(0), m.dir(1)];
    let len = m.leg();
    let mut sum = [0.0f64; 2];
    let mut n = [0usize; 2];
    for p in &blob.px {
        let q = to_mm(frame, apply(proj, [p[0] as f64 + 0.5, p[1] as f64 + 0.5]));
        let r = [q[0] - m.corner[0], q[1] - m.corner[1]];
        for k in 0..2 {
            let t = r[0] * u[k][0] + r[1] * u[k][1];
            let o = r[0] * u[1 - k][0] + r[1] * u[1 - k][1];
            if t >= pitch && t <= len - pitch && o.abs() < pitch {
                sum[k] += o;
                n[k] += 1;
            }
        }
    }
    if n[0] < 20 || n[1] < 20 {
        return None;
    }
    let o = [sum[0] / n[0] as f64, sum[1] / n[1] as f64];
    // Leg 0's centre line is offset along leg 1's direction, and the other way round.
    Some([
        m.corner[0] + o[0] * u[1][0] + o[1] * u[0][0],
        m.corner[1] + o[0] * u[1][1] + o[1] * u[0][1],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_of_an_l_is_a_quarter_of_the_way_along_its_legs() {
        // Legs of length a from the origin along +x and +y, width w, round ends: by
        // symmetry the centre lies on the diagonal; for thin legs it tends to a/4 each way.
        let m = Marker {
            corner: [0.0, 0.0],
            ends: [[10.0, 0.0], [0.0, 10.0]],
        };
        let (c, area) = centre(&m, 0.1);
        // Two capsules (10 x 0.1 and round ends) overlapping at the corner in a 0.05 mm
        // square and three quarter disks.
        let (r2, pi) = (0.05f64 * 0.05, std::f64::consts::PI);
        let want = 2.0 * (1.0 + pi * r2) - (r2 + 0.75 * pi * r2);
        assert!((area - want).abs() < 0.002, "{area} vs {want}");
        assert!((c[0] - c[1]).abs() < 1e-3, "{c:?}");
        assert!((c[0] - 2.5).abs() < 0.02, "{c:?}");
    }

    #[test]
    fn points_go_round_clockwise_as_seen_from_the_first() {
        // y down: top-left, top-right, bottom-right, bottom-left.
        let pts = [[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]];
        assert_eq!(around(&pts, 2), [2, 1, 3, 0]);
    }
}
