//! `calibrate rheology`: fits flow curves (shear stress against shear rate) or oscillatory
//! sweeps (|G*| against angular frequency) with Newtonian, power-law, Herschel-Bulkley and
//! weak-gel models, picks the one the data support by AICc, and turns it into the core's
//! `Rheology`. Reading the CSV columns and drawing are delegated to `table` and `plot`.

use super::fit::{self, Fit, FitOptions, Model, Param, Scale, Space};
use super::format::{estimate, log_rms, sig, toml_float};
use super::output::StagedFiles;
use super::plot::{self, Mark, Panel, Series};
use super::table::{Bound, Limits, Table};
use super::CalError;
use dollop::rheology::Rheology;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What the two columns hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// Rotational flow curve: shear rate (1/s), shear stress (Pa).
    Rotational,
    /// Oscillatory frequency sweep: angular frequency (rad/s), |G*| (Pa).
    Oscillatory,
}

/// The models fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// `tau = mu rate` (oscillatory: `|G*| = eta w`, a viscous liquid).
    Newtonian,
    /// `tau = K rate^n`.
    PowerLaw,
    /// `tau = tau_y + K rate^n` (oscillatory: plateau plus power).
    HerschelBulkley,
    /// `|G*| = A w^(1/z)` (Gabriele et al.'s weak gel), oscillatory only.
    WeakGel,
}

impl Which {
    /// Printed name.
    pub fn name(self) -> &'static str {
        match self {
            Which::Newtonian => "Newtonian",
            Which::PowerLaw => "power law",
            Which::HerschelBulkley => "Herschel-Bulkley",
            Which::WeakGel => "weak gel",
        }
    }

    fn model(self, kind: Kind, start: &[f64]) -> Model {
        let (stress, k_unit) = match kind {
            Kind::Rotational => ("tau_y", "Pa s^n"),
            Kind::Oscillatory => ("G0", "Pa s^n"),
        };
        let p = |name, unit, scale, start| Param {
            name,
            unit,
            scale,
            start,
        };
        match self {
            Which::Newtonian => Model {
                name: self.name().into(),
                params: vec![p("mu", "Pa s", Scale::Log, start[0])],
                f: Arc::new(|x, p| p[0] * x),
                grad: Arc::new(|x, _, g| g[0] = x),
            },
            Which::PowerLaw => Model {
                name: self.name().into(),
                params: vec![
                    p("K", k_unit, Scale::Log, start[0]),
                    p("n", "", Scale::Log, start[1]),
                ],
                f: Arc::new(|x, p| p[0] * x.powf(p[1])),
                grad: Arc::new(|x, p, g| {
                    let xn = x.powf(p[1]);
                    g[0] = xn;
                    g[1] = p[0] * xn * x.ln();
                }),
            },
            Which::HerschelBulkley => Model {
                name: self.name().into(),
                params: vec![
                    p(stress, "Pa", Scale::Linear, start[0]),
                    p("K", k_unit, Scale::Log, start[1]),
                    p("n", "", Scale::Log, start[2]),
                ],
                f: Arc::new(|x, p| p[0] + p[1] * x.powf(p[2])),
                grad: Arc::new(|x, p, g| {
                    let xn = x.powf(p[2]);
                    g[0] = 1.0;
                    g[1] = xn;
                    g[2] = p[1] * xn * x.ln();
                }),
            },
            Which::WeakGel => Model {
                name: self.name().into(),
                params: vec![
                    p("A", "Pa s^(1/z)", Scale::Log, start[0]),
                    p("z", "", Scale::Log, start[1]),
                ],
                f: Arc::new(|x, p| p[0] * x.powf(1.0 / p[1])),
                grad: Arc::new(|x, p, g| {
                    let v = x.powf(1.0 / p[1]);
                    g[0] = v;
                    g[1] = -p[0] * v * x.ln() / (p[1] * p[1]);
                }),
            },
        }
    }
}

/// One fitted model.
#[derive(Clone, Debug)]
pub struct ModelFit {
    /// Which model.
    pub which: Which,
    /// The fit.
    pub fit: Fit,
    /// The core's rheology for it, or why the core cannot take it.
    pub rheology: Result<Rheology, String>,
    /// Where the fit sits on a physical bound: the yield stress (or plateau) the data
    /// wanted, below zero, before it was held at zero.
    pub bounded: Option<f64>,
}

/// Options of `calibrate rheology`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// What the columns hold; `None` reads it from the header.
    pub kind: Option<Kind>,
    /// Optimizer budget.
    pub fit: FitOptions,
    /// How much of the CSV is read.
    pub limits: Limits,
}

/// The result of `calibrate rheology`.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The data file.
    pub path: PathBuf,
    /// What the data are.
    pub kind: Kind,
    /// How the kind was decided.
    pub kind_source: &'static str,
    /// Shear rate or angular frequency.
    pub x: Vec<f64>,
    /// Shear stress or |G*|.
    pub y: Vec<f64>,
    /// Converged fits in model order.
    pub fits: Vec<ModelFit>,
    /// Models not fitted or not converged, with the reason.
    pub skipped: Vec<String>,
    /// Index in `fits` of the model the data support.
    pub best: usize,
    /// Index in `fits` of the model written to the config (the best one the core accepts).
    pub chosen: Option<usize>,
    /// Verdict lines.
    pub verdicts: Vec<String>,
}

fn kind_from_header(t: &Table) -> Option<Kind> {
    let h = t.header_of(0)?;
    if ["freq", "omega", "angular", "rad"]
        .iter()
        .any(|w| h.contains(w))
    {
        Some(Kind::Oscillatory)
    } else if ["shear", "rate", "1/s"].iter().any(|w| h.contains(w)) {
        Some(Kind::Rotational)
    } else {
        None
    }
}

/// Starting values: the log-log line gives K and n; Herschel-Bulkley is tried from a few
/// yield stresses (fractions of the lowest stress) and the best run kept.
fn starts(which: Which, x: &[f64], y: &[f64]) -> Vec<Vec<f64>> {
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let (a, b) = fit::line(&lx, &ly).unwrap_or((ly[0], 1.0));
    let n0 = b.clamp(0.05, 2.0);
    let k0 = a.exp();
    match which {
        Which::Newtonian => {
            let mean = lx.iter().zip(&ly).map(|(x, y)| y - x).sum::<f64>() / lx.len() as f64;
            vec![vec![mean.exp()]]
        }
        Which::PowerLaw => vec![vec![k0, n0]],
        Which::WeakGel => vec![vec![k0, 1.0 / n0]],
        Which::HerschelBulkley => {
            let ymin = y.iter().copied().fold(f64::INFINITY, f64::min);
            [0.0, 0.3, 0.6, 0.9]
                .iter()
                .map(|f| {
                    let ty = f * ymin;
                    let ry: Vec<f64> = y.iter().map(|v| (v - ty).max(1e-12 * v).ln()).collect();
                    let (a, b) = fit::line(&lx, &ry).unwrap_or((a, n0));
                    vec![ty, a.exp(), b.clamp(0.05, 2.0)]
                })
                .collect()
        }
    }
}

/// Herschel-Bulkley with the yield stress held at 0 (the bound `free` crossed): K and n
/// refitted as a power law, the yield stress reported as 0 with the interval cut at 0,
/// and AICc still counting three parameters (the model's, not the bound's).
fn yield_at_zero(kind: Kind, free: &Fit, x: &[f64], y: &[f64], options: Options) -> Option<Fit> {
    let pl = starts(Which::PowerLaw, x, y)
        .into_iter()
        .filter_map(|start| {
            fit::fit(
                &Which::PowerLaw.model(kind, &start),
                x,
                y,
                Space::Log,
                options.fit,
            )
            .ok()
        })
        .min_by(|a, b| a.rss.total_cmp(&b.rss))?;
    let v = pl.values();
    let tau = &free.estimates[0];
    let mut estimates = vec![fit::Estimate {
        name: tau.name,
        unit: tau.unit,
        value: 0.0,
        lo: 0.0,
        hi: tau.hi.max(0.0),
    }];
    estimates.extend(pl.estimates.iter().cloned());
    Some(Fit {
        model: Which::HerschelBulkley.model(kind, &[0.0, v[0], v[1]]),
        estimates,
        aicc: fit::aicc(pl.points, 3, pl.rss),
        ..pl
    })
}

fn to_core(which: Which, f: &Fit) -> Result<Rheology, String> {
    let v = f.values();
    let n_ok = |n: f64| {
        if (0.1..=1.0).contains(&n) {
            Ok(())
        } else {
            Err(format!(
                "flow index {} is outside the 0.1 ..= 1 the core accepts",
                sig(n, 3)
            ))
        }
    };
    match which {
        Which::Newtonian => Ok(Rheology::Newtonian {
            viscosity_pa_s: v[0] as f32,
        }),
        Which::PowerLaw => {
            n_ok(v[1])?;
            Ok(Rheology::PowerLaw {
                consistency_pa_sn: v[0] as f32,
                flow_index: v[1] as f32,
            })
        }
        Which::WeakGel => {
            // Cox-Merz: |G*|(w) read as tau(rate = w), so K = A and n = 1/z.
            n_ok(1.0 / v[1])?;
            Ok(Rheology::PowerLaw {
                consistency_pa_sn: v[0] as f32,
                flow_index: (1.0 / v[1]) as f32,
            })
        }
        Which::HerschelBulkley => {
            if v[0] < 0.0 {
                return Err(format!(
                    "negative yield stress ({} Pa): the data have none",
                    sig(v[0], 3)
                ));
            }
            n_ok(v[2])?;
            Ok(Rheology::HerschelBulkley {
                yield_stress_pa: v[0] as f32,
                consistency_pa_sn: v[1] as f32,
                flow_index: v[2] as f32,
            })
        }
    }
}

/// Reads `path` and fits it.
pub fn calibrate(path: &Path, options: Options) -> Result<Calibration, CalError> {
    let table = Table::read(path, options.limits)?;
    calibrate_table(&table, options)
}

/// Fits an already-read table.
pub fn calibrate_table(table: &Table, options: Options) -> Result<Calibration, CalError> {
    table.require_rows(3)?;
    let (kind, kind_source) = match (options.kind, kind_from_header(table)) {
        (Some(k), _) => (k, "--kind"),
        (None, Some(k)) => (k, "the header"),
        (None, None) if table.header.is_none() => (Kind::Rotational, "default (no header)"),
        (None, None) => {
            return Err(CalError::KindUnclear {
                path: table.path.clone(),
                header: table.header_of(0).unwrap_or("").to_string(),
            })
        }
    };
    let x = table.numbers(0, Bound::Positive)?;
    let y = table.numbers(1, Bound::Positive)?;
    let models: &[Which] = match kind {
        Kind::Rotational => &[Which::Newtonian, Which::PowerLaw, Which::HerschelBulkley],
        Kind::Oscillatory => &[Which::Newtonian, Which::WeakGel, Which::HerschelBulkley],
    };
    let mut fits = Vec::new();
    let mut skipped = Vec::new();
    if kind == Kind::Rotational {
        skipped.push("weak gel: describes oscillatory sweeps; not fitted to a flow curve".into());
    }
    for &which in models {
        let k = match which {
            Which::Newtonian => 1,
            Which::HerschelBulkley => 3,
            _ => 2,
        };
        if x.len() < k + 2 {
            skipped.push(format!(
                "{}: needs at least {} points, the file has {}",
                which.name(),
                k + 2,
                x.len()
            ));
            continue;
        }
        let mut best: Option<Fit> = None;
        let mut last_err = String::new();
        for start in starts(which, &x, &y) {
            match fit::fit(&which.model(kind, &start), &x, &y, Space::Log, options.fit) {
                Ok(f) => {
                    if best.as_ref().is_none_or(|b| f.rss < b.rss) {
                        best = Some(f);
                    }
                }
                Err(e) => last_err = e.0,
            }
        }
        let (best, bounded) = match best {
            Some(f) if which == Which::HerschelBulkley && f.values()[0] < 0.0 => {
                // A yield stress cannot be negative: hold it at its bound, 0, where the
                // curve is the power law, and say what the data wanted.
                let wanted = f.values()[0];
                (yield_at_zero(kind, &f, &x, &y, options), Some(wanted))
            }
            // Held or not, a yield stress (or plateau) below 0 means nothing: its interval
            // stops at the bound.
            Some(mut f) if which == Which::HerschelBulkley => {
                f.estimates[0].lo = f.estimates[0].lo.max(0.0);
                (Some(f), None)
            }
            other => (other, None),
        };
        match best {
            Some(f) => fits.push(ModelFit {
                which,
                rheology: to_core(which, &f),
                fit: f,
                bounded,
            }),
            None => skipped.push(format!("{}: did not converge: {last_err}", which.name())),
        }
    }
    let plain: Vec<Fit> = fits.iter().map(|m| m.fit.clone()).collect();
    let Some(best) = fit::select(&plain) else {
        return Err(CalError::NoConvergence {
            path: table.path.clone(),
            model: "every".into(),
            reason: skipped.join("; "),
        });
    };
    let mut order: Vec<usize> = (0..fits.len()).collect();
    order.sort_by(|&a, &b| fits[a].fit.aicc.total_cmp(&fits[b].fit.aicc));
    let chosen = std::iter::once(best)
        .chain(order.iter().copied())
        .find(|&i| fits[i].rheology.is_ok());
    let mut cal = Calibration {
        path: table.path.clone(),
        kind,
        kind_source,
        x,
        y,
        fits,
        skipped,
        best,
        chosen,
        verdicts: Vec::new(),
    };
    cal.verdicts = verdicts(&cal);
    Ok(cal)
}

fn verdicts(cal: &Calibration) -> Vec<String> {
    let mut out = Vec::new();
    let best = &cal.fits[cal.best];
    let lowest = cal
        .fits
        .iter()
        .min_by(|a, b| a.fit.aicc.total_cmp(&b.fit.aicc))
        .map(|m| m.fit.aicc)
        .unwrap_or(best.fit.aicc);
    let mut rest: Vec<&ModelFit> = cal.fits.iter().filter(|m| m.which != best.which).collect();
    rest.sort_by(|a, b| a.fit.aicc.total_cmp(&b.fit.aicc));
    let others: Vec<String> = rest
        .iter()
        .map(|m| format!("{} {:+.1}", m.which.name(), m.fit.aicc - best.fit.aicc))
        .collect();
    let mut line = format!(
        "{} fits best (AICc {:.1}{}{})",
        best.which.name(),
        best.fit.aicc,
        if others.is_empty() {
            ""
        } else {
            "; others by dAICc: "
        },
        others.join(", ")
    );
    if best.fit.aicc > lowest + 1e-9 {
        let _ = write!(
            line,
            ": within {} of the lowest AICc with fewer parameters, so the simpler model is preferred",
            fit::AICC_TIE
        );
    }
    out.push(line);
    for m in &cal.fits {
        match m.which {
            Which::HerschelBulkley => {
                let e = &m.fit.estimates[0];
                let what = if cal.kind == Kind::Rotational {
                    "yield stress"
                } else {
                    "plateau modulus"
                };
                if let Some(wanted) = m.bounded {
                    out.push(format!(
                        "Herschel-Bulkley's {what} held at 0: the data want {} Pa, below the physical bound, i.e. no {what}; the fit with it at 0 is the power law",
                        sig(wanted, 3)
                    ));
                } else if e.excludes(0.0) && e.value > 0.0 {
                    out.push(format!(
                        "Herschel-Bulkley's {what} is significant: {}",
                        estimate(e)
                    ));
                } else {
                    out.push(format!(
                        "Herschel-Bulkley's {what} is not significant: {} includes 0",
                        estimate(e)
                    ));
                }
            }
            Which::PowerLaw => {
                let n = &m.fit.estimates[1];
                out.push(if n.excludes(1.0) && n.value < 1.0 {
                    format!("shear-thinning: power-law {} excludes 1", estimate(n))
                } else if n.excludes(1.0) {
                    format!("shear-thickening: power-law {} is above 1", estimate(n))
                } else {
                    format!(
                        "power-law {} includes 1: not told apart from Newtonian",
                        estimate(n)
                    )
                });
            }
            Which::WeakGel => {
                let z = &m.fit.estimates[1];
                out.push(format!(
                    "weak gel: {} (network extent; flow index n = 1/z = {}), mapped to the \
                     config by the Cox-Merz rule |eta*|(w) = eta(rate), which pastes with a \
                     yield stress often break: confirm with a rotational test",
                    estimate(z),
                    sig(1.0 / z.value, 3)
                ));
            }
            Which::Newtonian => {}
        }
    }
    match cal.chosen {
        Some(i) if i == cal.best => {}
        Some(i) => out.push(format!(
            "the core cannot take the {} fit ({}); the config gets the {} fit",
            best.which.name(),
            best.rheology.as_ref().err().map_or("", String::as_str),
            cal.fits[i].which.name()
        )),
        None => out.push("no fitted model is one the core accepts: no fragment".into()),
    }
    out
}

impl Calibration {
    /// The model written to the config.
    pub fn rheology(&self) -> Option<Rheology> {
        self.fits[self.chosen?].rheology.clone().ok()
    }

    /// The human-readable report.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let (xn, yn) = match self.kind {
            Kind::Rotational => ("shear rate 1/s", "shear stress Pa"),
            Kind::Oscillatory => ("angular frequency rad/s", "|G*| Pa"),
        };
        let (lo, hi) = self
            .x
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
        let _ = writeln!(
            s,
            "rheology: {} points from {} ({} test per {}: {xn} {} .. {}, {yn})",
            self.x.len(),
            self.path.display(),
            match self.kind {
                Kind::Rotational => "rotational",
                Kind::Oscillatory => "oscillatory",
            },
            self.kind_source,
            sig(lo, 3),
            sig(hi, 3)
        );
        let _ = writeln!(
            s,
            "fits by Levenberg-Marquardt on log residuals; 95 % confidence intervals from the Jacobian"
        );
        for m in &self.fits {
            let f = &m.fit;
            let _ = writeln!(
                s,
                "  {:<17} {}",
                m.which.name(),
                f.estimates
                    .iter()
                    .map(estimate)
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let _ = writeln!(
                s,
                "  {:<17} {}, R^2 {:.4} (log), AICc {:.1}",
                "",
                log_rms(f.rms),
                f.r2,
                f.aicc
            );
        }
        for k in &self.skipped {
            let _ = writeln!(s, "  (skipped) {k}");
        }
        let _ = writeln!(
            s,
            "selection: lowest AICc (Akaike's criterion, small-sample corrected); a model with \
             fewer parameters within {} of it is preferred",
            fit::AICC_TIE
        );
        for v in &self.verdicts {
            let _ = writeln!(s, "verdict: {v}");
        }
        s
    }

    /// The TOML fragment (keys of one `[[inlet]]`), or `None` when no model fits the core.
    pub fn fragment(&self) -> Option<String> {
        let r = self.rheology()?;
        let chosen = &self.fits[self.chosen?];
        let mut s = format!(
            "# dollop calibrate rheology {}: {}, {}, R^2 {:.4}\n\
             # Apply to the inlet of this material: dollop config --apply THIS.toml MACHINE.toml --inlet N\n",
            self.path.display(),
            chosen.which.name(),
            log_rms(chosen.fit.rms),
            chosen.fit.r2
        );
        let _ = writeln!(s, "rheology = {}", rheology_toml(&r));
        Some(s)
    }

    /// Data and fits (log-log) over relative residuals.
    pub fn plot(&self, path: &Path, out: &mut StagedFiles) -> Result<(), CalError> {
        let (xn, yn) = match self.kind {
            Kind::Rotational => ("shear rate (1/s)", "shear stress (Pa)"),
            Kind::Oscillatory => ("angular frequency (rad/s)", "|G*| (Pa)"),
        };
        let (lo, hi) = self
            .x
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
        let xs = plot::grid(lo, hi, 120, true);
        let mut top = Panel {
            title: format!(
                "{}: {} fits best",
                self.path
                    .file_name()
                    .map(|f| f.to_string_lossy().to_string())
                    .unwrap_or_default(),
                self.fits[self.best].which.name()
            ),
            x_label: xn.into(),
            y_label: yn.into(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                label: "measured".into(),
                points: self.x.iter().copied().zip(self.y.iter().copied()).collect(),
                mark: Mark::Points,
                color: 0,
            }],
            ..Panel::default()
        };
        let mut bottom = Panel {
            title: format!("residuals of the fits within {RESIDUAL_PANEL_AICC} AICc of the best"),
            x_label: xn.into(),
            y_label: "model / measured - 1 (%)".into(),
            log_x: true,
            ..Panel::default()
        };
        for (i, m) in self.fits.iter().enumerate() {
            let label = format!("{} (AICc {:.1})", m.which.name(), m.fit.aicc);
            top.series.push(Series {
                label: label.clone(),
                points: xs.iter().map(|&x| (x, m.fit.eval(x))).collect(),
                mark: if i == self.best {
                    Mark::Line
                } else {
                    Mark::Dashed
                },
                color: i + 1,
            });
            if m.fit.aicc > self.fits[self.best].fit.aicc + RESIDUAL_PANEL_AICC {
                continue;
            }
            bottom.series.push(Series {
                label: m.which.name().into(),
                points: self
                    .x
                    .iter()
                    .zip(&m.fit.residuals)
                    .map(|(&x, &r)| (x, 100.0 * (r.exp() - 1.0)))
                    .collect(),
                mark: Mark::Points,
                color: i + 1,
            });
        }
        plot::render(path, &[top, bottom], 900, 420, out)
    }
}

/// Fits this far behind the best are left out of the residual panel: their residuals
/// would set its scale and hide the ones that matter.
const RESIDUAL_PANEL_AICC: f64 = 10.0;

/// `{ power_law = { consistency_pa_sn = .., flow_index = .. } }`.
pub fn rheology_toml(r: &Rheology) -> String {
    let f = |v: f32| toml_float(v as f64, 5);
    match *r {
        Rheology::Newtonian { viscosity_pa_s } => {
            format!("{{ newtonian = {{ viscosity_pa_s = {} }} }}", f(viscosity_pa_s))
        }
        Rheology::PowerLaw {
            consistency_pa_sn,
            flow_index,
        } => format!(
            "{{ power_law = {{ consistency_pa_sn = {}, flow_index = {} }} }}",
            f(consistency_pa_sn),
            f(flow_index)
        ),
        Rheology::HerschelBulkley {
            yield_stress_pa,
            consistency_pa_sn,
            flow_index,
        } => format!(
            "{{ herschel_bulkley = {{ yield_stress_pa = {}, consistency_pa_sn = {}, flow_index = {} }} }}",
            f(yield_stress_pa),
            f(consistency_pa_sn),
            f(flow_index)
        ),
    }
}
