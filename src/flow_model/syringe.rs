//! Stepper-driven syringe inlets: the plunger displaces paste at a set rate while its
//! inlet feeds, and the outflow follows with the measured lag, a Weibull step response
//! `F(t) = 1 - exp(-k t^n)`, followed by a cascade of first-order stages fitted to it at
//! set-up (`lag_fit`): a linear system, so starts and stops superpose by themselves and a
//! cycle costs the same however many rate changes are still settling. Which inlet feeds
//! the channel is `mod.rs`'s call; plunger steps are the executor's.

use super::lag_fit::{self, Map, STAGES, TRI};
use crate::real::Real;

// `Map::apply` is written out for eight stages.
const _: () = assert!(STAGES == 8 && TRI == 36);

/// Cycles of the look-ahead's chunk (`predict`), which reads the outflow half a chunk and
/// a whole chunk ahead: both are powers of two of cycles, so each is one step.
pub const CHUNK_CYCLES: u64 = 64;
const CHUNK_LEVELS: u32 = 6; // 2^6 cycles
const HALF_CHUNK_LEVELS: u32 = 5;

/// A syringe's lag as the cascade fitted to its Weibull curve (`lag_fit`), ready to run:
/// its steps over a cycle, half a chunk and a chunk, the outflow weights, and the
/// volume still to come from a state once the plunger stops.
#[derive(Clone, Copy, Debug)]
pub struct Response<R> {
    /// Each stage's share of its gap closed per cycle.
    b: [R; STAGES],
    half_chunk: Map<R>,
    chunk: Map<R>,
    c: [R; STAGES],
    rest: [R; STAGES],
}

impl<R: Real> Map<R> {
    const ZERO: Self = Map {
        m: [R::ZERO; TRI],
        g: [R::ZERO; STAGES],
    };

    fn of(m: &Map<f64>) -> Self {
        Map {
            m: m.m.map(R::of),
            g: m.g.map(R::of),
        }
    }

    /// The state after this step, in place: written out for the eight stages (no loop,
    /// no bounds checks; the M4 keeps the old state in registers), 36 + 8 products.
    #[inline(always)]
    fn apply(&self, x: &mut [R; STAGES], u: R) {
        let (m, g) = (&self.m, &self.g);
        let [x0, x1, x2, x3, x4, x5, x6, x7] = *x;
        x[0] = g[0] * u + m[0] * x0;
        x[1] = g[1] * u + m[1] * x0 + m[2] * x1;
        x[2] = g[2] * u + m[3] * x0 + m[4] * x1 + m[5] * x2;
        x[3] = g[3] * u + m[6] * x0 + m[7] * x1 + m[8] * x2 + m[9] * x3;
        x[4] = g[4] * u + m[10] * x0 + m[11] * x1 + m[12] * x2 + m[13] * x3 + m[14] * x4;
        x[5] =
            g[5] * u + m[15] * x0 + m[16] * x1 + m[17] * x2 + m[18] * x3 + m[19] * x4 + m[20] * x5;
        x[6] = g[6] * u
            + m[21] * x0
            + m[22] * x1
            + m[23] * x2
            + m[24] * x3
            + m[25] * x4
            + m[26] * x5
            + m[27] * x6;
        x[7] = g[7] * u
            + m[28] * x0
            + m[29] * x1
            + m[30] * x2
            + m[31] * x3
            + m[32] * x4
            + m[33] * x5
            + m[34] * x6
            + m[35] * x7;
    }

    /// The outflow after this step (`c . x'`), the state left as it is.
    #[inline(always)]
    fn out(&self, x: &[R; STAGES], u: R, c: &[R; STAGES]) -> R {
        let mut y = *x;
        self.apply(&mut y, u);
        dot(c, &y)
    }
}

#[inline(always)]
fn dot<R: Real>(a: &[R; STAGES], b: &[R; STAGES]) -> R {
    a[0] * b[0]
        + a[1] * b[1]
        + a[2] * b[2]
        + a[3] * b[3]
        + a[4] * b[4]
        + a[5] * b[5]
        + a[6] * b[6]
        + a[7] * b[7]
}

impl<R: Real> Response<R> {
    /// No lag yet; `fill` fits one. A constant, so a model can be built at compile time
    /// and its responses filled in place.
    pub const EMPTY: Self = Response {
        b: [R::ZERO; STAGES],
        half_chunk: Map::ZERO,
        chunk: Map::ZERO,
        c: [R::ZERO; STAGES],
        rest: [R::ZERO; STAGES],
    };

    /// The response for Weibull `k`, `n` and control cycles of `dt` seconds.
    pub fn new(k: f64, n: f64, dt: f64) -> Self {
        let mut r = Self::EMPTY;
        r.fill(k, n, dt);
        r
    }

    /// Makes this the response of `new(k, n, dt)`, in place.
    #[inline(never)]
    pub fn fill(&mut self, k: f64, n: f64, dt: f64) {
        let fit = lag_fit::fit(k, n, dt);
        let settle_cycles = crate::config::Syringe::settle_time(k, n) / dt;
        // Steady state exact: each row of a step sums to 1 with its `g`, so a settled
        // state stays at the rate in single precision too.
        let exact = |m: Map<R>| -> Map<R> {
            let mut r = m;
            let mut row = 0;
            for i in 0..STAGES {
                let mut s = R::ZERO;
                for j in 0..=i {
                    s += r.m[row + j];
                }
                r.g[i] = R::ONE - s;
                row += i + 1;
            }
            r
        };
        self.b = fit.b.map(R::of);
        // The look-ahead's steps and the remaining volume by squaring in the chip's own
        // precision: in software double precision they cost it 1.2 million instructions
        // a syringe, and the whole set-up kept the board from answering its host.
        let step = Map::<R>::of(&fit.step);
        self.half_chunk = exact(lag_fit::power(&step, HALF_CHUNK_LEVELS));
        self.chunk = exact(lag_fit::power(&step, CHUNK_LEVELS));
        self.c = fit.c.map(R::of);
        self.rest = lag_fit::rest(&step, &self.c, dt, 4.0 * settle_cycles + 1.0);
    }
}

/// A syringe's plunger and the lag between it and the outflow: the cascade's state at the
/// start of the model's next cycle and the rate it is driven towards.
#[derive(Clone, Copy, Debug)]
pub struct Plunger<R> {
    x: [R; STAGES],
    /// Outflow `c . x` over the last cycle stepped, mm^3/s: the outflow now.
    y: R,
    /// Plunger rate now commanded, mm^3/s (0 when stopped).
    u: R,
    /// Rate of the last start or stop, mm^3/s: the scale of "settled".
    scale: R,
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
        x: [R::ZERO; STAGES],
        y: R::ZERO,
        u: R::ZERO,
        scale: R::ZERO,
        running: false,
    };

    /// Starts or stops the plunger (at `rate`) from the next cycle on.
    pub fn command(&mut self, run: bool, rate: R) {
        self.running = run;
        self.u = if run { rate } else { R::ZERO };
        self.scale = rate;
    }

    /// True while some stage of the lag is more than 1e-6 of the last rate change away
    /// from the commanded rate (an outflow that has not settled yet).
    pub fn settling(&self) -> bool {
        let tol = self.scale.abs() * R::of(1e-6);
        self.x.iter().any(|&x| (x - self.u).abs() > tol)
    }

    /// Outflow over this cycle (mm^3/s, its mean), moving on to the next: one step of
    /// the cascade, a fixed cost whatever the plunger did before. Each stage closes its
    /// share of the gap to the stage before (the first to the rate): a settled stage has
    /// no gap, so it stays exactly at the rate in single precision, which the same step
    /// as a matrix would not (a slow stage's factor is 1 - 1e-5).
    #[inline(never)]
    pub fn flow_mid(&mut self, resp: &Response<R>) -> R {
        // Written out for the eight stages, as `Map::apply` is.
        let (b, c) = (&resp.b, &resp.c);
        let x = &mut self.x;
        x[0] += b[0] * (self.u - x[0]);
        x[1] += b[1] * (x[0] - x[1]);
        x[2] += b[2] * (x[1] - x[2]);
        x[3] += b[3] * (x[2] - x[3]);
        x[4] += b[4] * (x[3] - x[4]);
        x[5] += b[5] * (x[4] - x[5]);
        x[6] += b[6] * (x[5] - x[6]);
        x[7] += b[7] * (x[6] - x[7]);
        let y = dot(c, x);
        self.y = y;
        y.max(R::ZERO)
    }

    /// Outflow now (over the last cycle stepped).
    #[inline]
    pub fn flow_now(&self) -> R {
        self.y.max(R::ZERO)
    }

    /// Outflow half a look-ahead chunk (`CHUNK_CYCLES / 2`) from now.
    pub fn flow_half_chunk(&self, resp: &Response<R>) -> R {
        resp.half_chunk.out(&self.x, self.u, &resp.c).max(R::ZERO)
    }

    /// Moves on by a look-ahead chunk; returns the outflow there.
    pub fn advance_chunk(&mut self, resp: &Response<R>) -> R {
        resp.chunk.apply(&mut self.x, self.u);
        self.y = dot(&resp.c, &self.x);
        self.flow_now()
    }

    /// Volume still to come out (mm^3) from now on once the plunger has stopped (as
    /// commanded: a running plunger's is unbounded, and this is what has yet to settle).
    pub fn remaining(&self, resp: &Response<R>) -> R {
        dot(&resp.rest, &self.x).max(R::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Syringe;

    #[test]
    fn single_precision_steps_follow_the_weibull_curve() {
        // The chip's f32 response, stepped every cycle over 0.2 s, against the curve.
        let (k, n) = (400.0, 1.5);
        let r: Response<f32> = Response::new(k, n, 1e-4);
        let mut p = Plunger::IDLE;
        p.command(true, 1.0);
        let mut worst = 0.0f64;
        for i in 0..2000u64 {
            let t = (i as f64 + 0.5) * 1e-4;
            let q = p.flow_mid(&r) as f64;
            worst = worst.max((q - Syringe::response(k, n, t)).abs());
        }
        assert!(worst < 1e-3, "{worst}");
    }

    #[test]
    fn starts_and_stops_superpose_as_the_weibull_curve_does() {
        // A plunger toggled at irregular times, faster than its lag settles, against the
        // sum of Weibull responses to each change (the plant's own law), every cycle.
        let (k, n, dt, rate) = (30.0, 1.3, 1e-4, 4.0);
        let r: Response<f32> = Response::new(k, n, dt);
        let mut p = Plunger::IDLE;
        let toggles = [0u64, 700, 1500, 1900, 4200, 4300, 4500, 9000];
        let mut worst = 0.0f64;
        for cyc in 0..20_000u64 {
            if let Some(i) = toggles.iter().position(|&t| t == cyc) {
                p.command(i % 2 == 0, rate as f32);
            }
            let q = p.flow_mid(&r) as f64;
            let t = (cyc as f64 + 0.5) * dt;
            let mut exact = 0.0;
            for (i, &at) in toggles.iter().enumerate().filter(|(_, &a)| a <= cyc) {
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                exact += sign * rate * Syringe::response(k, n, t - at as f64 * dt);
            }
            worst = worst.max((q - exact).abs() / rate);
        }
        eprintln!("superposed starts and stops: worst {worst:.2e} of the rate");
        assert!(worst < 2.5e-3, "{worst}");
    }

    #[test]
    fn chunk_steps_agree_with_cycle_steps() {
        let r: Response<f64> = Response::new(30.0, 1.3, 1e-4);
        let mut a = Plunger::IDLE;
        a.command(true, 5.0);
        let mut b = a;
        for _ in 0..3 {
            let half = b.flow_half_chunk(&r);
            for i in 0..CHUNK_CYCLES {
                if i == CHUNK_CYCLES / 2 {
                    assert!((a.flow_now() - half).abs() < 1e-9);
                }
                a.flow_mid(&r);
            }
            let end = b.advance_chunk(&r);
            assert!((a.flow_now() - end).abs() < 1e-9, "{} {end}", a.flow_now());
        }
    }

    #[test]
    fn start_then_stop_delivers_the_plunger_volume() {
        // Plunger runs 0.2 s at 5 mm^3/s: whatever the lag, 1 mm^3 comes out in the end.
        let r: Response<f64> = Response::new(400.0, 1.5, 1e-4);
        let mut p = Plunger::default();
        let dt = 1e-4;
        p.command(true, 5.0);
        let mut v = 0.0;
        for k in 0..10_000u64 {
            if k == 2000 {
                p.command(false, 5.0);
            }
            v += p.flow_mid(&r) * dt;
        }
        assert!((v - 1.0).abs() < 1e-3, "{v}");
        assert!(p.flow_now().abs() < 1e-9);
        // What remains after the stop, predicted at the stop, is what then came out.
        let mut p = Plunger::default();
        p.command(true, 5.0);
        let mut before = 0.0;
        for _ in 0..2000u64 {
            before += p.flow_mid(&r) * dt;
        }
        p.command(false, 5.0);
        let predicted = p.remaining(&r);
        let mut after = 0.0;
        for _ in 0..20_000u64 {
            after += p.flow_mid(&r) * dt;
        }
        assert!((predicted - after).abs() < 1e-6, "{predicted} vs {after}");
        assert!(
            (before + predicted - 1.0).abs() < 2e-3,
            "{before} + {predicted}"
        );
    }

    #[test]
    fn a_settled_plunger_stays_at_its_rate_in_single_precision() {
        let r: Response<f32> = Response::new(45.0, 1.1, 1e-4);
        let mut p = Plunger::IDLE;
        p.command(true, 3.0);
        let mut q = 0.0;
        // 10 minutes of cycles.
        for _ in 0..6_000_000u64 {
            q = p.flow_mid(&r);
        }
        assert!((q - 3.0).abs() < 1e-4, "{q}");
    }
}
