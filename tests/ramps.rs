//! Whole jobs with valves whose pressure switches at once: the head ramps through the
//! flow's speed steps within each axis's acceleration limit (1 ms central differences of
//! the commanded position, wherever a valve is open), boundaries stay within 0.05 mm, and
//! the section over every 0.2 mm of bead stays within what the limit forces. Also the
//! trade-off the README quotes: worst section against the acceleration limit.

mod common;
use common::*;
use dollop::config::Config;
use dollop::RunState;
use dollop_sim::designs::{chessboard, stripes, Job};
use dollop_sim::RunResult;

/// The seed printhead with instantaneous valves at X/Y acceleration `a`.
fn seed_at(a: f32) -> Config {
    let mut c = config("seed-paper.toml");
    c.motion.max_accel_mm_s2[0] = a;
    c.motion.max_accel_mm_s2[1] = a;
    c
}

/// The food pastes (power law) with their valves made instantaneous.
fn pastes_instant() -> Config {
    let mut c = config("food-pastes.toml");
    for i in c.inlets.iter_mut() {
        i.valve_open_delay_ms = 0.0;
        i.valve_close_delay_ms = 0.0;
        i.pressure_rise_ms = 0.0;
        i.pressure_decay_ms = 0.0;
    }
    c
}

fn board() -> Job {
    job(&fill(12.0, 10, 2), chessboard(2.0))
}

/// Checks the bounds and returns (worst section over 0.2 mm, X, Y acceleration).
fn assert_ramped(name: &str, cfg: &Config, r: &RunResult) -> (f64, f64, f64) {
    summary(name, r);
    let m = cfg.validate::<f64, 4>().unwrap();
    assert!(m.ramp_cycles > 1, "{name}: no ramps on this machine");
    assert_landed(name, r, 40);
    assert_axes_within(name, &m, r, 1.02);
    let section = r.metrics.worst_section_long();
    let bound = section_bound(&m);
    assert!(
        section <= bound,
        "{name}: section off by {:.2} % over 0.2 mm (bound {:.2} %)",
        section * 100.0,
        bound * 100.0
    );
    (section, r.axis_accel[0], r.axis_accel[1])
}

#[test]
fn instantaneous_valves_keep_the_acceleration_limit_newtonian() {
    // The machine: the seed printhead at 5 000 mm/s^2.
    let cfg = seed_at(5000.0);
    assert_ramped("chessboard/instant 5000", &cfg, &run(&cfg, &board()));
    let j = job(&fill(15.0, 6, 2), stripes(2.5));
    assert_ramped("stripes/instant 5000", &cfg, &run(&cfg, &j));
}

#[test]
fn instantaneous_valves_keep_the_acceleration_limit_power_law() {
    let cfg = pastes_instant();
    let j = job(&fill(12.0, 8, 2), chessboard(2.0));
    assert_ramped("chessboard/power law instant", &cfg, &run(&cfg, &j));
    let j = job(&fill(15.0, 6, 2), stripes(2.5));
    assert_ramped("stripes/power law instant", &cfg, &run(&cfg, &j));
}

/// `rows` beads of two materials, each printed left to right from a travel back along
/// the row before: every bead starts against the travel that brought the head there.
fn raster(rows: usize, width: f64) -> Job {
    use dollop::command::Command;
    let um = |mm: f64| (mm * 1000.0).round() as i32;
    let mut commands = Vec::new();
    for r in 0..rows {
        let y = 20.0 + r as f64 * 0.8;
        commands.push(Command::Travel {
            x: um(20.0),
            y: um(y),
            z: um(0.6),
        });
        for m in 0..2 {
            commands.push(Command::Print {
                dx: um(width / 2.0),
                dy: 0,
                material: m,
            });
        }
    }
    commands.push(Command::End);
    Job {
        start_um: [um(30.0), um(15.0), um(0.6)],
        initial_material: 0,
        commands,
    }
}

/// A travel brakes at the whole limit to its end, and a bead's start with instantaneous
/// valves steps the head's speed, ramped over a window centred on the step: where the bead
/// leaves against the travel they added on X, 6 248 mm/s^2 (Newtonian) and 7 614 (the
/// food pastes) on a 5 000 machine at the logo's bead starts, with the valves still shut.
/// The head now holds a window first (`start_hold`); the whole run's differences count.
#[test]
fn bead_starts_against_the_travel_keep_the_limit() {
    for (name, cfg) in [
        ("raster/instant 5000", seed_at(5000.0)),
        ("raster/power law instant", pastes_instant()),
    ] {
        let r = run(&cfg, &raster(6, 8.0));
        summary(name, &r);
        assert_landed(name, &r, 6);
        let m = cfg.validate::<f64, 4>().unwrap();
        eprintln!(
            "{name}: X {:.0} Y {:.0} mm/s^2 over the whole run",
            r.axis_accel_moving[0], r.axis_accel_moving[1]
        );
        assert_axes_within(name, &m, &r, 1.02);
    }
}

/// Real valves (30/20 ms pressure rise/decay) ramp the flow within the limit by
/// themselves: the head follows it as it is, section within 1 % over every 0.02 mm.
#[test]
fn real_valves_need_no_ramp_and_keep_the_limit() {
    for name in ["seed-paper-valves.toml", "food-pastes.toml"] {
        let cfg = config(name);
        let m = cfg.validate::<f64, 4>().unwrap();
        assert_eq!(m.ramp_cycles, 1, "{name}");
        let r = run(&cfg, &board());
        summary(name, &r);
        assert_eq!(r.state, RunState::Done);
        assert!(r.metrics.worst_boundary() <= 0.05);
        assert!(r.metrics.worst_section() <= 0.01);
        for a in 0..2 {
            assert!(
                r.axis_accel[a] <= m.motion.max_accel[a] * 1.02,
                "{name}: axis {a}"
            );
        }
    }
}

/// The README's table: the seed printhead with instantaneous valves, 2 mm chessboard,
/// at four X/Y limits.
#[test]
fn ramp_trade_off_on_the_seed_printhead() {
    let mut rows = Vec::new();
    for a in [1000.0f32, 2000.0, 5000.0, 10000.0] {
        let cfg = seed_at(a);
        let m = cfg.validate::<f64, 4>().unwrap();
        let r = run(&cfg, &board());
        let (section, ax, ay) = assert_ramped(&format!("chessboard/instant {a}"), &cfg, &r);
        rows.push((
            a,
            m.ramp_cycles,
            section,
            ax,
            ay,
            r.metrics.worst_boundary(),
        ));
    }
    eprintln!("| X/Y limit mm/s^2 | ramp ms | worst section over 0.2 mm | X / Y peak mm/s^2 | worst boundary mm |");
    for (a, w, s, ax, ay, b) in &rows {
        eprintln!(
            "| {a:.0} | {:.1} | {:.1} % | {ax:.0} / {ay:.0} | {b:.4} |",
            *w as f64 * 0.1,
            s * 100.0
        );
    }
    // A higher limit never costs more section.
    for w in rows.windows(2) {
        assert!(w[1].2 <= w[0].2 + 1e-3, "{rows:?}");
    }
}

/// The seed printhead with instantaneous valves at 2 000 mm/s^2 (so its head ramps)
/// printing `board()` cycle by cycle, commands pushed as room allows.
struct Driven {
    e: dollop::Executor<f32>,
    out: dollop::RecordingOutputs,
    job: Job,
    next: usize,
    cycle: u64,
}

impl Driven {
    fn new() -> Self {
        let m = seed_at(2000.0).validate::<f32, 4>().unwrap();
        assert!(m.ramp_cycles > 1);
        let job = board();
        let mut e = dollop::Executor::new(m);
        e.begin(job.start_um, job.initial_material).unwrap();
        Driven {
            e,
            out: Default::default(),
            job,
            next: 0,
            cycle: 0,
        }
    }

    /// One control cycle; the state its report gives.
    fn tick(&mut self) -> RunState {
        while self.next < self.job.commands.len()
            && self.e.push(self.job.commands[self.next]).is_ok()
        {
            self.next += 1;
        }
        self.cycle += 1;
        self.e.tick(self.cycle * 100, &mut self.out).unwrap().state
    }

    /// Ticks until `n` cycles have printed with a valve open.
    fn print_for(&mut self, n: u32) {
        let mut printed = 0;
        while printed < n {
            if self.tick() == RunState::Printing && self.out.valves != 0 {
                printed += 1;
            }
        }
    }
}

/// An abort while the head ramps stops the outputs where they are: no step and no valve
/// after it, although the plan ran half a window ahead.
#[test]
fn abort_mid_ramp_stops_where_the_outputs_are() {
    let mut d = Driven::new();
    // Into the first bead, past the valve's opening, then a little more.
    d.print_for(500);
    d.e.abort(&mut d.out);
    let (pos, pulses) = (d.out.position, d.out.pulses);
    assert_eq!(d.out.valves, 0);
    for _ in 0..2000 {
        assert_eq!(d.tick(), RunState::Aborted);
    }
    assert_eq!(d.out.valves, 0);
    assert_eq!(d.out.pulses, pulses, "stepped after the abort");
    assert_eq!(d.out.position, pos);
}

/// Pause and resume on a machine with ramps: after `resume` the outputs still show the
/// paused frames for half a window, but the state a host polls must not say "paused"
/// again (found on the emulated board: `dollop resume` saw Paused, took the print for
/// paused and left). The job then runs to Done.
#[test]
fn a_resumed_print_is_never_reported_paused_while_the_window_drains() {
    let mut d = Driven::new();
    d.print_for(2000);
    d.e.pause();
    let mut waited = 0;
    while {
        d.tick();
        d.e.state() != RunState::Paused
    } {
        waited += 1;
        assert!(waited < 200_000, "never paused");
    }
    for _ in 0..1000 {
        d.tick();
        assert_eq!(d.e.state(), RunState::Paused);
    }
    d.e.resume().unwrap();
    let mut n = 0;
    loop {
        d.tick();
        let s = d.e.state();
        assert_ne!(
            s,
            RunState::Paused,
            "reported paused {n} cycles after resume"
        );
        if s == RunState::Done {
            break;
        }
        n += 1;
        assert!(n < 5_000_000, "never finished");
    }
}
