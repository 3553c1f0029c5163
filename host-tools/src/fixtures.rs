//! The bundled example data shared by the tests, `dollop bench` and the command's own
//! examples: the example machine config, where the bundled designs live and the options
//! they slice with, and designs and pictures built in code (a chessboard, a test image).
//! Data only: nothing here runs a job or parses arguments.

use crate::slicer::design::Design;
use crate::slicer::image::ImageOptions;
use crate::slicer::SliceOptions;
use dollop::config::Config;
use std::path::{Path, PathBuf};

/// The example machine config (the seed paper's printhead): `dollop config --example`
/// prints it, and it is every benchmark figure's base machine.
pub const EXAMPLE_CONFIG: &str = include_str!("example-config.toml");

/// The example config (the seed paper's printhead), as every figure's base machine.
pub fn example_config() -> anyhow::Result<Config> {
    Ok(toml::from_str(EXAMPLE_CONFIG)?)
}

/// Where the bundled designs live (the source tree's `host-tools/designs`).
pub fn designs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("designs")
}

/// A two-material test picture: a chessboard of 16 squares across inside a disc, the
/// rest transparent.
pub fn test_image(size: u32) -> ::image::DynamicImage {
    let sq = (size / 16).max(1);
    let r = size as f64 * 0.48;
    let c = size as f64 / 2.0;
    ::image::DynamicImage::ImageRgba8(::image::RgbaImage::from_fn(size, size, |x, y| {
        let (dx, dy) = (x as f64 + 0.5 - c, y as f64 + 0.5 - c);
        if dx * dx + dy * dy > r * r {
            ::image::Rgba([255, 255, 255, 0])
        } else if ((x / sq) + (y / sq)).is_multiple_of(2) {
            ::image::Rgba([70, 40, 20, 255])
        } else {
            ::image::Rgba([240, 225, 190, 255])
        }
    }))
}

/// The bundled designs, sliced for the example machine: (label, design files, options).
pub fn bundled() -> Vec<(&'static str, Vec<PathBuf>, SliceOptions)> {
    let d = designs_dir();
    let logo = SliceOptions {
        image: ImageOptions {
            width_mm: Some(40.0),
            ..Default::default()
        },
        ..Default::default()
    };
    vec![
        (
            "chessboard.png",
            vec![d.join("chessboard.png")],
            SliceOptions::default(),
        ),
        ("logo.png (40 mm)", vec![d.join("logo.png")], logo),
        (
            "cube-shell.stl + cube-ball.stl",
            vec![d.join("cube-shell.stl"), d.join("cube-ball.stl")],
            SliceOptions::default(),
        ),
    ]
}

/// A chessboard design of `width` mm with `square` mm squares at `pitch`, built directly
/// (boundaries exactly on the squares).
pub fn chessboard_design(width: f64, square: f64, pitch: f64) -> Design {
    use crate::slicer::design::{Layer, Run};
    let rows = (width / pitch).round() as usize;
    let n = (width / square).round() as usize;
    let mut layer = Layer::new();
    for r in 0..rows {
        let y = (r as f64 + 0.5) * pitch;
        let mut runs: Vec<Run> = (0..n)
            .map(|c| Run {
                x0: c as f64 * square,
                x1: (c + 1) as f64 * square,
                material: (((y / square).floor() as usize + c) % 2) as u8,
            })
            .collect();
        layer.push_row(&mut runs, 0.0);
    }
    Design {
        name: format!("{square} mm chessboard"),
        size_mm: [n as f64 * square, rows as f64 * pitch],
        pitch_mm: pitch,
        layers: vec![layer],
    }
}
