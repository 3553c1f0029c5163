//! The report's `section floor` line: where the bead section over 0.2 mm of straight bead
//! leaves its bound, how near the physics allows there (`dollop_sim::floor`), so that a
//! reader tells a machine too soft for the flow from a controller that could do better.
//! It reruns the job up to the worst stretch (runs are deterministic) and solves two
//! small cone programs; it stops at saying: the bound and the warning are `report`'s.

use dollop::config::Config;
use dollop_sim::floor::{floor, stretch_at, Floor, FloorOptions};
use dollop_sim::{Job, PausePlan, RunOptions, RunResult};

/// Stretch taken either side of the worst window's end, s: the flow's change there and
/// the head's planning for it (the ring's half window at 500 mm/s^2 is 21 ms).
const AROUND_S: f64 = 0.12;

/// The floor around the run's worst straight window, when its section leaves `bound`;
/// None when it holds, or when the floor cannot be had (said in the text).
pub fn section_floor(
    config: &Config,
    job: &Job,
    plan: &PausePlan,
    plant: bool,
    r: &RunResult,
    bound: f64,
) -> Option<String> {
    let m = &r.metrics;
    if m.worst_section_straight() <= bound {
        return None;
    }
    let machine = config.validate::<f64, { crate::slicer::INLETS }>().ok()?;
    let dt = machine.period_us as f64 * 1e-6;
    let around = (AROUND_S / dt) as u64;
    let opts = RunOptions {
        plant,
        ..Default::default()
    };
    if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        // The rerun takes as long as the run did up to there: say so on a terminal.
        eprintln!(
            "dollop: finding the section floor (rerunning the job to {:.1} s of {:.1} s)",
            m.section_straight_worst_cycle as f64 * dt,
            r.time_s
        );
    }
    let stretch = match stretch_at(
        config,
        job,
        &opts,
        plan,
        m.section_straight_worst_cycle,
        around,
        around,
    ) {
        Ok(s) => s,
        Err(e) => return Some(format!("section floor     not found: {e}\n")),
    };
    let accel = config.motion.max_accel_mm_s2[0].min(config.motion.max_accel_mm_s2[1]) as f64;
    let o = FloorOptions {
        accel,
        ..Default::default()
    };
    Some(match floor(&stretch, &o) {
        Ok(f) => text(&f, accel, bound),
        Err(e) => format!("section floor     not found: {e}\n"),
    })
}

/// The line, and its reading against the section's `bound`.
fn text(f: &Floor, accel: f64, bound: f64) -> String {
    let pc = |x: f64| format!("{:.2} %", x * 100.0);
    let opt = |x: Option<f64>| x.map_or("none".to_string(), pc);
    let mut s = format!(
        "section floor     there the head's lead on the paste spreads {} over 0.2 mm of straight bead ({} with turns); no head along this path within {accel} mm/s^2, its lead no larger ({:.4} mm), does better than {} ({} with turns)\n",
        pc(f.executor_straight),
        pc(f.executor_all),
        f.executor_lag_mm,
        opt(f.straight),
        opt(f.all),
    );
    let allows = format!(
        "the machine allows {} there: the controller's plan, not the machine, leaves it off",
        pc(bound)
    );
    let reading = match f.straight {
        Some(fl) if fl <= bound => allows.as_str(),
        Some(_) => "the machine allows no better than that there: a stiffer X/Y, a slower flow change or a wider turn would",
        None => "no head within the limit meets the run's own turns and lag there",
    };
    s.push_str(&format!("                  ({reading})\n"));
    s
}
