//! Faults and operator actions end in the safe state: valves closed, motion stopped,
//! drivers disabled, the fault reported as a value. Each test checks the outputs.

mod common;
use common::*;
use dollop::executor::{LoadError, PushError};
use dollop::{Command, Executor, Fault, RecordingOutputs, RunState};
use dollop_sim::designs::{stripes, Job};
use dollop_sim::RunOptions;

const PERIOD_US: u64 = 100;

fn executor(cfg_name: &str) -> Executor<f32> {
    Executor::new(config(cfg_name).validate().unwrap())
}

/// Ticks until `stop` says so or a fault; returns the outputs, the last tick's result and
/// whether any valve was open at some point.
fn drive(
    ex: &mut Executor<f32>,
    job: &[Command],
    max_cycles: u64,
) -> (RecordingOutputs, Result<dollop::Report<f32>, Fault>, bool) {
    let mut out = RecordingOutputs::default();
    let mut next = 0;
    let mut was_open = false;
    let mut last = Err(Fault::NotReady);
    for k in 0..max_cycles {
        while next < job.len() && ex.room() > 0 {
            match ex.push(job[next]) {
                Ok(()) => next += 1,
                Err(PushError::Full) => break,
                Err(PushError::Rejected(_)) => {
                    next = job.len();
                    break;
                }
            }
        }
        last = ex.tick(k * PERIOD_US, &mut out);
        was_open |= out.valves != 0;
        match &last {
            Err(_) => break,
            Ok(r) if r.state == RunState::Done => break,
            _ => {}
        }
    }
    (out, last, was_open)
}

fn assert_safe(out: &RecordingOutputs, what: &str) {
    assert_eq!(out.valves, 0, "{what}: valves left open");
    assert!(!out.drivers, "{what}: drivers left enabled");
}

/// A long print (more segments than the executor queues) followed by `tail`.
fn long_print_then(tail: &[Command]) -> Job {
    let mut j = job(&fill(12.0, 40, 1), stripes(0.5));
    j.commands.pop(); // End
    j.commands.extend_from_slice(tail);
    j
}

#[test]
fn a_job_that_drives_an_axis_past_its_limit_stops_safely_before_going_there() {
    // Travel limits of the seed printhead: X 0..200 mm.
    let j = long_print_then(&[
        Command::Print {
            dx: 200_000,
            dy: 0,
            material: 0,
        },
        Command::End,
    ]);
    let mut max_x = 0.0f64;
    let r = dollop_sim::run::<f32>(
        &config("seed-paper.toml"),
        &j,
        &RunOptions::default(),
        |c| {
            max_x = max_x.max(c.report.position[0] as f64);
        },
    )
    .unwrap();
    assert_eq!(r.state, RunState::Faulted);
    assert_eq!(
        r.fault,
        Some(Fault::Limit {
            axis: dollop::Axis::X
        })
    );
    assert_safe(&r.outputs, "limit");
    assert!(r.metrics.section_cycles > 100, "the print had started");
    assert!(max_x <= 200.0, "head went to x = {max_x}");

    // A travel past the limit while idle is refused the same way.
    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 1000], 0).unwrap();
    let (out, last, _) = drive(
        &mut ex,
        &[Command::Travel {
            x: 10_000,
            y: 10_000,
            z: 150_000,
        }],
        10,
    );
    assert_eq!(
        last.unwrap_err(),
        Fault::Limit {
            axis: dollop::Axis::Z
        }
    );
    assert_safe(&out, "travel limit");
}

#[test]
fn a_step_rate_over_the_maximum_stops_safely_mid_bead() {
    let mut m = config("seed-paper.toml").validate::<f32, 4>().unwrap();
    // A machine whose drivers take one step per cycle, with fine microstepping: printing at
    // 10 mm/s needs 2 steps per cycle.
    m.motion.steps_per_mm = [2000.0, 2000.0, 400.0];
    m.motion.max_steps_per_cycle = 1;
    let mut ex: Executor<f32> = Executor::new(m);
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    let job = [
        Command::Print {
            dx: 50_000,
            dy: 0,
            material: 0,
        },
        Command::End,
    ];
    let (out, last, was_open) = drive(&mut ex, &job, 100_000);
    match last {
        Err(Fault::StepRate { axis, steps, max }) => {
            assert_eq!(axis, dollop::Axis::X);
            assert!(steps > max && max == 1, "{steps} > {max}");
        }
        other => panic!("expected a step-rate fault, got {other:?}"),
    }
    assert!(was_open, "the fault came while paste was flowing");
    assert_safe(&out, "step rate");
    // The fault holds: further ticks keep everything off and report it.
    let mut out2 = out.clone();
    out2.valves = 0b11;
    out2.drivers = true;
    assert!(matches!(
        ex.tick(10_000_000_000, &mut out2),
        Err(Fault::StepRate { .. })
    ));
    assert_safe(&out2, "held fault");
}

#[test]
fn an_invalid_config_stops_a_running_machine_safely() {
    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    let job = [
        Command::Print {
            dx: 50_000,
            dy: 0,
            material: 0,
        },
        Command::End,
    ];
    let (mut out, last, was_open) = drive(&mut ex, &job, 3000);
    assert!(last.is_ok() && was_open && out.valves != 0 && out.drivers);
    let mut bad = config("seed-paper.toml");
    bad.channel.nozzle_diameter_mm = -0.8;
    let e = ex.load_config(&bad, &mut out).unwrap_err();
    match e {
        LoadError::Invalid(ce) => assert!(
            ce.to_string().starts_with("channel.nozzle_diameter_mm"),
            "{ce}"
        ),
        other => panic!("{other:?}"),
    }
    assert_safe(&out, "invalid config");
    assert_eq!(
        ex.tick(3000 * PERIOD_US, &mut out).unwrap_err(),
        Fault::InvalidConfig
    );
    assert_eq!(ex.state(), RunState::Faulted);
    // A valid config is refused while a job is loaded, accepted once the fault is cleared.
    ex.clear_fault();
    ex.load_config(&config("seed-paper-valves.toml"), &mut out)
        .unwrap();
    assert_eq!(ex.machine().inlets[0].open_delay_s, 0.01);
}

#[test]
fn a_config_change_during_a_job_is_refused_without_stopping_it() {
    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    let job = [
        Command::Print {
            dx: 50_000,
            dy: 0,
            material: 0,
        },
        Command::End,
    ];
    let (mut out, _, _) = drive(&mut ex, &job, 3000);
    assert_eq!(
        ex.load_config(&config("seed-paper-valves.toml"), &mut out),
        Err(LoadError::Busy)
    );
    assert_eq!(ex.state(), RunState::Printing);
    assert_ne!(out.valves, 0);
}

#[test]
fn a_queue_that_runs_dry_while_printing_is_an_underrun() {
    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    // Two segments and no End: the feeder "stalls".
    let job = [
        Command::Print {
            dx: 10_000,
            dy: 0,
            material: 0,
        },
        Command::Print {
            dx: 10_000,
            dy: 0,
            material: 1,
        },
    ];
    let (out, last, was_open) = drive(&mut ex, &job, 100_000);
    assert_eq!(last.unwrap_err(), Fault::Underrun);
    assert!(was_open);
    assert_safe(&out, "underrun");
}

#[test]
fn invalid_commands_and_late_ticks_are_faults() {
    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    assert!(matches!(
        ex.push(Command::Print {
            dx: 1000,
            dy: 0,
            material: 7
        }),
        Err(PushError::Rejected(Fault::InvalidCommand(_)))
    ));
    let mut out = RecordingOutputs::default();
    assert!(matches!(
        ex.tick(0, &mut out),
        Err(Fault::InvalidCommand(_))
    ));
    assert_safe(&out, "invalid command");

    let mut ex = executor("seed-paper.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    ex.push(Command::Print {
        dx: 30_000,
        dy: 0,
        material: 0,
    })
    .unwrap();
    ex.push(Command::End).unwrap();
    let mut out = RecordingOutputs::default();
    for k in 0..100 {
        ex.tick(k * PERIOD_US, &mut out).unwrap();
    }
    // The control loop stalled for a millisecond.
    assert_eq!(
        ex.tick(110 * PERIOD_US, &mut out).unwrap_err(),
        Fault::Late { periods: 11 }
    );
    assert_safe(&out, "late tick");
}

#[test]
fn e_stop_abort_and_pause() {
    let job = [
        Command::Print {
            dx: 20_000,
            dy: 0,
            material: 0,
        },
        Command::Travel {
            x: 10_000,
            y: 20_000,
            z: 600,
        },
        Command::Print {
            dx: 20_000,
            dy: 0,
            material: 1,
        },
        Command::End,
    ];
    // E-stop mid-bead.
    let mut ex = executor("seed-paper-valves.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    let (mut out, _, _) = drive(&mut ex, &job, 5000);
    assert_ne!(out.valves, 0);
    ex.fault(Fault::EStop, &mut out);
    assert_safe(&out, "e-stop");
    assert_eq!(
        ex.tick(5000 * PERIOD_US, &mut out).unwrap_err(),
        Fault::EStop
    );

    // Abort mid-bead.
    let mut ex = executor("seed-paper-valves.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    let (mut out, _, _) = drive(&mut ex, &job, 5000);
    ex.abort(&mut out);
    assert_safe(&out, "abort");
    assert_eq!(ex.state(), RunState::Aborted);

    // Pause mid-bead: the valves shut at once, the head follows the tail to rest well
    // short of the bead's end, holds there with the valves shut, and the job finishes
    // after resume. Resuming what is not paused is refused.
    let mut ex = executor("seed-paper-valves.toml");
    ex.begin([10_000, 10_000, 600], 0).unwrap();
    for c in job {
        ex.push(c).unwrap();
    }
    let mut out = RecordingOutputs::default();
    let mut k = 0u64;
    let mut x_req = 0.0;
    while k < 5000 {
        x_req = ex.tick(k * PERIOD_US, &mut out).unwrap().position[0];
        k += 1;
    }
    assert_eq!(ex.resume(), Err(dollop::executor::ResumeError::NotPaused));
    ex.pause();
    let mut paused_at = None;
    for _ in 0..200_000 {
        let r = ex.tick(k * PERIOD_US, &mut out).unwrap();
        k += 1;
        if r.state == RunState::Paused {
            paused_at = Some(r.position);
            break;
        }
    }
    let at = paused_at.expect("never paused");
    assert_eq!(out.valves, 0, "paused with a valve open");
    assert!(
        at[0] > x_req && at[0] < 29.0,
        "paused at {at:?}, requested at x = {x_req}: not mid-bead"
    );
    let info = ex.pause_info().expect("pause recorded");
    assert!(!info.at_bead_end);
    assert!(
        info.shut_cycle.unwrap() <= info.requested_cycle + 1,
        "{info:?}"
    );
    for _ in 0..1000 {
        let r = ex.tick(k * PERIOD_US, &mut out).unwrap();
        k += 1;
        assert_eq!(r.state, RunState::Paused);
        assert!(
            (r.position[0] - at[0]).abs() < 1e-3,
            "{:?} {at:?}",
            r.position
        );
        assert_eq!(out.valves, 0);
    }
    ex.resume().unwrap();
    let mut done = false;
    for _ in 0..200_000 {
        let r = ex.tick(k * PERIOD_US, &mut out).unwrap();
        k += 1;
        if r.state == RunState::Done {
            done = true;
            break;
        }
    }
    assert!(done);
    assert_eq!(out.valves, 0);
}

/// The executor's safe state is the device's (`outputs::force_safe`): a fault, an abort
/// and every faulted cycle close each valve a config can name, not only the inlets of
/// the machine loaded. A valve past them can be open (left by an earlier config with
/// more inlets, or a valve test); closing only `inlet_count` valves left it open.
#[test]
fn faults_and_aborts_close_valves_beyond_the_machines_inlets() {
    let mut ex = executor("seed-paper-valves.toml");
    let inlets = ex.machine().inlet_count();
    let beyond = dollop::config::MAX_CONFIG_INLETS - 1;
    assert!(inlets <= beyond, "seed-paper-valves has {inlets} inlets");
    let stray = || RecordingOutputs {
        valves: 1 << beyond | 1 << inlets,
        drivers: true,
        ..Default::default()
    };

    let mut out = stray();
    ex.abort(&mut out);
    assert_safe(&out, "abort with a valve beyond the machine's inlets");

    let mut ex = executor("seed-paper-valves.toml");
    let mut out = stray();
    ex.fault(Fault::EStop, &mut out);
    assert_safe(&out, "e-stop with a valve beyond the machine's inlets");
    // Held every cycle while faulted, whatever else touched the pins.
    out.valves = 1 << beyond;
    out.drivers = true;
    assert_eq!(ex.tick(0, &mut out).unwrap_err(), Fault::EStop);
    assert_safe(
        &out,
        "a faulted cycle with a valve beyond the machine's inlets",
    );
}
