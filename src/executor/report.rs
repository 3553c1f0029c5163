//! The executor's `Report`: the plan's own on a machine without speed ramps, what the
//! ramp window's outputs show on one with them. Stops at reading the state.

use super::{Executor, Phase};
use crate::real::Real;
use crate::state::Report;
use crate::vol::Vol;

impl<R: Real, const N: usize> Executor<R, N> {
    pub(super) fn report(&self) -> Report<R> {
        if self.ramped {
            self.ramped_report()
        } else {
            self.plan_report()
        }
    }

    /// The report of a machine without ramps: the plan is what the outputs show.
    pub(super) fn plan_report(&self) -> Report<R> {
        Report {
            state: self.model_state(),
            position: self.head_pos,
            valves: self.valves_out,
            feeding: self.model.feeding(),
            landing: self.model.channel().landing(),
            q: self.last_q,
            dv: self.last_dv,
            speed: self.speed(),
            plan_volume: self.head,
            command_index: self.last_index,
            slugs: self.model.channel().len().min(u8::MAX as usize) as u8,
        }
    }

    /// Head speed along the print path (plan), mm/s: the last cycle's mean flow over the
    /// bead section (a late tick's catch-up included, whose summed volume would overstate
    /// it; and without converting the volume again).
    #[inline(always)]
    fn speed(&self) -> R {
        if matches!(self.phase, Phase::Print { .. }) {
            self.last_q * self.inv_s
        } else {
            R::ZERO
        }
    }

    /// The report with speed ramps: what the outputs show, half a window behind the plan.
    /// Out of line, so that machines without ramps do not carry it in their tick.
    fn ramped_report(&self) -> Report<R> {
        self.ramped_report_at(self.ramp.position(&self.step_ramps))
    }

    /// `ramped_report` with the window's mean position already worked out (the tick has
    /// it: the mean of the window costs about 70 instructions).
    #[inline(never)]
    pub(super) fn ramped_report_at(&self, position: [R; 3]) -> Report<R> {
        let f = self.ramp.current();
        Report {
            state: self.state(),
            position,
            valves: self.valves_out,
            feeding: f.feeding,
            landing: f.landing,
            q: self.last_q,
            dv: Vol(f.dv as i64),
            speed: self.speed(),
            plan_volume: self.head,
            command_index: f.index,
            slugs: f.slugs,
        }
    }
}
