//! Valve decisions while printing: the switch and stop predictions (`Tracker`), the
//! cursor that runs ahead of the head by the lead window, and the valve outputs. Stops at
//! the decision: the flow model carries it out, and `sizing` sizes its ramp window.

use super::{cycles32, Executor, Phase, PREDICT_BUDGET, PREDICT_INTERVAL};
use crate::config::Machine;
use crate::flow_model::predict::{Goal, Outcome, Prediction};
use crate::flow_model::FlowModel;
use crate::outputs::Outputs;
use crate::real::Real;
use crate::state::Fault;
use crate::vol::Vol;

/// Tracks predictions of one kind and extrapolates their answer to the present.
#[derive(Clone, Debug)]
pub(super) struct Tracker<R, const N: usize> {
    goal: Option<Goal>,
    pred: Prediction<R, N>,
    running: bool,
    last: Option<(u64, R)>,
    prev: Option<(u64, R)>,
    /// Change of the answer per cycle between the last two predictions (0 with one).
    slope: R,
    /// Until this cycle the flow is what valve commands already made (a switch's: their
    /// dead time): a lone prediction's answer falls by the flow since it started.
    committed_until: u64,
}

impl<R: Real, const N: usize> Tracker<R, N> {
    pub(super) const fn new() -> Self {
        Tracker {
            goal: None,
            pred: Prediction::new(),
            running: false,
            last: None,
            prev: None,
            slope: R::ZERO,
            committed_until: 0,
        }
    }
    /// Forgets everything; field by field, as moving the prediction is dearer than this.
    pub(super) fn reset(&mut self) {
        self.goal = None;
        self.running = false;
        self.last = None;
        self.prev = None;
        self.slope = R::ZERO;
        self.committed_until = 0;
    }

    /// `reset` after a valve command that takes effect only `until` (a cycle): till
    /// then the flow, and so a stop's tail counted from now, is the commands' already.
    pub(super) fn reset_committed(&mut self, until: u64) {
        self.reset();
        self.committed_until = until;
    }

    /// The current answer for `goal`: the last two predictions extrapolated to the
    /// present (a new goal forgets the old one's).
    pub(super) fn answer(&mut self, model: &FlowModel<R, N>, goal: Goal) -> Option<R> {
        if self.goal != Some(goal) {
            // A switch's dead time outlasts the goal's change (`reset_committed`).
            let until = self.committed_until;
            self.reset();
            self.committed_until = until;
            self.goal = Some(goal);
        }
        let (t1, v1) = self.last?;
        // A lead changes because time passes; it cannot change faster than the flow
        // itself, which bounds a slope taken across a jump in the state.
        let cap = model.q() * model.dt();
        let now = model.next_cycle();
        if self.prev.is_none() && t1 < self.committed_until {
            // One prediction since a switch, started within its dead time: what flowed
            // since was already on its way, and the tail from now is that much less
            // (taken as no change, the priming line's stop 3.5 ms after a switch came
            // 0.025 mm^3 early, and the random cells' first two boundaries, still in the
            // channel then, landed 0.050 and 0.113 mm late; 0.004 and 0.000 now).
            let gone = R::from_u32(cycles32(now.min(self.committed_until) - t1));
            return Some((v1 - cap * gone).max(R::ZERO));
        }
        let slope = self.slope.max(-cap).min(cap);
        let since = R::from_u32(cycles32(now - t1));
        Some((v1 + slope * since).max(R::ZERO))
    }

    /// One unit of work (a restart or half a chunk) on the goal of the last `answer`.
    /// Done after the cycle's decision, so a cycle that acts on an answer (and so forgets
    /// the prediction) spends nothing on it.
    pub(super) fn work(&mut self, model: &FlowModel<R, N>) {
        let Some(goal) = self.goal else { return };
        let now = model.next_cycle();
        if !self.running && self.last.is_none_or(|(t, _)| now >= t + PREDICT_INTERVAL) {
            self.pred.restart(model, goal);
            self.running = true;
        } else if self.running {
            if let Some(outcome) = self.pred.advance(model, PREDICT_BUDGET) {
                self.running = false;
                let at = self.pred.start_cycle();
                match outcome {
                    Outcome::Volume(v) => {
                        self.prev = self.last;
                        self.last = Some((at, v));
                        // The slope between the last two answers, worked out once here
                        // rather than in every cycle's `answer`.
                        self.slope = match self.prev {
                            Some((t0, v0)) if at > t0 => (v - v0) / R::from_u32(cycles32(at - t0)),
                            _ => R::ZERO,
                        };
                    }
                    Outcome::Never => {
                        self.prev = None;
                        self.last = None;
                        self.slope = R::ZERO;
                    }
                }
            }
        }
    }
}

impl<R: Real, const N: usize> Executor<R, N> {
    /// Valves as decided.
    #[inline(always)]
    pub(super) fn set_valves(&mut self, mask: u32, out: &mut impl Outputs) {
        if mask != self.valves_out {
            for i in 0..self.machine.inlet_count() {
                let bit = 1u32 << i;
                if (mask ^ self.valves_out) & bit != 0 {
                    out.valve(i as u8, mask & bit != 0);
                }
            }
            self.valves_out = mask;
        }
    }

    /// Valve decisions while printing: switch material when the cursor (head + transit
    /// volume + predicted switch lead) reaches the next boundary; stop the flow when the
    /// head plus the predicted tail reaches the bead's end.
    pub(super) fn decide_valves(&mut self) -> Result<(), Fault> {
        if !matches!(self.phase, Phase::Print { .. }) {
            return Ok(());
        }
        let entry = self.head + self.machine.v_transit();
        // Of several boundaries already behind the cursor only the last still matters.
        // They are in plan order, so while the first is ahead none is behind (the usual
        // case, checked without walking the queue).
        while self.boundaries.front().is_some_and(|b| b.0 <= entry)
            && self.boundaries.iter().nth(1).is_some_and(|b| b.0 <= entry)
        {
            self.boundaries.pop_front();
        }
        if let Some(known) = self.known_to {
            if known < entry + self.window {
                return Err(if self.room() == 0 {
                    Fault::LookaheadFull
                } else {
                    Fault::Underrun
                });
            }
        }
        // Material switch.
        let mut switched = false;
        if let Some(&(u_b, m)) = self.boundaries.front() {
            if m == self.entry_material {
                // Already the material entering: nothing to switch.
                if entry >= u_b {
                    self.boundaries.pop_front();
                }
            } else if entry + self.window >= u_b
                && !matches!(self.phase, Phase::Print { stopping: true })
            {
                // Not while the bead's stop runs out: its valves are shut, and a switch
                // would reopen one (the tail ran on to a second stop) for a paste that
                // enters only when the next bead opens it (`Executor::open_bead`).
                // Behind the cursor already (job start, or a lead the prediction missed):
                // switch at once; otherwise when the predicted lead says so.
                let due = entry >= u_b
                    || self
                        .switch
                        .answer(&self.model, Goal::Switch(m))
                        .is_some_and(|lead| entry + Vol::from_mm3(lead) >= u_b);
                if !due && self.work(0) {
                    self.switch.work(&self.model);
                }
                if due {
                    if self.sizing {
                        self.size_ramp(Some(m));
                    }
                    self.model.command(1 << m);
                    self.want = Some(m);
                    self.entry_material = m;
                    self.boundaries.pop_front();
                    self.switch.reset();
                    // The opening line's dead time, in cycles as the model keeps it.
                    let dead = self
                        .model
                        .params()
                        .get(m as usize)
                        .map_or(0, |p| p.open_delay);
                    self.stop
                        .reset_committed(self.model.next_cycle() + dead as u64);
                    switched = true;
                }
            }
        }
        // End of the bead.
        if let Some(end) = self.bead_end() {
            if self.model.commanded() != 0 && self.head + self.window >= end {
                let due = self
                    .stop
                    .answer(&self.model, Goal::Stop)
                    .is_some_and(|tail| self.head + Vol::from_mm3(tail) >= end);
                if due {
                    if self.sizing {
                        self.size_ramp(None);
                    }
                    self.model.command(0);
                    self.want = None;
                    self.phase = Phase::Print { stopping: true };
                    self.stop.reset();
                } else if self.work(1) && !switched {
                    self.stop.work(&self.model);
                }
            }
        }
        Ok(())
    }

    /// Whether prediction work of the kind whose turn falls on cycles of `parity` runs
    /// this cycle. The kinds take turns; a cycle whose flow step took its slow path
    /// (a slug start crossing the exit or landing) does none, nor does one that
    /// commanded a switch or a stop, so that the dearest steps and a prediction unit never
    /// share a cycle. These come a few times per material change, so the predictions lose
    /// a unit or two per switch.
    pub(super) fn work(&self, parity: u64) -> bool {
        self.cycle % 2 == parity && !self.model.crossed()
    }

    /// Plan volume where the current bead ends, if its last segment is planned.
    pub(super) fn bead_end(&self) -> Option<Vol> {
        self.ends.front().copied()
    }
}

/// How far ahead of a boundary (as volume) predictions start: the most that can flow at
/// top speed during the slowest valve's dead time plus eight time constants (or a
/// syringe's time to 90 % response), plus 2 ms.
pub(super) fn lead_window<R: Real, const N: usize>(m: &Machine<R, N>) -> Vol {
    let mut t = R::of(0.002);
    let mut worst = R::ZERO;
    for i in m.inlets.iter() {
        let d = match i.syringe.filter(|_| m.syringes) {
            // A syringe's switch and its tail are over well before 90 % of its response.
            Some(sy) => R::of(libm::pow(
                core::f64::consts::LN_10 / sy.lag_k.to_f64(),
                1.0 / sy.lag_n.to_f64(),
            )),
            None => i.open_delay_s.max(i.close_delay_s) + R::of(8.0) * i.rise_s.max(i.decay_s),
        };
        worst = worst.max(d);
    }
    t += worst;
    Vol::from_mm3(m.v_flow_max * m.bead_area * t)
}
