//! Parked pauses, whole jobs in virtual time against the reference plant: each pause
//! lifts Z and moves to the park position once the head rests, and resume comes back,
//! lowers and restarts the flow. The part is held to the unpaused bounds (every boundary
//! within 0.05 mm, materials as designed), each seam to the mid-bead pause's (gap
//! <= 0.1 mm, section over 0.2 mm within 1.3 S), and the step outputs (what the motors
//! did) must show the lift, the park position and the way back. On the syringe machine
//! each park also refills: the plungers retract to where their fill began and count
//! from there, and no boundary moves.

mod common;
use common::*;
use dollop::config::{Config, PauseConfig};
use dollop::executor::{ParkStage, RefillError};
use dollop::{Executor, RecordingOutputs};
use dollop_sim::designs::{chessboard, stripes, Job};
use dollop_sim::{PausePlan, RunOptions, RunResult};

const LIFT_MM: f32 = 3.0;
const PARK_XY: [f32; 2] = [5.0, 150.0];

fn parked_config(name: &str) -> Config {
    let mut c = config(name);
    c.pause = PauseConfig {
        park_lift_mm: LIFT_MM,
        park_position_mm: Some(PARK_XY),
    };
    c
}

/// What the step outputs did: highest Z, and the closest XY came to the park position
/// (mm), from the net step counts; and the plungers' lowest count after the first step.
#[derive(Default)]
struct Trace {
    z_max: f64,
    park_miss: f64,
    e_max: i64,
    e_min_after_max: i64,
}

fn run_parked(cfg: &Config, j: &Job, plan: &PausePlan) -> (RunResult, Trace) {
    let m = cfg.validate::<f64, 4>().unwrap();
    let spm = m.motion.steps_per_mm;
    let start = j.start_um.map(|u| u as f64 * 1e-3);
    let mut tr = Trace {
        z_max: f64::NEG_INFINITY,
        park_miss: f64::INFINITY,
        ..Default::default()
    };
    let opts = RunOptions {
        max_time_s: 1500.0,
        ..Default::default()
    };
    let r = dollop_sim::run_paused::<f32>(cfg, cfg, j, &opts, plan, |c| {
        let o: &RecordingOutputs = c.outputs;
        let p: [f64; 3] = core::array::from_fn(|a| start[a] + o.position[a] as f64 / spm[a]);
        tr.z_max = tr.z_max.max(p[2]);
        let miss = (p[0] - PARK_XY[0] as f64).hypot(p[1] - PARK_XY[1] as f64);
        tr.park_miss = tr.park_miss.min(miss);
        let e = o.position[3..].iter().copied().max().unwrap_or(0);
        if e > tr.e_max {
            tr.e_max = e;
            tr.e_min_after_max = e;
        }
        tr.e_min_after_max = tr
            .e_min_after_max
            .min(o.position[3..].iter().copied().min().unwrap_or(0));
    })
    .unwrap();
    (r, tr)
}

/// Every pause parked and came back, seams within bounds.
fn assert_parked(name: &str, cfg: &Config, j: &Job, r: &RunResult, tr: &Trace, n: usize) {
    summary(name, r);
    let worst = assert_landed(name, r, 0);
    assert_eq!(r.pauses.len(), n, "{name}: pauses made");
    let z0 = j.start_um[2] as f64 * 1e-3;
    let m = cfg.validate::<f64, 4>().unwrap();
    let step_mm = 1.0 / m.motion.steps_per_mm[0].min(m.motion.steps_per_mm[1]);
    assert!(
        tr.park_miss <= 1.5 * step_mm,
        "{name}: the steps came no closer than {:.4} mm to the park position",
        tr.park_miss
    );
    assert!(
        (tr.z_max - z0 - LIFT_MM as f64).abs() <= 1.0 / m.motion.steps_per_mm[2],
        "{name}: Z rose to {:.4} mm, the pause point is at {z0} + lift {LIFT_MM}",
        tr.z_max
    );
    let (mut gap, mut sec) = (0.0f64, (f64::INFINITY, f64::NEG_INFINITY));
    let mut away = (f64::INFINITY, 0.0f64);
    for (k, p) in r.pauses.iter().enumerate() {
        let what = format!("{name}: pause {k} at {:.4} s", p.t_request);
        let park = p
            .park
            .as_ref()
            .unwrap_or_else(|| panic!("{what}: never parked"));
        assert!(park.t_back.is_some(), "{what}: never came back ({park:?})");
        assert!(
            (park.lift_mm - LIFT_MM as f64).abs() < 1e-3,
            "{what}: lift {:.4} mm",
            park.lift_mm
        );
        let miss = (park.far_xy[0] - PARK_XY[0] as f64).hypot(park.far_xy[1] - PARK_XY[1] as f64);
        assert!(miss < 1e-3, "{what}: farthest point {:?}", park.far_xy);
        let t_away = park.t_back.unwrap() - park.t_left;
        away = (away.0.min(t_away), away.1.max(t_away));
        if p.at_bead_end {
            continue;
        }
        assert_seam(&what, p);
        gap = gap.max(p.seam_gap_mm);
        sec = (sec.0.min(p.seam_section.0), sec.1.max(p.seam_section.1));
    }
    eprintln!(
        "{name}: {n} parked pauses, boundaries within {worst:.4} mm; seam gap <= {gap:.3} mm, section {:.3}..{:.3} S; Z to {:.3} mm, park position within {:.4} mm (steps); off the pause point {:.2}..{:.2} s",
        sec.0, sec.1, tr.z_max, tr.park_miss, away.0, away.1
    );
}

fn plan(times: &[f64], wait: f64, refill: bool) -> PausePlan {
    PausePlan {
        park: true,
        refill,
        ..PausePlan::uniform(times, wait)
    }
}

/// Parked pauses on a chessboard and stripes, with real and instantaneous valves.
#[test]
fn parked_pauses_keep_boundaries_and_seams() {
    let chess = job(&fill(8.0, 4, 1), chessboard(2.0));
    let stripe = job(&fill(8.0, 4, 1), stripes(1.5));
    for (name, cfg_name, j, times) in [
        (
            "chessboard",
            "seed-paper-valves.toml",
            &chess,
            &[0.9, 2.3, 3.7][..],
        ),
        (
            "chessboard",
            "seed-paper.toml",
            &chess,
            &[0.9, 2.3, 3.7][..],
        ),
        (
            "stripes",
            "seed-paper-valves.toml",
            &stripe,
            &[1.6, 3.1][..],
        ),
    ] {
        let cfg = parked_config(cfg_name);
        let (r, tr) = run_parked(&cfg, j, &plan(times, 0.5, false));
        assert_parked(&format!("{name}/{cfg_name}"), &cfg, j, &r, &tr, times.len());
    }
}

/// Stepper syringes: each park refills (plungers back to where the fill began, then
/// counting from there), and the boundaries stay where the unrefilled run has them.
#[test]
fn syringe_refill_while_parked_moves_no_boundary() {
    // 3 mm squares: a syringe's lag needs more bead between boundaries than 2 mm ones.
    let j = job(&fill(9.0, 4, 1), chessboard(3.0));
    let cfg = parked_config("syringes.toml");
    let times = [2.0, 7.5];
    let (r, tr) = run_parked(&cfg, &j, &plan(&times, 0.5, true));
    assert_parked(
        "chessboard/syringes refilled",
        &cfg,
        &j,
        &r,
        &tr,
        times.len(),
    );
    for (k, p) in r.pauses.iter().enumerate() {
        let park = p.park.as_ref().expect("parked");
        assert!(park.refilled, "pause {k}: no refill");
        assert!(
            park.retract_steps > 0,
            "pause {k}: plungers did not retract"
        );
    }
    // The plungers went back to the start of their fill (0) at least once.
    assert!(
        tr.e_max > 0 && tr.e_min_after_max <= 0,
        "plungers {} .. {}",
        tr.e_max,
        tr.e_min_after_max
    );
    eprintln!(
        "refills: plungers retracted {:?} steps",
        r.pauses
            .iter()
            .map(|p| p.park.as_ref().map(|x| x.retract_steps))
            .collect::<Vec<_>>()
    );
}

/// The executor alone: refill refused unless parked on a syringe machine; park while
/// already paused parks from the pause point; resume while parked first comes back.
#[test]
fn refill_and_park_requests_refused_or_taken() {
    let pneumatic = parked_config("seed-paper.toml");
    let mut e: Executor<f32> = Executor::new(pneumatic.validate().unwrap());
    assert_eq!(e.refill(), Err(RefillError::NotSyringes));
    let sy = parked_config("syringes.toml");
    let mut e: Executor<f32> = Executor::new(sy.validate().unwrap());
    assert_eq!(e.refill(), Err(RefillError::NotParked));
    let j = job(&fill(6.0, 2, 1), stripes(1.5));
    e.begin(j.start_um, j.initial_material).unwrap();
    let mut out = RecordingOutputs::default();
    let mut cmds = j.commands.iter();
    let mut t = 0u64;
    let mut tick = |e: &mut Executor<f32>, out: &mut RecordingOutputs, n: usize| {
        for _ in 0..n {
            while e.room() > 0 {
                match cmds.next() {
                    Some(c) => e.push(*c).unwrap(),
                    None => break,
                }
            }
            e.tick(t, out).unwrap();
            t += 100;
        }
    };
    tick(&mut e, &mut out, 5_000);
    e.pause();
    tick(&mut e, &mut out, 5_000);
    assert_eq!(e.state(), dollop::RunState::Paused);
    assert_eq!(e.park_stage(), ParkStage::None);
    assert_eq!(e.refill(), Err(RefillError::NotParked));
    e.park();
    tick(&mut e, &mut out, 20_000);
    assert_eq!(e.park_stage(), ParkStage::Parked);
    assert_eq!(e.refill(), Ok(()));
    e.resume().unwrap();
    // Still paused while the refill retracts and the head comes back.
    assert_eq!(e.state(), dollop::RunState::Paused);
    tick(&mut e, &mut out, 40_000);
    assert_eq!(e.park_stage(), ParkStage::None);
    assert_eq!(e.refills(), 1);
    assert_ne!(e.state(), dollop::RunState::Paused);
    assert!(e.resume().is_err(), "a second resume must be refused");
}
