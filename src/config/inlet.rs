//! `[[inlet]]`: how many there are, each material's rheology, and each inlet's drive (a
//! supply pressure and valve timings, or a syringe), checked and turned into the flow
//! model's `Inlet`s. It stops at one inlet at a time; the highest flow they make together
//! and what it asks of the head are `flow.rs`'s business.

use super::check::Check;
use super::{
    ConfigError, Inlet, InletConfig, Pressure, Problem, Syringe, SyringeConfig,
    MAX_SYRINGE_SETTLE_S,
};
use crate::real::Real;
use crate::rheology::{FlowLaw, Rheology};

/// What the inlets need of the sections before them.
pub(super) struct Context {
    /// Nozzle diameter, mm.
    pub(super) d: f64,
    /// Bead section, mm^2.
    pub(super) s: f64,
    /// Shared channel volume, mm^3.
    pub(super) v_channel: f64,
    /// Print speed, mm/s.
    pub(super) print_speed: f64,
    /// Steps/s a driver may be asked for.
    pub(super) allowed_rate: f64,
}

/// The checked inlets: the core's `Inlet`s, and for the flow's own checks the flow laws
/// and supply pressures in f64.
pub(super) struct Inlets<R, const N: usize> {
    pub(super) inlets: heapless::Vec<Inlet<R>, N>,
    pub(super) laws: heapless::Vec<FlowLaw<f64>, N>,
    pub(super) supplies: heapless::Vec<f64, N>,
}

/// Checks the `[[inlet]]` entries for a build of `N` inlets.
pub(super) fn check<R: Real, const N: usize>(
    all: &[InletConfig],
    cx: &Context,
) -> Result<Inlets<R, N>, ConfigError> {
    count::<N>(all)?;
    let mut laws: heapless::Vec<FlowLaw<f64>, N> = heapless::Vec::new();
    for (i, inlet) in all.iter().enumerate() {
        rheology(&at(i), &inlet.rheology)?;
        // Capacity N was checked above, so this push cannot fail.
        let _ = laws.push(FlowLaw::new(&inlet.rheology, cx.d));
    }
    let mut inlets: heapless::Vec<Inlet<R>, N> = heapless::Vec::new();
    let mut supplies: heapless::Vec<f64, N> = heapless::Vec::new();
    for (i, inlet) in all.iter().enumerate() {
        let ic = at(i);
        let supply_pa = supply(&ic, inlet.pressure_kpa, &laws[i], cx)?;
        let syringe = match inlet.syringe {
            Some(sy) => Some(syringe(&ic, &sy, all, cx)?),
            None => None,
        };
        let open = ic.range(
            "valve_open_delay_ms",
            inlet.valve_open_delay_ms,
            0.0,
            2000.0,
        )?;
        let close = ic.range(
            "valve_close_delay_ms",
            inlet.valve_close_delay_ms,
            0.0,
            2000.0,
        )?;
        let rise = ic.range("pressure_rise_ms", inlet.pressure_rise_ms, 0.0, 5000.0)?;
        let decay = ic.range("pressure_decay_ms", inlet.pressure_decay_ms, 0.0, 5000.0)?;
        let _ = supplies.push(supply_pa);
        let flushed = if syringe.is_some() {
            0.0
        } else {
            laws[i].flow_full(supply_pa, cx.v_channel) / cx.s
        };
        let _ = inlets.push(Inlet {
            law: FlowLaw::new(&inlet.rheology, cx.d),
            supply_pa: R::of(supply_pa),
            flushed_mm_s: R::of(flushed),
            open_delay_s: R::of(open as f64 * 1e-3),
            close_delay_s: R::of(close as f64 * 1e-3),
            rise_s: R::of(rise as f64 * 1e-3),
            decay_s: R::of(decay as f64 * 1e-3),
            syringe,
        });
    }
    Ok(Inlets {
        inlets,
        laws,
        supplies,
    })
}

fn at(i: usize) -> Check {
    Check {
        section: "inlet",
        index: Some(i as u8),
    }
}

/// At least one inlet, and no more than the build holds.
fn count<const N: usize>(all: &[InletConfig]) -> Result<(), ConfigError> {
    let ic = Check::section("inlet");
    if all.is_empty() {
        return Err(ic.err("material", Problem::NoInlets));
    }
    if all.len() > N {
        return Err(ic.err(
            "material",
            Problem::TooManyInlets {
                got: all.len(),
                max: N,
            },
        ));
    }
    Ok(())
}

/// The material's flow law parameters.
fn rheology(ic: &Check, r: &Rheology) -> Result<(), ConfigError> {
    match *r {
        Rheology::Newtonian { viscosity_pa_s } => {
            ic.positive_max("rheology.newtonian.viscosity_pa_s", viscosity_pa_s, 1e7)?;
        }
        Rheology::PowerLaw {
            consistency_pa_sn,
            flow_index,
        } => {
            ic.positive_max(
                "rheology.power_law.consistency_pa_sn",
                consistency_pa_sn,
                1e7,
            )?;
            ic.range("rheology.power_law.flow_index", flow_index, 0.1, 1.0)?;
        }
        Rheology::HerschelBulkley {
            yield_stress_pa,
            consistency_pa_sn,
            flow_index,
        } => {
            ic.range(
                "rheology.herschel_bulkley.yield_stress_pa",
                yield_stress_pa,
                0.0,
                1e6,
            )?;
            ic.positive_max(
                "rheology.herschel_bulkley.consistency_pa_sn",
                consistency_pa_sn,
                1e7,
            )?;
            ic.range("rheology.herschel_bulkley.flow_index", flow_index, 0.1, 1.0)?;
        }
    }
    Ok(())
}

/// The supply pressure, Pa: as given, or `auto`, the pressure that prints the print speed
/// through a channel full of this material.
fn supply(ic: &Check, p: Pressure, law: &FlowLaw<f64>, cx: &Context) -> Result<f64, ConfigError> {
    match p {
        Pressure::Kpa(k) => Ok(ic.range("pressure_kpa", k, 0.1, 2000.0)? as f64 * 1e3),
        Pressure::Auto => {
            let q = cx.print_speed * cx.s;
            let p = cx.v_channel * (law.a * libm::pow(q, law.n) + law.b);
            if !(p.is_finite() && p > 0.0) {
                return Err(ic.err("pressure_kpa", Problem::AutoPressure));
            }
            if p > 2.0e6 {
                return Err(ic.err(
                    "pressure_kpa",
                    Problem::Above {
                        got: (p / 1e3) as f32,
                        limit: 2000.0,
                        what:
                            "the 2000 kPa the core accepts (\"auto\" for this material and speed)",
                    },
                ));
            }
            Ok(p)
        }
    }
}

/// A syringe inlet: its plunger's steps and lag, on a machine of syringes only.
fn syringe<R: Real>(
    ic: &Check,
    sy: &SyringeConfig,
    all: &[InletConfig],
    cx: &Context,
) -> Result<Syringe<R>, ConfigError> {
    let spm3 = ic.range("syringe.steps_per_mm3", sy.steps_per_mm3, 0.01, 1.0e6)?;
    let k = ic.positive_max("syringe.lag_k", sy.lag_k, 1.0e6)?;
    let n = ic.range("syringe.lag_n", sy.lag_n, 0.2, 5.0)?;
    // The executor follows the lag through a 255-point response table
    // and looks ahead a bounded volume: a lag that takes longer than
    // this to settle (k = 1e-6, n = 5 takes 27 s) misplaced boundaries
    // by 21 mm in simulation.
    let settle = Syringe::settle_time(k as f64, n as f64);
    if settle.is_nan() || settle > MAX_SYRINGE_SETTLE_S {
        return Err(ic.err(
            "syringe.lag_k",
            Problem::Above {
                got: settle as f32,
                limit: MAX_SYRINGE_SETTLE_S as f32,
                what: "the longest lag the core follows, in seconds to settle \
                       within 1e-6 ((ln 1e6 / lag_k)^(1/lag_n)); raise lag_k \
                       or lower lag_n",
            },
        ));
    }
    if all.iter().any(|x| x.syringe.is_none()) {
        return Err(ic.err("syringe", Problem::MixedDrives));
    }
    let rate = cx.print_speed * cx.s;
    let needed = rate * spm3 as f64;
    if needed > cx.allowed_rate {
        return Err(ic.err(
            "syringe.steps_per_mm3",
            Problem::StepRate {
                needed: needed as f32,
                allowed: cx.allowed_rate as f32,
            },
        ));
    }
    Ok(Syringe {
        steps_per_mm3: R::of(spm3 as f64),
        lag_k: R::of(k as f64),
        lag_n: R::of(n as f64),
        rate: R::of(rate),
    })
}
