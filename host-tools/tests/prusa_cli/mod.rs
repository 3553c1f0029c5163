//! Runs Debian's `prusa-slicer` with the committed paste profile, for the tests that slice
//! with it (`gcode_slicers`, `gcode_widths`); stops at the G-code it writes.

use std::path::Path;
use std::process::Command;

/// Slices `model` with `tests/data/slicers/prusaslicer-paste.ini`, centred at (100, 100)
/// mm, with `extra` options after the profile's, into `out`: the G-code's text. Panics
/// with the slicer's own message where it fails.
pub fn slice(model: &Path, out: &Path, extra: &[&str]) -> String {
    let ini =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/slicers/prusaslicer-paste.ini");
    let r = Command::new("prusa-slicer")
        .arg("--export-gcode")
        .arg(model)
        .arg("--load")
        .arg(&ini)
        .args(["--center", "100,100"])
        .args(extra)
        .arg("--output")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        r.status.success(),
        "prusa-slicer: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    std::fs::read_to_string(out).unwrap()
}
