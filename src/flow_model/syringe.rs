//! Stepper-driven syringe inlets: the plunger displaces paste at a set rate while its
//! inlet feeds, and the outflow follows with the measured lag, a Weibull step response
//! `F(t) = 1 - exp(-k t^n)` (tabulated at set-up, so the chip evaluates no exponentials).
//! Starts and stops superpose: outflow = sum of rate changes times F(time since each).
//! Which inlet feeds the channel is `mod.rs`'s call; plunger steps are the executor's.

use crate::config::Syringe;
use crate::real::Real;

/// Samples of the response table.
pub const RESPONSE_POINTS: usize = 256;
/// Rate changes a syringe remembers until they have settled (older ones are folded into
/// the steady rate once `F` has reached 1 within 1e-6).
pub const EVENTS: usize = 6;

/// `F` tabulated on `[0, t_end]` (1 beyond), and `H(t) = integral of (1 - F) from t on`,
/// the volume per unit rate still to come out after a change `t` seconds ago.
#[derive(Clone, Debug)]
pub struct Response<R> {
    inv_step: R,
    t_end: R,
    f: [R; RESPONSE_POINTS],
    h: [R; RESPONSE_POINTS],
}

impl<R: Real> Response<R> {
    /// The table for Weibull `k`, `n`.
    pub fn new(k: f64, n: f64) -> Self {
        let t_end = Syringe::settle_time(k, n);
        let step = t_end / (RESPONSE_POINTS - 1) as f64;
        let mut f = [R::ZERO; RESPONSE_POINTS];
        for (i, v) in f.iter_mut().enumerate() {
            *v = R::of(Syringe::response(k, n, i as f64 * step));
        }
        // H by Simpson's rule on 64 sub-intervals per table step, from the end backwards.
        let mut h = [R::ZERO; RESPONSE_POINTS];
        let mut acc = 0.0f64;
        let sub = 64;
        for i in (0..RESPONSE_POINTS - 1).rev() {
            let a = i as f64 * step;
            let hh = step / sub as f64;
            let g = |t: f64| 1.0 - Syringe::response(k, n, t);
            let mut sum = g(a) + g(a + step);
            for j in 1..sub {
                sum += g(a + j as f64 * hh) * if j % 2 == 1 { 4.0 } else { 2.0 };
            }
            acc += sum * hh / 3.0;
            h[i] = R::of(acc);
        }
        Response {
            inv_step: R::of(1.0 / step),
            t_end: R::of(t_end),
            f,
            h,
        }
    }

    /// F(t), linearly interpolated over 255 steps up to the settling time (error under
    /// 1e-3 of the rate where F bends most, at the start of the response).
    #[inline]
    pub fn f(&self, t: R) -> R {
        if t <= R::ZERO {
            return R::ZERO;
        }
        if t >= self.t_end {
            return R::ONE;
        }
        let x = t * self.inv_step;
        // floor(x) for x > 0: round(x - 1/2), ties away from zero.
        let i = (x - R::HALF)
            .round_i64()
            .clamp(0, RESPONSE_POINTS as i64 - 2) as usize;
        let frac = x - R::from_u32(i as u32);
        self.f[i] + (self.f[i + 1] - self.f[i]) * frac
    }

    /// H(t), linearly interpolated; 0 beyond the table.
    #[inline]
    pub fn h(&self, t: R) -> R {
        if t >= self.t_end {
            return R::ZERO;
        }
        let t = t.max(R::ZERO);
        let x = t * self.inv_step;
        let i = (x - R::HALF)
            .round_i64()
            .clamp(0, RESPONSE_POINTS as i64 - 2) as usize;
        let frac = x - R::from_u32(i as u32);
        self.h[i] + (self.h[i + 1] - self.h[i]) * frac
    }

    /// Seconds after which F is 1.
    pub fn t_end(&self) -> R {
        self.t_end
    }
}

/// A syringe's rate changes: `(cycle at whose start it acts, +-rate)`, oldest first, and
/// the rate of those already folded in.
#[derive(Clone, Copy, Debug)]
pub struct Plunger<R> {
    /// Settled outflow, mm^3/s.
    pub base: R,
    /// Rate changes still settling.
    pub events: [(u64, R); EVENTS],
    /// How many of `events` are in use.
    pub len: u8,
    /// Plunger commanded to run.
    pub running: bool,
}

impl<R: Real> Default for Plunger<R> {
    fn default() -> Self {
        Plunger {
            base: R::ZERO,
            events: [(0, R::ZERO); EVENTS],
            len: 0,
            running: false,
        }
    }
}

impl<R: Real> Plunger<R> {
    /// Starts or stops the plunger (at `rate`) from cycle `at` on.
    pub fn command(&mut self, run: bool, at: u64, rate: R) {
        if run == self.running {
            return;
        }
        self.running = run;
        if self.len as usize == EVENTS {
            // Fold the oldest change early; with EVENTS changes in one lag time the
            // syringe is being toggled faster than it can respond anyway.
            self.base += self.events[0].1;
            self.events.copy_within(1.., 0);
            self.len -= 1;
        }
        self.events[self.len as usize] = (at, if run { rate } else { -rate });
        self.len += 1;
    }

    /// Outflow at the middle of cycle `k` (mm^3/s), folding settled changes.
    #[inline]
    pub fn flow_mid(&mut self, k: u64, dt: R, resp: &Response<R>) -> R {
        let mut q = self.base;
        let mut keep = 0usize;
        for e in 0..self.len as usize {
            let (at, dr) = self.events[e];
            if k < at {
                self.events[keep] = (at, dr);
                keep += 1;
                continue;
            }
            let t = (R::from_u32((k - at).min(u32::MAX as u64) as u32) + R::HALF) * dt;
            if t >= resp.t_end {
                self.base += dr;
                q += dr;
            } else {
                q += dr * resp.f(t);
                self.events[keep] = (at, dr);
                keep += 1;
            }
        }
        self.len = keep as u8;
        q.max(R::ZERO)
    }

    /// Volume still to come out (mm^3) from cycle `at_cycle` on, once the plunger has
    /// stopped for good: every change's `H` since it happened, the settled part cancelling.
    pub fn remaining(&self, at_cycle: R, dt: R, resp: &Response<R>) -> R {
        let mut v = R::ZERO;
        for &(at, dr) in &self.events[..self.len as usize] {
            let t = (at_cycle - R::from_u32(at.min(u32::MAX as u64) as u32)) * dt;
            v -= dr * resp.h(t);
        }
        v.max(R::ZERO)
    }

    /// Outflow at time `t_cycles` cycles after the start of cycle 0 (no folding).
    #[inline]
    pub fn flow_at(&self, at_cycle: R, dt: R, resp: &Response<R>) -> R {
        let mut q = self.base;
        for &(at, dr) in &self.events[..self.len as usize] {
            let t = (at_cycle - R::from_u32(at.min(u32::MAX as u64) as u32)) * dt;
            q += dr * resp.f(t);
        }
        q.max(R::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_follows_the_weibull_curve() {
        let (k, n) = (400.0, 1.5);
        let r: Response<f32> = Response::new(k, n);
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let t = i as f64 * 1e-4;
            let exact = Syringe::response(k, n, t);
            worst = worst.max((r.f(t as f32) as f64 - exact).abs());
        }
        assert!(worst < 1e-3, "{worst}");
    }

    #[test]
    fn start_then_stop_delivers_the_plunger_volume() {
        // Plunger runs 0.2 s at 5 mm^3/s: whatever the lag, 1 mm^3 comes out in the end.
        let r: Response<f64> = Response::new(400.0, 1.5);
        let mut p = Plunger::default();
        let dt = 1e-4;
        p.command(true, 0, 5.0);
        let mut v = 0.0;
        for k in 0..10_000u64 {
            if k == 2000 {
                p.command(false, k, 5.0);
            }
            v += p.flow_mid(k, dt, &r) * dt;
        }
        assert!((v - 1.0).abs() < 1e-3, "{v}");
        assert_eq!(p.len, 0);
        assert!(p.base.abs() < 1e-12);
        // What remains after the stop, predicted at the stop, is what then came out.
        let mut p = Plunger::default();
        p.command(true, 0, 5.0);
        let mut before = 0.0;
        for k in 0..2000u64 {
            before += p.flow_mid(k, dt, &r) * dt;
        }
        p.command(false, 2000, 5.0);
        let predicted = p.remaining(2000.0, dt, &r);
        assert!(
            (before + predicted - 1.0).abs() < 2e-3,
            "{before} + {predicted}"
        );
    }
}
