//! Preview pictures of a job: the plate seen from above with every bead drawn in its
//! material's colour at its width, later layers over earlier ones, and travel moves as
//! thin dashed lines; framed with mm axes and a material key for people (`figure`), as a
//! grid of layers when the job has several. PNG out, written atomically. Simulation
//! heatmaps are not drawn here.

use super::error::SliceError;
use super::output::{stage, write_atomic, StagedFiles};
use crate::figure;
use dollop::command::walk::{walk, MoveKind};
use dollop::Command;
use image::{Rgb, RgbImage};
use std::path::Path;

/// Colours of materials 0, 1, ... (then repeating): brown, cream-yellow, blue, red,
/// green, purple, orange, grey. Chosen to tell apart, not to look like the pastes.
pub const MATERIAL_COLOURS: [[u8; 3]; 8] = [
    [122, 72, 36],
    [236, 190, 70],
    [58, 123, 213],
    [214, 69, 69],
    [70, 160, 90],
    [140, 80, 170],
    [240, 130, 40],
    [120, 120, 120],
];

/// How to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewOptions {
    /// Longest side of the picture, pixels.
    pub max_px: u32,
    /// Bead width drawn, mm (the line pitch).
    pub bead_mm: f64,
    /// Draw travel moves.
    pub travel: bool,
    /// Draw only this layer (0 = the first); all layers, later over earlier, if None.
    pub layer: Option<usize>,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            max_px: 1600,
            bead_mm: 0.8,
            travel: true,
            layer: None,
        }
    }
}

struct Canvas {
    img: RgbImage,
    origin: [f64; 2],
    scale: f64,
}

impl Canvas {
    fn px(&self, p: [f64; 2]) -> [f64; 2] {
        let h = self.img.height() as f64;
        [
            (p[0] - self.origin[0]) * self.scale,
            h - (p[1] - self.origin[1]) * self.scale,
        ]
    }

    /// A thick line (a capsule of radius `r` px).
    fn line(&mut self, a: [f64; 2], b: [f64; 2], r: f64, c: [u8; 3]) {
        let (a, b) = (self.px(a), self.px(b));
        let (w, h) = (self.img.width() as i64, self.img.height() as i64);
        let x0 = ((a[0].min(b[0]) - r).floor() as i64).max(0);
        let x1 = ((a[0].max(b[0]) + r).ceil() as i64).min(w - 1);
        let y0 = ((a[1].min(b[1]) - r).floor() as i64).max(0);
        let y1 = ((a[1].max(b[1]) + r).ceil() as i64).min(h - 1);
        let d = [b[0] - a[0], b[1] - a[1]];
        let l2 = d[0] * d[0] + d[1] * d[1];
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = [x as f64 + 0.5 - a[0], y as f64 + 0.5 - a[1]];
                let t = if l2 > 0.0 {
                    ((p[0] * d[0] + p[1] * d[1]) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let q = [p[0] - t * d[0], p[1] - t * d[1]];
                if q[0] * q[0] + q[1] * q[1] <= r * r {
                    self.img.put_pixel(x as u32, y as u32, Rgb(c));
                }
            }
        }
    }

    /// A dashed line: 6 px on, 4 px off.
    fn dashed(&mut self, a: [f64; 2], b: [f64; 2], c: [u8; 3]) {
        let len_px = ((b[0] - a[0]).hypot(b[1] - a[1])) * self.scale;
        if len_px <= 0.0 {
            return;
        }
        let mut t = 0.0;
        while t < len_px {
            let t1 = (t + 6.0).min(len_px);
            let p = |s: f64| {
                [
                    a[0] + (b[0] - a[0]) * s / len_px,
                    a[1] + (b[1] - a[1]) * s / len_px,
                ]
            };
            self.line(p(t), p(t1), 0.6, c);
            t += 10.0;
        }
    }
}

/// Draws the toolpath of `commands` (starting at `start_um`) into an image.
pub fn draw(commands: &[Command], start_um: [i32; 3], opts: &PreviewOptions) -> RgbImage {
    draw_plate(commands, start_um, opts).img
}

/// Layers in a job that hold beads, numbered as the preview numbers them (from the first
/// Z, each higher Z the next); a lift after the last bead is not a layer.
pub fn layer_count(commands: &[Command], start_um: [i32; 3]) -> usize {
    walk(commands, start_um)
        .filter(|m| matches!(m.kind, MoveKind::Print { .. }))
        .last()
        .map_or(0, |m| m.layer as usize)
        + 1
}

/// Most layers a multi-layer preview shows (evenly chosen, first and last included).
pub const GRID_LAYERS: usize = 9;

/// The preview for a person: the plate on mm axes with a key of the job's materials
/// (named by `names`, by inlet) and of travel. A job of several layers, unless one layer
/// is asked for, shows a grid of up to [`GRID_LAYERS`] layers, so that a material inside a
/// part shows too. An asked-for layer beyond the job's is refused with the valid range.
pub fn figure(
    commands: &[Command],
    start_um: [i32; 3],
    opts: &PreviewOptions,
    names: &[String],
) -> Result<RgbImage, SliceError> {
    let n = layer_count(commands, start_um);
    if let Some(l) = opts.layer.filter(|&l| l >= n) {
        return Err(SliceError::Picture {
            message: format!(
                "layer {l} asked for: the job has {n} layer(s), numbered 0 to {}",
                n - 1
            ),
        });
    }
    let shown: Vec<Option<usize>> = match opts.layer {
        Some(l) => vec![Some(l)],
        None if n == 1 => vec![None],
        None => {
            let k = n.min(GRID_LAYERS);
            let mut v: Vec<Option<usize>> = (0..k)
                .map(|i| Some((i * (n - 1) + (k - 1) / 2) / (k - 1)))
                .collect();
            v.dedup();
            v
        }
    };
    let columns = (shown.len() as f64).sqrt().ceil() as usize;
    let plates: Vec<figure::Plate> = shown
        .iter()
        .map(|&layer| {
            let o = PreviewOptions {
                layer,
                max_px: (opts.max_px / columns as u32).max(200),
                travel: opts.travel && shown.len() == 1,
                ..*opts
            };
            let mut p = draw_plate(commands, start_um, &o);
            p.caption = match layer {
                Some(l) if n > 1 => format!("layer {l} of 0..{}", n - 1),
                _ => String::new(),
            };
            p
        })
        .collect();
    let mut used = [false; MATERIAL_COLOURS.len()];
    for c in commands {
        if let Command::Print { material, .. } = *c {
            used[material as usize % MATERIAL_COLOURS.len()] = true;
        }
    }
    let mut key: Vec<figure::Key> = used
        .iter()
        .enumerate()
        .filter(|(_, &u)| u)
        .map(|(m, _)| {
            let name = names
                .get(m)
                .cloned()
                .unwrap_or_else(|| format!("material {m}"));
            figure::Key::Swatch(name, MATERIAL_COLOURS[m])
        })
        .collect();
    if plates.len() == 1 && opts.travel {
        key.push(figure::Key::Line(
            "travel (valves shut)".into(),
            [40, 40, 40],
        ));
    }
    key.push(figure::Key::Note(format!(
        "bead {:.2} mm wide",
        opts.bead_mm
    )));
    let p = &plates[0];
    let title = format!(
        "toolpath: {} layer(s), plate {:.1} x {:.1} mm shown",
        n,
        p.x_mm.1 - p.x_mm.0,
        p.y_mm.1 - p.y_mm.0
    );
    figure::framed(&title, &plates, columns, &key)
        .map_err(|message| SliceError::Picture { message })
}

/// The picture and the mm it spans.
fn draw_plate(commands: &[Command], start_um: [i32; 3], opts: &PreviewOptions) -> figure::Plate {
    let (lo, hi) = super::job_file::bounds(commands, start_um);
    let margin = opts.bead_mm * 2.0 + 1.0;
    let lo = [lo[0] as f64 * 1e-3 - margin, lo[1] as f64 * 1e-3 - margin];
    let hi = [hi[0] as f64 * 1e-3 + margin, hi[1] as f64 * 1e-3 + margin];
    let size = [hi[0] - lo[0], hi[1] - lo[1]];
    let scale = opts.max_px.max(16) as f64 / size[0].max(size[1]);
    let w = ((size[0] * scale).ceil() as u32).clamp(1, opts.max_px.max(16));
    let h = ((size[1] * scale).ceil() as u32).clamp(1, opts.max_px.max(16));
    let mut cv = Canvas {
        img: RgbImage::from_pixel(w, h, Rgb([246, 246, 242])),
        origin: lo,
        scale,
    };
    let r = (opts.bead_mm * scale / 2.0).max(0.7);
    let mut travels = Vec::new();
    // Layers count from the first Z (the priming bead's); each higher Z is the next.
    let shown = |layer: u32| opts.layer.is_none_or(|l| l == layer as usize);
    let mm = |p: [i32; 3]| [p[0] as f64 * 1e-3, p[1] as f64 * 1e-3];
    for m in walk(commands, start_um).filter(|m| shown(m.layer)) {
        match m.kind {
            MoveKind::Print { material } => {
                let col = MATERIAL_COLOURS[material as usize % MATERIAL_COLOURS.len()];
                cv.line(mm(m.from), mm(m.to), r, col);
            }
            MoveKind::Travel => travels.push((mm(m.from), mm(m.to))),
            MoveKind::Layer => {}
        }
    }
    if opts.travel {
        // On top, so that they show across the beads they skip over.
        for (a, b) in travels {
            cv.dashed(a, b, [40, 40, 40]);
        }
    }
    let (w, h) = (cv.img.width() as f64, cv.img.height() as f64);
    figure::Plate {
        caption: String::new(),
        x_mm: (lo[0], lo[0] + w / scale),
        y_mm: (lo[1], lo[1] + h / scale),
        img: cv.img,
    }
}

/// Renders the toolpath and writes it as PNG to `path` (atomically).
pub fn render(
    path: &Path,
    commands: &[Command],
    start_um: [i32; 3],
    opts: &PreviewOptions,
) -> Result<(), SliceError> {
    let img = draw(commands, start_um, opts);
    write_png(path, &img)
}

/// Writes an RGB image as PNG atomically.
pub fn write_png(path: &Path, img: &RgbImage) -> Result<(), SliceError> {
    write_atomic(path, |w| encode_png(img, w))
}

/// Stages an RGB image as PNG for `path` in `out` (renamed when `out` is committed).
pub fn stage_png(out: &mut StagedFiles, path: &Path, img: &RgbImage) -> Result<(), SliceError> {
    stage(out, path, |w| encode_png(img, w))
}

fn encode_png(img: &RgbImage, w: &mut dyn std::io::Write) -> std::io::Result<()> {
    let mut buf = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
        .map_err(std::io::Error::other)?;
    w.write_all(&buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beads_take_their_material_colour_and_travel_is_dashed() {
        let cmds = [
            Command::Travel { x: 0, y: 0, z: 800 },
            Command::Print {
                dx: 10_000,
                dy: 0,
                material: 1,
            },
            Command::Travel {
                x: 0,
                y: 5_000,
                z: 800,
            },
            Command::Print {
                dx: 10_000,
                dy: 0,
                material: 0,
            },
            Command::End,
        ];
        let img = draw(
            &cmds,
            [0, 0, 800],
            &PreviewOptions {
                max_px: 200,
                ..Default::default()
            },
        );
        let count = |c: [u8; 3]| img.pixels().filter(|p| p.0 == c).count();
        assert!(count(MATERIAL_COLOURS[0]) > 100);
        assert!(count(MATERIAL_COLOURS[1]) > 100);
        assert!(count([40, 40, 40]) > 10);
    }
}
