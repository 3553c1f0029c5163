//! `calibrate lag`: fits the Weibull start-up curve `M(t) = M_inf (1 - exp(-k t^n))` to
//! cumulative mass after a valve opens or a syringe starts, reports `t_lag` (90 % of
//! `M_inf`), and maps the curve onto the core's models: for valves the dead time plus
//! first-order rise closest to it, for syringes the Weibull `lag_k`/`lag_n` themselves.
//!
//! The mapping: `F(t) = M(t) / M_inf` is read as the inlet's normalised step response.
//! The core's valve model responds to a step as `G(t) = 1 - exp(-(t - t_d) / tau)` after
//! the dead time `t_d` (the line pressure, and so a Newtonian flow, rises first-order), so
//! `t_d` and `tau` are the least-squares fit of `G` to `F` on 400 points from 0 to the time
//! `F` reaches 99.9 %. For `n = 1` this is exact: `t_d = 0`, `tau = 1/k`.

use super::fit::{self, Estimate, Fit, FitOptions, Model, Param, Scale, Space};
use super::format::{estimate, sig, toml_float};
use super::output::StagedFiles;
use super::plot::{self, Mark, Panel, Series};
use super::table::{Bound, Limits, Table};
use super::CalError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Unit of the time column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TimeUnit {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
}

/// Which kind of inlet the curve was measured on (decides what the fragment holds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum InletKind {
    /// Pneumatic valve: `valve_open_delay_ms` and `pressure_rise_ms`.
    #[default]
    Valve,
    /// Stepper syringe: `syringe = { steps_per_mm3, lag_k, lag_n }`.
    Syringe,
}

/// Options of `calibrate lag`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// Unit of the time column; `None` reads it from the header (default seconds).
    pub time_unit: Option<TimeUnit>,
    /// What the fragment is for.
    pub inlet: InletKind,
    /// The syringe's steps per mm^3 (for a complete `syringe` table).
    pub steps_per_mm3: Option<f64>,
    /// Optimizer budget.
    pub fit: FitOptions,
    /// How much of the CSV is read.
    pub limits: Limits,
}

/// The core's valve model fitted to the Weibull curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeadTimeRise {
    /// Dead time, s.
    pub dead_s: f64,
    /// First-order time constant, s.
    pub rise_s: f64,
    /// RMS difference between the two normalised curves.
    pub rms: f64,
    /// Largest difference between them.
    pub max_dev: f64,
    /// Time the first-order curve reaches 90 %, s.
    pub t90_s: f64,
}

/// The Weibull fit's parameters, with `t` in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weibull {
    /// Final mass (data units).
    pub m_inf: f64,
    /// Rate, s^-n.
    pub k: f64,
    /// Shape.
    pub n: f64,
}

impl Weibull {
    /// Normalised curve `1 - exp(-k t^n)`.
    pub fn fraction(&self, t: f64) -> f64 {
        if t <= 0.0 {
            0.0
        } else {
            1.0 - (-self.k * t.powf(self.n)).exp()
        }
    }
    /// Time to reach fraction `f` (0 < f < 1), s.
    pub fn time_to(&self, f: f64) -> f64 {
        (-(1.0 - f).ln() / self.k).powf(1.0 / self.n)
    }
    /// `t_lag = (ln 0.1 / -k)^(1/n)`: the time to 90 % of `M_inf`, s.
    pub fn t_lag(&self) -> f64 {
        (0.1f64.ln() / -self.k).powf(1.0 / self.n)
    }
}

/// The result of `calibrate lag`.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The data file.
    pub path: PathBuf,
    /// Time unit of the file.
    pub unit: TimeUnit,
    /// Times, s.
    pub t_s: Vec<f64>,
    /// Cumulative masses (data units).
    pub m: Vec<f64>,
    /// The Weibull fit.
    pub fit: Fit,
    /// Its parameters.
    pub weibull: Weibull,
    /// The valve model closest to it.
    pub valve: DeadTimeRise,
    /// Options used.
    pub options: Options,
    /// Verdicts.
    pub verdicts: Vec<String>,
}

fn weibull_model(start: [f64; 3]) -> Model {
    let p = |name, unit, start| Param {
        name,
        unit,
        scale: Scale::Log,
        start,
    };
    Model {
        name: "Weibull".into(),
        params: vec![
            p("M_inf", "", start[0]),
            p("k", "s^-n", start[1]),
            p("n", "", start[2]),
        ],
        f: Arc::new(|t, p| {
            if t <= 0.0 {
                0.0
            } else {
                p[0] * (1.0 - (-p[1] * t.powf(p[2])).exp())
            }
        }),
        grad: Arc::new(|t, p, g| {
            if t <= 0.0 {
                g.fill(0.0);
                return;
            }
            let tn = t.powf(p[2]);
            let e = (-p[1] * tn).exp();
            g[0] = 1.0 - e;
            g[1] = p[0] * e * tn;
            g[2] = p[0] * e * p[1] * tn * t.ln();
        }),
    }
}

/// Starting values from the linearised curve `ln(-ln(1 - M/M_inf)) = ln k + n ln t`.
fn weibull_start(t: &[f64], m: &[f64], m_inf: f64) -> [f64; 3] {
    let (mut lx, mut ly) = (Vec::new(), Vec::new());
    for (&t, &m) in t.iter().zip(m) {
        let f = m / m_inf;
        if t > 0.0 && f > 0.02 && f < 0.98 {
            lx.push(t.ln());
            ly.push((-(1.0 - f).ln()).ln());
        }
    }
    match fit::line(&lx, &ly) {
        Some((a, b)) if b > 0.0 && a.is_finite() => [m_inf, a.exp(), b.clamp(0.2, 5.0)],
        _ => {
            let t_mid = t.iter().copied().fold(0.0, f64::max) / 3.0;
            [m_inf, 1.0 / t_mid.max(1e-6), 1.0]
        }
    }
}

fn step_model(fixed_dead: Option<f64>, start: (f64, f64)) -> Model {
    let tau = Param {
        name: "tau",
        unit: "s",
        scale: Scale::Log,
        start: start.1,
    };
    match fixed_dead {
        None => Model {
            name: "dead time + first order".into(),
            params: vec![
                Param {
                    name: "t_d",
                    unit: "s",
                    scale: Scale::Linear,
                    start: start.0,
                },
                tau,
            ],
            f: Arc::new(|t, p| {
                if t <= p[0] {
                    0.0
                } else {
                    1.0 - (-(t - p[0]) / p[1]).exp()
                }
            }),
            grad: Arc::new(|t, p, g| {
                if t <= p[0] {
                    g.fill(0.0);
                } else {
                    let e = (-(t - p[0]) / p[1]).exp();
                    g[0] = -e / p[1];
                    g[1] = -e * (t - p[0]) / (p[1] * p[1]);
                }
            }),
        },
        Some(td) => Model {
            name: "first order".into(),
            params: vec![tau],
            f: Arc::new(move |t, p| {
                if t <= td {
                    0.0
                } else {
                    1.0 - (-(t - td) / p[0]).exp()
                }
            }),
            grad: Arc::new(move |t, p, g| {
                g[0] = if t <= td {
                    0.0
                } else {
                    -(-(t - td) / p[0]).exp() * (t - td) / (p[0] * p[0])
                };
            }),
        },
    }
}

/// The dead time + first-order step response closest to `w`'s normalised curve.
pub fn dead_time_rise(w: &Weibull) -> Option<DeadTimeRise> {
    let t_end = w.time_to(0.999);
    let t: Vec<f64> = plot::grid(0.0, t_end, 400, false);
    let f: Vec<f64> = t.iter().map(|&t| w.fraction(t)).collect();
    // Two-point start: 10 % and 90 % times of a first-order curve are ln(10/9) tau and
    // ln(10) tau after the dead time.
    let (t10, t90) = (w.time_to(0.1), w.time_to(0.9));
    let tau0 = ((t90 - t10) / 9f64.ln()).max(t_end * 1e-3);
    let td0 = (t10 - tau0 * (10.0f64 / 9.0).ln()).max(0.0);
    let opts = FitOptions::default();
    let free = fit::fit(&step_model(None, (td0, tau0)), &t, &f, Space::Linear, opts).ok();
    let (td, tau, fit) = match free {
        Some(fit) if fit.values()[0] >= 0.0 => (fit.values()[0], fit.values()[1], fit),
        // A negative dead time is not a valve: pin it at zero and fit tau alone.
        _ => {
            let fit = fit::fit(
                &step_model(Some(0.0), (0.0, tau0)),
                &t,
                &f,
                Space::Linear,
                opts,
            )
            .ok()?;
            (0.0, fit.values()[0], fit)
        }
    };
    let max_dev = fit.residuals.iter().fold(0.0f64, |a, r| a.max(r.abs()));
    Some(DeadTimeRise {
        dead_s: td,
        rise_s: tau,
        rms: fit.rms,
        max_dev,
        t90_s: td + tau * 10f64.ln(),
    })
}

/// Reads `path` and fits it.
pub fn calibrate(path: &Path, options: Options) -> Result<Calibration, CalError> {
    let table = Table::read(path, options.limits)?;
    calibrate_table(&table, options)
}

/// Fits an already-read table.
pub fn calibrate_table(table: &Table, options: Options) -> Result<Calibration, CalError> {
    table.require_rows(5)?;
    let unit = options
        .time_unit
        .unwrap_or_else(|| match table.header_of(0) {
            Some(h) if h.contains("ms") || h.contains("milli") => TimeUnit::Ms,
            _ => TimeUnit::S,
        });
    let scale = if unit == TimeUnit::Ms { 1e-3 } else { 1.0 };
    let t_s: Vec<f64> = table
        .numbers(0, Bound::NonNegative)?
        .into_iter()
        .map(|t| t * scale)
        .collect();
    let m = table.numbers(1, Bound::Finite)?;
    let fail = |reason: String| CalError::NoConvergence {
        path: table.path.clone(),
        model: "Weibull".into(),
        reason,
    };
    let m_max = m.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let t_max = t_s.iter().copied().fold(0.0, f64::max);
    if m_max <= 0.0 {
        return Err(fail("the mass never rises above zero".into()));
    }
    let mut best: Option<Fit> = None;
    let mut last = String::new();
    for factor in [1.0, 1.1, 1.5] {
        let start = weibull_start(&t_s, &m, m_max * factor);
        match fit::fit(&weibull_model(start), &t_s, &m, Space::Linear, options.fit) {
            Ok(f) if best.as_ref().is_none_or(|b| f.rss < b.rss) => best = Some(f),
            Ok(_) => {}
            Err(e) => last = e.0,
        }
    }
    let fit = best.ok_or_else(|| fail(last))?;
    let v = fit.values();
    let weibull = Weibull {
        m_inf: v[0],
        k: v[1],
        n: v[2],
    };
    // A curve that has not levelled off by the last sample lets M_inf run away.
    if weibull.m_inf > 2.0 * m_max || weibull.time_to(0.9) > 2.0 * t_max {
        return Err(fail(format!(
            "the mass has not levelled off by the last sample (t = {} s; the fit wants \
             M_inf = {}, {} times the largest mass): record until it stops rising",
            sig(t_max, 3),
            sig(weibull.m_inf, 3),
            sig(weibull.m_inf / m_max, 3)
        )));
    }
    let valve = dead_time_rise(&weibull)
        .ok_or_else(|| fail("no dead time + first-order curve fits the Weibull curve".into()))?;
    let mut cal = Calibration {
        path: table.path.clone(),
        unit,
        t_s,
        m,
        fit,
        weibull,
        valve,
        options,
        verdicts: Vec::new(),
    };
    cal.verdicts = verdicts(&cal);
    Ok(cal)
}

fn valve_ok(d: &DeadTimeRise) -> Result<(), String> {
    if d.dead_s * 1e3 > 2000.0 {
        Err("the dead time is above the 2000 ms the core accepts".into())
    } else if d.rise_s * 1e3 > 5000.0 {
        Err("the rise time is above the 5000 ms the core accepts".into())
    } else {
        Ok(())
    }
}

fn syringe_ok(w: &Weibull) -> Result<(), String> {
    if !(0.2..=5.0).contains(&w.n) {
        Err(format!(
            "lag_n {} is outside the 0.2 ..= 5 the core accepts",
            sig(w.n, 3)
        ))
    } else if w.k > 1e6 {
        Err(format!(
            "lag_k {} is above the 1e6 the core accepts",
            sig(w.k, 3)
        ))
    } else {
        Ok(())
    }
}

fn verdicts(cal: &Calibration) -> Vec<String> {
    let mut out = Vec::new();
    let w = &cal.weibull;
    let n = &cal.fit.estimates[2];
    out.push(format!(
        "t_lag = {} ms: the output reaches 90 % of M_inf that long after the start",
        sig(w.t_lag() * 1e3, 3)
    ));
    out.push(if n.excludes(1.0) && n.value > 1.0 {
        format!(
            "{}: S-shaped start (n > 1), a dead time before the rise",
            estimate(n)
        )
    } else if n.excludes(1.0) {
        format!("{}: fast start and a long tail (n < 1)", estimate(n))
    } else {
        format!("{}: includes 1, a plain first-order rise", estimate(n))
    });
    let d = &cal.valve;
    if cal.options.inlet == InletKind::Syringe {
        out.push(
            "syringe: the core compensates this Weibull lag itself (syringe.lag_k, lag_n), \
             starting the plunger early"
                .into(),
        );
        if let Err(e) = syringe_ok(w) {
            out.push(format!("syringe lag not written: {e}"));
        }
        return out;
    }
    out.push(format!(
        "valve model: dead time {} ms + first-order rise {} ms follows the Weibull curve within \
         {} % RMS ({} % at worst); its 90 % time is {} ms",
        sig(d.dead_s * 1e3, 3),
        sig(d.rise_s * 1e3, 3),
        sig(d.rms * 100.0, 2),
        sig(d.max_dev * 100.0, 2),
        sig(d.t90_s * 1e3, 3)
    ));
    if let Err(e) = valve_ok(d) {
        out.push(format!("valve keys not written: {e}"));
    }
    out
}

impl Calibration {
    /// The human-readable report.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "lag: {} points from {} (time {}, cumulative mass)",
            self.t_s.len(),
            self.path.display(),
            match self.unit {
                TimeUnit::S => "s",
                TimeUnit::Ms => "ms",
            }
        );
        let _ = writeln!(
            s,
            "Weibull M(t) = M_inf (1 - exp(-k t^n)), t in s, by Levenberg-Marquardt; 95 % confidence intervals"
        );
        let _ = writeln!(
            s,
            "  {}",
            self.fit
                .estimates
                .iter()
                .map(estimate)
                .collect::<Vec<_>>()
                .join(", ")
        );
        let _ = writeln!(
            s,
            "  RMS {} (mass units), R^2 {:.4}",
            sig(self.fit.rms, 3),
            self.fit.r2
        );
        if self.options.inlet == InletKind::Valve {
            let _ = writeln!(
                s,
                "mapping for valves: F(t) = M(t)/M_inf read as the step response; the core's dead \
                 time + first-order rise fitted to F on [0, t(99.9 %)]"
            );
        }
        for v in &self.verdicts {
            let _ = writeln!(s, "verdict: {v}");
        }
        s
    }

    /// Keys of one `[[inlet]]`.
    pub fn fragment(&self) -> Option<String> {
        let w = &self.weibull;
        let mut s = format!(
            "# dollop calibrate lag {}: Weibull k = {} s^-n, n = {}; t_lag = {} ms\n",
            self.path.display(),
            sig(w.k, 4),
            sig(w.n, 4),
            sig(w.t_lag() * 1e3, 3)
        );
        match self.options.inlet {
            InletKind::Valve => {
                valve_ok(&self.valve).ok()?;
                let _ = write!(
                    s,
                    "# Dead time + first-order rise closest to the curve. Apply to this valve's inlet:\n# dollop config --apply THIS.toml MACHINE.toml --inlet N\n\
                     valve_open_delay_ms = {}\npressure_rise_ms = {}\n",
                    toml_float(self.valve.dead_s * 1e3, 4),
                    toml_float(self.valve.rise_s * 1e3, 4)
                );
            }
            InletKind::Syringe => {
                syringe_ok(w).ok()?;
                match self.options.steps_per_mm3 {
                    Some(spm) => {
                        let _ = write!(
                            s,
                            "# Apply to this syringe's inlet: dollop config --apply THIS.toml MACHINE.toml --inlet N\n\
                             syringe = {{ steps_per_mm3 = {}, lag_k = {}, lag_n = {} }}\n",
                            toml_float(spm, 6),
                            toml_float(w.k, 5),
                            toml_float(w.n, 5)
                        );
                    }
                    None => {
                        let _ = write!(
                            s,
                            "# Syringe lag: lag_k = {}, lag_n = {}. Give --steps-per-mm3 (or run\n\
                             # `dollop calibrate syringe --lag {}`) for the whole syringe table.\n",
                            toml_float(w.k, 5),
                            toml_float(w.n, 5),
                            self.path.display()
                        );
                    }
                }
            }
        }
        Some(s)
    }

    /// Data, Weibull fit and the valve model over the mass residuals.
    pub fn plot(&self, path: &Path, out: &mut StagedFiles) -> Result<(), CalError> {
        let (scale, unit) = match self.unit {
            TimeUnit::S => (1.0, "s"),
            TimeUnit::Ms => (1e3, "ms"),
        };
        let t_end = self
            .t_s
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .max(self.weibull.time_to(0.99));
        let ts = plot::grid(0.0, t_end, 300, false);
        let w = self.weibull;
        let d = self.valve;
        let first_order = |t: f64| {
            if t <= d.dead_s {
                0.0
            } else {
                1.0 - (-(t - d.dead_s) / d.rise_s).exp()
            }
        };
        let mut top = Panel {
            title: format!(
                "start-up lag: Weibull k = {}, n = {}, t_lag = {} ms",
                sig(w.k, 3),
                sig(w.n, 3),
                sig(w.t_lag() * 1e3, 3)
            ),
            x_label: format!("time ({unit})"),
            y_label: "cumulative mass".into(),
            series: vec![
                Series {
                    label: "measured".into(),
                    points: self
                        .t_s
                        .iter()
                        .map(|t| t * scale)
                        .zip(self.m.iter().copied())
                        .collect(),
                    mark: Mark::Points,
                    color: 0,
                },
                Series {
                    label: "Weibull fit".into(),
                    points: ts
                        .iter()
                        .map(|&t| (t * scale, w.m_inf * w.fraction(t)))
                        .collect(),
                    mark: Mark::Line,
                    color: 1,
                },
                Series {
                    label: "t_lag (90 %)".into(),
                    points: vec![(w.t_lag() * scale, 0.0), (w.t_lag() * scale, w.m_inf)],
                    mark: Mark::Dashed,
                    color: 3,
                },
            ],
            ..Panel::default()
        };
        if self.options.inlet == InletKind::Valve {
            top.series.insert(
                2,
                Series {
                    label: format!(
                        "valve model: {} ms dead + {} ms rise",
                        sig(d.dead_s * 1e3, 3),
                        sig(d.rise_s * 1e3, 3)
                    ),
                    points: ts
                        .iter()
                        .map(|&t| (t * scale, w.m_inf * first_order(t)))
                        .collect(),
                    mark: Mark::Dashed,
                    color: 2,
                },
            );
        }
        let bottom = Panel {
            title: "residuals of the Weibull fit".into(),
            x_label: format!("time ({unit})"),
            y_label: "fit - measured".into(),
            series: vec![Series {
                label: "residual".into(),
                points: self
                    .t_s
                    .iter()
                    .map(|t| t * scale)
                    .zip(self.fit.residuals.iter().copied())
                    .collect(),
                mark: Mark::Points,
                color: 1,
            }],
            ..Panel::default()
        };
        plot::render(path, &[top, bottom], 900, 400, out)
    }

    /// The three Weibull estimates (M_inf, k, n).
    pub fn estimates(&self) -> &[Estimate] {
        &self.fit.estimates
    }
}
