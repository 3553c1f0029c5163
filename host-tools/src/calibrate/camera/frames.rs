//! Loading a frame sequence: every .png/.jpg/.jpeg/.bmp in a folder, in file-name order,
//! checked against the frame and pixel limits from the image headers before anything is
//! decoded, then decoded to 8-bit grey, all of one size. Measuring them is `track`'s and
//! `edges`' job.

use super::super::error::CalOption;
use super::super::CalError;
use image::GrayImage;
use std::path::{Path, PathBuf};

/// The extensions of the files read as frames (any case); others in the folder are passed
/// over.
pub const EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "bmp"];

/// How much of a frame folder is read. Frames are held decoded (one byte a pixel) with
/// their pyramids and edges, and both memory and time grow with the pixels: ten 1280 x 960
/// frames (12 * 10^6 pixels) peaked at 83 MB, about 7 bytes a pixel. The default total,
/// 5 * 10^7 pixels, is 160 frames of 640 x 480 and about 0.35 GB at the peak.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most frames (`--max-frames`).
    pub max_frames: usize,
    /// Most pixels over all frames (`--max-pixels`).
    pub max_pixels: u64,
}

/// Default `--max-frames`.
pub const MAX_FRAMES: usize = 2_000;
/// Default `--max-pixels`.
pub const MAX_PIXELS: u64 = 50_000_000;

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_frames: MAX_FRAMES,
            max_pixels: MAX_PIXELS,
        }
    }
}

/// The image files of `dir`, sorted by name; at most `max_frames` of them.
pub fn list(dir: &Path, max_frames: usize) -> Result<Vec<PathBuf>, CalError> {
    let read = |source| CalError::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    let mut extra = 0usize;
    for entry in std::fs::read_dir(dir).map_err(read)? {
        let path = entry.map_err(read)?.path();
        let is_image = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        if is_image && path.is_file() {
            // Past the limit the files are only counted, to say by how much.
            if files.len() < max_frames {
                files.push(path);
            } else {
                extra += 1;
            }
        }
    }
    if extra > 0 {
        return Err(CalError::OverLimit {
            path: dir.to_path_buf(),
            what: format!(
                "{} frames, over the limit of {max_frames} by {extra}",
                max_frames + extra
            ),
            option: CalOption::MaxFrames,
        });
    }
    if files.is_empty() {
        return Err(CalError::NoImages {
            path: dir.to_path_buf(),
        });
    }
    files.sort();
    Ok(files)
}

fn reader(path: &Path) -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>, CalError> {
    let read = |source| CalError::Read {
        path: path.to_path_buf(),
        source,
    };
    image::ImageReader::open(path)
        .map_err(read)?
        .with_guessed_format()
        .map_err(read)
}

/// Every frame's size from its header (nothing decoded): all must match the first, and
/// their pixels together stay within `max_pixels`. Returns the common size.
pub fn check_sizes(files: &[PathBuf], dir: &Path, max_pixels: u64) -> Result<(u32, u32), CalError> {
    let mut first: Option<(u32, u32)> = None;
    for path in files {
        let (w, h) = reader(path)?
            .into_dimensions()
            .map_err(|e| CalError::Image {
                path: path.clone(),
                message: e.to_string(),
            })?;
        match first {
            None => first = Some((w, h)),
            Some((fw, fh)) if (fw, fh) != (w, h) => {
                return Err(CalError::FrameSize {
                    path: path.clone(),
                    got_w: w,
                    got_h: h,
                    want_w: fw,
                    want_h: fh,
                })
            }
            Some(_) => {}
        }
    }
    let (w, h) = first.unwrap_or((0, 0));
    let total = u64::from(w) * u64::from(h) * files.len() as u64;
    if total > max_pixels {
        return Err(CalError::OverLimit {
            path: dir.to_path_buf(),
            what: format!(
                "{} frames of {w}x{h} px are {total} pixels, over the limit of {max_pixels} by {}",
                files.len(),
                total - max_pixels
            ),
            option: CalOption::MaxPixels,
        });
    }
    Ok((w, h))
}

/// Decodes one frame to grey; `want` is the size its header promised (checked again, in
/// case the file changed since).
pub fn load_one(path: &Path, want: (u32, u32)) -> Result<GrayImage, CalError> {
    let img = reader(path)?
        .decode()
        .map_err(|e| CalError::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?
        .to_luma8();
    if img.dimensions() != want {
        return Err(CalError::FrameSize {
            path: path.to_path_buf(),
            got_w: img.width(),
            got_h: img.height(),
            want_w: want.0,
            want_h: want.1,
        });
    }
    Ok(img)
}
