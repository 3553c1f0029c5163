//! The bundled designs slice into compact jobs, and the golden job file guards the bytes
//! the slicer writes for the bundled chessboard. `make_bundled_designs` (ignored) is how
//! the designs were made; `DOLLOP_BLESS=1` rewrites the golden file after a deliberate
//! format change.

use dollop::config::Config;
use dollop::Command;
use dollop_host::fixtures::{bundled, designs_dir, example_config};
use dollop_host::slicer::job_file::{decode_job, read_job};
use dollop_host::slicer::mesh::{shapes, write_stl};
use dollop_host::slicer::{self, SliceOptions};
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn golden_config() -> Config {
    slicer::load_config(&data("golden-machine.toml")).unwrap()
}

/// Anti-aliased drawing: `inside(x, y)` in pixel units gives the colour at a point or
/// None (transparent); 4x4 samples per pixel.
fn draw(size: u32, inside: impl Fn(f64, f64) -> Option<[u8; 3]>) -> image::RgbaImage {
    image::RgbaImage::from_fn(size, size, |x, y| {
        let mut acc = [0u32; 4];
        for sy in 0..4 {
            for sx in 0..4 {
                let p = (
                    x as f64 + (sx as f64 + 0.5) / 4.0,
                    y as f64 + (sy as f64 + 0.5) / 4.0,
                );
                if let Some(c) = inside(p.0, p.1) {
                    for k in 0..3 {
                        acc[k] += c[k] as u32;
                    }
                    acc[3] += 1;
                }
            }
        }
        if acc[3] == 0 {
            return image::Rgba([0, 0, 0, 0]);
        }
        let n = acc[3];
        image::Rgba([
            (acc[0] / n) as u8,
            (acc[1] / n) as u8,
            (acc[2] / n) as u8,
            (n * 255 / 16) as u8,
        ])
    })
}

#[test]
#[ignore = "regenerates host-tools/designs; run by hand"]
fn make_bundled_designs() {
    let dir = designs_dir();
    // 8 x 8 squares of 6 px: with one pixel per 0.8 mm pitch, a 38.4 mm board.
    let board = image::RgbaImage::from_fn(48, 48, |x, y| {
        if (x / 6 + y / 6).is_multiple_of(2) {
            image::Rgba([40, 28, 20, 255])
        } else {
            image::Rgba([240, 228, 200, 255])
        }
    });
    board.save(dir.join("chessboard.png")).unwrap();
    // A chocolate disc with a cream ring and dot, on a transparent background.
    let brown = [90, 58, 34];
    let cream = [243, 227, 195];
    let logo = draw(240, |x, y| {
        let r = ((x - 120.0).powi(2) + (y - 120.0).powi(2)).sqrt();
        if r <= 25.0 || (60.0..=80.0).contains(&r) {
            Some(cream)
        } else if r <= 110.0 {
            Some(brown)
        } else {
            None
        }
    });
    logo.save(dir.join("logo.png")).unwrap();
    // A 20 mm cube with a 7 mm ball inside it, each body its own STL.
    let p = [dir.join("cube-shell.stl"), dir.join("cube-ball.stl")];
    let bodies = shapes::box_with_sphere([&p[0], &p[1]], [0.0; 3], [20.0; 3], 7.0, 4000);
    for (m, path) in bodies.iter().zip(&p) {
        write_stl(path, m).unwrap();
    }
}

#[test]
fn bundled_designs_slice_to_at_most_8_bytes_per_print_segment() {
    let config = example_config().unwrap();
    for (label, files, opts) in bundled() {
        let s =
            slicer::slice_files(&files, &config, &opts).unwrap_or_else(|e| panic!("{label}: {e}"));
        let per = s.file_bytes_per_segment();
        eprintln!(
            "{label}: {} segments, {} bytes, {per:.2} B/segment (body {:.2}), {} switches",
            s.header.print_segments,
            s.to_bytes().len(),
            s.body_bytes_per_segment(),
            s.stats.switches
        );
        assert!(per <= 8.0, "{label}: {per:.2} bytes per segment");
        assert!(s.stats.switches > 0, "{label} has two materials");
        assert_eq!(s.header.materials.len(), 2, "{label}");
        // What was written decodes to what was sliced.
        let (h, cmds) = decode_job(&s.to_bytes()).unwrap();
        assert_eq!(h, s.header);
        assert_eq!(cmds, s.commands);
    }
}

#[test]
fn golden_job_file_guards_the_chessboard_bytes() {
    let s = slicer::slice_files(
        &[designs_dir().join("chessboard.png")],
        &golden_config(),
        &SliceOptions::default(),
    )
    .unwrap();
    let bytes = s.to_bytes();
    let golden = data("chessboard.dlp");
    if std::env::var_os("DOLLOP_BLESS").is_some() {
        std::fs::write(&golden, &bytes).unwrap();
    }
    let want = std::fs::read(&golden).expect("golden file missing: run with DOLLOP_BLESS=1");
    assert!(bytes == want, "sliced bytes differ from {} ({} vs {} bytes); if the change is deliberate, bump the format version and re-bless", golden.display(), bytes.len(), want.len());
    // And the golden file reads back with every check passing.
    let (h, cmds) = read_job(&golden).unwrap();
    assert_eq!(
        h.print_segments as usize,
        cmds.iter()
            .filter(|c| matches!(c, Command::Print { .. }))
            .count()
    );
    assert_eq!(h.config_hash, dollop::job::config_hash(&golden_config()));
}

#[test]
fn the_chessboard_prints_each_square_in_its_material_with_boundaries_where_drawn() {
    let s = slicer::slice_files(
        &[designs_dir().join("chessboard.png")],
        &golden_config(),
        &SliceOptions::default(),
    )
    .unwrap();
    // Walk the job: every print segment's midpoint must lie in a square of its material.
    let [x0, y0] = [s.header.bounds_min_um[0], s.header.bounds_min_um[1]];
    let _ = (x0, y0);
    let mut at = [s.header.start_um[0] as i64, s.header.start_um[1] as i64];
    let mut design_origin: Option<[i64; 2]> = None;
    let mut checked = 0;
    for (i, c) in s.commands.iter().enumerate() {
        match *c {
            Command::Travel { x, y, .. } => {
                if i > 0 && design_origin.is_none() {
                    // The first travel after the priming bead goes to the lower-left row
                    // start: half a pitch above the design's lower edge.
                    design_origin = Some([x as i64, y as i64 - 400]);
                }
                at = [x as i64, y as i64];
            }
            Command::Print { dx, dy, material } => {
                if let (Some(o), true) = (design_origin, dy == 0) {
                    let mid = [at[0] + dx as i64 / 2 - o[0], at[1] - o[1]];
                    let (cx, cy) = (mid[0] / 4800, mid[1] / 4800);
                    // Dark squares (material 0) where (column + row-from-top) is even.
                    let row_from_top = 7 - cy;
                    let want = ((cx + row_from_top) % 2) as u8;
                    assert_eq!(material, want, "segment {i} at {mid:?}");
                    // Row segments end on square edges.
                    assert_eq!((at[0] + dx as i64 - o[0]) % 4800, 0, "segment {i}");
                    checked += 1;
                }
                at[0] += dx as i64;
                at[1] += dy as i64;
            }
            _ => {}
        }
    }
    assert_eq!(checked, 48 * 8, "48 rows of 8 squares");
}
