//! Loading a frame sequence: every .png/.jpg/.jpeg/.bmp in a folder, in file-name order,
//! decoded to 8-bit grey, all of one size. Measuring them is `track`'s and `edges`' job.

use super::super::CalError;
use image::GrayImage;
use std::path::{Path, PathBuf};

const EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "bmp"];

/// The image files of `dir`, sorted by name.
pub fn list(dir: &Path) -> Result<Vec<PathBuf>, CalError> {
    let read = |source| CalError::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(read)? {
        let path = entry.map_err(read)?.path();
        let is_image = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        if is_image && path.is_file() {
            files.push(path);
        }
    }
    if files.is_empty() {
        return Err(CalError::NoImages {
            path: dir.to_path_buf(),
        });
    }
    files.sort();
    Ok(files)
}

/// Decodes `files` to grey, checking that they share the first frame's size.
pub fn load(files: &[PathBuf]) -> Result<Vec<GrayImage>, CalError> {
    let mut out: Vec<GrayImage> = Vec::with_capacity(files.len());
    for path in files {
        let img = image::ImageReader::open(path)
            .map_err(|source| CalError::Read {
                path: path.clone(),
                source,
            })?
            .with_guessed_format()
            .map_err(|source| CalError::Read {
                path: path.clone(),
                source,
            })?
            .decode()
            .map_err(|e| CalError::Image {
                path: path.clone(),
                message: e.to_string(),
            })?
            .to_luma8();
        if let Some(first) = out.first() {
            if img.dimensions() != first.dimensions() {
                return Err(CalError::FrameSize {
                    path: path.clone(),
                    got_w: img.width(),
                    got_h: img.height(),
                    want_w: first.width(),
                    want_h: first.height(),
                });
            }
        }
        out.push(img);
    }
    Ok(out)
}
