//! Filament width in one frame: Canny edges (imageproc) with thresholds set from the
//! frame's own gradients, the outermost edge pair of each row as the filament's sides,
//! each refined to sub-pixel by a parabola through the horizontal gradient. Which rows
//! to use is the caller's choice.

use image::GrayImage;
use imageproc::edges::canny;
use imageproc::filter::gaussian_blur_f32;
use imageproc::gradients::{horizontal_sobel, vertical_sobel};

/// The same blur imageproc's Canny applies, so the refinement sees the edges it found.
const SIGMA: f32 = 1.4;

/// One row's filament sides, px (sub-pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sides {
    /// Row.
    pub y: u32,
    /// Left side.
    pub left: f64,
    /// Right side.
    pub right: f64,
}

impl Sides {
    /// Width, px.
    pub fn width(&self) -> f64 {
        self.right - self.left
    }
}

/// Rectangle of interest, px.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Roi {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width.
    pub w: u32,
    /// Height.
    pub h: u32,
}

impl Roi {
    /// The whole `w` x `h` frame.
    pub fn full(w: u32, h: u32) -> Roi {
        Roi { x: 0, y: 0, w, h }
    }
    /// This rectangle clipped to a `w` x `h` frame.
    pub fn clip(self, w: u32, h: u32) -> Roi {
        let x = self.x.min(w);
        let y = self.y.min(h);
        Roi {
            x,
            y,
            w: self.w.min(w - x),
            h: self.h.min(h - y),
        }
    }
}

/// Sides of the filament in every row of `roi` where both are found.
pub fn sides(frame: &GrayImage, roi: Roi) -> Vec<Sides> {
    let (w, h) = frame.dimensions();
    if w < 5 || h < 5 {
        return Vec::new();
    }
    let blurred = gaussian_blur_f32(frame, SIGMA);
    let gx = horizontal_sobel(&blurred);
    let gy = vertical_sobel(&blurred);
    let mut mags: Vec<f32> = gx
        .pixels()
        .zip(gy.pixels())
        .map(|(a, b)| (a[0] as f32).hypot(b[0] as f32))
        .collect();
    mags.sort_by(f32::total_cmp);
    let p99 = mags[(mags.len() - 1) * 99 / 100];
    if p99 <= 0.0 {
        return Vec::new();
    }
    // Canny's Sobel runs on the blurred frame as above; 40 % of the strongest gradients
    // keeps the filament's sides and drops most of the texture inside it.
    let high = 0.4 * p99;
    let edges = canny(frame, 0.5 * high, high);
    let mut out = Vec::new();
    let x_end = roi.x + roi.w;
    for y in roi.y..roi.y + roi.h {
        let mut first = None;
        let mut last = None;
        for x in roi.x..x_end {
            if edges.get_pixel(x, y)[0] > 0 {
                first.get_or_insert(x);
                last = Some(x);
            }
        }
        let (Some(l), Some(r)) = (first, last) else {
            continue;
        };
        if r <= l + 2 {
            continue;
        }
        let g = |x: i64| -> f64 {
            let x = x.clamp(0, w as i64 - 1) as u32;
            (gx.get_pixel(x, y)[0] as f64).abs()
        };
        let left = refine(l as i64, &g);
        let right = refine(r as i64, &g);
        out.push(Sides { y, left, right });
    }
    out
}

/// Sub-pixel position of the gradient peak near column `x`: the largest |gx| within two
/// pixels, then the vertex of the parabola through it and its neighbours.
fn refine(x: i64, g: &dyn Fn(i64) -> f64) -> f64 {
    let peak = (x - 2..=x + 2)
        .max_by(|&a, &b| g(a).total_cmp(&g(b)))
        .unwrap_or(x);
    let (a, b, c) = (g(peak - 1), g(peak), g(peak + 1));
    let denom = a - 2.0 * b + c;
    let offset = if denom < 0.0 {
        (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    peak as f64 + offset
}

/// Median of `v` (NaN-free), `None` when empty.
pub fn median(v: &[f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    Some(if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    })
}
