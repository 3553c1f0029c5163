//! The picture `dollop inspect` writes: the photo rectified into the design's frame, the
//! footprint outlined, each design boundary drawn across its bead and the landed one
//! beside it coloured by its offset (green within 0.05 mm, yellow within 0.2 mm, red
//! beyond), boundaries not found in grey.

use super::Inspection;
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_filled_circle_mut, draw_hollow_rect_mut, draw_line_segment_mut};
use imageproc::rect::Rect;

/// Colour for an offset of `e` mm.
pub fn offset_colour(e: f64) -> Rgb<u8> {
    let e = e.abs();
    if e <= 0.05 {
        Rgb([40, 200, 60])
    } else if e <= 0.2 {
        Rgb([240, 200, 30])
    } else {
        Rgb([230, 40, 40])
    }
}

/// Draws the inspection over its rectified photo.
pub fn draw(i: &Inspection) -> RgbImage {
    let mut img = i.rectified.clone();
    let f = &i.frame;
    let c = f.corners();
    let (x0, y0) = (c[0][0] as i32, c[0][1] as i32);
    let (w, h) = ((c[2][0] - c[0][0]) as u32, (c[2][1] - c[0][1]) as u32);
    if w > 0 && h > 0 {
        draw_hollow_rect_mut(
            &mut img,
            Rect::at(x0, y0).of_size(w, h),
            Rgb([255, 255, 255]),
        );
    }
    let half = i.plan.pitch / 2.0;
    let r = ((0.12 * f.px_per_mm).round() as i32).max(2);
    let mut found = vec![None; i.plan.boundaries.len()];
    for x in &i.found {
        found[x.index] = Some(x.offset);
    }
    for (k, b) in i.plan.boundaries.iter().enumerate() {
        let bead = &i.plan.beads[b.bead];
        let (p, u) = bead.at(b.s);
        let n = [-u[1], u[0]];
        let a = f.to_px([p[0] + n[0] * half, p[1] + n[1] * half]);
        let z = f.to_px([p[0] - n[0] * half, p[1] - n[1] * half]);
        draw_line_segment_mut(
            &mut img,
            (a[0] as f32, a[1] as f32),
            (z[0] as f32, z[1] as f32),
            Rgb([255, 255, 255]),
        );
        let (at, colour) = match found[k] {
            Some(e) => (bead.at(b.s + e).0, offset_colour(e)),
            None => (p, Rgb([128, 128, 128])),
        };
        let q = f.to_px(at);
        draw_filled_circle_mut(&mut img, (q[0] as i32, q[1] as i32), r, colour);
    }
    img
}
