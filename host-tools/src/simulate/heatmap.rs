//! The plate as a picture: the material deposited in each cell and every material
//! boundary as a dot coloured by its error; the file written is that picture framed on mm
//! axes with a material key and a labelled error scale (`figure`). Painting only: the run
//! that feeds it is `simulate`'s, the staging of files `slicer::output`'s.

use crate::figure;
use crate::slicer::{self, output};
use dollop::config::Config;
use dollop_sim::metrics::Boundary;
use dollop_sim::Job;
use std::path::Path;

/// Material colours on the plate, by inlet: the same as the toolpath preview's.
pub const PALETTE: [[u8; 3]; 8] = slicer::preview::MATERIAL_COLOURS;

/// The plate as a picture: deposited material per cell, boundary errors as coloured dots.
pub struct Heatmap {
    x0: f64,
    y1: f64,
    px_per_mm: f64,
    img: image::RgbImage,
    radius: i64,
    last: Option<(i64, i64, u8)>,
    names: Vec<String>,
    used: [bool; PALETTE.len()],
}

/// The error at which a boundary's dot is fully red, mm: the goal boundaries are held to.
pub const ERROR_SCALE_MM: f64 = 0.05;

/// Largest heatmap side, pixels.
const MAX_SIDE: f64 = 4000.0;

impl Heatmap {
    /// A blank plate covering the job's extent with a margin.
    pub fn for_job(job: &Job, config: &Config) -> Self {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut grow = |p: [i32; 3]| {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a] as f64 * 1e-3);
                hi[a] = hi[a].max(p[a] as f64 * 1e-3);
            }
        };
        grow(job.start_um);
        for m in dollop::command::walk(&job.commands, job.start_um) {
            grow(m.to);
        }
        let margin = 2.0;
        let (w_mm, h_mm) = (hi[0] - lo[0] + 2.0 * margin, hi[1] - lo[1] + 2.0 * margin);
        let px_per_mm = (20.0f64).min(MAX_SIDE / w_mm.max(h_mm).max(1.0));
        let w = (w_mm * px_per_mm).ceil().max(1.0) as u32;
        let h = (h_mm * px_per_mm).ceil().max(1.0) as u32;
        let pitch = config.channel.line_pitch_mm as f64;
        Heatmap {
            x0: lo[0] - margin,
            y1: hi[1] + margin,
            px_per_mm,
            img: image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255])),
            radius: ((pitch * 0.5 * px_per_mm).round() as i64).max(1),
            last: None,
            names: crate::slicer::material_names(config),
            used: [false; PALETTE.len()],
        }
    }

    fn to_px(&self, x: f64, y: f64) -> (i64, i64) {
        (
            ((x - self.x0) * self.px_per_mm).round() as i64,
            ((self.y1 - y) * self.px_per_mm).round() as i64,
        )
    }

    fn disk(&mut self, cx: i64, cy: i64, r: i64, colour: [u8; 3]) {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy > r * r {
                    continue;
                }
                let (x, y) = (cx + dx, cy + dy);
                if x >= 0
                    && y >= 0
                    && (x as u32) < self.img.width()
                    && (y as u32) < self.img.height()
                {
                    self.img.put_pixel(x as u32, y as u32, image::Rgb(colour));
                }
            }
        }
    }

    /// Paint bead of `material` where the head stands.
    pub fn paint(&mut self, x: f64, y: f64, material: u8) {
        let (px, py) = self.to_px(x, y);
        if self.last == Some((px, py, material)) {
            return;
        }
        self.last = Some((px, py, material));
        self.used[material as usize % PALETTE.len()] = true;
        let colour = PALETTE[material as usize % PALETTE.len()];
        self.disk(px, py, self.radius, colour);
    }

    /// Dots for every boundary, coloured by its error along the path.
    pub fn mark_boundaries(&mut self, boundaries: &[Boundary]) {
        let r = (self.radius / 2).max(2);
        for b in boundaries {
            let (px, py) = self.to_px(b.point[0], b.point[1]);
            self.disk(px, py, r + 1, [0, 0, 0]);
            self.disk(px, py, r, error_colour(b.error().abs()));
        }
    }

    /// The plate framed for a person: mm axes, the materials deposited, the error scale.
    pub fn figure(&self) -> Result<image::RgbImage, String> {
        let (w, h) = (self.img.width() as f64, self.img.height() as f64);
        let plate = figure::Plate {
            caption: String::new(),
            img: self.img.clone(),
            x_mm: (self.x0, self.x0 + w / self.px_per_mm),
            y_mm: (self.y1 - h / self.px_per_mm, self.y1),
        };
        let mut key: Vec<figure::Key> = self
            .used
            .iter()
            .enumerate()
            .filter(|(_, &u)| u)
            .map(|(m, _)| {
                let name = self
                    .names
                    .get(m)
                    .cloned()
                    .unwrap_or_else(|| format!("material {m}"));
                figure::Key::Swatch(name, PALETTE[m])
            })
            .collect();
        key.push(figure::Key::Note("dots: material boundaries".into()));
        key.push(figure::Key::Bar {
            label: "boundary error (mm)".into(),
            lo: 0.0,
            hi: ERROR_SCALE_MM,
            colour: error_colour,
        });
        figure::framed(
            "plate after the simulated print",
            std::slice::from_ref(&plate),
            1,
            &key,
        )
    }

    /// Writes the PNG atomically.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let mut staged = output::StagedFiles::new();
        self.stage(&mut staged, path)?;
        output::commit(staged)?;
        Ok(())
    }

    /// Stages the framed PNG ([`Heatmap::figure`]) in `staged` (renamed into place when
    /// it is committed).
    pub fn stage(&self, staged: &mut output::StagedFiles, path: &Path) -> anyhow::Result<()> {
        use image::ImageEncoder;
        let img = self
            .figure()
            .map_err(|e| anyhow::anyhow!("{}: cannot draw the heatmap: {e}", path.display()))?;
        output::stage(staged, path, |w| {
            image::codecs::png::PngEncoder::new(w)
                .write_image(
                    img.as_raw(),
                    img.width(),
                    img.height(),
                    image::ExtendedColorType::Rgb8,
                )
                .map_err(std::io::Error::other)
        })?;
        Ok(())
    }

    /// The plate alone, unframed, one pixel per cell.
    pub fn image(&self) -> &image::RgbImage {
        &self.img
    }
}

/// Green at 0, yellow at half [`ERROR_SCALE_MM`], red at it and beyond.
pub fn error_colour(e: f64) -> [u8; 3] {
    let f = (e / ERROR_SCALE_MM).clamp(0.0, 1.0);
    if f < 0.5 {
        [(510.0 * f) as u8, 190, 40]
    } else {
        [255, (190.0 * (1.0 - f) * 2.0) as u8, 40]
    }
}
