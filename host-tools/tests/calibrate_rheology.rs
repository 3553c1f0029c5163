//! `calibrate rheology` against synthetic flow curves and sweeps from known parameters
//! with seeded noise: the fit recovers them, picks the right model, its confidence
//! intervals cover the truth about as often as they claim, and its fragments validate.

mod calibrate_common;

use calibrate_common::*;
use dollop::rheology::Rheology;
use dollop_host::calibrate::fit::FitOptions;
use dollop_host::calibrate::rheology::{calibrate, Kind, Options, Which};

fn flow_curve(
    dir: &std::path::Path,
    seed: u64,
    noise: f64,
    f: impl Fn(f64) -> f64,
) -> std::path::PathBuf {
    let mut r = rng(seed);
    let rows: Vec<(f64, f64)> = log_grid(0.3, 300.0, 16)
        .into_iter()
        .map(|g| (g, f(g) * (1.0 + noise * gauss(&mut r))))
        .collect();
    csv(
        dir,
        &format!("curve-{seed}.csv"),
        "shear_rate_1_s,shear_stress_pa",
        &rows,
    )
}

#[test]
fn power_law_is_recovered_and_chosen() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 1, 0.03, |g| 5.0 * g.powf(0.8));
    let cal = calibrate(&path, Options::default()).unwrap();
    assert_eq!(
        cal.fits[cal.best].which,
        Which::PowerLaw,
        "{}",
        cal.report()
    );
    let Some(Rheology::PowerLaw {
        consistency_pa_sn: k,
        flow_index: n,
    }) = cal.rheology()
    else {
        panic!("{}", cal.report())
    };
    // 3 % noise on 16 points: K within 5 %, n within 0.02.
    assert!(rel(k as f64, 5.0) < 0.05, "K {k}");
    assert!((n as f64 - 0.8).abs() < 0.02, "n {n}");
    assert!(cal.report().contains("verdict: power law fits best"));
    // The fragment merges into the seed config and validates.
    let (config, _) = merge_into_seed(&cal.fragment().unwrap()).unwrap();
    let Rheology::PowerLaw {
        consistency_pa_sn: kf,
        flow_index: nf,
    } = config.inlets[0].rheology
    else {
        panic!("{:?}", config.inlets[0].rheology)
    };
    // The fragment keeps 5 significant digits.
    assert!(rel(kf as f64, k as f64) < 1e-4 && rel(nf as f64, n as f64) < 1e-4);
}

#[test]
fn confidence_intervals_cover_the_truth_about_95_percent_of_the_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut covered = [0usize; 2];
    let runs = 60;
    for seed in 0..runs {
        let path = flow_curve(dir.path(), 100 + seed, 0.05, |g| 5.0 * g.powf(0.8));
        let cal = calibrate(&path, Options::default()).unwrap();
        let pl = cal
            .fits
            .iter()
            .find(|m| m.which == Which::PowerLaw)
            .unwrap();
        for (i, truth) in [5.0, 0.8].into_iter().enumerate() {
            let e = &pl.fit.estimates[i];
            if !e.excludes(truth) {
                covered[i] += 1;
            }
        }
    }
    // Binomial(60, 0.95): 51 or more with probability > 99.8 %; far fewer means the
    // intervals are too narrow (a wrong covariance or quantile).
    for c in covered {
        assert!(c >= 51 && c <= runs as usize, "covered {c} of {runs}");
    }
}

#[test]
fn newtonian_data_choose_the_one_parameter_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 2, 0.02, |g| 2.0 * g);
    let cal = calibrate(&path, Options::default()).unwrap();
    assert_eq!(
        cal.fits[cal.best].which,
        Which::Newtonian,
        "{}",
        cal.report()
    );
    let Some(Rheology::Newtonian { viscosity_pa_s }) = cal.rheology() else {
        panic!()
    };
    assert!(rel(viscosity_pa_s as f64, 2.0) < 0.02);
    assert!(
        cal.report().contains("not told apart from Newtonian"),
        "{}",
        cal.report()
    );
    merge_into_seed(&cal.fragment().unwrap()).unwrap();
}

#[test]
fn yield_stress_is_recovered_and_significant() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 3, 0.02, |g| 6.0 + 4.0 * g.powf(0.8));
    let cal = calibrate(&path, Options::default()).unwrap();
    assert_eq!(
        cal.fits[cal.best].which,
        Which::HerschelBulkley,
        "{}",
        cal.report()
    );
    let Some(Rheology::HerschelBulkley {
        yield_stress_pa,
        consistency_pa_sn,
        flow_index,
    }) = cal.rheology()
    else {
        panic!()
    };
    assert!(rel(yield_stress_pa as f64, 6.0) < 0.10, "{yield_stress_pa}");
    assert!(
        rel(consistency_pa_sn as f64, 4.0) < 0.08,
        "{consistency_pa_sn}"
    );
    assert!((flow_index as f64 - 0.8).abs() < 0.03, "{flow_index}");
    assert!(cal.report().contains("yield stress is significant"));
    merge_into_seed(&cal.fragment().unwrap()).unwrap();
}

#[test]
fn power_law_data_make_the_yield_stress_not_significant() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 4, 0.03, |g| 12.0 * g.powf(0.6));
    let cal = calibrate(&path, Options::default()).unwrap();
    let r = cal.report();
    assert!(
        r.contains("yield stress is not significant") || r.contains("yield stress held at 0"),
        "{r}"
    );
    // Physics: a fitted yield stress is never negative, whatever the noise wants.
    for m in &cal.fits {
        if m.which == dollop_host::calibrate::rheology::Which::HerschelBulkley {
            assert!(m.fit.values()[0] >= 0.0, "{r}");
            assert!(m.fit.estimates[0].lo >= 0.0, "{r}");
        }
    }
}

#[test]
fn weak_gel_sweep_is_recovered_and_mapped_by_cox_merz() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = rng(5);
    let rows: Vec<(f64, f64)> = log_grid(0.1, 100.0, 16)
        .into_iter()
        .map(|w| (w, 5.0 * w.powf(1.0 / 1.25) * (1.0 + 0.02 * gauss(&mut r))))
        .collect();
    let path = csv(
        dir.path(),
        "sweep.csv",
        "angular_frequency_rad_s,g_star_pa",
        &rows,
    );
    let cal = calibrate(&path, Options::default()).unwrap();
    assert_eq!(cal.kind, Kind::Oscillatory);
    assert_eq!(cal.fits[cal.best].which, Which::WeakGel, "{}", cal.report());
    let wg = &cal.fits[cal.best].fit;
    assert!(rel(wg.estimates[0].value, 5.0) < 0.03);
    assert!(rel(wg.estimates[1].value, 1.25) < 0.03);
    let Some(Rheology::PowerLaw {
        consistency_pa_sn,
        flow_index,
    }) = cal.rheology()
    else {
        panic!()
    };
    assert!(rel(consistency_pa_sn as f64, 5.0) < 0.03);
    assert!((flow_index as f64 - 0.8).abs() < 0.02);
    assert!(cal.report().contains("Cox-Merz"));
    merge_into_seed(&cal.fragment().unwrap()).unwrap();
}

#[test]
fn shear_thickening_best_fit_falls_back_to_a_model_the_core_takes() {
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 6, 0.02, |g| 2.0 * g.powf(1.3));
    let cal = calibrate(&path, Options::default()).unwrap();
    assert_eq!(cal.fits[cal.best].which, Which::PowerLaw);
    assert!(cal
        .rheology()
        .is_some_and(|r| matches!(r, Rheology::Newtonian { .. })));
    assert!(
        cal.report().contains("the core cannot take"),
        "{}",
        cal.report()
    );
}

#[test]
fn a_model_that_does_not_converge_is_reported_and_the_others_still_fit() {
    // One evaluation per parameter: the Newtonian and power-law starts are already the
    // log-space optimum, Herschel-Bulkley needs iterations it does not get.
    let dir = tempfile::tempdir().unwrap();
    let path = flow_curve(dir.path(), 7, 0.03, |g| 5.0 * g.powf(0.8));
    let cal = calibrate(
        &path,
        Options {
            kind: None,
            fit: FitOptions { patience: 1 },
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        cal.skipped
            .iter()
            .any(|s| s.starts_with("Herschel-Bulkley: did not converge")),
        "{}",
        cal.report()
    );
    assert!(cal
        .report()
        .contains("(skipped) Herschel-Bulkley: did not converge"));
    assert_eq!(cal.fits[cal.best].which, Which::PowerLaw);
}
