//! Fitting a syringe's measured lag, the Weibull step response `F(t) = 1 - exp(-k t^n)`,
//! with a cascade of first-order stages whose outflow is a weighted sum of the stages: a
//! response whose cost per control cycle is fixed however many rate changes are in flight
//! (`syringe` runs it). Set-up only: the board runs this once per machine config.
//!
//! The cascade is discrete, on control cycles (its outflow after a cycle's step stands for
//! the cycle's mean outflow, which is what the volume clock counts): stage 0 moves towards the plunger's rate, each later stage towards
//! the stage before, each by `1 - a_j` of the gap per cycle with `a_j = exp(-dt / tau_j)`, the later
//! stage taking its predecessor's new value. The time constants run in a geometric series
//! `tau_j = tau_0 r^j`; the weights (summing to 1, so the outflow settles at the plunger's
//! rate) are least squares against `F` on 256 points up to the settling time, and
//! `tau_0`, `r` are searched. What is fitted is exactly the discrete system the chip runs.

// Loops over a packed triangle index several arrays by `at(i, j)`; ranges say that best.
#![allow(clippy::needless_range_loop)]

use crate::config::Syringe;
use crate::real::Real;

/// Stages of the cascade. Eight follow the Weibull curve's mean over every control cycle
/// within 4e-3 of the rate for shapes `0.2 <= n <= 2` but near `n = 0.9` (6e-3), the
/// bundled syringes within 1.2e-3; 7e-3 at `n = 2.5`, 1.5e-2 at 3, 0.1 at 4 and 5,
/// the validation's largest, where the curve is nearly a pure delay that stages follow
/// badly (`tests::fit_error_across_shapes`). The fit weighs the tail of a stop relative
/// to what is still to come (`TAIL`): a bead ends on that tail, where the head follows a
/// flow of a few percent of the rate, so a small error there is a large one in the bead's
/// section. Six stages, or eight fitted without that weight, let the section stray 1.6 to
/// 2.8 % over 0.02 mm at such an end (the whole-job syringe tests); eight with it, 0.4 %.
/// A cycle costs one step of 2 operations a stage and a sum of the stages.
pub const STAGES: usize = 8;
/// Entries of a lower-triangular STAGES x STAGES matrix, stored row by row.
pub const TRI: usize = STAGES * (STAGES + 1) / 2;

/// Below about this share of the rate still to come, the fit weighs its error relative
/// to that share.
const TAIL: f64 = 0.02;

/// Points of `F` the weights are fitted to (and the error is measured on).
const POINTS: usize = 64;

#[inline]
const fn at(i: usize, j: usize) -> usize {
    i * (i + 1) / 2 + j
}

/// An affine step of the cascade's state: `x' = M x + g u` for a plunger rate `u` held
/// over the step. `M` is lower triangular (a stage hears only the stages before it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Map<T> {
    /// `M`, row by row.
    pub m: [T; TRI],
    /// `g`.
    pub g: [T; STAGES],
}

impl Map<f64> {
    /// One cycle of the cascade with per-cycle factors `a`.
    fn cascade(a: &[f64; STAGES]) -> Self {
        let mut map = Map {
            m: [0.0; TRI],
            g: [0.0; STAGES],
        };
        for i in 0..STAGES {
            let b = 1.0 - a[i];
            // x'_i = a_i x_i + b_i x'_{i-1}, with x'_{-1} = u.
            if i == 0 {
                map.g[0] = b;
            } else {
                for j in 0..i {
                    map.m[at(i, j)] = b * map.m[at(i - 1, j)];
                }
                map.g[i] = b * map.g[i - 1];
            }
            map.m[at(i, i)] = a[i];
        }
        map
    }
}

impl<T: Real> Map<T> {
    /// This step twice.
    pub fn squared(&self) -> Self {
        let mut out = Map {
            m: [T::ZERO; TRI],
            g: [T::ZERO; STAGES],
        };
        for i in 0..STAGES {
            for j in 0..=i {
                let mut s = T::ZERO;
                for l in j..=i {
                    s += self.m[at(i, l)] * self.m[at(l, j)];
                }
                out.m[at(i, j)] = s;
            }
            let mut s = self.g[i];
            for l in 0..=i {
                s += self.m[at(i, l)] * self.g[l];
            }
            out.g[i] = s;
        }
        out
    }

    /// The state after this step.
    fn stepped(&self, x: &[T; STAGES], u: T) -> [T; STAGES] {
        let mut y = [T::ZERO; STAGES];
        for i in 0..STAGES {
            let mut s = self.g[i] * u;
            for j in 0..=i {
                s += self.m[at(i, j)] * x[j];
            }
            y[i] = s;
        }
        y
    }
}

/// A fitted cascade: its step over a cycle, weights, and how far its step response strays
/// from the Weibull curve.
#[derive(Clone, Copy, Debug)]
pub struct Fit {
    /// Time constants, s.
    pub tau: [f64; STAGES],
    /// Outflow weights (sum 1).
    pub c: [f64; STAGES],
    /// Largest difference from `F` on the fit's points, as a fraction of the rate (NaN
    /// where the fit was not asked to measure it: the board's).
    pub error: f64,
    /// The cascade over one control cycle.
    pub step: Map<f64>,
    /// Each stage's share of its gap closed per cycle, `1 - a_j`.
    pub b: [f64; STAGES],
}

/// `F`'s mean over the cycle ending at each of the fit's points: at 1, 2, 4, ... cycles
/// up to the uniform grid's spacing
/// (where a shape `n < 1` does most of its rising), then on that grid, a power of two of
/// cycles apart, up to the settling time.
struct Target {
    early: [f64; MAX_LEVELS],
    f: [f64; POINTS],
    log2_spacing: u32,
}

/// Most doublings of the cycle the fit's grid takes (63 x 2^24 cycles, 29 hours at
/// 10 kHz, is far past any validated settling time).
const MAX_LEVELS: usize = 24;

impl Target {
    fn new(k: f64, n: f64, dt: f64) -> Self {
        let settle_cycles = Syringe::settle_time(k, n) / dt;
        let mut log2_spacing = 0u32;
        while (log2_spacing as usize) < MAX_LEVELS
            && ((1u64 << log2_spacing) as f64) * ((POINTS - 1) as f64) < settle_cycles
        {
            log2_spacing += 1;
        }
        // Single precision: the board has no double-precision FPU (a software `pow` in
        // f64 costs about 25 000 instructions); f32 is within 1e-7 of the curve.
        let (kf, nf) = (k as f32, n as f32);
        let f_at = |t: f32| -> f64 {
            if t <= 0.0 {
                0.0
            } else {
                1.0 - libm::expf(-kf * libm::powf(t, nf)) as f64
            }
        };
        // The mean of F over the cycle ending `cycles` after the start: three-point
        // Gauss-Legendre (exact enough even where a shape n < 1 rises steeply).
        let f_mean = |cycles: f64| -> f64 {
            if cycles <= 0.0 {
                return 0.0;
            }
            const X: f64 = 0.387_298_334_620_741_7; // sqrt(3/5) / 2
            let mid = (cycles - 0.5) * dt;
            let at = |d: f64| f_at((mid + d * dt) as f32);
            (5.0 * at(-X) + 8.0 * at(0.0) + 5.0 * at(X)) / 18.0
        };
        let mut early = [0.0; MAX_LEVELS];
        for (i, e) in early.iter_mut().enumerate().take(log2_spacing as usize) {
            *e = f_mean((1u64 << i) as f64);
        }
        let mut f = [0.0; POINTS];
        let spacing = (1u64 << log2_spacing) as f64;
        for (i, fi) in f.iter_mut().enumerate() {
            *fi = f_mean(i as f64 * spacing);
        }
        Target {
            early,
            f,
            log2_spacing,
        }
    }

    /// Calls `each(state, F)` for every point, the state propagated by `step`'s powers
    /// from rest under a unit rate.
    fn walk<T: Real>(&self, step: &Map<f64>, mut each: impl FnMut(&[T; STAGES], T)) {
        let narrow = |m: &Map<f64>| Map::<T> {
            m: m.m.map(T::of),
            g: m.g.map(T::of),
        };
        let mut level = *step;
        let mut x = narrow(step).stepped(&[T::ZERO; STAGES], T::ONE);
        for i in 0..self.log2_spacing as usize {
            each(&x, T::of(self.early[i]));
            x = narrow(&level).stepped(&x, T::ONE);
            level = level.squared();
        }
        // Now x is at 2^L cycles, the grid's second point, and `level` its spacing.
        each(&[T::ZERO; STAGES], T::of(self.f[0]));
        let spacing = narrow(&level);
        for &f in self.f[1..].iter() {
            each(&x, T::of(f));
            x = spacing.stepped(&x, T::ONE);
        }
    }
}

/// The cascade's shape for Weibull shapes `n` (time constants scale with the curve's
/// median): `(n, log10(tau_0 / median), r)`, the best of `search` at each `n` on a 1 s
/// scale with 100 us cycles. `tests::the_shape_table_is_the_search_result` recomputes it
/// (and prints it when it differs); `tests::fit_error_across_shapes` checks shapes between
/// its rows. A table, because the search costs the board 66 fits in software double
/// precision (856 million instructions, seconds, past the watchdog); one fit costs it
/// about a million.
const SHAPES: [(f64, f64, f64); 49] = [
    (0.2000, -0.3125, 5.9874),
    (0.2139, 0.2500, 4.0000),
    (0.2287, 0.0000, 4.5326),
    (0.2446, -0.2500, 4.0000),
    (0.2615, -0.7500, 4.0000),
    (0.2797, -1.0000, 4.0000),
    (0.2991, -1.1250, 4.1270),
    (0.3198, -1.3125, 4.0000),
    (0.3420, -1.5625, 4.0000),
    (0.3657, -1.7500, 4.0000),
    (0.3911, -2.2500, 4.0000),
    (0.4182, -2.5000, 4.0000),
    (0.4472, -2.2500, 3.5300),
    (0.4782, -2.4375, 3.5300),
    (0.5114, -1.5000, 2.7457),
    (0.5469, -1.5000, 3.2101),
    (0.5848, -1.6250, 2.6612),
    (0.6254, -1.6250, 2.5000),
    (0.6687, -1.6875, 2.5000),
    (0.7151, -1.5000, 2.2062),
    (0.7647, -1.2500, 1.8290),
    (0.8178, -2.0000, 2.5000),
    (0.8745, -1.0000, 4.1270),
    (0.9351, -0.7500, 1.6474),
    (1.0000, -2.0000, 12.0000),
    (1.0694, -1.0000, 1.5000),
    (1.1435, -1.2500, 1.5000),
    (1.2228, -0.8125, 1.3237),
    (1.3077, -1.0000, 1.5000),
    (1.3984, -0.5000, 1.0000),
    (1.4953, -0.4375, 1.0000),
    (1.5991, -0.5000, 1.0000),
    (1.7100, -0.5000, 1.0000),
    (1.8286, -0.6250, 1.0645),
    (1.9554, -0.4375, 1.0000),
    (2.0910, -0.6250, 1.0000),
    (2.2361, -0.7500, 1.0000),
    (2.3912, -0.6250, 1.0645),
    (2.5570, -0.8750, 1.1331),
    (2.7344, 0.0000, 1.0000),
    (2.9240, -0.8750, 1.0000),
    (3.1268, -0.7500, 1.0000),
    (3.3437, -0.7500, 1.3248),
    (3.5756, -0.5000, 2.1384),
    (3.8236, -0.5000, 2.2763),
    (4.0888, -0.5000, 2.4231),
    (4.3724, -1.0000, 1.1331),
    (4.6757, -1.0000, 1.0000),
    (5.0000, -1.0000, 1.0000),
];

/// Fits the cascade for Weibull `k`, `n` and control cycles of `dt` seconds: time
/// constants from the shape table's nearest row, weights fitted to this curve.
#[inline(never)]
pub fn fit(k: f64, n: f64, dt: f64) -> Fit {
    let target = Target::new(k, n, dt);
    let median = median(k, n);
    // Nearest in log n, without logarithms: the smaller of the two ratios.
    let off = |s: f64| if s > n { s / n } else { n / s };
    let mut row = SHAPES[0];
    for s in SHAPES {
        if off(s.0) < off(row.0) {
            row = s;
        }
    }
    let tau0 = median * libm::pow(10.0, row.1);
    candidate(&target, tau0, row.2, dt, false).unwrap_or_else(|| first_order(median, dt))
}

/// The Weibull curve's median time, s: the scale of the cascade's time constants.
fn median(k: f64, n: f64) -> f64 {
    libm::pow(core::f64::consts::LN_2 / k, 1.0 / n)
}

/// A first-order lag at the median: only if a fit failed (cannot happen for validated
/// inputs, whose solves are well posed).
fn first_order(median: f64, dt: f64) -> Fit {
    let tau = [median; STAGES];
    let mut c = [0.0; STAGES];
    c[0] = 1.0;
    let a = tau.map(|t| libm::exp(-dt / t));
    Fit {
        tau,
        c,
        error: 1.0,
        step: Map::cascade(&a),
        b: tau.map(|t| -libm::expm1(-dt / t)),
    }
}

/// The best cascade for Weibull `k`, `n` by search: a coarse grid over the fastest
/// stage (1e-3 to 1 median) and the spread, then a pattern search from the best point,
/// halving its steps. Where the shape table comes from (host and tests; too costly for
/// the board).
pub fn search(k: f64, n: f64, dt: f64) -> Fit {
    let target = Target::new(k, n, dt);
    let median = median(k, n);
    let mut best = None::<Fit>;
    let keep = |cand: Option<Fit>, best: &mut Option<Fit>| {
        if let Some(c) = cand {
            if best.as_ref().is_none_or(|b| c.error < b.error) {
                *best = Some(c);
            }
        }
    };
    const RATIOS: [f64; 6] = [1.0, 1.5, 2.5, 4.0, 7.0, 12.0];
    let (mut l0, mut lr) = (0.0, 0.0);
    for i in 0..7 {
        let tau0 = median * libm::pow(10.0, -3.0 + 0.5 * i as f64);
        for r in RATIOS {
            let before = best.map(|b| b.error);
            keep(candidate(&target, tau0, r, dt, true), &mut best);
            if best.map(|b| b.error) != before {
                (l0, lr) = (libm::log(tau0), libm::log(r));
            }
        }
    }
    let (mut s0, mut sr) = (0.5 * core::f64::consts::LN_10, 0.25);
    for _ in 0..4 {
        for (d0, dr) in [(s0, 0.0), (-s0, 0.0), (0.0, sr), (0.0, -sr)] {
            let (t0, r) = (libm::exp(l0 + d0), libm::exp((lr + dr).max(0.0)));
            let before = best.map(|b| b.error);
            keep(candidate(&target, t0, r, dt, true), &mut best);
            if best.map(|b| b.error) != before {
                (l0, lr) = (l0 + d0, (lr + dr).max(0.0));
            }
        }
        s0 *= 0.5;
        sr *= 0.5;
    }
    best.unwrap_or_else(|| first_order(median, dt))
}

/// The cascade with `tau_j = tau0 r^j`, its weights fitted; `None` if the least-squares
/// system is singular.
#[inline(never)]
fn candidate(target: &Target, tau0: f64, r: f64, dt: f64, measure: bool) -> Option<Fit> {
    let mut tau = [0.0; STAGES];
    let mut a = [0.0; STAGES];
    for j in 0..STAGES {
        tau[j] = tau0 * libm::pow(r, j as f64);
        a[j] = libm::exp(-dt / tau[j]);
    }
    let step = Map::cascade(&a);
    // Least squares with the weights summing to 1: the last weight is 1 minus the others,
    // so the unknowns are the first STAGES - 1 against `F - x_last`.
    // Rows in single precision, each folded into a triangular factor by Givens rotations
    // as it comes (whose error grows with the rows' condition, not its square as the
    // normal equations' does, and which keeps no rows: the board fits in its control
    // interrupt, whose stack frame must stay small). The board has an FPU for f32 only:
    // this fit in software f64 cost it 2.7 million instructions a syringe, enough to keep
    // it from answering its host.
    const U: usize = STAGES - 1;
    let mut tri = [[0.0f32; U + 1]; U];
    target.walk::<f32>(&step, |x, f| {
        let last = x[STAGES - 1];
        // Relative to what is still to come where little is: a bead ends on the tail of
        // a stop, where the head follows a flow of a few percent of the rate and its
        // section is the ratio of the two flows.
        let w = 1.0 / (1.0 - f + TAIL as f32);
        let mut row = [0.0f32; U + 1];
        for j in 0..U {
            row[j] = w * (x[j] - last);
        }
        row[U] = w * (f - last);
        givens(&mut tri, row);
    });
    let w = back_substitute(&tri)?;
    let mut c = [0.0; STAGES];
    for (cj, wj) in c.iter_mut().zip(w.iter()) {
        *cj = *wj as f64;
    }
    c[STAGES - 1] = 1.0 - c[..U].iter().sum::<f64>();
    // The error takes a second pass: the search needs it, the board's fit does not (it
    // costs the board a third of its set-up; its `error` is then NaN).
    let mut error = if measure { 0.0f64 } else { f64::NAN };
    if measure {
        target.walk::<f64>(&step, |x, f| {
            let y: f64 = c.iter().zip(x.iter()).map(|(c, x)| c * x).sum();
            error = error.max((y - f).abs());
        });
    }
    (error.is_finite() || !measure).then_some(Fit {
        tau,
        c,
        error,
        step,
        b: tau.map(|t| -libm::expm1(-dt / t)),
    })
}

/// Folds `row` (`[a_0 .. a_(U-1) | b]`) into the upper-triangular factor `tri` of the
/// least-squares problem by plane rotations.
fn givens<const V: usize, const U: usize>(tri: &mut [[f32; V]; U], mut row: [f32; V]) {
    for k in 0..U {
        let (a, b) = (tri[k][k], row[k]);
        if b == 0.0 {
            continue;
        }
        let h = libm::hypotf(a, b);
        let (c, s) = (a / h, b / h);
        for j in k..V {
            let (t, r) = (tri[k][j], row[j]);
            tri[k][j] = c * t + s * r;
            row[j] = c * r - s * t;
        }
    }
}

/// The least-squares solution from the triangular factor; `None` if a column is
/// (nearly) dependent on the others.
fn back_substitute<const V: usize, const U: usize>(tri: &[[f32; V]; U]) -> Option<[f32; U]> {
    let mut w = [0.0f32; U];
    for j in (0..U).rev() {
        let d = tri[j][j];
        if d.abs() < 1e-30 {
            return None;
        }
        let mut s = tri[j][V - 1];
        for l in j + 1..U {
            s -= tri[j][l] * w[l];
        }
        w[j] = s / d;
    }
    w.iter().all(|v| v.is_finite()).then_some(w)
}

/// `map` composed with itself `2^levels` times.
pub fn power<T: Real>(map: &Map<T>, levels: u32) -> Map<T> {
    let mut m = *map;
    for _ in 0..levels {
        m = m.squared();
    }
    m
}

/// The volume per unit of state still to come once the plunger has stopped, as a row
/// vector `rest` (volume = `rest . x` for the state `x` at a cycle's start): the cycles'
/// outflows `c M^(i+1) x` summed over `i >= 0` and times `dt`, that is
/// `dt (sum_i c M^i) M`, summed by doubling to beyond `cycles`.
pub fn rest<T: Real>(step: &Map<T>, c: &[T; STAGES], dt: f64, cycles: f64) -> [T; STAGES] {
    let mut p = *step;
    let mut acc = *c;
    let mut covered = 1.0;
    while covered < cycles {
        // acc += acc P; P = P^2 (the affine part is zero: the plunger is stopped).
        let mut next = acc;
        for (j, nj) in next.iter_mut().enumerate() {
            for i in j..STAGES {
                *nj += acc[i] * p.m[at(i, j)];
            }
        }
        acc = next;
        p = p.squared();
        covered *= 2.0;
    }
    core::array::from_fn(|j| {
        let mut v = T::ZERO;
        for i in j..STAGES {
            v += acc[i] * step.m[at(i, j)];
        }
        v * T::of(dt)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;

    /// The step response of the fitted cascade at every control cycle (its outflow after
    /// the cycle's step, as the chip reads it) against the Weibull curve's mean over that
    /// cycle, in double precision.
    fn worst_per_cycle(k: f64, n: f64, dt: f64) -> f64 {
        let fit = fit(k, n, dt);
        let settle = Syringe::settle_time(k, n);
        let mut x = [0.0; STAGES];
        let mut worst = 0.0f64;
        let mut t = 0.0;
        while t < 1.2 * settle {
            x = fit.step.stepped(&x, 1.0);
            let y: f64 = fit.c.iter().zip(x.iter()).map(|(c, x)| c * x).sum();
            // The cycle's mean of F, by the midpoint rule on 64 parts.
            let mean = (0..64)
                .map(|i| Syringe::response(k, n, t + (i as f64 + 0.5) / 64.0 * dt))
                .sum::<f64>()
                / 64.0;
            worst = worst.max((y - mean).abs());
            t += dt;
        }
        worst
    }

    /// The shapes the table holds: 0.2 to 5 evenly in log n (6.9 % apart).
    fn table_shapes() -> [f64; 49] {
        core::array::from_fn(|i| {
            let t = i as f64 / 48.0;
            libm::exp(libm::log(0.2) + t * (libm::log(5.0) - libm::log(0.2)))
        })
    }

    #[test]
    fn the_shape_table_is_the_search_result() {
        let mut rows = [(0.0, 0.0, 0.0); 49];
        for (row, n) in rows.iter_mut().zip(table_shapes()) {
            let f = search(10.0, n, 1e-4);
            let m = median(10.0, n);
            let r = f.tau[1] / f.tau[0];
            *row = (n, libm::log10(f.tau[0] / m), r);
        }
        let same = rows.iter().zip(SHAPES.iter()).all(|(a, b)| {
            (a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3 && (a.2 - b.2).abs() < 1e-3
        });
        if !same {
            let mut text = std::string::String::new();
            for (n, l, r) in rows {
                text += &std::format!("    ({n:.4}, {l:.4}, {r:.4}),\n");
            }
            panic!("the shape table is stale; the search gives:\n{text}");
        }
    }

    #[test]
    fn fit_error_across_shapes() {
        // Shapes across the validated range at a 1 s scale, and the bundled syringes.
        let dt = 1e-4;
        let mut failed = false;
        for (n, bound) in [
            (0.2, 4e-3),
            (0.3, 4e-3),
            (0.4, 4e-3),
            (0.5, 4e-3),
            (0.7, 4e-3),
            (0.9, 7e-3),
            (1.0, 4e-3),
            (1.1, 4e-3),
            (1.3, 4e-3),
            (1.5, 4e-3),
            (2.0, 4e-3),
            (2.5, 7e-3),
            (3.0, 1.5e-2),
            (4.0, 0.1),
            (5.0, 0.1),
        ] {
            let k = 10.0;
            let e = worst_per_cycle(k, n, dt);
            eprintln!("n {n}: worst {e:.2e} (bound {bound:.0e})");
            failed |= e >= bound;
        }
        for (k, n) in [(30.0, 1.3), (45.0, 1.1), (400.0, 1.5)] {
            let e = worst_per_cycle(k, n, dt);
            eprintln!("k {k} n {n}: worst {e:.2e}");
            failed |= e >= 1.5e-3;
        }
        assert!(!failed);
    }
}
