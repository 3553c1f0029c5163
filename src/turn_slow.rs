//! The head's speed through fillets too tight for the flow's speed (issue 22's row-end
//! U-turns on a soft machine): where the segments leave a fillet no wider than the
//! pitch allows (0.4 mm between rows 0.8 mm apart), the flow may bring the head to it
//! faster than the X/Y limit allows round it (paste B opening into a channel still of
//! paste A: 14.7 mm/s on 0.4 mm, 540 mm/s^2 at 500), and no ramp window narrow enough
//! to keep the switch's section can soften it. Here the plan's head slows inside the
//! fillet to the speed at which the ring's mean (a box over the plan) takes it within
//! the ramps' share of the limit (`sqrt(a r)` with no box; `box_cap`), keeps its
//! speed's change round the fillet within what the turn leaves of the limit (vector
//! sum; a flow falling faster is met with a lead ahead of the clock), and returns the
//! lag (or lead) after the turn at a small share of the speed (what that lays off the
//! section). It stops at the speed: the executor keeps the lag, finds the fillet and
//! leaves the turns to the flow's follower while that runs (`executor::turns`).

use crate::real::Real;

/// Share of the ramps' acceleration a fillet's centripetal acceleration may use at the
/// head's capped speed; the speed's change round it keeps `LEAST_SHARE` on top (vector
/// sum: 1.02 times the ramps' share, within the whole limit). On the random pattern at
/// 500 mm/s^2 (X peak, section off over 0.2 mm away from turns): 0.9, 542 and 12.2 %;
/// 1.0, 511 and 8.9 %.
pub const TURN_SHARE: f64 = 1.0;

/// Share of the ramps' acceleration the head brakes at on its way into a tight fillet
/// (`Ahead::env2` with a distance; the executor looks at the fillet the head is in only).
pub const BRAKE_SHARE: f64 = 0.5;

/// Most the lag's return adds to the head's speed, relative: what it lays off the
/// section over the bead after the turn.
pub const RETURN_SHARE: f64 = 0.005;

/// Least of the limit the speed's change keeps inside a fillet met at its capped speed.
const LEAST_SHARE: f64 = 0.2;

/// What the fillets ahead ask of the head's speed now.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ahead<R> {
    /// The least `cap^2 + 2 brake d` over the fillets ahead (`d` mm to each one's start,
    /// 0 inside it), mm^2/s^2; `None` with none ahead.
    pub env2: Option<R>,
    /// The radius of the fillet the head is in, mm, if it is in one.
    pub radius: Option<R>,
    /// The span of the ring's mean (a box over the plan), s.
    pub span: R,
}

/// The head's speed along the path while a tight fillet is near or a lag is carried.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurnSlow<R> {
    /// Head speed along the path, mm/s (the plan's own while idle).
    u: R,
    /// The ramps' acceleration (the X/Y limit's share), mm/s^2; 0: never on.
    a: R,
    /// The head's speed's upper envelope, falling at half the speed's change a fillet
    /// allows (mm/s): what a lead holds the head's speed to within the mean's box.
    peak: R,
}

impl<R: Real> TurnSlow<R> {
    /// Never on.
    pub const fn off() -> Self {
        TurnSlow {
            u: R::ZERO,
            a: R::ZERO,
            peak: R::ZERO,
        }
    }

    /// Idle, for ramps of acceleration `a` mm/s^2 (not finite or not positive: off).
    pub fn reset(&mut self, a: R) {
        self.u = R::ZERO;
        self.a = if a.is_finite() && a > R::ZERO {
            a
        } else {
            R::ZERO
        };
    }

    /// Whether it is configured at all.
    pub fn on(&self) -> bool {
        self.a > R::ZERO
    }

    /// Centripetal acceleration a fillet may take at the head's capped speed, mm/s^2.
    pub fn turn_accel(&self) -> R {
        self.a * R::of(TURN_SHARE)
    }

    /// Deceleration into a tight fillet, mm/s^2.
    pub fn brake(&self) -> R {
        self.a * R::of(BRAKE_SHARE)
    }

    /// The speed (mm/s) at which the ring's mean, a box of `span` s over the path, takes
    /// a fillet of radius `r` (mm) and sweep `sweep` (rad, either sign) within
    /// `turn_accel`. The box's velocity changes by `2 u sin(phi / 2)` across it, `phi`
    /// the heading's change within it (`u span / r`, at most the sweep), so its
    /// acceleration is that over `span`: with `x = u span / (2 r)`,
    /// `4 r x sin(x) / span^2` while the box holds part of the arc. `sqrt(turn_accel r)`
    /// with no box; none (1e6 mm/s) where the box holds all of the arc at that speed. A
    /// box partly over the turn asks less slowing than the plain cap did (the 0.6 mm
    /// stripes at 500 went 8.6 to 11.9 % off over 0.2 mm away from turns with that).
    /// Three Newton steps on `x sin x`, from below its root.
    pub fn box_cap(&self, r: R, sweep: R, span: R) -> R {
        let a = self.turn_accel();
        let half = (sweep.abs() * R::of(0.5)).min(R::of(core::f64::consts::FRAC_PI_2));
        if !(span > R::ZERO && r > R::ZERO) {
            return (a * r).max(R::ZERO).sqrt();
        }
        let k = a * span * span / (R::of(4.0) * r);
        let (s, _) = half.sin_cos();
        if k >= half * s {
            // The box holds the whole arc at the capped speed: a decision sized the
            // window for this turn (`switch_window::turn_window`), and the head is
            // left to it. Slowing there to `sweep`'s chord over the span (11.2 mm/s on
            // the 0.6 mm stripes' 0.2 mm row ends at 500, 12.4 planned) bought nothing
            // (X 481 / Y 299 against 481 / 305) and took the section through the turns
            // from 22.2 to 25.8 % off.
            return R::of(1.0e6);
        }
        // `x sin x <= x^2`, so `sqrt(k)` is at or below the root and `x sin x` is convex
        // on [0, pi / 2]: Newton's steps from below overshoot once, then stay above and
        // fall; the last is clamped into [0, half].
        let mut x = k.sqrt().min(half);
        for _ in 0..3 {
            let (sn, cs) = x.sin_cos();
            let d = sn + x * cs;
            if !(d.is_finite() && d > R::ZERO) {
                break;
            }
            x -= (x * sn - k) / d;
            x = x.max(R::ZERO).min(half);
        }
        R::of(2.0) * r * x / span
    }

    /// Whether the head at `v` mm/s in a fillet of radius `r` mm leaves the plan's speed:
    /// past half the speed the fillet allows (`turn_accel`).
    pub fn slows_in(&self, v: R, r: R) -> bool {
        v * v > R::of(0.25) * self.turn_accel() * r
    }

    /// Keeps the plan's speed `v`: nothing carried, no fillet.
    pub fn keep(&mut self, v: R) {
        self.u = v;
    }

    /// Whether the head need not leave the plan's speed `v` (mm/s): no lag carried, and
    /// the fillets ahead and the one it is in allow `v`. Then it keeps `v`.
    pub fn idle(&mut self, v: R, lag: R, ahead: &Ahead<R>) -> bool {
        let free = lag == R::ZERO
            && ahead.env2.is_none_or(|e| v * v <= e)
            && ahead.radius.is_none_or(|r| !self.slows_in(v, r));
        if free {
            self.u = v;
        }
        free
    }

    /// The head's speed this cycle (mm/s) for the plan's `v`, with `lag` mm carried
    /// behind the volume clock (negative: a lead ahead of it), cycles of `dt` s, the
    /// lag's return at up to `ret` of the speed (at least `RETURN_SHARE`; more near a
    /// bead's end), at most `lag_max` mm of lag (past it the head keeps the plan's
    /// speed) and `lead_max` of lead.
    pub fn step(&mut self, v: R, lag: R, dt: R, ahead: &Ahead<R>, ret: R, limits: (R, R)) -> R {
        let (lag_max, lead_max) = limits;
        let ret = ret.max(R::of(RETURN_SHARE));
        let mut u = if lag > R::ZERO {
            v * (R::ONE + ret)
        } else if lag < R::ZERO {
            v * (R::ONE - ret)
        } else {
            v
        };
        // A lag or a lead returns to the clock, never past it.
        if lag > R::ZERO {
            u = u.min(v + lag / dt);
        } else if lag < R::ZERO {
            u = u.max(v + lag / dt);
        }
        // Inside a fillet the speed's change gets what its turn leaves of the limit by
        // the vector sum (never under `LEAST_SHARE`), up and down, whether that builds a
        // lag or a lead: a flow collapsing inside a U-turn (13 to 3.5 mm/s in 30 ms) is
        // met with a lead. On a straight the plan's own, as the ring's window ramps it:
        // a head held under the flow there (a switch's flow rising into a row end) laid
        // 18 % over the section over 0.2 mm of straight bead.
        if let Some(r) = ahead.radius.filter(|&r| r > R::ZERO) {
            let c = self.u * self.u / r;
            let least = self.a * R::of(LEAST_SHARE);
            let left = self.a * self.a - c * c;
            let acc = if left > least * least {
                left.sqrt()
            } else {
                least
            };
            u = u.min(self.u + acc * dt);
            // Down, at `acc` a cycle, or (the looser) a drop of up to `acc span / 2` at
            // once under an envelope falling at `acc / 2`, which the mean's box of `span`
            // takes within `acc` (a U-turn's flow collapse met under a box sized for the
            // turn then asks little lead: the 0.6 mm stripes at 500 went 8.6 to 10.6 %
            // off over 0.2 mm away from turns with a lead at `acc` a cycle alone).
            let half = acc * R::of(0.5);
            self.peak = (self.peak - half * dt).max(self.u);
            if lag > -lead_max {
                u = u.max((self.peak - half * ahead.span).min(self.u - acc * dt));
            }
        } else {
            self.peak = self.u;
        }
        if let Some(e) = ahead.env2 {
            if u * u > e {
                u = u.min(e.max(R::ZERO).sqrt());
            }
        }
        if lag >= lag_max {
            u = u.max(v);
        }
        u = u.max(R::ZERO);
        self.u = u;
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1e-4;

    /// The plan's speed `v(t)` through a U-turn of radius `r` that starts `d0` mm ahead:
    /// the head slows to `sqrt(TURN_SHARE a r)` before it, stays within the limit round
    /// it (the vector sum of its speed's change and the turn), and returns the lag after
    /// it at `RETURN_SHARE` of the speed, never ahead of the volume clock.
    fn run(v: impl Fn(f64) -> f64, r: f64, d0: f64, a: f64) -> (f64, f64, f64) {
        run_lead(v, r, d0, a, 0.0).0
    }

    /// `run` with up to `lead` mm of lead; also the most lead carried.
    fn run_lead(
        v: impl Fn(f64) -> f64,
        r: f64,
        d0: f64,
        a: f64,
        lead: f64,
    ) -> ((f64, f64, f64), f64) {
        let mut ts: TurnSlow<f64> = TurnSlow::off();
        ts.reset(a);
        let sweep = core::f64::consts::PI * r;
        let (mut s_plan, mut s_head, mut lag) = (0.0f64, 0.0f64, 0.0f64);
        let (mut peak, mut lag_max, mut prev_u) = (0.0f64, 0.0f64, None::<f64>);
        let mut lead_max = 0.0f64;
        let mut t = 0.0;
        while s_head < d0 + sweep + 40.0 {
            let vp = v(t);
            s_plan += vp * DT;
            // Where the head is against the fillet.
            let d = d0 - s_head;
            let inside = d <= 0.0 && d > -sweep;
            let ahead = Ahead {
                env2: (d > 0.0 || inside)
                    .then(|| ts.turn_accel() * r + 2.0 * ts.brake() * d.max(0.0)),
                radius: inside.then_some(r),
                span: 0.0,
            };
            let u = if ts.idle(vp, lag, &ahead) {
                vp
            } else {
                ts.step(vp, lag, DT, &ahead, 0.0, (1.0, lead))
            };
            s_head += u * DT;
            lag = s_plan - s_head;
            assert!(lag >= -lead - 1e-6, "ahead of the clock at {t}: {lag}");
            lag_max = lag_max.max(lag);
            lead_max = lead_max.max(-lag);
            // On the straight past the turn the head steps back up to the plan's speed
            // (at most the lag's share over it), for the ring's window to ramp.
            if let Some(p) = prev_u.filter(|_| d > -sweep) {
                let tan = (u - p) / DT;
                let cen = if inside { u * u / r } else { 0.0 };
                peak = peak.max((tan * tan + cen * cen).sqrt());
            }
            prev_u = Some(u);
            t += DT;
        }
        ((peak, lag_max, lag), lead_max)
    }

    #[test]
    fn a_u_turn_met_fast_is_taken_within_the_limit_and_the_lag_returns() {
        let a = 475.0;
        // The plan at 14.7 mm/s on 0.4 mm: 540 mm/s^2 unslowed.
        // Within the whole X/Y limit: the turn at the ramps' share, the speed's change
        // at `LEAST_SHARE` of it (measured 486 of 500).
        let whole = a / crate::config::RAMP_SHARE;
        let (peak, most, left) = run(|_| 14.7, 0.4, 1.0, a);
        assert!(peak <= whole, "{peak}");
        // The lag: (14.7 - sqrt(TURN_SHARE a 0.4)) over the turn's time and the brake.
        let cap = (TURN_SHARE * a * 0.4).sqrt();
        let turn = (14.7 - cap) * core::f64::consts::PI * 0.4 / cap;
        assert!(most > turn && most < 1.5 * turn, "{most} against {turn}");
        // 40 mm after the turn at half a percent returns 0.2 mm.
        assert!(left < 1e-6, "{left} left");
        // The plan's speed rising round the turn (a switch's flow, 7 to 14.7 mm/s at
        // 300 mm/s^2): the speed's change and the turn within the limit by their sum.
        let (peak, most, left) = run(|t| (7.0 + 300.0 * t).min(14.7), 0.4, 0.1, a);
        assert!(peak <= whole, "{peak}");
        assert!(most > 0.0 && left < 1e-6, "{most} {left}");
    }

    /// The box's cap: the plain `sqrt(a r)` with no box, and for a box, the speed at which
    /// the box's velocity change across its span (the heading's change within it, from
    /// the arc's own geometry) is `turn_accel` times the span.
    #[test]
    fn a_box_over_the_fillet_raises_its_speed() {
        let mut ts: TurnSlow<f64> = TurnSlow::off();
        ts.reset(475.0);
        let a = ts.turn_accel();
        let plain = ts.box_cap(0.4, core::f64::consts::PI, 0.0);
        assert!((plain - (a * 0.4).sqrt()).abs() < 1e-9);
        use core::f64::consts::{FRAC_PI_2, PI};
        // A box over the whole arc at the capped speed: none.
        assert_eq!(ts.box_cap(0.2, FRAC_PI_2, 0.036), 1.0e6);
        for (r, sweep, span) in [(0.4, PI, 0.0085), (0.4, FRAC_PI_2, 0.02), (0.2, PI, 0.01)] {
            let u = ts.box_cap(r, sweep, span);
            // The box's largest acceleration at `u`: its velocity change across the span.
            let phi = (u * span / r).min(sweep);
            let peak = 2.0 * u * (phi / 2.0).sin() / span;
            assert!(
                (peak - a).abs() < 1e-3 * a,
                "{r} {sweep} {span}: {u} -> {peak}"
            );
            assert!(u >= plain * (r / 0.4f64).sqrt() - 1e-9);
        }
    }

    /// The flow collapsing inside the U-turn (13 to 3.4 mm/s, `exp(-t / 8 ms)` from a
    /// tenth of a second in): the head's speed falls within what the turn leaves of the
    /// limit, ahead of the clock by a lead that returns; with no lead allowed it falls
    /// with the flow, past the limit.
    #[test]
    fn a_flow_collapsing_in_the_turn_is_met_with_a_lead() {
        let a = 475.0;
        let whole = a / crate::config::RAMP_SHARE;
        let flow = |t: f64| {
            let late = (t - 0.1f64).max(0.0);
            3.4 + (13.0 - 3.4) * (-late / 0.008).exp()
        };
        // The U-turn starts 1.2 mm in (92 ms at 13 mm/s): the collapse meets it.
        let ((peak, _, left), lead) = run_lead(flow, 0.4, 1.2, a, 0.1);
        assert!(peak <= whole, "{peak}");
        assert!(lead > 0.0 && lead < 0.1, "{lead}");
        assert!(left.abs() < 1e-6, "{left} left");
        let ((peak, _, _), lead) = run_lead(flow, 0.4, 1.2, a, 0.0);
        assert!(peak > whole && lead == 0.0, "{peak} {lead}");
    }

    #[test]
    fn a_fillet_within_the_limit_leaves_the_plan_alone() {
        // 10 mm/s on 0.4 mm: 250 mm/s^2.
        let (peak, most, _) = run(|_| 10.0, 0.4, 1.0, 475.0);
        assert_eq!(most, 0.0);
        assert!(peak <= 10.0 * 10.0 / 0.4 + 1e-9, "{peak}");
    }
}
