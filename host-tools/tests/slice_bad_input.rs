//! Bad input to `dollop slice`: each case exits non-zero with one line naming the file
//! and the problem, and leaves no output (not even a temporary file) behind.

use dollop_host::slicer::mesh::{shapes, write_stl};
use std::path::{Path, PathBuf};
use std::process::Command;

fn seed_config() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/seed-paper.toml")
}

/// Runs `dollop slice ARGS --out DIR/out.dlp --gcode .. --preview ..` in `dir`; returns
/// stderr after checking the exit code, the one-line message and that nothing was written.
fn refused(dir: &Path, args: &[&str]) -> String {
    let before: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .current_dir(dir)
        .arg("slice")
        .args(args)
        .args([
            "--out",
            "out.dlp",
            "--gcode",
            "out.gcode",
            "--preview",
            "out.png",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "{args:?}: one line expected: {err}"
    );
    assert!(err.starts_with("dollop: "), "{err}");
    assert!(
        out.stdout.is_empty(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    let after: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(before, after, "{args:?} left files behind");
    err
}

fn png(dir: &Path, name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> String {
    image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)))
        .save(dir.join(name))
        .unwrap();
    name.to_string()
}

#[test]
fn each_bad_input_gets_a_one_line_reason_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = seed_config();
    let cfg = cfg.to_str().unwrap();

    let e = refused(d, &["missing.png", "--config", cfg]);
    assert!(e.contains("missing.png: no such file"), "{e}");

    std::fs::write(d.join("garbage.png"), b"\x89PNG\r\n\x1a\nthis is not a png").unwrap();
    let e = refused(d, &["garbage.png", "--config", cfg]);
    assert!(e.contains("garbage.png: unreadable image"), "{e}");

    let clear = png(d, "clear.png", 8, 8, |_, _| [0, 0, 0, 0]);
    let e = refused(d, &[&clear, "--config", cfg]);
    assert!(e.contains("clear.png: empty design"), "{e}");

    let white = png(d, "white.png", 8, 8, |_, _| [255, 255, 255, 255]);
    let e = refused(d, &[&white, "--config", cfg, "--background", "#ffffff"]);
    assert!(e.contains("white.png: empty design"), "{e}");

    let rgb = png(d, "rgb.png", 30, 10, |x, _| match x / 10 {
        0 => [200, 30, 30, 255],
        1 => [30, 200, 30, 255],
        _ => [30, 30, 200, 255],
    });
    let e = refused(d, &[&rgb, "--config", cfg, "--palette", "auto"]);
    assert!(
        e.contains("rgb.png: 3 materials but the machine has 2 inlet(s)"),
        "{e}"
    );
    let e = refused(
        d,
        &[
            &rgb,
            "--config",
            cfg,
            "--palette",
            "#ff0000,#00ff00,#0000ff",
        ],
    );
    assert!(e.contains("rgb.png: 3 materials"), "{e}");

    let big = png(d, "big.png", 20, 20, |_, _| [0, 0, 0, 255]);
    let e = refused(d, &[&big, "--config", cfg, "--width-mm", "250"]);
    assert!(
        e.contains("big.png: design is") && e.contains("travel limits allow 200.0"),
        "{e}"
    );
    let e = refused(d, &[&big, "--config", cfg, "--origin", "190,10"]);
    assert!(
        e.contains("big.png") && e.contains("leaves the travel limits on X"),
        "{e}"
    );

    std::fs::write(d.join("empty.stl"), b"solid empty\nendsolid empty\n").unwrap();
    let e = refused(d, &["empty.stl", "--config", cfg]);
    assert!(e.contains("empty.stl: STL has no triangles"), "{e}");
    let mut bin = vec![0u8; 84];
    bin[..5].copy_from_slice(b"dolop");
    std::fs::write(d.join("empty-bin.stl"), &bin).unwrap();
    let e = refused(d, &["empty-bin.stl", "--config", cfg]);
    assert!(e.contains("empty-bin.stl: STL has no triangles"), "{e}");

    std::fs::write(
        d.join("nan.stl"),
        "solid n\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 nan\nvertex 0 1 0\nendloop\nendfacet\nendsolid n\n",
    )
    .unwrap();
    let e = refused(d, &["nan.stl", "--config", cfg]);
    assert!(e.contains("nan.stl: ") && e.contains("NaN"), "{e}");
    let mut nan = shapes::cuboid(Path::new("nan-bin.stl"), [0.0; 3], [10.0; 3]);
    nan.vertices[3][1] = f32::NAN;
    write_stl(&d.join("nan-bin.stl"), &nan).unwrap();
    let e = refused(d, &["nan-bin.stl", "--config", cfg]);
    assert!(
        e.contains("nan-bin.stl: triangle 0 has a NaN or infinite vertex"),
        "{e}"
    );

    let mut open = shapes::cuboid(&d.join("open.stl"), [0.0; 3], [10.0; 3]);
    open.triangles.pop();
    write_stl(&d.join("open.stl"), &open).unwrap();
    let e = refused(d, &["open.stl", "--config", cfg]);
    assert!(e.contains("open.stl: not a closed manifold body"), "{e}");

    let mut flipped = shapes::cuboid(&d.join("flipped.stl"), [0.0; 3], [10.0; 3]);
    flipped.triangles[0].swap(1, 2);
    write_stl(&d.join("flipped.stl"), &flipped).unwrap();
    let e = refused(d, &["flipped.stl", "--config", cfg]);
    assert!(
        e.contains("flipped.stl: faces not consistently oriented") && e.contains("normals"),
        "{e}"
    );

    write_stl(
        &d.join("a.stl"),
        &shapes::cuboid(Path::new("a"), [0.0; 3], [10.0; 3]),
    )
    .unwrap();
    write_stl(
        &d.join("b.stl"),
        &shapes::cuboid(Path::new("b"), [5.0, 5.0, 0.0], [15.0, 15.0, 10.0]),
    )
    .unwrap();
    let e = refused(d, &["a.stl", "b.stl", "--config", cfg]);
    assert!(e.contains("a.stl and b.stl overlap"), "{e}");
    let e = refused(d, &["a.stl", "b.stl", "a.stl", "--config", cfg]);
    assert!(
        e.contains("3 materials but the machine has 2 inlet(s)"),
        "{e}"
    );

    std::fs::write(d.join("design.obj"), b"o x").unwrap();
    let e = refused(d, &["design.obj", "--config", cfg]);
    assert!(e.contains("design.obj: unknown design format"), "{e}");

    let good = std::fs::read_to_string(seed_config()).unwrap();
    std::fs::write(
        d.join("bad.toml"),
        good.replace("nozzle_diameter_mm = 0.8", "nozzle_diameter_mm = 0.0"),
    )
    .unwrap();
    let e = refused(d, &[&big, "--config", "bad.toml"]);
    assert!(
        e.contains("bad.toml: invalid config: channel.nozzle_diameter_mm"),
        "{e}"
    );
    std::fs::write(
        d.join("typo.toml"),
        good.replace("line_pitch_mm", "line_pich_mm"),
    )
    .unwrap();
    let e = refused(d, &[&big, "--config", "typo.toml"]);
    assert!(
        e.contains("typo.toml: config does not parse") && e.contains("line_pich_mm"),
        "{e}"
    );
    let e = refused(d, &[&big, "--config", "nowhere.toml"]);
    assert!(e.contains("nowhere.toml: no such file"), "{e}");
}

#[test]
fn a_failed_slice_leaves_an_existing_job_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("out.dlp"), b"previous job").unwrap();
    let clear = png(d, "clear.png", 4, 4, |_, _| [0, 0, 0, 0]);
    let cfg = seed_config();
    refused(d, &[&clear, "--config", cfg.to_str().unwrap()]);
    assert_eq!(std::fs::read(d.join("out.dlp")).unwrap(), b"previous job");
}
