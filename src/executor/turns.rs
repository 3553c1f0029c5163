//! The executor's side of slowing at tight fillets (`crate::turn_slow`): the fillets
//! ahead of the head in the plan, and the lag the slowed head carries behind the volume
//! clock (`Executor::lag`, which `follow_path` places the head by). Machines whose
//! valves' windows are sized per decision only (`sizing`); stops at the lag.

use super::plan::Item;
use super::{Executor, Phase};
use crate::real::Real;
use crate::turn_slow::Ahead;
use crate::vol::Vol;

/// Fillets turning less than this (rad) are not slowed for: a segment split where it
/// runs on nearly straight.
const LEAST_SWEEP: f64 = 0.1;

/// Most lag carried, mm: past it the head keeps the plan's speed (the limit gives way
/// before the material boundaries move further along the bead).
const LAG_MAX_MM: f64 = 0.25;

/// Most lead carried, mm: a head kept from slowing as fast as the flow inside a fillet
/// runs ahead of the clock by at most this.
const LEAD_MAX_MM: f64 = 0.1;

impl<R: Real, const N: usize> Executor<R, N> {
    /// The head's lag behind the volume clock for the next cycle, from this cycle's
    /// flow: slowed round a tight fillet, returned after it. Once a cycle while the ring's
    /// mean is narrowed (the machines whose windows are sized per decision; a lag carried
    /// keeps it so): the ring's full window takes the turns by itself.
    pub(super) fn slow_at_turns(&mut self) {
        if !self.turn_slow.on() || !matches!(self.phase, Phase::Print { .. }) {
            return;
        }
        let q = self.last_q;
        let at = self.head - self.lag;
        // The fillet the head is in, if any: the front segment holds the head as the last
        // cycle left it, or the next one does (a U-turn's middle segment may be of no
        // length). Plan volumes compared as integers: the usual cycle, on a straight with
        // nothing carried, converts nothing (a volume's conversion to a float is a
        // software routine on the chip).
        let mut inside = None;
        for item in self.plan.iter().take(2) {
            let Item::Seg(seg) = item else { break };
            if at < seg.u_end {
                if at >= seg.u_arc {
                    inside = seg
                        .fillet
                        .filter(|f| f.sweep.abs() >= R::of(LEAST_SWEEP))
                        .map(|f| (seg.u_arc, f.radius, f.sweep));
                }
                break;
            }
            if seg.last {
                break;
            }
        }
        // While the flow's follower bends the head (`crate::flow_follow`), the turns are
        // its: it aims the head at the flow's speed and takes what a turn leaves of the
        // limit, and a plan slowed under it only had it pull the head back up (608 mm/s^2
        // on Y at a row end of random 0.8 mm cells at 500). A lag carried still returns.
        let inv_s = self.inv_s;
        let v = q * inv_s;
        if self.follow.active() {
            // A fillet this plan takes unslowed is in the ring until the outputs pass it:
            // the follower stays on till then. It stood down as the mean neared such a
            // U-turn (nothing turning at the outputs yet), and the head met it at the
            // flow's speed: real valves whose beads run past the U-turns' share at
            // 1 000 mm/s^2 (`dollop slice`'s note), X 1 678 mm/s^2 there; 1 244 now.
            if inside.is_some_and(|(_, r, _)| self.turn_slow.slows_in(v, r)) {
                self.follow.hold_ring();
            }
            inside = None;
        }
        if inside.is_none() && self.lag == Vol::ZERO {
            self.turn_slow.keep(v);
            return;
        }
        let lag = self.lag.mm3::<R>() * inv_s;
        let mut ahead = Ahead {
            env2: None,
            radius: None,
            span: R::from_u32(2 * self.mean_half + 1) * self.dt,
        };
        if let Some((u_arc, r, sweep)) = inside {
            ahead.radius = Some(r);
            // The ring's mean takes part of the turn (its window may have been sized for
            // it): slow to what the mean needs, worked out once a fillet. Only the fillet
            // the head is in: braking on the straight into it, while a switch's flow rose
            // into the row end, laid 18 % over the section over 0.2 mm of straight bead
            // on the random pattern at 500.
            let plain = self.turn_slow.turn_accel() * r;
            ahead.env2 = Some(if v * v <= plain {
                plain
            } else {
                let key = (u_arc, self.mean_half);
                if self.cap_cache.0 != key {
                    let c = self.turn_slow.box_cap(r, sweep, ahead.span);
                    self.cap_cache = (key, c * c);
                }
                self.cap_cache.1
            });
        }
        if self.turn_slow.idle(v, lag, &ahead) {
            return;
        }
        // Near the bead's end the lag returns by then: twice its share of what is left;
        // no lead within a millimetre of it (the head would reach the end early).
        let (ret, lead_max) = match self.bead_end() {
            Some(end) if end > at => {
                let left = (end - at).mm3::<R>() * inv_s;
                let lead = if left > R::ONE {
                    R::of(LEAD_MAX_MM)
                } else {
                    R::ZERO
                };
                (R::of(2.0) * lag.abs() / left, lead)
            }
            Some(_) => (R::ZERO, R::ZERO),
            None => (R::ZERO, R::of(LEAD_MAX_MM)),
        };
        let dt = self.dt;
        let limits = (R::of(LAG_MAX_MM), lead_max);
        let u = self
            .turn_slow
            .step(v, lag, dt, &ahead, ret.min(R::of(0.2)), limits);
        let grown = Vol::from_mm3((v - u) * dt / inv_s);
        self.lag += grown;
        // What rounding leaves of a returned lag (1e-8 mm^3, a hundred-millionth of a
        // millimetre of bead) is none, so that the head goes idle.
        if self.lag.0.abs() < 100 {
            self.lag = Vol::ZERO;
        } else {
            self.ramp.keep_slow();
        }
    }
}
