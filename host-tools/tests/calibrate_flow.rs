//! `calibrate flow` against synthetic pressure-flow data generated through the core's
//! own channel law (`dollop::rheology::FlowLaw`) for known materials: the effective
//! rheology comes back, the pressure for the bead equals the core's "auto" pressure for
//! it, units convert, and the fragment validates in the seed config.

mod calibrate_common;

use calibrate_common::*;
use dollop::config::Pressure;
use dollop::rheology::{FlowLaw, Rheology};
use dollop_host::calibrate::flow::{calibrate, Options, RateUnit, Which};
use dollop_host::calibrate::output::load_config;
use dollop_host::calibrate::CalError;
use std::fmt::Write as _;

/// Flow (mm^3/s) at pressure `p_pa` through the seed channel (d 0.8, L 2.4) full of `r`.
fn q_of(r: &Rheology, p_pa: f64) -> f64 {
    let law: FlowLaw<f64> = FlowLaw::new(r, 0.8);
    let v_s = std::f64::consts::PI * 0.8 * 0.8 / 4.0 * 2.4;
    ((p_pa / v_s - law.b) / law.a).powf(1.0 / law.n)
}

fn table(materials: &[(&str, Rheology)], seed: u64, unit_factor: f64, header: &str) -> String {
    let mut r = rng(seed);
    let mut s = format!("pressure_kpa,{header},material\n");
    for (name, rh) in materials {
        for p in log_grid(0.8, 12.0, 8) {
            let q = q_of(rh, p * 1e3) * (1.0 + 0.02 * gauss(&mut r));
            let _ = writeln!(s, "{p},{},{name}", q * unit_factor);
        }
    }
    s
}

fn seed_options() -> Options {
    Options {
        config: Some(load_config(&root().join("configs/seed-paper.toml")).unwrap()),
        ..Default::default()
    }
}

#[test]
fn effective_rheology_and_bead_pressure_are_recovered() {
    let dir = tempfile::tempdir().unwrap();
    let puree = Rheology::PowerLaw {
        consistency_pa_sn: 6.0,
        flow_index: 0.75,
    };
    let custard = Rheology::Newtonian {
        viscosity_pa_s: 1.6,
    };
    let path = write(
        dir.path(),
        "flow.csv",
        &table(
            &[("puree", puree), ("custard", custard)],
            1,
            1.0,
            "flow_mm3_s",
        ),
    );
    let cal = calibrate(&path, &seed_options()).unwrap();
    assert_eq!(cal.unit, RateUnit::Mm3PerS);
    assert_eq!(cal.materials.len(), 2);
    let (p, c) = (&cal.materials[0], &cal.materials[1]);
    assert_eq!(p.fits[p.best].0, Which::PowerLaw, "{}", cal.report());
    assert_eq!(c.fits[c.best].0, Which::Newtonian, "{}", cal.report());
    // 2 % noise on 8 points: K within 4 %, n within 0.02, viscosity within 2 %.
    let Ok(Rheology::PowerLaw {
        consistency_pa_sn: k,
        flow_index: n,
    }) = p.in_channel.as_ref().unwrap().rheology
    else {
        panic!("{}", cal.report())
    };
    assert!(rel(k as f64, 6.0) < 0.04, "K {k}");
    assert!((n as f64 - 0.75).abs() < 0.02, "n {n}");
    let Ok(Rheology::Newtonian { viscosity_pa_s: mu }) = c.in_channel.as_ref().unwrap().rheology
    else {
        panic!()
    };
    assert!(rel(mu as f64, 1.6) < 0.02, "mu {mu}");

    // The pressure written is the one the core's "auto" gives for the written rheology:
    // the core and the calibration agree on the channel law.
    let fragment = cal.fragment().unwrap();
    let (config, machine) = merge_into_seed(&fragment).unwrap();
    for i in 0..2 {
        let Pressure::Kpa(written) = config.inlets[i].pressure_kpa else {
            panic!()
        };
        let auto = merge_into_seed(&fragment.replace(
            &format!("pressure_kpa = {}", toml_number(&fragment, i)),
            "pressure_kpa = \"auto\"",
        ))
        .unwrap()
        .1
        .inlets[i]
            .supply_pa;
        assert!(
            rel(written as f64 * 1e3, auto) < 1e-4,
            "{written} kPa vs auto {auto} Pa"
        );
        assert!(rel(machine.inlets[i].supply_pa, auto) < 1e-4);
    }
    assert_eq!(config.inlets[0].material.as_str(), "puree");
}

/// The text of the `i`-th `pressure_kpa = ...` value in `fragment`.
fn toml_number(fragment: &str, i: usize) -> String {
    fragment
        .lines()
        .filter_map(|l| l.strip_prefix("pressure_kpa = "))
        .nth(i)
        .unwrap()
        .to_string()
}

#[test]
fn mass_flows_convert_with_the_density() {
    let dir = tempfile::tempdir().unwrap();
    let custard = Rheology::Newtonian {
        viscosity_pa_s: 2.0,
    };
    // g/min at 1.2 g/ml: mm^3/s * 1.2e-3 g/mm^3 * 60 s/min.
    let path = write(
        dir.path(),
        "flow.csv",
        &table(&[("custard", custard)], 2, 1.2e-3 * 60.0, "mass_g_per_min"),
    );
    let mut o = seed_options();
    let e = calibrate(&path, &o).unwrap_err();
    assert!(matches!(e, CalError::NeedsDensity { .. }), "{e}");
    o.density_g_ml = Some(1.2);
    let cal = calibrate(&path, &o).unwrap();
    assert_eq!(cal.unit, RateUnit::GPerMin);
    let Ok(Rheology::Newtonian { viscosity_pa_s }) =
        cal.materials[0].in_channel.as_ref().unwrap().rheology
    else {
        panic!()
    };
    assert!(rel(viscosity_pa_s as f64, 2.0) < 0.02, "{viscosity_pa_s}");
}

#[test]
fn without_a_config_the_law_is_fitted_but_no_fragment_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let r = Rheology::Newtonian {
        viscosity_pa_s: 2.0,
    };
    let path = write(dir.path(), "f.csv", &table(&[("x", r)], 3, 1.0, "q_ul_s"));
    let cal = calibrate(&path, &Options::default()).unwrap();
    assert!(cal.fragment().is_none());
    // R = 128 mu L / (pi d^4).
    let want = 128.0 * 2.0 * 2.4 / (std::f64::consts::PI * 0.8f64.powi(4));
    let m = &cal.materials[0];
    assert!(rel(m.fits[m.best].1.estimates[0].value, want) < 0.02);
    let e = run(&[
        "flow",
        path.to_str().unwrap(),
        "--out",
        "/nonexistent/x.toml",
    ])
    .unwrap_err();
    assert!(e.to_string().contains("--config"), "{e}");
}

#[test]
fn a_material_with_too_few_rows_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "f.csv",
        "pressure_kpa,flow_mm3_s,material\n1,2,a\n2,4,a\n3,6,a\n1,1,b\n2,2,b\n",
    );
    let e = calibrate(&path, &Options::default()).unwrap_err();
    let text = e.to_string();
    assert!(text.contains("f.csv") && text.contains("\"b\""), "{text}");
}
