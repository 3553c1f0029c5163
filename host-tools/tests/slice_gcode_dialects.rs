//! `dollop slice --gcode` options from the command line: the default is the export from the
//! executor's run in the plain dialect, `--gcode-dialect` and `--gcode-ports` pick the
//! words and ports, the older styles stay selectable, and bad combinations are refused
//! with one line naming the option, leaving nothing written.

use std::path::Path;
use std::process::Command;

fn manifest(p: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(p)
        .to_str()
        .unwrap()
        .to_string()
}

fn slice(dir: &Path, extra: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .current_dir(dir)
        .args([
            "slice",
            &manifest("designs/logo.png"),
            "--config",
            &manifest("../configs/seed-paper-valves.toml"),
            "--out",
            "logo.dlp",
            "--gcode",
            "logo.gcode",
        ])
        .args(extra)
        .args(if extra.contains(&"--width-mm") {
            &[][..]
        } else {
            &["--width-mm", "12"][..]
        })
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn each_dialect_is_written_and_the_default_is_plain_from_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, err) = slice(d, &[]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(g.starts_with("; dollop G-code (plain dialect), sampled from the executor's run"));
    assert!(g.contains("M42 P1 S1") && g.contains("\nG0 ") && !g.contains("M670"));
    let (code, err) = slice(d, &["--gcode-dialect", "reprap", "--gcode-ports", "5,6"]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(
        g.contains("M670 P5:6 T0") && g.contains("M42 P5 S1"),
        "{g:.2000}"
    );
    // Switches while moving ride on the move: bit 1 (inlet 1, port 6).
    assert!(g
        .lines()
        .any(|l| l.starts_with("G1 ") && l.ends_with(" P2")));
    let (code, err) = slice(d, &["--gcode-dialect", "klipper", "--gcode-ports", "3,4"]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(
        g.contains("[output_pin dollop_valve3]")
            && g.contains("SET_PIN PIN=dollop_valve4 VALUE=1\n"),
        "{g:.2000}"
    );
    assert!(!g.contains("M42"));
    let (code, err) = slice(d, &["--gcode-dialect", "marlin", "--gcode-ports", "2,3"]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(
        g.contains("M106 P2 S255\n") && g.contains("M107 P3\n") && !g.contains("M400\nM106"),
        "{g:.2000}"
    );
    assert!(g.contains("LASER_SYNCHRONOUS_M106_M107") && !g.contains("M42"));
    let (code, err) = slice(d, &["--gcode-dialect", "marlin-m42", "--gcode-ports", "40"]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(g.contains("M400\nM42 P40 S255") && g.contains("M42 P1 S255"));
    let (code, err) = slice(d, &["--gcode-style", "coarse"]);
    assert_eq!(code, 0, "{err}");
    let g = std::fs::read_to_string(d.join("logo.gcode")).unwrap();
    assert!(g.contains("coarse (seed paper) style"));
}

#[test]
fn bad_gcode_options_are_refused_in_one_line() {
    for (args, says) in [
        (&["--gcode-ports", "1,x"][..], "--gcode-ports"),
        (&["--gcode-ports", "3,3"][..], "--gcode-ports"),
        (&["--gcode-ports", "1,2,3"][..], "--gcode-ports"),
        // Inlet 1 keeps port 1 by default: taken by inlet 0.
        (&["--gcode-ports", "1"][..], "--gcode-ports"),
        (&["--gcode-ports", "99999"][..], "--gcode-ports"),
        // Marlin has fans P0 to P7.
        (
            &["--gcode-dialect", "marlin", "--gcode-ports", "0,8"][..],
            "P0 to P7",
        ),
        (
            &["--gcode-style", "fine", "--gcode-dialect", "reprap"][..],
            "--gcode-style run",
        ),
        (&["--gcode-dialect", "smoothie"][..], "--gcode-dialect"),
        (&["--gcode-max-mb", "0"][..], "--gcode-max-mb"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (code, err) = slice(dir.path(), args);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(says), "{args:?}: {err}");
        if code == 1 {
            assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        }
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "{args:?} left files"
        );
    }
}

#[test]
fn g_code_over_the_size_limit_is_refused_and_nothing_written() {
    // The bundled cube's G-code is over 1 MiB: refused after the executor's run, naming
    // the option, with neither the job nor the G-code written.
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .current_dir(dir.path())
        .args([
            "slice",
            &manifest("designs/cube-shell.stl"),
            &manifest("designs/cube-ball.stl"),
            "--config",
            &manifest("../configs/seed-paper-valves.toml"),
            "--out",
            "cube.dlp",
            "--gcode",
            "cube.gcode",
            "--gcode-max-mb",
            "1",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("MiB, over the limit of 1.0 MiB (--gcode-max-mb)"),
        "{err}"
    );
    // One line of error; a loaded machine may also print the long run's progress lines
    // (every 5 s on a pipe), which are not errors.
    let errors: Vec<&str> = err
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.contains(" so far"))
        .collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
