//! The executor's side of the speed-ramp window (`crate::ramp`): the frame each planned
//! cycle enters, the outputs of a ramped tick, holding and stopping the window, and the
//! acceleration each step's own ramp may use. Stops at the window's interface.

use super::Executor;
use crate::config::Machine;
use crate::outputs::Outputs;
use crate::ramp::{to_units, Frame};
use crate::real::Real;
use crate::state::{Fault, Report, RunState};
use crate::vol::Vol;

impl<R: Real, const N: usize> Executor<R, N> {
    /// The head at rest where the plan has it, valves as commanded: the whole ramp window
    /// that frame (after a job begins, a config loads, or the outputs went safe).
    pub(super) fn hold_ramp(&mut self) {
        self.sizer = None;
        self.deferred = None;
        self.sums.stop();
        if self.ramped {
            let f = self.frame();
            let m = &self.machine;
            let per_unit = crate::ramp::frames_per_unit(step_ramp_accel(m), m.dt().to_f32());
            self.ramp
                .reset(m.ramp_cycles, f, &mut self.step_ramps, per_unit);
            // The follower of a valve decision's flow: the whole X/Y limit in position
            // units a frame squared (it shares it with the head's turn itself).
            let dt = m.dt().to_f32();
            let a = m.motion.max_accel[0].min(m.motion.max_accel[1]).to_f32();
            self.follow.reset(m.ramp_cycles / 2, a * dt * dt * 1.0e4);
        }
    }

    /// This cycle as planned, for the ramp window.
    #[inline(always)]
    fn frame(&self) -> Frame<N> {
        Frame {
            pos: to_units(self.head_pos),
            valves: self.model.commanded(),
            state: self.model_state(),
            index: self.last_index,
            dv: self.last_dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            landing: self.model.channel().landing(),
            feeding: self.model.feeding(),
            slugs: self.model.channel().len().min(u8::MAX as usize) as u8,
            plunger: self.plunger_targets(),
        }
    }

    /// Motion stops where the outputs are, not where the plan ran ahead to. Once per
    /// fault or abort: refilling the window is 24 KiB of stores.
    pub(super) fn stop_ramp(&mut self) {
        if self.ramped {
            self.head_pos = self.ramp.position(&self.step_ramps);
            self.hold_ramp();
        }
    }

    /// The outputs of a tick with speed ramps: the cycles just planned enter the window
    /// and the outputs show it. Out of line, so that machines without ramps run the tick
    /// they ran before ramps existed, plus one branch. A late tick's catch-up cycles enter
    /// as copies of the last (the window smooths the jump).
    #[inline(never)]
    pub(super) fn ramped_outputs(
        &mut self,
        cycles: u32,
        total_dv: Vol,
        out: &mut impl Outputs,
    ) -> Result<Report<R>, Fault> {
        // One cycle a tick but for a late tick's catch-up: no 64-bit division then (a
        // software routine on the M4, 65 instructions).
        let dv = if cycles <= 1 {
            total_dv
        } else {
            Vol(total_dv.0 / cycles as i64)
        };
        for _ in 0..cycles {
            self.push_frame(dv);
        }
        let target = probe!(MEAN, self.ramp.position(&self.step_ramps));
        if let Err(f) = probe!(STEPS, self.move_head(target, cycles, out)) {
            self.safe_state(f, out);
            return Err(f);
        }
        probe!(REPORT, {
            if let Err(f) = self.move_plungers(true, cycles, out) {
                self.safe_state(f, out);
                return Err(f);
            }
            self.set_valves(self.ramp.current().valves, out);
            Ok(self.ramped_report_at(target))
        })
    }

    /// The cycle just planned enters the ramp window; `dv` is its volume alone
    /// (`last_dv` sums a catch-up's cycles). Out of line, as `ramped_report`.
    #[inline(never)]
    fn push_frame(&mut self, dv: Vol) {
        if self.ramp.narrowing() {
            // In tail position: the usual path keeps its registers.
            return self.push_frame_narrow(dv);
        }
        let mut f = probe!(FRAME, self.frame());
        f.dv = dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        probe!(RING, self.ramp.push(f, &mut self.step_ramps));
    }

    /// `push_frame` while a valve decision's window narrows the ramp's mean.
    #[inline(never)]
    fn push_frame_narrow(&mut self, dv: Vol) {
        let mut f = probe!(FRAME, self.frame());
        f.dv = dv.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let h0 = probe!(RING, self.ramp.push_narrow(f, &mut self.step_ramps));
        // The follower's window sums (`crate::window_sums`), while it runs or waits for
        // them to fill.
        if self.sums.on() {
            self.sums.pushed(&self.ramp, h0);
        }
        if self.sizer.is_some() {
            // A valve decision's sizing, a step a frame (`sizing_step`), on the slow path
            // only: the usual tick pays nothing for it.
            probe!(SIZING, self.sizing_step());
            if self.sizer.is_some() {
                self.ramp.keep_slow();
            }
        }
        if self.deferred.is_some() {
            self.widen_when_due();
        }
        // The soft machines' slowing at tight fillets, for the next cycle's position
        // (`turns`): here, on the narrowed ring's path, the others pay nothing for it.
        probe!(TURNS, self.slow_at_turns());
        if self.follow.active() {
            probe!(FOLLOWER, {
                let (sums, ramp) = (&self.sums, &self.ramp);
                let lead = ramp.half() + 1;
                let step = ramp.back(lead as usize).dv;
                self.follow
                    .push(lead, step, ramp.back(0).dv, || sums.look(ramp));
                self.follow_flow();
                self.ramp.keep_slow();
            });
        }
    }

    /// Bends the ramp's mean where the flow's follower (`crate::flow_follow`) puts the
    /// head. Out of line: only while a valve decision's flow changes.
    #[inline(never)]
    fn follow_flow(&mut self) {
        let c = *self.ramp.current();
        let printing = matches!(
            c.state,
            RunState::Printing | RunState::Settling | RunState::Pausing
        );
        let (base, off) = self.ramp.mean_parts(&mut self.step_ramps);
        let d = probe!(
            FOLLOW,
            self.follow
                .follow(base, off, c.dv, printing, self.sums.mean(&self.ramp))
        );
        self.ramp.bend(d, &mut self.step_ramps);
        if !self.follow.active() {
            self.sums.stop();
        }
    }
}

/// Acceleration each step's own ramp may use (`crate::step_ramps`), mm/s^2: the ramps'
/// share of the X/Y limit, as the machine's window has, less what the flow's smooth
/// change under the ramp may add (the channel's contents changing as it flushes: the head
/// speed moves by at most `v_flow_max` over the channel's volume of bead, at up to
/// `v_flow_max`). The machine's one window, sized for the largest step, left that room
/// under every smaller step; a window sized to the step leaves none (measured: 2 064
/// mm/s^2 on a 2 000 machine at a bead's end just after a switch, without this).
pub fn step_ramp_accel<R: Real, const N: usize>(m: &Machine<R, N>) -> f32 {
    let a = m.motion.max_accel[0].min(m.motion.max_accel[1]).to_f32()
        * crate::config::RAMP_SHARE as f32;
    let v = m.v_flow_max.to_f32();
    let along = m.v_channel.mm3::<f32>() / m.bead_area.to_f32();
    let smooth = if along > 0.0 { v * v / along } else { 0.0 };
    // Under a quarter of the limit left: every step keeps the machine's window.
    if a - smooth > 0.25 * a {
        a - smooth
    } else {
        0.0
    }
}
