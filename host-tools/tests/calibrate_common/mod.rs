//! Helpers shared by the `calibrate_*` tests: seeded noise, temporary CSV files, the
//! `execute` entry point driven by argument lists, and merging a fragment into
//! configs/seed-paper.toml to prove the core accepts it.
#![allow(dead_code)]

use clap::Parser;
use dollop::config::{Config, Machine};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

/// A seeded generator.
pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

/// Standard normal deviate (Box-Muller).
pub fn gauss(rng: &mut StdRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// `n` values spaced evenly in log from `lo` to `hi`.
pub fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (lo.ln() + (hi.ln() - lo.ln()) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

/// Writes `text` to `dir/name`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A CSV with `header` and rows of `(x, y)`.
pub fn csv(dir: &Path, name: &str, header: &str, rows: &[(f64, f64)]) -> PathBuf {
    let mut s = format!("{header}\n");
    for (x, y) in rows {
        s.push_str(&format!("{x},{y}\n"));
    }
    write(dir, name, &s)
}

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The bundled example data folder.
pub fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration")
}

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: dollop_host::cmd::calibrate::Args,
}

/// Runs `dollop calibrate ARGS..` through the command's own code and returns its output.
pub fn run(args: &[&str]) -> Result<String, dollop_host::calibrate::CalError> {
    let cli = Cli::try_parse_from(std::iter::once("calibrate").chain(args.iter().copied()))
        .unwrap_or_else(|e| panic!("arguments {args:?}: {e}"));
    dollop_host::cmd::calibrate::execute(cli.args)
}

/// Applies `fragment` to a copy of configs/seed-paper.toml with `dollop config --apply`
/// (top-level inlet keys into its first `[[inlet]]`, `[[inlet]]` tables into the inlets in
/// order, other tables key by key), checks every comment survived, then parses and
/// validates the result for 4 inlets.
pub fn merge_into_seed(fragment: &str) -> Result<(Config, Machine<f64, 4>), String> {
    merge(fragment, false)
}

/// As [`merge_into_seed`], but top-level inlet keys go into every inlet (the core takes
/// syringe inlets only when all inlets are syringes).
pub fn merge_into_seed_all(fragment: &str) -> Result<(Config, Machine<f64, 4>), String> {
    merge(fragment, true)
}

fn merge(fragment: &str, all_inlets: bool) -> Result<(Config, Machine<f64, 4>), String> {
    // Through the command a user runs: `dollop config --apply FRAGMENT MACHINE --inlet ..`.
    let seed_path = root().join("configs/seed-paper.toml");
    let seed = std::fs::read_to_string(&seed_path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (frag, machine) = (
        write(dir.path(), "fragment.toml", fragment),
        write(dir.path(), "machine.toml", &seed),
    );
    let tables = fragment.lines().filter(|l| l.trim() == "[[inlet]]").count();
    let inlets = match (all_inlets, tables) {
        (true, _) => "0,1".to_string(),
        (false, 0) => "0".to_string(),
        (false, n) => (0..n).map(|i| i.to_string()).collect::<Vec<_>>().join(","),
    };
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dollop"))
        .args(["config", "--apply"])
        .arg(&frag)
        .arg(&machine)
        .args(["--inlet", &inlets])
        .output()
        .unwrap();
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(" -> "), "no change listed: {stdout}");
    let text = std::fs::read_to_string(&machine).unwrap();
    for comment in seed.lines().filter(|l| l.trim_start().starts_with('#')) {
        assert!(text.contains(comment), "comment lost: {comment}");
    }
    let config: Config = toml::from_str(&text).map_err(|e| format!("config: {e}"))?;
    let machine = config
        .validate::<f64, 4>()
        .map_err(|e| format!("validate: {e}"))?;
    Ok((config, machine))
}

/// Relative error.
pub fn rel(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}
