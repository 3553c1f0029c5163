//! Nonlinear least squares for every calibration: a model is a curve `y = f(x; p)` with
//! named parameters; [`fit`] runs the `levenberg-marquardt` crate on it and returns the
//! estimates with 95 % confidence intervals from the Jacobian at the optimum
//! (`cov = s^2 (J^T J)^-1`, Student-t quantile), residual statistics and AICc;
//! [`select`] picks the model the data support. Which models exist is the callers' business.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use statrs::distribution::{ContinuousCDF, StudentsT};
use std::fmt;
use std::sync::Arc;

/// How a parameter is searched. Positive quantities are fitted as their logarithm, which
/// keeps them positive without bounds and gives intervals that cannot cross zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// Any real value.
    Linear,
    /// Strictly positive: fitted as `ln p`.
    Log,
}

/// One parameter of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    /// Short name as printed ("K", "n", "tau_y").
    pub name: &'static str,
    /// Unit as printed ("Pa s^n"), empty when dimensionless.
    pub unit: &'static str,
    /// Search scale.
    pub scale: Scale,
    /// Starting value (natural units); must be positive for `Scale::Log`.
    pub start: f64,
}

/// Where residuals are measured. Rheology spans decades, so its residuals are relative
/// (`ln f - ln y`); cumulative masses are absolute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// `f - y`.
    Linear,
    /// `ln f - ln y` (every `y` must be positive).
    Log,
}

/// The curve `f(x; p)`.
pub type CurveFn = Arc<dyn Fn(f64, &[f64]) -> f64 + Send + Sync>;
/// Its gradient with respect to the natural parameters, written into the slice.
pub type GradFn = Arc<dyn Fn(f64, &[f64], &mut [f64]) + Send + Sync>;

/// A model: name, parameters, curve and analytic gradient.
#[derive(Clone)]
pub struct Model {
    /// Name as printed ("power law").
    pub name: String,
    /// Parameters in order.
    pub params: Vec<Param>,
    /// The curve.
    pub f: CurveFn,
    /// Its gradient.
    pub grad: GradFn,
}

impl fmt::Debug for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Model")
            .field("name", &self.name)
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}

/// One fitted parameter with its 95 % confidence interval.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Name.
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Best value.
    pub value: f64,
    /// Lower end of the 95 % interval.
    pub lo: f64,
    /// Upper end of the 95 % interval.
    pub hi: f64,
}

impl Estimate {
    /// True when the interval excludes `v`.
    pub fn excludes(&self, v: f64) -> bool {
        v < self.lo || v > self.hi
    }
}

/// A converged fit.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The model fitted.
    pub model: Model,
    /// Estimates, in the model's parameter order.
    pub estimates: Vec<Estimate>,
    /// Points fitted.
    pub points: usize,
    /// Residual sum of squares (in the residual space).
    pub rss: f64,
    /// Root mean square residual (in the residual space; for `Space::Log` about the
    /// relative error).
    pub rms: f64,
    /// Coefficient of determination in the residual space.
    pub r2: f64,
    /// Akaike's information criterion corrected for small samples.
    pub aicc: f64,
    /// Residual of each point (`f - y` or `ln f - ln y`).
    pub residuals: Vec<f64>,
    /// Residual space.
    pub space: Space,
    /// Function evaluations the optimizer used.
    pub evaluations: usize,
}

impl Fit {
    /// Best parameter values in order.
    pub fn values(&self) -> Vec<f64> {
        self.estimates.iter().map(|e| e.value).collect()
    }
    /// The fitted curve at `x`.
    pub fn eval(&self, x: f64) -> f64 {
        (self.model.f)(x, &self.values())
    }
    /// The estimate called `name`.
    pub fn get(&self, name: &str) -> Option<&Estimate> {
        self.estimates.iter().find(|e| e.name == name)
    }
    /// Number of parameters.
    pub fn k(&self) -> usize {
        self.estimates.len()
    }
}

/// Why a fit failed; the caller adds the file and model name.
#[derive(Clone, Debug, PartialEq)]
pub struct FitFailure(pub String);

/// Optimizer budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Function evaluations allowed per parameter plus one (the crate's "patience").
    pub patience: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { patience: 200 }
    }
}

struct Problem<'a> {
    model: &'a Model,
    x: &'a [f64],
    y: &'a [f64],
    space: Space,
    u: DVector<f64>,
}

impl Problem<'_> {
    fn natural(&self, u: &DVector<f64>) -> Vec<f64> {
        self.model
            .params
            .iter()
            .zip(u.iter())
            .map(|(p, &u)| match p.scale {
                Scale::Linear => u,
                Scale::Log => u.exp(),
            })
            .collect()
    }
    fn residual(&self, f: f64, y: f64) -> f64 {
        match self.space {
            Space::Linear => f - y,
            // A model value at or below zero cannot be compared on a log scale: NaN makes
            // the optimizer reject the step that led there.
            Space::Log if f > 0.0 => f.ln() - y.ln(),
            Space::Log => f64::NAN,
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, u: &DVector<f64>) {
        self.u.copy_from(u);
    }
    fn params(&self) -> DVector<f64> {
        self.u.clone()
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        let p = self.natural(&self.u);
        Some(DVector::from_iterator(
            self.x.len(),
            self.x
                .iter()
                .zip(self.y)
                .map(|(&x, &y)| self.residual((self.model.f)(x, &p), y)),
        ))
    }
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let p = self.natural(&self.u);
        let k = p.len();
        let mut j = DMatrix::zeros(self.x.len(), k);
        let mut g = vec![0.0; k];
        for (i, &x) in self.x.iter().enumerate() {
            (self.model.grad)(x, &p, &mut g);
            let outer = match self.space {
                Space::Linear => 1.0,
                Space::Log => 1.0 / (self.model.f)(x, &p),
            };
            for c in 0..k {
                let chain = match self.model.params[c].scale {
                    Scale::Linear => 1.0,
                    Scale::Log => p[c],
                };
                j[(i, c)] = outer * g[c] * chain;
            }
        }
        Some(j)
    }
}

/// Two-sided 95 % Student-t quantile for `dof` degrees of freedom.
pub fn t95(dof: usize) -> f64 {
    match StudentsT::new(0.0, 1.0, dof.max(1) as f64) {
        Ok(t) => t.inverse_cdf(0.975),
        // Unreachable for dof >= 1; the normal quantile is the safe limit.
        Err(_) => 1.959_964,
    }
}

/// AICc for `points` residuals with sum of squares `rss` and `k` parameters.
pub fn aicc(points: usize, k: usize, rss: f64) -> f64 {
    let m = points as f64;
    let kf = k as f64;
    // A perfect fit (synthetic data without noise) would give ln 0.
    let rss = rss.max(m * 1e-300);
    m * (rss / m).ln() + 2.0 * kf + 2.0 * kf * (kf + 1.0) / (m - kf - 1.0).max(1e-9)
}

/// Fits `model` to `(x, y)`. Needs at least `k + 2` points (one degree of freedom for the
/// interval and one for AICc); the caller checks that and says so in its own words.
pub fn fit(
    model: &Model,
    x: &[f64],
    y: &[f64],
    space: Space,
    options: FitOptions,
) -> Result<Fit, FitFailure> {
    let k = model.params.len();
    let m = x.len();
    check_data(x, y, k)?;
    let problem = Problem {
        model,
        x,
        y,
        space,
        u: start(model)?,
    };
    let (problem, evaluations) = minimize(problem, options)?;
    let p = problem.natural(&problem.u);
    let (Some(r), Some(j)) = (problem.residuals(), problem.jacobian()) else {
        return Err(FitFailure("no residuals at the optimum".into()));
    };
    if p.iter().any(|v| !v.is_finite()) || r.iter().any(|v| !v.is_finite()) {
        return Err(FitFailure("a parameter ran off to infinity".into()));
    }
    check_bounds(model, &problem.u, &p)?;
    check_identifiable(&j)?;
    let rss = r.norm_squared();
    let dof = m - k;
    let s2 = rss / dof as f64;
    let jtj = j.transpose() * &j;
    let cov = jtj
        .try_inverse()
        .filter(|c| c.iter().all(|v| v.is_finite()))
        .ok_or_else(|| FitFailure("the parameters cannot be told apart from these data".into()))?;
    let estimates = estimates(model, &problem.u, &p, &cov, s2, t95(dof))?;
    Ok(Fit {
        model: model.clone(),
        estimates,
        points: m,
        rss,
        rms: (rss / m as f64).sqrt(),
        r2: r2(y, space, rss),
        aicc: aicc(m, k, rss),
        residuals: r.iter().copied().collect(),
        space,
        evaluations,
    })
}

/// Refuses data that cannot determine a curve of `k` parameters: too few points, a value
/// not finite, or no spread in x or in y.
fn check_data(x: &[f64], y: &[f64], k: usize) -> Result<(), FitFailure> {
    let m = x.len();
    if m != y.len() || m < k + 2 {
        return Err(FitFailure(format!(
            "{m} points for {k} parameters (need at least {})",
            k + 2
        )));
    }
    // Data that cannot determine any curve: refuse it rather than print a fit of it.
    let spread = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        (hi - lo, lo.abs().max(hi.abs()))
    };
    if x.iter().chain(y).any(|v| !v.is_finite() || v.abs() > 1e100) {
        return Err(FitFailure(
            "a value is not finite or beyond 1e100 (check the units)".into(),
        ));
    }
    let (dx, mx) = spread(x);
    if dx <= 1e-12 * mx {
        return Err(FitFailure(
            "every point has the same x: the curve is not identifiable".into(),
        ));
    }
    let (dy, my) = spread(y);
    if dy <= 1e-12 * my {
        return Err(FitFailure(
            "every measured value is the same (zero variance): nothing to fit".into(),
        ));
    }
    Ok(())
}

/// The search's starting point: each parameter's start on its scale.
fn start(model: &Model) -> Result<DVector<f64>, FitFailure> {
    let u0 = DVector::from_iterator(
        model.params.len(),
        model.params.iter().map(|p| match p.scale {
            Scale::Linear => p.start,
            Scale::Log => p.start.ln(),
        }),
    );
    if u0.iter().any(|v| !v.is_finite()) {
        return Err(FitFailure("no usable starting values".into()));
    }
    Ok(u0)
}

/// Runs Levenberg-Marquardt on `problem`: the problem at its optimum and the evaluations
/// it took, or why it found none.
fn minimize<'a>(
    problem: Problem<'a>,
    options: FitOptions,
) -> Result<(Problem<'a>, usize), FitFailure> {
    // The crate asserts a patience above zero.
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(options.patience.max(1))
        .minimize(problem);
    match report.termination {
        TerminationReason::Converged { .. }
        | TerminationReason::Orthogonal
        | TerminationReason::ResidualsZero
        | TerminationReason::NoImprovementPossible(_) => {}
        TerminationReason::LostPatience => {
            return Err(FitFailure(format!(
                "no optimum after {} evaluations",
                report.number_of_evaluations
            )))
        }
        other => return Err(FitFailure(format!("optimizer stopped: {other:?}"))),
    }
    Ok((problem, report.number_of_evaluations))
}

/// A parameter that ran many decades from its data-derived start has gone to a bound of
/// what the data can say (1.8e-39 ms is not a time constant). `u` is the optimum on the
/// search's scale, `p` in natural units.
fn check_bounds(model: &Model, u: &DVector<f64>, p: &[f64]) -> Result<(), FitFailure> {
    for (c, param) in model.params.iter().enumerate() {
        if param.scale == Scale::Log && (u[c] - param.start.ln()).abs() > 12.0 * 10f64.ln() {
            return Err(FitFailure(format!(
                "{} ran to a bound ({:.3e}, from a start of {:.3e}): the data do not determine it",
                param.name, p[c], param.start
            )));
        }
    }
    Ok(())
}

/// Refuses a singular (or nearly) Jacobian `j`, columns scaled to unit length: some
/// combination of parameters does not change the curve at these points.
fn check_identifiable(j: &DMatrix<f64>) -> Result<(), FitFailure> {
    let mut js = j.clone();
    for mut col in js.column_iter_mut() {
        let n = col.norm();
        if n > 0.0 && n.is_finite() {
            col /= n;
        }
    }
    let sv = js.singular_values();
    let (smin, smax) = sv
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    if smin.is_nan() || smin <= 1e-9 * smax {
        return Err(FitFailure(
            "the Jacobian is singular at the optimum: the parameters cannot be told apart \
             from these data"
                .into(),
        ));
    }
    Ok(())
}

/// Each parameter's value and 95 % interval (Student-t quantile `t`) from the covariance
/// `cov` scaled by the residual variance `s2`; `u` is the optimum on the search's scale,
/// `p` in natural units.
fn estimates(
    model: &Model,
    u: &DVector<f64>,
    p: &[f64],
    cov: &DMatrix<f64>,
    s2: f64,
    t: f64,
) -> Result<Vec<Estimate>, FitFailure> {
    let mut estimates = Vec::with_capacity(model.params.len());
    for (c, param) in model.params.iter().enumerate() {
        let var = cov[(c, c)] * s2;
        // NaN fails this test as well as a negative variance does.
        if var.is_nan() || var < 0.0 {
            return Err(FitFailure(format!("no variance for {}", param.name)));
        }
        let half = t * var.sqrt();
        let u = u[c];
        let (lo, hi) = match param.scale {
            Scale::Linear => (u - half, u + half),
            Scale::Log => ((u - half).exp(), (u + half).exp()),
        };
        // An infinite or NaN interval says nothing. (Zero width is left to a perfect fit
        // of varying data: constant data, the zero-width case, are refused above.)
        if !(lo.is_finite() && hi.is_finite() && p[c].is_finite() && hi >= lo) {
            return Err(FitFailure(format!(
                "no usable interval for {} ({:.3e} .. {:.3e}): the data do not determine it",
                param.name, lo, hi
            )));
        }
        estimates.push(Estimate {
            name: param.name,
            unit: param.unit,
            value: p[c],
            lo,
            hi,
        });
    }
    Ok(estimates)
}

/// R^2 of a fit with residual sum of squares `rss` to `y`, in `space`.
fn r2(y: &[f64], space: Space, rss: f64) -> f64 {
    let ty: Vec<f64> = y
        .iter()
        .map(|&v| match space {
            Space::Linear => v,
            Space::Log => v.ln(),
        })
        .collect();
    let mean = ty.iter().sum::<f64>() / y.len() as f64;
    let tss: f64 = ty.iter().map(|v| (v - mean).powi(2)).sum();
    if tss > 0.0 {
        1.0 - rss / tss
    } else {
        1.0
    }
}

/// AICc difference under which two models count as equally supported.
pub const AICC_TIE: f64 = 2.0;

/// Index of the model the data support: the lowest AICc, except that a model with fewer
/// parameters within [`AICC_TIE`] of it wins (the extra parameters are not earning their
/// keep). `None` when `fits` is empty.
pub fn select(fits: &[Fit]) -> Option<usize> {
    let best = fits
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.aicc.total_cmp(&b.1.aicc))?
        .0;
    let floor = fits[best].aicc;
    fits.iter()
        .enumerate()
        .filter(|(_, f)| f.aicc <= floor + AICC_TIE)
        .min_by(|a, b| a.1.k().cmp(&b.1.k()).then(a.1.aicc.total_cmp(&b.1.aicc)))
        .map(|(i, _)| i)
}

/// Ordinary least-squares line `y = a + b x`; starting values for the nonlinear fits.
/// `None` when fewer than two distinct x.
pub fn line(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = x.len().min(y.len());
    if n < 2 {
        return None;
    }
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let sxx: f64 = x[..n].iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x[..n]
        .iter()
        .zip(&y[..n])
        .map(|(a, b)| (a - mx) * (b - my))
        .sum();
    if sxx <= 0.0 || !sxx.is_finite() {
        return None;
    }
    let b = sxy / sxx;
    Some((my - b * mx, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3 e^(0.7 x) on 20 points with a deterministic 0.1 % wiggle, so the residuals are
    /// not zero.
    fn wiggly_exp() -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y = x
            .iter()
            .enumerate()
            .map(|(i, &x)| 3.0 * (0.7 * x).exp() * (1.0 + 0.001 * ((i * 7 % 5) as f64 - 2.0)))
            .collect();
        (x, y)
    }

    fn exp_model() -> Model {
        Model {
            name: "exp".into(),
            params: vec![
                Param {
                    name: "a",
                    unit: "",
                    scale: Scale::Log,
                    start: 1.0,
                },
                Param {
                    name: "b",
                    unit: "",
                    scale: Scale::Linear,
                    start: 0.1,
                },
            ],
            f: Arc::new(|x, p| p[0] * (p[1] * x).exp()),
            grad: Arc::new(|x, p, g| {
                g[0] = (p[1] * x).exp();
                g[1] = p[0] * x * (p[1] * x).exp();
            }),
        }
    }

    #[test]
    fn recovers_an_exact_curve_and_its_interval_is_tight() {
        let (x, y) = wiggly_exp();
        for space in [Space::Linear, Space::Log] {
            let f = fit(&exp_model(), &x, &y, space, FitOptions::default()).unwrap();
            let a = f.get("a").unwrap();
            let b = f.get("b").unwrap();
            assert!((a.value - 3.0).abs() < 0.01, "{a:?}");
            assert!((b.value - 0.7).abs() < 0.01, "{b:?}");
            assert!(a.lo < a.value && a.value < a.hi && a.hi - a.lo < 0.05);
            assert!(f.r2 > 0.999);
        }
    }

    #[test]
    fn too_small_a_budget_is_a_failure_not_a_wrong_answer() {
        let x: Vec<f64> = (0..20).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|&x| 1e3 * (0.3 * x).exp()).collect();
        let e = fit(
            &exp_model(),
            &x,
            &y,
            Space::Linear,
            FitOptions { patience: 1 },
        )
        .unwrap_err();
        assert!(e.0.contains("evaluations"), "{e:?}");
    }

    #[test]
    fn aicc_tie_prefers_the_simpler_model() {
        let mk = |k: usize, aicc: f64| Fit {
            model: exp_model(),
            estimates: vec![
                Estimate {
                    name: "p",
                    unit: "",
                    value: 1.0,
                    lo: 0.0,
                    hi: 2.0
                };
                k
            ],
            points: 10,
            rss: 1.0,
            rms: 1.0,
            r2: 0.9,
            aicc,
            residuals: vec![],
            space: Space::Log,
            evaluations: 1,
        };
        assert_eq!(select(&[mk(1, -10.0), mk(2, -11.5), mk(3, -11.0)]), Some(0));
        assert_eq!(select(&[mk(1, -10.0), mk(2, -13.0), mk(3, -12.0)]), Some(1));
        assert_eq!(select(&[]), None);
    }

    #[test]
    fn t_quantile_matches_tables() {
        assert!((t95(1) - 12.706).abs() < 1e-3);
        assert!((t95(10) - 2.228).abs() < 1e-3);
    }

    #[test]
    fn data_that_cannot_determine_a_fit_are_refused_with_the_reason() {
        let x: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let flat = vec![2.5; 10];
        let e = fit(
            &exp_model(),
            &x,
            &flat,
            Space::Linear,
            FitOptions::default(),
        )
        .unwrap_err();
        assert!(e.0.contains("zero variance"), "{e:?}");
        let same_x = vec![1.0; 10];
        let y: Vec<f64> = (0..10).map(|i| 1.0 + i as f64).collect();
        let e = fit(
            &exp_model(),
            &same_x,
            &y,
            Space::Linear,
            FitOptions::default(),
        )
        .unwrap_err();
        assert!(e.0.contains("same x"), "{e:?}");
        let huge: Vec<f64> = (0..10).map(|i| 1e300 * (1.0 + i as f64)).collect();
        let e = fit(
            &exp_model(),
            &x,
            &huge,
            Space::Linear,
            FitOptions::default(),
        )
        .unwrap_err();
        assert!(e.0.contains("1e100"), "{e:?}");
    }

    #[test]
    fn a_parameter_the_curve_does_not_depend_on_is_refused() {
        // y = a exp(b x) + 0 c: c is not identifiable whatever the data.
        let mut m = exp_model();
        m.params.push(Param {
            name: "c",
            unit: "",
            scale: Scale::Linear,
            start: 1.0,
        });
        let g = m.grad.clone();
        m.grad = Arc::new(move |x, p, out| {
            g(x, p, &mut out[..2]);
            out[2] = 0.0;
        });
        let (x, y) = wiggly_exp();
        let e = fit(&m, &x, &y, Space::Linear, FitOptions::default()).unwrap_err();
        assert!(
            e.0.contains("singular") || e.0.contains("told apart"),
            "{e:?}"
        );
    }
}
