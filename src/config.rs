//! Machine and material configuration: the serde types a user writes (TOML on the host,
//! postcard over USB) in the units they measure, and their validation into `Machine`, the
//! checked, SI-converted form the flow model and executor run on. Parsing files is the
//! host's job; every out-of-range or inconsistent value here becomes a `ConfigError`.

use crate::real::Real;
use crate::rheology::{FlowLaw, Rheology};
use crate::vol::Vol;
use core::fmt;
use serde::{Deserialize, Serialize};

mod channel;
mod check;
mod control;
mod flow;
mod inlet;
mod motion;
mod pause;
mod problem;
use check::{axis_check, Check};
pub use pause::{Park, PauseConfig};
pub use problem::{ConfigError, Field, Problem};

pub use crate::capacity::MAX_CONFIG_INLETS;
/// Longest material name, bytes.
pub const MATERIAL_NAME_LEN: usize = 24;

/// A whole machine: printhead channel, motion system, control loop and inlets.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Shared channel, nozzle and bead geometry.
    pub channel: ChannelConfig,
    /// Axes, limits, speeds.
    pub motion: MotionConfig,
    /// Control loop.
    #[serde(default)]
    pub control: ControlConfig,
    /// One entry per inlet (valve + material), in valve order.
    #[serde(rename = "inlet")]
    pub inlets: heapless::Vec<InletConfig, MAX_CONFIG_INLETS>,
    /// Pauses: where a parked pause takes the head (see `pause`).
    #[serde(default)]
    pub pause: PauseConfig,
}

/// The shared channel and the bead it lays.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelConfig {
    /// Diameter of the shared channel and nozzle, mm.
    pub nozzle_diameter_mm: f32,
    /// Length of the shared channel from the junction to the nozzle tip, mm.
    pub channel_length_mm: f32,
    /// Height of the nozzle tip above the layer below while printing, mm. Where it exceeds
    /// the layer height, a filament of the difference hangs below the nozzle.
    pub nozzle_height_mm: f32,
    /// Layer height, mm.
    pub layer_height_mm: f32,
    /// Line pitch (spacing of neighbouring beads), mm.
    pub line_pitch_mm: f32,
    /// Bead cross-section, mm^2; default `line_pitch_mm * layer_height_mm`.
    #[serde(default)]
    pub bead_area_mm2: Option<f32>,
}

/// Axes X, Y, Z in that order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionConfig {
    /// Microsteps per mm, per axis.
    pub steps_per_mm: [f32; 3],
    /// Lowest reachable coordinate per axis, mm.
    pub travel_min_mm: [f32; 3],
    /// Highest reachable coordinate per axis, mm.
    pub travel_max_mm: [f32; 3],
    /// Top speed per axis, mm/s.
    pub max_speed_mm_s: [f32; 3],
    /// Top acceleration per axis, mm/s^2.
    pub max_accel_mm_s2: [f32; 3],
    /// Print speed the `auto` pressures aim for, mm/s.
    pub print_speed_mm_s: f32,
    /// Fastest the head may print; the flow must not be able to push it faster, mm/s.
    pub print_speed_max_mm_s: f32,
    /// Speed of travel moves (valves closed), mm/s.
    pub travel_speed_mm_s: f32,
    /// Highest step rate the drivers take, per axis, steps/s.
    pub max_step_rate_hz: f32,
    /// Wait at the end of a bead until the flow has decayed before travelling.
    #[serde(default = "default_true")]
    pub wait_for_flow_decay: bool,
    /// Flow counted as stopped, as a fraction of the highest flow the machine reaches.
    #[serde(default = "default_stop_fraction")]
    pub flow_stop_fraction: f32,
}

fn default_true() -> bool {
    true
}
fn default_stop_fraction() -> f32 {
    0.005
}

/// The control loop.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlConfig {
    /// Control cycles per second; must divide 1 000 000 (the period is whole microseconds).
    pub rate_hz: u32,
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig { rate_hz: 10_000 }
    }
}

/// Supply pressure of an inlet: a value in kPa, or `auto`, the pressure that prints the
/// configured bead at `print_speed_mm_s` with the channel full of this inlet's material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pressure {
    /// Computed from the material, bead and print speed.
    Auto,
    /// kPa above ambient.
    Kpa(f32),
}

impl Serialize for Pressure {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            match *self {
                Pressure::Auto => s.serialize_str("auto"),
                Pressure::Kpa(k) => s.serialize_f32(k),
            }
        } else {
            // Compact forms: NaN never validates as a pressure, so it stands for `auto`.
            match *self {
                Pressure::Auto => s.serialize_f32(f32::NAN),
                Pressure::Kpa(k) => s.serialize_f32(k),
            }
        }
    }
}

impl<'de> Deserialize<'de> for Pressure {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Pressure;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a pressure in kPa or \"auto\"")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Pressure, E> {
                if v == "auto" {
                    Ok(Pressure::Auto)
                } else {
                    Err(E::invalid_value(serde::de::Unexpected::Str(v), &self))
                }
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Pressure, E> {
                Ok(Pressure::Kpa(v as f32))
            }
            fn visit_f32<E: serde::de::Error>(self, v: f32) -> Result<Pressure, E> {
                if v.is_nan() {
                    Ok(Pressure::Auto)
                } else {
                    Ok(Pressure::Kpa(v))
                }
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Pressure, E> {
                Ok(Pressure::Kpa(v as f32))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Pressure, E> {
                Ok(Pressure::Kpa(v as f32))
            }
        }
        if d.is_human_readable() {
            d.deserialize_any(V)
        } else {
            d.deserialize_f32(V)
        }
    }
}

/// One inlet: its valve, line and material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InletConfig {
    /// Material name, for people (at most 24 bytes).
    pub material: heapless::String<MATERIAL_NAME_LEN>,
    /// How the material flows.
    pub rheology: Rheology,
    /// Supply pressure, kPa, or "auto".
    pub pressure_kpa: Pressure,
    /// Time from the open command until the valve passes paste, ms.
    #[serde(default)]
    pub valve_open_delay_ms: f32,
    /// Time from the close command until the valve shuts, ms.
    #[serde(default)]
    pub valve_close_delay_ms: f32,
    /// First-order time constant of the line pressure rising after the valve opens, ms.
    #[serde(default)]
    pub pressure_rise_ms: f32,
    /// First-order time constant of the line pressure decaying after the valve shuts, ms.
    #[serde(default)]
    pub pressure_decay_ms: f32,
    /// Present when this inlet is a stepper-driven syringe instead of a pneumatic valve;
    /// `pressure_kpa` and the valve timings are then not used.
    #[serde(default)]
    pub syringe: Option<SyringeConfig>,
}

/// A syringe pushed by a stepper (an E axis): volumetric flow from the plunger's step
/// rate, arriving after a lag measured as a Weibull curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyringeConfig {
    /// Plunger microsteps per mm^3 of paste pushed.
    pub steps_per_mm3: f32,
    /// Weibull rate k of the outflow after the plunger starts,
    /// `M(t) = M_inf (1 - exp(-k t^n))` with t in seconds (units s^-n).
    pub lag_k: f32,
    /// Weibull shape n.
    pub lag_n: f32,
}

/// One validated inlet in the core's units (Pa, s, mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inlet<R> {
    /// Flow law of its material in this channel.
    pub law: FlowLaw<R>,
    /// Supply pressure, Pa.
    pub supply_pa: R,
    /// The head's speed with the channel full of this inlet's paste at its supply, mm/s
    /// (0 for a syringe): where a bead of it runs once the channel has flushed. Worked
    /// out here, as a shear-thinning paste's is a power of the pressure (software `powf`
    /// in a sizing step on the chip).
    pub flushed_mm_s: R,
    /// Valve open dead time, s.
    pub open_delay_s: R,
    /// Valve close dead time, s.
    pub close_delay_s: R,
    /// Rise time constant, s (0: instant).
    pub rise_s: R,
    /// Decay time constant, s (0: instant).
    pub decay_s: R,
    /// Present for a stepper-driven syringe inlet (then the fields above are unused).
    pub syringe: Option<Syringe<R>>,
}

/// A validated syringe inlet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Syringe<R> {
    /// Plunger microsteps per mm^3.
    pub steps_per_mm3: R,
    /// Weibull rate k of the outflow lag, s^-n.
    pub lag_k: R,
    /// Weibull shape n.
    pub lag_n: R,
    /// Plunger displacement rate while the inlet feeds, mm^3/s: the bead at
    /// `print_speed_mm_s`.
    pub rate: R,
}

/// Longest syringe lag the core follows: seconds for the Weibull response to come within
/// 1e-6 of full flow. The bundled configs' syringes settle in 0.3 to 1.5 s, the bundled
/// lag measurement (`host-tools/data/calibration/lag-syringe.csv`) in 3.2 s.
pub const MAX_SYRINGE_SETTLE_S: f64 = 5.0;

impl Syringe<f64> {
    /// Fraction of the plunger's rate flowing out `t` seconds after it started:
    /// `F(t) = 1 - exp(-k t^n)`.
    pub fn response(k: f64, n: f64, t: f64) -> f64 {
        if t <= 0.0 {
            0.0
        } else {
            1.0 - libm::exp(-k * libm::pow(t, n))
        }
    }
    /// Time after which the response is within 1e-6 of 1, s.
    pub fn settle_time(k: f64, n: f64) -> f64 {
        libm::pow(libm::log(1e6) / k, 1.0 / n)
    }
}

/// Validated motion limits in mm and s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion<R> {
    /// Microsteps per mm.
    pub steps_per_mm: [R; 3],
    /// Lowest coordinate, mm.
    pub min_mm: [R; 3],
    /// Highest coordinate, mm.
    pub max_mm: [R; 3],
    /// Top speed, mm/s.
    pub max_speed: [R; 3],
    /// Top acceleration, mm/s^2.
    pub max_accel: [R; 3],
    /// Travel speed, mm/s.
    pub travel_speed: R,
    /// Whole steps one axis may take in one control cycle.
    pub max_steps_per_cycle: u32,
    /// Wait for flow decay before travel.
    pub wait_for_flow_decay: bool,
}

/// A validated machine: everything the core needs, in mm, s, Pa, with derived constants.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine<R, const N: usize> {
    /// Channel diameter, mm.
    pub d_mm: R,
    /// Shared channel volume `pi d^2 L_s / 4`.
    pub v_channel: Vol,
    /// Hanging filament volume `pi d^2 H / 4`.
    pub v_hang: Vol,
    /// Bead cross-section S, mm^2.
    pub bead_area: R,
    /// Inlets in valve order.
    pub inlets: heapless::Vec<Inlet<R>, N>,
    /// Motion limits.
    pub motion: Motion<R>,
    /// Control period, microseconds.
    pub period_us: u32,
    /// The same in seconds (`dt`), worked out once: from the microseconds it is f64
    /// arithmetic, software on the M4 (about 120 instructions a call in a sizing step).
    dt: R,
    /// Fastest the flow can drive the head, mm/s (highest supply through the least
    /// resistive channel content).
    pub v_flow_max: R,
    /// Corner radius: the one the XY acceleration limit allows at `v_flow_max` (its
    /// `CORNER_SHARE` when the head ramps through flow steps), mm.
    pub corner_radius: R,
    /// Largest change of head speed the flow makes faster than the X/Y acceleration limit
    /// follows (a valve whose pressure switches at once), mm/s; 0 when it never does.
    pub flow_step: R,
    /// Largest head acceleration the flow asks for where it ramps within the limit
    /// (pressure rise and decay, syringe lag), mm/s^2.
    pub flow_accel: R,
    /// Length of the head's speed ramps, control cycles: odd, 1 when the head follows the
    /// flow as it is (see `crate::ramp`).
    pub ramp_cycles: u32,
    /// Farthest a speed ramp lays the paste from where the flow put it, mm: the window
    /// centred on a step of `dv` shifts it by up to `dv w / 8` (see `section_bound`).
    pub ramp_offset_mm: R,
    /// Flow counted as stopped, mm^3/s.
    pub q_stop: R,
    /// Every inlet is a stepper-driven syringe (else every inlet is pneumatic).
    pub syringes: bool,
    /// Where a parked pause takes the head.
    pub park: Park<R>,
}

impl<R: Real, const N: usize> Machine<R, N> {
    /// No machine: no inlets, no channel, no travel. Stands in for the machine of an
    /// executor not configured yet (the board builds that executor at compile time).
    pub const UNCONFIGURED: Self = Machine {
        d_mm: R::ZERO,
        v_channel: Vol::ZERO,
        v_hang: Vol::ZERO,
        bead_area: R::ZERO,
        inlets: heapless::Vec::new(),
        motion: Motion {
            steps_per_mm: [R::ZERO; 3],
            min_mm: [R::ZERO; 3],
            max_mm: [R::ZERO; 3],
            max_speed: [R::ZERO; 3],
            max_accel: [R::ZERO; 3],
            travel_speed: R::ZERO,
            max_steps_per_cycle: 0,
            wait_for_flow_decay: false,
        },
        period_us: 0,
        dt: R::ZERO,
        v_flow_max: R::ZERO,
        corner_radius: R::ZERO,
        flow_step: R::ZERO,
        flow_accel: R::ZERO,
        ramp_cycles: 1,
        ramp_offset_mm: R::ZERO,
        q_stop: R::ZERO,
        syringes: false,
        park: Park::NONE,
    };

    /// Channel plus hanging filament: the volume between the junction and the plate.
    pub fn v_transit(&self) -> Vol {
        self.v_channel + self.v_hang
    }
    /// Control period in seconds.
    #[inline]
    pub fn dt(&self) -> R {
        self.dt
    }
    /// Number of inlets.
    pub fn inlet_count(&self) -> usize {
        self.inlets.len()
    }
    /// Largest relative error of the bead section over `SECTION_WINDOW_MM` of bead away
    /// from its ends that this machine allows: `SECTION_BAND`, or where the head ramps
    /// through a step of the flow, what that ramp forces.
    ///
    /// A ramp window `w` centred on a step of `dv` (head speed from `v1` to `v1 + dv`)
    /// leaves the head ahead of (or behind) the paste by `e(t) = dv (w/2 - |t|)^2 / (2 w)`
    /// for `|t| < w/2`: `dv w / 8` at the step, nothing outside the window. Over a stretch
    /// of bead from `s1` to `s1 + W` the paste laid is `W - (e(t2) - e(t1))`, so the
    /// section is off by at most `dv w / (8 W)`, each side, once the stretch is longer
    /// than the ramp (a window at 22.5 mm/s and 10 ms covers 0.11 mm). With the window
    /// just long enough for the step, `w = dv / a`, this is the closed form
    /// `dv^2 / (8 a W)`: what acceleration `a` physically allows, since any speed change
    /// of `dv` within `a` leaves some stretch that far off. Why no speed profile does
    /// better over `W` longer than the ramp: the head must end where the paste is, so its
    /// lead on the paste, `E(t)`, starts and ends at 0; before the step it gains on the
    /// old speed and after it loses on the new, and with the speed moving at most `a` the
    /// least peak of `E` is that of the linear ramp centred on the step, `dv^2 / (8 a)`
    /// (a lead that first went negative would add its swing to some stretch). So worst
    /// over every 0.2 mm this bound is the floor; the percentile band the issue measures
    /// (p99 - p1 of the section, `dollop simulate --report`'s `section band`) counts
    /// only how much bead the ramps cover and is far below it where steps are sparse.
    pub fn section_bound(&self) -> f64 {
        (self.ramp_offset_mm.to_f64() / SECTION_WINDOW_MM).max(SECTION_BAND)
    }
}

/// Relative error of the bead section over `SECTION_WINDOW_MM` that the flow and the head
/// hold where no step of the flow forces more.
pub const SECTION_BAND: f64 = 0.01;

/// Share of the X/Y acceleration limit a speed ramp may use when the head ramps through
/// flow steps; corners get `CORNER_SHARE`. A ramp on a fillet adds its tangential
/// acceleration to the centripetal one at right angles, so their vector sum, and with it
/// each axis, stays within the limit when `RAMP_SHARE^2 + CORNER_SHARE^2 = 1`. The ramp
/// gets the larger part: its window is what costs the bead its section (a centred ramp
/// lays the paste up to `dv^2 / (8 a)` mm off), a corner's radius only rounds the path
/// more where the design turns.
pub const RAMP_SHARE: f64 = 0.95;
/// Share of the X/Y acceleration limit the corner fillets use on a machine whose head
/// ramps through flow steps: `sqrt(1 - RAMP_SHARE^2)`.
pub const CORNER_SHARE: f64 = 0.312_249_899_919_951_9;

/// Bead section tolerance over `SECTION_WINDOW_MM` of bead that `section_accel` is for.
pub const SECTION_TOLERANCE: f64 = 0.02;
/// Length of bead over which the section is held to `SECTION_TOLERANCE`, mm.
pub const SECTION_WINDOW_MM: f64 = 0.2;

/// Ramp acceleration that keeps the section within `SECTION_TOLERANCE` over
/// `SECTION_WINDOW_MM` through a step of head speed `step` (mm/s): a ramp centred on the
/// step lays the paste `step^2 / (8 a)` mm away from where the flow put it, on each side.
pub fn section_accel(step: f64) -> f64 {
    step * step / (8.0 * SECTION_TOLERANCE * SECTION_WINDOW_MM)
}

/// Shortest ramp window (s) that takes the head through a change of flow speed within
/// acceleration `a`: a change of `dv` in all (mm/s) that a line of time constant `tau`
/// (s) makes, moving from or towards speed `v`, so at most `v / tau` at its start.
///
/// The head at the mean of a window `w` of the planned positions accelerates by the
/// planned speed's change across the window over `w`. A first-order response changes the
/// speed by at most `v (1 - exp(-w / tau))` within any `w` (its steepest stretch is its
/// start), and never by more than `dv`; the window is the shortest `w` for which that
/// over `w` is within `a`. A step (`tau = 0`) needs `dv / a`; a response already within
/// `a` needs none. Treating a fast first-order response as a step sized the window of a
/// machine with real valves several times too long, and the window's mean then smeared
/// the flow's own smooth changes over the bead (issue 22).
pub fn ramp_window(dv: f64, v: f64, tau: f64, a: f64) -> f64 {
    if tau.is_nan() || tau <= 0.0 {
        return ramp_window_of(dv, f64::INFINITY, |_| dv, a);
    }
    ramp_window_of(dv, v / tau, |w| v * (1.0 - libm::exp(-w / tau)), a)
}

/// `ramp_window` for any response whose steepest stretch is its start: one of initial
/// slope `slope` (mm/s^2; infinite for a step) that has changed the speed by `change(w)`
/// after `w` s (`config::flow`'s decays through a shear-thinning paste, whose flow falls
/// faster than the pressure).
pub fn ramp_window_of(dv: f64, slope: f64, change: impl Fn(f64) -> f64, a: f64) -> f64 {
    if dv.is_nan() || a.is_nan() || dv <= 0.0 || a <= 0.0 {
        return 0.0;
    }
    let step = dv / a;
    if slope.is_nan() || slope == f64::INFINITY {
        return step;
    }
    if slope <= a {
        return 0.0;
    }
    let change = |w: f64| dv.min(change(w));
    // `change(w) / w` falls with `w`; `step` always suffices. Bisection to 0.1 us.
    let (mut lo, mut hi) = (0.0f64, step);
    while hi - lo > 1e-7 {
        let mid = 0.5 * (lo + hi);
        if change(mid) <= a * mid {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

impl Config {
    /// Validates this config for a build supporting `N` inlets and converts it to the
    /// core's units. Every problem names its field. The sections are checked in this
    /// order, each by its own `check` (a later one may lean on what an earlier one
    /// accepted), and the first problem found is the one reported.
    pub fn validate<R: Real, const N: usize>(&self) -> Result<Machine<R, N>, ConfigError> {
        let g = channel::check(&self.channel)?;
        let m = &self.motion;
        let timing = control::check(&self.control, motion::step_rate(m)?)?;
        let axes = motion::axes::<R>(m, timing.allowed_rate)?;
        let speeds = motion::speeds(m)?;
        let cx = inlet::Context {
            d: g.d,
            s: g.s,
            v_channel: g.v_channel,
            print_speed: speeds.print,
            allowed_rate: timing.allowed_rate,
        };
        let ins = inlet::check::<R, N>(&self.inlets, &cx)?;
        let a_xy = m.max_accel_mm_s2[0].min(m.max_accel_mm_s2[1]) as f64;
        let dt = timing.period_us as f64 * 1e-6;
        let flow = flow::check(
            &self.inlets,
            &ins,
            (g.s, g.v_channel),
            speeds.print,
            speeds.cap,
            a_xy,
            dt,
        )?;
        let (v_flow_max, demand) = (flow.v_flow_max, flow.demand);
        let corner_radius = v_flow_max * v_flow_max / (a_xy * flow.corner_share);
        Ok(Machine {
            d_mm: R::of(g.d),
            v_channel: Vol::from_mm3(g.v_channel),
            v_hang: Vol::from_mm3(g.v_hang),
            bead_area: R::of(g.s),
            inlets: ins.inlets,
            motion: Motion {
                steps_per_mm: axes.steps_per_mm,
                min_mm: axes.min_mm,
                max_mm: axes.max_mm,
                max_speed: axes.max_speed,
                max_accel: axes.max_accel,
                travel_speed: R::of(speeds.travel.min(m.max_speed_mm_s[0]) as f64),
                max_steps_per_cycle: timing.max_steps_per_cycle,
                wait_for_flow_decay: m.wait_for_flow_decay,
            },
            period_us: timing.period_us,
            dt: R::of(dt),
            v_flow_max: R::of(v_flow_max),
            corner_radius: R::of(corner_radius),
            flow_step: R::of(demand.step),
            flow_accel: R::of(demand.accel),
            ramp_cycles: flow.ramp_cycles,
            ramp_offset_mm: R::of(demand.instant * flow.ramp_cycles as f64 * dt / 8.0),
            q_stop: R::of(speeds.stop_fraction as f64 * v_flow_max * g.s),
            syringes: self.inlets.iter().all(|x| x.syringe.is_some()),
            park: self.pause.validate(&m.travel_min_mm, &m.travel_max_mm)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn seed() -> Config {
        let mut inlets = heapless::Vec::new();
        for (name, mu) in [("paste A", 1.41f32), ("paste B", 3.17)] {
            inlets
                .push(InletConfig {
                    material: heapless::String::try_from(name).unwrap(),
                    rheology: Rheology::Newtonian { viscosity_pa_s: mu },
                    pressure_kpa: Pressure::Auto,
                    valve_open_delay_ms: 0.0,
                    valve_close_delay_ms: 0.0,
                    pressure_rise_ms: 0.0,
                    pressure_decay_ms: 0.0,
                    syringe: None,
                })
                .unwrap();
        }
        Config {
            channel: ChannelConfig {
                nozzle_diameter_mm: 0.8,
                channel_length_mm: 2.4,
                nozzle_height_mm: 0.8,
                layer_height_mm: 0.6,
                line_pitch_mm: 0.8,
                bead_area_mm2: None,
            },
            motion: MotionConfig {
                steps_per_mm: [80.0, 80.0, 400.0],
                travel_min_mm: [0.0; 3],
                travel_max_mm: [200.0, 200.0, 100.0],
                max_speed_mm_s: [150.0, 150.0, 20.0],
                max_accel_mm_s2: [2000.0, 2000.0, 200.0],
                print_speed_mm_s: 10.0,
                print_speed_max_mm_s: 40.0,
                travel_speed_mm_s: 80.0,
                max_step_rate_hz: 50_000.0,
                wait_for_flow_decay: true,
                flow_stop_fraction: 0.005,
            },
            control: ControlConfig::default(),
            inlets,
            pause: PauseConfig::default(),
        }
    }

    #[test]
    fn seed_validates_and_auto_pressure_prints_the_target_speed() {
        let m: Machine<f64, 4> = seed().validate().unwrap();
        // Channel full of paste A at its auto pressure: v = P / (a V_s) / S = 10 mm/s.
        let law = &m.inlets[0].law;
        let q = m.inlets[0].supply_pa / (law.a * m.v_channel.mm3::<f64>());
        assert!((q / m.bead_area - 10.0).abs() < 1e-4, "{}", q / m.bead_area);
        // B's higher pressure through a channel full of A: 10 * 3.17 / 1.41.
        assert!((m.v_flow_max - 10.0 * 3.17 / 1.41).abs() < 1e-3);
        // Each paste through a channel full of itself: the print speed, its flushed one.
        for i in &m.inlets {
            assert!((i.flushed_mm_s - 10.0).abs() < 1e-9, "{}", i.flushed_mm_s);
        }
        // A shear-thinning paste's too, and a given pressure's by its own power: the food
        // pastes at 1.5 times mashed potato's auto pressure run 1.5^(1 / 0.6) as fast.
        let mut c: Config = toml::from_str(include_str!("../configs/food-pastes.toml")).unwrap();
        let m: Machine<f64, 4> = c.clone().validate().unwrap();
        for i in &m.inlets {
            assert!((i.flushed_mm_s - 10.0).abs() < 1e-9, "{}", i.flushed_mm_s);
        }
        let kpa = m.inlets[0].supply_pa * 1.5e-3;
        c.inlets[0].pressure_kpa = Pressure::Kpa(kpa as f32);
        let v = c.validate::<f64, 4>().unwrap().inlets[0].flushed_mm_s;
        let want = 10.0 * libm::pow(kpa as f32 as f64 / (kpa / 1.5), 1.0 / 0.6);
        assert!((v - want).abs() < 1e-6 * want, "{v} against {want}");
    }

    #[test]
    fn each_bad_value_names_its_field() {
        type Edit = fn(&mut Config);
        let cases: [(Edit, &str); 8] = [
            (
                |c| c.channel.nozzle_diameter_mm = 0.0,
                "channel.nozzle_diameter_mm",
            ),
            (
                |c| c.channel.channel_length_mm = f32::NAN,
                "channel.channel_length_mm",
            ),
            (
                |c| c.inlets[1].pressure_kpa = Pressure::Kpa(-3.0),
                "inlet[1].pressure_kpa",
            ),
            (
                |c| c.motion.travel_max_mm[2] = -1.0,
                "motion.travel_max_mm[2]",
            ),
            (
                |c| c.motion.print_speed_max_mm_s = 5.0,
                "motion.print_speed_mm_s",
            ),
            (|c| c.control.rate_hz = 7000, "control.rate_hz"),
            (
                |c| c.inlets[0].valve_open_delay_ms = -1.0,
                "inlet[0].valve_open_delay_ms",
            ),
            (
                |c| c.motion.max_speed_mm_s[0] = 1000.0,
                "motion.max_speed_mm_s[0]",
            ),
        ];
        for (edit, field) in cases {
            let mut c = seed();
            edit(&mut c);
            let e = c.validate::<f32, 4>().unwrap_err();
            let text = std::format!("{e}");
            assert!(text.starts_with(field), "{text} should name {field}");
        }
    }

    /// The food pastes on a 500 mm/s^2 machine with real valves: chocolate (n 0.45)
    /// draining at 20 ms drops the head at first `v / (n tau)`, twice its line's own
    /// rate. Taken at the pressure's rate that asked for a 4.7 ms window, and the head,
    /// riding the flow, braked at 860 mm/s^2 on a chessboard; now the window holds the
    /// whole drop at the ramps' share twice over (the follower sees it ahead, half the
    /// window), and the Newtonian seed keeps its window.
    #[test]
    fn shear_thinning_pastes_size_the_window_by_their_own_fall() {
        let mut c = seed();
        c.motion.max_accel_mm_s2 = [500.0, 500.0, 200.0];
        let laws = [(60.0, 0.6), (120.0, 0.45)];
        for (i, (k, n)) in c.inlets.iter_mut().zip(laws) {
            i.rheology = Rheology::PowerLaw {
                consistency_pa_sn: k,
                flow_index: n,
            };
            i.valve_open_delay_ms = 10.0;
            i.valve_close_delay_ms = 10.0;
            i.pressure_rise_ms = 30.0;
            i.pressure_decay_ms = 20.0;
        }
        let m = c.validate::<f64, 2>().unwrap();
        let a = 500.0 * RAMP_SHARE;
        let w = m.ramp_cycles as f64 * m.period_us as f64 * 1e-6;
        assert!(m.flow_step > 10.0, "{}", m.flow_step);
        assert!(
            w >= 2.0 * m.flow_step / a && w < 2.0 * m.flow_step / a + 3e-4,
            "{w}"
        );
        // The seed's Newtonian pastes at the same times and limit: the window their
        // first-order decay needs (from 22.48 mm/s at 20 ms), not twice a step.
        let mut c = seed();
        c.motion.max_accel_mm_s2 = [1000.0, 1000.0, 200.0];
        for i in c.inlets.iter_mut() {
            i.pressure_rise_ms = 30.0;
            i.pressure_decay_ms = 20.0;
        }
        let m = c.validate::<f64, 2>().unwrap();
        let v = m.v_flow_max;
        let expect = ramp_window(m.flow_step, v, 0.02, 1000.0 * RAMP_SHARE);
        let w = m.ramp_cycles as f64 * 1e-4;
        assert!(w >= expect && w < expect + 2e-4, "{w} {expect}");
    }

    #[test]
    fn more_inlets_than_the_build_supports_are_refused() {
        let c = seed();
        let e = c.validate::<f32, 1>().unwrap_err();
        assert_eq!(e.problem, Problem::TooManyInlets { got: 2, max: 1 });
    }

    /// The seed printhead's instantaneous valves step the head speed by 22.48 mm/s (paste
    /// B's supply through a channel full of paste A): ramps sized to it at `RAMP_SHARE`
    /// of the limit, corners at `CORNER_SHARE`; pressure rise and decay remove them; a
    /// limit whose ramp outlasts the window is refused, naming the field.
    #[test]
    fn flow_steps_size_the_speed_ramps() {
        let m = seed().validate::<f64, 2>().unwrap();
        assert!(
            (m.flow_step - 10.0 * 3.17 / 1.41).abs() < 1e-3,
            "{}",
            m.flow_step
        );
        let t = m.flow_step / (2000.0 * RAMP_SHARE);
        assert_eq!(m.ramp_cycles, (libm::ceil(t / 1e-4) as u32) | 1);
        assert!((m.corner_radius - m.v_flow_max.powi(2) / (2000.0 * CORNER_SHARE)).abs() < 1e-9);
        assert!((RAMP_SHARE.powi(2) + CORNER_SHARE.powi(2) - 1.0).abs() < 1e-12);
        let mut c = seed();
        for i in c.inlets.iter_mut() {
            i.pressure_rise_ms = 30.0;
            i.pressure_decay_ms = 20.0;
        }
        let m = c.validate::<f64, 2>().unwrap();
        assert_eq!((m.flow_step, m.ramp_cycles), (0.0, 1));
        assert!(
            m.flow_accel > 0.0 && m.flow_accel < 2000.0,
            "{}",
            m.flow_accel
        );
        let mut c = seed();
        c.motion.max_accel_mm_s2 = [400.0, 400.0, 200.0];
        let e = c.validate::<f64, 2>().unwrap_err();
        assert_eq!(e.field.key, "max_accel_mm_s2");
        assert!(matches!(e.problem, Problem::RampTooLong { .. }), "{e:?}");
    }

    /// A first-order response is ramped over the window its own steepest stretch needs,
    /// not over a step's: the issue-22 machine's 20 ms decay from 22.48 mm/s (1 124
    /// mm/s^2 at its start) at 900 mm/s^2. Checked against the response integrated.
    #[test]
    fn ramp_windows_follow_the_response() {
        let (v, tau, a) = (22.48, 0.02, 900.0);
        let w = ramp_window(12.48, v, tau, a);
        // 9.2 ms, two thirds of the 13.9 ms a step of 12.48 mm/s would need.
        assert!(w > 0.0 && w < 0.7 * 12.48 / a, "{w}");
        // The speed's largest change over any window of `w` (from the response's start,
        // where it is steepest) is within `a w`, and a tenth shorter it is not.
        let change = |w: f64| v * (1.0 - libm::exp(-w / tau));
        assert!(change(w) <= a * w * (1.0 + 1e-6));
        assert!(change(0.9 * w) > a * 0.9 * w);
        // A step needs dv / a; a response within the limit, none.
        assert_eq!(ramp_window(10.0, 10.0, 0.0, 500.0), 0.02);
        assert_eq!(ramp_window(10.0, 10.0, 0.03, 500.0), 0.0);
        assert_eq!(ramp_window(0.0, 10.0, 0.0, 500.0), 0.0);
    }

    #[test]
    fn a_pressure_that_outruns_the_cap_is_refused() {
        let mut c = seed();
        c.inlets[1].pressure_kpa = Pressure::Kpa(50.0);
        let e = c.validate::<f32, 4>().unwrap_err();
        assert!(
            matches!(
                e.problem,
                Problem::FlowTooFast {
                    inlet: 1,
                    through: 0,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn values_that_cannot_print_sensibly_are_refused_with_their_field() {
        type Edit = fn(&mut Config);
        let cases: [(Edit, &str); 9] = [
            (|c| c.channel.line_pitch_mm = 0.01, "channel.line_pitch_mm"),
            (
                |c| c.channel.layer_height_mm = 0.001,
                "channel.layer_height_mm",
            ),
            (
                |c| c.channel.nozzle_diameter_mm = 0.01,
                "channel.nozzle_diameter_mm",
            ),
            (
                |c| c.motion.steps_per_mm[1] = 0.01,
                "motion.steps_per_mm[1]",
            ),
            (
                |c| c.motion.max_accel_mm_s2[0] = 0.001,
                "motion.max_accel_mm_s2[0]",
            ),
            (
                |c| c.motion.print_speed_mm_s = 1e-4,
                "motion.print_speed_mm_s",
            ),
            (
                |c| c.motion.travel_speed_mm_s = 1e-4,
                "motion.travel_speed_mm_s",
            ),
            (
                |c| c.inlets[0].pressure_kpa = Pressure::Kpa(1e-3),
                "inlet[0].pressure_kpa",
            ),
            (
                |c| c.motion.max_speed_mm_s[2] = 0.01,
                "motion.max_speed_mm_s[2]",
            ),
        ];
        for (edit, field) in cases {
            let mut c = seed();
            edit(&mut c);
            let e = c.validate::<f64, 4>().unwrap_err();
            let text = std::format!("{e}");
            assert!(text.starts_with(field), "{text} should name {field}");
            assert!(text.contains("accepted range"), "{text}");
        }
    }

    #[test]
    fn a_syringe_lag_too_slow_to_follow_is_refused_and_the_bundled_ones_pass() {
        let with_lag = |k: f32, n: f32| {
            let mut c = seed();
            for i in c.inlets.iter_mut() {
                i.syringe = Some(SyringeConfig {
                    steps_per_mm3: 2.264,
                    lag_k: k,
                    lag_n: n,
                });
            }
            c.validate::<f64, 4>()
        };
        // The case: settles in 27 s.
        let e = with_lag(1e-6, 5.0).unwrap_err();
        let text = std::format!("{e}");
        assert!(text.starts_with("inlet[0].syringe.lag_k"), "{text}");
        assert!(text.contains("longest lag"), "{text}");
        for (k, n) in [(45.0, 1.1), (30.0, 1.3), (8.0, 1.5), (20.0, 1.0)] {
            with_lag(k, n).unwrap_or_else(|e| panic!("lag_k {k}, lag_n {n}: {e}"));
        }
    }
}
