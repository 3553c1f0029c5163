//! Synthetic side-view frames of a filament leaving a nozzle: a vertical band of known
//! width with a smooth texture that moves down a known distance per frame, anti-aliased
//! sides and a little pixel noise. Tests and the bundled example folder use it as ground
//! truth for `calibrate camera`; it is not a physics simulation.

use super::super::output::write_atomic;
use super::super::CalError;
use image::{GrayImage, Luma};
use std::path::Path;

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Synth {
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Filament width, px.
    pub filament_px: f64,
    /// Filament axis, px from the left.
    pub center_px: f64,
    /// Downward displacement per frame, px.
    pub speed_px_per_frame: f64,
    /// Background grey (0-255).
    pub background: f64,
    /// Mean filament grey (0-255).
    pub filament: f64,
    /// Texture amplitude (grey levels).
    pub texture: f64,
    /// Pixel noise amplitude (grey levels, uniform).
    pub noise: f64,
    /// Seeds the texture phases and the noise.
    pub seed: u64,
}

impl Default for Synth {
    fn default() -> Self {
        Synth {
            width: 160,
            height: 120,
            filament_px: 48.0,
            center_px: 80.0,
            speed_px_per_frame: 4.5,
            background: 40.0,
            filament: 170.0,
            texture: 45.0,
            noise: 2.0,
            seed: 1,
        }
    }
}

/// splitmix64: a fixed, dependency-free hash for texture phases and pixel noise.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

impl Synth {
    /// Texture grey offset at paste coordinates (x, s), s measured along the filament.
    fn texture_at(&self, x: f64, s: f64) -> f64 {
        // Eight plane waves, wavelengths 7-22 px in assorted directions: smooth enough to
        // sample at sub-pixel shifts, rich enough in both directions for optical flow.
        let mut v = 0.0;
        for k in 0..8u64 {
            let h = mix(self.seed.wrapping_mul(1000).wrapping_add(k));
            let wavelength = 7.0 + 15.0 * unit(h);
            let angle = std::f64::consts::PI * unit(mix(h));
            let phase = std::f64::consts::TAU * unit(mix(h ^ 0x55));
            let f = std::f64::consts::TAU / wavelength;
            v += (f * (x * angle.cos() + s * angle.sin()) + phase).sin();
        }
        self.texture * v / 8f64.sqrt()
    }

    /// Frame `i` (0-based).
    pub fn frame(&self, i: usize) -> GrayImage {
        let half = self.filament_px / 2.0;
        let (l, r) = (self.center_px - half, self.center_px + half);
        let shift = self.speed_px_per_frame * i as f64;
        GrayImage::from_fn(self.width, self.height, |x, y| {
            // Fraction of the pixel [x, x+1] the filament covers: anti-aliased sides.
            let cover = ((x as f64 + 1.0).min(r) - (x as f64).max(l)).clamp(0.0, 1.0);
            let cx = x as f64 + 0.5;
            let s = y as f64 + 0.5 - shift;
            let paste = self.filament + self.texture_at(cx, s);
            let noise = self.noise
                * (2.0
                    * unit(mix(
                        self.seed ^ ((i as u64) << 40 ^ (y as u64) << 20 ^ x as u64)
                    ))
                    - 1.0);
            let v = self.background * (1.0 - cover) + paste * cover + noise;
            Luma([v.round().clamp(0.0, 255.0) as u8])
        })
    }

    /// Writes `frames` PNGs `frame_000.png`.. into `dir` (created if missing).
    pub fn write(&self, dir: &Path, frames: usize) -> Result<(), CalError> {
        std::fs::create_dir_all(dir).map_err(|source| CalError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        for i in 0..frames {
            let path = dir.join(format!("frame_{i:03}.png"));
            let mut png = Vec::new();
            self.frame(i)
                .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .map_err(|e| CalError::Image {
                    path: path.clone(),
                    message: e.to_string(),
                })?;
            write_atomic(&path, &png)?;
        }
        Ok(())
    }
}
