//! `calibrate flow`: fits measured flow against supply pressure (per material) with the
//! channel laws the core uses (`Q = P / R`, or `Q = (P / R)^(1/n)`), and, given the
//! machine config, turns the fit into the material's effective rheology in this channel
//! and the pressure that prints the configured bead. Plotting is delegated to `plot`.

use super::error::{CalError, CalOption, OptionError};
use super::fit::{self, Fit, FitOptions, Model, Param, Scale, Space};
use super::format::{estimate, log_rms, short, sig, toml_float, toml_string};
use super::output::StagedFiles;
use super::plot::{self, Mark, Panel, Series};
use super::rheology::rheology_toml;
use super::table::{Bound, Limits, Table};
use dollop::config::{Config, MATERIAL_NAME_LEN};
use dollop::rheology::Rheology;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Unit of the flow column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RateUnit {
    /// Cubic millimetres (microlitres) per second.
    #[value(name = "mm3/s", alias = "ul/s")]
    Mm3PerS,
    /// Millilitres per minute.
    #[value(name = "ml/min")]
    MlPerMin,
    /// Milligrams per second (needs the density).
    #[value(name = "mg/s")]
    MgPerS,
    /// Grams per second (needs the density).
    #[value(name = "g/s")]
    GPerS,
    /// Grams per minute (needs the density).
    #[value(name = "g/min")]
    GPerMin,
}

impl RateUnit {
    /// Printed name.
    pub fn name(self) -> &'static str {
        match self {
            RateUnit::Mm3PerS => "mm3/s",
            RateUnit::MlPerMin => "ml/min",
            RateUnit::MgPerS => "mg/s",
            RateUnit::GPerS => "g/s",
            RateUnit::GPerMin => "g/min",
        }
    }
    fn is_mass(self) -> bool {
        matches!(self, RateUnit::MgPerS | RateUnit::GPerS | RateUnit::GPerMin)
    }
    /// mm^3/s per unit (mass units: per g/ml of density).
    fn factor(self) -> f64 {
        match self {
            RateUnit::Mm3PerS => 1.0,
            RateUnit::MlPerMin => 1000.0 / 60.0,
            // 1 mg of paste of density rho g/ml is 1/rho mm^3.
            RateUnit::MgPerS => 1.0,
            RateUnit::GPerS => 1000.0,
            RateUnit::GPerMin => 1000.0 / 60.0,
        }
    }
    /// The unit a header names, as a pair of words: "flow_g_s", "rate (mm^3/s)",
    /// "mass_g_per_min" all work.
    fn from_header(h: &str) -> Option<RateUnit> {
        let h = h.replace('^', "");
        let words: Vec<&str> = h
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty() && *w != "per")
            .collect();
        words.windows(2).rev().find_map(|w| match (w[0], w[1]) {
            ("mm3" | "ul", "s") => Some(RateUnit::Mm3PerS),
            ("ml", "min") => Some(RateUnit::MlPerMin),
            ("mg", "s") => Some(RateUnit::MgPerS),
            ("g", "s") => Some(RateUnit::GPerS),
            ("g", "min") => Some(RateUnit::GPerMin),
            _ => None,
        })
    }
}

/// The two channel laws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// `Q = P / R`.
    Newtonian,
    /// `Q = (P / R)^(1/n)`, i.e. `P = R Q^n`.
    PowerLaw,
}

impl Which {
    /// Printed name.
    pub fn name(self) -> &'static str {
        match self {
            Which::Newtonian => "Newtonian (Q = P/R)",
            Which::PowerLaw => "power law (P = R Q^n)",
        }
    }
    fn model(self, r0: f64, n0: f64) -> Model {
        let p = |name, unit, start| Param {
            name,
            unit,
            scale: Scale::Log,
            start,
        };
        match self {
            Which::Newtonian => Model {
                name: self.name().into(),
                params: vec![p("R", "Pa s/mm^3", r0)],
                f: Arc::new(|x, p| x / p[0]),
                grad: Arc::new(|x, p, g| g[0] = -x / (p[0] * p[0])),
            },
            Which::PowerLaw => Model {
                name: self.name().into(),
                params: vec![p("R", "Pa (s/mm^3)^n", r0), p("n", "", n0)],
                f: Arc::new(|x, p| (x / p[0]).powf(1.0 / p[1])),
                grad: Arc::new(|x, p, g| {
                    let f = (x / p[0]).powf(1.0 / p[1]);
                    g[0] = -f / (p[1] * p[0]);
                    g[1] = -f * (x / p[0]).ln() / (p[1] * p[1]);
                }),
            },
        }
    }
}

/// Options of `calibrate flow`.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Unit of the flow column; `None` reads it from the header.
    pub unit: Option<RateUnit>,
    /// Paste density, g/ml (needed for mass units).
    pub density_g_ml: Option<f64>,
    /// Machine config: channel geometry, bead and print speed.
    pub config: Option<Config>,
    /// Print speed for the target pressure, mm/s (default: the config's).
    pub speed_mm_s: Option<f64>,
    /// Material name when the table has no material column (default: the file stem).
    pub material: Option<String>,
    /// Optimizer budget.
    pub fit: FitOptions,
    /// How much of the CSV is read.
    pub limits: Limits,
}

/// What the config turns a fit into.
#[derive(Clone, Debug, PartialEq)]
pub struct InChannel {
    /// The rheology that reproduces the fitted law in the config's channel.
    pub rheology: Result<Rheology, String>,
    /// Flow that prints the configured bead at the print speed, mm^3/s.
    pub q_target: f64,
    /// Pressure that gives it, kPa.
    pub pressure_kpa: f64,
    /// Apparent viscosity at the wall at that flow, Pa s.
    pub apparent_viscosity: f64,
}

/// One material's fits.
#[derive(Clone, Debug)]
pub struct Material {
    /// Name.
    pub name: String,
    /// Pressures, Pa.
    pub p_pa: Vec<f64>,
    /// Flows, mm^3/s.
    pub q: Vec<f64>,
    /// Converged fits.
    pub fits: Vec<(Which, Fit)>,
    /// Index of the supported model in `fits`.
    pub best: usize,
    /// Effective rheology and target pressure (with a config).
    pub in_channel: Option<InChannel>,
    /// Verdicts.
    pub verdicts: Vec<String>,
}

/// The result of `calibrate flow`.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The data file.
    pub path: PathBuf,
    /// Unit read.
    pub unit: RateUnit,
    /// Materials in file order.
    pub materials: Vec<Material>,
    /// Channel diameter and length, bead area and speed used (with a config).
    pub geometry: Option<(f64, f64, f64, f64)>,
}

/// Reads `path` and fits it.
pub fn calibrate(path: &Path, options: &Options) -> Result<Calibration, CalError> {
    let table = Table::read(path, options.limits)?;
    calibrate_table(&table, options)
}

/// Fits an already-read table.
pub fn calibrate_table(table: &Table, options: &Options) -> Result<Calibration, CalError> {
    table.require_rows(3)?;
    let unit = match (
        options.unit,
        table.header_of(1).and_then(RateUnit::from_header),
    ) {
        (Some(u), _) | (None, Some(u)) => u,
        (None, None) => {
            return Err(CalError::RateUnitUnclear {
                path: table.path.clone(),
            })
        }
    };
    let to_mm3 = if unit.is_mass() {
        match options.density_g_ml {
            Some(rho) if rho > 0.0 && rho.is_finite() => unit.factor() / rho,
            Some(rho) => {
                return Err(CalError::Option(OptionError::NotPositive {
                    option: CalOption::Density,
                    value: rho,
                }))
            }
            None => {
                return Err(CalError::NeedsDensity {
                    path: table.path.clone(),
                    unit: unit.name(),
                })
            }
        }
    } else {
        unit.factor()
    };
    let p_kpa = table.numbers(0, Bound::Positive)?;
    let rate = table.numbers(1, Bound::Positive)?;
    let names: Vec<String> = if table.columns() >= 3 {
        table.texts(2)
    } else {
        let stem = table
            .path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "material".into());
        vec![options.material.clone().unwrap_or(stem); table.rows.len()]
    };
    let mut order: Vec<String> = Vec::new();
    for n in &names {
        if !order.contains(n) {
            order.push(n.clone());
        }
    }
    let geometry = options.config.as_ref().map(|c| {
        let ch = &c.channel;
        let s = ch
            .bead_area_mm2
            .map_or(ch.line_pitch_mm as f64 * ch.layer_height_mm as f64, |a| {
                a as f64
            });
        let v = options
            .speed_mm_s
            .unwrap_or(c.motion.print_speed_mm_s as f64);
        (
            ch.nozzle_diameter_mm as f64,
            ch.channel_length_mm as f64,
            s,
            v,
        )
    });
    let mut materials = Vec::new();
    for name in order {
        let idx: Vec<usize> = (0..names.len()).filter(|&i| names[i] == name).collect();
        if idx.len() < 3 {
            return Err(CalError::TooFewRowsFor {
                path: table.path.clone(),
                material: name,
                rows: idx.len(),
                need: 3,
            });
        }
        let p_pa: Vec<f64> = idx.iter().map(|&i| p_kpa[i] * 1e3).collect();
        let q: Vec<f64> = idx.iter().map(|&i| rate[i] * to_mm3).collect();
        materials.push(fit_material(table, name, p_pa, q, geometry, options.fit)?);
    }
    Ok(Calibration {
        path: table.path.clone(),
        unit,
        materials,
        geometry,
    })
}

fn fit_material(
    table: &Table,
    name: String,
    p_pa: Vec<f64>,
    q: Vec<f64>,
    geometry: Option<(f64, f64, f64, f64)>,
    options: FitOptions,
) -> Result<Material, CalError> {
    let lp: Vec<f64> = p_pa.iter().map(|v| v.ln()).collect();
    let lq: Vec<f64> = q.iter().map(|v| v.ln()).collect();
    let r_newton = (lp.iter().zip(&lq).map(|(p, q)| p - q).sum::<f64>() / lp.len() as f64).exp();
    let (c, s) = fit::line(&lp, &lq).unwrap_or((0.0, 1.0));
    let n0 = if s > 0.0 {
        (1.0 / s).clamp(0.05, 3.0)
    } else {
        1.0
    };
    let r0 = (-c * n0).exp();
    let mut fits = Vec::new();
    let mut failures = Vec::new();
    for (which, r0, n0) in [
        (Which::Newtonian, r_newton, 1.0),
        (
            Which::PowerLaw,
            if r0.is_finite() { r0 } else { r_newton },
            n0,
        ),
    ] {
        if p_pa.len() < which.model(1.0, 1.0).params.len() + 2 {
            continue;
        }
        match fit::fit(&which.model(r0, n0), &p_pa, &q, Space::Log, options) {
            Ok(f) => fits.push((which, f)),
            Err(e) => failures.push(format!("{}: {}", which.name(), e.0)),
        }
    }
    let plain: Vec<Fit> = fits.iter().map(|f| f.1.clone()).collect();
    let Some(best) = fit::select(&plain) else {
        return Err(CalError::NoConvergence {
            path: table.path.clone(),
            model: format!("channel law of {name:?}"),
            reason: failures.join("; "),
        });
    };
    let mut verdicts = Vec::new();
    let others: Vec<String> = fits
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != best)
        .map(|(_, (w, f))| format!("{} {:+.1}", w.name(), f.aicc - fits[best].1.aicc))
        .collect();
    verdicts.push(format!(
        "{}: {} fits best (AICc {:.1}; {})",
        name,
        fits[best].0.name(),
        fits[best].1.aicc,
        others.join(", ")
    ));
    if let Some((Which::PowerLaw, f)) = fits.iter().find(|(w, _)| *w == Which::PowerLaw) {
        let n = &f.estimates[1];
        verdicts.push(if n.excludes(1.0) {
            format!(
                "{}: {} excludes 1: the flow is not proportional to pressure",
                name,
                estimate(n)
            )
        } else {
            format!(
                "{}: {} includes 1: a Newtonian channel fits",
                name,
                estimate(n)
            )
        });
    }
    let mut in_channel = geometry.map(|g| channel_terms(&fits[best], g));
    // A fitted index the core refuses (shear-thickening) falls back to the Newtonian law.
    if let Some(ic) = &in_channel {
        if let Err(why) = &ic.rheology {
            if let Some(nf) = fits.iter().find(|(w, _)| *w == Which::Newtonian) {
                verdicts.push(format!("{name}: {why}; the config gets the Newtonian law"));
                in_channel = geometry.map(|g| channel_terms(nf, g));
            }
        }
    }
    Ok(Material {
        name,
        p_pa,
        q,
        fits,
        best,
        in_channel,
        verdicts,
    })
}

/// Inverts the core's `FlowLaw` (see `dollop::rheology`): `P = V_s a Q^n` with
/// `a = 2 K / (pi r^3) ((3n+1)/(4n) 4 / (pi r^3))^n`, so the fitted `R = V_s a` gives `K`.
fn channel_terms((which, f): &(Which, Fit), (d, l, s, v): (f64, f64, f64, f64)) -> InChannel {
    let vals = f.values();
    let (r, n) = match which {
        Which::Newtonian => (vals[0], 1.0),
        Which::PowerLaw => (vals[0], vals[1]),
    };
    let rad = d / 2.0;
    let pir3 = PI * rad.powi(3);
    let v_s = PI * d * d / 4.0 * l;
    let a = r / v_s;
    let shear_per_q = (3.0 * n + 1.0) / (4.0 * n) * 4.0 / pir3;
    let k = a * pir3 / (2.0 * shear_per_q.powf(n));
    let q_target = s * v;
    let p = r * q_target.powf(n);
    let tau_w = p * d / (4.0 * l);
    let rate_w = shear_per_q * q_target;
    let rheology = if *which == Which::Newtonian {
        Ok(Rheology::Newtonian {
            viscosity_pa_s: k as f32,
        })
    } else if (0.1..=1.0).contains(&n) {
        Ok(Rheology::PowerLaw {
            consistency_pa_sn: k as f32,
            flow_index: n as f32,
        })
    } else {
        Err(format!(
            "flow index {} is outside the 0.1 ..= 1 the core accepts",
            sig(n, 3)
        ))
    };
    InChannel {
        rheology,
        q_target,
        pressure_kpa: p / 1e3,
        apparent_viscosity: tau_w / rate_w,
    }
}

fn fit_name(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if out.len() + c.len_utf8() > MATERIAL_NAME_LEN {
            break;
        }
        out.push(c);
    }
    out
}

impl Calibration {
    /// The human-readable report.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "flow: {} material(s) from {} (pressure kPa, flow {})",
            self.materials.len(),
            self.path.display(),
            self.unit.name()
        );
        let _ = writeln!(
            s,
            "fits by Levenberg-Marquardt on log residuals (flow in mm3/s, pressure in Pa); 95 % confidence intervals"
        );
        for m in &self.materials {
            let _ = writeln!(s, "  {} ({} points):", m.name, m.q.len());
            for (w, f) in &m.fits {
                let _ = writeln!(
                    s,
                    "    {:<22} {}; {}, R^2 {:.4} (log), AICc {:.1}",
                    w.name(),
                    f.estimates
                        .iter()
                        .map(estimate)
                        .collect::<Vec<_>>()
                        .join(", "),
                    log_rms(f.rms),
                    f.r2,
                    f.aicc
                );
            }
        }
        match self.geometry {
            Some((d, l, area, v)) => {
                let _ = writeln!(
                    s,
                    "in the config's channel (d = {} mm, L = {} mm; the fit lumps inlet line and \
                     nozzle into it), bead {} mm^2 at {} mm/s:",
                    short(d),
                    short(l),
                    short(area),
                    short(v)
                );
                for m in &self.materials {
                    if let Some(ic) = &m.in_channel {
                        let law = match &ic.rheology {
                            Ok(r) => rheology_toml(r),
                            Err(e) => e.clone(),
                        };
                        let _ = writeln!(
                            s,
                            "  {}: effective rheology {law}; apparent viscosity {} Pa s at {} mm3/s; \
                             pressure for the bead {} kPa",
                            m.name,
                            sig(ic.apparent_viscosity, 4),
                            sig(ic.q_target, 4),
                            sig(ic.pressure_kpa, 4)
                        );
                    }
                }
            }
            None => {
                let _ = writeln!(
                    s,
                    "(no --config: give the machine config for the effective rheology and the pressure for the bead)"
                );
            }
        }
        let _ = writeln!(
            s,
            "selection: lowest AICc; a model with fewer parameters within {} of it is preferred",
            fit::AICC_TIE
        );
        for m in &self.materials {
            for v in &m.verdicts {
                let _ = writeln!(s, "verdict: {v}");
            }
        }
        s
    }

    /// `[[inlet]]` tables, one per material; `None` without a config.
    pub fn fragment(&self) -> Option<String> {
        self.geometry?;
        let mut s = format!(
            "# dollop calibrate flow {}: effective rheology in this channel and the pressure for the bead\n",
            self.path.display()
        );
        for m in &self.materials {
            let ic = m.in_channel.as_ref()?;
            let r = ic.rheology.as_ref().ok()?;
            let _ = write!(
                s,
                "\n[[inlet]]\nmaterial = {}\nrheology = {}\npressure_kpa = {}\n",
                toml_string(&fit_name(&m.name)),
                rheology_toml(r),
                toml_float(ic.pressure_kpa, 5)
            );
        }
        Some(s)
    }

    /// Flow against pressure, log-log, each material with its supported law.
    pub fn plot(&self, path: &Path, out: &mut StagedFiles) -> Result<(), CalError> {
        let mut panel = Panel {
            title: "flow against supply pressure".into(),
            x_label: "pressure (kPa)".into(),
            y_label: "flow (mm^3/s)".into(),
            log_x: true,
            log_y: true,
            series: Vec::new(),
            ..Panel::default()
        };
        for (i, m) in self.materials.iter().enumerate() {
            let (lo, hi) = m
                .p_pa
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
            panel.series.push(Series {
                label: m.name.clone(),
                points: m
                    .p_pa
                    .iter()
                    .map(|p| p / 1e3)
                    .zip(m.q.iter().copied())
                    .collect(),
                mark: Mark::Points,
                color: i + 1,
            });
            let (w, f) = &m.fits[m.best];
            panel.series.push(Series {
                label: format!("{}: {}", m.name, w.name()),
                points: plot::grid(lo, hi, 80, true)
                    .into_iter()
                    .map(|p| (p / 1e3, f.eval(p)))
                    .collect(),
                mark: Mark::Line,
                color: i + 1,
            });
        }
        plot::render(path, &[panel], 900, 520, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_from_headers() {
        for (h, u) in [
            ("flow_g_s", Some(RateUnit::GPerS)),
            ("rate (mm^3/s)", Some(RateUnit::Mm3PerS)),
            ("mass_mg_per_s", Some(RateUnit::MgPerS)),
            ("flow ml/min", Some(RateUnit::MlPerMin)),
            ("g/min", Some(RateUnit::GPerMin)),
            ("flow", None),
        ] {
            assert_eq!(RateUnit::from_header(h), u, "{h}");
        }
    }
}
