//! Material rheology (Newtonian, power law, Herschel-Bulkley) turned into the pressure drop
//! per mm^3 of channel a slug of that material costs at a given flow. Solving the whole
//! channel for Q is `flow_model`'s job.

use crate::real::Real;
use serde::{Deserialize, Serialize};

/// How a paste flows, as the user measures it. Shear stress `tau = tau_y + K * rate^n`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Rheology {
    /// Constant viscosity.
    Newtonian {
        /// Viscosity, Pa s.
        viscosity_pa_s: f32,
    },
    /// Shear-thinning power law `tau = K rate^n`.
    PowerLaw {
        /// Consistency K, Pa s^n.
        consistency_pa_sn: f32,
        /// Flow index n (0.1 ..= 1; 1 is Newtonian).
        flow_index: f32,
    },
    /// Power law above a yield stress: `tau = tau_y + K rate^n`.
    HerschelBulkley {
        /// Yield stress, Pa.
        yield_stress_pa: f32,
        /// Consistency K, Pa s^n.
        consistency_pa_sn: f32,
        /// Flow index n (0.1 ..= 1).
        flow_index: f32,
    },
}

/// Pressure drop of channel content per unit volume: `dP/V = a Q^n + b` (Pa per mm^3, with
/// Q in mm^3/s). For a Newtonian slug this is Poiseuille's `128 mu l / (pi d^4)` per
/// `pi d^2 l / 4` of volume, i.e. `a = 512 mu / (pi^2 d^6)`, `n = 1`, `b = 0`.
///
/// Power law and Herschel-Bulkley use the wall shear stress of a pipe,
/// `tau_w = tau_y + K ((3n+1)/(4n) * 4Q/(pi r^3))^n`, `dP = 2 L tau_w / r`: exact for the
/// power law (Rabinowitsch-Mooney), and for Herschel-Bulkley the usual engineering
/// approximation that ignores the plug core's share of the flow (it overestimates the
/// pressure a little when the plug is wide).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowLaw<R> {
    /// Coefficient of `Q^n`, Pa (mm^3/s)^-n per mm^3.
    pub a: R,
    /// Flow index.
    pub n: R,
    /// Yield term, Pa per mm^3.
    pub b: R,
    /// True when `n == 1` and `b == 0`: the drop is linear in Q (closed-form paths apply).
    pub linear: bool,
}

impl<R: Real> FlowLaw<R> {
    /// The law for `rheology` in a channel of diameter `d_mm`.
    pub fn new(rheology: &Rheology, d_mm: f64) -> Self {
        let r = d_mm / 2.0;
        let pir3 = core::f64::consts::PI * r * r * r;
        let (tau_y, k, n) = match *rheology {
            Rheology::Newtonian { viscosity_pa_s } => (0.0, viscosity_pa_s as f64, 1.0),
            Rheology::PowerLaw {
                consistency_pa_sn,
                flow_index,
            } => (0.0, consistency_pa_sn as f64, flow_index as f64),
            Rheology::HerschelBulkley {
                yield_stress_pa,
                consistency_pa_sn,
                flow_index,
            } => (
                yield_stress_pa as f64,
                consistency_pa_sn as f64,
                flow_index as f64,
            ),
        };
        // dP per volume = 2 tau_w / (pi r^3).
        let shear_per_q = (3.0 * n + 1.0) / (4.0 * n) * 4.0 / pir3;
        let a = 2.0 * k / pir3 * libm::pow(shear_per_q, n);
        let b = 2.0 * tau_y / pir3;
        FlowLaw {
            a: R::of(a),
            n: R::of(n),
            b: R::of(b),
            linear: n == 1.0 && tau_y == 0.0,
        }
    }

    /// Pressure drop per mm^3 of this material at flow `q` (mm^3/s, >= 0).
    #[inline]
    pub fn drop_per_volume(&self, q: R) -> R {
        if self.linear {
            self.a * q
        } else if q <= R::ZERO {
            self.b
        } else {
            self.a * q.powf(self.n) + self.b
        }
    }
}

impl FlowLaw<f64> {
    /// Flow through a channel of `v_channel_mm3` full of this material at pressure `p_pa`,
    /// mm^3/s: `drop_per_volume`'s inverse (f64: at a config's validation only).
    pub fn flow_full(&self, p_pa: f64, v_channel_mm3: f64) -> f64 {
        let per_vol = p_pa / v_channel_mm3;
        if per_vol <= self.b {
            return 0.0;
        }
        libm::pow((per_vol - self.b) / self.a, 1.0 / self.n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newtonian_matches_poiseuille() {
        let d = 0.8f64;
        let mu = 1.41f64;
        let law: FlowLaw<f64> = FlowLaw::new(
            &Rheology::Newtonian {
                viscosity_pa_s: 1.41,
            },
            d,
        );
        let expect = 512.0 * (mu as f32 as f64) / (core::f64::consts::PI.powi(2) * d.powi(6));
        assert!((law.a - expect).abs() / expect < 1e-12);
        // 128 mu L / (pi d^4) for L = 2.4 mm equals a * volume.
        let l = 2.4;
        let vol = core::f64::consts::PI * d * d / 4.0 * l;
        let r_pois = 128.0 * (mu as f32 as f64) * l / (core::f64::consts::PI * d.powi(4));
        assert!((law.drop_per_volume(1.0) * vol - r_pois).abs() / r_pois < 1e-12);
    }

    #[test]
    fn power_law_with_n_one_is_newtonian() {
        let a: FlowLaw<f64> = FlowLaw::new(
            &Rheology::Newtonian {
                viscosity_pa_s: 3.0,
            },
            1.2,
        );
        let b: FlowLaw<f64> = FlowLaw::new(
            &Rheology::PowerLaw {
                consistency_pa_sn: 3.0,
                flow_index: 1.0,
            },
            1.2,
        );
        assert!((a.a - b.a).abs() / a.a < 1e-12);
    }

    /// A full channel's flow is the pressure drop's inverse, a yield stress's plug
    /// included; under the yield stress nothing flows.
    #[test]
    fn a_full_channels_flow_inverts_the_drop() {
        let v_channel = 1.2;
        for r in [
            Rheology::Newtonian {
                viscosity_pa_s: 1.41,
            },
            Rheology::PowerLaw {
                consistency_pa_sn: 120.0,
                flow_index: 0.45,
            },
            Rheology::HerschelBulkley {
                yield_stress_pa: 40.0,
                consistency_pa_sn: 60.0,
                flow_index: 0.6,
            },
        ] {
            let law: FlowLaw<f64> = FlowLaw::new(&r, 0.8);
            for q in [0.5, 4.8, 20.0] {
                let p = law.drop_per_volume(q) * v_channel;
                let back = law.flow_full(p, v_channel);
                assert!((back - q).abs() < 1e-9 * q, "{r:?}: {q} -> {back}");
            }
            if law.b > 0.0 {
                assert_eq!(law.flow_full(0.5 * law.b * v_channel, v_channel), 0.0);
            }
        }
    }
}
