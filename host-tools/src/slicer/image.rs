//! Images to designs: decode (PNG, JPEG, BMP), rotate and mirror, resample bilinearly to
//! rows at the line pitch, and turn each sample into a material by grey threshold or
//! nearest palette colour; transparent and background samples are not printed. Stops at
//! the `Design`: placement and toolpaths are `toolpath`'s.

use super::design::{Design, Layer, Run};
use super::error::{MaterialsHint, OptionError, SliceError, SliceLimit, SliceOption};
use image::{DynamicImage, RgbaImage};
use std::path::Path;

/// Quarter turns, counter-clockwise as seen on the plate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Rotation {
    /// As drawn.
    #[default]
    #[value(name = "0")]
    R0,
    /// A quarter turn.
    #[value(name = "90")]
    R90,
    /// A half turn.
    #[value(name = "180")]
    R180,
    /// Three quarter turns.
    #[value(name = "270")]
    R270,
}

/// Mirroring, applied after rotation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Mirror {
    /// None.
    #[default]
    None,
    /// Left and right swap (mirror across the Y axis).
    X,
    /// Top and bottom swap (mirror across the X axis).
    Y,
}

/// How a colour becomes a material.
#[derive(Clone, Debug, PartialEq)]
pub enum Classify {
    /// Two materials, the seed paper's method: grey below the level is material 0 (dark),
    /// at or above it material 1 (light).
    Threshold(u8),
    /// Nearest of these colours; the i-th is inlet i.
    Palette(Vec<[u8; 3]>),
    /// The image's own main colours (each covering at least 0.5 % of the printed pixels),
    /// darkest first as inlet 0.
    AutoPalette,
}

/// Image options.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageOptions {
    /// Printed width, mm; with only the height given, keeps the aspect ratio.
    pub width_mm: Option<f64>,
    /// Printed height, mm; with only the width given, keeps the aspect ratio. With
    /// neither, one pixel is one line pitch square.
    pub height_mm: Option<f64>,
    /// Rotation.
    pub rotate: Rotation,
    /// Mirroring.
    pub mirror: Mirror,
    /// Swap dark and light (threshold) or reverse the palette's order of inlets.
    pub invert: bool,
    /// Colour to material.
    pub classify: Classify,
    /// Pixels this close (RGB distance) to this colour are not printed.
    pub background: Option<[u8; 3]>,
    /// Distance within which a pixel counts as background.
    pub background_tolerance: f64,
    /// Samples with alpha below this are not printed.
    pub alpha_cutoff: u8,
}

impl Default for ImageOptions {
    fn default() -> Self {
        ImageOptions {
            width_mm: None,
            height_mm: None,
            rotate: Rotation::R0,
            mirror: Mirror::None,
            invert: false,
            classify: Classify::Threshold(150),
            background: None,
            background_tolerance: 40.0,
            alpha_cutoff: 128,
        }
    }
}

/// Extensions read as images.
pub const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "bmp"];

/// Decodes `path` with the default pixel limit.
pub fn load(path: &Path) -> Result<DynamicImage, SliceError> {
    load_limited(path, super::Limits::default().max_pixels)
}

/// Decodes `path`, refusing (from its header, before decoding) an image of more than
/// `max_pixels`: the slicer converts every image to 4-byte RGBA, so a one-bit PNG of
/// 32000 x 32000 would take 4 GB after its 128 MB decode.
pub fn load_limited(path: &Path, max_pixels: u64) -> Result<DynamicImage, SliceError> {
    let open = || -> Result<_, SliceError> {
        let file = std::fs::File::open(path).map_err(|e| SliceError::read(path, e))?;
        image::ImageReader::new(std::io::BufReader::new(file))
            .with_guessed_format()
            .map_err(|e| SliceError::read(path, e))
    };
    let bad = |e: image::ImageError| SliceError::Image {
        path: path.to_path_buf(),
        reason: one_line(&e.to_string()),
    };
    let (w, h) = open()?.into_dimensions().map_err(bad)?;
    let pixels = w as u64 * h as u64;
    if pixels > max_pixels {
        return Err(super::over_limit(
            &path.display().to_string(),
            &format!("{w} x {h} ="),
            pixels,
            max_pixels,
            SliceLimit::Pixels,
            None,
        ));
    }
    let mut reader = open()?;
    // The decoder's own buffer: up to 8 bytes a pixel (16-bit RGBA) within the limit.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(max_pixels.saturating_mul(8));
    reader.limits(limits);
    reader.decode().map_err(bad)
}

pub(crate) fn one_line(s: &str) -> String {
    s.lines().next().unwrap_or("").trim().to_string()
}

/// Samples of the resampled image: a material, or nothing printed.
type Cell = Option<u8>;

/// Slices one image into a design of `layers` identical layers at `pitch_mm`.
/// `inlets` is the machine's inlet count; `min_run_mm` drops shorter runs (see
/// [`super::design::normalize_row`]).
pub fn slice_image(
    img: &DynamicImage,
    name: &str,
    opts: &ImageOptions,
    pitch_mm: f64,
    layers: usize,
    inlets: usize,
    min_run_mm: f64,
) -> Result<Design, SliceError> {
    if !(opts.background_tolerance.is_finite() && opts.background_tolerance >= 0.0) {
        return Err(SliceError::BadOption(OptionError::new(
            SliceOption::BackgroundTolerance,
            Some(opts.background_tolerance.to_string()),
            "must be a distance of 0 or more".into(),
        )));
    }
    if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
        return Err(SliceError::LinePitch {
            what: name.to_string(),
            pitch_mm,
        });
    }
    let rgba = orient(img.to_rgba8(), opts);
    let (w, h) = (rgba.width() as usize, rgba.height() as usize);
    if w == 0 || h == 0 {
        return Err(SliceError::EmptyDesign {
            what: name.to_string(),
            why: "the image has no pixels".into(),
        });
    }
    let (px_x, px_y) = pixel_size(opts, w, h, pitch_mm, name)?;
    let palette = palette(&rgba, opts, inlets, name)?;
    // Rows at the pitch; along a row, samples as fine as the pixels (boundaries keep the
    // image's resolution) but never coarser than the pitch nor finer than 20 um.
    let rows = ((h as f64 * px_y / pitch_mm).round() as usize).max(1);
    // max then min (not clamp): a pitch under 20 um must not panic (clamp's min > max).
    let cell = px_x.max(0.02).min(pitch_mm);
    let cols = ((w as f64 * px_x / cell).round() as usize).max(1);
    if rows.saturating_mul(cols) > 400_000_000 {
        return Err(SliceError::TooManySamples {
            what: name.to_string(),
            cols,
            rows,
        });
    }
    let xs = axis_weights(cols, cell / px_x, w);
    let classifier = Classifier {
        palette: &palette,
        opts,
    };
    let mut layer = Layer::new();
    let mut cells: Vec<Cell> = vec![None; cols];
    let mut runs: Vec<Run> = Vec::new();
    let mut used = 0u32;
    for r in 0..rows {
        // Row r sits at design y = (r + 0.5) pitch; image rows count from the top.
        let y_img = h as f64 - (r as f64 + 0.5) * pitch_mm / px_y - 0.5;
        let (y0, y1, fy) = weight(y_img, h);
        let row0 = &rgba.as_raw()[y0 * w * 4..(y0 + 1) * w * 4];
        let row1 = &rgba.as_raw()[y1 * w * 4..(y1 + 1) * w * 4];
        for (c, &(x0, x1, fx)) in xs.iter().enumerate() {
            let s = bilinear(row0, row1, x0, x1, fx, fy);
            cells[c] = classifier.classify(s);
        }
        runs.clear();
        let mut start = 0;
        for c in 1..=cols {
            if c == cols || cells[c] != cells[start] {
                if let Some(m) = cells[start] {
                    used |= 1 << m;
                    runs.push(Run {
                        x0: start as f64 * cell,
                        x1: c as f64 * cell,
                        material: m,
                    });
                }
                start = c;
            }
        }
        layer.push_row(&mut runs, min_run_mm);
    }
    if layer.is_empty() {
        return Err(SliceError::EmptyDesign {
            what: name.to_string(),
            why: "every pixel is transparent or background".into(),
        });
    }
    let found = 32 - used.leading_zeros() as usize;
    if found > inlets {
        return Err(SliceError::TooManyMaterials {
            what: name.to_string(),
            found,
            inlets,
            hint: MaterialsHint::Background,
        });
    }
    Ok(Design {
        name: name.to_string(),
        size_mm: [cols as f64 * cell, rows as f64 * pitch_mm],
        pitch_mm,
        layers: vec![layer; layers.max(1)],
    })
}

fn orient(img: RgbaImage, opts: &ImageOptions) -> RgbaImage {
    use image::imageops;
    // Counter-clockwise on the plate is clockwise in image rows (which run downward).
    let img = match opts.rotate {
        Rotation::R0 => img,
        Rotation::R90 => imageops::rotate270(&img),
        Rotation::R180 => imageops::rotate180(&img),
        Rotation::R270 => imageops::rotate90(&img),
    };
    match opts.mirror {
        Mirror::None => img,
        Mirror::X => imageops::flip_horizontal(&img),
        Mirror::Y => imageops::flip_vertical(&img),
    }
}

fn pixel_size(
    opts: &ImageOptions,
    w: usize,
    h: usize,
    pitch: f64,
    name: &str,
) -> Result<(f64, f64), SliceError> {
    for (v, what) in [
        (opts.width_mm, SliceOption::Width),
        (opts.height_mm, SliceOption::Height),
    ] {
        if let Some(v) = v {
            if !(v.is_finite() && v > 0.0 && v <= 1e4) {
                return Err(SliceError::BadOption(
                    OptionError::new(
                        what,
                        Some(v.to_string()),
                        "must be above 0 and at most 10000".into(),
                    )
                    .of(name),
                ));
            }
        }
    }
    Ok(match (opts.width_mm, opts.height_mm) {
        (Some(wm), Some(hm)) => (wm / w as f64, hm / h as f64),
        (Some(wm), None) => (wm / w as f64, wm / w as f64),
        (None, Some(hm)) => (hm / h as f64, hm / h as f64),
        (None, None) => (pitch, pitch),
    })
}

/// For each output sample along an axis: the two source indices and the weight of the
/// second, sampling at centres with `step` source pixels per sample.
fn axis_weights(n: usize, step: f64, len: usize) -> Vec<(usize, usize, f32)> {
    (0..n)
        .map(|i| weight((i as f64 + 0.5) * step - 0.5, len))
        .map(|(a, b, f)| (a, b, f as f32))
        .collect()
}

fn weight(pos: f64, len: usize) -> (usize, usize, f64) {
    let last = len.saturating_sub(1) as f64;
    let p = pos.clamp(0.0, last);
    let i0 = p.floor();
    let i1 = (i0 + 1.0).min(last);
    (i0 as usize, i1 as usize, p - i0)
}

/// Bilinear RGBA on premultiplied colour, so transparent pixels' hidden RGB does not
/// bleed into edges. Returns straight RGB and alpha.
#[inline]
fn bilinear(row0: &[u8], row1: &[u8], x0: usize, x1: usize, fx: f32, fy: f64) -> [f32; 4] {
    let fy = fy as f32;
    let w = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    let px = [
        &row0[x0 * 4..x0 * 4 + 4],
        &row0[x1 * 4..x1 * 4 + 4],
        &row1[x0 * 4..x0 * 4 + 4],
        &row1[x1 * 4..x1 * 4 + 4],
    ];
    let mut acc = [0.0f32; 4];
    for (p, wi) in px.iter().zip(w) {
        let a = p[3] as f32 * wi;
        acc[0] += p[0] as f32 * a;
        acc[1] += p[1] as f32 * a;
        acc[2] += p[2] as f32 * a;
        acc[3] += a;
    }
    if acc[3] > 0.0 {
        [acc[0] / acc[3], acc[1] / acc[3], acc[2] / acc[3], acc[3]]
    } else {
        [0.0; 4]
    }
}

struct Classifier<'a> {
    palette: &'a [[f32; 3]],
    opts: &'a ImageOptions,
}

impl Classifier<'_> {
    #[inline]
    fn classify(&self, s: [f32; 4]) -> Cell {
        if s[3] < self.opts.alpha_cutoff as f32 {
            return None;
        }
        let rgb = [s[0], s[1], s[2]];
        if let Some(bg) = self.opts.background {
            let d = dist2(rgb, [bg[0] as f32, bg[1] as f32, bg[2] as f32]);
            let tol = self.opts.background_tolerance as f32;
            if d <= tol * tol {
                return None;
            }
        }
        match self.opts.classify {
            Classify::Threshold(level) => {
                let grey = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
                Some(u8::from((grey >= level as f32) != self.opts.invert))
            }
            _ => {
                let mut best = (f32::INFINITY, 0u8);
                for (i, p) in self.palette.iter().enumerate() {
                    let d = dist2(rgb, *p);
                    if d < best.0 {
                        best = (d, i as u8);
                    }
                }
                if self.opts.invert {
                    Some(self.palette.len() as u8 - 1 - best.1)
                } else {
                    Some(best.1)
                }
            }
        }
    }
}

#[inline]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The palette the classifier matches against (empty in threshold mode).
fn palette(
    img: &RgbaImage,
    opts: &ImageOptions,
    inlets: usize,
    name: &str,
) -> Result<Vec<[f32; 3]>, SliceError> {
    let too_many = |found| SliceError::TooManyMaterials {
        what: name.to_string(),
        found,
        inlets,
        hint: MaterialsHint::Palette,
    };
    match &opts.classify {
        Classify::Threshold(_) => Ok(Vec::new()),
        Classify::Palette(p) => {
            if p.len() > inlets {
                return Err(too_many(p.len()));
            }
            if p.is_empty() {
                return Err(SliceError::BadOption(
                    OptionError::new(
                        SliceOption::Palette,
                        None,
                        "needs at least one colour".into(),
                    )
                    .of(name),
                ));
            }
            Ok(p.iter().map(|&c| to_f(c)).collect())
        }
        Classify::AutoPalette => {
            let main = main_colours(img, opts);
            if main.is_empty() {
                return Err(SliceError::EmptyDesign {
                    what: name.to_string(),
                    why: "every pixel is transparent or background".into(),
                });
            }
            if main.len() > inlets {
                return Err(too_many(main.len()));
            }
            Ok(main.into_iter().map(to_f).collect())
        }
    }
}

fn to_f(c: [u8; 3]) -> [f32; 3] {
    [c[0] as f32, c[1] as f32, c[2] as f32]
}

/// The colours covering at least 0.5 % of the printed pixels (quantised to 5 bits per
/// channel, near ones merged), darkest first. Anti-aliased edge pixels fall below the
/// share and are matched to their nearest main colour later.
fn main_colours(img: &RgbaImage, opts: &ImageOptions) -> Vec<[u8; 3]> {
    let mut bins = vec![(0u64, [0u64; 3]); 1 << 15];
    let mut total = 0u64;
    for p in img.pixels() {
        let [r, g, b, a] = p.0;
        if a < opts.alpha_cutoff {
            continue;
        }
        if let Some(bg) = opts.background {
            let d = dist2(to_f([r, g, b]), to_f(bg));
            let tol = opts.background_tolerance as f32;
            if d <= tol * tol {
                continue;
            }
        }
        let k = ((r as usize >> 3) << 10) | ((g as usize >> 3) << 5) | (b as usize >> 3);
        let e = &mut bins[k];
        e.0 += 1;
        e.1[0] += r as u64;
        e.1[1] += g as u64;
        e.1[2] += b as u64;
        total += 1;
    }
    let min = (total / 200).max(1);
    let mut main: Vec<(u64, [f32; 3])> = bins
        .iter()
        .filter(|(n, _)| *n >= min)
        .map(|(n, s)| {
            let nf = *n as f32;
            (*n, [s[0] as f32 / nf, s[1] as f32 / nf, s[2] as f32 / nf])
        })
        .collect();
    // Merge near colours (a gradient across bin edges), biggest first.
    main.sort_by_key(|m| std::cmp::Reverse(m.0));
    let mut merged: Vec<(u64, [f32; 3])> = Vec::new();
    for (n, c) in main {
        match merged.iter_mut().find(|(_, m)| dist2(*m, c) < 48.0 * 48.0) {
            Some(m) => m.0 += n,
            None => merged.push((n, c)),
        }
    }
    let grey = |c: &[f32; 3]| 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2];
    merged.sort_by(|a, b| grey(&a.1).total_cmp(&grey(&b.1)));
    merged
        .into_iter()
        .map(|(_, c)| [c[0].round() as u8, c[1].round() as u8, c[2].round() as u8])
        .collect()
}

/// Parses "#rrggbb" or "rrggbb".
pub fn parse_colour(s: &str) -> Result<[u8; 3], String> {
    let h = s.trim().trim_start_matches('#');
    if h.len() != 6 || !h.chars().all(|c| c.is_ascii_hexdigit()) {
        return Err(format!("colour {s:?} is not #rrggbb"));
    }
    let v = |i: usize| u8::from_str_radix(&h[i..i + 2], 16).map_err(|e| e.to_string());
    Ok([v(0)?, v(2)?, v(4)?])
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgba;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> DynamicImage {
        DynamicImage::ImageRgba8(RgbaImage::from_fn(w, h, |x, y| Rgba(f(x, y))))
    }

    #[test]
    fn threshold_splits_dark_and_light_and_keeps_pixel_boundaries() {
        // 10 px wide: left 4 dark, right 6 light; 1 px = 0.1 mm, pitch 0.5 mm.
        let i = img(10, 10, |x, _| {
            if x < 4 {
                [20, 20, 20, 255]
            } else {
                [240, 240, 240, 255]
            }
        });
        let o = ImageOptions {
            width_mm: Some(1.0),
            ..Default::default()
        };
        let d = slice_image(&i, "t", &o, 0.5, 1, 2, 0.0).unwrap();
        assert_eq!(d.layers[0].rows(), 2);
        let row = d.layers[0].row(0);
        assert_eq!(row.len(), 2);
        assert_eq!(row[0].material, 0);
        assert!((row[0].x1 - 0.4).abs() < 1e-9, "{row:?}");
        assert_eq!(row[1].material, 1);
    }

    #[test]
    fn transparent_is_not_printed_and_invert_swaps() {
        let i = img(4, 1, |x, _| match x {
            0 => [0, 0, 0, 0],
            1 | 2 => [0, 0, 0, 255],
            _ => [255, 255, 255, 255],
        });
        let o = ImageOptions {
            invert: true,
            ..Default::default()
        };
        let d = slice_image(&i, "t", &o, 1.0, 1, 2, 0.0).unwrap();
        let row = d.layers[0].row(0);
        assert_eq!(row[0].x0, 1.0);
        assert_eq!(row[0].material, 1);
        assert_eq!(row[1].material, 0);
    }

    #[test]
    fn rotation_turns_counter_clockwise_on_the_plate() {
        // A dark top row: after a quarter turn counter-clockwise it is the left column.
        let i = img(
            3,
            3,
            |_, y| if y == 0 { [0, 0, 0, 255] } else { [0, 0, 0, 0] },
        );
        let o = ImageOptions {
            rotate: Rotation::R90,
            ..Default::default()
        };
        let d = slice_image(&i, "t", &o, 1.0, 1, 2, 0.0).unwrap();
        for r in 0..3 {
            assert_eq!(
                d.layers[0].row(r),
                &[Run {
                    x0: 0.0,
                    x1: 1.0,
                    material: 0
                }]
            );
        }
    }

    #[test]
    fn auto_palette_counts_main_colours_and_refuses_too_many() {
        let i = img(30, 3, |x, _| match x / 10 {
            0 => [200, 30, 30, 255],
            1 => [30, 200, 30, 255],
            _ => [30, 30, 200, 255],
        });
        let o = ImageOptions {
            classify: Classify::AutoPalette,
            ..Default::default()
        };
        let e = slice_image(&i, "rgb.png", &o, 1.0, 1, 2, 0.0).unwrap_err();
        assert!(e.to_string().contains("3 materials"), "{e}");
        let d = slice_image(&i, "rgb.png", &o, 1.0, 1, 3, 0.0).unwrap();
        assert_eq!(d.layers[0].row(0).len(), 3);
    }

    #[test]
    fn colours_parse() {
        assert_eq!(parse_colour("#ff8000"), Ok([255, 128, 0]));
        assert!(parse_colour("red").is_err());
    }
}
