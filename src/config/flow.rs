//! The inlets together: the fastest the flow can push the head (checked against
//! `[motion]`'s print-speed cap), and what the flow's changes ask of the head (the speed
//! ramps' window, checked against the ramp ring the executor holds, and the corner radius
//! the fillets keep). It stops at the bounds; the flow model and the ramp follow the flow
//! as it happens.

use super::check::Check;
use super::inlet::Inlets;
use super::{
    ramp_window, ramp_window_of, ConfigError, Inlet, InletConfig, Problem, Syringe, CORNER_SHARE,
    RAMP_SHARE,
};
use crate::capacity::RAMP_CAPACITY;
use crate::real::Real;
use crate::rheology::FlowLaw;

/// What the flow asks of the head, checked.
pub(super) struct Flow {
    /// Fastest the flow can push the head, mm/s.
    pub(super) v_flow_max: f64,
    /// The flow's demand on the head (see `FlowDemand`).
    pub(super) demand: FlowDemand,
    /// Cycles of the speed ramps' window (1: no ramps).
    pub(super) ramp_cycles: u32,
    /// Share of the X/Y acceleration the corner fillets use.
    pub(super) corner_share: f64,
}

/// Checks the flow the inlets make against the print-speed cap `cap` (mm/s) and the
/// ramps it asks for against the ring, at X/Y acceleration `a_xy` and cycle `dt` (s).
pub(super) fn check<R: Real, const N: usize>(
    all: &[InletConfig],
    ins: &Inlets<R, N>,
    geometry: (f64, f64),
    print_speed: f64,
    cap: f32,
    a_xy: f64,
    dt: f64,
) -> Result<Flow, ConfigError> {
    let (s, v_channel) = geometry;
    let mc = Check::section("motion");
    let syringes = all.iter().all(|x| x.syringe.is_some());
    // The junction never exceeds the highest supply and the channel never resists less
    // than when full of its least resistive material, so this bounds the head speed.
    let (v_flow_max, worst) = if syringes {
        syringe_flow_max(all, print_speed * s, s)
    } else {
        valve_flow_max(&ins.laws, &ins.supplies, v_channel, s)
    };
    if v_flow_max > cap as f64 * 1.000_001 {
        return Err(mc.err(
            "print_speed_max_mm_s",
            Problem::FlowTooFast {
                speed: v_flow_max as f32,
                inlet: worst.0,
                through: worst.1,
            },
        ));
    }
    let demand = if syringes {
        syringe_steps(&ins.inlets, print_speed, v_flow_max, a_xy)
    } else {
        valve_steps(&ins.inlets, &ins.laws, &ins.supplies, v_channel, s, a_xy)
    };
    let (corner_share, ramp_cycles) = if demand.step > 0.0 {
        let t = demand.window_s;
        let cycles = libm::ceil(t / dt) as u64 | 1;
        if cycles > RAMP_CAPACITY as u64 - 1 {
            return Err(mc.err(
                "max_accel_mm_s2",
                Problem::RampTooLong {
                    step: demand.step as f32,
                    needed_ms: (t * 1e3) as f32,
                    max_ms: ((RAMP_CAPACITY - 1) as f64 * dt * 1e3) as f32,
                },
            ));
        }
        let reach = (libm::ceil(demand.reach_s / dt) as u64 | 1).min(RAMP_CAPACITY as u64 - 1);
        (CORNER_SHARE, cycles.max(reach) as u32)
    } else {
        (1.0, 1)
    };
    Ok(Flow {
        v_flow_max,
        demand,
        ramp_cycles,
        corner_share,
    })
}

/// Syringes push volume: during a switch the stopping syringe's outflow decays while the
/// starting one's rises; their sum bounds the speed. The highest head speed (mm/s) at
/// plunger rate `rate` (mm^3/s), and the (starting, stopping) inlets that reach it.
fn syringe_flow_max(all: &[InletConfig], rate: f64, s: f64) -> (f64, (u8, u8)) {
    let mut v_flow_max = 0.0f64;
    let mut worst = (0u8, 0u8);
    // The curves in single precision: the board validates in thread mode on an FPU
    // without doubles, where 16 000 double `pow`s took it seconds.
    let response = |k: f64, n: f64, t: f64| -> f64 {
        if t <= 0.0 {
            0.0
        } else {
            1.0 - libm::expf(-(k as f32) * libm::powf(t as f32, n as f32)) as f64
        }
    };
    for (i, a) in all.iter().enumerate() {
        for (j, b) in all.iter().enumerate() {
            let (Some(sa), Some(sb)) = (a.syringe, b.syringe) else {
                continue;
            };
            if i == j {
                // Its own stop and start cancel: the plunger's rate all along.
                if rate / s > v_flow_max {
                    v_flow_max = rate / s;
                    worst = (j as u8, i as u8);
                }
                continue;
            }
            let (ka, na) = (sa.lag_k as f64, sa.lag_n as f64);
            let (kb, nb) = (sb.lag_k as f64, sb.lag_n as f64);
            let t_end = Syringe::settle_time(ka, na).max(Syringe::settle_time(kb, nb));
            for step in 0..=4000 {
                let t = t_end * step as f64 / 4000.0;
                let total = 1.0 - response(ka, na, t) + response(kb, nb, t);
                let v = rate * total / s;
                if v > v_flow_max {
                    v_flow_max = v;
                    worst = (j as u8, i as u8);
                }
            }
        }
    }
    (v_flow_max, worst)
}

/// Valves: each supply through a channel full of each material. The highest head speed
/// (mm/s), and the (inlet, material) that reach it.
fn valve_flow_max(
    laws: &[FlowLaw<f64>],
    supplies: &[f64],
    v_channel: f64,
    s: f64,
) -> (f64, (u8, u8)) {
    let mut v_flow_max = 0.0f64;
    let mut worst = (0u8, 0u8);
    for (i, &p) in supplies.iter().enumerate() {
        for (j, law) in laws.iter().enumerate() {
            let v = law.flow_full(p, v_channel) / s;
            if v > v_flow_max {
                v_flow_max = v;
                worst = (i as u8, j as u8);
            }
        }
    }
    (v_flow_max, worst)
}

/// What the flow asks of the head: the largest change of head speed faster than the X/Y
/// limit follows (mm/s, 0 if none), the largest acceleration the flow asks for where it
/// stays within that limit (mm/s^2), and the ramp window its faster changes need at
/// `RAMP_SHARE` of the limit (s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FlowDemand {
    pub(super) step: f64,
    /// The largest of those changes made at once (a valve whose pressure switches at
    /// once, a syringe's lag taken as a step), mm/s.
    pub(super) instant: f64,
    pub(super) accel: f64,
    pub(super) window_s: f64,
    /// How far ahead (s) the flow's follower must see a shear-thinning paste's fastest
    /// change to slow for it within the limit (`crate::flow_follow`, which takes every
    /// change there): the whole of it at the ramps' share, ahead of the outputs, so the
    /// ring's window is twice that where the ring holds it. At the box's own window (half
    /// of it ahead) the head first slowed as the flow fell, and laid chocolate draining
    /// into mashed potato 4.4 % off over 0.2 mm at 500 mm/s^2.
    pub(super) reach_s: f64,
}

impl FlowDemand {
    /// A change of `dv` by a line of time constant `tau` moving at up to `v`.
    fn event(&mut self, dv: f64, tau: f64, v: f64, a_xy: f64) {
        // A first-order pressure change moves the flow at most `v / tau` (its start).
        let a = if tau > 0.0 { v / tau } else { f64::INFINITY };
        self.demand(dv, a, tau.is_nan() || tau <= 0.0, a_xy);
        self.window_s = self
            .window_s
            .max(ramp_window(dv, v, tau, a_xy * RAMP_SHARE));
    }

    /// A change of `dv` by a line's pressure decaying (`decay`) through a channel full of
    /// one paste: its own curve where the paste thins with shear.
    fn decay(&mut self, dv: f64, decay: &Decay, a_xy: f64) {
        if decay.law.linear || decay.tau.is_nan() || decay.tau <= 0.0 {
            return self.event(dv, decay.tau, decay.v, a_xy);
        }
        let slope = decay.slope();
        self.demand(dv, slope, false, a_xy);
        if slope > a_xy {
            self.reach_s = self.reach_s.max(2.0 * dv / (a_xy * RAMP_SHARE));
        }
        self.window_s = self.window_s.max(ramp_window_of(
            dv,
            slope,
            |w| decay.change(w),
            a_xy * RAMP_SHARE,
        ));
    }

    /// A change of `dv` at up to `a` (mm/s^2), `instant` if made at once.
    fn demand(&mut self, dv: f64, a: f64, instant: bool, a_xy: f64) {
        if a > a_xy {
            self.step = self.step.max(dv);
            if instant {
                self.instant = self.instant.max(dv);
            }
        } else {
            self.accel = self.accel.max(a);
        }
    }
}

/// A line's pressure decaying as `exp(-t / tau)` from `p_pa` through a channel
/// (`v_channel` mm^3) full of a paste of flow law `law`, the head at `v` (mm/s) at its
/// start. The flow is the law's at each pressure: `((P - b) / a)^(1 / n)`, `P` the
/// pressure per channel volume, so a shear-thinning paste (`n < 1`) falls faster than
/// the pressure, at first by `1 / n` (`P / (n (P - b))` with a yield term), and its
/// steepest stretch is still its start. Taken at the pressure's own rate, chocolate
/// (`n` 0.45) draining at 20 ms from 10 mm/s counted 500 mm/s^2, not 1 111: the food
/// pastes on a 500 mm/s^2 machine got a 4.7 ms window, and the head, riding the flow,
/// braked at 862 mm/s^2 on a chessboard.
struct Decay<'a> {
    law: &'a FlowLaw<f64>,
    p_per_vol: f64,
    tau: f64,
    v: f64,
}

impl Decay<'_> {
    fn new<'a>(law: &'a FlowLaw<f64>, p_pa: f64, v_channel: f64, tau: f64, v: f64) -> Decay<'a> {
        Decay {
            law,
            p_per_vol: p_pa / v_channel,
            tau,
            v,
        }
    }

    /// The speed's fall at the start, mm/s^2 (a line that drops at once: as good as
    /// infinite).
    fn slope(&self) -> f64 {
        let tau = self.tau.max(1e-30);
        let (p, b) = (self.p_per_vol, self.law.b);
        if self.law.linear {
            return self.v / tau;
        }
        if p <= b || self.v == 0.0 {
            return 0.0;
        }
        self.v * p / (self.law.n * (p - b) * tau)
    }

    /// The speed's fall `w` s after the start, mm/s.
    fn change(&self, w: f64) -> f64 {
        let (p, b) = (self.p_per_vol, self.law.b);
        if p <= b {
            return 0.0;
        }
        let left = (p * libm::exp(-w / self.tau) - b).max(0.0) / (p - b);
        self.v * (1.0 - libm::pow(left, 1.0 / self.law.n))
    }
}

/// Pneumatic inlets: the flow's demand (valve opening, closing or switching with a
/// channel full of any one material: a mix lies between).
fn valve_steps<R: Real, const N: usize>(
    inlets: &[Inlet<R>],
    laws: &heapless::Vec<FlowLaw<f64>, N>,
    supplies: &heapless::Vec<f64, N>,
    v_channel: f64,
    s: f64,
    a_xy: f64,
) -> FlowDemand {
    let mut d = FlowDemand::default();
    for law in laws.iter() {
        for (j, &pj) in supplies.iter().enumerate() {
            let vj = law.flow_full(pj, v_channel) / s;
            let (rise_j, decay_j) = (inlets[j].rise_s.to_f64(), inlets[j].decay_s.to_f64());
            // A rise through a shear-thinning paste starts slower than the pressure and
            // never changes faster than its own first-order curve: taken as that.
            d.event(vj, rise_j, vj, a_xy);
            d.decay(vj, &Decay::new(law, pj, v_channel, decay_j, vj), a_xy);
            for (i, &pi) in supplies.iter().enumerate() {
                if i == j {
                    continue;
                }
                let vi = law.flow_full(pi, v_channel) / s;
                let closing = Decay::new(law, pi, v_channel, inlets[i].decay_s.to_f64(), vi);
                // Both lines move during a switch; the faster bounds the junction.
                if vj / rise_j.max(1e-30) > closing.slope() {
                    d.event((vj - vi).abs(), rise_j, vj, a_xy);
                } else {
                    d.decay((vj - vi).abs(), &closing, a_xy);
                }
            }
        }
    }
    d
}

/// Syringes: a plunger start, stop or switch moves the flow through the Weibull lag
/// `1 - exp(-k t^n)`, whose steepest slope is `k` at the start for `n = 1`, unbounded for
/// `n < 1`, and `n k t^(n-1) exp(-(n-1)/n)` at `k t^n = (n-1)/n` above.
fn syringe_steps<R: Real>(
    inlets: &[Inlet<R>],
    print_speed: f64,
    v_flow_max: f64,
    a_xy: f64,
) -> FlowDemand {
    let mut d = FlowDemand::default();
    for sy in inlets.iter().filter_map(|i| i.syringe) {
        let (k, n) = (sy.lag_k.to_f64(), sy.lag_n.to_f64());
        let slope = if n < 1.0 {
            f64::INFINITY
        } else if n == 1.0 {
            k
        } else {
            let t = libm::pow((n - 1.0) / (n * k), 1.0 / n);
            n * k * libm::pow(t, n - 1.0) * libm::exp(-(n - 1.0) / n)
        };
        // A switch's two responses move in opposite directions; each one at most
        // `slope` of the print speed per second.
        let a = print_speed * slope;
        if a > a_xy {
            d.step = d.step.max(v_flow_max);
            d.instant = d.instant.max(v_flow_max);
            // Ramped as a step: a Weibull lag is no first-order response.
            d.window_s = d.window_s.max(v_flow_max / (a_xy * RAMP_SHARE));
        } else {
            d.accel = d.accel.max(a);
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rheology::Rheology;

    /// Through a power-law paste (no yield) the flow at a decaying pressure `p e^(-t/tau)`
    /// is `v e^(-t / (n tau))`: the decay's curve and slope are that exponential's, to
    /// rounding; a yield stress makes the start steeper still; a Newtonian paste keeps
    /// the pressure's own rate.
    #[test]
    fn a_shear_thinning_decay_falls_at_its_own_rate() {
        let (tau, v, p, vol) = (0.02, 10.0, 12_000.0, 1.2);
        let thin = FlowLaw::<f64>::new(
            &Rheology::PowerLaw {
                consistency_pa_sn: 120.0,
                flow_index: 0.45,
            },
            0.8,
        );
        let d = Decay::new(&thin, p, vol, tau, v);
        let n = thin.n; // 0.45 as the config holds it (f32)
        assert!(
            (d.slope() - v / (n * tau)).abs() < 1e-9 * v / tau,
            "{}",
            d.slope()
        );
        for w in [1e-4, 1e-3, 5e-3, 0.02, 0.1] {
            let exact = v * (1.0 - libm::exp(-w / (n * tau)));
            assert!(
                (d.change(w) - exact).abs() < 1e-9 * v,
                "{w}: {}",
                d.change(w)
            );
        }
        let yielding = FlowLaw::<f64>::new(
            &Rheology::HerschelBulkley {
                yield_stress_pa: 20.0,
                consistency_pa_sn: 120.0,
                flow_index: 0.45,
            },
            0.8,
        );
        let y = Decay::new(&yielding, p, vol, tau, v);
        assert!(y.slope() > d.slope() && y.change(0.005) > d.change(0.005));
        let newtonian = FlowLaw::<f64>::new(
            &Rheology::Newtonian {
                viscosity_pa_s: 3.17,
            },
            0.8,
        );
        assert_eq!(Decay::new(&newtonian, p, vol, tau, v).slope(), v / tau);
    }

    /// The window for such a decay holds the limit over the response's steepest stretch
    /// and is nearly the shortest that does, as for a first-order one.
    #[test]
    fn its_window_holds_the_limit() {
        let (n, tau, v, a) = (0.45f64, 0.02, 10.0, 475.0);
        let change = |w: f64| v * (1.0 - libm::exp(-w / (n * tau)));
        let w = ramp_window_of(v, v / (n * tau), change, a);
        assert!(change(w) <= a * w * (1.0 + 1e-6), "{w}");
        assert!(change(0.95 * w) > a * 0.95 * w, "{w}");
        // At the pressure's own rate (v / tau = 500 mm/s^2) it asked for 4 ms, not 17.
        assert!(w > 2.0 * ramp_window(v, v, tau, a), "{w}");
    }
}
