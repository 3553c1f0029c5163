//! `dollop inspect` end to end on the bundled worked example (a chessboard printed on a
//! machine whose channel is 20 % longer than its config says): the report, the picture,
//! the suggestion and its fragment; bad arguments refused in one line, nothing written.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn inspect(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let data = root().join("host-tools/data/inspect");
    Command::new(env!("CARGO_BIN_EXE_dollop"))
        .arg("inspect")
        .arg(data.join("chessboard-photo.jpg"))
        .arg("--job")
        .arg(data.join("chessboard.dlp"))
        .arg("--config")
        .arg(root().join("configs/seed-paper-valves.toml"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_worked_example_finds_the_longer_channel() {
    let dir = tempfile::tempdir().unwrap();
    let (pic, frag) = (dir.path().join("plate.png"), dir.path().join("fix.toml"));
    let out = inspect(&[
        "--picture".as_ref(),
        pic.as_os_str(),
        "--suggest".as_ref(),
        "--out".as_ref(),
        frag.as_os_str(),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("boundaries        51 of 51 found"), "{text}");
    assert!(text.contains("photo resolution  43.8 px/mm"), "{text}");
    assert!(text.contains("  widest "), "{text}");
    assert!(
        text.contains("away from switches, median: paste A (1.41 Pa s): 0.800 mm"),
        "{text}"
    );
    assert!(
        text.contains("believed off: channel and filament volume (channel_length_mm)"),
        "{text}"
    );
    let fragment = std::fs::read_to_string(&frag).unwrap();
    // Configured 2.4 mm; the print's channel is 2.88 mm.
    let line = fragment
        .lines()
        .find(|l| l.starts_with("channel_length_mm = "))
        .unwrap_or_else(|| panic!("{fragment}"));
    let l: f64 = line["channel_length_mm = ".len()..].parse().unwrap();
    assert!((l - 2.88).abs() < 0.03, "{line}");
    let img = image::open(&pic).unwrap();
    assert!(img.width() > 400 && img.height() > 300);
}

#[test]
fn bad_arguments_are_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let pic = dir.path().join("plate.png");
    for (args, needle) in [
        (vec!["--px-per-mm", "0"], "--px-per-mm"),
        (vec!["--max-pixels", "100"], "--max-pixels"),
    ] {
        let mut a: Vec<&std::ffi::OsStr> = args.iter().map(|s| s.as_ref()).collect();
        a.push("--picture".as_ref());
        a.push(pic.as_os_str());
        let out = inspect(&a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} accepted");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{err}");
        assert!(!pic.exists(), "{args:?} wrote the picture");
    }
    // --out without --suggest is refused by the parser.
    let out = inspect(&["--out".as_ref(), pic.as_os_str()]);
    assert!(!out.status.success());
}
