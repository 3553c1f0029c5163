//! Registering the photo to the job: the print's outline as four corners (the extreme
//! points along the diagonals, refined by fitting a straight line to each side's outline
//! pixels and intersecting them), the homography from those corners to the footprint of
//! the design, and the photo resampled into the design's frame. Which of the four
//! rotations is right is decided by the caller from the colours.

use super::frame::DesignFrame;
use super::measure::Drift;
use super::photo::Photo;
use image::{GrayImage, Rgb, RgbImage};
use imageproc::geometric_transformations::{warp_into_with, Border, Interpolation, Projection};

/// The print's four corners in the photo, top-left, top-right, bottom-right,
/// bottom-left (as the photo shows them), sub-pixel. The outline is taken as its convex
/// hull (over the pixels' own corners), so the round ends of the rows and the notches
/// between them do not pull a side inward: each side is the line through the hull
/// vertices along it, and the corners are where those lines meet. `None` when the
/// outline is not a quadrilateral it can fit.
pub fn corners(print: &GrayImage) -> Option<[[f64; 2]; 4]> {
    let (w, h) = print.dimensions();
    let inside = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && x < w as i64
            && y < h as i64
            && print.get_pixel(x as u32, y as u32)[0] > 0
    };
    let mut edge: Vec<imageproc::point::Point<i64>> = Vec::new();
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if inside(x, y)
                && (!inside(x - 1, y)
                    || !inside(x + 1, y)
                    || !inside(x, y - 1)
                    || !inside(x, y + 1))
            {
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    edge.push(imageproc::point::Point::new(x + dx, y + dy));
                }
            }
        }
    }
    if edge.len() < 64 {
        return None;
    }
    let hull: Vec<[f64; 2]> = imageproc::geometry::convex_hull(edge)
        .into_iter()
        .map(|p| [p.x as f64, p.y as f64])
        .collect();
    if hull.len() < 4 {
        return None;
    }
    let pick = |f: &dyn Fn(&[f64; 2]) -> f64| {
        *hull
            .iter()
            .max_by(|a, b| f(a).total_cmp(&f(b)))
            .expect("hull is not empty")
    };
    let rough = [
        pick(&|p| -p[0] - p[1]),
        pick(&|p| p[0] - p[1]),
        pick(&|p| p[0] + p[1]),
        pick(&|p| -p[0] + p[1]),
    ];
    let mut lines = Vec::with_capacity(4);
    for k in 0..4 {
        let (a, b) = (rough[k], rough[(k + 1) % 4]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = d[0].hypot(d[1]);
        if len < 8.0 {
            return None;
        }
        let u = [d[0] / len, d[1] / len];
        let along = |lo: f64, hi: f64| -> Vec<[f64; 2]> {
            hull.iter()
                .filter(|p| {
                    let r = [p[0] - a[0], p[1] - a[1]];
                    let t = r[0] * u[0] + r[1] * u[1];
                    let off = (r[0] * u[1] - r[1] * u[0]).abs();
                    t >= lo * len && t <= hi * len && off < (0.03 * len).max(3.0)
                })
                .copied()
                .collect()
        };
        // Away from the rounded corners where the vertices there span enough of the side
        // to give its direction; else the whole side; else the corners themselves.
        let extent = |v: &[[f64; 2]]| {
            let t = v
                .iter()
                .map(|p| (p[0] - a[0]) * u[0] + (p[1] - a[1]) * u[1]);
            let (lo, hi) = t.fold((f64::INFINITY, f64::NEG_INFINITY), |m, x| {
                (m.0.min(x), m.1.max(x))
            });
            hi - lo
        };
        let mut near = along(0.1, 0.9);
        if near.len() < 2 || extent(&near) < 0.3 * len {
            near = along(0.0, 1.0);
        }
        if near.len() < 2 || extent(&near) < 0.3 * len {
            near = vec![a, b];
        }
        lines.push(fit_line(&near)?);
    }
    let mut out = [[0.0; 2]; 4];
    for k in 0..4 {
        // Corner k is where side k-1 (into it) meets side k (out of it).
        out[k] = intersect(lines[(k + 3) % 4], lines[k])?;
    }
    Some(out)
}

/// Total least squares line through `pts`: (a point, unit direction).
fn fit_line(pts: &[[f64; 2]]) -> Option<([f64; 2], [f64; 2])> {
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let c = [
        pts.iter().map(|p| p[0]).sum::<f64>() / n,
        pts.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some((c, [theta.cos(), theta.sin()]))
}

fn intersect(l1: ([f64; 2], [f64; 2]), l2: ([f64; 2], [f64; 2])) -> Option<[f64; 2]> {
    let (p, r) = l1;
    let (q, s) = l2;
    let den = r[0] * s[1] - r[1] * s[0];
    if den.abs() < 1e-6 {
        return None;
    }
    let t = ((q[0] - p[0]) * s[1] - (q[1] - p[1]) * s[0]) / den;
    Some([p[0] + t * r[0], p[1] + t * r[1]])
}

/// The homography taking the photo's corners to the frame's footprint corners, the
/// photo's corner list turned by `turn` quarter turns (0..4).
pub fn projection(photo: [[f64; 2]; 4], frame: &DesignFrame, turn: usize) -> Option<Projection> {
    projection_to(photo, frame.corners(), turn)
}

/// The homography taking the photo's corners (turned by `turn`) to `to`, frame pixels.
pub fn projection_to(photo: [[f64; 2]; 4], to: [[f64; 2]; 4], turn: usize) -> Option<Projection> {
    let from: [(f32, f32); 4] = std::array::from_fn(|k| {
        (
            photo[(k + turn) % 4][0] as f32,
            photo[(k + turn) % 4][1] as f32,
        )
    });
    let to: [(f32, f32); 4] = std::array::from_fn(|k| (to[k][0] as f32, to[k][1] as f32));
    Projection::from_control_points(from, to)
}

/// The photo's evened colours resampled into `frame` through `proj` (bilinear; outside
/// the photo reads as plate), as f32 RGB and as an 8-bit picture for people. With
/// `drift`, each frame pixel reads the photo where `drift` says its content shows, in the
/// same single resampling (labels resampled a second time would drop or double the
/// one-pixel slivers of plate between beads).
pub fn rectify(
    photo: &Photo,
    frame: &DesignFrame,
    proj: Projection,
    drift: Option<&Drift>,
) -> (Vec<[f32; 3]>, RgbImage) {
    let (w, h) = frame.size();
    let back = proj.invert();
    let ppm = frame.px_per_mm;
    let drift = drift.copied();
    // Frame pixel (its centre at +0.5, as `to_px` has it) to where the photo shows it.
    let mapping = move |x: f32, y: f32| -> (f32, f32) {
        let (mut fx, mut fy) = (x as f64, y as f64);
        if let Some(d) = drift {
            let p = [
                (fx + 0.5) / ppm - frame.margin_mm + frame.lo[0],
                frame.hi[1] + frame.margin_mm - (fy + 0.5) / ppm,
            ];
            let e = d.at(p);
            fx += e[0] * ppm;
            fy -= e[1] * ppm;
        }
        back * (fx as f32, fy as f32)
    };
    // Three channels in f32 through imageproc's warp, one image per channel.
    let mut out = vec![[1.0f32; 3]; (w * h) as usize];
    for k in 0..3 {
        let src = image::ImageBuffer::<image::Luma<f32>, Vec<f32>>::from_fn(
            photo.size.0,
            photo.size.1,
            |x, y| image::Luma([photo.get(x, y)[k]]),
        );
        let mut dst = image::ImageBuffer::<image::Luma<f32>, Vec<f32>>::new(w, h);
        warp_into_with(
            &src,
            mapping,
            Interpolation::Bilinear,
            Border::Constant(image::Luma([1.0])),
            &mut dst,
        );
        for (o, p) in out.iter_mut().zip(dst.pixels()) {
            o[k] = p[0];
        }
    }
    let plate = photo.plate;
    let pic = RgbImage::from_fn(w, h, |x, y| {
        let c = out[(y * w + x) as usize];
        Rgb(std::array::from_fn(|k| {
            (c[k] * plate[k] * 255.0).clamp(0.0, 255.0) as u8
        }))
    });
    (out, pic)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_corners_of_a_turned_rectangle_are_found_within_a_pixel() {
        // A 300 x 200 px rectangle turned by 12 degrees about (320, 240).
        let (c, s) = (12f64.to_radians().cos(), 12f64.to_radians().sin());
        let turn = |p: [f64; 2]| [320.0 + c * p[0] - s * p[1], 240.0 + s * p[0] + c * p[1]];
        let want = [
            turn([-150.0, -100.0]),
            turn([150.0, -100.0]),
            turn([150.0, 100.0]),
            turn([-150.0, 100.0]),
        ];
        let img = GrayImage::from_fn(640, 480, |x, y| {
            let (dx, dy) = (x as f64 + 0.5 - 320.0, y as f64 + 0.5 - 240.0);
            let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
            image::Luma([if u.abs() <= 150.0 && v.abs() <= 100.0 {
                255
            } else {
                0
            }])
        });
        let got = corners(&img).expect("four corners");
        for k in 0..4 {
            let e = (got[k][0] - want[k][0]).hypot(got[k][1] - want[k][1]);
            assert!(
                e < 1.0,
                "corner {k}: {:?} vs {:?} ({e} px)",
                got[k],
                want[k]
            );
        }
    }
}
