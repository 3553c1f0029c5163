//! One control cycle of the plan: the flow model's step, then the head driven through the
//! phases (print along the bead by volume, settle, travel, dwell, pause, park), plan items
//! taken as each ends; and the step outputs for the head and the syringe plungers. Stops
//! at the cycle: what the ramp window does with it is `ramp`'s.

use super::plan::{Item, Seg};
use super::{cycles32, park, Executor, Phase, PLAN_CAPACITY};
use crate::config::Machine;
use crate::motion::Trapezoid;
use crate::outputs::{Axis, Outputs};
use crate::real::Real;
use crate::state::Fault;
use crate::vol::Vol;

impl<R: Real, const N: usize> Executor<R, N> {
    /// Syringe plunger targets, steps. Inlined: every ramped frame asks, and a pneumatic
    /// machine's answer is a test; the syringes' out of line.
    #[inline(always)]
    pub(super) fn plunger_targets(&self) -> [i32; N] {
        if !self.machine.syringes {
            return [0i32; N];
        }
        self.syringe_targets()
    }

    /// `plunger_targets` of a syringe machine.
    #[inline(never)]
    fn syringe_targets(&self) -> [i32; N] {
        let mut t = [0i32; N];
        for (i, inlet) in self.machine.inlets.iter().enumerate() {
            if let Some(sy) = inlet.syringe {
                t[i] = plunger_steps(self.plunger_vol[i], sy.steps_per_mm3);
            }
        }
        t
    }

    /// Steps for head position `target` over `cycles`.
    #[inline(always)]
    pub(super) fn move_head(
        &mut self,
        target: [R; 3],
        cycles: u32,
        out: &mut impl Outputs,
    ) -> Result<(), Fault> {
        self.steps
            .move_over(target, cycles, out)
            .map_err(|e| Fault::StepRate {
                axis: e.axis,
                steps: e.steps,
                max: e.max,
            })
    }

    /// Syringe plungers (E axes): to the ramp window's current frame (`ramped`) or to the
    /// volume displaced so far.
    #[inline(always)]
    pub(super) fn move_plungers(
        &mut self,
        ramped: bool,
        cycles: u32,
        out: &mut impl Outputs,
    ) -> Result<(), Fault> {
        if !self.machine.syringes {
            return Ok(());
        }
        let max = self.machine.motion.max_steps_per_cycle as u64 * cycles as u64;
        for (i, inlet) in self.machine.inlets.iter().enumerate() {
            let Some(sy) = inlet.syringe else { continue };
            let target = if ramped {
                self.ramp.current().plunger[i] as i64
            } else {
                plunger_steps(self.plunger_vol[i], sy.steps_per_mm3) as i64
            };
            let d = target - self.plunger_steps[i];
            if d.unsigned_abs() > max {
                return Err(Fault::StepRate {
                    axis: Axis::E(i as u8),
                    steps: d.unsigned_abs().min(u32::MAX as u64) as u32,
                    max: max as u32,
                });
            }
            if d != 0 {
                out.step(Axis::E(i as u8), d > 0, d.unsigned_abs() as u32);
                self.plunger_steps[i] = target;
            }
        }
        Ok(())
    }

    /// Model, head and valve decisions for one cycle. Returns the volume extruded.
    pub(super) fn cycle_once(&mut self) -> Result<Vol, Fault> {
        self.cycle += 1;
        if self.machine.syringes {
            self.displace_plungers();
        }
        let flow = probe!(FLOW, self.model.step())?;
        self.last_q = flow.q;
        let dv = flow.dv;
        // Phases may hand over to the next within a cycle (end of bead -> travel ...);
        // each hand-over consumes a plan item, so this is bounded by the plan's length.
        #[cfg(feature = "probe")]
        let start = crate::probe::now();
        let mut dv_left = dv;
        for _ in 0..=PLAN_CAPACITY {
            match self.phase {
                Phase::Print { stopping } => {
                    self.head += dv_left;
                    dv_left = Vol::ZERO;
                    let ended = self.follow_path(stopping, flow.q)?
                        || (stopping && self.tail_ran_out(flow.q));
                    if !ended {
                        break;
                    }
                }
                Phase::Settle { cycles } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    let flow_done = !self.machine.motion.wait_for_flow_decay
                        || (flow.q <= self.machine.q_stop && self.model.commanded() == 0);
                    // A pause asked for waits here until the flow is at its rest flow
                    // (never past the settle limit: that is the fault's business).
                    let settled = flow_done
                        && (!self.pause.requested
                            || cycles >= self.settle_limit
                            || self.rest_reached(flow.q));
                    if settled {
                        self.phase = Phase::Idle;
                        continue;
                    }
                    if cycles > self.settle_limit {
                        return Err(Fault::FlowDidNotStop);
                    }
                    self.phase = Phase::Settle { cycles: cycles + 1 };
                    break;
                }
                Phase::Travel {
                    from,
                    dir,
                    trap,
                    cycles,
                } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    if self.travel_cycle(from, dir, trap, cycles) {
                        continue;
                    }
                    break;
                }
                Phase::Dwell { left } => {
                    self.lost += dv_left;
                    if left <= 1 {
                        self.plan.pop_front();
                        self.phase = Phase::Idle;
                    } else {
                        self.phase = Phase::Dwell { left: left - 1 };
                    }
                    break;
                }
                Phase::Idle => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    if !self.start_next()? {
                        break;
                    }
                }
                Phase::Pausing => {
                    self.head += dv_left;
                    dv_left = Vol::ZERO;
                    if self.follow_pause(flow.q)? {
                        continue;
                    }
                    break;
                }
                // Paused, the head holds still: what little still trickles below the
                // stop threshold (micrometres of bead) stays at the pause point, unless
                // a park moves the head away and back (valves shut).
                Phase::Paused { .. } => {
                    self.lost += dv_left;
                    dv_left = Vol::ZERO;
                    if self.pause.park.stage != park::ParkStage::None {
                        self.park_cycle();
                        // Back from a park between beads: the next item starts now.
                        if matches!(self.phase, Phase::Idle) {
                            continue;
                        }
                    }
                    break;
                }
                Phase::Done | Phase::Aborted | Phase::Faulted(_) => {
                    self.lost += dv_left;
                    break;
                }
            }
        }
        #[cfg(feature = "probe")]
        crate::probe::add(crate::probe::PHASES, start);
        if self.pause.requested && matches!(self.phase, Phase::Print { stopping: false }) {
            self.pause_check();
        }
        if matches!(self.phase, Phase::Print { .. }) {
            probe!(DECIDE, self.decide_valves())?;
        }
        Ok(dv)
    }

    /// The syringes' displaced volume: each running plunger's volume per cycle. Inlined,
    /// as the rest of `cycle_once`, whose one caller it is.
    #[inline(always)]
    fn displace_plungers(&mut self) {
        let running = self.model.commanded();
        for (i, v) in self.plunger_vol.iter_mut().enumerate() {
            if running & (1 << i) != 0 {
                *v += self.plunger_per_cycle[i];
            }
        }
    }

    /// One cycle of a travel move, `cycles` into it. Returns true when the move ended
    /// and the next item should see this cycle too. Inlined, as `displace_plungers`.
    #[inline(always)]
    fn travel_cycle(&mut self, from: [R; 3], dir: [R; 3], trap: Trapezoid<R>, cycles: u64) -> bool {
        if cycles == 0 && (self.travel_hold > 0 || self.follow.active()) {
            // The head holds where the bead left it (`end_hold`), and while the flow's
            // follower still returns the lag it built (`crate::flow_follow`: the head
            // placed behind the mean on its path, which turns into the travel here):
            // run into a travel's start at the whole limit, the return swung Y to
            // 698 mm/s^2 on a 500 machine (issue 22's random cells). The follower stands
            // down once the lag is spent, the outputs past the bead.
            self.travel_hold = self.travel_hold.saturating_sub(1);
            return false;
        }
        let t = self.dt * R::from_u32(cycles32(cycles + 1));
        let d = trap.distance(t);
        for a in 0..3 {
            self.head_pos[a] = from[a] + dir[a] * d;
        }
        if t >= trap.duration() {
            if self.start_hold > 0 && self.reverses_into_bead(dir) {
                // The travel's item leaves as the hold ends (`Phase::Dwell` takes it).
                self.phase = Phase::Dwell {
                    left: self.start_hold as u64,
                };
                return false;
            }
            self.plan.pop_front();
            self.phase = Phase::Idle;
            return true;
        }
        self.phase = Phase::Travel {
            from,
            dir,
            trap,
            cycles: cycles + 1,
        };
        false
    }

    /// Whether the plan's next item after the travel in front (heading `dir`) is a bead
    /// that leaves against it along X or Y: the travel's braking and the bead's first
    /// ramp then push that axis the same way (`start_hold`).
    fn reverses_into_bead(&self, dir: [R; 3]) -> bool {
        match self.plan.iter().nth(1) {
            Some(Item::Seg(s)) => (0..2).any(|a| dir[a] * s.dir[a] < R::of(-1e-3)),
            _ => false,
        }
    }

    /// Cycles a travel holds the head before it starts (heading `dir`) where the head
    /// still moved as the bead before it ended (a real valve's tail creeps at the stop
    /// flow, 0.14 mm/s on the seed printhead) against the travel along X or Y. The end
    /// of that creep is a step of the head's speed, ramped over its own window centred on
    /// it, and the travel accelerates at the whole limit from its first cycle, which the
    /// ring's mean spreads over its span centred there: they add (690 mm/s^2 on Y of a
    /// 500 mm/s^2 machine, issue 22's random cells). Held half of both, they lie apart.
    fn end_hold(&self, dir: [R; 3]) -> u32 {
        if !self.ramped {
            return 0;
        }
        // The plan's last moves, 0.1 um units a cycle: a creep moves a unit in several.
        const OVER: usize = 16;
        let (p0, p1) = (self.ramp.back(0).pos, self.ramp.back(OVER).pos);
        let u = [
            p0[0].wrapping_sub(p1[0]) as f32 / OVER as f32,
            p0[1].wrapping_sub(p1[1]) as f32 / OVER as f32,
        ];
        if !(0..2).any(|a| u[a] * dir[a].to_f32() < -0.05) {
            return 0;
        }
        let window = self.ramp.window() as f32;
        let m = &self.machine;
        let per_unit =
            crate::ramp::frames_per_unit(super::ramp::step_ramp_accel(m), m.dt().to_f32());
        let step = per_unit * libm::sqrtf(u[0] * u[0] + u[1] * u[1]);
        let step = if step.is_finite() {
            step.min(window)
        } else {
            window
        };
        let span = (2 * self.ramp.half().max(self.ramp.goal()) + 1) as f32;
        ((span + step) / 2.0) as u32 + 1
    }

    /// Takes the next plan item when idle. Returns true if a new phase began that should
    /// see this cycle too.
    fn start_next(&mut self) -> Result<bool, Fault> {
        if self.pause.requested {
            self.pause_between_beads();
            return Ok(false);
        }
        // By reference: only the fields each arm needs are read (a whole segment copied
        // cost the bench's worst tick an instruction once it carried its section).
        let Some(item) = self.plan.front() else {
            if !self.begun || self.ended {
                self.phase = if self.ended { Phase::Done } else { Phase::Idle };
            }
            return Ok(false);
        };
        match *item {
            Item::Seg(Seg {
                index,
                u_start,
                inv_s,
                ..
            }) => {
                self.last_index = index;
                self.head = u_start;
                // The segment's own section (`follow_path` takes each next one's): the
                // head's `v = Q / S`, and what turns volume into length.
                self.inv_s = inv_s;
                self.phase = Phase::Print { stopping: false };
                self.open_bead();
                Ok(false)
            }
            Item::Travel { to, index } => {
                self.last_index = index;
                let from = self.head_pos;
                let mut delta = [R::ZERO; 3];
                let mut len2 = R::ZERO;
                for a in 0..3 {
                    delta[a] = to[a] - from[a];
                    len2 += delta[a] * delta[a];
                }
                let len = len2.sqrt();
                if len <= R::of(1e-6) {
                    self.head_pos = to;
                    self.plan.pop_front();
                    return Ok(true);
                }
                let mut dir = [R::ZERO; 3];
                let mut v = self.machine.motion.travel_speed;
                let mut acc = R::of(1e9);
                for a in 0..3 {
                    dir[a] = delta[a] / len;
                    let c = dir[a].abs();
                    if c > R::of(1e-9) {
                        v = v.min(self.machine.motion.max_speed[a] / c);
                        acc = acc.min(self.machine.motion.max_accel[a] / c);
                    }
                }
                self.travel_hold = self.end_hold(dir);
                self.phase = Phase::Travel {
                    from,
                    dir,
                    trap: Trapezoid::new(len, v, acc),
                    cycles: 0,
                };
                Ok(false)
            }
            Item::Dwell { cycles, index } => {
                self.last_index = index;
                self.phase = Phase::Dwell { left: cycles };
                Ok(false)
            }
            Item::End { index } => {
                self.last_index = index;
                self.plan.pop_front();
                self.phase = Phase::Done;
                Ok(false)
            }
        }
    }

    /// Moves the head to plan volume `self.head` along the current bead. Returns true
    /// when the bead ended and the next phase should run this cycle. Inlined into the
    /// tick's print path (a pause's tail calls it too, out of line).
    #[inline(always)]
    pub(super) fn follow_path(&mut self, stopping: bool, q: R) -> Result<bool, Fault> {
        let q_stop = self.machine.q_stop;
        let shut = self.model.commanded() == 0;
        // Where the head is: the volume clock less what it lags after a tight fillet.
        let at = self.head - self.lag;
        for _ in 0..PLAN_CAPACITY {
            let Some(Item::Seg(seg)) = self.plan.front() else {
                // Printing with no segment queued: the feeder fell behind.
                return Err(Fault::Underrun);
            };
            self.last_index = seg.index;
            let past = at >= seg.u_end;
            // A tail that ran out short of the end: the rest is within the stop threshold
            // (short of an earlier segment: `tail_ran_out`).
            let tail_done = seg.last && stopping && q <= q_stop && shut;
            if past || tail_done {
                if seg.last {
                    let seg = *seg;
                    self.end_bead(seg, stopping);
                    return Ok(true);
                }
                self.plan.pop_front();
                // The next segment's own section (a bead may change it mid-way): for the
                // valves' sizing, the report and a pause.
                match self.plan.front() {
                    Some(Item::Seg(n)) => self.inv_s = n.inv_s,
                    _ => return Err(Fault::Underrun),
                }
                continue;
            }
            let off = (at - seg.u_start).mm3::<R>() * seg.inv_s;
            if off <= seg.len {
                self.head_pos[0] = seg.start[0] + seg.dir[0] * off;
                self.head_pos[1] = seg.start[1] + seg.dir[1] * off;
            } else if let Some(f) = &seg.fillet {
                let p = f.point((off - seg.len).min(f.length()));
                self.head_pos[0] = p[0];
                self.head_pos[1] = p[1];
            } else {
                // Past the straight with no fillet, by the rounding of its end's volume and
                // of `inv_s`, yet short of `u_end`: at its end. Left where the last cycle
                // had put it, the head stood a cycle and caught up the next (1 um at
                // 10 mm/s: 1 907 mm/s^2 from 1 ms differences on a 1 500 machine, the logo
                // with real valves).
                self.head_pos[0] = seg.start[0] + seg.dir[0] * seg.len;
                self.head_pos[1] = seg.start[1] + seg.dir[1] * seg.len;
            }
            return Ok(false);
        }
        Ok(false)
    }

    /// A stopping bead's tail that ran out (flow within the stop threshold, valves shut)
    /// short of a segment before the last: a last segment shorter than the shortfall (a
    /// slicer's 2 um move ending a perimeter) left the head on the one before, waiting
    /// for paste that never came, and the job never ended. Ends the bead there; true if
    /// it did. Out of line: `follow_path` sees the last segment's case itself.
    #[cold]
    #[inline(never)]
    fn tail_ran_out(&mut self, q: R) -> bool {
        if q > self.machine.q_stop || self.model.commanded() != 0 {
            return false;
        }
        while let Some(Item::Seg(seg)) = self.plan.front() {
            let seg = *seg;
            if seg.last {
                self.end_bead(seg, true);
                return true;
            }
            self.plan.pop_front();
        }
        false
    }

    /// Opens the valve of the material the cursor stands on as a bead starts or a pause
    /// resumes on one: that of the last boundary already behind the cursor, if any (one
    /// that came due while the last bead's stop or the pause's tail ran out), else the one
    /// entering. Switching to it in the bead's first cycle instead pulsed the other valve
    /// for a cycle. In line in both callers: called, the bead's start cost the seed
    /// machine's worst tick in bench-m4 14 instructions.
    #[inline(always)]
    pub(super) fn open_bead(&mut self) {
        let entry = self.head + self.machine.v_transit();
        while let Some(&(u_b, m)) = self.boundaries.front() {
            if u_b > entry {
                break;
            }
            self.entry_material = m;
            self.boundaries.pop_front();
        }
        self.want = Some(self.entry_material);
        if self.sizing {
            self.size_ramp(Some(self.entry_material));
        }
        self.model.command(1 << self.entry_material);
        self.stop.reset();
        self.switch.reset();
    }

    fn end_bead(&mut self, seg: Seg<R>, stopping: bool) {
        if !stopping || self.model.commanded() != 0 {
            self.model.command(0);
            self.want = None;
        }
        // Volume past the end stays where the head stops (a lag still carried was laid
        // on the bead).
        let at = self.head - self.lag;
        self.lag = Vol::ZERO;
        if at > seg.u_end {
            self.lost += at - seg.u_end;
        }
        // The head stays where the paste ran out: a tail that delivered less than the
        // bead's rest leaves it a little short, rather than jumping the gap dry. The plan
        // clock moves on to the end so the next bead's boundaries keep their volumes.
        if self.head < seg.u_end {
            self.short = self.short.max(seg.u_end - self.head);
        }
        self.head = seg.u_end;
        self.ends.pop_front();
        self.plan.pop_front();
        self.switch.reset();
        self.stop.reset();
        self.phase = Phase::Settle { cycles: 0 };
    }
}

/// Cycles a bead's end may take to settle before the flow counts as not stopping.
pub(super) fn settle_limit<R: Real, const N: usize>(machine: &Machine<R, N>) -> u64 {
    // Ten times the slowest line's dead time plus eight time constants, at least 1 s.
    let mut s = R::ONE;
    for i in machine.inlets.iter() {
        s = s.max(R::of(10.0) * (i.close_delay_s + R::of(8.0) * i.decay_s));
    }
    (s / machine.dt()).round_i64().max(1) as u64
}

/// A plunger's step target for the volume it displaced. Step counts fit i32 (2^31 steps
/// is a thousand litres); beyond, the saturated target becomes a step-rate fault.
#[inline]
fn plunger_steps<R: Real>(v: Vol, steps_per_mm3: R) -> i32 {
    (v.mm3::<R>() * steps_per_mm3).round_i32()
}

/// Cycles the head holds at a bead's start after a travel that reverses along an axis
/// (`travel_cycle`): the ring's window, less the cycles the opening valve's dead time
/// holds it anyway, on a ramped machine where some pneumatic inlet's flow steps as it
/// opens (no pressure rise); 0 elsewhere. A travel brakes at the whole limit to its end,
/// and the ring's mean carries that up to half its window past the end; the step of the
/// bead's start is ramped over a window centred on it, half of it before the step. Where
/// the bead leaves against the travel along an axis the two add: 6 248 mm/s^2 on X of a
/// 5 000 mm/s^2 machine at the logo's bead starts (issue 22's instantaneous valves), 7 614
/// with the food pastes. Held a window, they lie apart.
pub(super) fn start_hold<R: Real, const N: usize>(m: &Machine<R, N>) -> u32 {
    if m.ramp_cycles <= 1 || m.syringes {
        return 0;
    }
    let dt = m.dt();
    m.inlets
        .iter()
        .filter(|i| i.rise_s <= R::ZERO)
        .map(|i| {
            let dead = (i.open_delay_s / dt).to_f32();
            let dead = if dead.is_finite() && dead > 0.0 {
                dead as u32
            } else {
                0
            };
            m.ramp_cycles.saturating_sub(dead)
        })
        .max()
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::Command;
    use crate::config::Config;

    fn print(dx: i32, material: u8) -> Command {
        Command::Print {
            dx,
            dy: 0,
            material,
        }
    }

    /// A head whose plan volume the f32 arithmetic puts past a straight's end, short of
    /// the segment's end volume, is at the straight's end. There was no else for it: the
    /// head stood where the last cycle had put it and caught up the next (the logo with
    /// real valves at 1 500 mm/s^2: 1 907 mm/s^2 on X from 1 ms differences, at the end
    /// of a 29.6 mm straight before a change of paste).
    #[test]
    fn a_head_past_a_straight_by_the_rounding_is_at_its_end() {
        let cfg: Config =
            toml::from_str(include_str!("../../configs/soft-real-valves.toml")).unwrap();
        let mut e = Executor::new(cfg.validate::<f32, 4>().unwrap());
        e.begin([20_000, 20_000, 600], 0).unwrap();
        for c in [print(29_600, 0), print(10_000, 1), Command::End] {
            e.push(c).unwrap();
        }
        while !matches!(e.plan.front(), Some(Item::Seg(_))) {
            e.plan.pop_front();
        }
        let Some(Item::Seg(seg)) = e.plan.front() else {
            unreachable!()
        };
        let seg = *seg;
        assert!(seg.fillet.is_none() && !seg.last);
        let end = [
            seg.start[0] + seg.dir[0] * seg.len,
            seg.start[1] + seg.dir[1] * seg.len,
        ];
        let mut past = 0;
        let mut at = seg.u_end.0 - 1;
        while at > seg.u_end.0 - 1_000_000 {
            let off = (Vol(at) - seg.u_start).mm3::<f32>() * seg.inv_s;
            if off > seg.len {
                past += 1;
                e.head = Vol(at);
                e.lag = Vol::ZERO;
                e.head_pos = [0.0; 3];
                assert_eq!(e.follow_path(false, 0.0), Ok(false));
                let d = [e.head_pos[0] - end[0], e.head_pos[1] - end[1]];
                assert!(
                    d[0].abs() < 1e-4 && d[1].abs() < 1e-4,
                    "at {at}: {:?}",
                    e.head_pos
                );
            }
            at -= 997;
        }
        assert!(
            past > 0,
            "no plan volume past the straight: the case is not met"
        );
    }
}
