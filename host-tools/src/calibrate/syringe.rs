//! `calibrate syringe`: steps per mm^3 of a stepper-driven syringe, from its geometry
//! (bore, lead screw, gearing, microsteps) or from a measured mass per step, the line
//! width `a = sqrt(4 / (pi c)) sqrt(Q / v)` it lays at a print speed, and the `syringe`
//! table of the config (with the lag from a `calibrate lag` fit or documented defaults).

use super::error::{positive, CalOption, OptionError};
use super::format::{sig, toml_float};
use super::lag::Weibull;
use super::CalError;
use dollop::config::Config;
use std::f64::consts::PI;
use std::fmt::Write as _;

/// Weibull rate used when no lag was measured, s^-n: with [`DEFAULT_LAG_N`] = 1 a
/// first-order lag of 50 ms that reaches 90 % after 115 ms, typical of a 10 ml syringe
/// of stiff paste. Measure it with `dollop calibrate lag`.
pub const DEFAULT_LAG_K: f64 = 20.0;
/// Weibull shape used when no lag was measured.
pub const DEFAULT_LAG_N: f64 = 1.0;

/// Options of `calibrate syringe`.
#[derive(Clone, Debug)]
pub struct Options {
    /// Syringe barrel inner diameter, mm.
    pub diameter_mm: Option<f64>,
    /// Lead of the screw (plunger travel per screw turn), mm.
    pub lead_mm: Option<f64>,
    /// Full steps per motor turn.
    pub steps_per_rev: f64,
    /// Microsteps per full step.
    pub microsteps: f64,
    /// Motor turns per screw turn.
    pub gear_ratio: f64,
    /// Measured paste mass per microstep, mg.
    pub mg_per_step: Option<f64>,
    /// Paste density, g/ml.
    pub density_g_ml: Option<f64>,
    /// Flow for the line width, mm^3/s.
    pub flow_mm3_s: Option<f64>,
    /// Plunger step rate for the line width, steps/s.
    pub step_rate_hz: Option<f64>,
    /// Print speed for the line width, mm/s.
    pub speed_mm_s: Option<f64>,
    /// Bead shape factor c: cross-section / (pi a^2 / 4).
    pub shape_c: f64,
    /// Measured lag (from `calibrate lag`), else the defaults.
    pub lag: Option<Weibull>,
    /// Machine config: print speed, bead and step-rate limit.
    pub config: Option<Config>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            diameter_mm: None,
            lead_mm: None,
            steps_per_rev: 200.0,
            microsteps: 16.0,
            gear_ratio: 1.0,
            mg_per_step: None,
            density_g_ml: None,
            flow_mm3_s: None,
            step_rate_hz: None,
            speed_mm_s: None,
            shape_c: 1.0,
            lag: None,
            config: None,
        }
    }
}

/// The result of `calibrate syringe`.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// From geometry, steps/mm^3.
    pub geometric: Option<f64>,
    /// From the measured mass per step, steps/mm^3.
    pub measured: Option<f64>,
    /// The one written (measured when given).
    pub steps_per_mm3: f64,
    /// Flow and speed used for the width, and the width, mm.
    pub line: Option<Line>,
    /// Steps/s the config's bead needs at its print speed, and what the core allows.
    pub config_rate: Option<(f64, f64)>,
    /// Lag written.
    pub lag: Weibull,
    /// Whether the lag was measured.
    pub lag_measured: bool,
    /// Verdicts.
    pub verdicts: Vec<String>,
}

/// The line a flow lays at a speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Flow, mm^3/s.
    pub q: f64,
    /// Print speed, mm/s.
    pub v: f64,
    /// Shape factor.
    pub c: f64,
    /// Width, mm.
    pub width_mm: f64,
}

/// `a = sqrt(4 / (pi c)) sqrt(Q / v)`: the width of a bead of cross-section `Q / v` whose
/// area is `c` times the circle of its width.
pub fn line_width(q_mm3_s: f64, v_mm_s: f64, c: f64) -> f64 {
    (4.0 / (PI * c)).sqrt() * (q_mm3_s / v_mm_s).sqrt()
}

/// The syringe's steps/mm^3 from its geometry and from a measured mass per step (with
/// the density), and the one written: the measured one when there is one.
fn scale(o: &Options) -> Result<(Option<f64>, Option<f64>, f64), CalError> {
    let geometric = match (o.diameter_mm, o.lead_mm) {
        (Some(d), Some(lead)) => {
            let d = positive(CalOption::Diameter, d)?;
            let lead = positive(CalOption::Lead, lead)?;
            let spr = positive(CalOption::StepsPerRev, o.steps_per_rev)?;
            let micro = positive(CalOption::Microsteps, o.microsteps)?;
            let gear = positive(CalOption::GearRatio, o.gear_ratio)?;
            let steps_per_mm = spr * micro * gear / lead;
            Some(steps_per_mm / (PI * d * d / 4.0))
        }
        (None, None) => None,
        _ => return Err(CalError::Option(OptionError::HalfGeometry)),
    };
    let measured = match (o.mg_per_step, o.density_g_ml) {
        (Some(mg), Some(rho)) => {
            let mg = positive(CalOption::MgPerStep, mg)?;
            let rho = positive(CalOption::Density, rho)?;
            // rho g/ml = rho mg/mm^3.
            Some(rho / mg)
        }
        (None, None) => None,
        (Some(_), None) => return Err(CalError::Option(OptionError::MassWithoutDensity)),
        (None, Some(_)) => None,
    };
    let steps_per_mm3 = measured
        .or(geometric)
        .ok_or(CalError::Option(OptionError::NoSyringeScale))?;
    if steps_per_mm3 > 1e6 {
        return Err(CalError::arg(format!(
            "{} steps/mm^3 is above the 1e6 the core accepts",
            sig(steps_per_mm3, 3)
        )));
    }
    Ok((geometric, measured, steps_per_mm3))
}

/// The verdict on the measured (`m`) against the geometric (`g`) steps/mm^3.
fn agreement(g: f64, m: f64) -> String {
    let dev = m / g - 1.0;
    if dev.abs() < 0.03 {
        format!(
            "measured and geometric steps/mm^3 agree within {:.1} %",
            100.0 * dev.abs()
        )
    } else if m > g {
        format!(
            "the syringe delivers {:.1} % less paste per step than its geometry says \
             (air, plunger seal or compression): the measured value is written",
            100.0 * (1.0 - g / m)
        )
    } else {
        format!(
            "the syringe delivers {:.1} % more paste per step than its geometry allows: \
             check the bore, lead, gearing and microsteps; the measured value is written",
            100.0 * (g / m - 1.0)
        )
    }
}

/// Computes the calibration.
pub fn calibrate(o: &Options) -> Result<Calibration, CalError> {
    let (geometric, measured, steps_per_mm3) = scale(o)?;
    let c = positive(CalOption::Shape, o.shape_c)?;
    let speed = match (o.speed_mm_s, &o.config) {
        (Some(v), _) => Some(positive(CalOption::Speed, v)?),
        (None, Some(cfg)) => Some(cfg.motion.print_speed_mm_s as f64),
        _ => None,
    };
    let bead = o.config.as_ref().map(|cfg| {
        let ch = &cfg.channel;
        ch.bead_area_mm2
            .map_or(ch.line_pitch_mm as f64 * ch.layer_height_mm as f64, |a| {
                a as f64
            })
    });
    let q = match (o.flow_mm3_s, o.step_rate_hz) {
        (Some(q), _) => Some(positive(CalOption::Flow, q)?),
        (None, Some(r)) => Some(positive(CalOption::StepRate, r)? / steps_per_mm3),
        (None, None) => bead.zip(speed).map(|(s, v)| s * v),
    };
    let line = q.zip(speed).map(|(q, v)| Line {
        q,
        v,
        c,
        width_mm: line_width(q, v, c),
    });
    // The core allows the drivers' rate less one step per control cycle.
    let config_rate = o.config.as_ref().zip(bead).map(|(cfg, s)| {
        let q = s * cfg.motion.print_speed_mm_s as f64;
        let allowed = cfg.motion.max_step_rate_hz as f64 - cfg.control.rate_hz as f64;
        (q * steps_per_mm3, allowed)
    });
    let (lag, lag_measured) = match o.lag {
        Some(w) => (w, true),
        None => (
            Weibull {
                m_inf: 1.0,
                k: DEFAULT_LAG_K,
                n: DEFAULT_LAG_N,
            },
            false,
        ),
    };
    if !(0.2..=5.0).contains(&lag.n) || lag.k > 1e6 {
        return Err(CalError::arg(format!(
            "the measured lag (k = {}, n = {}) is outside what the core accepts (n 0.2 ..= 5, k <= 1e6)",
            sig(lag.k, 3),
            sig(lag.n, 3)
        )));
    }
    let mut verdicts = Vec::new();
    if let (Some(g), Some(m)) = (geometric, measured) {
        verdicts.push(agreement(g, m));
    }
    if let (Some((need, max)), Some(cfg)) = (config_rate, o.config.as_ref()) {
        // Both figures the user can find in the config, beside the one the core derives.
        let why = format!(
            "max_step_rate_hz {} less one step per control cycle at rate_hz {}",
            cfg.motion.max_step_rate_hz, cfg.control.rate_hz
        );
        verdicts.push(if need <= max {
            format!(
                "the config's bead at its print speed needs {} steps/s of the {} the core allows ({why})",
                sig(need, 4),
                sig(max, 4)
            )
        } else {
            format!(
                "the config's bead at its print speed needs {} steps/s, above the {} the core \
                 allows ({why}): fewer microsteps or a coarser lead",
                sig(need, 4),
                sig(max, 4)
            )
        });
    }
    if !lag_measured {
        verdicts.push(format!(
            "lag not measured: defaults lag_k = {DEFAULT_LAG_K}, lag_n = {DEFAULT_LAG_N} \
             (90 % after {} ms); measure it with `dollop calibrate lag --inlet syringe`",
            sig(lag.t_lag() * 1e3, 3)
        ));
    }
    Ok(Calibration {
        geometric,
        measured,
        steps_per_mm3,
        line,
        config_rate,
        lag,
        lag_measured,
        verdicts,
    })
}

impl Calibration {
    /// The human-readable report.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "syringe:");
        if let Some(g) = self.geometric {
            let _ = writeln!(s, "  from geometry:    {} steps/mm^3", sig(g, 5));
        }
        if let Some(m) = self.measured {
            let _ = writeln!(s, "  from measurement: {} steps/mm^3", sig(m, 5));
        }
        let _ = writeln!(
            s,
            "  written:          {} steps/mm^3 ({} mm^3 per step)",
            sig(self.steps_per_mm3, 5),
            sig(1.0 / self.steps_per_mm3, 4)
        );
        if let Some(l) = self.line {
            let _ = writeln!(
                s,
                "  line width a = sqrt(4/(pi c)) sqrt(Q/v) = {} mm (Q = {} mm^3/s = {} steps/s, v = {} mm/s, c = {})",
                sig(l.width_mm, 4),
                sig(l.q, 4),
                sig(l.q * self.steps_per_mm3, 4),
                sig(l.v, 4),
                sig(l.c, 3)
            );
        }
        let _ = writeln!(
            s,
            "  lag: Weibull k = {} s^-n, n = {} ({}), t_lag = {} ms",
            sig(self.lag.k, 4),
            sig(self.lag.n, 4),
            if self.lag_measured {
                "measured"
            } else {
                "default"
            },
            sig(self.lag.t_lag() * 1e3, 3)
        );
        for v in &self.verdicts {
            let _ = writeln!(s, "verdict: {v}");
        }
        s
    }

    /// Keys of one `[[inlet]]`.
    pub fn fragment(&self) -> String {
        format!(
            "# dollop calibrate syringe: {} steps/mm^3, {} lag\n\
             # Apply to the inlet this syringe feeds: dollop config --apply THIS.toml MACHINE.toml --inlet N\n\
             syringe = {{ steps_per_mm3 = {}, lag_k = {}, lag_n = {} }}\n",
            sig(self.steps_per_mm3, 5),
            if self.lag_measured {
                "measured"
            } else {
                "default"
            },
            toml_float(self.steps_per_mm3, 6),
            toml_float(self.lag.k, 5),
            toml_float(self.lag.n, 5)
        )
    }
}
