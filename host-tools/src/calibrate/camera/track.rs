//! Pyramidal Lucas-Kanade optical flow (Bouguet's formulation): Gaussian pyramids of two
//! frames, and for each point the displacement that best matches a window of the first
//! frame in the second, refined from the coarsest level to the finest with bilinear
//! sampling. Choosing the points and turning pixels into speeds is the caller's job.

use image::{GrayImage, ImageBuffer, Luma};
use imageproc::filter::gaussian_blur_f32;

type FloatImage = ImageBuffer<Luma<f32>, Vec<f32>>;

/// A grey image in floats with its central-difference gradients.
struct Level {
    w: usize,
    h: usize,
    v: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
}

impl Level {
    fn new(img: &FloatImage) -> Level {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let v: Vec<f32> = img.as_raw().clone();
        let mut gx = vec![0.0; w * h];
        let mut gy = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let at = |x: usize, y: usize| v[y * w + x];
                let (xl, xr) = (x.saturating_sub(1), (x + 1).min(w - 1));
                let (yu, yd) = (y.saturating_sub(1), (y + 1).min(h - 1));
                gx[y * w + x] = (at(xr, y) - at(xl, y)) / (xr - xl).max(1) as f32;
                gy[y * w + x] = (at(x, yd) - at(x, yu)) / (yd - yu).max(1) as f32;
            }
        }
        Level { w, h, v, gx, gy }
    }

    /// Bilinear sample of `buf` at (x, y); `None` outside the image.
    fn sample(&self, buf: &[f32], x: f64, y: f64) -> Option<f64> {
        if !(x >= 0.0 && y >= 0.0 && x <= (self.w - 1) as f64 && y <= (self.h - 1) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |x: usize, y: usize| buf[y * self.w + x] as f64;
        let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
        let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    }
}

/// Gaussian pyramid of one frame, finest level first.
pub struct Pyramid {
    levels: Vec<Level>,
}

/// Tracker settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LkOptions {
    /// Window half-size, px (the window is `2 half + 1` square).
    pub half: i32,
    /// Pyramid levels above the finest.
    pub levels: usize,
    /// Iterations per level.
    pub iterations: usize,
    /// Stop iterating below this update, px.
    pub epsilon: f64,
}

impl Default for LkOptions {
    fn default() -> Self {
        LkOptions {
            half: 5,
            levels: 3,
            iterations: 30,
            epsilon: 0.005,
        }
    }
}

impl Pyramid {
    /// Builds `levels + 1` levels (fewer if the frame gets too small); the finest is the
    /// frame lightly blurred, which makes the sub-pixel matching smoother.
    pub fn new(frame: &GrayImage, levels: usize) -> Pyramid {
        let base: FloatImage = ImageBuffer::from_fn(frame.width(), frame.height(), |x, y| {
            Luma([frame.get_pixel(x, y)[0] as f32 / 255.0])
        });
        let mut img = gaussian_blur_f32(&base, 1.0);
        let mut out = vec![Level::new(&img)];
        for _ in 0..levels {
            let (w, h) = (img.width() / 2, img.height() / 2);
            if w < 16 || h < 16 {
                break;
            }
            let blurred = gaussian_blur_f32(&img, 1.0);
            img = ImageBuffer::from_fn(w, h, |x, y| {
                // Mean of the 2x2 block of the blurred level above.
                let s: f32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|(dx, dy)| blurred.get_pixel(2 * x + dx, 2 * y + dy)[0])
                    .sum();
                Luma([s / 4.0])
            });
            out.push(Level::new(&img));
        }
        Pyramid { levels: out }
    }
}

/// Displacement (dx, dy) in px of the point `(x, y)` from `prev` to `next`, or `None` when
/// the window leaves the frame, the texture is too weak to track, or it does not settle.
pub fn track(prev: &Pyramid, next: &Pyramid, x: f64, y: f64, o: LkOptions) -> Option<(f64, f64)> {
    let top = prev.levels.len().min(next.levels.len()).checked_sub(1)?;
    let mut g = (0.0f64, 0.0f64);
    for l in (0..=top).rev() {
        let (pi, pj) = (&prev.levels[l], &next.levels[l]);
        let s = (1u32 << l) as f64;
        let (px, py) = (x / s, y / s);
        // Window of the first frame and its gradients: fixed during the iterations.
        let mut win = Vec::with_capacity(((2 * o.half + 1) * (2 * o.half + 1)) as usize);
        let (mut gxx, mut gxy, mut gyy) = (0.0, 0.0, 0.0);
        for j in -o.half..=o.half {
            for i in -o.half..=o.half {
                let (sx, sy) = (px + i as f64, py + j as f64);
                let v = pi.sample(&pi.v, sx, sy)?;
                let ix = pi.sample(&pi.gx, sx, sy)?;
                let iy = pi.sample(&pi.gy, sx, sy)?;
                gxx += ix * ix;
                gxy += ix * iy;
                gyy += iy * iy;
                win.push((i, j, v, ix, iy));
            }
        }
        let det = gxx * gyy - gxy * gxy;
        // Smallest eigenvalue of the structure tensor, per window pixel: too flat a
        // patch gives no reliable displacement.
        let tr = gxx + gyy;
        let min_eig = 0.5 * (tr - ((gxx - gyy).powi(2) + 4.0 * gxy * gxy).sqrt());
        if det <= 0.0 || min_eig / win.len() as f64 <= 1e-6 {
            return None;
        }
        let mut v = (0.0f64, 0.0f64);
        let mut settled = false;
        for _ in 0..o.iterations {
            let (mut bx, mut by) = (0.0, 0.0);
            for &(i, j, val, ix, iy) in &win {
                let jx = px + i as f64 + g.0 + v.0;
                let jy = py + j as f64 + g.1 + v.1;
                let d = val - pj.sample(&pj.v, jx, jy)?;
                bx += d * ix;
                by += d * iy;
            }
            let ex = (gyy * bx - gxy * by) / det;
            let ey = (gxx * by - gxy * bx) / det;
            v.0 += ex;
            v.1 += ey;
            if ex.hypot(ey) < o.epsilon {
                settled = true;
                break;
            }
        }
        if l == 0 {
            if !settled {
                return None;
            }
            return Some((g.0 + v.0, g.1 + v.1));
        }
        g = (2.0 * (g.0 + v.0), 2.0 * (g.1 + v.1));
    }
    None
}
