//! Whole jobs in virtual time: what a printed part would show. The executor (f32, as on
//! the chip) drives recording outputs; an independent f64 plant turns its valve commands
//! into flow; boundaries and bead section are measured on the plate.

mod common;
use common::*;
use dollop::RunState;
use dollop_sim::designs::{chessboard, stripes, Fill, Job};
use dollop_sim::RunResult;

/// The bounds the issue sets for every printed part.
fn assert_part(name: &str, cfg_name: &str, r: &RunResult, boundaries_at_least: usize) {
    summary(name, r);
    let cfg = config(cfg_name);
    let m = cfg.validate::<f64, 4>().unwrap();
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
    let section = r.metrics.worst_section();
    assert!(
        section <= 0.01,
        "{name}: bead section off by {:.3} %",
        section * 100.0
    );
    assert!(
        r.worst_step_error <= 1.0,
        "{name}: steps {} microsteps off the plan",
        r.worst_step_error
    );
    let a_max = m.motion.max_accel[0].min(m.motion.max_accel[1]);
    assert!(
        r.peak_accel <= a_max * 1.02,
        "{name}: corner acceleration {:.0} mm/s^2 over the {a_max} limit",
        r.peak_accel
    );
    for (a, &rate) in r.peak_step_rate.iter().enumerate() {
        assert!(
            rate <= 50_000.0,
            "{name}: axis {a} stepped at {rate} steps/s"
        );
    }
}

fn part(cfg_name: &str, j: &Job) -> RunResult {
    run(&config(cfg_name), j)
}

const IDEAL: &str = "seed-paper.toml";
const VALVES: &str = "seed-paper-valves.toml";
const PASTES: &str = "food-pastes.toml";

#[test]
fn stripes_land_within_0_05_mm_with_ideal_valves() {
    let j = job(&fill(15.0, 6, 2), stripes(2.5));
    assert_part("stripes/ideal", IDEAL, &part(IDEAL, &j), 40);
}

#[test]
fn stripes_land_within_0_05_mm_with_10_ms_dead_time_and_30_20_ms_pressure() {
    let j = job(&fill(15.0, 6, 2), stripes(2.5));
    assert_part("stripes/valves", VALVES, &part(VALVES, &j), 40);
}

#[test]
fn chessboard_lands_within_0_05_mm_with_ideal_valves() {
    let j = job(&fill(12.0, 10, 2), chessboard(2.0));
    assert_part("chessboard/ideal", IDEAL, &part(IDEAL, &j), 80);
}

#[test]
fn chessboard_lands_within_0_05_mm_with_10_ms_dead_time_and_30_20_ms_pressure() {
    let j = job(&fill(12.0, 10, 2), chessboard(2.0));
    assert_part("chessboard/valves", VALVES, &part(VALVES, &j), 80);
}

/// Features of 0.6 mm: the channel and filament hold about 2.7 mm of bead, so four or
/// five slugs are in flight at once.
fn short_features() -> Job {
    let f = Fill {
        cell_mm: 0.1,
        ..fill(9.0, 4, 1)
    };
    job(&f, stripes(0.6))
}

#[test]
fn features_shorter_than_the_channel_land_within_0_05_mm() {
    for cfg in [IDEAL, VALVES] {
        let r = part(cfg, &short_features());
        assert!(
            r.max_slugs >= 3,
            "{cfg}: only {} slugs in flight",
            r.max_slugs
        );
        assert_part(
            &format!("short features/{cfg} ({} slugs)", r.max_slugs),
            cfg,
            &r,
            50,
        );
    }
}

#[test]
fn power_law_pastes_meet_the_same_bounds() {
    let cfg = config(PASTES);
    let laws: Vec<f32> = cfg
        .inlets
        .iter()
        .map(|i| match i.rheology {
            dollop::rheology::Rheology::PowerLaw { flow_index, .. } => flow_index,
            _ => 1.0,
        })
        .collect();
    assert_eq!(laws, vec![0.6, 0.45]);
    let j = job(&fill(12.0, 8, 2), chessboard(2.0));
    assert_part("chessboard/power law", PASTES, &part(PASTES, &j), 60);
    let r = part(PASTES, &short_features());
    assert!(r.max_slugs >= 3);
    assert_part("short features/power law", PASTES, &r, 50);
}
