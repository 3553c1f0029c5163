//! `calibrate lag` against synthetic start-up curves: Weibull parameters and `t_lag` come
//! back from noisy Weibull data; the mapping to the core's dead time + first-order rise
//! is exact for n = 1 and recovers a true dead-time + first-order response; a curve that
//! never levels off is a typed error; both fragments validate in the seed config.

mod calibrate_common;

use calibrate_common::*;
use dollop_host::calibrate::lag::{calibrate, dead_time_rise, InletKind, Options, Weibull};
use dollop_host::calibrate::CalError;

fn weibull_csv(
    dir: &std::path::Path,
    w: Weibull,
    t_end_ms: f64,
    noise: f64,
    seed: u64,
) -> std::path::PathBuf {
    let mut r = rng(seed);
    let rows: Vec<(f64, f64)> = (0..=50)
        .map(|i| {
            let t_ms = t_end_ms * i as f64 / 50.0;
            (
                t_ms,
                w.m_inf * w.fraction(t_ms * 1e-3) + noise * gauss(&mut r),
            )
        })
        .collect();
    csv(dir, "lag.csv", "time_ms,mass_g", &rows)
}

#[test]
fn weibull_parameters_and_t_lag_are_recovered() {
    let dir = tempfile::tempdir().unwrap();
    // t_lag = 80 ms with n = 1.6.
    let n = 1.6;
    let truth = Weibull {
        m_inf: 0.3,
        k: 10f64.ln() / 0.08f64.powf(n),
        n,
    };
    let path = weibull_csv(dir.path(), truth, 250.0, 0.0015, 1);
    let cal = calibrate(&path, Options::default()).unwrap();
    let w = cal.weibull;
    // 1.5 mg noise on 0.3 g, 51 points: M_inf within 1 %, n within 5 %, t_lag within 3 %.
    assert!(rel(w.m_inf, 0.3) < 0.01, "{w:?}");
    assert!(rel(w.n, n) < 0.05, "{w:?}");
    assert!(rel(w.t_lag(), 0.08) < 0.03, "{}", w.t_lag());
    // The 95 % intervals hold the truth for this seed.
    let e = cal.estimates();
    assert!(!e[0].excludes(0.3) && !e[2].excludes(n), "{e:?}");
    assert!(cal.report().contains("t_lag = "));
}

#[test]
fn mapping_is_exact_for_a_first_order_curve() {
    // n = 1: F(t) = 1 - exp(-k t) is a first-order step response without dead time.
    let w = Weibull {
        m_inf: 1.0,
        k: 25.0,
        n: 1.0,
    };
    let d = dead_time_rise(&w).unwrap();
    assert!(d.dead_s < 1e-4, "{d:?}");
    assert!(rel(d.rise_s, 1.0 / 25.0) < 0.01, "{d:?}");
    assert!(d.rms < 1e-3, "{d:?}");
}

#[test]
fn a_true_dead_time_and_rise_come_back_through_the_weibull_fit() {
    // The core's own valve model: 15 ms dead time, then a 30 ms first-order rise.
    let (td, tau) = (0.015, 0.030);
    let dir = tempfile::tempdir().unwrap();
    let mut r = rng(2);
    let rows: Vec<(f64, f64)> = (0..=60)
        .map(|i| {
            let t = 0.004 * i as f64;
            let f = if t <= td {
                0.0
            } else {
                1.0 - (-(t - td) / tau).exp()
            };
            (t, 0.2 * f + 0.001 * gauss(&mut r))
        })
        .collect();
    let path = csv(dir.path(), "valve.csv", "time_s,mass_g", &rows);
    let cal = calibrate(&path, Options::default()).unwrap();
    let d = cal.valve;
    // The Weibull curve cannot have a sharp dead time, so the round trip is approximate:
    // dead time within 5 ms, rise within 20 %, the 90 % time within 5 %.
    assert!((d.dead_s - td).abs() < 0.005, "{d:?}\n{}", cal.report());
    assert!(rel(d.rise_s, tau) < 0.20, "{d:?}");
    let t90 = td + tau * 10f64.ln();
    assert!(rel(d.t90_s, t90) < 0.05, "{d:?} vs {t90}");
    // The Weibull curve itself rounds the corner and reaches 90 % earlier (75 ms here).
    assert!(rel(cal.weibull.t_lag(), t90) < 0.15, "{}", cal.report());

    let (config, machine) = merge_into_seed(&cal.fragment().unwrap()).unwrap();
    assert!(rel(config.inlets[0].valve_open_delay_ms as f64, d.dead_s * 1e3) < 1e-3);
    assert!(rel(config.inlets[0].pressure_rise_ms as f64, d.rise_s * 1e3) < 1e-3);
    assert!(rel(machine.inlets[0].rise_s, d.rise_s) < 1e-3);
}

#[test]
fn syringe_fragment_holds_the_weibull_lag_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    let truth = Weibull {
        m_inf: 0.5,
        k: 3.0,
        n: 1.3,
    };
    let path = weibull_csv(dir.path(), truth, 3000.0, 0.002, 3);
    let o = Options {
        inlet: InletKind::Syringe,
        steps_per_mm3: Some(40.0),
        ..Default::default()
    };
    let cal = calibrate(&path, o).unwrap();
    // The core takes syringes only on an all-syringe machine: every seed inlet gets it.
    let (config, machine) = merge_into_seed_all(&cal.fragment().unwrap()).unwrap();
    assert!(machine.syringes);
    let s = config.inlets[0].syringe.unwrap();
    assert_eq!(s.steps_per_mm3, 40.0);
    assert!(rel(s.lag_k as f64, 3.0) < 0.05, "{s:?}");
    assert!(rel(s.lag_n as f64, 1.3) < 0.05, "{s:?}");
    // Without the steps the lag is only a comment: the fragment still parses, and
    // `config --apply` says it sets nothing rather than writing an unchanged config.
    let cal = calibrate(
        &path,
        Options {
            steps_per_mm3: None,
            ..o
        },
    )
    .unwrap();
    let f = cal.fragment().unwrap();
    assert!(f.contains("# Syringe lag: lag_k = "), "{f}");
    toml::from_str::<toml::Table>(&f).unwrap();
    let e = merge_into_seed(&f).unwrap_err();
    assert!(e.contains("the fragment sets no key"), "{e}");
}

#[test]
fn a_curve_that_never_levels_off_does_not_converge() {
    // A valve held open: the mass grows linearly and M_inf has no finite estimate.
    let dir = tempfile::tempdir().unwrap();
    let mut r = rng(4);
    let rows: Vec<(f64, f64)> = (0..=40)
        .map(|i| (i as f64 * 10.0, 0.002 * i as f64 + 0.0005 * gauss(&mut r)))
        .collect();
    let path = csv(dir.path(), "ramp.csv", "time_ms,mass_g", &rows);
    let e = calibrate(&path, Options::default()).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, CalError::NoConvergence { .. }), "{text}");
    assert!(
        text.contains("ramp.csv") && text.contains("did not converge"),
        "{text}"
    );
}

#[test]
fn negative_times_are_refused_with_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = csv(
        dir.path(),
        "neg.csv",
        "time_s,mass_g",
        &[
            (0.0, 0.0),
            (0.1, 0.1),
            (-0.2, 0.2),
            (0.3, 0.25),
            (0.4, 0.26),
            (0.5, 0.27),
        ],
    );
    let e = calibrate(&path, Options::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("neg.csv: line 4, column 1 (time_s)"), "{e}");
}
