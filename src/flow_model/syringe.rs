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
/// the volume per unit rate still to come out after a change `t` seconds ago. The table
/// step is a whole number of control cycles, so the per-cycle path finds its entry and
/// the fraction within it from the integer cycle count (one hardware division on the
/// M4): no float rounding, and exact however long a job runs.
#[derive(Clone, Debug)]
pub struct Response<R> {
    /// Table step in half cycles.
    half_steps: u32,
    /// Half cycles after a change from which F is 1.
    end_half: u64,
    /// 1 / (table step in half cycles).
    inv_half_steps: R,
    f: [R; RESPONSE_POINTS],
    h: [R; RESPONSE_POINTS],
}

impl<R: Real> Response<R> {
    /// No table yet (settled at once); `fill` makes one. A constant, so a model can be
    /// built at compile time and its tables filled in place.
    pub const EMPTY: Self = Response {
        half_steps: 1,
        end_half: 0,
        inv_half_steps: R::ONE,
        f: [R::ZERO; RESPONSE_POINTS],
        h: [R::ZERO; RESPONSE_POINTS],
    };

    /// The table for Weibull `k`, `n` and control cycles of `dt` seconds: the smallest
    /// whole number of cycles a step whose 255 steps reach the settling time.
    pub fn new(k: f64, n: f64, dt: f64) -> Self {
        let mut r = Self::EMPTY;
        r.fill(k, n, dt);
        r
    }

    /// Makes this the table of `new(k, n, dt)`, in place (the tables are 2 KiB: the
    /// board's control interrupt must not build one on its stack and move it).
    pub fn fill(&mut self, k: f64, n: f64, dt: f64) {
        let settle = Syringe::settle_time(k, n);
        let cycles_per_step =
            libm::ceil(settle / dt / (RESPONSE_POINTS - 1) as f64).clamp(1.0, 1e6) as u32;
        let step = cycles_per_step as f64 * dt;
        // 1 - F in single precision: the board fills these tables in its control interrupt,
        // and its FPU has no double precision (a software `pow` in f64 costs about 25 000
        // instructions; 16 000 of them made a syringe config take seconds, far past the
        // watchdog). Single precision is within 1e-7 of the curve, far inside the table's
        // own interpolation error.
        let (kf, nf) = (k as f32, n as f32);
        let g = |t: f64| -> f64 {
            if t <= 0.0 {
                1.0
            } else {
                libm::expf(-kf * libm::powf(t as f32, nf)) as f64
            }
        };
        // H by Simpson's rule on each table step (its ends and middle), from the end
        // backwards: 2 x 255 + 1 evaluations in all.
        let last = RESPONSE_POINTS - 1;
        self.f[last] = R::ONE;
        self.h[last] = R::ZERO;
        let mut g_hi = g(last as f64 * step);
        let mut acc = 0.0f64;
        for i in (0..last).rev() {
            let a = i as f64 * step;
            let g_lo = g(a);
            acc += (g_lo + 4.0 * g(a + 0.5 * step) + g_hi) * step / 6.0;
            self.f[i] = R::of(1.0 - g_lo);
            self.h[i] = R::of(acc);
            g_hi = g_lo;
        }
        let half_steps = 2 * cycles_per_step;
        self.half_steps = half_steps;
        self.end_half = half_steps as u64 * (RESPONSE_POINTS - 1) as u64;
        self.inv_half_steps = R::of(1.0 / half_steps as f64);
    }

    /// Table entry and fraction `half_cycles` half cycles after a change; `None` once
    /// settled (F = 1, H = 0).
    #[inline]
    fn at_half(&self, half_cycles: u64) -> Option<(usize, R)> {
        if half_cycles >= self.end_half {
            return None;
        }
        // Below end_half, which fits u32: a 32-bit division (one instruction).
        let p = half_cycles as u32;
        let i = p / self.half_steps;
        let rem = p - i * self.half_steps;
        Some((i as usize, R::from_u32(rem) * self.inv_half_steps))
    }

    /// F `half_cycles` half cycles after a change, linearly interpolated over 255 steps up
    /// to the settling time (error under 1e-3 of the rate where F bends most, at the start
    /// of the response).
    #[inline]
    pub fn f_half(&self, half_cycles: u64) -> R {
        match self.at_half(half_cycles) {
            Some((i, frac)) => lerp(&self.f, i, frac),
            None => R::ONE,
        }
    }

    /// H `half_cycles` half cycles after a change, linearly interpolated; 0 beyond the
    /// table.
    #[inline]
    pub fn h_half(&self, half_cycles: u64) -> R {
        match self.at_half(half_cycles) {
            Some((i, frac)) => lerp(&self.h, i, frac),
            None => R::ZERO,
        }
    }
}

/// Linear interpolation of `table` between entries `i` and `i + 1` (i < 255).
#[inline]
fn lerp<R: Real>(table: &[R; RESPONSE_POINTS], i: usize, frac: R) -> R {
    let i = i.min(RESPONSE_POINTS - 2);
    let (a, b) = (table[i], table[i + 1]);
    a + (b - a) * frac
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
        Self::IDLE
    }
}

impl<R: Real> Plunger<R> {
    /// At rest: no outflow, nothing settling.
    pub const IDLE: Self = Plunger {
        base: R::ZERO,
        events: [(0, R::ZERO); EVENTS],
        len: 0,
        running: false,
    };
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

    /// Becomes `src`, copying only its live changes (cheaper than the whole struct).
    pub fn copy_from(&mut self, src: &Plunger<R>) {
        let n = (src.len as usize).min(EVENTS);
        self.events[..n].copy_from_slice(&src.events[..n]);
        self.base = src.base;
        self.len = n as u8;
        self.running = src.running;
    }

    /// Outflow at the middle of cycle `k` (mm^3/s), folding settled changes. Not inlined:
    /// on its own its loop keeps its state in registers.
    #[inline(never)]
    pub fn flow_mid(&mut self, k: u64, resp: &Response<R>) -> R {
        let mut q = self.base;
        let mut keep = 0usize;
        for e in 0..self.len as usize {
            let (at, dr) = self.events[e];
            if k >= at {
                match resp.at_half(2 * (k - at) + 1) {
                    Some((i, frac)) => q += dr * lerp(&resp.f, i, frac),
                    None => {
                        self.base += dr;
                        q += dr;
                        continue;
                    }
                }
            }
            if keep != e {
                self.events[keep] = (at, dr);
            }
            keep += 1;
        }
        self.len = keep as u8;
        q.max(R::ZERO)
    }

    /// Volume still to come out (mm^3) from the start of cycle `k` on, once the plunger
    /// has stopped for good: every change's `H` since it happened, the settled part
    /// cancelling.
    pub fn remaining(&self, k: u64, resp: &Response<R>) -> R {
        let mut v = R::ZERO;
        for &(at, dr) in &self.events[..self.len as usize] {
            v -= dr * resp.h_half(2 * k.saturating_sub(at));
        }
        v.max(R::ZERO)
    }

    /// Outflow at the start of cycle `k` (no folding).
    #[inline]
    pub fn flow_at(&self, k: u64, resp: &Response<R>) -> R {
        let mut q = self.base;
        for &(at, dr) in &self.events[..self.len as usize] {
            if k > at {
                q += dr * resp.f_half(2 * (k - at));
            }
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
        let r: Response<f32> = Response::new(k, n, 1e-4);
        let mut worst = 0.0f64;
        // Every half cycle over the first 0.2 s.
        for i in 0..4000u64 {
            let t = i as f64 * 0.5e-4;
            let exact = Syringe::response(k, n, t);
            worst = worst.max((r.f_half(i) as f64 - exact).abs());
        }
        assert!(worst < 1e-3, "{worst}");
    }

    #[test]
    fn the_tail_integral_matches_a_fine_double_precision_reference() {
        // H(t) against Simpson's rule on 64 sub-intervals a step in f64 (what the table
        // was built from before it had to be cheap on the chip), for the bundled lags
        // and the validation's extremes of shape.
        for (k, n) in [
            (30.0, 1.3),
            (45.0, 1.1),
            (400.0, 1.5),
            (5.0, 1.0),
            (2000.0, 2.5),
        ] {
            let dt = 1e-4;
            let r: Response<f64> = Response::new(k, n, dt);
            let step = r.half_steps as f64 / 2.0 * dt;
            let g = |t: f64| 1.0 - Syringe::response(k, n, t);
            let mut acc = 0.0;
            let mut worst = 0.0f64;
            for i in (0..RESPONSE_POINTS - 1).rev() {
                let a = i as f64 * step;
                let hh = step / 64.0;
                let mut sum = g(a) + g(a + step);
                for j in 1..64 {
                    sum += g(a + j as f64 * hh) * if j % 2 == 1 { 4.0 } else { 2.0 };
                }
                acc += sum * hh / 3.0;
                worst = worst.max((r.h[i] - acc).abs() / r.h[0]);
                worst = worst.max((r.f[i] - Syringe::response(k, n, a)).abs());
            }
            assert!(worst < 1e-4, "k {k} n {n}: {worst}");
        }
    }

    #[test]
    fn start_then_stop_delivers_the_plunger_volume() {
        // Plunger runs 0.2 s at 5 mm^3/s: whatever the lag, 1 mm^3 comes out in the end.
        let r: Response<f64> = Response::new(400.0, 1.5, 1e-4);
        let mut p = Plunger::default();
        let dt = 1e-4;
        p.command(true, 0, 5.0);
        let mut v = 0.0;
        for k in 0..10_000u64 {
            if k == 2000 {
                p.command(false, k, 5.0);
            }
            v += p.flow_mid(k, &r) * dt;
        }
        assert!((v - 1.0).abs() < 1e-3, "{v}");
        assert_eq!(p.len, 0);
        assert!(p.base.abs() < 1e-12);
        // What remains after the stop, predicted at the stop, is what then came out.
        let mut p = Plunger::default();
        p.command(true, 0, 5.0);
        let mut before = 0.0;
        for k in 0..2000u64 {
            before += p.flow_mid(k, &r) * dt;
        }
        p.command(false, 2000, 5.0);
        let predicted = p.remaining(2000, &r);
        assert!(
            (before + predicted - 1.0).abs() < 2e-3,
            "{before} + {predicted}"
        );
    }
}
