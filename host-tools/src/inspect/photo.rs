//! The photo before it is registered: decoded within a pixel limit, checked for light and
//! contrast, the plate's colour taken from the border, the light's unevenness fitted over
//! the plate (a quadratic in log brightness) and divided out, and the print found as the
//! largest region that is not plate. Registering and classifying are other modules'.

use super::error::InspectError;
use image::{GrayImage, ImageBuffer, Luma, RgbImage};
use imageproc::region_labelling::{connected_components, Connectivity};
use std::path::Path;

/// Default `--max-pixels` for a photo: a 24-megapixel camera's frame. The photo is held
/// as RGB in f32 with its mask, labels and the rectified frame: a 12-megapixel photo
/// peaked at 437 MB (`/usr/bin/time`), about 36 bytes a pixel, so 24 megapixels stay
/// under 0.9 GB.
pub const MAX_PIXELS: u64 = 24_000_000;

/// A photo with the light evened out, in linear-ish RGB scaled so the plate is 1.
pub struct Photo {
    /// Width and height, px.
    pub size: (u32, u32),
    /// RGB per pixel, row-major, plate = about (1, 1, 1) after `plate` is divided out.
    pub rgb: Vec<[f32; 3]>,
    /// The plate's colour before evening out, 0..1.
    pub plate: [f32; 3],
    /// The print: its pixels are set.
    pub print: GrayImage,
    /// Pixels in the print.
    pub print_px: u64,
    /// The other regions that are not plate (markers, the priming bead, crumbs), largest
    /// first, at most `MAX_BLOBS`, none smaller than 1/2000 of the print.
    pub blobs: Vec<Blob>,
}

/// Regions besides the print kept for finding markers.
pub const MAX_BLOBS: usize = 32;

/// A region of the photo that is not plate, apart from the print.
#[derive(Clone, Debug)]
pub struct Blob {
    /// Its pixels (x, y).
    pub px: Vec<[u32; 2]>,
}

impl Blob {
    /// Centre of its pixels (pixel centres at +0.5).
    pub fn centroid(&self) -> [f64; 2] {
        let n = self.px.len().max(1) as f64;
        let mut c = [0.0; 2];
        for p in &self.px {
            c[0] += (p[0] as f64 + 0.5) / n;
            c[1] += (p[1] as f64 + 0.5) / n;
        }
        c
    }
    /// Larger over smaller eigenvalue of its pixels' covariance: about 4 for an L of
    /// equal legs, tens for a straight bead.
    pub fn elongation(&self) -> f64 {
        let c = self.centroid();
        let n = self.px.len().max(1) as f64;
        let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
        for p in &self.px {
            let (dx, dy) = (p[0] as f64 + 0.5 - c[0], p[1] as f64 + 0.5 - c[1]);
            xx += dx * dx / n;
            xy += dx * dy / n;
            yy += dy * dy / n;
        }
        let m = nalgebra::Matrix2::new(xx, xy, xy, yy);
        let e = m.symmetric_eigenvalues();
        let (a, b) = (e[0].max(e[1]), e[0].min(e[1]));
        a / b.max(1e-9)
    }
}

impl Photo {
    /// The evened-out colour at pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.rgb[(y * self.size.0 + x) as usize]
    }
}

fn lum(c: [f32; 3]) -> f32 {
    0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]
}

fn median(mut v: Vec<f32>) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, f32::total_cmp).1
}

/// Reads `path` (at most `max_pixels`, checked from the header) and finds the print.
pub fn load(path: &Path, max_pixels: u64) -> Result<Photo, InspectError> {
    let read = |source| InspectError::Read {
        path: path.to_path_buf(),
        source,
    };
    let reader = image::ImageReader::open(path)
        .map_err(read)?
        .with_guessed_format()
        .map_err(read)?;
    let (w, h) = reader.into_dimensions().map_err(|e| InspectError::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let px = u64::from(w) * u64::from(h);
    if px > max_pixels {
        return Err(InspectError::TooLarge {
            path: path.to_path_buf(),
            w,
            h,
            px,
            limit: max_pixels,
            over: px - max_pixels,
        });
    }
    let img = image::ImageReader::open(path)
        .map_err(read)?
        .with_guessed_format()
        .map_err(read)?
        .decode()
        .map_err(|e| InspectError::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?
        .to_rgb8();
    from_image(path, &img)
}

/// Finds the print in an RGB image; `path` names it in messages.
pub fn from_image(path: &Path, img: &RgbImage) -> Result<Photo, InspectError> {
    let bad = |message: String| InspectError::Photo {
        path: path.to_path_buf(),
        message,
    };
    let (w, h) = img.dimensions();
    if w < 64 || h < 64 {
        return Err(bad(format!(
            "{w} x {h} px is too small to measure a print; take the photo at 640 x 480 or more"
        )));
    }
    let rgb: Vec<[f32; 3]> = img
        .pixels()
        .map(|p| {
            [
                p[0] as f32 / 255.0,
                p[1] as f32 / 255.0,
                p[2] as f32 / 255.0,
            ]
        })
        .collect();
    // Light and contrast first: nothing below can be trusted in a dark or flat photo.
    check_light(&rgb).map_err(bad)?;
    // The plate fills the border of a photo of a print.
    let band = (w.min(h) / 30).max(2);
    let mut border: Vec<[f32; 3]> = Vec::new();
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            if x < band || y < band || x >= w - band || y >= h - band {
                border.push(rgb[(y * w + x) as usize]);
            }
        }
    }
    let plate = [
        median(border.iter().map(|c| c[0]).collect()),
        median(border.iter().map(|c| c[1]).collect()),
        median(border.iter().map(|c| c[2]).collect()),
    ];
    let plate_l = lum(plate).max(1e-3);
    let chroma = |c: [f32; 3]| {
        let s = (c[0] + c[1] + c[2]).max(1e-3);
        [c[0] / s, c[1] / s]
    };
    let pc = chroma(plate);
    // Plate pixels: the plate's hue at any brightness the light could give it.
    let is_plate = |c: [f32; 3]| {
        let q = chroma(c);
        let r = lum(c) / plate_l;
        (q[0] - pc[0]).hypot(q[1] - pc[1]) < 0.025 && (0.35..2.5).contains(&r)
    };
    let field = fit_light(&rgb, w, h, is_plate, plate_l);
    let mut even = rgb;
    for y in 0..h {
        for x in 0..w {
            let g = field(x as f32 / w as f32, y as f32 / h as f32);
            let c = &mut even[(y * w + x) as usize];
            for (k, v) in c.iter_mut().enumerate() {
                *v /= g * plate[k].max(1e-3);
            }
        }
    }
    // The print: far from the plate's evened colour (1, 1, 1), then its largest region.
    let dist =
        |c: [f32; 3]| ((c[0] - 1.0).powi(2) + (c[1] - 1.0).powi(2) + (c[2] - 1.0).powi(2)).sqrt();
    let mask = GrayImage::from_fn(w, h, |x, y| {
        Luma([if dist(even[(y * w + x) as usize]) > 0.18 {
            255
        } else {
            0
        }])
    });
    let mask = imageproc::morphology::open(&mask, imageproc::distance_transform::Norm::LInf, 1);
    let labels = connected_components(&mask, Connectivity::Eight, Luma([0u8]));
    let mut area: Vec<u64> = Vec::new();
    for p in labels.pixels() {
        let l = p[0] as usize;
        if l == 0 {
            continue;
        }
        if area.len() <= l {
            area.resize(l + 1, 0);
        }
        area[l] += 1;
    }
    let (best, &best_area) = area
        .iter()
        .enumerate()
        .max_by_key(|a| *a.1)
        .unwrap_or((0, &0));
    if best_area < (u64::from(w) * u64::from(h)) / 200 {
        return Err(bad(
            "no print found: nothing in the frame differs from the plate over more than 0.5 % of the photo".into(),
        ));
    }
    let print = GrayImage::from_fn(w, h, |x, y| {
        Luma([if labels.get_pixel(x, y)[0] as usize == best {
            255
        } else {
            0
        }])
    });
    let blobs = blobs(&labels, &area, best, best_area);
    Ok(Photo {
        size: (w, h),
        rgb: even,
        plate,
        print,
        print_px: best_area,
        blobs,
    })
}

/// Refuses a photo too dark or too flat to tell the materials apart (the reason).
fn check_light(rgb: &[[f32; 3]]) -> Result<(), String> {
    let mut l: Vec<f32> = rgb.iter().step_by(7).map(|&c| lum(c)).collect();
    l.sort_unstable_by(f32::total_cmp);
    let pct = |q: f64| l[((l.len() - 1) as f64 * q) as usize];
    if pct(0.5) < 0.08 || pct(0.99) < 0.2 {
        return Err(format!(
            "too dark to tell the materials apart (median brightness {:.0} %, brightest {:.0} %); light the print evenly and expose for the plate",
            100.0 * pct(0.5),
            100.0 * pct(0.99)
        ));
    }
    if pct(0.99) - pct(0.01) < 0.06 {
        return Err("the photo has almost no contrast: no print stands out from the plate".into());
    }
    Ok(())
}

/// The other regions that stand out from the plate (`labels`, `area` by label), beside
/// the print (`best`, `best_area` px): the largest `MAX_BLOBS` of at least 1/2000 of it.
fn blobs(
    labels: &ImageBuffer<Luma<u32>, Vec<u32>>,
    area: &[u64],
    best: usize,
    best_area: u64,
) -> Vec<Blob> {
    let min_blob = (best_area / 2000).max(20);
    let mut keep: Vec<usize> = (1..area.len())
        .filter(|&l| l != best && area[l] >= min_blob)
        .collect();
    keep.sort_by_key(|&l| std::cmp::Reverse(area[l]));
    keep.truncate(MAX_BLOBS);
    let mut slot = vec![usize::MAX; area.len()];
    for (i, &l) in keep.iter().enumerate() {
        slot[l] = i;
    }
    let mut blobs: Vec<Blob> = keep
        .iter()
        .map(|&l| Blob {
            px: Vec::with_capacity(area[l] as usize),
        })
        .collect();
    for (x, y, p) in labels.enumerate_pixels() {
        if let Some(b) = slot.get(p[0] as usize).and_then(|&i| blobs.get_mut(i)) {
            b.px.push([x, y]);
        }
    }
    blobs
}

/// Fits log brightness of the plate pixels (relative to `plate_l`) as a quadratic in
/// the normalised coordinates and returns the light field it gives (1 = as the border).
fn fit_light(
    rgb: &[[f32; 3]],
    w: u32,
    h: u32,
    is_plate: impl Fn([f32; 3]) -> bool,
    plate_l: f32,
) -> impl Fn(f32, f32) -> f32 {
    let basis = |u: f64, v: f64| [1.0, u, v, u * u, u * v, v * v];
    let mut ata = nalgebra::SMatrix::<f64, 6, 6>::zeros();
    let mut atb = nalgebra::SVector::<f64, 6>::zeros();
    let step = ((w.max(h) / 200).max(1)) as usize;
    for y in (0..h as usize).step_by(step) {
        for x in (0..w as usize).step_by(step) {
            let c = rgb[y * w as usize + x];
            if !is_plate(c) {
                continue;
            }
            let b =
                nalgebra::SVector::<f64, 6>::from(basis(x as f64 / w as f64, y as f64 / h as f64));
            let t = ((lum(c) / plate_l).max(1e-3) as f64).ln();
            ata += b * b.transpose();
            atb += b * t;
        }
    }
    let coef = ata
        .try_inverse()
        .map(|inv| inv * atb)
        .unwrap_or_else(nalgebra::SVector::<f64, 6>::zeros);
    move |u: f32, v: f32| {
        let b = basis(u as f64, v as f64);
        let t: f64 = (0..6).map(|i| coef[i] * b[i]).sum();
        t.clamp(-3.0, 3.0).exp() as f32
    }
}
