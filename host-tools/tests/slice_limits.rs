//! Hostile inputs from issue 11 to `dollop slice`: each is refused in one line naming
//! the file or option and the limit, exits non-zero and writes nothing; and outputs are
//! written together or not at all, never over a symlink.

mod png_header;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn seed_config() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/seed-paper.toml")
}

fn slice(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dollop"))
        .current_dir(dir)
        .arg("slice")
        .args(args)
        .arg("--config")
        .arg(seed_config())
        .output()
        .unwrap()
}

fn files(dir: &Path) -> Vec<std::ffi::OsString> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    v.sort();
    v
}

/// Runs the slice; checks exit 1, one line containing `needle`, nothing written.
fn refused(dir: &Path, args: &[&str], needle: &str) {
    let before = files(dir);
    let out = slice(
        dir,
        &[args, &["--out", "out.dlp", "--preview", "out.png"]].concat(),
    );
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
    assert_eq!(before, files(dir), "{args:?} left files behind");
}

fn small_png(dir: &Path) {
    image::RgbaImage::from_fn(20, 10, |x, _| {
        image::Rgba(if x < 10 { [0, 0, 0, 255] } else { [255; 4] })
    })
    .save(dir.join("d.png"))
    .unwrap();
}

#[test]
fn options_that_would_panic_or_mislead_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_png(d);
    refused(
        d,
        &["d.png", "--layers", "18446744073709551615"],
        "--max-segments",
    );
    refused(d, &["d.png", "--layers", "1000000"], "--max-segments");
    refused(d, &["d.png", "--connect-mm", "nan"], "--connect-mm");
    refused(
        d,
        &["d.png", "--background-tolerance", "nan"],
        "--background-tolerance",
    );
    refused(d, &["d.png", "--prime-mm", "nan"], "--prime-mm");
}

#[test]
fn a_huge_one_bit_png_is_refused_from_its_header_before_decoding() {
    // 32000 x 32000 one-bit grey: 128 MB decoded, 4 GB as RGBA. The header alone says
    // so; there is no image data at all, so decoding would fail differently.
    let dir = tempfile::tempdir().unwrap();
    png_header::write(&dir.path().join("big.png"), 32000, 32000, 1);
    refused(
        dir.path(),
        &["big.png"],
        "32000 x 32000 = 1024000000 exceeds the limit of 50000000 by 974000000 (--max-pixels",
    );
    // The limit is the user's to set.
    small_png(dir.path());
    refused(
        dir.path(),
        &["d.png", "--max-pixels", "100"],
        "--max-pixels",
    );
}

/// A 3MF package (stored, not compressed) holding `model` as its model part.
fn write_3mf(path: &Path, model: &str) {
    let f = std::fs::File::create(path).unwrap();
    let mut z = zip::ZipWriter::new(f);
    let o =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    z.start_file("[Content_Types].xml", o).unwrap();
    z.write_all(br#"<?xml version="1.0" encoding="UTF-8"?><Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types"><Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>"#).unwrap();
    z.start_file("3D/3dmodel.model", o).unwrap();
    z.write_all(model.as_bytes()).unwrap();
    z.finish().unwrap();
}

const TETRA: &str = r#"<mesh><vertices><vertex x="0" y="0" z="0"/><vertex x="10" y="0" z="0"/><vertex x="0" y="10" z="0"/><vertex x="0" y="0" z="10"/></vertices><triangles><triangle v1="0" v2="2" v3="1"/><triangle v1="0" v2="1" v3="3"/><triangle v1="0" v2="3" v3="2"/><triangle v1="1" v2="2" v3="3"/></triangles></mesh>"#;

#[test]
fn nested_3mf_components_are_counted_not_expanded() {
    // Ten wide, nine deep: 4 x 10^9 triangles from a file of a few kilobytes.
    let dir = tempfile::tempdir().unwrap();
    let mut objects = format!(r#"<object id="1" type="model">{TETRA}</object>"#);
    for id in 2..=10 {
        objects.push_str(&format!(r#"<object id="{id}" type="model"><components>"#));
        for _ in 0..10 {
            objects.push_str(&format!(r#"<component objectid="{}"/>"#, id - 1));
        }
        objects.push_str("</components></object>");
    }
    let model = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02"><resources>{objects}</resources><build><item objectid="10"/></build></model>"#
    );
    write_3mf(&dir.path().join("nest.3mf"), &model);
    refused(
        dir.path(),
        &["nest.3mf"],
        "triangles after expanding components: 4000000000 exceeds the limit of 5000000",
    );
}

#[test]
fn a_3mf_of_mostly_whitespace_is_refused_by_its_decompressed_size() {
    let dir = tempfile::tempdir().unwrap();
    let pad = " ".repeat(3 << 20);
    let model = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">{pad}<resources><object id="1" type="model">{TETRA}</object></resources><build><item objectid="1"/></build></model>"#
    );
    write_3mf(&dir.path().join("ws.3mf"), &model);
    refused(
        dir.path(),
        &["ws.3mf", "--max-3mf-mb", "2"],
        "model XML is more than the limit of 2 MiB (--max-3mf-mb",
    );
}

#[test]
fn a_missing_folder_for_one_output_leaves_none_and_names_the_users_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_png(d);
    for extra in [
        ["--preview", "nowhere/p.png"],
        ["--gcode", "nowhere/g.gcode"],
    ] {
        let out = slice(
            d,
            &[&["d.png", "--out", "out.dlp"][..], &extra[..]].concat(),
        );
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.contains(&format!("{}: cannot write", extra[1])),
            "{err}"
        );
        assert!(!err.contains(".part"), "{err}");
        assert_eq!(files(d), vec![std::ffi::OsString::from("d.png")], "{err}");
    }
}

#[cfg(unix)]
#[test]
fn an_output_path_that_is_a_symlink_is_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_png(d);
    std::fs::write(d.join("precious"), b"keep").unwrap();
    std::os::unix::fs::symlink(d.join("precious"), d.join("job.dlp")).unwrap();
    let out = slice(d, &["d.png", "--out", "job.dlp"]);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("job.dlp: cannot write: is a symbolic link"),
        "{err}"
    );
    assert!(std::fs::symlink_metadata(d.join("job.dlp"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(d.join("precious")).unwrap(), b"keep");
}
