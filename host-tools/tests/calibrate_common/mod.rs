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

/// Merges `fragment` into configs/seed-paper.toml (top-level inlet keys into its first
/// `[[inlet]]`, `[[inlet]]` tables into the inlets in order, other tables key by key),
/// then parses and validates the result for 4 inlets.
pub fn merge_into_seed(fragment: &str) -> Result<(Config, Machine<f64, 4>), String> {
    merge(fragment, false)
}

/// As [`merge_into_seed`], but top-level inlet keys go into every inlet (the core takes
/// syringe inlets only when all inlets are syringes).
pub fn merge_into_seed_all(fragment: &str) -> Result<(Config, Machine<f64, 4>), String> {
    merge(fragment, true)
}

fn merge(fragment: &str, all_inlets: bool) -> Result<(Config, Machine<f64, 4>), String> {
    let seed = std::fs::read_to_string(root().join("configs/seed-paper.toml")).unwrap();
    let mut config: toml::Table = toml::from_str(&seed).unwrap();
    let frag: toml::Table = toml::from_str(fragment).map_err(|e| format!("fragment: {e}"))?;
    for (key, value) in frag {
        match (key.as_str(), value) {
            ("inlet", toml::Value::Array(items)) => {
                let inlets = config["inlet"].as_array_mut().unwrap();
                for (i, item) in items.into_iter().enumerate() {
                    let target = inlets[i].as_table_mut().unwrap();
                    for (k, v) in item.as_table().unwrap() {
                        target.insert(k.clone(), v.clone());
                    }
                }
            }
            ("channel" | "motion" | "control", toml::Value::Table(t)) => {
                let target = config[key.as_str()].as_table_mut().unwrap();
                for (k, v) in t {
                    target.insert(k, v);
                }
            }
            (_, v) => {
                let inlets = config["inlet"].as_array_mut().unwrap();
                let n = if all_inlets { inlets.len() } else { 1 };
                for inlet in &mut inlets[..n] {
                    inlet.as_table_mut().unwrap().insert(key.clone(), v.clone());
                }
            }
        }
    }
    let config: Config = toml::Value::Table(config)
        .try_into()
        .map_err(|e| format!("config: {e}"))?;
    let machine = config
        .validate::<f64, 4>()
        .map_err(|e| format!("validate: {e}"))?;
    Ok((config, machine))
}

/// Relative error.
pub fn rel(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}
