//! Helpers shared by the tests that run the `dollop` command: run it in a folder, and name
//! a file of the host-tools package.
#![allow(dead_code)]

use std::path::Path;
use std::process::Command;

/// Runs `dollop ARGS..` in `dir`: (exit code, stdout, stderr).
pub fn dollop(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// `p` under the host-tools package, as a string argument.
pub fn manifest(p: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(p)
        .to_str()
        .unwrap()
        .to_string()
}
