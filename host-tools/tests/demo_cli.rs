//! `dollop demo` end to end: it writes every file it lists into its folder, and a folder
//! where one of them cannot be written (a directory in the way) gets none of them.

use std::path::Path;
use std::process::Command;

fn demo(out_dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dollop"))
        .args(["demo", "--out-dir"])
        .arg(out_dir)
        .output()
        .unwrap()
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn the_demo_writes_its_files_together() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("demo");
    let out = demo(&dir);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("boundaries") && text.contains("worst"),
        "{text}"
    );
    assert_eq!(
        files(&dir),
        [
            "logo-plate.png",
            "logo-toolpath.png",
            "logo.dlp",
            "logo.gcode",
            "logo.png",
            "machine.toml"
        ]
    );
    // The copies are the bundled inputs, and the job reads back.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    assert_eq!(
        std::fs::read(dir.join("logo.png")).unwrap(),
        std::fs::read(root.join("designs/logo.png")).unwrap()
    );
    dollop_host::slicer::job_file::read_job(&dir.join("logo.dlp")).unwrap();
}

#[test]
fn a_folder_where_one_output_cannot_go_gets_none() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("demo");
    std::fs::create_dir_all(dir.join("logo.gcode")).unwrap();
    let out = demo(&dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "the demo wrote over a directory");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("logo.gcode"), "{err}");
    assert_eq!(files(&dir), ["logo.gcode"], "the demo left files behind");
}
