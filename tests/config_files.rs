//! The bundled example configs load and validate; bad files are refused with the field named.

use dollop::config::{Config, Pressure};
use dollop::Machine;

fn load(name: &str) -> Config {
    let path = format!("{}/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

#[test]
fn every_bundled_config_validates() {
    let dir = format!("{}/configs", env!("CARGO_MANIFEST_DIR"));
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let name = path.file_name().unwrap().to_str().unwrap().to_string();
            let c = load(&name);
            let m: Machine<f32, 4> = c.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
            eprintln!(
                "{name}: S = {} mm^2, v_flow_max = {:.2} mm/s, corner r = {:.3} mm, P = {:?} Pa",
                m.bead_area,
                m.v_flow_max,
                m.corner_radius,
                m.inlets.iter().map(|i| i.supply_pa).collect::<Vec<_>>()
            );
            n += 1;
        }
    }
    assert!(n >= 3);
}

#[test]
fn seed_paper_config_is_the_papers_printhead() {
    let c = load("seed-paper.toml");
    assert_eq!(c.channel.nozzle_diameter_mm, 0.8);
    assert_eq!(c.channel.channel_length_mm, 2.4);
    assert_eq!(c.inlets.len(), 2);
    assert_eq!(c.inlets[0].pressure_kpa, Pressure::Auto);
}

#[test]
fn postcard_round_trip_keeps_auto_pressure() {
    let c = load("seed-paper-valves.toml");
    let bytes = postcard::to_allocvec(&c).unwrap();
    let back: Config = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(back, c);
}

#[test]
fn bad_files_are_refused_with_the_field_named() {
    let good = std::fs::read_to_string(format!(
        "{}/configs/seed-paper.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    // Parse errors name the key.
    let typo = good.replace("nozzle_diameter_mm", "nozle_diameter_mm");
    let e = toml::from_str::<Config>(&typo).unwrap_err().to_string();
    assert!(e.contains("nozle_diameter_mm"), "{e}");
    let bad_pressure = good.replacen("pressure_kpa = \"auto\"", "pressure_kpa = \"high\"", 1);
    let e = toml::from_str::<Config>(&bad_pressure)
        .unwrap_err()
        .to_string();
    assert!(e.contains("auto"), "{e}");
    // Validation errors name the field.
    let zero = good.replace("nozzle_diameter_mm = 0.8", "nozzle_diameter_mm = 0.0");
    let e = toml::from_str::<Config>(&zero)
        .unwrap()
        .validate::<f32, 4>()
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("channel.nozzle_diameter_mm"), "{e}");
    let neg = good.replacen("pressure_kpa = \"auto\"", "pressure_kpa = -5", 1);
    let e = toml::from_str::<Config>(&neg)
        .unwrap()
        .validate::<f32, 4>()
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("inlet[0].pressure_kpa"), "{e}");
    let mut five = good.clone();
    for _ in 0..3 {
        five.push_str("\n[[inlet]]\nmaterial = \"x\"\nrheology = { newtonian = { viscosity_pa_s = 2.0 } }\npressure_kpa = 1.0\n");
    }
    let e = toml::from_str::<Config>(&five)
        .unwrap()
        .validate::<f32, 4>()
        .unwrap_err()
        .to_string();
    assert!(e.contains("at most 4"), "{e}");
}

/// A machine too soft for the flow's largest change is refused at `max_accel_mm_s2`, and
/// each remedy its message names is one: the soft machine with real valves at
/// 300 mm/s^2 (it named the valves' rise and decay times, which this machine already has).
#[test]
fn a_machine_too_soft_for_its_flow_is_told_what_would_do() {
    let mut soft = load("soft-real-valves.toml");
    soft.motion.max_accel_mm_s2 = [300.0, 300.0, 200.0];
    let e = soft.validate::<f32, 4>().unwrap_err().to_string();
    assert!(e.starts_with("motion.max_accel_mm_s2"), "{e}");
    for remedy in ["raise it", "pressure_kpa", "slower pressure_rise_ms"] {
        assert!(e.contains(remedy), "{e}");
    }
    let mut stiffer = soft.clone();
    stiffer.motion.max_accel_mm_s2 = [500.0, 500.0, 200.0];
    let mut lower = soft.clone();
    for i in lower.inlets.iter_mut() {
        if let Pressure::Kpa(p) = i.pressure_kpa {
            i.pressure_kpa = Pressure::Kpa(p * 0.6);
        }
    }
    let mut slower = soft.clone();
    for i in slower.inlets.iter_mut() {
        i.pressure_rise_ms = 60.0;
        i.pressure_decay_ms = 60.0;
    }
    for (what, c) in [("stiffer", stiffer), ("lower", lower), ("slower", slower)] {
        if let Err(e) = c.validate::<f32, 4>() {
            panic!("{what}: {e}");
        }
    }
}
