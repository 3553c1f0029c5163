//! `dollop calibrate` within stated limits: CSV rows and bytes, camera frames and pixels
//! (from the image headers, before anything is decoded), each refusal naming the input,
//! the limit, by how much and the option that raises it; and the fragment and plot
//! written together or not at all.

mod calibrate_common;
mod png_header;

use calibrate_common::*;
use std::path::Path;

fn arg(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A power-law flow curve of `n` rows, every stress exact.
fn flow_curve_rows(dir: &Path, n: usize) -> std::path::PathBuf {
    let rows: Vec<(f64, f64)> = log_grid(0.5, 200.0, n)
        .into_iter()
        .map(|g| (g, 12.0 * g.powf(0.6) * (1.0 + 0.01 * (g * 7.0).sin())))
        .collect();
    csv(dir, "curve.csv", "shear_rate_1_s,shear_stress_pa", &rows)
}

#[test]
fn a_csv_with_more_rows_than_the_limit_is_refused_saying_by_how_much() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve_rows(dir.path(), 50);
    let e = run(&["rheology", arg(&path), "--max-rows", "10"]).unwrap_err();
    let msg = e.to_string();
    assert_eq!(msg.lines().count(), 1, "{msg}");
    assert!(msg.contains("curve.csv"), "{msg}");
    assert!(
        msg.contains("50 data rows, over the limit of 10 by 40") && msg.contains("--max-rows"),
        "{msg}"
    );
    // At the limit it fits, and the default limit takes it too.
    assert!(run(&["rheology", arg(&path), "--max-rows", "50"]).is_ok());
    assert!(run(&["rheology", arg(&path)]).is_ok());
    // Every CSV subcommand has the limit.
    for sub in ["flow", "lag"] {
        let e = run(&[sub, arg(&path), "--max-rows", "10"]).unwrap_err();
        assert!(e.to_string().contains("--max-rows"), "{sub}: {e}");
    }
    let e = run(&["syringe", "--lag", arg(&path), "--max-rows", "10"]).unwrap_err();
    assert!(e.to_string().contains("--max-rows"), "syringe --lag: {e}");
}

#[test]
fn a_csv_larger_than_the_byte_limit_is_refused_before_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    // 2.2 MiB of one endless line: no row to count, so only the size can refuse it.
    let path = dir.path().join("line.csv");
    std::fs::write(&path, "1".repeat(2_300_000)).unwrap();
    let e = run(&["rheology", arg(&path), "--max-csv-mb", "1"]).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("line.csv: 2.2 MiB of CSV, over the 1 MiB limit by 1.2 MiB")
            && msg.contains("--max-csv-mb"),
        "{msg}"
    );
}

fn camera(dir: &Path, extra: &[&str]) -> Result<String, dollop_host::calibrate::CalError> {
    let mut args = vec!["camera", arg(dir), "--fps", "30", "--mm-per-px", "0.02"];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn camera_frames_over_the_pixel_limit_are_refused_from_their_headers() {
    // Three 20000 x 20000 frames: 1.2 * 10^9 pixels. No pixel data is there, so a refusal
    // that names the limit can only come from the headers.
    let dir = tempfile::tempdir().unwrap();
    for i in 0..3 {
        png_header::write(&dir.path().join(format!("f{i}.png")), 20000, 20000, 8);
    }
    let msg = camera(dir.path(), &[]).unwrap_err().to_string();
    assert_eq!(msg.lines().count(), 1, "{msg}");
    assert!(
        msg.contains("3 frames of 20000x20000 px are 1200000000 pixels, over the limit of 50000000 by 1150000000")
            && msg.contains("--max-pixels"),
        "{msg}"
    );
    // The bundled frames (160 x 120) pass the default and are refused by a lower limit.
    let bundled = data().join("camera");
    assert!(camera(&bundled, &[]).is_ok());
    let msg = camera(&bundled, &["--max-pixels", "100000"])
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("over the limit of 100000") && msg.contains("--max-pixels"),
        "{msg}"
    );
}

#[test]
fn more_frames_than_the_limit_are_refused_saying_by_how_much() {
    let bundled = data().join("camera");
    let n = std::fs::read_dir(&bundled).unwrap().count();
    let msg = camera(&bundled, &["--max-frames", "3"])
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains(&format!("{n} frames, over the limit of 3 by {}", n - 3))
            && msg.contains("--max-frames"),
        "{msg}"
    );
}

#[test]
fn a_frame_of_another_size_is_refused_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    png_header::write(&dir.path().join("a.png"), 64, 48, 8);
    png_header::write(&dir.path().join("b.png"), 64, 40, 8);
    let msg = camera(dir.path(), &[]).unwrap_err().to_string();
    assert!(
        msg.contains("b.png: frame is 64x40 px but the first frame is 64x48"),
        "{msg}"
    );
}

#[test]
fn fragment_and_plot_are_written_together_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("puree.toml");
    let plot = dir.path().join("missing-folder").join("puree.png");
    let e = run(&[
        "rheology",
        arg(&data().join("rheology-puree.csv")),
        "--out",
        arg(&out),
        "--plot",
        arg(&plot),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("puree.png"), "{e}");
    assert!(
        !out.exists(),
        "the fragment was written although the plot failed"
    );
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // With both paths good, both are there.
    let plot = dir.path().join("puree.png");
    run(&[
        "rheology",
        arg(&data().join("rheology-puree.csv")),
        "--out",
        arg(&out),
        "--plot",
        arg(&plot),
    ])
    .unwrap();
    assert!(out.exists() && plot.exists());
}
