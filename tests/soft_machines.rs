//! Whole jobs on soft machines (X/Y limited to 500 and 1 000 mm/s^2, issue 22): the
//! seed printhead with real valves (10 ms dead time, 30/20 ms pressure rise/decay) and
//! with instantaneous ones. Each run asserts the bead section over every 0.2 mm of bead
//! against the machine's bound (`Machine::section_bound`: 1 %, or what a ramp through a
//! step of the flow forces) and each axis's peak acceleration from 1 ms central
//! differences of the commanded head position while a valve is open. The stiffer
//! machines of `whole_jobs.rs` never showed the regression these pin down.

mod common;
use common::*;
use dollop::config::Config;
use dollop::RunState;
use dollop_sim::designs::{chessboard, stripes, Fill};
use dollop_sim::RunResult;

/// Slack on the acceleration limit for the measurement (f32 positions differenced over
/// 1 ms), as `whole_jobs.rs` allows.
const ACCEL_SLACK: f64 = 1.02;

/// The machine (the seed printhead, nozzle at layer height, real valves) at X/Y
/// limit `a`, its valves made instantaneous if `instant`.
fn soft(a: f32, instant: bool) -> Config {
    let mut c = config("soft-real-valves.toml");
    c.motion.max_accel_mm_s2[0] = a;
    c.motion.max_accel_mm_s2[1] = a;
    if instant {
        for i in c.inlets.iter_mut() {
            i.valve_open_delay_ms = 0.0;
            i.valve_close_delay_ms = 0.0;
            i.pressure_rise_ms = 0.0;
            i.pressure_decay_ms = 0.0;
        }
    }
    c
}

/// The machine at 500 mm/s^2 with the food pastes' shear-thinning laws (mashed
/// potato n 0.6, chocolate n 0.45, `auto` pressure): the bundled
/// `configs/soft-food-pastes.toml`, the one `docs/soft-machines.md` measures.
fn soft_food_pastes() -> Config {
    config("soft-food-pastes.toml")
}

/// Checks a run against the machine's bounds; returns (section off over 0.2 mm, its
/// bound, X and Y peak acceleration).
fn assert_soft(name: &str, cfg: &Config, r: &RunResult) -> (f64, f64, f64, f64) {
    summary(name, r);
    let m = cfg.validate::<f64, 4>().unwrap();
    assert_landed(name, r, 40);
    let section = r.metrics.worst_section_long();
    let bound = m.section_bound();
    eprintln!(
        "{name}: ramp window {} cycles, section off {:.3} % over 0.2 mm (bound {:.3} %), X {:.0} Y {:.0} mm/s^2",
        m.ramp_cycles,
        section * 100.0,
        bound * 100.0,
        r.axis_accel[0],
        r.axis_accel[1]
    );
    assert!(
        section <= bound,
        "{name}: section off by {:.3} % over 0.2 mm (bound {:.3} %)",
        section * 100.0,
        bound * 100.0
    );
    assert_axes_within(name, &m, r, ACCEL_SLACK);
    (section, bound, r.axis_accel[0], r.axis_accel[1])
}

/// 4 mm squares (the chessboard PNG's at the default pitch, as sliced): every square is
/// longer than the 2.5 mm of bead the channel holds.
fn board() -> dollop_sim::Job {
    job(&fill(24.0, 16, 1), chessboard(4.0))
}

/// Each valve decision's flow change goes to the follower (`dollop::flow_follow`), and
/// its ramp window is sized for the turns ahead and the plan's rounding only
/// (`dollop::switch_window`): never under what keeps two thirds of a velocity step too
/// small for `dollop::step_ramps` within the limit (57 cycles at 500 mm/s^2, 29 at
/// 1 000). At 500 the machine's one window (415 cycles) smeared every change, 18.9 % off
/// over 0.2 mm; a box window sized for each change (one paste in the channel), 0.959 %.
/// Measured now (section off over 0.2 mm, X / Y peak while a valve is open): 500:
/// 0.271 %, 507 / 259 mm/s^2 (X 496 less the f32 position's rounding: the
/// follower's speed changes by 0.99 of the limit on a straight, and its placing adds to
/// that); 1 000: 0.121 %, 519 / 492; 2 000: 0.030 %, 824 / 988. Each is pinned a little
/// above what it measured; the axes within their limit with no slack at 1 000 and 2 000,
/// and at 500 within the slack the food pastes' follower takes too, and within the limit
/// itself less the rounding (the held-out check allows 1.1 times).
#[test]
fn real_valves_hold_the_section_and_the_limit_on_soft_machines() {
    for (a, within, slack) in [
        (500.0f32, 0.0035, ACCEL_SLACK),
        (1000.0, 0.0016, 1.0),
        (2000.0, 0.0006, 1.0),
    ] {
        let cfg = soft(a, false);
        let name = format!("chessboard/real valves {a}");
        let r = run(&cfg, &board());
        let (section, bound, _, _) = assert_soft(&name, &cfg, &r);
        eprintln!(
            "{name}: X {:.0} Y {:.0} mm/s^2 less the f32 position's rounding",
            r.axis_accel_open_net[0], r.axis_accel_open_net[1]
        );
        // Real valves ramp the flow themselves: no step forces more than 1 %.
        assert_eq!(bound, dollop::config::SECTION_BAND, "{a}");
        assert!(section <= within, "{a}: {section}");
        assert_axes_within(&name, &cfg.validate::<f64, 4>().unwrap(), &r, slack);
        for (axis, net) in ["X", "Y"].iter().zip(r.axis_accel_open_net) {
            assert!(
                net <= a as f64,
                "{name}: {axis} {net:.0} mm/s^2 less the rounding"
            );
        }
    }
}

/// Known limit at 500 mm/s^2: features shorter than the channel (0.6 mm stripes) switch
/// with several pastes in it, whose moving boundaries change the flow on top of what the
/// valves do. The head follows the flow within the limit (`dollop::flow_follow`), near the
/// row ends' tight turns too: it plans by the mean's own path ahead (how fast the mean
/// goes there, and what its turn leaves for the speed to change by) and a head lagging
/// the mean stays on the mean's path (`dollop::follow_trail`). The axes keep their limit;
/// the section keeps 1 % away from turns but for a tenth of a point, and not through the
/// row ends' turns: measured 1.07 % off over 0.2 mm away from turns and 13.4 % through
/// them, X 502 Y 463 mm/s^2 (X within 500 less the f32 position's rounding; 484 with the
/// follower's straights at 0.95 of the limit), worst boundary 0.008 mm. Before a bead's
/// start put off widening its window for the turns far ahead (`dollop::switch_window`'s
/// `Sizing::defer`), the first bead's start was 4.7 % off (the head led the paste by half
/// the machine's window) and the worst boundary 0.011 mm. With the follower barred near
/// the turns and a window sized from the contents there: 9.0 and 21.8 %, X 481 Y 305,
/// 0.020 mm. This measures the limit.
#[test]
fn real_valves_at_500_keep_the_limit_and_the_known_section_cost_on_short_features() {
    let cfg = soft(500.0, false);
    let f = Fill {
        cell_mm: 0.1,
        ..fill(9.0, 4, 1)
    };
    let j = job(&f, stripes(0.6));
    let r = run_to_the_end("short features/real valves 500", &cfg, &j);
    assert!(r.metrics.worst_boundary() <= 0.02);
    // The head itself within the limit (the differences less what the f32 position's
    // rounding can put in them); the raw differences within the measurement's slack.
    for a in 0..2 {
        assert!(
            r.axis_accel_open_net[a] <= 500.0,
            "axis {a}: {} at {} s",
            r.axis_accel_open_net[a],
            r.axis_accel_open_net_at[a]
        );
        assert!(r.axis_accel[a] <= 500.0 * ACCEL_SLACK, "axis {a}");
    }
    let section = r.metrics.worst_section_long();
    assert!(
        section <= 0.15,
        "section off by {:.2} % over 0.2 mm",
        section * 100.0
    );
    let straight = r.metrics.worst_section_straight();
    assert!(
        straight <= 0.015,
        "section off by {:.2} % over 0.2 mm away from turns",
        straight * 100.0
    );
    let bl = r.metrics.section_band(true);
    eprintln!(
        "short features/real valves 500: band p99 - p1 {:.4} over 0.2 mm",
        bl.1 - bl.0
    );
    // The rows are 9 mm, so their ends' turns are more than a percent of the windows: the
    // band holds them (measured 0.104; 0.198 with the follower barred near them), five
    // times the goal; the random cells' is within it.
    assert!(bl.1 - bl.0 <= 0.12, "band over 0.2 mm {bl:?}");
}

/// The goal for the band (p99 - p1 of the section over 0.2 mm).
const BAND_500: f64 = 0.02;

#[test]
fn instantaneous_valves_hold_the_section_bound_and_the_limit_on_soft_machines() {
    for a in [500.0f32, 1000.0] {
        let cfg = soft(a, true);
        assert_soft(
            &format!("chessboard/instant {a}"),
            &cfg,
            &run(&cfg, &board()),
        );
    }
}

/// The closed form of `Machine::section_bound` for the steps a bead meets between its
/// ends: a window `w` centred on a step of `dv` lays the section off by `dv w / (8 W)`
/// over `W` = 0.2 mm, `dv^2 / (8 a W)` with the window sized to the step. The
/// chessboard's and the stripes' mid-bead steps are paste B's supply through a channel
/// full of paste A against paste A's (22.48 - 10 mm/s), each ramped over its own window
/// (29 cycles; the machine's, for the 22.48 mm/s bead starts, is 49). A bead's ends keep
/// the machine's window, so the worst over 0.2 mm is now there, `10 w / (8 W)` at the
/// 10 mm/s print speed: each design's measured section is within 10 % of the larger.
#[test]
fn instantaneous_valves_at_5000_meet_the_closed_form() {
    let cfg = soft(5000.0, true);
    let m = cfg.validate::<f64, 4>().unwrap();
    let dt = m.period_us as f64 * 1e-6;
    let dv = m.v_flow_max - cfg.motion.print_speed_mm_s as f64;
    // The step's own window (`dollop::step_ramps`): the odd number of cycles that takes
    // `dv` within the ramps' share of the limit.
    let a = dollop::executor::step_ramp_accel(&m) as f64;
    let w = ((dv / (a * dt)).ceil() as u32 / 2 * 2 + 1) as f64 * dt;
    assert!(w < m.ramp_cycles as f64 * dt, "{w} s");
    let switch = dv * w / (8.0 * dollop::config::SECTION_WINDOW_MM);
    // A bead's ends (from or to rest at the print speed) keep the machine's window
    // (`dollop::step_ramps`), and the 0.2 mm windows next to them count.
    let ends = cfg.motion.print_speed_mm_s as f64 * m.ramp_cycles as f64 * dt
        / (8.0 * dollop::config::SECTION_WINDOW_MM);
    let closed = switch.max(ends);
    let designs = [
        ("chessboard", board()),
        ("stripes", job(&fill(24.0, 16, 1), stripes(4.0))),
        ("short features", {
            let f = Fill {
                cell_mm: 0.1,
                ..fill(9.0, 4, 1)
            };
            job(&f, stripes(0.6))
        }),
    ];
    for (name, j) in designs {
        let r = run(&cfg, &j);
        let name = format!("{name}/instant 5000");
        let (section, bound, _, _) = assert_soft(&name, &cfg, &r);
        eprintln!(
            "{name}: closed form {:.3} % ({:.3} % for {dv:.2} mm/s in {:.1} ms, {:.3} % at the ends); measured {:.3} %; bound {:.3} %",
            closed * 100.0,
            switch * 100.0,
            w * 1e3,
            ends * 100.0,
            section * 100.0,
            bound * 100.0
        );
        // Features shorter than the channel switch with a mix in it, so their switch steps
        // are smaller than a channel full of one paste gives; their worst is at the bead
        // ends (measured 3.23 % against 3.06 %), held to within 10 % of it, not from below.
        let low = if name.starts_with("short") { 0.0 } else { 0.9 };
        let (b, bl) = (r.metrics.section_band(false), r.metrics.section_band(true));
        eprintln!(
            "{name}: band p99 - p1 {:.4} over 0.02 mm, {:.4} over 0.2 mm",
            b.1 - b.0,
            bl.1 - bl.0
        );
        // The goals in its own measure: the chessboard under 0.01 (measured
        // 0.0023 over 0.02 mm on the board, 0.0021 on the stripes), the fine features
        // under 0.02 (0.0082 over 0.2 mm; 0.059 over 0.02 mm, where each switch's ramp
        // covers a fifth of a 0.6 mm stripe's windows; 0.31 and 0.032 when every step
        // ramped over the bead starts' window).
        if name.starts_with("short") {
            assert!(bl.1 - bl.0 < 0.02, "{name}: band over 0.2 mm {:?}", bl);
        } else {
            assert!(b.1 - b.0 < 0.01, "{name}: band {:?}", b);
        }
        assert!(
            section >= low * closed && section <= 1.1 * closed,
            "{name}: measured {section} against the closed form {closed}"
        );
    }
}

/// How near the physics allows where the run's section over 0.2 mm of straight bead is
/// worst (`dollop_sim::floor`, as `dollop simulate --report` says): printed, and never
/// nearer than the run that measured it came (a floor that beats a run within the limit
/// is a wrong floor).
fn assert_floor_below(name: &str, cfg: &Config, job: &dollop_sim::Job, r: &RunResult) {
    let at = r.metrics.section_straight_worst_cycle;
    let stretch = dollop_sim::floor::stretch_at(
        cfg,
        job,
        &dollop_sim::RunOptions::default(),
        &dollop_sim::PausePlan::default(),
        at,
        1200,
        1200,
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    let o = dollop_sim::floor::FloorOptions {
        accel: cfg.motion.max_accel_mm_s2[0].min(cfg.motion.max_accel_mm_s2[1]) as f64,
        ..Default::default()
    };
    let f = dollop_sim::floor::floor(&stretch, &o).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: at cycle {at}, {f:?}");
    let (straight, all) = (
        f.straight
            .unwrap_or_else(|| panic!("{name}: no straight floor {f:?}")),
        f.all.unwrap_or_else(|| panic!("{name}: no floor {f:?}")),
    );
    assert!(
        straight <= f.executor_straight + 1e-4 && all <= f.executor_all + 1e-4,
        "{name}: the floor beats the run: {f:?}"
    );
}

/// Runs `job` on `cfg` to its end (every boundary where the design put a material,
/// the floor no better than the run at its worst straight window), summarised.
fn run_to_the_end(name: &str, cfg: &Config, job: &dollop_sim::Job) -> RunResult {
    let r = run(cfg, job);
    summary(name, &r);
    assert_floor_below(name, cfg, job, &r);
    assert_eq!(r.state, RunState::Done, "{:?}", r.fault);
    assert!(
        r.metrics.mismatches.is_empty(),
        "{:?}",
        r.metrics.mismatches
    );
    r
}

/// Paste A or B for the 0.8 mm cell holding (`x`, `y`) mm, from a fixed hash.
fn random_cell(x: f64, y: f64, _: usize) -> u8 {
    let (i, j) = ((x / 0.8).floor() as i64, (y / 0.8).floor() as i64);
    let h = (i.wrapping_mul(73_856_093) ^ j.wrapping_mul(19_349_663)) as u64;
    (h.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 63) as u8
}

/// Random 0.8 mm cells (a 48 px random pattern's pixels at the default pitch), each cell
/// paste A or B from a fixed hash: features shorter than the channel, so decisions find
/// one paste in the channel now and then and several the next time, each sizing its own
/// window, and the window changes while the head turns at a row's end. Each
/// frame of width moved the mean of the turning path, a velocity step of `x'' h dt / 3`
/// where a change started and stopped (the random pattern PNG at 500 mm/s^2: 2 090 /
/// 1 999 mm/s^2); `dollop::width_blend` takes those moves into an offset that returns
/// within a share of the path's own acceleration; the head slows round the row ends'
/// U-turns where the flow brings it faster than their fillets allow (`dollop::turn_slow`).
/// Measured: X 484 / Y 471 mm/s^2 (488 / 504 without slowing, 540 / 1 102 without the
/// blend either), section 4.0 % off over 0.2 mm (2.7 % away from turns), band 0.0187,
/// worst boundary 0.006 mm: the first bead's first two boundaries are still in the channel
/// when the priming line stops, 3.5 ms after a switch, and landed 0.050 and 0.113 mm late
/// while the stop's tail, predicted once since the switch, took no account of the flow
/// the switch had already committed (`Tracker::reset_committed`). With the flow's follower barred near the row ends' turns and
/// windows sized from the contents there: 8.6 % (the worst 0.7 mm past a row end's
/// turn), band 0.0184; with the machine's window 22.2 %.
#[test]
fn real_valves_at_500_keep_width_changes_smooth_on_random_cells() {
    let cfg = soft(500.0, false);
    let cells = job(&fill(16.0, 12, 1), random_cell);
    let r = run_to_the_end("random cells/real valves 500", &cfg, &cells);
    // Without the blend: X 540, Y 1 102 mm/s^2. Y met a row end's turn at 14.2 mm/s at
    // 504 mm/s^2 before the head slowed round it (471 now); the slack is the
    // measurement's.
    let m = cfg.validate::<f64, 4>().unwrap();
    assert_axes_within("random cells/real valves 500", &m, &r, ACCEL_SLACK);
    let section = r.metrics.worst_section_long();
    assert!(
        section <= 0.05,
        "section off by {:.2} % over 0.2 mm",
        section * 100.0
    );
    let bl = r.metrics.section_band(true);
    eprintln!(
        "random cells/real valves 500: band p99 - p1 {:.4} over 0.2 mm",
        bl.1 - bl.0
    );
    assert!(bl.1 - bl.0 <= BAND_500, "band over 0.2 mm {bl:?}");
    // The goal is 0.10 mm (0.06 at p95).
    assert!(
        r.metrics.worst_boundary() <= 0.02,
        "{}",
        r.metrics.worst_boundary()
    );
}

/// The soft machine with the food pastes' shear-thinning laws (mashed potato K 60 n 0.6,
/// chocolate ganache K 120 n 0.45, supplies for 10 mm/s) and real valves at 500 mm/s^2,
/// on the 4 mm board. Chocolate draining into potato drops the head from 10 to 1.5 mm/s,
/// at first `v / (n tau)` = 1 111 mm/s^2: taken at its line's own rate (500), the config
/// asked for a 4.7 ms window, and the head, riding the flow, braked at 839 mm/s^2 on X
/// here (862 on the chessboard PNG). The window now counts the paste's own fall
/// (`config::flow`'s `Decay`), the follower takes every change of such pastes
/// (`switch_window`), and the ring holds the whole drop ahead of it. Measured now: X 507,
/// Y 259 mm/s^2 while a valve is open; band p99 - p1 over 0.2 mm 0.0138, within the
/// issue's 0.02; 2.32 % off over 0.2 mm of straight bead, where the floor allows 1.76 %
/// in its measure (when first measured: X 504, 494 less the f32 position's rounding, Y
/// 254; 0.0169; 2.39 % and 1.75 %): the follower's aim eases into the fall and out of
/// it where the best head runs ahead first and undershoots the flow at the bottom. Worst
/// boundary 0.0035 mm. With the follower's speed changing by 0.95 of the limit on a
/// straight (the margin its turns take): X 484, band 0.0209, 2.78 %. With the machine's
/// window instead of the follower: band 0.066 on the chessboard PNG.
#[test]
fn shear_thinning_pastes_with_real_valves_keep_the_limit_on_a_soft_machine() {
    let cfg = soft_food_pastes();
    let name = "chessboard/shear-thinning pastes, real valves 500";
    let r = run_to_the_end(name, &cfg, &board());
    let m = cfg.validate::<f64, 4>().unwrap();
    assert_axes_within(name, &m, &r, ACCEL_SLACK);
    let bl = r.metrics.section_band(true);
    eprintln!(
        "{name}: band p99 - p1 {:.4} over 0.2 mm, {:.2} % off over 0.2 mm of straight bead",
        bl.1 - bl.0,
        r.metrics.worst_section_straight() * 100.0
    );
    assert!(bl.1 - bl.0 <= BAND_500, "{name}: band over 0.2 mm {bl:?}");
    assert!(r.metrics.worst_section_straight() <= 0.026);
    assert!(
        r.metrics.worst_boundary() <= 0.02,
        "{}",
        r.metrics.worst_boundary()
    );
}

/// A shear-thinning paste's bead with tight U-turns and no change of paste: rows 0.44 mm
/// apart (fillets of 0.22 mm at each row end, 455 mm/s^2 at the print speed of 10 mm/s,
/// within the ramps' share of 500), one paste at a steady flow. The decision at the bead's
/// start sizes the turns ahead at the paste's flushed speed (`Inlet::flushed_mm_s`), and
/// the window stays the least a decision takes: every 0.2 mm within 0.9943 .. 1.0087
/// (0.87 % off), X 460 / Y 444 mm/s^2. Sized at the fastest flow (10.63 mm/s:
/// 514 mm/s^2), the window was 45 ms and its box mean cut every U-turn with the flow
/// steady: 0.9943 .. 1.1973 through the turns, 4.24 % off over 0.2 mm of straight bead
/// out of one.
#[test]
fn a_shear_thinning_bead_keeps_its_section_through_tight_u_turns() {
    let cfg = soft_food_pastes();
    let f = dollop_sim::designs::Fill {
        pitch_mm: 0.44,
        ..fill(6.0, 12, 1)
    };
    let name = "tight U-turns/shear-thinning paste, real valves 500";
    let r = run_to_the_end(name, &cfg, &job(&f, |_, _, _| 0));
    let m = cfg.validate::<f64, 4>().unwrap();
    assert_axes_within(name, &m, &r, ACCEL_SLACK);
    let (lo, hi) = r.metrics.section_long_range;
    eprintln!(
        "{name}: section {lo:.4} .. {hi:.4} over 0.2 mm, {:.2} % off over 0.2 mm of straight bead, X {:.0} Y {:.0}",
        r.metrics.worst_section_straight() * 100.0,
        r.axis_accel[0],
        r.axis_accel[1]
    );
    assert!(lo >= 0.99 && hi <= 1.01, "{name}: section {lo} .. {hi}");
    assert!(r.metrics.worst_section_straight() <= 0.01);
}

/// Real valves whose beads run past the row-end U-turns' share of the limit: both
/// pressures doubled at 1 000 mm/s^2, so the beads run 20 mm/s round the rows' 0.4 mm
/// U-turns, the whole limit (`dollop config --check` and `dollop slice` say so: past
/// 60 % the section swells at the row ends and the axes may leave their limit). On the
/// random cells the job runs to its end and the head stays on its path. Before, the
/// flow's follower, with the mean's window as wide as the ring, ran the head under the
/// flow until the lag outgrew the trail it is placed on, and the head left the path:
/// 60 493 mm/s^2, a boundary 44 mm off here; on the 48 px random pattern a fault ("X
/// needed 6 steps in one cycle"). Measured now: X 1 362 / Y 895 mm/s^2 while a valve is
/// open, worst boundary 0.113 mm, 28.6 % off over 0.2 mm of straight bead. Pinned with a
/// little room: the section and the limit are not held past the share.
#[test]
fn real_valves_past_the_u_turns_share_stay_on_the_path() {
    let mut cfg = soft(1000.0, false);
    for i in cfg.inlets.iter_mut() {
        if let dollop::config::Pressure::Kpa(k) = i.pressure_kpa {
            i.pressure_kpa = dollop::config::Pressure::Kpa(2.0 * k);
        }
    }
    let name = "random cells/real valves at twice the pressure, 1 000";
    let r = run_to_the_end(name, &cfg, &job(&fill(16.0, 12, 1), random_cell));
    eprintln!(
        "{name}: X {:.0} Y {:.0} mm/s^2, {:.2} % off over 0.2 mm of straight bead",
        r.axis_accel[0],
        r.axis_accel[1],
        r.metrics.worst_section_straight() * 100.0
    );
    // 1.5 times the limit, on the raw differences.
    let m = cfg.validate::<f64, 4>().unwrap();
    assert_axes_within(name, &m, &r, 1.5);
    assert!(
        r.metrics.worst_boundary() <= 0.15,
        "{}",
        r.metrics.worst_boundary()
    );
}
