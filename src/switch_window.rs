//! Ramp windows per valve decision (issue 22): at the decision to open, switch or close
//! the valves, the window the head's speed ramp needs for the flow change they are about
//! to make, sized from the channel's contents then. The machine's one window is sized
//! for the fastest change the valves can make anywhere (paste B's line closing into a
//! channel still full of paste A); most decisions make far slower ones, and that window's
//! mean only smears them over the bead. This sizes one decision's window; the ramp ring
//! narrows or widens its mean to it (`Ramp::set_goal`); what is not sized here (steps of
//! pressure, power-law pastes, syringes, unequal dead times) keeps the machine's window.

use crate::config::{Machine, RAMP_SHARE};
use crate::flow_model::FlowModel;
use crate::real::Real;

/// Whether switching from the inlets of `closing` to inlet `opening` (bit masks, one bit
/// for the opening) moves the head's speed within the ramps' share of the X/Y limit with
/// no window. Newtonian contents and pneumatic lines with first-order pressure changes
/// of equal dead times only; anything else (a step of pressure, a power-law paste, a
/// syringe) is `false`, the machine's window.
///
/// The closing line's flow (the channel's now, `v_c`) decays as `exp(-t / tau_d)`, the
/// opening one's (its supply through the contents now, `v_o`) rises as
/// `1 - exp(-t / tau_r)`; the head's acceleration is
/// `a(t) = v_o / tau_r exp(-t / tau_r) - v_c / tau_d exp(-t / tau_d)`, largest in size at
/// the start or where its derivative vanishes. The channel's contents change as the new
/// paste enters it, over the channel's transit, far slower.
/// Half the window (frames) the head's mean needs for the valves going from the inlets of
/// `closing` (bit mask) to `opening` (none: closing only), or `None` for the machine's.
/// Newtonian contents and one closing, one opening pneumatic line of first-order
/// pressure changes with equal dead times only.
///
/// After the dead time the closing line's pressure decays as `exp(-t / tau_d)` and the
/// opening one's rises as `1 - exp(-t / tau_r)`; the junction follows the higher, so the
/// head's speed (the flow over the bead section) is
/// `v(t) = max(v_c exp(-t / tau_d), v_o (1 - exp(-t / tau_r)))`, `v_c` the channel's
/// speed now and `v_o` the opening line's supply through the contents now. The window
/// is the longer of the decay's from its start and the rise's from where it overtakes
/// the decay. The contents change as the new paste enters the channel, over its
/// transit, far slower. Once per decision: three Newton steps and two more per window
/// (an `expf` or two each), never per tick.
pub fn switch_half<R: Real, const N: usize>(
    m: &Machine<R, N>,
    model: &FlowModel<R, N>,
    closing: u32,
    opening: Option<u8>,
) -> Option<u32> {
    // A channel holding more than one paste changes its resistance as they move, on top
    // of what the valves do: the machine's window (0.6 mm stripes at 500 mm/s^2 reached
    // 685 mm/s^2 sized as if it held one).
    if model.syringes() || !model.all_linear() || model.channel().len() > 1 {
        return None;
    }
    let open = match opening {
        Some(o) => Some(m.inlets.get(o as usize)?),
        None => None,
    };
    let mut close = None;
    for (i, inlet) in m.inlets.iter().enumerate() {
        if closing & (1 << i) != 0 && opening != Some(i as u8) {
            if close.is_some() {
                return None;
            }
            close = Some(inlet);
        }
    }
    let r = model.resistance_linear().to_f32();
    let s = m.bead_area.to_f32();
    let (tau_r, tau_d) = (
        open.map_or(1.0, |o| o.rise_s.to_f32()),
        close.map_or(1.0, |c| c.decay_s.to_f32()),
    );
    if !(r > 0.0 && s > 0.0 && tau_r > 0.0 && tau_d > 0.0) {
        return None;
    }
    if let (Some(c), Some(o)) = (close, open) {
        if c.close_delay_s.to_f32() != o.open_delay_s.to_f32() {
            return None;
        }
    }
    let v_o = open.map_or(0.0, |o| o.supply_pa.to_f32() / r / s);
    let v_c = if close.is_some() {
        model.q().to_f32() / s
    } else {
        0.0
    };
    let limit = m.motion.max_accel[0].min(m.motion.max_accel[1]).to_f32() * RAMP_SHARE as f32;
    // The decay from the kink: the steepest chord of a falling exponential starts there.
    let mut w = window(v_c, tau_d, limit);
    if v_o > 0.0 {
        // The rise takes over where it crosses the decay; Newton from below the crossing
        // (the difference is concave and rising) stays below it, so what is left of the
        // rise is never underestimated.
        let mut t = if v_c > 0.0 {
            v_c / (v_o / tau_r + v_c / tau_d)
        } else {
            0.0
        };
        if v_c > 0.0 {
            for _ in 0..3 {
                let (er, ed) = (libm::expf(-t / tau_r), libm::expf(-t / tau_d));
                let g = v_o * (1.0 - er) - v_c * ed;
                let dg = v_o / tau_r * er + v_c / tau_d * ed;
                if !(g < 0.0 && dg > 0.0) {
                    break;
                }
                t -= g / dg;
            }
        }
        w = w.max(window(v_o * libm::expf(-t / tau_r), tau_r, limit));
    }
    let cycles = w / m.dt().to_f32();
    let half = m.ramp_cycles / 2;
    if cycles.is_nan() || cycles < 0.0 || cycles >= (2 * half + 1) as f32 {
        return None;
    }
    let h = (libm::ceilf(cycles) as u32) / 2;
    Some(h)
}

/// The shortest window (s) over which the head's mean takes a first-order change of `v`
/// (mm/s, time constant `tau`, from its kink) within `limit`, or a little longer: any
/// chord of the change over `w` is at most `v (1 - exp(-w / tau)) / w`, so `x = w / tau`
/// is the root of `f(x) = 1 - exp(-x) - r x`, `r = limit tau / v`. `f` is concave, and
/// `1 - exp(-x) <= 2 x / (2 + x)` puts `2 (1 / r - 1)` at or past the root: Newton's
/// steps from there stay at or past it.
fn window(v: f32, tau: f32, limit: f32) -> f32 {
    let r = limit * tau / v;
    if r.is_nan() || r >= 1.0 {
        return 0.0;
    }
    let mut x = 2.0 * (1.0 / r - 1.0);
    for _ in 0..2 {
        let e = libm::expf(-x);
        let (f, df) = (1.0 - e - r * x, e - r);
        if !(f < 0.0 && df < 0.0) {
            break;
        }
        x -= f / df;
    }
    x * tau
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window is the f64 reference's (`config::ramp_window`, bisection) or a little
    /// longer, never shorter: within the limit, and within 1 % of the shortest.
    #[test]
    fn windows_hold_the_limit_and_are_nearly_the_shortest() {
        for (v, tau, a) in [
            (10.0f32, 0.02f32, 475.0f32),
            (22.48, 0.03, 475.0),
            (16.3, 0.03, 475.0),
            (22.48, 0.02, 950.0),
            (5.0, 0.001, 200.0),
        ] {
            let w = window(v, tau, a);
            let reference = crate::config::ramp_window(v as f64, v as f64, tau as f64, a as f64);
            assert!(
                w as f64 >= reference * (1.0 - 1e-4) && (w as f64) <= reference * 1.01 + 1e-6,
                "{v} {tau} {a}: {w} against {reference}"
            );
            assert!(
                v * (1.0 - libm::expf(-w / tau)) <= a * w * 1.0001,
                "{v} {tau} {a}"
            );
        }
        // Within the limit already, or nothing to change: no window.
        assert_eq!(window(10.0, 0.03, 475.0), 0.0);
        assert_eq!(window(0.0, 0.03, 475.0), 0.0);
    }
}
