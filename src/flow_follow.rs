//! A slew-limited follower of the flow's speed for a channel of several pastes (issue 22).
//! There the valves change the flow faster than the X/Y limit allows (paste B's line
//! closing into a channel still mostly paste A: from 14.8 to 4.2 mm/s in 26 ms, up to
//! 1 124 mm/s^2 at the kink), and a centred box mean within the limit must be as wide as
//! the change is large (24 ms on the fine features at 500 mm/s^2): it spreads the head's
//! ramp over the change and its own width, 8 % off the section over 0.2 mm. This head
//! speed `u` changes by at most `a` a frame and aims between the highest speed from which
//! the head can still meet the flow ahead (the ring's frames, up to the outputs' half
//! window ahead: a sliding minimum) and the lowest from which it can, so that it starts
//! slowing as late as the limit allows and meets the flow where the flow's own change
//! drops within it; the lag `e` it builds returns at most 1 % of the speed (what that lays
//! off the section). Inside a turn the speed's change gets what the turn leaves of the
//! whole limit by the vector sum. Offline on the fine features' worst stretch this took
//! the section from 7.9 % off to 1.7 % at 475 mm/s^2; in the executor, 1.8 % away from
//! turns. It stops at the head's arc speed and lag along the mean's direction: the ring's
//! mean (with its narrow box for fillets and rounding) is what it bends, through the
//! width blend's offset (`crate::width_blend`). Where to use it is `crate::switch_window`'s
//! call: not near a turn tighter than the limit allows at the flow's speed.

use crate::fast::{max, min};

/// Frames a block of the envelopes takes: each entry is the extreme of `BLOCK` frames
/// (exact for them, referred to the block's first frame), so that the envelopes reach
/// the outputs' half window of the largest ring in 512 B. Whole frames took 4 KiB, which
/// the firmware built on `control_state`'s stack frame (7 KiB, over the 4 KiB gate).
const BLOCK: i32 = 8;

/// Blocks an envelope holds: the outputs' half window of the largest ring.
const QUEUE: usize = crate::capacity::RAMP_CAPACITY / 2 / BLOCK as usize;

/// Weight of the low envelope (the latest slowing that meets the flow) against the high
/// one in the head's aim; offline on the fine features' worst stretch at 475 mm/s^2
/// (section off over 0.2 mm): 1.0, 2.1 %; 0.75, 1.7 %; 0.5, 3.7 %.
const LOW_WEIGHT: f32 = 0.75;

/// Frames over which the lag is returned (10 ms at 10 kHz; offline 1.7 % against
/// 1.9 % at 20 ms).
const RETURN_FRAMES: f32 = 100.0;

/// Frames of the smoothing of the direction whose turn rate gives the turn's share of the
/// limit: short, as the mean's moves are taken to a fraction of a unit.
const TURN_FRAMES: f32 = 4.0;

/// Frames of the mean's direction's smoothing (the 0.1 um rounding of the mean's steps
/// shows in its direction; the lag along a raw direction jitters by up to a unit).
const DIR_FRAMES: f32 = 20.0;

/// The whole X/Y limit over the ramps' share (`config::RAMP_SHARE`).
const WHOLE: f32 = 1.0 / crate::config::RAMP_SHARE as f32;
/// Most the lag's return adds to the head's speed, relative: what it lays off the section.
const RETURN_SHARE: f32 = 0.01;

#[derive(Clone, Copy, Debug)]
struct Entry {
    at: i32,
    v: f32,
}

/// A sliding extreme over the frames ahead of the outputs: the least `v(k) + a (k - c)`
/// (`low`) or the greatest `v(k) - a (k - c)`, `c` the outputs' frame. Amortised one push
/// and one pop a frame; a flow falling faster than the limit pops a few a frame.
#[derive(Clone, Copy, Debug)]
struct Envelope {
    q: [Entry; QUEUE],
    front: u16,
    len: u16,
}

impl Envelope {
    /// All zero, so that the executor holding it is still built in place (a field that
    /// is not put the follower on `control_state`'s frame in the firmware, 9 KiB).
    const fn new() -> Self {
        Envelope {
            q: [Entry { at: 0, v: 0.0 }; QUEUE],
            front: 0,
            len: 0,
        }
    }

    fn clear(&mut self) {
        self.front = 0;
        self.len = 0;
    }

    fn slot(&self, i: u16) -> usize {
        (self.front as usize + i as usize) % QUEUE
    }

    /// Frame `at` (newer than every frame held) of speed `v`; `low` for the least.
    fn push(&mut self, at: i32, v: f32, a: f32, low: bool) {
        while self.len > 0 {
            let b = self.q[self.slot(self.len - 1)];
            let a = a * (at - b.at) as f32;
            let beaten = if low { b.v - a >= v } else { b.v + a <= v };
            if !beaten {
                break;
            }
            self.len -= 1;
        }
        if self.len as usize == QUEUE {
            self.front = ((self.front as usize + 1) % QUEUE) as u16;
            self.len -= 1;
        }
        let s = self.slot(self.len);
        self.q[s] = Entry { at, v };
        self.len += 1;
    }

    /// The extreme for outputs at frame `c` (frames before it leave), if any is held.
    fn at(&mut self, c: i32, a: f32, low: bool) -> Option<f32> {
        while self.len > 0 && self.q[self.front as usize].at < c {
            self.front = ((self.front as usize + 1) % QUEUE) as u16;
            self.len -= 1;
        }
        if self.len == 0 {
            return None;
        }
        let f = self.q[self.front as usize];
        let a = a * (f.at - c) as f32;
        Some(if low { f.v + a } else { f.v - a })
    }
}

/// The follower's state; all zero until reset, so the executor holding it is built in
/// place.
#[derive(Clone, Debug)]
pub struct FlowFollow {
    low: Envelope,
    high: Envelope,
    active: bool,
    started: bool,
    /// Frames pushed since it started (the newest's number).
    frames: i32,
    /// The block being gathered: its first frame, its least `v + a (k - first)` and
    /// greatest `v - a (k - first)`, and its frames so far.
    block: (i32, f32, f32, i32),
    /// Frames from the outputs' to the newest.
    half: i32,
    /// The limit, position units a frame squared.
    a: f32,
    /// Position units a frame per volume unit a frame (1 / bead section).
    per_dv: f32,
    /// Head speed (units a frame), lag behind the mean (units), the causal envelopes.
    u: f32,
    e: f32,
    fall: f32,
    rise: f32,
    /// The mean where it was last: the newest frame's position and the mean's offset from
    /// it (kept apart, so that a frame's move keeps its fraction of a unit in f32).
    last: ([i32; 2], [f32; 2]),
    /// The mean's direction smoothed over `TURN_FRAMES`: how fast the path turns.
    heading: [f32; 2],
    dir: [f32; 2],
    /// Frames since the last start.
    since: i32,
}

impl FlowFollow {
    /// Off.
    pub const fn new() -> Self {
        FlowFollow {
            low: Envelope::new(),
            high: Envelope::new(),
            active: false,
            started: false,
            frames: 0,
            block: (0, 0.0, 0.0, 0),
            half: 0,
            a: 0.0,
            per_dv: 0.0,
            u: 0.0,
            e: 0.0,
            fall: 0.0,
            rise: 0.0,
            last: ([0; 2], [0.0; 2]),
            heading: [0.0; 2],
            dir: [0.0; 2],
            since: 0,
        }
    }

    /// Off, for a ring whose outputs are `half` frames behind its newest and a limit of
    /// `a` position units a frame squared (0: never on).
    pub fn reset(&mut self, half: u32, a: f32) {
        self.active = false;
        self.half = half.min(QUEUE as u32 * BLOCK as u32) as i32;
        self.a = if a.is_finite() && a > 0.0 { a } else { 0.0 };
    }

    /// Whether it bends the head now (the ring keeps its slow path).
    #[inline(always)]
    pub fn active(&self) -> bool {
        self.active
    }

    /// A valve decision in a channel of several pastes, in a bead of `per_dv` position
    /// units a frame per volume unit a frame (1 / its section): on from the frames it
    /// plans next (those already in the ring were planned before the decision's change).
    pub fn start(&mut self, per_dv: f32) {
        self.since = 0;
        if self.active || self.a == 0.0 || self.half < 2 || !(per_dv.is_finite() && per_dv > 0.0) {
            return;
        }
        self.per_dv = per_dv;
        self.active = true;
        self.started = false;
        self.frames = 0;
        self.block.3 = 0;
        self.low.clear();
        self.high.clear();
        self.e = 0.0;
    }

    /// The newest frame, `dv` volume units, entered the ring.
    pub fn push(&mut self, dv: i32) {
        self.frames += 1;
        self.since = self.since.saturating_add(1);
        let v = dv as f32 * self.per_dv;
        let (first, lo, hi, n) = self.block;
        self.block = if n == 0 {
            (self.frames, v, v, 1)
        } else {
            let d = self.a * (self.frames - first) as f32;
            (first, min(lo, v + d), max(hi, v - d), n + 1)
        };
        if self.block.3 == BLOCK {
            let (first, lo, hi, _) = self.block;
            self.low.push(first, lo, self.a, true);
            self.high.push(first, hi, self.a, false);
            self.block.3 = 0;
        }
    }

    /// What to add to the mean the outputs show (the newest frame's X/Y `base`, units, and
    /// the mean's offset `off` from it), whose frame moved `dv` volume units; `printing`
    /// while the outputs' frame lays a bead. Off once the lag is spent, the head on the
    /// flow and no change ahead.
    pub fn follow(&mut self, base: [i32; 2], off: [f32; 2], dv: i32, printing: bool) -> [f32; 2] {
        let v = dv as f32 * self.per_dv;
        let dx = base[0].wrapping_sub(self.last.0[0]) as f32 + (off[0] - self.last.1[0]);
        let dy = base[1].wrapping_sub(self.last.0[1]) as f32 + (off[1] - self.last.1[1]);
        self.last = (base, off);
        if !self.started {
            // The mean's first move is the next call's.
            self.started = true;
            self.dir = [0.0; 2];
            self.fall = v;
            self.rise = v;
            return [0.0; 2];
        }
        let d2 = dx * dx + dy * dy;
        let vm = libm::sqrtf(d2);
        if self.dir == [0.0; 2] {
            // The head's speed and direction, as the mean had them, where it starts.
            if vm <= 0.05 {
                return [0.0; 2];
            }
            self.u = vm;
            self.dir = [dx / vm, dy / vm];
            self.heading = self.dir;
        }
        let before = self.heading;
        if vm > 0.05 {
            let k = 1.0 / DIR_FRAMES;
            self.dir[0] += (dx / vm - self.dir[0]) * k;
            self.dir[1] += (dy / vm - self.dir[1]) * k;
            let k = 1.0 / TURN_FRAMES;
            self.heading[0] += (dx / vm - self.heading[0]) * k;
            self.heading[1] += (dy / vm - self.heading[1]) * k;
        }
        // The turn's share: the mean's own acceleration across the path (its speed times
        // its direction's turn a frame); the speed's change gets what is left of the
        // whole limit, by the vector sum.
        // Squared, so that the usual tick takes no root for it (a software `sqrtf` is
        // about 60 instructions on the chip).
        let (tx, ty) = (self.heading[0] - before[0], self.heading[1] - before[1]);
        let turn2 = tx * tx + ty * ty;
        let whole = self.a * WHOLE;
        let left = whole * whole - d2 * turn2;
        let slew = if left > self.a * self.a {
            self.a
        } else {
            // Nothing kept back for the speed: a floor of a quarter of the limit (tried
            // with the follower through every turn) moved the peaks at 500 mm/s^2 by at
            // most 9 mm/s^2 either way and the section away from turns not at all.
            libm::sqrtf(max(left, 0.0))
        };
        let a = self.a;
        let c = self.frames - self.half;
        let low = self.low.at(c, a, true).map_or(v, |x| min(x, v));
        let high = self.high.at(c, a, false).map_or(v, |x| max(x, v));
        self.fall = max(v, self.fall - a);
        self.rise = min(v, self.rise + a);
        let lo = min(low, self.rise);
        let hi = max(high, self.fall);
        // `min`/`max`, not `clamp`: it panics on NaN bounds, and its message would pull
        // float formatting into the tick.
        let back = max(
            min(self.e / RETURN_FRAMES, RETURN_SHARE * vm),
            -RETURN_SHARE * vm,
        );
        // Past the bead's end the flow is no guide: the head keeps to the mean while the
        // lag returns (dropping it at once would step the head by it).
        if printing {
            let want = LOW_WEIGHT * lo + (1.0 - LOW_WEIGHT) * hi + back;
            self.u = max(min(want, self.u + slew), max(self.u - slew, 0.0));
            // The lag lies along the path's tangent, which turns: a lag changing at `de`
            // moves the head across the path at `2 de turn` on top of the turn's own.
            // Within what the turn leaves, the head keeps nearer the mean's speed.
            if turn2 > 0.0 {
                let most = libm::sqrtf(max(left, 0.0) / (4.0 * turn2));
                self.u = max(max(min(self.u, vm + most), vm - most), 0.0);
            }
        } else {
            // Past the bead's end the flow is no guide: the head keeps to the mean, which
            // moves within the limit, while the lag returns (dropping it at once would
            // step the head by it).
            self.u = vm + self.e / RETURN_FRAMES;
        }
        self.e += vm - self.u;
        let settled = libm::fabsf(self.e) < 0.5
            && libm::fabsf(self.u - vm) < 4.0 * a
            && hi - lo < 4.0 * a
            && self.since > 2 * self.half;
        if settled || (!printing && libm::fabsf(self.e) < 0.5) {
            self.active = false;
            return [0.0; 2];
        }
        let n = libm::sqrtf(self.dir[0] * self.dir[0] + self.dir[1] * self.dir[1]);
        if n < 0.5 {
            return [0.0; 2];
        }
        [-self.e * self.dir[0] / n, -self.e * self.dir[1] / n]
    }
}

impl Default for FlowFollow {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paste B's line closing into paste A's rise (14.8 units a frame decaying over 200
    /// frames, A rising to 10 over 300: 1.5 times the limit at the kink): the head's
    /// speed never changes faster than the limit, its lag returns and the follower stands
    /// down, and the section (flow over head over 2 000 units) stays within half the
    /// narrowest box mean's within the limit.
    #[test]
    fn follows_a_fast_fall_within_the_limit() {
        let a = 0.05f32;
        let mut f = FlowFollow::new();
        f.reset(200, a);
        let n = 3000usize;
        let flow: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f32 - 300.0;
                if t < 0.0 {
                    14.8
                } else {
                    (14.8 * libm::expf(-t / 200.0)).max(10.0 * (1.0 - libm::expf(-t / 300.0)))
                }
            })
            .collect();
        f.start(1.0e-3);
        // The ring: frames pushed `half` ahead of the outputs.
        for v in flow.iter().take(200) {
            f.push((*v * 1000.0) as i32);
        }
        let mut mean = 0.0f32;
        let mut head = vec![];
        let mut prev_u = None;
        let mut most_lag = 0.0f32;
        for i in 0..(n - 200) {
            f.push((flow[i + 200] * 1000.0) as i32);
            mean += flow[i];
            let c = f.follow([0, 0], [mean, 0.0], (flow[i] * 1000.0) as i32, true);
            head.push(mean + c[0]);
            most_lag = most_lag.max(f.e.abs());
            // The first call only notes the mean; the second takes its speed.
            if let Some(p) = prev_u.filter(|_| i > 1) {
                let du: f32 = f.u - p;
                assert!(du.abs() <= a * 1.001, "frame {i}: {du}");
            }
            prev_u = Some(f.u);
        }
        assert!(!f.active() && f.e.abs() < 1.0, "lag returned: {}", f.e);
        assert!(most_lag > 10.0, "it bent the head: {most_lag}");
        let cum: Vec<f32> = flow
            .iter()
            .scan(0.0, |s, v| {
                *s += v;
                Some(*s)
            })
            .collect();
        let off = |head: &[f32]| {
            let mut worst = 0.0f32;
            for i in 100..(n - 700) {
                let j = (i..n - 200).find(|&j| head[j] - head[i] >= 2000.0).unwrap();
                let s = (cum[j] - cum[i]) / (head[j] - head[i]);
                worst = worst.max((s - 1.0).abs());
            }
            worst
        };
        // The narrowest centred box mean within the limit, on the same flow.
        let boxed = (1..400usize)
            .map(|h| {
                let mean = |i: usize| {
                    let (lo, hi) = (i.saturating_sub(h), (i + h).min(n - 1));
                    (cum[hi] - if lo > 0 { cum[lo - 1] } else { 0.0 }) / (hi + 1 - lo) as f32
                };
                let v: Vec<f32> = (0..n).map(mean).collect();
                let peak = (h + 1..n - h - 1)
                    .map(|i| (v[i + 1] - v[i]).abs())
                    .fold(0.0f32, f32::max);
                (peak, v)
            })
            .find(|(peak, _)| *peak <= a)
            .map(|(_, v)| {
                v.iter()
                    .scan(0.0, |s, x| {
                        *s += x;
                        Some(*s)
                    })
                    .collect::<Vec<f32>>()
            })
            .unwrap();
        let (follower, boxed) = (off(&head), off(&boxed));
        // Measured: 0.0081 against the box's 0.0402.
        assert!(
            follower < 0.5 * boxed,
            "{follower} against the box's {boxed}"
        );
    }
}
