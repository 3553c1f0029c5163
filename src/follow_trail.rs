//! The path the ring's mean has taken while the flow's follower runs, by arc length: the
//! follower's head, when it lags the mean, is placed on it (`crate::flow_follow`), so that
//! a lag carried round a tight turn keeps the head on the path. Along the mean's tangent
//! instead, a lag of 0.1 mm swung across a row end's U-turn as the tangent turned: the
//! 0.6 mm stripes' X went to 608 mm/s^2 at 500. Stops at placing a point; the follower
//! decides the lag.

/// Spacing of the points kept, position units (0.1 um): a chord of 5 um on a 0.1 mm
/// fillet strays 0.03 um from the arc.
const SPACING: f32 = 50.0;

/// Points kept: 0.32 mm of path behind the mean at `SPACING` (the lag of the follower
/// and the slowing at tight fillets together stay under half of it). A lag past the
/// oldest point runs on along the oldest chord.
const POINTS: usize = 64;

/// Past this distance from the anchor, units (100 mm), the points are moved to a new one,
/// so that f32 keeps positions to a hundredth of a unit.
const REANCHOR: f32 = 1.0e6;

/// The mean's path behind it; all zero until started, so that the executor holding it is
/// still built in place.
#[derive(Clone, Debug)]
pub struct Trail {
    /// Points, relative to `anchor`, and their arc length from the start.
    p: [[f32; 2]; POINTS],
    s: [f32; POINTS],
    /// Points pushed since the start (the next one's number).
    count: u32,
    /// Point number at or before the head, where the last search ended.
    cursor: u32,
    anchor: [i32; 2],
    /// The mean now, relative to `anchor`, and its arc length.
    now: [f32; 2],
    s_now: f32,
}

impl Trail {
    /// Empty.
    pub const fn new() -> Self {
        Trail {
            p: [[0.0; 2]; POINTS],
            s: [0.0; POINTS],
            count: 0,
            cursor: 0,
            anchor: [0; 2],
            now: [0.0; 2],
            s_now: 0.0,
        }
    }

    /// A path starting at the mean at `base` (units) plus `off`.
    pub fn start(&mut self, base: [i32; 2], off: [f32; 2]) {
        self.anchor = base;
        self.now = off;
        self.s_now = 0.0;
        self.count = 0;
        self.cursor = 0;
        self.push();
    }

    fn push(&mut self) {
        let i = self.count as usize % POINTS;
        self.p[i] = self.now;
        self.s[i] = self.s_now;
        self.count = self.count.wrapping_add(1);
    }

    /// The mean moved to `base` plus `off`, by `step` units along its path (the length of
    /// the move, which the follower has worked out).
    pub fn advance(&mut self, base: [i32; 2], off: [f32; 2], step: f32) {
        let rel = [
            base[0].wrapping_sub(self.anchor[0]) as f32 + off[0],
            base[1].wrapping_sub(self.anchor[1]) as f32 + off[1],
        ];
        self.now = rel;
        self.s_now += step;
        if self.count == 0 {
            return self.push();
        }
        let last = (self.count - 1) as usize % POINTS;
        if self.s_now - self.s[last] >= SPACING {
            self.push();
        }
        if libm::fabsf(rel[0]) > REANCHOR || libm::fabsf(rel[1]) > REANCHOR || self.s_now > REANCHOR
        {
            self.reanchor(base);
        }
    }

    /// Moves the anchor to `base` and the arc length's zero to the oldest point: once in
    /// 100 mm of path.
    #[cold]
    fn reanchor(&mut self, base: [i32; 2]) {
        let d = [
            base[0].wrapping_sub(self.anchor[0]) as f32,
            base[1].wrapping_sub(self.anchor[1]) as f32,
        ];
        let s0 = self.s[self.oldest() as usize % POINTS];
        for (p, s) in self.p.iter_mut().zip(self.s.iter_mut()) {
            *p = [p[0] - d[0], p[1] - d[1]];
            *s -= s0;
        }
        self.now = [self.now[0] - d[0], self.now[1] - d[1]];
        self.s_now -= s0;
        self.anchor = base;
    }

    fn oldest(&self) -> u32 {
        self.count.saturating_sub(POINTS as u32)
    }

    /// The point `lag` units (> 0) behind the mean along its path, as an offset from the
    /// mean. Amortised a step or two a frame: the head moves on along the path, and the
    /// search starts where the last one ended.
    pub fn behind(&mut self, lag: f32) -> [f32; 2] {
        // NaN or not above 0: no point behind.
        if self.count == 0 || lag.is_nan() || lag <= 0.0 {
            return [0.0; 2];
        }
        let target = self.s_now - lag;
        let (oldest, newest) = (self.oldest(), self.count - 1);
        let mut k = self.cursor.clamp(oldest, newest);
        while k > oldest && self.s[k as usize % POINTS] > target {
            k -= 1;
        }
        while k < newest && self.s[(k + 1) as usize % POINTS] <= target {
            k += 1;
        }
        self.cursor = k;
        let (p0, s0) = (self.p[k as usize % POINTS], self.s[k as usize % POINTS]);
        // The chord from point `k` to the next one, or to the mean now; past the oldest
        // point, the oldest chord runs on.
        let (p1, s1) = if k < newest {
            let j = (k + 1) as usize % POINTS;
            (self.p[j], self.s[j])
        } else {
            (self.now, self.s_now)
        };
        let len = s1 - s0;
        let t = if len > 1.0e-3 {
            (target - s0) / len
        } else {
            0.0
        };
        [
            p0[0] + (p1[0] - p0[0]) * t - self.now[0],
            p0[1] + (p1[1] - p0[1]) * t - self.now[1],
        ]
    }
}

impl Default for Trail {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Round a quarter circle of 1 000 units, the point found at each lag lies on the arc
    /// (within the chords' 0.3 units) and at that arc length behind the mean.
    #[test]
    fn places_the_lag_on_the_path() {
        let r = 1000.0f64;
        let mut t = Trail::new();
        let at = |phi: f64| [r * phi.cos(), r * phi.sin()];
        let base = [3_000_000, -2_000_000];
        let split = |p: [f64; 2]| -> [f32; 2] { [p[0] as f32, p[1] as f32] };
        t.start(base, split(at(0.0)));
        let n = 2000;
        let dphi = core::f64::consts::FRAC_PI_2 / n as f64;
        for i in 1..=n {
            let phi = i as f64 * dphi;
            t.advance(base, split(at(phi)), (r * dphi) as f32);
            if i % 100 == 0 {
                for lag in [10.0, 120.0, 400.0, 900.0] {
                    let back = lag / r;
                    if back > phi {
                        continue;
                    }
                    let d = t.behind(lag as f32);
                    let want = at(phi - back);
                    let now = at(phi);
                    let got = [now[0] + d[0] as f64, now[1] + d[1] as f64];
                    let err = ((got[0] - want[0]).powi(2) + (got[1] - want[1]).powi(2)).sqrt();
                    assert!(err < 0.5, "phi {phi:.3}, lag {lag}: {err} off");
                }
            }
        }
        assert_eq!(t.behind(0.0), [0.0; 2]);
        assert_eq!(t.behind(f32::NAN), [0.0; 2]);
    }

    /// A lag past the points kept runs on along the oldest chord, and a path longer than
    /// the anchor's reach keeps its precision.
    #[test]
    fn runs_past_the_oldest_point_and_far() {
        let mut t = Trail::new();
        t.start([0, 0], [0.0, 0.0]);
        let mut x = 0i32;
        for _ in 0..30_000 {
            x += 70;
            t.advance([x, 0], [0.25, 0.0], 70.0);
        }
        // 2.1 million units along X: reanchored at least once.
        let d = t.behind(35.0);
        assert!((d[0] + 35.0).abs() < 0.05 && d[1].abs() < 1e-3, "{d:?}");
        let far = t.behind(20_000.0);
        assert!((far[0] + 20_000.0).abs() < 0.5, "{far:?}");
    }
}
