//! The board's logic on every machine kind and in every state: syringe machines print,
//! every request type is answered (never a panic) on a configured, homed, printing board,
//! plungers are not jogged, the control rate is the board's, nothing moves or opens while
//! an upload writes the store, and the e-stop's latch wins over a control tick it
//! preempted.

mod device_support;

use core::sync::atomic::{AtomicBool, Ordering};
use device_support::*;
use dollop::device::{Control, EStopGuard, Inputs, Queues, ResetCause};
use dollop::wire::*;
use dollop::{Axis, Config, Outputs, RecordingOutputs, RunState};

const MACHINES: [&str; 3] = [
    "seed-paper-valves.toml",
    "food-pastes.toml",
    "syringes.toml",
];

/// Runs a job until a bead is being laid (a valve open or a plunger pushing, drivers on).
fn printing(b: &mut Board, h: &mut Host) {
    h.ok(b, &Request::Start);
    h.wait(b, |s| s.control.run == RunState::Printing);
    assert!(b.out.drivers);
}

#[test]
fn a_syringe_machine_prints_a_whole_job_and_drives_its_plungers() {
    let mut b = board();
    let mut h = Host::ready_with(&mut b, config_file("syringes.toml"), 3);
    h.ok(&mut b, &Request::Start);
    let s = h.wait(&mut b, |s| {
        s.control.mode == Mode::Idle && s.control.run == RunState::Done
    });
    assert!(s.control.halt.is_none(), "{s:?}");
    // Both plungers (E0, E1) pushed paste forward.
    for e in 0..2u8 {
        let i = Axis::E(e).index();
        assert!(b.out.position[i] > 0, "plunger {e} never moved");
    }
    assert_eq!(b.control.commanded().steps[3..5], b.out.position[3..5]);
}

#[test]
fn every_request_on_a_printing_board_is_answered_on_every_machine() {
    for name in MACHINES {
        let cfg = config_file(name);
        let mut b = board();
        let mut h = Host::ready_with(&mut b, cfg.clone(), 4);
        printing(&mut b, &mut h);
        let (hd, body) = small_job(&cfg, 1);
        let busy = |r: Refusal| matches!(r, Refusal::Busy { mode: Mode::Job });
        assert_eq!(h.status(&mut b).control.mode, Mode::Job);
        assert!(busy(h.refused(&mut b, &Request::LoadConfig(cfg.clone()))));
        assert!(busy(h.refused(&mut b, &Request::BeginJob(hd.clone()))));
        assert_eq!(
            h.refused(
                &mut b,
                &Request::Chunk {
                    offset: 0,
                    data: &body[..8]
                }
            ),
            Refusal::NotUploading
        );
        // The stored job is checked and ready: ending it again is a no-op.
        h.ok(&mut b, &Request::EndJob);
        assert!(busy(h.refused(&mut b, &Request::Start)));
        assert!(busy(h.refused(&mut b, &Request::Home)));
        for axis in [Axis::X, Axis::Z, Axis::E(0), Axis::E(7), Axis::E(255)] {
            let r = h.refused(&mut b, &Request::Jog { axis, um: 1000 });
            assert!(
                busy(r.clone()) || matches!(r, Refusal::NotJoggable { .. }),
                "{name}: jog {axis:?}: {r:?}"
            );
        }
        for inlet in [0u8, 1, 3, 9, 255] {
            let r = h.refused(&mut b, &Request::Valve { inlet, open: true });
            assert!(
                busy(r.clone()) || matches!(r, Refusal::NoSuchInlet { .. }),
                "{name}: valve {inlet}: {r:?}"
            );
        }
        h.ok(&mut b, &Request::Settings(Settings::default()));
        h.ok(&mut b, &Request::ClearFault);
        h.ok(&mut b, &Request::Pause);
        h.wait(&mut b, |s| s.control.run == RunState::Paused);
        h.ok(&mut b, &Request::Resume);
        h.wait(&mut b, |s| s.control.run != RunState::Paused);
        h.ok(&mut b, &Request::Abort);
        h.wait(&mut b, |s| s.control.mode == Mode::Idle);
        assert_eq!(b.out.valves, 0, "{name}: a valve stayed open after abort");
        // Printing again, then the host's e-stop.
        h.ok(&mut b, &Request::Home);
        h.wait(&mut b, |s| s.control.homed && s.control.mode == Mode::Idle);
        printing(&mut b, &mut h);
        h.ok(&mut b, &Request::EStop);
        b.advance(200);
        assert_safe(&b);
        assert!(matches!(
            h.refused(&mut b, &Request::Home),
            Refusal::Halted(_)
        ));
        h.ok(&mut b, &Request::ClearFault);
        h.wait(&mut b, |s| s.control.mode == Mode::Idle);
    }
}

#[test]
fn plungers_are_not_jogged_and_say_why() {
    for name in ["syringes.toml", "seed-paper-valves.toml"] {
        let mut b = board();
        let mut h = Host::ready_with(&mut b, config_file(name), 1);
        for e in [0u8, 1, 3, 4, 200] {
            let r = h.refused(
                &mut b,
                &Request::Jog {
                    axis: Axis::E(e),
                    um: 500,
                },
            );
            assert_eq!(r, Refusal::NotJoggable { axis: Axis::E(e) });
            assert!(r.to_string().contains("X, Y and Z"), "{r}");
        }
        // The head still jogs.
        h.ok(
            &mut b,
            &Request::Jog {
                axis: Axis::X,
                um: 1000,
            },
        );
        h.wait(&mut b, |s| s.control.mode == Mode::Idle);
    }
}

/// The board names every kind of config problem in its refusal (`Problem::name`): a
/// machine mixing syringes and valves used to come back as "invalid".
#[test]
fn a_config_mixing_syringes_and_valves_is_refused_by_name() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    let mut cfg: Config = config();
    cfg.inlets[0].syringe = Some(dollop::config::SyringeConfig {
        steps_per_mm3: 100.0,
        lag_k: 5.0,
        lag_n: 1.0,
    });
    let e = cfg.validate::<f32, 4>().unwrap_err();
    assert_eq!(e.problem, dollop::config::Problem::MixedDrives, "{e}");
    match h.refused(&mut b, &Request::LoadConfig(cfg)) {
        Refusal::Config(t) => assert_eq!(t, "inlet[0].syringe: mixes syringe and pneumatic inlets"),
        other => panic!("{other:?}"),
    }
    assert_eq!(h.status(&mut b).config, None);
}

#[test]
fn a_config_for_another_control_rate_is_refused() {
    let mut b = board();
    let mut h = Host::default();
    h.hello(&mut b);
    for rate in [5_000u32, 20_000] {
        let mut cfg: Config = config();
        cfg.control.rate_hz = rate;
        assert!(
            cfg.validate::<f32, 4>().is_ok(),
            "{rate} Hz must be valid in itself"
        );
        match h.refused(&mut b, &Request::LoadConfig(cfg)) {
            Refusal::Config(t) => {
                assert!(
                    t.contains("control.rate_hz") && t.contains("10000 Hz"),
                    "{t}"
                )
            }
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(h.status(&mut b).config, None);
    h.ok(&mut b, &Request::LoadConfig(config()));
}

#[test]
fn nothing_moves_or_opens_while_an_upload_writes_the_store() {
    let mut b = board();
    let mut h = Host::ready(&mut b, 1);
    let cfg = config();
    let (hd, body) = small_job(&cfg, 6);
    h.ok(&mut b, &Request::BeginJob(hd.clone()));
    b.advance(1000);
    h.ok(
        &mut b,
        &Request::Chunk {
            offset: 0,
            data: &body[..MAX_CHUNK],
        },
    );
    // Receiving: the store is being written.
    assert!(matches!(h.status(&mut b).job, JobSlot::Receiving { .. }));
    assert_eq!(h.refused(&mut b, &Request::Home), Refusal::Uploading);
    assert_eq!(
        h.refused(
            &mut b,
            &Request::Jog {
                axis: Axis::X,
                um: 1000
            }
        ),
        Refusal::Uploading
    );
    assert_eq!(
        h.refused(
            &mut b,
            &Request::Valve {
                inlet: 0,
                open: true
            }
        ),
        Refusal::Uploading
    );
    // Closing a valve is the safe direction and always allowed.
    h.ok(
        &mut b,
        &Request::Valve {
            inlet: 0,
            open: false,
        },
    );
    assert_eq!(b.out.valves, 0);
    assert!(Refusal::Uploading.to_string().contains("wait"));
    // Finishing the upload lifts the rule.
    h.chunks(&mut b, &body, 1);
    h.ok(&mut b, &Request::EndJob);
    h.wait(&mut b, |s| matches!(s.job, JobSlot::Ready { .. }));
    h.ok(
        &mut b,
        &Request::Valve {
            inlet: 0,
            open: true,
        },
    );
    b.advance(300);
    assert_eq!(b.out.valves, 1);
}

/// Outputs on which the e-stop "interrupt" fires at the worst moment: while the control
/// loop is writing a valve open or the drivers on, just before the write lands.
struct EStopMidWrite<'a> {
    pins: RecordingOutputs,
    latch: &'a AtomicBool,
    armed: bool,
}

impl EStopMidWrite<'_> {
    fn estop_isr(&mut self) {
        if self.armed {
            self.armed = false;
            // What the firmware's e-stop handler does: safe state, then the latch.
            dollop::device::force_safe(&mut self.pins);
            self.latch.store(true, Ordering::Release);
        }
    }
}

impl Outputs for EStopMidWrite<'_> {
    fn step(&mut self, axis: Axis, forward: bool, count: u32) {
        self.pins.step(axis, forward, count);
    }
    fn valve(&mut self, inlet: u8, open: bool) {
        if open {
            self.estop_isr();
        }
        self.pins.valve(inlet, open);
    }
    fn drivers(&mut self, enabled: bool) {
        if enabled {
            self.estop_isr();
        }
        self.pins.drivers(enabled);
    }
}

/// A control loop with the seed config, idle, asked to open valve 0 on its next tick.
fn valve_test_pending() -> (Control, Queues) {
    let mut c = Control::new(ResetCause::PowerOn);
    let mut q = Queues::default();
    let mut out = RecordingOutputs::default();
    c.power_up(&mut out);
    c.load_config(&config(), &mut out).unwrap();
    use dollop::device::{ControlOrder, ToControl};
    q.order(ControlOrder::Valve {
        inlet: 0,
        open: true,
    })
    .unwrap();
    (c, q)
}

#[test]
fn an_estop_that_preempts_a_valve_write_is_not_undone() {
    // Without the guard the race is real: the preempted write reopens the valve.
    let latch = AtomicBool::new(false);
    let (mut c, mut q) = valve_test_pending();
    let mut raw = EStopMidWrite {
        pins: RecordingOutputs::default(),
        latch: &latch,
        armed: true,
    };
    c.tick(100, Inputs::default(), &mut q, &mut raw);
    assert!(latch.load(Ordering::Acquire));
    assert_eq!(
        raw.pins.valves, 1,
        "the unguarded write should land after the e-stop"
    );

    // With it, the latch wins within the same tick, and the next tick halts on it.
    let latch = AtomicBool::new(false);
    let (mut c, mut q) = valve_test_pending();
    let mut pins = EStopMidWrite {
        pins: RecordingOutputs::default(),
        latch: &latch,
        armed: true,
    };
    let mut out = EStopGuard {
        out: &mut pins,
        latch: &latch,
    };
    c.tick(100, Inputs::default(), &mut q, &mut out);
    assert_eq!(pins.pins.valves, 0, "the e-stop was undone");
    assert!(!pins.pins.drivers);
    let estop = latch.swap(false, Ordering::AcqRel);
    let inputs = Inputs {
        estop,
        ..Inputs::default()
    };
    let mut out = EStopGuard {
        out: &mut pins,
        latch: &latch,
    };
    c.tick(200, inputs, &mut q, &mut out);
    assert_eq!(c.mode(), Mode::Halted);
    assert_eq!(pins.pins.valves, 0);
}

#[test]
fn the_boards_compile_time_control_state_learns_a_watchdog_reset_at_boot() {
    // The firmware builds its `Control` in a static before it can read the reset cause.
    let mut c = Control::new(ResetCause::PowerOn);
    c.set_reset_cause(ResetCause::Watchdog);
    let mut out = RecordingOutputs::default();
    c.power_up(&mut out);
    let mut q = Queues::default();
    c.tick(100, Inputs::default(), &mut q, &mut out);
    use dollop::device::ToControl;
    let s = q.snapshot();
    assert_eq!(s.mode, Mode::Halted);
    assert_eq!(s.halt, Some(Halt::Fault(dollop::Fault::Watchdog)));
}
