//! The flow model against the seed paper's closed forms for one Newtonian switch:
//! Q(t) = 1/sqrt(2at + b^2), t0 = b V_s + a V_s^2 / 2, and the per-cycle mean speed in its
//! stable form, for viscosity ratios 1/10 ..= 10 including exactly 1, in f64 (1e-6) and in
//! the f32 the chip runs (1e-4).

use dollop::config::{ChannelConfig, Config, ControlConfig, InletConfig, MotionConfig, Pressure};
use dollop::flow_model::FlowModel;
use dollop::rheology::Rheology;
use dollop::{Machine, Real};

const D: f64 = 0.8;
const LS: f64 = 2.4;
const S: f64 = 0.48;
const P_KPA: f64 = 3.0;

fn config(mu_cur: f32, mu_nxt: f32) -> Config {
    let inlet = |name: &str, mu: f32| InletConfig {
        material: heapless::String::try_from(name).unwrap(),
        rheology: Rheology::Newtonian { viscosity_pa_s: mu },
        pressure_kpa: Pressure::Kpa(P_KPA as f32),
        valve_open_delay_ms: 0.0,
        valve_close_delay_ms: 0.0,
        pressure_rise_ms: 0.0,
        pressure_decay_ms: 0.0,
        syringe: None,
    };
    let mut inlets = heapless::Vec::new();
    inlets.push(inlet("current", mu_cur)).unwrap();
    inlets.push(inlet("next", mu_nxt)).unwrap();
    Config {
        channel: ChannelConfig {
            nozzle_diameter_mm: D as f32,
            channel_length_mm: LS as f32,
            nozzle_height_mm: 0.6,
            layer_height_mm: 0.6,
            line_pitch_mm: 0.8,
            bead_area_mm2: Some(S as f32),
        },
        motion: MotionConfig {
            steps_per_mm: [80.0, 80.0, 400.0],
            travel_min_mm: [0.0; 3],
            travel_max_mm: [200.0, 200.0, 100.0],
            max_speed_mm_s: [2000.0, 2000.0, 20.0],
            // Switches between viscosities 1000 times apart step the head speed by up to
            // 186 mm/s at once: a ramp at 2 000 mm/s^2 would outlast the executor's
            // ramp window, and this config is refused. These tests run the model only.
            max_accel_mm_s2: [1.0e5, 1.0e5, 200.0],
            print_speed_mm_s: 10.0,
            print_speed_max_mm_s: 2000.0,
            travel_speed_mm_s: 80.0,
            max_step_rate_hz: 1.0e6,
            wait_for_flow_decay: true,
            flow_stop_fraction: 0.005,
        },
        control: ControlConfig { rate_hz: 10_000 },
        inlets,
        pause: Default::default(),
    }
}

struct Errors {
    q: f64,
    speed: f64,
    t0: f64,
    cycles: usize,
}

/// Runs one switch and returns the worst relative errors against the closed forms.
fn switch_errors<R: Real>(mu_cur: f64, mu_nxt: f64) -> Errors {
    let cfg = config(mu_cur as f32, mu_nxt as f32);
    let m: Machine<R, 2> = cfg.validate().unwrap();
    // The reference uses exactly the values the model was given.
    let mu_c = mu_cur as f32 as f64;
    let mu_n = mu_nxt as f32 as f64;
    let p = P_KPA * 1e3;
    let pi = std::f64::consts::PI;
    // The config holds f32: the closed form gets the same rounded geometry.
    let d = D as f32 as f64;
    let ls = LS as f32 as f64;
    let a = 512.0 * (mu_n - mu_c) / (pi * pi * d.powi(6) * p);
    let b = 128.0 * mu_c * ls / (pi * d.powi(4) * p);
    let vs = m.v_channel.mm3::<f64>();
    let t0 = b * vs + a * vs * vs / 2.0;
    let dt = 1e-4;

    let mut model: FlowModel<R, 2> = FlowModel::new(&m, 0);
    model.command(0b01);
    for _ in 0..50 {
        model.step().unwrap();
    }
    // Channel still full of the current material; switch now (t = 0).
    model.command(0b10);
    let q_closed = |t: f64| 1.0 / (2.0 * a * t + b * b).sqrt();
    let mut worst = Errors {
        q: 0.0,
        speed: 0.0,
        t0: f64::NAN,
        cycles: 0,
    };
    let mut t = 0.0f64;
    let entered0 = model.channel().entered();
    loop {
        // Instantaneous flow at the cycle boundary (valid while t < t0).
        // Both lines supply the same pressure, so the junction holds P across the switch.
        let q_model = model.flow_now().to_f64();
        let rel = (q_model - q_closed(t)).abs() / q_closed(t);
        worst.q = worst.q.max(rel);
        let before = model.channel().entered();
        let r_before = model.resistance_linear().to_f64();
        let exit_before = model.channel().at_exit();
        let flow = model.step().unwrap();
        let dv: f64 = flow.dv.mm3();
        if model.channel().at_exit() != exit_before {
            // The new material reached the exit inside this cycle: solve for the moment
            // from the model's own state at the start of the cycle.
            let v_in: f64 = (before - entered0).mm3();
            let left = vs - v_in;
            let k = 512.0 * (mu_n - mu_c) / (pi * pi * d.powi(6));
            let tc = t + (r_before * left + k * left * left / 2.0) / p;
            worst.t0 = (tc - t0).abs() / t0;
            break;
        }
        let v_mean = dv / (S * dt);
        let stable =
            2.0 / (S * ((2.0 * a * (t + dt) + b * b).sqrt() + (2.0 * a * t + b * b).sqrt()));
        worst.speed = worst.speed.max((v_mean - stable).abs() / stable);
        t += dt;
        worst.cycles += 1;
        assert!(worst.cycles < 10_000_000, "switch never completed");
    }
    worst
}

const RATIOS: [f64; 9] = [0.1, 0.2, 0.5, 0.9, 1.0, 1.1, 2.0, 5.0, 10.0];

#[test]
fn f64_model_matches_the_closed_forms_within_1e_6() {
    for ratio in RATIOS {
        let e = switch_errors::<f64>(1.41, 1.41 * ratio);
        eprintln!(
            "f64 ratio {ratio:>4}: Q {:.1e}, mean speed {:.1e}, t0 {:.1e} over {} cycles",
            e.q, e.speed, e.t0, e.cycles
        );
        assert!(e.cycles > 100);
        assert!(e.q < 1e-6, "ratio {ratio}: Q off by {:.2e}", e.q);
        assert!(
            e.speed < 1e-6,
            "ratio {ratio}: speed off by {:.2e}",
            e.speed
        );
        assert!(e.t0 < 1e-6, "ratio {ratio}: t0 off by {:.2e}", e.t0);
    }
}

#[test]
fn f32_model_matches_the_closed_forms_within_1e_4() {
    for ratio in RATIOS {
        let e = switch_errors::<f32>(1.41, 1.41 * ratio);
        eprintln!(
            "f32 ratio {ratio:>4}: Q {:.1e}, mean speed {:.1e}, t0 {:.1e} over {} cycles",
            e.q, e.speed, e.t0, e.cycles
        );
        assert!(e.q < 1e-4, "ratio {ratio}: Q off by {:.2e}", e.q);
        assert!(
            e.speed < 1e-4,
            "ratio {ratio}: speed off by {:.2e}",
            e.speed
        );
        assert!(e.t0 < 1e-4, "ratio {ratio}: t0 off by {:.2e}", e.t0);
    }
}

#[test]
fn the_unstable_textbook_form_loses_precision_in_f32_where_the_stable_one_does_not() {
    // Why the model uses 2 / (S (sqrt(..) + sqrt(..))): with a small a the difference of
    // square roots cancels catastrophically in f32.
    let (a, b, s, dt, t) = (1e-9f32, 0.1f32, 0.48f32, 1e-4f32, 0.05f32);
    let naive = ((2.0 * a * (t + dt) + b * b).sqrt() - (2.0 * a * t + b * b).sqrt()) / (a * s * dt);
    let stable = 2.0 / (s * ((2.0 * a * (t + dt) + b * b).sqrt() + (2.0 * a * t + b * b).sqrt()));
    let (a6, b6, s6, dt6, t6) = (a as f64, b as f64, s as f64, dt as f64, t as f64);
    let exact =
        2.0 / (s6 * ((2.0 * a6 * (t6 + dt6) + b6 * b6).sqrt() + (2.0 * a6 * t6 + b6 * b6).sqrt()));
    assert!(((stable as f64) - exact).abs() / exact < 1e-6);
    assert!(
        ((naive as f64) - exact).abs() / exact > 1e-2,
        "naive {naive} exact {exact}"
    );
}
