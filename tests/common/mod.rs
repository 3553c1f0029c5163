//! Shared helpers for whole-job tests: config loading, standard fills, result printing.
#![allow(dead_code)]

use dollop::config::Config;
use dollop_sim::designs::{boustrophedon, Fill, Job};
use dollop_sim::{RunOptions, RunResult};

pub fn config(name: &str) -> Config {
    let path = format!("{}/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// A fill of `rows` rows, `width` mm wide, with 0.8 mm pitch, boundaries on a 0.1 mm grid.
pub fn fill(width: f64, rows: usize, layers: usize) -> Fill {
    Fill {
        origin_mm: [20.0, 20.0],
        width_mm: width,
        rows,
        pitch_mm: 0.8,
        layers,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 12.0,
    }
}

pub fn job(f: &Fill, m: impl Fn(f64, f64, usize) -> u8) -> Job {
    boustrophedon(f, m)
}

pub fn run(cfg: &Config, job: &Job) -> RunResult {
    dollop_sim::run::<f32>(cfg, job, &RunOptions::default(), |_| {}).unwrap()
}

pub fn summary(name: &str, r: &RunResult) {
    let m = &r.metrics;
    eprintln!(
        "{name}: {:?} {:?} after {:.2} s, {} boundaries, worst {:.4} mm, section {:.5}..{:.5} over {} cycles (worst at {:?}), off-path {:.4} mm3, slivers {}, switches {}, peak accel {:.0} mm/s2, step error {:.3}",
        r.state,
        r.fault,
        r.time_s,
        m.boundaries.len(),
        m.worst_boundary(),
        m.section_range.0,
        m.section_range.1,
        m.section_cycles,
        m.section_worst_at,
        m.off_path_volume,
        m.slivers,
        r.switches,
        r.peak_accel,
        r.worst_step_error,
    );
    for mm in m.mismatches.iter().take(5) {
        eprintln!("  mismatch: {mm}");
    }
    let mut worst: Vec<_> = m.boundaries.iter().collect();
    worst.sort_by(|a, b| b.error().abs().total_cmp(&a.error().abs()));
    for b in worst.iter().take(5) {
        eprintln!(
            "  boundary at {:?} -> {}: error {:+.4} mm",
            b.point,
            b.material,
            b.error()
        );
    }
}
