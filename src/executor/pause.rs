//! Pause and resume anywhere in a bead. A pause request shuts the valves at the first
//! cycle where the flow's tail (the stop prediction) can run out on the bead without
//! carrying the valve cursor over a material boundary, and the head then follows the
//! tail to rest: the pause point. The channel's slugs do not move while the valves are
//! shut, so resuming is a bead start at the pause point and every later boundary lands as
//! if there had been no pause. What the board, the link or the simulator do around a
//! pause (status, link loss, park moves) is theirs.
//!
//! The latency rule: the valves are commanded shut within one control cycle of the
//! request unless (a) a valve change is in flight (a switch commanded whose new inlet does
//! not feed the channel yet, or a bead start whose valve has not acted yet; on machines
//! with speed ramps, also a flow step re-ramped over its own window that the stop's ramp
//! would land on: `StepRamps::narrowed_ahead`), (b) a material boundary lies within the
//! tail's reach of the valve cursor, (c) another inlet could take the junction back during
//! the tail (another syringe's lag still running out, or a line that decays more slowly
//! still holding pressure: `others_spent`), or (d) the bead's planned end does. In (a) to
//! (c) the valves shut at the first cycle where none holds any more, that is once the
//! switch the boundary needs has taken effect; in (d) the bead ends as planned and the
//! pause follows at its end. The head is at rest (flow below
//! `Machine::q_stop` and below 0.5 % of the flow at the request) one tail later, plus
//! half a ramp window on machines with speed ramps.

use super::park::ParkState;
use super::{Executor, Phase};
use crate::flow_model::predict::Goal;
use crate::real::Real;
use crate::vol::Vol;

/// What the executor knows about the latest pause, for status and measurement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PauseInfo {
    /// Cycle (`Executor::cycle`) when the pause was requested.
    pub requested_cycle: u64,
    /// Cycle when the valves were commanded shut for it (or found shut).
    pub shut_cycle: Option<u64>,
    /// Cycle when the head came to rest (the plan's flow fell below the rest flow).
    pub rest_cycle: Option<u64>,
    /// Plan volume (along the concatenated print paths) of the pause point.
    pub point: Option<Vol>,
    /// Head position at the pause point (plan), micrometres.
    pub position_um: [i32; 3],
    /// The pause fell at a bead's planned end (or between beads) rather than mid-bead.
    pub at_bead_end: bool,
}

/// Why `resume` did nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResumeError {
    /// No pause requested and none in effect.
    NotPaused,
}

impl core::fmt::Display for ResumeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ResumeError::NotPaused => write!(f, "nothing to resume: the print is not paused"),
        }
    }
}

/// The pause request and the latest pause's record.
#[derive(Clone, Copy, Debug)]
pub(super) struct PauseState<R> {
    /// A pause is requested (or in effect) and not yet resumed.
    pub requested: bool,
    pub info: Option<PauseInfo>,
    /// A parked pause's excursion (`park.rs`).
    pub park: ParkState<R>,
    /// The flow under which the head is at rest for this pause (`rest_flow`).
    pub q_rest: R,
}

impl<R: Real> PauseState<R> {
    pub const NONE: PauseState<R> = PauseState {
        requested: false,
        info: None,
        park: ParkState::NONE,
        q_rest: R::ZERO,
    };
}

/// Share of the flow at the request under which the head is at rest: the tail has landed
/// once the plant gives less than 1 % of the flow it printed with (issue 23), and the
/// model's flow is a little off the plant's, so half of that.
const REST_SHARE: f64 = 0.005;
/// The rest flow is never below this share of `Machine::q_stop`, so that a pause asked
/// while the flow is still rising from nothing (a bead's start) still comes to rest one
/// tail later: the lines decay exponentially, ten times lower is 2.3 time constants more.
const REST_FLOOR: f64 = 0.1;
/// Seconds from the request after which a flow under the stop threshold is rest enough:
/// a bound on the wait should a model's tail level off above the rest flow.
const REST_WAIT_S: f64 = 1.0;

/// Margin on the predicted tail when deciding whether it clears a boundary or the bead's
/// end: the tracker extrapolates the last prediction over up to `PREDICT_INTERVAL` cycles.
const TAIL_MARGIN: f64 = 1.2;
/// Path added to that margin, mm: the 0.05 mm the boundaries are held to.
const TAIL_SLACK_MM: f64 = 0.05;
/// Another syringe's lag may still give this much bead, mm, when the valves shut: the
/// metering's sliver length is 0.005 mm.
const SLIVER_MM: f64 = 0.002;
/// Another line more slowly decaying than the feeding one may hold this share of its
/// pressure when the valves shut.
const OTHER_LINE_SHARE: f64 = 0.02;

impl<R: Real, const N: usize> Executor<R, N> {
    /// Requests a pause: the valves shut at the soonest point of the current bead where
    /// the flow's tail lands on it without crossing a material boundary (see the module's
    /// latency rule), the head follows the tail to rest and holds there, drivers on,
    /// until `resume`. Between beads (travel, dwell) the pause takes effect when the
    /// move is over. A second request while one is pending or in effect changes nothing.
    pub fn pause(&mut self) {
        if self.pause.requested
            || !self.begun
            || matches!(self.phase, Phase::Done | Phase::Aborted | Phase::Faulted(_))
        {
            return;
        }
        self.pause.requested = true;
        self.pause.q_rest = self.rest_flow();
        self.pause.info = Some(PauseInfo {
            requested_cycle: self.cycle,
            shut_cycle: (self.model.commanded() == 0).then_some(self.cycle),
            rest_cycle: None,
            point: None,
            position_um: [0; 3],
            at_bead_end: false,
        });
    }

    /// Continues after a pause: mid-bead, the valve of the material the cursor stands on
    /// opens as at a bead start, and the head leaves the pause point as the flow reaches
    /// the nozzle (the volume clock). While the head still follows the tail, the flow
    /// restarts from there; a request whose valves have not shut yet is withdrawn.
    /// Refused when nothing is paused.
    /// With a park under way the head first goes back over the pause point and lowers
    /// onto it (`park.rs`); the flow restarts once it is there.
    pub fn resume(&mut self) -> Result<(), ResumeError> {
        if matches!(self.phase, Phase::Paused { .. }) && self.park_resume() {
            return Ok(());
        }
        self.pause.park.wanted = false;
        self.restart_flow()
    }

    /// `resume`'s flow restart, at once (the head is on the pause point).
    pub(super) fn restart_flow(&mut self) -> Result<(), ResumeError> {
        match self.phase {
            Phase::Pausing | Phase::Paused { on_bead: true } => {
                self.phase = Phase::Print { stopping: false };
                // As a bead's start: the flow rises from rest, the same valve decision.
                self.open_bead();
            }
            Phase::Paused { on_bead: false } => {
                self.phase = Phase::Idle;
            }
            Phase::Done | Phase::Aborted | Phase::Faulted(_) => return Err(ResumeError::NotPaused),
            _ if self.pause.requested => {}
            _ => return Err(ResumeError::NotPaused),
        }
        self.pause.requested = false;
        Ok(())
    }

    /// The run state for status: `state`, but a pause request still waiting for its
    /// valve decision reads Pausing rather than Printing. Not in the tick's report (the
    /// tick's instruction budget): for status, which asks at its own pace.
    pub fn status_state(&self) -> crate::executor::RunState {
        match self.state() {
            crate::executor::RunState::Printing if self.pause.requested => {
                crate::executor::RunState::Pausing
            }
            s => s,
        }
    }

    /// The pause point (plan position, micrometres) while a pause is in effect: from
    /// the head's rest until the flow restarts (a park's excursion included).
    pub fn pause_point_um(&self) -> Option<[i32; 3]> {
        self.pause
            .info
            .filter(|i| self.pause.requested && i.rest_cycle.is_some())
            .map(|i| i.position_um)
    }

    /// The latest pause (requested, in effect or resumed) since the job began.
    pub fn pause_info(&self) -> Option<PauseInfo> {
        self.pause.info
    }

    /// A requested pause while printing: shuts the valves now if the tail clears the
    /// next boundary and the bead's end, else waits (and works on the tail prediction).
    #[inline(never)]
    pub(super) fn pause_check(&mut self) {
        let s = self.bead_s();
        let tail = self.stop.answer(&self.model, Goal::Stop);
        let bound = self.tail_bound();
        let reach = match tail {
            Some(t) => Vol::from_mm3(t * R::of(TAIL_MARGIN) + s * R::of(TAIL_SLACK_MM)).min(bound),
            None => bound,
        };
        let end = self.bead_end();
        let near_end = end.is_some_and(|e| self.head + self.window >= e);
        // Room left after the pause point for the resumed flow to end the bead as planned
        // (its stop decision needs a tail's worth of bead).
        let end_clear = end.is_none_or(|e| self.head + reach + bound < e);
        let m = self.entry_material;
        let feeding = self.model.commanded() == 1 << m && self.model.feeding() == Some(m);
        let entry = self.head + self.machine.v_transit();
        let boundary_clear = self
            .boundaries
            .iter()
            .take_while(|b| b.0 <= entry + reach)
            .all(|b| b.1 == m);
        // A stop's ramp must not land on a re-ramped step's (`StepRamps::narrowed_ahead`).
        let ramps_clear = !self.ramped || !self.step_ramps.narrowed_ahead(self.ramp.newest());
        if end_clear && feeding && boundary_clear && ramps_clear && self.others_spent(m) {
            // The head follows the tail within the limit as at a bead's planned end: the
            // shut is a valve decision like the stop's (`size_ramp`). Without it the head
            // followed the food pastes' tail (flow ~ pressure^2.2, its 20 ms decay a 9 ms
            // one) at 626 mm/s^2 on a 500 mm/s^2 machine.
            if self.sizing {
                self.size_ramp(None);
            }
            self.model.command(0);
            self.want = None;
            self.stop.reset();
            self.switch.reset();
            self.phase = Phase::Pausing;
            if let Some(i) = self.pause.info.as_mut() {
                i.shut_cycle = Some(self.cycle);
            }
        } else if !near_end && self.work(1) {
            // Near the end the bead's own stop decision works on the same prediction.
            self.stop.work(&self.model);
        }
    }

    /// Head along the bead by the tail's volume. Returns true when the tail reached the bead's planned end: the
    /// bead then ends as planned and the pause follows between beads.
    #[inline(never)]
    pub(super) fn follow_pause(&mut self, q: R) -> Result<bool, super::Fault> {
        // Not as a stopping bead: its last segment is not cut short where the flow ends.
        if self.follow_path(false, q)? {
            return Ok(true);
        }
        if matches!(self.phase, Phase::Pausing) && self.rest_reached(q) && self.acted_shut() {
            self.phase = Phase::Paused { on_bead: true };
            self.record_rest(false);
            self.park_at_rest();
        }
        Ok(false)
    }

    /// The flow under which the head is at rest for a pause asked now: `REST_SHARE` of
    /// the flow now, within `REST_FLOOR` of the stop threshold and the threshold itself
    /// (0.5 % of top flow: a bead printing at half the top flow would otherwise rest with
    /// the plant still giving 1 % of its flow).
    fn rest_flow(&self) -> R {
        let q_stop = self.machine.q_stop;
        (R::of(REST_SHARE) * self.model.q())
            .min(q_stop)
            .max(R::of(REST_FLOOR) * q_stop)
    }

    /// The flow `q` is low enough for the head to rest: under the pause's rest flow, or
    /// under the stop threshold once `REST_WAIT_S` have passed since the request. A bead
    /// that ends with a pause requested settles to this too, so a pause at a bead's end
    /// rests as low as one mid-bead.
    #[inline(never)]
    pub(super) fn rest_reached(&self, q: R) -> bool {
        if q <= self.pause.q_rest {
            return true;
        }
        let since = self
            .pause
            .info
            .map_or(0, |i| self.cycle.saturating_sub(i.requested_cycle));
        let wait = (R::of(REST_WAIT_S) / self.dt).round_i64().max(0) as u64;
        q <= self.machine.q_stop && since > wait
    }

    /// A bound on the tail's volume from now, before any prediction: the fastest flow
    /// for the slowest line's close dead time plus its decay's whole volume (an
    /// exponential's, `q tau`; a shear-thinning paste's `q n tau` is less). A syringe's
    /// lag has no such short form: the lead window bounds it.
    fn tail_bound(&self) -> Vol {
        let m = &self.machine;
        if m.syringes {
            return self.window;
        }
        let mut t = R::ZERO;
        for i in m.inlets.iter() {
            t = t.max(i.close_delay_s + i.decay_s);
        }
        let q = m.v_flow_max * m.bead_area;
        Vol::from_mm3(q * t * R::of(TAIL_MARGIN) + self.bead_s() * R::of(TAIL_SLACK_MM))
    }

    /// True when no other inlet can take the junction back while inlet `m`'s tail runs
    /// out: another syringe's lag still to settle, or another line holding pressure
    /// that decays more slowly than `m`'s (the junction sits at the highest pressure).
    fn others_spent(&self, m: u8) -> bool {
        let m = m as usize;
        let s = self.bead_s();
        let sliver = s * R::of(SLIVER_MM);
        let resp = self.model.responses();
        for (i, p) in self.model.plungers().iter().enumerate() {
            if i != m && resp.get(i).is_some_and(|r| p.remaining(r) > sliver) {
                return false;
            }
        }
        let (lines, params) = (self.model.lines(), self.model.params());
        let (Some(own), Some(own_p)) = (lines.get(m), params.get(m)) else {
            return true;
        };
        lines
            .iter()
            .zip(params.iter())
            .enumerate()
            .all(|(i, (l, p))| {
                i == m || p.tau_decay <= own_p.tau_decay || l.p <= own.p * R::of(OTHER_LINE_SHARE)
            })
    }

    /// Every valve has acted shut (its close dead time is over) and no plunger runs: from
    /// here the flow only decays.
    fn acted_shut(&self) -> bool {
        if self.model.syringes() {
            // A syringe machine's model steps its plungers only, never its lines.
            return self.model.plungers().iter().all(|p| !p.running);
        }
        self.model
            .lines()
            .iter()
            .all(|l| !l.open && l.pending.is_empty())
    }

    /// A requested pause taking effect between beads (a bead's end settles to the pause's
    /// rest flow first: see `rest_reached`).
    pub(super) fn pause_between_beads(&mut self) {
        self.phase = Phase::Paused { on_bead: false };
        self.record_rest(true);
        self.park_at_rest();
    }

    fn record_rest(&mut self, at_bead_end: bool) {
        let (cycle, head) = (self.cycle, self.head);
        let p = self.head_pos;
        if let Some(i) = self.pause.info.as_mut() {
            i.shut_cycle.get_or_insert(cycle);
            i.rest_cycle = Some(cycle);
            i.point = Some(head);
            i.at_bead_end = at_bead_end;
            i.position_um = [
                (p[0] * R::of(1e3)).round_i32(),
                (p[1] * R::of(1e3)).round_i32(),
                (p[2] * R::of(1e3)).round_i32(),
            ];
        }
    }
}
