//! Per-step ramp windows (issue 22): the ramp ring's box mean takes the head through
//! every change of the plan's velocity over the machine's one window, sized for its worst
//! step. This finds each step of the planned velocity (a second difference of the planned
//! X/Y position far beyond what smooth motion makes in one cycle) as it enters the ring,
//! and re-ramps it over the shortest window that keeps *that* step within the ramp's
//! share of the limit. It stops at the correction of the ring's mean; sizing the
//! machine's window stays the config's.
//!
//! The box mean is linear in the plan, and the plan's velocity stepping by `d` (position
//! units a cycle) between frames `k - 1` and `k` adds `d e_H(m)` to the mean of a window
//! of `2H + 1` frames centred `m - 1` frames past `k`, with
//! `e_H(m) = ((m + H)(m + H + 1) / 2 - (2H + 1) max(m, 0)) / (2H + 1)` for `|m| < H`
//! and nothing outside. Taking `d (e_H(m) - e_h(m))` back off the mean leaves that step
//! ramped over `2h + 1` frames, exactly, whatever else the window holds; `e_h` is 0 until
//! `m` reaches `-h`, so a step's own window may still change while it is that far off.

use crate::real::Real;
use crate::width_blend::WidthBlend;

/// Steps re-ramped at once. Two a switch at most (a flow step split across two cycles),
/// and switches are several windows apart; a step finding no room keeps the machine's
/// window, which always holds the limit.
pub const STEP_CAPACITY: usize = 4;

/// A second difference (position units a cycle^2) is a step when a component lies
/// outside `-STEP_MIN ..= STEP_MIN - 1`: each position is rounded to the unit, so smooth
/// motion's read up to 2 either way.
const STEP_MIN: i32 = 4;

impl StepRamps {
    /// The largest second difference (position units a cycle^2) that is no step.
    pub const UNSEEN: i32 = STEP_MIN;
}

/// Frames within which a second step joins the previous one's window (a step the flow
/// model spreads over two cycles).
const JOIN_FRAMES: u32 = 2;

#[derive(Clone, Copy, Debug, Default)]
struct Step {
    /// Ring index of the frame whose velocity changed.
    at: u32,
    /// The velocity step, X and Y, position units a cycle.
    d: [i32; 2],
    /// Half the step's own window, frames.
    half: i32,
    /// Size its window is for, units a cycle (its pair's and its own if paired).
    size: f32,
    /// One of a pair sharing a window.
    paired: bool,
}

/// The steps the ring's window holds, and how to size their windows.
#[derive(Clone, Debug)]
pub struct StepRamps {
    steps: [Step; STEP_CAPACITY],
    len: u8,
    /// Frames until the outputs have passed every step's window (then all leave).
    live: u32,
    /// Ring index of the last step left to the machine's window (`skipped`: there is one).
    skip_at: u32,
    skipped: bool,
    /// Half the machine's window, frames (0: no re-ramping).
    half_max: i32,
    /// Window frames per position unit a cycle of velocity step (0: no re-ramping).
    frames_per_unit: f32,
    /// The ring's width changes, blended (beside the ring for the same reason as these).
    blend: WidthBlend,
}

impl StepRamps {
    /// None, re-ramping off.
    pub const fn new() -> Self {
        StepRamps {
            steps: [Step {
                at: 0,
                d: [0; 2],
                half: 0,
                size: 0.0,
                paired: false,
            }; STEP_CAPACITY],
            len: 0,
            live: 0,
            skip_at: 0,
            skipped: false,
            half_max: 0,
            frames_per_unit: 0.0,
            blend: WidthBlend::new(),
        }
    }

    /// No steps; windows of `window` frames (odd), each step's sized at
    /// `frames_per_unit` frames per position unit a cycle of its velocity step (0: off).
    pub fn reset(&mut self, window: u32, frames_per_unit: f32) {
        self.blend.reset(window / 2);
        self.len = 0;
        self.live = 0;
        self.skipped = false;
        self.half_max = (window / 2) as i32;
        self.frames_per_unit = if frames_per_unit.is_finite() && frames_per_unit > 0.0 {
            frames_per_unit
        } else {
            0.0
        };
    }

    /// The ring's width-change blend (`crate::width_blend`).
    pub fn blend(&mut self) -> &mut WidthBlend {
        &mut self.blend
    }

    /// Is the second difference `d2` (X, Y) a step? One branch on the tick's path.
    #[inline(always)]
    pub fn is_step(d2: [i32; 2]) -> bool {
        // Both offsets within 0 .. 2 STEP_MIN (a power of two) exactly when their OR is.
        let (x, y) = (
            d2[0].wrapping_add(STEP_MIN) as u32,
            d2[1].wrapping_add(STEP_MIN) as u32,
        );
        (x | y) >= 2 * STEP_MIN as u32
    }

    /// A step `d` entered the ring as push `at` (the newest frame); the steps whose
    /// windows the outputs have passed leave. Out of line: a few times a bead.
    ///
    /// A step the flow model spreads over two cycles comes as two, a frame or two apart:
    /// they share one window, sized for the sum of their sizes (so that their ramps, one
    /// on top of the other, keep the limit). A third so close (a late tick's catch-up,
    /// a steep but not sudden change) hands the group back to the machine's window.
    ///
    /// Only a step into motion (`moving`: the plan moves after it, and moved the cycle
    /// before it or stood still over the whole window before it) is re-ramped. A bead's
    /// end, and its start straight after a travel, keep the machine's window: the travel's
    /// own deceleration into the start (at the full limit; measured 6 828 mm/s^2 on a
    /// 5 000 machine with the two added) or out of the end lies under it.
    #[inline(never)]
    pub fn add(&mut self, at: u32, dx: i32, dy: i32, moving: bool) {
        let d = [dx, dy];
        if self.frames_per_unit == 0.0 || self.half_max < 2 {
            return;
        }
        self.expire(at);
        let near_skip = self.skipped && at.wrapping_sub(self.skip_at) <= JOIN_FRAMES;
        if !moving || near_skip {
            self.skipped = true;
            self.skip_at = at;
            // A step just re-ramped whose second part is this one: both keep the machine's
            // window (what its first frames already took off is a few hundredths of a unit
            // a frame).
            let n = self.len as usize;
            if let Some(l) = self.steps[..n].last().copied() {
                if at.wrapping_sub(l.at) <= JOIN_FRAMES {
                    let first = if l.paired { n - 2 } else { n - 1 };
                    for s in &mut self.steps[first..n] {
                        s.half = self.half_max;
                    }
                }
            }
            return;
        }
        // Every step kept leaves with the last: its window ends 2H frames on.
        self.live = 2 * self.half_max as u32 + 1;
        let (x, y) = (d[0] as f32, d[1] as f32);
        let size = libm::sqrtf(x * x + y * y);
        let n = self.len as usize;
        let last = self.steps[..n].last().copied();
        match last {
            Some(l) if at.wrapping_sub(l.at) <= JOIN_FRAMES => {
                let first = if l.paired { n - 2 } else { n - 1 };
                if l.paired || n >= STEP_CAPACITY {
                    for s in &mut self.steps[first..n] {
                        s.half = self.half_max;
                    }
                    return;
                }
                let total = l.size + size;
                let half = self.half_for(total);
                self.steps[n - 1].half = half;
                self.steps[n - 1].paired = true;
                self.steps[n] = Step {
                    at,
                    d,
                    half,
                    size: total,
                    paired: true,
                };
                self.len += 1;
            }
            _ => {
                if n < STEP_CAPACITY {
                    self.steps[n] = Step {
                        at,
                        d,
                        half: self.half_for(size),
                        size,
                        paired: false,
                    };
                    self.len += 1;
                }
            }
        }
    }

    /// Half the window, frames, for a velocity step of `size` units a cycle: an odd
    /// window of `2h + 1` frames at least `size * frames_per_unit` long. A step needing
    /// nearly the machine's window keeps it: a paired step's window may change only while
    /// the outputs are still at least its half short of it, which the first of a pair,
    /// up to `JOIN_FRAMES + 1` frames into the machine's window, is for
    /// `h <= H - JOIN_FRAMES - 1`.
    fn half_for(&self, size: f32) -> i32 {
        let limit = self.half_max - JOIN_FRAMES as i32 - 1;
        let frames = size * self.frames_per_unit;
        if frames.is_finite() && frames < (2 * limit) as f32 {
            ((libm::ceilf(frames) as i32) / 2).min(limit)
        } else {
            self.half_max
        }
    }

    /// Forgets the steps whose windows the outputs have passed (`now` newest).
    fn expire(&mut self, now: u32) {
        let mut i = 0;
        while i < self.len as usize {
            if self.m(now, self.steps[i].at) >= self.half_max {
                self.len -= 1;
                self.steps[i] = self.steps[self.len as usize];
            } else {
                i += 1;
            }
        }
    }

    /// A frame entered the ring. Once the outputs have passed every step's window, all
    /// leave: ring indices wrap, and a step kept longer would come round again.
    #[inline(always)]
    pub fn tick(&mut self) {
        if self.live != 0 {
            self.live -= 1;
            if self.live == 0 {
                self.len = 0;
            }
        }
    }

    /// Where the outputs are relative to a step at ring index `at`, `now` newest: `m`
    /// above. The ring holds the machine's window, so `now - at` is within it while the
    /// step is kept.
    #[inline(always)]
    fn m(&self, now: u32, at: u32) -> i32 {
        (now.wrapping_sub(at) & (crate::capacity::RAMP_CAPACITY as u32 - 1)) as i32 - self.half_max
            + 1
    }

    /// Whether a step of the velocity entering the ring after frame `newest` and ramped
    /// over the machine's window (a stop) would overlap a re-ramped step's own window:
    /// their ramps would add. A pause's shut waits for it (`Executor::pause_check`): one
    /// asked 66 frames after a change of paste's step, its stop's ramp on top of that
    /// step's, took X to 2 138 mm/s^2 on a 2 000 machine.
    pub fn narrowed_ahead(&self, newest: u32) -> bool {
        self.steps[..self.len as usize]
            .iter()
            .any(|s| s.half < self.half_max && self.m(newest, s.at) <= s.half)
    }

    /// Whether any step is being re-ramped.
    #[inline(always)]
    pub fn any(&self) -> bool {
        self.len != 0
    }

    /// What to take off the ring's X/Y mean, position units, `now` the newest frame's
    /// ring index, the mean over `2 box_half + 1` frames centred on the outputs' (the
    /// ring's window, or what a switch narrowed it to: `crate::switch_window`). Out of
    /// line: only while a step passes the outputs.
    #[inline(never)]
    pub fn offset<R: Real>(&self, now: u32, box_half: u32) -> [R; 2] {
        let mut o = [R::ZERO; 2];
        let big = box_half as i32;
        for s in &self.steps[..self.len as usize] {
            let m = self.m(now, s.at);
            let f = e::<R>(m, big) - e::<R>(m, s.half);
            o[0] += R::from_i64(s.d[0] as i64) * f;
            o[1] += R::from_i64(s.d[1] as i64) * f;
        }
        o
    }
}

impl Default for StepRamps {
    fn default() -> Self {
        Self::new()
    }
}

/// `e_h(m)` above: how far a window of `2h + 1` frames centred `m - 1` frames past a
/// velocity step of one unit a cycle puts its mean ahead of the plan, units.
#[inline(always)]
fn e<R: Real>(m: i32, h: i32) -> R {
    if m <= -h || m >= h {
        return R::ZERO;
    }
    let w = 2 * h + 1;
    let a = m + h;
    let num = a * (a + 1) - 2 * w * m.max(0);
    R::from_i64(num as i64) / R::from_i64((2 * w) as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mean of a box of `2h + 1` frames over a plan whose velocity steps by one unit
    /// a cycle, brute force, against `e`.
    #[test]
    fn e_is_the_box_mean_of_a_velocity_step() {
        for h in [1i32, 3, 12, 40] {
            let w = 2 * h + 1;
            let k = 200i32;
            let r = |n: i32| (n - k + 1).max(0) as f64;
            for c in (k - 60)..(k + 60) {
                let mean: f64 = ((c - h)..=(c + h)).map(r).sum::<f64>() / w as f64;
                let got = e::<f64>(c - k + 1, h);
                assert!((mean - r(c) - got).abs() < 1e-5, "h {h} c {c}: {got}");
            }
        }
    }

    #[test]
    fn a_step_is_sized_to_its_own_window_and_joins_its_neighbour() {
        let mut s = StepRamps::new();
        s.reset(49, 0.5);
        // 10 units a cycle: 5 frames, half 2.
        s.add(100, 10, 0, true);
        assert_eq!(s.steps[0].half, 2);
        // A second part the next cycle: the pair needs 20 * 0.5 = 10 frames, half 5.
        s.add(101, 10, 0, true);
        assert_eq!((s.steps[0].half, s.steps[1].half), (5, 5));
        // A third: the group goes back to the machine's window (half 24).
        s.add(102, 0, -10, true);
        assert_eq!((s.len, s.steps[0].half, s.steps[1].half), (2, 24, 24));
        // Far past both windows they leave.
        s.add(400, 0, 30, true);
        assert_eq!(s.len, 1);
        assert_eq!(s.steps[0].half, 7);
        // Opposite steps a frame apart (a one-cycle blip) ramp for both sizes together.
        s.add(800, 40, 0, true);
        s.add(801, -40, 0, true);
        assert_eq!((s.steps[0].half, s.steps[1].half), (20, 20));
        // What rounding makes is no step; a few units are.
        assert!(!StepRamps::is_step([2, -2]) && !StepRamps::is_step([-4, 3]));
        assert!(StepRamps::is_step([4, 0]) && StepRamps::is_step([0, -5]));
        assert!(StepRamps::is_step([i32::MAX, 0]) && StepRamps::is_step([0, i32::MIN]));
        // A step from rest, and the next frame's, keep the machine's window.
        s.add(900, 40, 0, false);
        s.add(901, 10, 0, true);
        assert!(s.steps[..s.len as usize].iter().all(|x| x.at < 900));
        // Off: nothing kept.
        s.reset(49, 0.0);
        s.add(500, 100, 0, true);
        assert!(!s.any());
    }
}
