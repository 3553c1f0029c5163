//! Every path to the safe state, through the board-independent logic on recorded
//! outputs: power-up, executor fault, e-stop (input and request), watchdog expiry, link
//! loss while printing (pause and stop), panic, soft limits, homing before a job.

mod device_support;

use device_support::*;
use dollop::device::{force_safe, Control, ControlOrder, Inputs, Queues, ResetCause, ToControl};
use dollop::wire::*;
use dollop::{Axis, Command, Fault, Outputs, RecordingOutputs, RunState};

/// Runs a job until a bead is being laid (a valve open, drivers on).
fn printing(b: &mut Board, h: &mut Host) {
    h.ok(b, &Request::Start);
    h.wait(b, |s| {
        s.control.run == RunState::Printing && s.control.valves != 0
    });
    assert!(b.out.valves != 0 && b.out.drivers);
}

#[test]
fn power_up_closes_valves_and_disables_drivers() {
    let b = board();
    // SimBoard starts its outputs in an unsafe state on purpose.
    assert_safe(&b);
    assert_eq!(b.snapshot().mode, Mode::Unconfigured);
}

#[test]
fn a_watchdog_reset_starts_halted_and_safe() {
    let mut c = Control::new(ResetCause::Watchdog);
    let mut out = RecordingOutputs {
        valves: 0b11,
        drivers: true,
        ..Default::default()
    };
    c.power_up(&mut out);
    assert_eq!(out.valves, 0);
    assert!(!out.drivers);
    let mut q = Queues::default();
    c.tick(100, Inputs::default(), &mut q, &mut out);
    let s = q.snapshot();
    assert_eq!(s.mode, Mode::Halted);
    assert_eq!(s.halt, Some(Halt::Fault(Fault::Watchdog)));
}

#[test]
fn estop_input_while_printing_goes_safe_and_stays_latched() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 4);
    printing(&mut b, &mut h);
    b.estop = true;
    b.advance(200);
    assert_safe(&b);
    let s = h.status(&mut b);
    assert_eq!(s.control.mode, Mode::Halted);
    assert_eq!(s.control.halt, Some(Halt::Fault(Fault::EStop)));
    assert!(s.control.estop);
    // Held safe every cycle, and no clearing while the input is active.
    assert_eq!(
        h.refused(&mut b, &Request::ClearFault),
        Refusal::EStopActive
    );
    assert!(matches!(
        h.refused(&mut b, &Request::Start),
        Refusal::Halted(_)
    ));
    b.advance(100_000);
    assert_safe(&b);
    b.estop = false;
    b.advance(300);
    h.ok(&mut b, &Request::ClearFault);
    b.advance(1000);
    let s = h.status(&mut b);
    assert_eq!(s.control.mode, Mode::Idle);
    // The drivers were off: the position is lost and a new job needs homing.
    assert!(!s.control.homed);
    assert_eq!(h.refused(&mut b, &Request::Start), Refusal::NotHomed);
}

#[test]
fn estop_request_goes_safe() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 4);
    printing(&mut b, &mut h);
    h.ok(&mut b, &Request::EStop);
    b.advance(300);
    assert_safe(&b);
    assert_eq!(
        h.status(&mut b).control.halt,
        Some(Halt::Fault(Fault::EStop))
    );
}

#[test]
fn a_short_estop_pulse_is_not_missed() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 4);
    printing(&mut b, &mut h);
    b.estop = true;
    b.cycle();
    b.estop = false;
    b.advance(1000);
    assert_safe(&b);
    assert_eq!(h.status(&mut b).control.mode, Mode::Halted);
}

#[test]
fn a_hung_control_loop_is_reset_by_the_watchdog_into_the_safe_state() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 4);
    printing(&mut b, &mut h);
    b.control_hung = true;
    // Outputs stay as the hung loop left them until the watchdog bites.
    b.advance(dollop::device::sim_board::WATCHDOG_US / 2);
    assert_eq!(b.watchdog_resets, 0);
    b.advance(dollop::device::sim_board::WATCHDOG_US);
    assert_eq!(b.watchdog_resets, 1);
    assert_safe(&b);
    // After the reset the board is halted, says why, and has lost its session.
    let mut h2 = Host {
        session: 0x777,
        ..Host::default()
    };
    h2.hello(&mut b);
    let s = h2.status(&mut b);
    assert_eq!(s.control.halt, Some(Halt::Fault(Fault::Watchdog)));
    assert!(matches!(
        h.req(&mut b, &Request::Status),
        Reply::Refused(Refusal::NoSession)
    ));
}

#[test]
fn link_loss_while_printing_pauses_safely_by_default() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 30);
    printing(&mut b, &mut h);
    // The host falls silent.
    b.advance((LINK_TIMEOUT_MS as u64 + 200) * 1000);
    // It finishes the bead and holds with the valves closed; drivers hold the position.
    for _ in 0..600 {
        if b.snapshot().run == RunState::Paused {
            break;
        }
        b.advance(50_000);
    }
    let s = b.snapshot();
    assert_eq!(s.run, RunState::Paused, "{s:?}");
    assert_eq!(b.out.valves, 0);
    assert!(b.out.drivers);
    // A new session sees why, and can resume.
    let mut h2 = Host {
        session: 0x999,
        ..Host::default()
    };
    h2.hello(&mut b);
    let st = h2.status(&mut b);
    assert!(!st.link_lost, "a new hello starts clean");
    h2.ok(&mut b, &Request::Resume);
    h2.wait(&mut b, |s| s.control.run == RunState::Printing);
}

#[test]
fn link_loss_with_stop_policy_goes_safe_at_once() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 30);
    let s = Settings {
        on_link_loss: LinkLossPolicy::Stop,
        ..Settings::default()
    };
    h.ok(&mut b, &Request::Settings(s));
    printing(&mut b, &mut h);
    b.disconnect();
    b.advance(300);
    assert_safe(&b);
    assert_eq!(b.snapshot().halt, Some(Halt::Fault(Fault::LinkLost)));
    assert!(h.status(&mut b).link_lost);
}

#[test]
fn link_loss_during_a_valve_test_closes_the_valve() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    h.ok(
        &mut b,
        &Request::Valve {
            inlet: 1,
            open: true,
        },
    );
    b.advance(300);
    assert_eq!(b.out.valves, 0b10);
    b.advance((LINK_TIMEOUT_MS as u64 + 100) * 1000);
    assert_eq!(b.out.valves, 0);
}

#[test]
fn an_executor_fault_goes_safe() {
    // A job whose body leaves the travel although its header says otherwise.
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let cfg = config();
    h.ok(&mut b, &Request::LoadConfig(cfg.clone()));
    b.advance(1000);
    let cmds = [
        Command::Travel {
            x: 20_000,
            y: 20_000,
            z: 600,
        },
        Command::Print {
            dx: 5_000,
            dy: 0,
            material: 0,
        },
        Command::Print {
            dx: 0,
            dy: -30_000,
            material: 0,
        },
        Command::End,
    ];
    let (mut hd, body) = job(&cfg, [20_000, 20_000, 600], &cmds);
    hd.bounds_min_um = [20_000, 20_000, 600];
    h.upload(&mut b, &hd, &body);
    h.home(&mut b);
    h.ok(&mut b, &Request::Start);
    let s = h.wait(&mut b, |s| s.control.mode == Mode::Halted);
    assert!(
        matches!(
            s.control.halt,
            Some(Halt::Fault(Fault::Limit { axis: Axis::Y }))
        ),
        "{s:?}"
    );
    assert_safe(&b);
}

#[test]
fn a_panic_leaves_the_outputs_safe() {
    // The firmware's panic handler disables interrupts and calls `force_safe` on raw
    // registers; here the same function runs after a panic in the middle of a cycle.
    let mut out = RecordingOutputs::default();
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        out.drivers(true);
        out.valve(0, true);
        out.valve(7, true);
        panic!("bug in the middle of a cycle");
    }));
    assert!(r.is_err());
    force_safe(&mut out);
    assert_eq!(out.valves, 0);
    assert!(!out.drivers);
}

#[test]
fn jogs_stay_inside_the_soft_limits() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 2);
    let pos = h.status(&mut b).control.position_um;
    let r = h.refused(
        &mut b,
        &Request::Jog {
            axis: Axis::X,
            um: -pos[0] - 1,
        },
    );
    assert!(
        matches!(r, Refusal::SoftLimit { axis: Axis::X, .. }),
        "{r:?}"
    );
    assert!(r.to_string().contains("outside its travel"));
    // A jog inside moves by exactly that much.
    h.ok(
        &mut b,
        &Request::Jog {
            axis: Axis::X,
            um: 5_000,
        },
    );
    let s = h.wait(&mut b, |s| s.control.mode == Mode::Idle);
    assert_eq!(s.control.position_um[0], pos[0] + 5_000);
    // An order that slipped past the link is ignored by the control loop as well.
    let steps = b.out.position;
    b.queues
        .order(ControlOrder::Jog {
            axis: Axis::X,
            um: -10_000_000,
        })
        .unwrap();
    b.advance(100_000);
    assert_eq!(b.out.position, steps);
}

#[test]
fn a_job_outside_the_travel_is_refused_before_upload() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let cfg = config();
    h.ok(&mut b, &Request::LoadConfig(cfg.clone()));
    b.advance(1000);
    let (hd, _) = job(
        &cfg,
        [20_000, 20_000, 600],
        &[
            Command::Travel {
                x: 250_000,
                y: 0,
                z: 600,
            },
            Command::End,
        ],
    );
    assert_eq!(
        h.refused(&mut b, &Request::BeginJob(hd)),
        Refusal::JobOutsideTravel { axis: Axis::X }
    );
}

#[test]
fn homing_is_required_before_a_job_or_a_jog() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let cfg = config();
    h.ok(&mut b, &Request::LoadConfig(cfg.clone()));
    b.advance(1000);
    let (hd, body) = small_job(&cfg, 2);
    h.upload(&mut b, &hd, &body);
    assert_eq!(h.refused(&mut b, &Request::Start), Refusal::NotHomed);
    assert_eq!(
        h.refused(
            &mut b,
            &Request::Jog {
                axis: Axis::Z,
                um: 1000
            }
        ),
        Refusal::NotHomed
    );
    // The control loop ignores a start that is not homed even if asked directly.
    b.queues
        .order(ControlOrder::Start {
            epoch: 9,
            start_um: [20_000; 3],
            initial_material: 0,
        })
        .unwrap();
    b.advance(10_000);
    assert_eq!(b.snapshot().mode, Mode::Idle);
    assert!(!b.out.drivers);
    h.home(&mut b);
    let s = h.status(&mut b);
    // Homed against the endstops: X and Y at their minimum plus the back-off, Z at max.
    assert_eq!(s.control.position_um[0], 2_000);
    assert_eq!(s.control.position_um[2], 100_000 - 2_000);
    h.ok(&mut b, &Request::Start);
}

#[test]
fn broken_endstops_fail_homing_into_the_safe_state() {
    let mut b = board();
    b.endstops_broken = true;
    let mut h = Host::default();
    h.hello(&mut b);
    h.ok(&mut b, &Request::LoadConfig(config()));
    b.advance(1000);
    h.ok(&mut b, &Request::Home);
    let s = h.wait(&mut b, |s| s.control.mode == Mode::Halted);
    assert_eq!(s.control.halt, Some(Halt::HomingFailed { axis: Axis::Z }));
    assert_safe(&b);
}

#[test]
fn abort_stops_now_valves_closed_drivers_off() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 10);
    printing(&mut b, &mut h);
    h.ok(&mut b, &Request::Abort);
    b.advance(300);
    assert_safe(&b);
    let s = h.status(&mut b);
    assert_eq!(s.control.mode, Mode::Idle);
    // No stale command of the aborted job reaches a later one.
    h.home(&mut b);
    h.ok(&mut b, &Request::Start);
    let s = h.wait(&mut b, |s| s.control.mode != Mode::Job);
    assert_eq!(s.control.run, RunState::Done);
    assert_eq!(s.fed, 10 * 11 + 2);
}
