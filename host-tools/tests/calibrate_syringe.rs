//! `calibrate syringe`: steps per mm^3 from geometry and from a measured mass per step,
//! the line width formula, the lag (measured or default) and a fragment the core takes.

mod calibrate_common;

use calibrate_common::*;
use dollop_host::calibrate::lag::Weibull;
use dollop_host::calibrate::syringe::{
    calibrate, line_width, Options, DEFAULT_LAG_K, DEFAULT_LAG_N,
};
use dollop_host::calibrate::CalError;
use std::f64::consts::PI;

#[test]
fn steps_per_mm3_from_geometry() {
    // 10 mm bore, 1 mm lead, 200 x 16 microsteps, 3:1 gearing: 9600 steps/mm of plunger
    // over 78.54 mm^2.
    let cal = calibrate(&Options {
        diameter_mm: Some(10.0),
        lead_mm: Some(1.0),
        gear_ratio: 3.0,
        ..Options::default()
    })
    .unwrap();
    let want = 9600.0 / (PI * 25.0);
    assert!(
        rel(cal.steps_per_mm3, want) < 1e-12,
        "{}",
        cal.steps_per_mm3
    );
    assert!(!cal.lag_measured);
    assert_eq!((cal.lag.k, cal.lag.n), (DEFAULT_LAG_K, DEFAULT_LAG_N));
}

#[test]
fn a_measurement_wins_over_geometry_and_the_gap_is_explained() {
    let cal = calibrate(&Options {
        diameter_mm: Some(10.0),
        lead_mm: Some(1.0),
        mg_per_step: Some(0.025),
        density_g_ml: Some(1.1),
        ..Options::default()
    })
    .unwrap();
    // 0.025 mg at 1.1 mg/mm^3 is 0.02273 mm^3 per step; the geometry says 0.02454.
    assert!(rel(cal.steps_per_mm3, 1.1 / 0.025) < 1e-12);
    assert!(cal.geometric.is_some());
    assert!(
        cal.report()
            .contains("less paste per step than its geometry"),
        "{}",
        cal.report()
    );
}

#[test]
fn line_width_matches_its_cross_section() {
    // A bead of width a and area c pi a^2 / 4 laid at v carries Q = v c pi a^2 / 4.
    for (q, v, c) in [(4.8, 10.0, 1.0), (2.0, 5.0, 0.6), (12.0, 30.0, 0.8)] {
        let a = line_width(q, v, c);
        assert!(rel(v * c * PI * a * a / 4.0, q) < 1e-12);
    }
    // The config's bead (0.48 mm^2) at 10 mm/s as a round filament: a = sqrt(4 S / pi).
    let cal = calibrate(&Options {
        diameter_mm: Some(10.0),
        lead_mm: Some(1.0),
        config: Some(
            dollop_host::calibrate::output::load_config(&root().join("configs/seed-paper.toml"))
                .unwrap(),
        ),
        ..Options::default()
    })
    .unwrap();
    let line = cal.line.unwrap();
    assert!(rel(line.width_mm, (4.0 * 0.48 / PI).sqrt()) < 1e-6);
    assert!(
        cal.report()
            .contains("steps/s of the 40000 the core allows (max_step_rate_hz 50000 less one step per control cycle at rate_hz 10000)"),
        "{}",
        cal.report()
    );
}

#[test]
fn the_fragment_carries_a_measured_lag_and_validates() {
    let cal = calibrate(&Options {
        diameter_mm: Some(14.5),
        lead_mm: Some(2.0),
        lag: Some(Weibull {
            m_inf: 0.5,
            k: 3.1,
            n: 1.3,
        }),
        ..Options::default()
    })
    .unwrap();
    assert!(cal.lag_measured);
    let (config, machine) = merge_into_seed_all(&cal.fragment()).unwrap();
    let s = config.inlets[1].syringe.unwrap();
    assert!(rel(s.steps_per_mm3 as f64, cal.steps_per_mm3) < 1e-5);
    assert_eq!((s.lag_k, s.lag_n), (3.1, 1.3));
    assert!(machine.syringes);
}

#[test]
fn the_command_fits_the_lag_file_itself() {
    let out = run(&[
        "syringe",
        "--diameter",
        "14.5",
        "--lead",
        "2",
        "--lag",
        data().join("lag-syringe.csv").to_str().unwrap(),
    ])
    .unwrap();
    assert!(
        out.contains("lag: Weibull k = 3.") && out.contains("(measured)"),
        "{out}"
    );
    let fragment = &out[out.find("fragment:\n").unwrap() + 10..];
    let (config, _) = merge_into_seed_all(fragment).unwrap();
    let s = config.inlets[0].syringe.unwrap();
    assert!(rel(s.lag_n as f64, 1.3) < 0.05, "{s:?}");
}

#[test]
fn incomplete_or_impossible_options_are_argument_errors() {
    let cases = [
        Options {
            diameter_mm: Some(10.0),
            ..Options::default()
        },
        Options::default(),
        Options {
            mg_per_step: Some(0.1),
            ..Options::default()
        },
        Options {
            diameter_mm: Some(-10.0),
            lead_mm: Some(1.0),
            ..Options::default()
        },
        Options {
            diameter_mm: Some(10.0),
            lead_mm: Some(1.0),
            shape_c: 0.0,
            ..Options::default()
        },
        Options {
            diameter_mm: Some(0.01),
            lead_mm: Some(0.01),
            microsteps: 256.0,
            ..Options::default()
        },
    ];
    // The options as given (typed, for the front end to name), then a table the given
    // geometry makes that the core refuses.
    for (i, o) in cases.iter().enumerate() {
        let e = calibrate(o).unwrap_err();
        if i + 1 < cases.len() {
            assert!(matches!(e, CalError::Option(_)), "{e}");
        } else {
            assert!(matches!(e, CalError::Argument(_)), "{e}");
        }
    }
}
