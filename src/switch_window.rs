//! Ramp windows per valve decision (issue 22): at the decision to open, switch or close
//! the valves, the window the head's speed ramp needs there, sized from the channel's
//! contents then. The machine's one window is sized for the fastest change the valves
//! can make anywhere (paste B's line closing into a channel still full of paste A); its
//! mean only smears most changes over the bead. The flow's change itself goes to the
//! follower (`crate::flow_follow`), which meets it within the limit; this sizes the
//! window for what the follower bends: the turns ahead and the plan's rounding. The ramp
//! ring narrows or widens its mean to it (`Ramp::set_goal`); what is not sized here
//! (syringes, two lines closing at once, unequal dead times) keeps the machine's window.

use crate::config::{Machine, RAMP_SHARE};
use crate::flow_model::FlowModel;
use crate::real::Real;

/// A decision's window in the making: half the window (frames) the head's mean needs for
/// the valves going from the inlets of `closing` (bit mask) to `opening` (none: closing
/// only), or `None` for the machine's. One closing, one opening pneumatic line with equal
/// dead times only.
///
/// The flow's change is the follower's (`begin_follow`). Sized here for that change
/// instead, a box mean as wide as a valve's first-order decay needs within the limit
/// (Newtonian contents of one paste; the follower took the rest) spread the head's ramp
/// over the change and its own width: on real valves at 500 mm/s^2 the chessboard's band
/// over 0.2 mm was 0.0089 and the random pattern 3.41 % off over 0.2 mm of straight
/// bead; with the follower, 0.0031 and 2.64 %. At 1 000 the bands moved by 0.0001 at
/// most, at 2 000 not at all.
///
/// The window is never shorter than the bead's tight turns ahead need (`TurnWalk`), nor
/// than keeps the plan's unramped kinks within the limit (`min_half`: 2.9 ms at
/// 1 000 mm/s^2): a window narrowed for the flow shows the head every fillet, and every
/// rounding of the plan, that the machine's long window smoothed. Of the two, the kinks'
/// floor took the logo at 500 mm/s^2 from 610 to 519 / 534 mm/s^2 on X / Y; sized at
/// the flushed speed, no turn of the four designs measured (chessboard, random pattern,
/// logo, fine features) widened a window.
///
/// A step at a time, so that the executor spreads it over the cycles after the decision
/// (`crate::executor`'s sizing; the whole of it, with the walk over the turns ahead, was
/// up to 5 000 instructions in the decision's cycle on the soft machine): `switch_start`
/// checks the contents, `begin_follow` hands the flow's change to the follower, `step`
/// sets the walk up, and the caller feeds `walk` the turns ahead and reads `half`.
#[derive(Clone, Copy, Debug)]
pub struct Sizing {
    /// The ramps' share of the X/Y limit it holds, mm/s^2.
    pub limit: f32,
    /// The turns ahead, fed by the caller once `step` is done.
    pub walk: TurnWalk,
    flow: FlowChange,
    /// A bead's start from closed valves: how long (s) the window may keep to what the
    /// flow's rise and the turns within `soon` mm need before it widens to the rest
    /// (`half_now`); 0 otherwise.
    pub defer: f32,
    soon: f32,
}

/// The flow's change a decision makes: the channel's speed `v_c` going to the opening
/// line's `v_o` after `delay`, settled some `settle` s later; the speed the turns are
/// sized at.
#[derive(Clone, Copy, Debug)]
struct FlowChange {
    v_o: f32,
    v_c: f32,
    delay: f32,
    settle: f32,
    v_turn: f32,
    /// 0: the follower to start; 1: the walk to set up (`Sizing::step`); 2: sized.
    stage: u8,
}

impl Sizing {
    /// Whether the walk is set up (`step`).
    pub fn sized(&self) -> bool {
        self.flow.stage > 1
    }

    /// Whether the follower is still to start.
    pub fn checking(&self) -> bool {
        self.flow.stage == 0
    }

    /// The follower (`crate::flow_follow`) takes the flow's change, a head speed slewed
    /// within the limit, and the window is sized for the turns and the plan's rounding
    /// only. Near a fillet tighter than the limit allows at the flow's speed too, since
    /// the follower plans its speed by the mean's own path ahead and keeps a lagging head
    /// on that path (`crate::follow_trail`): barred there, a box sized from the contents
    /// left the random pattern 8.9 % off over 0.2 mm of straight bead at 500 (3.8 % then).
    pub fn begin_follow(&mut self) {
        self.flow.stage = 1;
    }

    /// How long (s) after the decision the bulk of its flow change lasts: the dead time
    /// and the slower line's time constant (a quarter of `settle`). The follower holds on
    /// that long (`FlowFollow::start`); to the whole settling (four time constants) it
    /// measured the same on the machine and ran on 86 % of the soft bench
    /// machine's ticks; to the dead time alone, the random pattern's band over 0.02 mm
    /// at 1 000 mm/s^2 was 0.0063 (0.0035).
    pub fn change_s(&self) -> f32 {
        self.flow.delay + 0.25 * self.flow.settle
    }

    /// Sets the walk over the turns ahead up; `true` once it is.
    pub fn step(&mut self) -> bool {
        let f = &mut self.flow;
        if f.stage > 1 {
            return true;
        }
        // The flow's change lies within the dead time and a few time constants of the
        // decision; a turn there meets it.
        let near = crate::fast::max(f.v_o, f.v_c) * (f.delay + f.settle);
        self.walk = TurnWalk::new(f.v_turn, near, self.limit).soon(self.soon);
        f.stage = 2;
        true
    }

    /// Half the window (frames) with the turns fed so far, or `None` for the machine's.
    pub fn half<R: Real, const N: usize>(&self, m: &Machine<R, N>) -> Option<u32> {
        self.half_of(m, self.walk.window())
    }

    /// `half` over the turns within `soon` only: a bead's start keeps to it for `defer`
    /// seconds (the whole `half` without a deferral).
    pub fn half_now<R: Real, const N: usize>(&self, m: &Machine<R, N>) -> Option<u32> {
        self.half_of(m, self.walk.window_soon())
    }

    fn half_of<R: Real, const N: usize>(&self, m: &Machine<R, N>, turns: f32) -> Option<u32> {
        let cycles = turns / m.dt().to_f32();
        let half = m.ramp_cycles / 2;
        if cycles.is_nan() || cycles < 0.0 || cycles >= (2 * half + 1) as f32 {
            return None;
        }
        let h = (libm::ceilf(cycles) as u32) / 2;
        Some(h.max(min_half(m, self.limit)))
    }
}

#[cfg(test)]
impl Sizing {
    /// A sizing with its flow's change sized (no window for it), walking `walk`'s turns.
    pub(crate) fn walking(walk: TurnWalk) -> Self {
        Sizing {
            limit: 1.0,
            walk,
            flow: FlowChange {
                v_o: 0.0,
                v_c: 0.0,
                delay: 0.0,
                settle: 0.0,
                v_turn: 0.0,
                stage: 2,
            },
            defer: 0.0,
            soon: f32::INFINITY,
        }
    }
}

/// A decision's `Sizing` begun: whether the contents are sized here at all (`None`: the
/// machine's window), and the flow's change they make.
pub fn switch_start<R: Real, const N: usize>(
    m: &Machine<R, N>,
    model: &FlowModel<R, N>,
    closing: u32,
    opening: Option<u8>,
) -> Option<Sizing> {
    if model.syringes() {
        return None;
    }
    // A shear-thinning paste's flow is no first-order curve of the pressure (its decay
    // falls at first `1 / n` times faster, `config::flow`'s `Decay`), and its supply
    // through the contents is no closed form: the follower takes every change there, and
    // the window is sized for the turns at the opening paste's flushed speed
    // (`Inlet::flushed_mm_s`), as a Newtonian one's is below.
    let linear = model.all_linear();
    let open = match opening {
        Some(o) => Some(m.inlets.get(o as usize)?),
        None => None,
    };
    let mut close = None;
    for (i, inlet) in m.inlets.iter().enumerate() {
        if closing & (1 << i) != 0 && opening != Some(i as u8) {
            if close.is_some() {
                return None;
            }
            close = Some(inlet);
        }
    }
    let r = if linear {
        model.resistance_linear().to_f32()
    } else {
        1.0
    };
    let s = m.bead_area.to_f32();
    let (tau_r, tau_d) = (
        open.map_or(1.0, |o| o.rise_s.to_f32()),
        close.map_or(1.0, |c| c.decay_s.to_f32()),
    );
    if !(r > 0.0 && s > 0.0 && tau_r > 0.0 && tau_d > 0.0) {
        return None;
    }
    if let (Some(c), Some(o)) = (close, open) {
        if c.close_delay_s.to_f32() != o.open_delay_s.to_f32() {
            return None;
        }
    }
    let v_o = match open {
        None => 0.0,
        Some(o) if linear => o.supply_pa.to_f32() / r / s,
        // The fastest any supply drives the head through any contents.
        Some(_) => m.v_flow_max.to_f32(),
    };
    let v_c = if close.is_some() {
        model.q().to_f32() / s
    } else {
        0.0
    };
    let whole = m.motion.max_accel[0].min(m.motion.max_accel[1]).to_f32();
    let limit = whole * RAMP_SHARE as f32;
    let delay = m.inlets.iter().fold(0.0f32, |d, i| {
        d.max(i.open_delay_s.max(i.close_delay_s).to_f32())
    });
    let v = v_o.max(v_c);
    // The opening paste's supply through a channel full of it (`Inlet::flushed_mm_s`),
    // a shear-thinning one's too: at the fastest flow instead (10.63 mm/s for the food
    // pastes), a U-turn of 0.22 mm fillets took a 45 ms window on the food pastes' logo at
    // 500 mm/s^2, and its box mean cut the turn with the flow steady: 4.03 % off over
    // 0.2 mm of a crop, none now.
    let flush = open.map(|o| o.flushed_mm_s.to_f32()).filter(|&v| v > 0.0);
    // Past the channel's flush the head moves at the opening paste's own speed through a
    // channel full of it (a bead's end: the closing speed, at most). Before the flush it
    // may be faster (paste B opening into paste A), but sizing the turns for that took
    // the chessboard's every window back to the machine's (section 14.5 % off at
    // 500 mm/s^2): they are sized for the flushed speed.
    let settle = 4.0
        * open
            .map_or(0.0, |_| tau_r)
            .max(close.map_or(0.0, |_| tau_d));
    let v_turn = flush.map_or(v, |f| f.min(v));
    // A bead's start: the head stands while the paste comes, then follows the flow's
    // rise. The machine's window, widened there for turns far ahead, led the paste by
    // half of it (the 0.6 mm stripes at 500 mm/s^2: 4.7 % off over 0.2 mm of the first
    // bead's start, 1.1 % deferred). It widens once the rise has settled, well before
    // any turn it was widened for reaches the window: the turns within `soon`, which the
    // head may reach by then at the fastest flow, count at once.
    let (defer, soon) = if close.is_none() && open.is_some() {
        let d = delay + settle;
        let ahead = m.ramp_cycles as f32 * m.dt().to_f32();
        (d, m.v_flow_max.to_f32() * (d + ahead))
    } else {
        (0.0, f32::INFINITY)
    };
    Some(Sizing {
        limit,
        walk: TurnWalk::new(v_turn, 0.0, limit),
        flow: FlowChange {
            v_o,
            v_c,
            delay,
            settle,
            v_turn,
            stage: 0,
        },
        defer,
        soon,
    })
}

/// A fillet of the bead ahead: `radius` mm, turning the head from unit `from` to unit
/// `to`, starting `at` mm along the path ahead of the head.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turn {
    /// Where the fillet starts, mm of path ahead of the head.
    pub at: f32,
    /// Its radius, mm.
    pub radius: f32,
    /// Unit direction into the turn.
    pub from: [f32; 2],
    /// Unit direction out of it.
    pub to: [f32; 2],
}

/// Turns looked at per decision (bounds the decision's cost; a bead's turns past them
/// keep what the window is by then).
pub const TURNS_AHEAD: usize = 64;

/// The shortest window (s) whose mean takes the head through the tight turns ahead
/// within `limit` at speeds up to `v`, fed a turn at a time (nearest first, at most
/// `TURNS_AHEAD`). The mean's acceleration is the change of the planned velocity across
/// the window over its length, so a turn from unit `from` to `to` whose fillet is
/// tighter than `v^2 / limit` (a segment too short for the machine's radius) needs
/// `v |to - from| / limit`, and two in a row within the window (a U-turn between rows)
/// their pair's change. A turn within `near` mm of the head may meet the flow's own
/// change, from speed 0 ..= `v` to another: the velocity's change across the window is
/// then at most `v max(|to - from|, 1)` (their vector sum: the largest of
/// `|v2 to - v1 from|` lies at a corner of the speeds' square).
#[derive(Clone, Copy, Debug)]
pub struct TurnWalk {
    v: f32,
    near: f32,
    limit: f32,
    /// The head's distance over a window per unit of the velocity's change
    /// (`v^2 / limit`).
    reach: f32,
    /// The largest squared change a window must take (relative to `v`).
    most: f32,
    /// Turns up to this far (mm) count in `most_soon` too (`soon`).
    soon: f32,
    most_soon: f32,
    prev: Option<(Turn, bool)>,
    seen: u32,
}

impl TurnWalk {
    /// No turn seen yet.
    pub fn new(v: f32, near: f32, limit: f32) -> Self {
        TurnWalk {
            v,
            near,
            limit,
            reach: v * v / limit,
            most: 0.0,
            soon: f32::INFINITY,
            most_soon: 0.0,
            prev: None,
            seen: 0,
        }
    }

    /// Keeps apart the window the turns within `d` mm need (`window_soon`).
    pub fn soon(mut self, d: f32) -> Self {
        self.soon = d;
        self
    }

    /// Whether it has seen the most turns it looks at.
    pub fn full(&self) -> bool {
        self.seen as usize >= TURNS_AHEAD
    }

    /// The next turn ahead (ignored once `full`).
    pub fn feed(&mut self, t: Turn) {
        if self.full() {
            return;
        }
        self.seen += 1;
        // Squared chords throughout and one root at the end: a software `sqrtf` is about
        // 50 instructions, and two a turn over 64 turns took the soft machine's dearest
        // tick to 8 375 instructions (5 256 without).
        let chord2 = |a: [f32; 2], b: [f32; 2]| {
            let (x, y) = (a[0] - b[0], a[1] - b[1]);
            x * x + y * y
        };
        let close = t.at < self.near;
        let change = |c2: f32| if close { crate::fast::max(c2, 1.0) } else { c2 };
        let tight = t.radius * self.limit < self.v * self.v;
        let mut most = self.most;
        if tight {
            most = crate::fast::max(most, change(chord2(t.from, t.to)));
        }
        if let Some((p, p_tight)) = self.prev {
            if tight || p_tight {
                let pair = change(chord2(p.from, t.to));
                // Closer than the head goes over the pair's window.
                let gap = t.at - p.at;
                if gap < 0.0 || gap * gap < self.reach * self.reach * pair {
                    most = crate::fast::max(most, pair);
                }
            }
        }
        if t.at < self.soon {
            self.most_soon = most;
        }
        self.most = most;
        self.prev = Some((t, tight));
    }

    /// The window (s) the turns fed so far need.
    pub fn window(&self) -> f32 {
        self.window_of(self.most)
    }

    /// The window (s) the turns fed so far that lie within `soon` need.
    pub fn window_soon(&self) -> f32 {
        self.window_of(self.most_soon)
    }

    fn window_of(&self, most: f32) -> f32 {
        if most > 0.0 {
            self.v / self.limit * libm::sqrtf(most)
        } else {
            0.0
        }
    }
}

/// `TurnWalk` over `turns` at once.
#[cfg(test)]
fn turn_window(v: f32, near: f32, limit: f32, turns: impl Iterator<Item = Turn>) -> f32 {
    let mut w = TurnWalk::new(v, near, limit);
    for t in turns.take(TURNS_AHEAD) {
        w.feed(t);
    }
    w.window()
}

/// Share of the largest step of the plan's velocity that `crate::step_ramps` does not
/// take for one (`StepRamps::UNSEEN` position units a cycle, 4 mm/s at 10 kHz) that a
/// decision's narrowest window keeps within the limit (`min_half`): 2.7 mm/s, twice the
/// largest such kink measured (1.3 mm/s over a few frames, the fine features at
/// 500 mm/s^2). The whole of it kept every decision's window at least 4.3 ms wide at
/// 1 000 mm/s^2, and the box mean laid its `dv w / 8` at every kink of a valve's flow
/// whose own change needed none: on issue 22's machine (`configs/soft-real-valves.toml`)
/// the random pattern's band over 0.2 mm 0.0043 -> 0.0020 and over 0.02 mm 0.0196 ->
/// 0.0091 at 2 / 3; at a half, 0.0012 and 0.0045, but the logo at 500 mm/s^2 took Y to
/// 511 mm/s^2 with the valves shut.
const KINK_SHARE: f32 = 2.0 / 3.0;

/// The narrowest half window (frames) a decision takes: what keeps within `limit`
/// `KINK_SHARE` of the largest step of the plan's velocity that `crate::step_ramps` does
/// not ramp over a window of its own. With no floor the logo at 500 mm/s^2 reached
/// 610 mm/s^2 on X and Y, and the fine features 1 045 on Y (a 1.3 mm/s kink over a few
/// frames).
fn min_half<R: Real, const N: usize>(m: &Machine<R, N>, limit: f32) -> u32 {
    let dt = m.dt().to_f32();
    let step = KINK_SHARE * crate::step_ramps::StepRamps::UNSEEN as f32 * 1.0e-4 / dt;
    let frames = libm::ceilf(step / limit / dt);
    (frames as u32 / 2).min(m.ramp_cycles / 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Headings along X, along Y and back along X.
    const X: [f32; 2] = [1.0, 0.0];
    const Y: [f32; 2] = [0.0, 1.0];
    const NX: [f32; 2] = [-1.0, 0.0];

    /// A fillet `at` mm ahead, of `radius` mm, turning from heading `from` to `to`.
    fn t(at: f32, radius: f32, from: [f32; 2], to: [f32; 2]) -> Turn {
        Turn {
            at,
            radius,
            from,
            to,
        }
    }

    /// A fillet tighter than the limit allows at the speed needs the window that takes
    /// the velocity's whole change across it within the limit; a looser one none; two
    /// in a row closer than their pair's window need the pair's; near the flow's change
    /// a turn of under 60 degrees still needs the speed's own change.
    #[test]
    fn turns_need_their_velocity_change_over_the_window() {
        let (x, y, nx) = (X, Y, NX);
        let r2 = core::f32::consts::SQRT_2;
        // 10 mm/s on 0.1 mm: 1 000 mm/s^2 against 475.
        let w = turn_window(10.0, 0.0, 475.0, [t(5.0, 0.1, x, y)].into_iter());
        assert!((w - 10.0 * r2 / 475.0).abs() < 1e-6, "{w}");
        // 0.4 mm: 250 mm/s^2, within.
        assert_eq!(
            turn_window(10.0, 0.0, 475.0, [t(5.0, 0.4, x, y)].into_iter()),
            0.0
        );
        // A U-turn of two tight fillets 0.1 mm apart: the pair's reversal, 2 v.
        let u = [t(5.0, 0.05, x, y), t(5.1, 0.05, y, nx)];
        let w = turn_window(10.0, 0.0, 475.0, u.into_iter());
        assert!((w - 20.0 / 475.0).abs() < 1e-6, "{w}");
        // The same fillets 5 mm apart: each on its own.
        let u = [t(5.0, 0.05, x, y), t(10.0, 0.05, y, nx)];
        let w = turn_window(10.0, 0.0, 475.0, u.into_iter());
        assert!((w - 10.0 * r2 / 475.0).abs() < 1e-6, "{w}");
        // A tight 30 degree turn within the flow's change: at least v / limit.
        let d = [0.866_025_4, 0.5];
        let w = turn_window(10.0, 6.0, 475.0, [t(5.0, 0.01, x, d)].into_iter());
        assert!((w - 10.0 / 475.0).abs() < 1e-6, "{w}");
    }

    /// A shear-thinning paste's bead sizes its turns at the speed it runs once the channel
    /// has flushed (its supply through a channel full of it: the print speed at `auto`),
    /// not the fastest any supply drives the head through any contents. The food pastes
    /// at 500 mm/s^2: a U-turn of 0.22 mm fillets past the bead's start takes 455 mm/s^2
    /// at 10 mm/s, within the ramps' share of the limit, and the window is the least a
    /// decision takes; sized at the fastest flow (chocolate's supply through mashed
    /// potato, 10.63 mm/s: 514 mm/s^2) it took a window of 45 ms, whose box mean cut the
    /// logo's U-turns with the flow steady (4.03 % off over 0.2 mm on a crop).
    #[test]
    fn a_shear_thinning_bead_sizes_its_turns_at_its_flushed_speed() {
        let mut c: crate::config::Config =
            toml::from_str(include_str!("../configs/food-pastes.toml")).unwrap();
        c.motion.max_accel_mm_s2 = [500.0, 500.0, 200.0];
        let m = c.validate::<f32, 4>().unwrap();
        assert!((m.v_flow_max - 10.63).abs() < 0.01, "{}", m.v_flow_max);
        let model = FlowModel::new(&m, 0);
        let mut s = switch_start(&m, &model, 0, Some(0)).unwrap();
        assert!(s.checking());
        s.begin_follow();
        while !s.step() {}
        let far = s.soon + 10.0;
        let u_turn = [t(far, 0.22, X, Y), t(far + 0.35, 0.22, Y, NX)];
        for turn in u_turn {
            s.walk.feed(turn);
        }
        assert_eq!(s.half(&m), Some(min_half(&m, s.limit)));
        // Walked at the fastest flow, the same U-turn takes its whole reversal's window,
        // 2 v / limit (45 ms, half of it 224 frames).
        let v = m.v_flow_max.to_f32();
        let mut fast = TurnWalk::new(v, 0.0, s.limit);
        for turn in u_turn {
            fast.feed(turn);
        }
        s.walk = fast;
        let reversal = libm::ceilf(2.0 * v / s.limit / m.dt().to_f32()) as u32 / 2;
        assert_eq!(s.half(&m), Some(reversal));
        assert_eq!(reversal, 224);
    }

    /// A bead start's window at once counts the turns within `soon` only; the whole
    /// window, every turn fed, as before. A pair straddling `soon` counts at once when its
    /// second turn lies within it.
    #[test]
    fn a_bead_start_keeps_far_turns_for_later() {
        let (x, y, nx) = (X, Y, NX);
        let r2 = core::f32::consts::SQRT_2;
        let far = [t(0.5, 0.4, x, y), t(9.0, 0.05, x, y), t(9.1, 0.05, y, nx)];
        let mut w = TurnWalk::new(10.0, 0.0, 475.0).soon(2.0);
        for turn in far {
            w.feed(turn);
        }
        // The loose turn near the start needs nothing; the far U-turn its reversal.
        assert_eq!(w.window_soon(), 0.0);
        assert!((w.window() - 20.0 / 475.0).abs() < 1e-6, "{}", w.window());
        let mut w = TurnWalk::new(10.0, 0.0, 475.0).soon(2.0);
        for turn in [t(1.0, 0.05, x, y), t(9.0, 0.05, y, nx)] {
            w.feed(turn);
        }
        assert!((w.window_soon() - 10.0 * r2 / 475.0).abs() < 1e-6);
        assert_eq!(w.window_soon(), w.window());
        // Without `soon` both are the whole.
        let mut w = TurnWalk::new(10.0, 0.0, 475.0);
        w.feed(t(9.0, 0.05, x, y));
        assert_eq!(w.window_soon(), w.window());
    }
}
