//! Blends the ramp mean's width changes into the head's motion (issue 22). A valve
//! decision narrows or widens the ring's mean a frame a push (`Ramp::set_goal`); the mean
//! over `h` frames either side of a path accelerating at `x''` (a fillet, the flow
//! changing speed) lies `x'' (h dt)^2 / 6` inside it, so each frame of width moves the
//! head, a velocity step of `x'' h dt / 3` where the change starts and where it stops
//! (1.3 mm/s on the random pattern at 500 mm/s^2, read as 2 000 mm/s^2 in 1 ms
//! differences). This takes each push's move into an offset and lets the offset return
//! to zero as a critically damped second-order system, slow enough that its acceleration
//! stays within a share of the path's own. It stops at the offset: the ring adds it to
//! its sum (`Ramp::push_narrow`), on its slow path only.

/// Share of the path's acceleration the offset's return may add: the offset is at most
/// the mean's inset at the widest window, `x'' (H dt)^2 / 6`, and a critically damped
/// return from rest accelerates at most `w^2` times it.
const SHARE: f32 = 0.2;

/// Below this (position units, and units a push), the offset is spent: dropping it moves
/// the head by 0.005 um, 5 mm/s^2 in 1 ms differences.
const SPENT: f32 = 0.05;

/// The offset (X, Y, position units of the ring) and its rate, and the part of it the
/// ring's sum holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WidthBlend {
    offset: [f32; 2],
    rate: [f32; 2],
    /// `offset` times the mean's span, rounded, as the ring's sum holds it.
    held: [i32; 2],
    /// `(w dt)^2` and `2 w dt` of the return, per push.
    k1: f32,
    k2: f32,
    /// `RETURNING` while an offset returns, `BENT` while the follower bends the mean: one
    /// load tells the push that neither is (the speed-ramp machine's worst tick).
    state: u8,
    /// The flow follower's bend of the mean (`crate::flow_follow`), units, held in the
    /// ring's sum with the offset so that the tick's usual path pays nothing for it.
    bend: [f32; 2],
}

const RETURNING: u8 = 1;
const BENT: u8 = 2;

impl WidthBlend {
    /// No offset, no return (a ring of window 1).
    pub const fn new() -> Self {
        WidthBlend {
            offset: [0.0; 2],
            rate: [0.0; 2],
            held: [0; 2],
            k1: 0.0,
            k2: 0.0,
            state: 0,
            bend: [0.0; 2],
        }
    }

    /// No offset; the return's pace for a ring whose widest mean is `half_max` frames
    /// either side: `w dt = sqrt(6 SHARE) / half_max`, so that `w^2` times the widest
    /// inset is `SHARE x''`.
    pub fn reset(&mut self, half_max: u32) {
        *self = Self::new();
        if half_max > 0 {
            let wdt = libm::sqrtf(6.0 * SHARE) / half_max as f32;
            self.k1 = wdt * wdt;
            self.k2 = 2.0 * wdt;
        }
    }

    /// Whether an offset is still returning (the ring keeps its slow path).
    pub fn active(&self) -> bool {
        self.state & RETURNING != 0
    }

    /// What the ring's sum holds of the offset (units times the mean's span).
    pub fn held(&self) -> [i32; 2] {
        self.held
    }

    /// The mean moved by `moved` (units) as its width changed: the offset takes it back.
    pub fn absorb(&mut self, moved: [f32; 2]) {
        if self.k1 > 0.0 {
            self.offset[0] -= moved[0];
            self.offset[1] -= moved[1];
            self.state |= RETURNING;
        }
    }

    /// One push of the return; the change (units times `span`) the ring's sum takes so
    /// that it holds the offset over a mean of `span` frames.
    pub fn advance(&mut self, span: u32) -> [i32; 2] {
        if self.state == 0 {
            return [0; 2];
        }
        if self.state & RETURNING != 0 {
            // X then Y, in line (a loop of two is not unrolled at opt-level "s").
            let spent = self.return_axis(0) & self.return_axis(1);
            if spent {
                self.offset = [0.0; 2];
                self.rate = [0.0; 2];
                self.state &= !RETURNING;
            }
        }
        self.hold(span)
    }

    /// The follower's bend `d` (units) from now; the change the ring's sum takes, as
    /// `advance`'s.
    pub fn bend(&mut self, d: [f32; 2], span: u32) -> [i32; 2] {
        self.bend = d;
        if d == [0.0; 2] {
            self.state &= !BENT;
        } else {
            self.state |= BENT;
        }
        self.hold(span)
    }

    /// The follower's bend the sum holds now, units.
    pub fn bent(&self) -> [f32; 2] {
        self.bend
    }

    /// One push of axis `a`'s return; whether it is spent.
    #[inline(always)]
    fn return_axis(&mut self, a: usize) -> bool {
        self.rate[a] -= self.k1 * self.offset[a] + self.k2 * self.rate[a];
        self.offset[a] += self.rate[a];
        libm::fabsf(self.offset[a]) < SPENT && libm::fabsf(self.rate[a]) < SPENT
    }

    #[inline(always)]
    fn hold(&mut self, span: u32) -> [i32; 2] {
        let span = span as f32;
        [self.hold_axis(0, span), self.hold_axis(1, span)]
    }

    /// Axis `a` of `hold`, in line.
    #[inline(always)]
    fn hold_axis(&mut self, a: usize, span: f32) -> i32 {
        // `Real::round_i32`: as `roundf` then `as i32`, without the call.
        let now = crate::real::Real::round_i32((self.offset[a] + self.bend[a]) * span);
        let c = now.wrapping_sub(self.held[a]);
        self.held[a] = now;
        c
    }
}

impl Default for WidthBlend {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An offset returns to zero without overshoot, its largest acceleration within
    /// `w^2` times the offset, and the blend then stands down holding nothing.
    #[test]
    fn an_offset_returns_critically_damped() {
        let mut b = WidthBlend::new();
        b.reset(207);
        b.absorb([-100.0, 50.0]);
        let mut last = [100.0f32, -50.0];
        let mut held = [0i64; 2];
        let mut pushes = 0;
        let mut prev_rate = [0.0f32; 2];
        let mut peak_acc = 0.0f32;
        while b.active() && pushes < 100_000 {
            let c = b.advance(41);
            held[0] += c[0] as i64;
            held[1] += c[1] as i64;
            for (now, before) in b.offset.iter().zip(last) {
                assert!(now.abs() <= before.abs() + 1e-3, "no overshoot");
            }
            peak_acc = peak_acc.max((b.rate[0] - prev_rate[0]).abs() / 100.0);
            prev_rate = b.rate;
            last = b.offset;
            pushes += 1;
        }
        assert!(!b.active(), "stood down");
        assert_eq!(held, [0, 0], "the sum holds nothing once spent");
        assert_eq!(b.held(), [0, 0]);
        // Returns over several of the widest windows, not one.
        assert!(pushes > 4 * 207, "{pushes} pushes");
        let w2 = 6.0 * SHARE / (207.0f32 * 207.0);
        assert!(peak_acc <= w2 * 1.01, "{peak_acc} vs {w2}");
    }

    /// A ring of window 1 has no width to change: nothing is absorbed.
    #[test]
    fn no_window_no_blend() {
        let mut b = WidthBlend::new();
        b.reset(0);
        b.absorb([5.0, 5.0]);
        assert!(!b.active());
        assert_eq!(b.advance(1), [0, 0]);
    }
}
