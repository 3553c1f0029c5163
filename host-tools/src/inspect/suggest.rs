//! Corrections from an inspection, by asking the reference plant: for each parameter that
//! could be off (the channel and filament volume through `channel_length_mm`, the valves'
//! dead time, each paste's viscosity) the value under which the simulated print's
//! boundaries land where the photo found them, by a one-dimensional search; the parameter
//! whose best value explains the offsets best is the one believed off. A constant offset
//! in both switch directions points at the volume, an offset that grows with head speed
//! at dead time, a different offset per direction (or a bead narrower than its pitch) at
//! a viscosity; one print at one speed cannot tell volume from dead time, and the report
//! says when two explain it alike. The search and its interval are this module's; the
//! physics is `dollop_sim`'s.

use super::measure::{self, MaterialWidth};
use super::synth::{self, Truth};
use super::Inspection;
use dollop::config::Config;
use dollop_sim::{Job, RunOptions};
use std::fmt::Write as _;

/// One parameter's best explanation of the measured offsets.
#[derive(Clone, Debug)]
pub struct Fit {
    /// What was varied, for people.
    pub what: String,
    /// The truth at its best value.
    pub truth: Truth,
    /// Its best value and 95 % interval, in the parameter's own unit.
    pub value: (f64, f64, f64),
    /// RMS of measured minus simulated offsets at the best value, mm.
    pub rms: f64,
}

/// [`suggest`] for the job of a job file (its start, first material and commands).
pub fn for_job(
    i: &Inspection,
    config: &Config,
    start_um: [i32; 3],
    initial_material: u8,
    commands: &[dollop::Command],
) -> Suggestion {
    let job = Job {
        start_um,
        initial_material,
        commands: commands.to_vec(),
    };
    suggest(i, config, &job)
}

/// The corrections.
#[derive(Clone, Debug)]
pub struct Suggestion {
    /// RMS of the offsets the config as it is leaves unexplained, mm.
    pub rms_now: f64,
    /// Every parameter's fit, best first.
    pub fits: Vec<Fit>,
    /// What was concluded, one line each.
    pub lines: Vec<String>,
    /// The TOML fragment, if anything is worth changing.
    pub fragment: Option<String>,
    /// The config with the best correction applied.
    pub config: Config,
}

/// A parameter to search.
struct Candidate {
    /// What is varied, for people.
    what: String,
    /// The truth at a search value.
    truth_of: Box<dyn Fn(f64) -> Truth>,
    /// The range searched.
    range: (f64, f64),
    /// The value is the log of a scale factor.
    log: bool,
    /// The range's low end is the physical limit: a best value there is an answer, not
    /// the least bad of a range too narrow.
    lo_physical: bool,
}

/// An error common to every boundary read off the photo, in frame pixels, that the
/// interval allows for (see `suggest`).
pub const SYSTEMATIC_PX: f64 = 0.25;

/// Offsets the photo cannot resolve better than this (RMS, mm): nothing is changed.
pub const DEADBAND_MM: f64 = 0.02;

/// Simulated offset of each found boundary (same order), or `None` where the simulation
/// lost one; measured with the executor on `config` against `truth`'s plant.
fn simulated(i: &Inspection, config: &Config, job: &Job, truth: &Truth) -> Option<Vec<f64>> {
    let plant = synth::plant_config(config, &truth.physics(config), &truth.supply_scale).ok()?;
    let r = dollop_sim::run_with_plant::<f32>(config, &plant, job, &RunOptions::default(), |_| {})
        .ok()?;
    if r.fault.is_some() {
        return None;
    }
    i.found
        .iter()
        .map(|f| {
            let b = i.plan.boundaries[f.index];
            r.metrics
                .boundaries
                .iter()
                .find(|p| (p.point[0] - b.at[0]).hypot(p.point[1] - b.at[1]) < 0.02)
                .map(|p| p.error())
        })
        .collect()
}

/// Each material's bead width away from its switches as a photo of the print `truth`'s
/// plant lands would show it: the deposit painted into the inspection's frame and measured
/// as the photo was (so beads that touch read as touching alike).
fn simulated_widths(
    i: &Inspection,
    config: &Config,
    job: &Job,
    truth: &Truth,
) -> Option<Vec<MaterialWidth>> {
    let plant = synth::plant_config(config, &truth.physics(config), &truth.supply_scale).ok()?;
    let (d, run) = synth::deposit(config, &plant, job, i.frame).ok()?;
    if run.fault.is_some() {
        return None;
    }
    let found = measure::boundaries(&i.plan, &i.frame, &d.px);
    let moved = measure::moved(&i.plan, &found);
    let widths = measure::widths(&i.plan, &i.frame, &d.px, 0.5);
    Some(measure::width_by_material(&i.plan, &moved, &found, &widths))
}

/// How far a material's measured bead width may lie from the simulated one and still
/// agree, mm (and as a share of it, `WIDTH_AGREE_SHARE`; the larger counts). Measured on
/// the test photos: every material's median equal to the simulated one where the offsets'
/// correction was the whole truth; 0.10 mm apart where a supply pressure was off too.
pub const WIDTH_AGREE_MM: f64 = 0.05;
/// See `WIDTH_AGREE_MM`.
pub const WIDTH_AGREE_SHARE: f64 = 0.08;

/// Lines comparing the measured widths with the simulated ones under `truth` (named
/// `what`), and what a disagreement points at: a flow the offsets' one parameter does not
/// explain (a paste's viscosity or a supply pressure; widths alone cannot tell which, nor
/// always whose, as the pastes share the channel).
fn width_lines(
    i: &Inspection,
    config: &Config,
    job: &Job,
    truth: &Truth,
    what: &str,
) -> Vec<String> {
    let Some(sim) = simulated_widths(i, config, job, truth) else {
        return Vec::new();
    };
    let cap = 1.5 * i.plan.pitch - 1e-9;
    let name = |m: u8| {
        config
            .inlets
            .get(m as usize)
            .map_or(format!("inlet {m}"), |x| x.material.to_string())
    };
    let shown = |w: f64| {
        if w >= cap {
            "touching".to_string()
        } else {
            format!("{w:.3} mm")
        }
    };
    let mut pairs = Vec::new();
    for m in &i.width_by_material {
        if let Some(s) = sim.iter().find(|s| s.material == m.material) {
            pairs.push((m.material, m.median, s.median));
        }
    }
    if pairs.is_empty() {
        return Vec::new();
    }
    let mut lines = vec![format!(
        "bead width away from switches, measured against simulated with {what}: {}",
        pairs
            .iter()
            .map(|&(m, a, b)| format!("{} {} against {}", name(m), shown(a), shown(b)))
            .collect::<Vec<_>>()
            .join("; ")
    )];
    // Where both touch their neighbours nothing is measured.
    let off = pairs
        .iter()
        .filter(|p| p.1 < cap || p.2 < cap)
        .map(|&(m, a, b)| (m, a, b, (a - b).abs()))
        .filter(|p| p.3 > WIDTH_AGREE_MM.max(WIDTH_AGREE_SHARE * p.2.min(cap)))
        .max_by(|x, y| x.3.total_cmp(&y.3));
    lines.push(match off {
        None => "  the widths agree with it".into(),
        Some((m, a, b, _)) => format!(
            "  the widths disagree with it: {}'s beads run {} than that explains ({} against {}), so a flow is off as well: a paste's viscosity or a supply pressure (every paste in the shared channel sets the flow, so not necessarily this one's)",
            name(m),
            if a < b { "narrower" } else { "wider" },
            shown(a),
            shown(b)
        ),
    });
    lines
}

fn sse(i: &Inspection, sim: &[f64]) -> f64 {
    i.found
        .iter()
        .zip(sim)
        .map(|(f, s)| (f.offset - s).powi(2))
        .sum()
}

/// Golden-section search of `f` over [lo, hi] (`f` may fail: then +inf), `iters` steps.
fn golden(mut lo: f64, mut hi: f64, iters: usize, f: &mut impl FnMut(f64) -> f64) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..iters {
        if fa < fb {
            hi = b;
            (b, fb) = (a, fa);
            a = hi - g * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            (a, fa) = (b, fb);
            b = lo + g * (hi - lo);
            fb = f(b);
        }
    }
    if fa < fb {
        (a, fa)
    } else {
        (b, fb)
    }
}

impl Suggestion {
    /// No correction needed: parameters were fitted and the config as it is already puts
    /// the boundaries within the dead band of where the photo shows them.
    pub fn none_needed(&self) -> bool {
        self.fragment.is_none() && !self.fits.is_empty() && self.rms_now <= DEADBAND_MM
    }
}

/// Suggests corrections to `config` (which `job` was printed with) from `i`.
pub fn suggest(i: &Inspection, config: &Config, job: &Job) -> Suggestion {
    let n = i.found.len();
    let base = simulated(i, config, job, &Truth::default());
    let rms_now = base.as_ref().map_or(f64::INFINITY, |b| rms(sse(i, b), n));
    let mut lines = Vec::new();
    let mut fits: Vec<Fit> = Vec::new();
    if n < 3 || base.is_none() {
        lines.push(format!(
            "{n} boundaries found{}; at least 3, and a job the simulator can run, are needed to suggest anything",
            if base.is_none() { " and the job does not simulate" } else { "" }
        ));
    } else {
        let mut misses = Vec::new();
        for c in candidates(i, config) {
            match fit_one(i, config, job, c) {
                Ok(fit) => fits.push(fit),
                Err(what) => misses.push(format!(
                    "  {what}: no value in the range searched explains the offsets"
                )),
            }
        }
        fits.sort_by(|a, b| a.rms.total_cmp(&b.rms));
        lines.push(format!(
            "as configured the simulated boundaries miss the measured ones by {rms_now:.3} mm RMS over {n} boundaries"
        ));
        lines.extend(fits.iter().map(fit_line));
        lines.extend(misses);
    }
    let (out, fragment) = conclude(i, config, job, rms_now, &fits, &mut lines);
    Suggestion {
        rms_now,
        fits,
        lines,
        fragment,
        config: out,
    }
}

/// RMS over `n` boundaries (at least one) of offsets whose squares sum to `sse`, mm.
fn rms(sse: f64, n: usize) -> f64 {
    (sse / n.max(1) as f64).sqrt()
}

/// The parameters to search: the channel and filament volume, the valves' dead time, and
/// the viscosity of each material the plan prints.
fn candidates(i: &Inspection, config: &Config) -> Vec<Candidate> {
    // The valves' dead time can be found shorter than configured down to none.
    let min_delay = config
        .inlets
        .iter()
        .map(|v| v.valve_open_delay_ms.min(v.valve_close_delay_ms) as f64)
        .fold(40.0, f64::min)
        .max(0.0);
    let mut candidates = vec![
        Candidate {
            what: "channel and filament volume (channel_length_mm)".into(),
            truth_of: Box::new(|x: f64| Truth {
                channel_scale: x.exp(),
                ..Default::default()
            }),
            range: (0.5f64.ln(), 2f64.ln()),
            log: true,
            lo_physical: false,
        },
        Candidate {
            what: "valve dead time (valve_open_delay_ms, valve_close_delay_ms)".into(),
            truth_of: Box::new(|x: f64| Truth {
                dead_time_ms: x,
                ..Default::default()
            }),
            range: (-min_delay, 40.0),
            log: false,
            lo_physical: true,
        },
    ];
    for &m in &i.plan.materials {
        let name = config
            .inlets
            .get(m as usize)
            .map_or(format!("inlet {m}"), |x| x.material.to_string());
        candidates.push(Candidate {
            what: format!("viscosity of inlet {m} ({name})"),
            truth_of: Box::new(move |x: f64| {
                let mut v = [1.0; 4];
                if let Some(s) = v.get_mut(m as usize) {
                    *s = x.exp();
                }
                Truth {
                    viscosity_scale: v,
                    ..Default::default()
                }
            }),
            range: (0.5f64.ln(), 2f64.ln()),
            log: true,
            lo_physical: false,
        });
    }
    candidates
}

/// `c`'s best value by a golden-section search of its range, with its interval; or, where
/// no value in the range explains the offsets, what `c` varies.
fn fit_one(i: &Inspection, config: &Config, job: &Job, c: Candidate) -> Result<Fit, String> {
    let (lo, hi) = c.range;
    let mut f =
        |x: f64| simulated(i, config, job, &(c.truth_of)(x)).map_or(f64::INFINITY, |s| sse(i, &s));
    let (x, best) = golden(lo, hi, 14, &mut f);
    // A best value at the edge of the search is no explanation, only the least bad.
    let edge = (!c.lo_physical && x - lo < 0.01 * (hi - lo)) || hi - x < 0.01 * (hi - lo);
    if !best.is_finite() || edge {
        return Err(c.what);
    }
    let half = half_interval(i, config, job, &c, x, best);
    let shown = |v: f64| if c.log { v.exp() } else { v };
    // Not beyond the physical limit at the range's low end.
    let low = if c.lo_physical {
        (x - half).max(lo)
    } else {
        x - half
    };
    Ok(Fit {
        truth: (c.truth_of)(x),
        what: c.what,
        value: (shown(x), shown(low), shown(x + half)),
        rms: rms(best, i.found.len()),
    })
}

/// Half the 95 % interval of `c` about its best value `x` (squared error `best` there), in
/// the search's unit; NaN where the misfit does not curve up about it.
fn half_interval(
    i: &Inspection,
    config: &Config,
    job: &Job,
    c: &Candidate,
    x: f64,
    best: f64,
) -> f64 {
    let n = i.found.len();
    let (lo, hi) = c.range;
    // Interval from the curvature of the squared error at the best value.
    // (A neighbour the simulator cannot match boundary for boundary counts as
    // unknown, and the step shrinks until both sides can be evaluated.)
    let mut h = (hi - lo) * 0.02;
    let mut curv = f64::NAN;
    // The simulated offsets' change with the value, mm per unit, each boundary.
    let mut slope: Vec<f64> = Vec::new();
    for _ in 0..6 {
        let sim = |x: f64| simulated(i, config, job, &(c.truth_of)(x));
        if let (Some(up), Some(down)) = (sim(x + h), sim(x - h)) {
            curv = (sse(i, &up) + sse(i, &down) - 2.0 * best) / (h * h);
            slope = up
                .iter()
                .zip(&down)
                .map(|(u, d)| (u - d) / (2.0 * h))
                .collect();
            break;
        }
        h *= 0.3;
    }
    let var = if curv > 0.0 && n > 1 {
        2.0 * best / (n - 1) as f64 / curv
    } else {
        f64::NAN
    };
    // The scatter of the offsets about the fit is not all the photo can get wrong:
    // an error common to every boundary (the photo read at `SYSTEMATIC_PX` of a
    // frame pixel) moves the best value by bias * sum(slope) / sum(slope^2),
    // which no scatter shows. It is added to the interval.
    let (sum, sum2) = slope
        .iter()
        .fold((0.0, 0.0), |(a, b), &g| (a + g, b + g * g));
    let bias = SYSTEMATIC_PX / i.frame.px_per_mm;
    let systematic = if sum2 > 0.0 {
        bias * sum.abs() / sum2
    } else {
        0.0
    };
    1.96 * var.sqrt() + systematic
}

/// The report's line for one fit.
fn fit_line(f: &Fit) -> String {
    // No interval where the misfit does not curve up about the best value (or
    // its neighbours do not simulate): say so rather than print NaN.
    let interval = if f.value.1.is_finite() && f.value.2.is_finite() {
        format!("[{:.4}, {:.4}]", f.value.1, f.value.2)
    } else {
        "[no interval: the misfit does not curve up about it]".into()
    };
    format!(
        "  {}: {} {:.4} {interval} leaves {:.3} mm RMS",
        f.what,
        if f.truth.dead_time_ms != 0.0 {
            "+ ms"
        } else {
            "x"
        },
        f.value.0,
        f.rms
    )
}

/// What the fits (best first) conclude, in `lines`: the config with the best fit's
/// correction and its TOML fragment where one explains the offsets well enough, else the
/// config as it is and none.
fn conclude(
    i: &Inspection,
    config: &Config,
    job: &Job,
    rms_now: f64,
    fits: &[Fit],
    lines: &mut Vec<String>,
) -> (Config, Option<String>) {
    match fits.first() {
        Some(b) if rms_now > DEADBAND_MM && b.rms < 0.7 * rms_now => {
            let out = b.truth.physics(config);
            lines.push(format!(
                "believed off: {} ({:.3} -> explains all but {:.3} mm RMS)",
                b.what, b.value.0, b.rms
            ));
            if let Some(second) = fits.get(1) {
                if second.rms < 1.2 * b.rms {
                    lines.push(format!(
                        "  {} explains it almost as well: print switches at several head speeds (`dollop slice --calibration-pattern`) to tell them apart",
                        second.what
                    ));
                }
            }
            let fragment = Some(fragment_for(i, config, &out));
            lines.extend(width_lines(i, config, job, &b.truth, "the correction"));
            return (out, fragment);
        }
        Some(_) if rms_now <= DEADBAND_MM => {
            lines.push(format!(
                "nothing to correct: the boundaries land where the config says within {rms_now:.3} mm RMS"
            ));
            lines.extend(width_lines(i, config, job, &Truth::default(), "the config as it is"));
        }
        Some(_) => lines.push(
            "no single parameter explains the offsets (none halves the misfit): check the photo and the job, or calibrate the pastes (`dollop calibrate`)".into(),
        ),
        None => {}
    }
    (config.clone(), None)
}

/// The TOML that turns `from` into `to`: valid TOML throughout, each inlet's corrections in
/// an `[[inlet]]` table named by its `material` (what `dollop config --apply` matches on).
fn fragment_for(i: &Inspection, from: &Config, to: &Config) -> String {
    use crate::calibrate::format::{toml_float, toml_string};
    use crate::calibrate::rheology::rheology_toml;
    let mut s = format!(
        "# dollop inspect {} --suggest: corrections to the machine config.\n\
         # Apply with: dollop config --apply THIS.toml MACHINE.toml\n",
        i.path.display()
    );
    if to.channel.channel_length_mm != from.channel.channel_length_mm {
        let _ = writeln!(
            s,
            "[channel]\nchannel_length_mm = {}",
            toml_float(to.channel.channel_length_mm as f64, 5)
        );
    }
    for (a, b) in from.inlets.iter().zip(&to.inlets) {
        let lag = a.valve_open_delay_ms != b.valve_open_delay_ms;
        let rheology = a.rheology != b.rheology;
        if !lag && !rheology {
            continue;
        }
        let _ = writeln!(s, "[[inlet]]\nmaterial = {}", toml_string(&a.material));
        if lag {
            let _ = writeln!(
                s,
                "valve_open_delay_ms = {}\nvalve_close_delay_ms = {}",
                toml_float(b.valve_open_delay_ms as f64, 4),
                toml_float(b.valve_close_delay_ms as f64, 4)
            );
        }
        if rheology {
            let _ = writeln!(s, "rheology = {}", rheology_toml(&b.rheology));
        }
    }
    s
}
