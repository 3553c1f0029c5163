//! The ramp window sized at each valve decision (`crate::switch_window`), over the cycles
//! after the decision's: the contents in the next, the follower's start in the ones after
//! (several pastes in the channel; once its window sums are whole), the change in three
//! more (an `expf` or a few each), then the bead's turns ahead, `WALK_ITEMS` plan items a
//! cycle. Done in the decision's cycle, the whole was up to 5 000 instructions on the soft
//! machine's dearest tick (bench-m4's `soft`); a step now is at most about 650. Stops at
//! the window's size: the ramp ring moves to it (`Ramp::set_goal`).

use super::plan::{Item, Seg};
use super::Executor;
use crate::real::Real;
use crate::switch_window::{Sizing, Turn};
use crate::vol::Vol;

/// Plan items walked a cycle from a decision on, turns or not: the walk's cost is the
/// items', about 30 instructions for a straight segment and 100 for a turn (the plan's
/// whole 256 items took up to 3 000 instructions at the decision). The whole plan in 64
/// cycles (6.4 ms at 10 kHz, 64 um of bead at 10 mm/s).
const WALK_ITEMS: usize = 4;

/// A decision's sizing, under way.
#[derive(Clone, Copy, Debug)]
pub(super) enum Pending<R> {
    /// Made in cycle `cycle`, sized in the next: the valves going from the inlets of
    /// `closing` (bit mask) to `opening`, at plan volume `head` in a bead of `inv_s`.
    Start {
        opening: Option<u8>,
        closing: u32,
        head: Vol,
        inv_s: R,
        cycle: u64,
    },
    /// The flow's change being sized, then the turns ahead being walked.
    Walk(Walk<R>),
}

/// A decision's walk of the turns ahead, under way.
#[derive(Clone, Copy, Debug)]
pub(super) struct Walk<R> {
    sizing: Sizing,
    /// The plan volume and bead section the turns' distances are taken from (the
    /// decision's).
    head: Vol,
    inv_s: R,
    /// The plan item to look at next, and its fillet's start, by which it is found again
    /// after the items before it left the plan.
    next: usize,
    next_u: Vol,
}

impl<R: Real, const N: usize> Executor<R, N> {
    /// Sizes the ramp window for the valve command about to be made (`opening` the inlet
    /// it opens, none to stop), from the channel's contents then
    /// (`crate::switch_window`); the machine's window where those do not say. Over the
    /// cycles after the decision's (`sizing_step`): the flow's change in the next, the
    /// turns ahead a few at a time after it, so that the decision's cycle, which the
    /// valve command already makes the dearest, carries none of it.
    pub(super) fn size_ramp(&mut self, opening: Option<u8>) {
        // A new decision sizes the window afresh.
        self.deferred = None;
        self.sizer = Some(Pending::Start {
            opening,
            closing: self.model.commanded(),
            head: self.head,
            inv_s: self.inv_s,
            cycle: self.cycle,
        });
        // Its steps go with the ring's slow path (`push_frame_narrow`).
        self.ramp.keep_slow();
    }

    /// The next step of a decision's sizing (`size_ramp`): the contents, the follower's
    /// start, the walk's set-up, or the next `WALK_ITEMS` plan items of the walk over the
    /// turns ahead. The window keeps the ring's width until the follower has started, a
    /// few cycles after the decision (a real valve's dead time is a hundred); it then
    /// narrows to the plan's rounding and widens as the walk finds turns that need it. In
    /// place: a sizing is some 150 bytes, and copying it out and back took a step from 430
    /// to 670 instructions. Out of line: only in the cycles after a decision.
    #[inline(never)]
    pub(super) fn sizing_step(&mut self) {
        let cycle = self.cycle;
        let w = match self.sizer.as_mut() {
            None => return,
            Some(Pending::Start { cycle: c, .. }) if *c == cycle => return,
            Some(&mut Pending::Start {
                opening,
                closing,
                head,
                inv_s,
                ..
            }) => return self.size_flow(opening, closing, head, inv_s),
            Some(Pending::Walk(w)) => w,
        };
        let machine_half = self.machine.ramp_cycles / 2;
        let (goal, done) = if w.sizing.checking() {
            // The follower takes the flow's change from the frames planned next; the
            // window is sized for the turns and rounding only. It plans by the plan's
            // moves over the ring's windows (`window_sums`): they are counted from here,
            // a few pushes to fill, and it starts once they are.
            if !self.follow.active() {
                if !self.sums.on() {
                    self.sums.start();
                }
                if !self.sums.ready(&self.ramp) {
                    return;
                }
            }
            w.sizing.begin_follow();
            // The bead's speed per volume: position units (1e-4 mm) per volume unit
            // (1e-10 mm^3, `Vol`), through the bead's own section.
            // Saturating: a NaN or a negative time is no hold past the window's.
            let change = (w.sizing.change_s() / self.machine.dt().to_f32()) as u32;
            self.follow.start(w.inv_s.to_f32() * 1.0e-6, change);
            self.ramp.keep_slow();
            (None, false)
        } else if !w.sizing.sized() {
            // The cycle that sets the walk up walks no turns yet (the flow's window and a
            // walk's items together were the soft machine's dearest tick).
            let goal = w
                .sizing
                .step()
                .then(|| w.sizing.half(&self.machine).unwrap_or(machine_half));
            (goal, false)
        } else {
            let ended = walk_items(self.plan.as_slices(), w);
            let h = w.sizing.half(&self.machine);
            (
                Some(h.unwrap_or(machine_half)),
                ended || h.is_none() || w.sizing.walk.full(),
            )
        };
        // A bead's start keeps to the window its rise and near turns need for a while
        // (`Sizing::defer`); the whole window comes after. Worked out for a bead's start
        // only: it is a software root more on the step.
        let defer = w.sizing.defer;
        let now = goal
            .filter(|_| defer > 0.0)
            .map(|_| w.sizing.half_now(&self.machine).unwrap_or(machine_half));
        if let Some(g) = goal {
            let g_now = now.map_or(g, |n| n.min(g));
            self.ramp.set_goal(g_now);
            // The slowing at tight fillets (`turns`) sizes its cap by the decision's
            // whole window, as the walk ends: set at each step of the walk, it took the
            // 0.6 mm stripes' row ends from 21.8 to 27.3 % off over 0.2 mm.
            if done {
                self.mean_half = g;
                self.deferred = (g > g_now).then(|| {
                    let cycles = (defer / self.machine.dt().to_f32()) as u64;
                    (cycle + cycles, g)
                });
            }
        }
        if done {
            self.sizer = None;
        }
    }

    /// A bead start's deferred widening (`Sizing::defer`), once due; the ring's slow path
    /// until then. Out of line: only after a bead's start.
    #[inline(never)]
    pub(super) fn widen_when_due(&mut self) {
        if let Some((due, g)) = self.deferred {
            if self.cycle >= due {
                self.ramp.set_goal(g);
                self.deferred = None;
            } else {
                self.ramp.keep_slow();
            }
        }
    }

    /// The contents' part of the window (`switch_window::switch_start`).
    fn size_flow(&mut self, opening: Option<u8>, closing: u32, head: Vol, inv_s: R) {
        self.sizer =
            crate::switch_window::switch_start(&self.machine, &self.model, closing, opening).map(
                |sizing| {
                    Pending::Walk(Walk {
                        sizing,
                        head,
                        inv_s,
                        next: 0,
                        next_u: Vol::ZERO,
                    })
                },
            );
        if self.sizer.is_none() {
            self.mean_half = self.machine.ramp_cycles / 2;
            self.ramp.set_goal(self.mean_half);
        }
    }
}

/// The next `WALK_ITEMS` plan items of walk `w`, its turns fed; whether the bead (or the
/// plan) ended.
fn walk_items<R: Real>(slices: (&[Item<R>], &[Item<R>]), w: &mut Walk<R>) -> bool {
    // The item looked at next moved towards the front as items before it left.
    let mut k = w.next.min(slices.0.len() + slices.1.len());
    if w.next > 0 {
        while k > 0 && at(slices, k).is_none_or(|s| s.u_arc != w.next_u) {
            k -= 1;
        }
    }
    let mut ended = false;
    for _ in 0..WALK_ITEMS {
        let (Some(a), Some(b)) = (at(slices, k).filter(|a| !a.last), at(slices, k + 1)) else {
            ended = true;
            break;
        };
        k += 1;
        if let Some(t) = turn(a, b, w.head, w.inv_s) {
            w.sizing.walk.feed(t);
        }
    }
    w.next = k;
    w.next_u = at(slices, k).map_or(Vol::ZERO, |s| s.u_arc);
    ended
}

/// The plan's print segment at index `k` of its two slices, if it is one.
fn at<'a, R>(slices: (&'a [Item<R>], &'a [Item<R>]), k: usize) -> Option<&'a Seg<R>> {
    let item = if k < slices.0.len() {
        slices.0.get(k)
    } else {
        slices.1.get(k - slices.0.len())
    };
    match item {
        Some(Item::Seg(s)) => Some(s),
        _ => None,
    }
}

/// The bead's turns from the plan's front whose fillets start before plan volume `until`:
/// each segment's fillet into the next, to the bead's end. By reference, in one pass: a
/// segment is 23 words, and copying each twice a turn (as two zipped iterators did) was a
/// good part of a decision's cost. The tests' whole walk, against the one in steps.
#[cfg(test)]
fn turns_from<'a, R: Real>(
    slices: (&'a [Item<R>], &'a [Item<R>]),
    head: Vol,
    inv_s: R,
    until: Vol,
) -> impl Iterator<Item = Turn> + Clone + 'a {
    let mut k = 0;
    core::iter::from_fn(move || loop {
        let a = at(slices, k).filter(|a| !a.last && a.u_arc <= until)?;
        let b = at(slices, k + 1)?;
        k += 1;
        if let Some(t) = turn(a, b, head, inv_s) {
            return Some(t);
        }
    })
}

/// Segment `a`'s fillet into `b`, if it has one, `at` mm of path past plan volume `head`
/// in a bead of `inv_s` (1 / section).
#[inline(always)]
fn turn<R: Real>(a: &Seg<R>, b: &Seg<R>, head: Vol, inv_s: R) -> Option<Turn> {
    let f2 = |v: crate::motion::V2<R>| [v[0].to_f32(), v[1].to_f32()];
    a.fillet.map(|f| Turn {
        at: ((a.u_arc - head).mm3::<R>() * inv_s).to_f32(),
        radius: f.radius.to_f32(),
        from: f2(a.dir),
        to: f2(b.dir),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capacity::PLAN_CAPACITY;
    use crate::motion::Fillet;
    use crate::switch_window::TurnWalk;
    use heapless::Deque;

    /// A bead of `n` segments of 1 mm, every third one straight into the next (no fillet),
    /// the others turning by 10 degrees but for the 62nd fillet (or the last), which
    /// turns by 150: the window is that turn's only if the walk feeds every fillet once,
    /// and stops after 64.
    fn bead(n: usize) -> Deque<Item<f32>, PLAN_CAPACITY> {
        let mut plan = Deque::new();
        let fillets = (0..n - 1).filter(|k| k % 3 != 2).count();
        let sharp = fillets.min(62);
        let (mut angle, mut seen) = (0.0f32, 0);
        for k in 0..n {
            let has = k + 1 < n && k % 3 != 2;
            seen += has as usize;
            let dir = [libm::cosf(angle), libm::sinf(angle)];
            if has {
                angle += if seen == sharp { 2.618 } else { 0.1745 };
            }
            let u = Vol(k as i64 * 4_800_000_000);
            let seg = Seg {
                material: 0,
                start: [k as f32, 0.0],
                dir,
                len: 1.0,
                fillet: has.then_some(Fillet {
                    tangent: 0.05,
                    centre: [0.0; 2],
                    radius: 0.05,
                    start_angle: 0.0,
                    sweep: 1.0,
                }),
                u_start: u,
                u_arc: Vol(u.0 + 4_500_000_000),
                u_end: Vol(u.0 + 4_800_000_000),
                last: k == n - 1,
                index: k as u32,
                inv_s: 1.0 / 0.48,
            };
            assert!(plan.push_back(Item::Seg(seg)).is_ok());
        }
        plan
    }

    fn walker() -> Walk<f32> {
        Walk {
            sizing: Sizing::walking(TurnWalk::new(12.0, 0.0, 350.0)),
            head: Vol::ZERO,
            inv_s: 1.0 / 0.48,
            next: 0,
            next_u: Vol::ZERO,
        }
    }

    /// The walk a few items a cycle, with the head passing items behind it in between,
    /// sizes the same window as the whole walk at once, and ends at the bead's end or at
    /// the most turns it looks at.
    #[test]
    fn a_walk_in_steps_sizes_what_the_whole_walk_does() {
        for n in [5, 40, 200] {
            let mut plan = bead(n);
            let mut whole = TurnWalk::new(12.0, 0.0, 350.0);
            for t in turns_from(plan.as_slices(), Vol::ZERO, 1.0 / 0.48, Vol(i64::MAX)) {
                whole.feed(t);
            }
            let mut w = walker();
            let mut steps = 0;
            let mut popped = 0;
            while !walk_items(plan.as_slices(), &mut w) && !w.sizing.walk.full() {
                steps += 1;
                // The head passes an item now and then, always one the walk is past.
                if steps % 3 == 0 && w.next > 1 {
                    plan.pop_front();
                    popped += 1;
                }
                assert!(steps <= PLAN_CAPACITY, "the walk must end");
            }
            assert!(n < 40 || popped > 0, "{n}: items left while it walked");
            assert_eq!(
                w.sizing.walk.window().to_bits(),
                whole.window().to_bits(),
                "{n} segments"
            );
            // The sharp turn's: v / limit * |to - from| for 150 degrees.
            let sharp = 12.0 / 350.0 * 2.0 * libm::sinf(1.309);
            assert!(
                (whole.window() - sharp).abs() < 1e-6,
                "{n}: {} against {sharp}",
                whole.window()
            );
        }
    }

    /// An item the walk was to look at next that left the plan (the head overtook the
    /// walk) restarts it at the plan's front: it still ends.
    #[test]
    fn a_walk_overtaken_by_the_head_goes_on_from_the_front() {
        let mut plan = bead(60);
        let mut w = walker();
        assert!(!walk_items(plan.as_slices(), &mut w));
        for _ in 0..10 {
            plan.pop_front();
        }
        let mut steps = 0;
        while !walk_items(plan.as_slices(), &mut w) && !w.sizing.walk.full() {
            steps += 1;
            assert!(steps <= PLAN_CAPACITY, "the walk must end");
        }
        assert!(w.sizing.walk.window() > 0.0);
    }
}
