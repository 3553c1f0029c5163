//! Shared helpers for whole-job tests: config loading, standard fills, result printing.
#![allow(dead_code)]

use dollop::config::Config;
use dollop::RunState;
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

/// The run ended Done with every material where the design has it: at least
/// `boundaries_at_least` boundaries measured, each within 0.05 mm of the design. Returns
/// the worst boundary offset, mm.
pub fn assert_landed(name: &str, r: &RunResult, boundaries_at_least: usize) -> f64 {
    assert_eq!(
        r.state,
        RunState::Done,
        "{name}: ended in {:?} {:?}",
        r.state,
        r.fault
    );
    assert!(
        r.metrics.mismatches.is_empty(),
        "{name}: {:?}",
        r.metrics.mismatches
    );
    assert!(
        r.metrics.boundaries.len() >= boundaries_at_least,
        "{name}: only {} boundaries measured",
        r.metrics.boundaries.len()
    );
    let worst = r.metrics.worst_boundary();
    assert!(worst <= 0.05, "{name}: a boundary landed {worst:.4} mm off");
    worst
}

/// Each of X and Y at most `slack` times its acceleration limit (1 ms central differences
/// of the commanded position while a valve is open, and over the whole run less the f32
/// position's rounding: travels and the bead starts and ends that meet them).
pub fn assert_axes_within(
    name: &str,
    m: &dollop::config::Machine<f64, 4>,
    r: &RunResult,
    slack: f64,
) {
    for (a, axis) in ["X", "Y"].iter().enumerate() {
        let limit = m.motion.max_accel[a];
        assert!(
            r.axis_accel[a] <= limit * slack,
            "{name}: {axis} at {:.0} mm/s^2 (at {:.4} s) over the {limit} limit",
            r.axis_accel[a],
            r.axis_accel_at[a]
        );
        // Travels brake at the whole limit: their differences carry the ring's 0.1 um
        // unit as well (502 mm/s^2 on a 500 machine's chessboard).
        assert!(
            r.axis_accel_moving[a] <= limit * slack.max(1.02),
            "{name}: {axis} at {:.0} mm/s^2 (at {:.4} s, the whole run) over the {limit} limit",
            r.axis_accel_moving[a],
            r.axis_accel_moving_at[a]
        );
    }
}

pub fn run(cfg: &Config, job: &Job) -> RunResult {
    dollop_sim::run::<f32>(cfg, job, &RunOptions::default(), |_| {}).unwrap()
}

pub fn summary(name: &str, r: &RunResult) {
    let m = &r.metrics;
    eprintln!(
        "{name}: {:?} {:?} after {:.2} s, {} boundaries, worst {:.4} mm, section {:.5}..{:.5} over {} cycles (worst at {:?}), off-path {:.4} mm3, slivers {}, switches {}, peak accel {:.0} mm/s2, step error {:.3}; over 0.2 mm: section {:.4}..{:.4} (worst at {:?}), away from turns {:.4}..{:.4} (at {:?}); axis accel (1 ms, valve open) X {:.0} Y {:.0} mm/s2 (at {:.4} s, {:.4} s)",
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
        m.section_long_range.0,
        m.section_long_range.1,
        m.section_long_worst_at,
        m.section_straight_range.0,
        m.section_straight_range.1,
        m.section_straight_worst_at,
        r.axis_accel[0],
        r.axis_accel[1],
        r.axis_accel_at[0],
        r.axis_accel_at[1],
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

/// What a speed ramp through the machine's worst flow step may cost the section over
/// 0.2 mm of bead: 2 %, or where the acceleration limit forces more, the centred ramp's
/// `step^2 / (8 a)` over 0.2 mm plus a quarter for the ramp's rounding to whole cycles
/// and corners met mid-ramp.
pub fn section_bound(m: &dollop::config::Machine<f64, 4>) -> f64 {
    let a = m.motion.max_accel[0].min(m.motion.max_accel[1]) * dollop::config::RAMP_SHARE;
    let step = m.flow_step;
    let cost = step * step / (8.0 * a) / dollop::config::SECTION_WINDOW_MM;
    (cost * 1.25).max(0.02)
}

/// Issue 23's seam bounds for a mid-bead pause: measured, no uncovered stretch over
/// 0.1 mm, and the section over 0.2 mm at the seam within 1.3 S.
pub fn assert_seam(what: &str, p: &dollop_sim::PauseRecord) {
    assert!(p.seam_measured, "{what}: seam not measured");
    assert!(
        p.seam_gap_mm <= 0.1,
        "{what}: seam gap {:.3} mm",
        p.seam_gap_mm
    );
    assert!(
        p.seam_section.1 <= 1.3,
        "{what}: seam section {:.3} S",
        p.seam_section.1
    );
}
