//! A bead's section changing mid-bead (job format 2's `Command::Section` between two print
//! segments of one bead, issue 26): the flow does not change there, the head's speed
//! `v = Q / S` does. A step of `1 / S` would step the head's speed at once (by up to 88 %
//! of the flow's top speed over the eight-fold range of sections), which no X/Y limit
//! follows; this spreads it over a staircase in plan volume. Its mean acceleration at the
//! flow's top is `TAPER_SHARE` of the X/Y limit, and each stair steps the speed by at most
//! what that share gives over 1 ms (a machine without speed ramps shows each stair as is;
//! one with ramps smooths it further in its window). Linear in volume, the inverse section
//! keeps the acceleration constant at constant flow: `dv/dt = Q^2 d(1/S)/dV`. It stops at
//! the plan: which straight lengths lie on which stair; laying them is the executor's.

use crate::real::Real;

/// Most stairs a change of section takes. Each stair is a plan item of its own, so the
/// plan keeps this many places free while a change is under way (`Executor::room`);
/// eight keep a stair under 2 % of the flow's top speed for sections up to 1.2 times
/// apart, and the largest change (eight times) within 11 %.
pub const TAPER_STAIRS: usize = 8;

/// Share of the X/Y acceleration limit the taper's mean acceleration takes at the flow's
/// top (`Machine::v_flow_max` through the config's section): the other half is left to
/// the flow's own changes under it and to the corners, which it may meet. Printing at
/// the usual flow, under half the top, it takes under a quarter of that.
pub const TAPER_SHARE: f64 = 0.5;

/// Time over which one stair's speed step is held within the share, s: a stair steps the
/// speed by at most `TAPER_SHARE` of the limit times this.
pub const STAIR_S: f64 = 1.0e-3;

/// Which section the plan lays now, and where a change under way goes.
#[derive(Clone, Copy, Debug)]
pub struct Taper<R> {
    /// The stair laid now: section, mm^2, and its inverse.
    s: R,
    inv: R,
    /// The section asked for (the last stair's inverse).
    target: R,
    /// Change of the inverse a stair, 1/mm^2.
    step: R,
    /// Volume each stair holds, mm^3, and what is left of the current one.
    stair_vol: R,
    left: R,
    /// Stairs still to come (0: none, the plan lays `target`).
    stairs: u8,
}

impl<R: Real> Taper<R> {
    /// No section (the executor's constant constructor: all zeros).
    pub const fn new() -> Self {
        Taper {
            s: R::ZERO,
            inv: R::ZERO,
            target: R::ZERO,
            step: R::ZERO,
            stair_vol: R::ZERO,
            left: R::ZERO,
            stairs: 0,
        }
    }

    /// Lays section `s` (mm^2, inverse `inv`) from here, at once: between beads.
    pub fn set(&mut self, s: R, inv: R) {
        self.s = s;
        self.inv = inv;
        self.target = inv;
        self.stairs = 0;
    }

    /// The section the plan lays now (mm^2) and its inverse.
    pub fn now(&self) -> (R, R) {
        (self.s, self.inv)
    }

    /// The inverse section the plan is heading to.
    pub fn target(&self) -> R {
        self.target
    }

    /// A change is under way: stairs are still to come.
    pub fn active(&self) -> bool {
        self.stairs > 0
    }

    /// Starts the change to section `s` (inverse `inv`) mid-bead, for a flow of at most
    /// `q_max` (mm^3/s) and an X/Y limit of `accel` (mm/s^2). The first stair starts here.
    pub fn start(&mut self, s: R, inv: R, q_max: R, accel: R) {
        let d = inv - self.inv;
        let a = accel * R::of(TAPER_SHARE);
        let dv = (q_max * d).abs();
        let per_stair = a * R::of(STAIR_S);
        let stairs = if dv.is_finite() && per_stair > R::ZERO {
            let n = (dv / per_stair).to_f64();
            libm::ceil(n).clamp(1.0, TAPER_STAIRS as f64) as u8
        } else {
            1
        };
        // The whole change's volume at mean acceleration `a` at the top flow.
        let total = q_max * q_max * d.abs() / a;
        if stairs <= 1 || !(total.is_finite() && total > R::ZERO) {
            self.set(s, inv);
            return;
        }
        let n = R::from_u32(stairs as u32);
        self.target = inv;
        self.step = d / n;
        self.stair_vol = total / n;
        self.stairs = stairs;
        self.next_stair();
    }

    /// Steps to the next stair (the last one is the target, exactly).
    fn next_stair(&mut self) {
        self.stairs -= 1;
        self.inv = if self.stairs == 0 {
            self.target
        } else {
            self.inv + self.step
        };
        self.s = R::ONE / self.inv;
        self.left = self.stair_vol;
    }

    /// Lays `len` mm of straight bead from here: the length laid on the current stair
    /// before the next one starts (then on it), or None when all of `len` lies on the
    /// current stair. Some at most `TAPER_STAIRS` times a change.
    pub fn take(&mut self, len: R) -> Option<R> {
        if self.stairs == 0 {
            return None;
        }
        let l = self.left * self.inv;
        if l < len {
            self.next_stair();
            Some(l)
        } else {
            self.left -= len * self.s;
            None
        }
    }
}

impl<R: Real> Default for Taper<R> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A change from 0.46 to 0.28 mm^2 at a top flow of 10 mm^3/s on a 2 000 mm/s^2
    /// machine: eight stairs, the speed stepping by at most the share over 1 ms a stair
    /// (capped: the change asks for 13), the mean acceleration at the top flow the share,
    /// and the last stair exactly the target.
    #[test]
    fn a_change_is_a_staircase_at_the_share_of_the_limit() {
        let (s0, s1, q, a) = (0.46f64, 0.28f64, 10.0f64, 2000.0f64);
        let mut t: Taper<f64> = Taper::new();
        t.set(s0, 1.0 / s0);
        t.start(s1, 1.0 / s1, q, a);
        assert!(t.active());
        let d = 1.0 / s1 - 1.0 / s0;
        let mut invs = vec![t.now().1];
        let mut laid = 0.0;
        let mut vol = 0.0;
        // Laid in 0.05 mm pieces, as short segments do.
        for _ in 0..200 {
            let mut left = 0.05;
            while let Some(l) = t.take(left) {
                vol += l / invs.last().unwrap();
                left -= l;
                invs.push(t.now().1);
            }
            vol += left / invs.last().unwrap();
            laid += 0.05;
            if !t.active() {
                break;
            }
        }
        assert_eq!(invs.len(), TAPER_STAIRS);
        assert_eq!(*invs.last().unwrap(), 1.0 / s1);
        let steps: Vec<f64> = invs.windows(2).map(|w| w[1] - w[0]).collect();
        for s in &steps {
            assert!((s - d / 8.0).abs() < 1e-12, "{s}");
        }
        // The volume the stairs before the last hold: the mean acceleration's.
        let total = q * q * d / (a * TAPER_SHARE);
        let before_last = total * 7.0 / 8.0;
        assert!(
            (vol - before_last).abs() < 0.05 / s1,
            "{vol} vs {before_last} (laid {laid} mm)"
        );
        // A small change is one step, at once.
        t.set(0.40, 1.0 / 0.40);
        t.start(0.401, 1.0 / 0.401, q, a);
        assert!(!t.active());
        assert_eq!(t.now().1, 1.0 / 0.401);
        // A machine with no flow (unconfigured) changes at once, never divides by zero.
        t.start(0.5, 2.0, 0.0, a);
        assert!(!t.active() && t.now() == (0.5, 2.0));
        t.start(0.4, 2.5, q, 0.0);
        assert!(!t.active() && t.now() == (0.4, 2.5));
    }
}
