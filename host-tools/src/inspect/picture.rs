//! The picture `dollop inspect` writes: the photo rectified into the design's frame, the
//! footprint outlined, each design boundary drawn across its bead and the landed one
//! beside it coloured by its offset (green within 0.05 mm, yellow within 0.2 mm, red
//! beyond), boundaries not found in grey; framed on mm axes with a key (`figure`) for the
//! file `dollop inspect --picture` writes.

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

/// What the picture shows, mm (lower-left, upper-right): the whole print, design and corner
/// markers, with two pitches of plate around it. The frame's margin is as wide on every
/// side as the farthest marker needs, so the picture crops to this.
pub fn shown_mm(i: &Inspection) -> ([f64; 2], [f64; 2]) {
    let (lo, hi) = i.plan.extent();
    let pad = 2.0 * i.plan.pitch;
    ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad])
}

/// Smallest width of the framed picture's plate, pixels: a photo rectified at the
/// measuring resolution can be a few hundred pixels, too small to read the marks.
pub const MIN_PLATE_PX: u32 = 1000;

/// The picture for a person: the inspection drawn over the rectified photo, enlarged to at
/// least [`MIN_PLATE_PX`] wide, on mm axes with a key to its marks.
pub fn figure(i: &Inspection) -> Result<RgbImage, String> {
    let f = &i.frame;
    let (lo, hi) = shown_mm(i);
    let full = draw(i);
    let a = f.to_px([lo[0], hi[1]]);
    let z = f.to_px([hi[0], lo[1]]);
    let x0 = (a[0].floor().max(0.0) as u32).min(full.width().saturating_sub(1));
    let y0 = (a[1].floor().max(0.0) as u32).min(full.height().saturating_sub(1));
    let x1 = (z[0].ceil().max(0.0) as u32).clamp(x0 + 1, full.width().max(x0 + 1));
    let y1 = (z[1].ceil().max(0.0) as u32).clamp(y0 + 1, full.height().max(y0 + 1));
    let img = image::imageops::crop_imm(&full, x0, y0, x1 - x0, y1 - y0).to_image();
    let (w, h) = (img.width().max(1), img.height().max(1));
    let img = if w < MIN_PLATE_PX {
        let k = MIN_PLATE_PX as f64 / w as f64;
        image::imageops::resize(
            &img,
            MIN_PLATE_PX,
            (h as f64 * k).round() as u32,
            image::imageops::FilterType::Triangle,
        )
    } else {
        img
    };
    let plate = crate::figure::Plate {
        caption: String::new(),
        x_mm: (
            f.lo[0] - f.margin_mm + x0 as f64 / f.px_per_mm,
            f.lo[0] - f.margin_mm + (x0 + w) as f64 / f.px_per_mm,
        ),
        y_mm: (
            f.hi[1] + f.margin_mm - (y0 + h) as f64 / f.px_per_mm,
            f.hi[1] + f.margin_mm - y0 as f64 / f.px_per_mm,
        ),
        img,
    };
    use crate::figure::Key;
    let key = [
        Key::Line("design boundary, across its bead".into(), [255, 255, 255]),
        Key::Line("the design's footprint".into(), [255, 255, 255]),
        Key::Dot("landed within 0.05 mm".into(), offset_colour(0.0).0),
        Key::Dot("landed within 0.2 mm".into(), offset_colour(0.1).0),
        Key::Dot("landed more than 0.2 mm off".into(), offset_colour(1.0).0),
        Key::Dot("not found in the photo".into(), [128, 128, 128]),
        Key::Note(format!("photo rectified at {:.1} px/mm", f.px_per_mm)),
    ];
    crate::figure::framed(
        "where the boundaries landed",
        std::slice::from_ref(&plate),
        1,
        &key,
    )
}
