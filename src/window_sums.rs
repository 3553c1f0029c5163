//! The plan's moves summed over two windows of the ramp ring while the flow's follower
//! runs (`crate::flow_follow`): the mean's window about the outputs' frame, and the same
//! width at the newest frames, where the ring last knows the mean's path (`Look`). Kept
//! beside the ring, and only on its narrowed path while the follower runs: the four
//! gated machines' ticks pay nothing for them (summed in every push they cost the
//! instantaneous-valve machine 29 instructions a tick, its worst 2 020). Frames pushed
//! before the follower started are not counted; each sum says how many frames it holds.
//! Stops at the sums: the follower decides what they mean.

use crate::ramp::Ramp;

/// The mean's path where the ring last knows it, the mean's window's half plus one frames
/// before the newest, for the follower to plan by. Positions in units (0.1 um), moves as
/// volume (`Vol` units).
#[derive(Clone, Copy, Debug, Default)]
pub struct Look {
    /// The mean's move into that frame times the window, X/Y: the newest frame less the
    /// one a window before it.
    pub chord: [i32; 2],
    /// The same 8 frames earlier.
    pub chord8: [i32; 2],
    /// The plan's moves over the window ending at the newest frame, summed, and its
    /// frames (0 until every one is counted: `WindowSums`).
    pub moved: (u32, u32),
    /// The window, frames.
    pub span: u32,
}

/// Frames before the start counted a push, on top of the new one: the mean's window of
/// the soft machine (415 cycles) is whole 8 pushes after the start, at about 8
/// instructions a frame.
const FILL: usize = 32;

/// A sum of frames' `dv` (wrapping: only its value over a window is read, at most the
/// ring's 512 frames of 0.2 mm^3) and the frames in it.
#[derive(Clone, Copy, Debug, Default)]
struct Sum {
    dv: u32,
    n: u32,
}

/// `s` and its frames if it holds all `span` of its window; else (0, 0).
fn whole(s: Sum, span: u32) -> (u32, u32) {
    if s.n == span {
        (s.dv, s.n)
    } else {
        (0, 0)
    }
}

/// The two windows' sums, counting the frames pushed since `start`.
#[derive(Clone, Copy, Debug, Default)]
pub struct WindowSums {
    on: bool,
    /// Frames pushed since the start: the frame `back` frames before the newest is
    /// counted if `back < since`.
    since: u32,
    mean: Sum,
    ahead: Sum,
}

impl WindowSums {
    /// Off.
    pub const fn new() -> Self {
        WindowSums {
            on: false,
            since: 0,
            mean: Sum { dv: 0, n: 0 },
            ahead: Sum { dv: 0, n: 0 },
        }
    }

    /// Counting from the next frame pushed.
    pub fn start(&mut self) {
        *self = WindowSums {
            on: true,
            ..WindowSums::new()
        };
    }

    /// Off until the next start.
    pub fn stop(&mut self) {
        self.on = false;
    }

    /// Whether counting.
    pub fn on(&self) -> bool {
        self.on
    }

    /// A frame was pushed on the ring's narrowed path (`Ramp::push_narrow`), whose mean's
    /// half window was `h0` before it: the windows slide a frame, and grow or shrink by
    /// one at each end as the mean's did.
    pub fn pushed<const N: usize>(&mut self, ring: &Ramp<N>, h0: u32) {
        self.since = self.since.saturating_add(1);
        let big = ring.window() / 2;
        let (h0, h1) = (h0 as usize, ring.half() as usize);
        let l0 = 2 * h0 + 1;
        let since = self.since as usize;
        let add = |s: &mut Sum, back: usize, sign: bool| {
            if back < since {
                let dv = ring.back(back).dv as u32;
                if sign {
                    s.dv = s.dv.wrapping_add(dv);
                    s.n += 1;
                } else {
                    s.dv = s.dv.wrapping_sub(dv);
                    s.n = s.n.saturating_sub(1);
                }
            }
        };
        // The slide: what `push_narrow` enters and leaves.
        add(&mut self.mean, big - h0, true);
        add(&mut self.mean, big + h0 + 1, false);
        add(&mut self.ahead, 0, true);
        add(&mut self.ahead, l0, false);
        if h1 > h0 {
            add(&mut self.mean, big - h0 - 1, true);
            add(&mut self.mean, big + h0 + 1, true);
            add(&mut self.ahead, l0, true);
            add(&mut self.ahead, l0 + 1, true);
        } else if h1 < h0 {
            add(&mut self.mean, big - h0, false);
            add(&mut self.mean, big + h0, false);
            add(&mut self.ahead, l0 - 1, false);
            add(&mut self.ahead, l0 - 2, false);
        }
        // The frames before the start are counted `FILL` a push, oldest last, so that
        // both windows are whole within a few pushes (the windows reach `big + h1` back).
        let reach = big + h1 + 1;
        if since < reach {
            let to = (since + FILL).min(reach);
            let l1 = 2 * h1 + 1;
            for b in since..to {
                let dv = ring.back(b).dv as u32;
                if b + h1 >= big && b <= big + h1 {
                    self.mean.dv = self.mean.dv.wrapping_add(dv);
                    self.mean.n += 1;
                }
                if b < l1 {
                    self.ahead.dv = self.ahead.dv.wrapping_add(dv);
                    self.ahead.n += 1;
                }
            }
            self.since = to as u32;
        }
    }

    /// Whether both windows hold every frame of theirs.
    pub fn ready<const N: usize>(&self, ring: &Ramp<N>) -> bool {
        let l = 2 * ring.half() + 1;
        self.on && self.mean.n == l && self.ahead.n == l
    }

    /// The plan's moves over the mean's window, and its frames (0 until every one of
    /// them is counted).
    pub fn mean<const N: usize>(&self, ring: &Ramp<N>) -> (u32, u32) {
        whole(self.mean, 2 * ring.half() + 1)
    }

    /// The mean's path where `ring` last knows it.
    pub fn look<const N: usize>(&self, ring: &Ramp<N>) -> Look {
        let cap = crate::capacity::RAMP_CAPACITY;
        let l = (2 * ring.half() as usize + 1).min(cap - 9);
        let pos = |b: usize| -> [i32; 3] { ring.back(b).pos };
        let d = |a: usize, b: usize| {
            let (p, q) = (pos(a), pos(b));
            [p[0].wrapping_sub(q[0]), p[1].wrapping_sub(q[1])]
        };
        Look {
            chord: d(0, l),
            chord8: d(8, l + 8),
            moved: whole(self.ahead, l as u32),
            span: l as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ramp::Frame;
    use crate::step_ramps::StepRamps;

    /// A frame of flow `dv` at `x` units.
    fn frame(x: i32, dv: i32) -> Frame<1> {
        Frame {
            pos: [x, -x / 3, 0],
            dv,
            ..Frame::IDLE
        }
    }

    /// Through the window narrowing, widening and narrowing again, started while it
    /// narrows: once each sum says it holds its whole window, it is the window's sum of
    /// `dv`, counted from the ring's own frames; and the look's chords and step are the
    /// ring's.
    #[test]
    fn sums_follow_the_windows() {
        let mut r: Ramp<1> = Ramp::new();
        let mut st = StepRamps::new();
        r.reset(201, frame(0, 0), &mut st, 0.0);
        let mut sums = WindowSums::new();
        let (mut x, mut ready_at) = (0i32, None);
        for i in 0..900i32 {
            match i {
                40 => r.set_goal(30),
                300 => r.set_goal(70),
                600 => r.set_goal(12),
                _ => {}
            }
            if i == 60 {
                sums.start();
            }
            let dv = 1000 + (i * 37) % 501;
            x += dv / 100;
            let h0 = if r.narrowing() {
                r.push_narrow(frame(x, dv), &mut st)
            } else {
                r.push(frame(x, dv), &mut st);
                r.half()
            };
            if !sums.on() {
                continue;
            }
            sums.pushed(&r, h0);
            if !sums.ready(&r) {
                assert!(ready_at.is_none(), "push {i}: it stayed whole once whole");
                continue;
            }
            ready_at.get_or_insert(i);
            let (big, h) = (r.window() / 2, r.half() as usize);
            let sum =
                |from: usize, to: usize| -> u32 { (from..=to).map(|b| r.back(b).dv as u32).sum() };
            let l = 2 * h + 1;
            assert_eq!(sums.mean(&r), (sum(big - h, big + h), l as u32), "push {i}");
            let look = sums.look(&r);
            assert_eq!(look.moved, (sum(0, l - 1), l as u32), "push {i}");
            let (p, q) = (r.back(0).pos, r.back(l).pos);
            assert_eq!(look.chord, [p[0] - q[0], p[1] - q[1]], "push {i}");
        }
        // Counted `FILL` frames a push besides the new one: whole within the mean's reach
        // over that many.
        let ready_at = ready_at.expect("the sums became whole");
        assert!(
            ready_at - 60 <= (100 + 30 + 1) / FILL as i32 + 1,
            "{ready_at}"
        );
    }
}
