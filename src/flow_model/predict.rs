//! Look-ahead of the flow model: "if the valves were set to X now, how much would flow
//! before the new material starts entering the channel (a switch), or before the flow dies
//! out (a stop)?". It integrates a copy of the lines and channel content forward in chunks
//! of up to `MAX_CHUNK` cycles, and is resumable so each control cycle spends a bounded
//! budget on it. Deciding when to act on the answer is the executor's job.

use super::lines::Line;
use super::{solve, FlowModel, MAX_CHUNK};
use crate::real::Real;

/// What to predict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Goal {
    /// Open only this inlet now: volume until it feeds the channel.
    Switch(u8),
    /// Close every valve now: volume until the flow has died out.
    Stop,
}

/// A finished prediction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome<R> {
    /// Volume (mm^3) that flows from the command until the goal is reached.
    Volume(R),
    /// The goal is not reached within the horizon (e.g. the new line never overtakes).
    Never,
}

/// Upcoming exit changes the prediction follows.
const EXITS: usize = 6;
/// Horizon, in cycles, after which a prediction gives up (5 s at 10 kHz).
const HORIZON_CYCLES: u64 = 50_000;

/// A prediction in progress.
#[derive(Clone, Debug)]
pub struct Prediction<R, const N: usize> {
    goal: Goal,
    lines: heapless::Vec<Line<R>, N>,
    vin: [R; N],
    exits: [(R, u8); EXITS],
    n_exits: usize,
    exit_next: usize,
    exit_material: u8,
    exit_pos: R,
    start: u64,
    k: u64,
    vol: R,
    q: R,
    p_scale: R,
}

impl<R: Real, const N: usize> Prediction<R, N> {
    /// Starts predicting `goal` as if commanded before the model's next cycle.
    pub fn start(model: &FlowModel<R, N>, goal: Goal) -> Self {
        let mut lines: heapless::Vec<Line<R>, N> = heapless::Vec::new();
        let mask = match goal {
            Goal::Switch(to) => 1u32 << to,
            Goal::Stop => 0,
        };
        let next = model.next_cycle();
        let mut p_scale = R::ZERO;
        for (i, (l, p)) in model.lines().iter().zip(model.params()).enumerate() {
            let mut c = l.clone();
            c.command(mask & (1 << i) != 0, next, p);
            p_scale = p_scale.max(p.supply).max(l.p);
            let _ = lines.push(c);
        }
        let mut raw = [(crate::vol::Vol::ZERO, 0u8); EXITS];
        let n_exits = model.channel().exit_changes(&mut raw);
        let mut exits = [(R::ZERO, 0u8); EXITS];
        for (e, r) in exits.iter_mut().zip(raw.iter()).take(n_exits) {
            *e = (r.0.mm3(), r.1);
        }
        Prediction {
            goal,
            lines,
            vin: model.vin(),
            exits,
            n_exits,
            exit_next: 0,
            exit_material: model.channel().at_exit(),
            exit_pos: R::ZERO,
            start: next,
            k: next,
            vol: R::ZERO,
            q: model.q(),
            p_scale,
        }
    }

    /// What this prediction is for.
    pub fn goal(&self) -> Goal {
        self.goal
    }
    /// Cycle at which the hypothetical command is given.
    pub fn start_cycle(&self) -> u64 {
        self.start
    }

    /// Integrates at most `budget` chunks; `Some` once finished.
    pub fn advance(&mut self, model: &FlowModel<R, N>, budget: u32) -> Option<Outcome<R>> {
        let params = model.params();
        let powers = model.powers();
        let dt = model.dt();
        for _ in 0..budget {
            if self.k - self.start > HORIZON_CYCLES {
                return Some(Outcome::Never);
            }
            // Changes act at chunk starts: end the chunk before the next pending one.
            let mut j = MAX_CHUNK as u64;
            let mut any_open = false;
            for l in self.lines.iter_mut() {
                l.apply_due(self.k);
                if let Some(&(t, _)) = l.pending.front() {
                    j = j.min(t - self.k);
                }
                any_open |= l.open || l.pending.iter().any(|&(_, o)| o);
            }
            let j = j.max(1) as usize;
            // Where the goal's line already leads right after the changes, and nothing can
            // overtake it any more, it feeds from now on.
            if let Goal::Switch(to) = self.goal {
                let (lead, other) = self.lead_margin(to as usize, params, true);
                if lead > R::ZERO && lead >= other && self.settled(to as usize) {
                    return Some(Outcome::Volume(self.vol));
                }
            }
            let start_margin = match self.goal {
                Goal::Switch(to) => {
                    let (lead, other) = self.lead_margin(to as usize, params, false);
                    other - lead
                }
                Goal::Stop => R::ZERO,
            };
            // Integrate every line over j cycles.
            let span = dt * R::of(j as f64);
            let mut best: Option<(usize, R)> = None;
            let mut p_max = R::ZERO;
            for (i, l) in self.lines.iter_mut().enumerate() {
                let (g, tau, _) = params[i].drive(l.open);
                let decay = powers[i][if l.open { 0 } else { 1 }][j];
                let gap = l.p - g;
                let imp = g * span + gap * tau * (R::ONE - decay);
                l.p = g + gap * decay;
                p_max = p_max.max(l.p);
                if imp > R::ZERO && best.is_none_or(|(_, b)| imp > b) {
                    best = Some((i, imp));
                }
            }
            let dv = match best {
                Some((f, imp)) => self.chunk_volume(model, f, imp, span),
                None => R::ZERO,
            };
            self.k += j as u64;
            if let Goal::Switch(to) = self.goal {
                let (lead, other) = self.lead_margin(to as usize, params, false);
                let end_margin = other - lead;
                if end_margin <= R::ZERO && lead > R::ZERO && self.settled(to as usize) {
                    // Crossed inside the chunk: interpolate the pressure difference.
                    let f = if start_margin > end_margin {
                        (start_margin / (start_margin - end_margin)).min(R::ONE).max(R::ZERO)
                    } else {
                        R::ZERO
                    };
                    return Some(Outcome::Volume(self.vol + f * dv));
                }
            }
            if let Some((f, _)) = best {
                self.take(f as u8, dv);
            }
            self.q = dv / span;
            self.vol += dv;
            if self.goal == Goal::Stop && !any_open && p_max <= self.p_scale * R::of(0.01) {
                // What is left decays like the line: about q * tau more.
                let tail = match best {
                    Some((f, _)) => dv / span * params[f].tau_decay,
                    None => R::ZERO,
                };
                return Some(Outcome::Volume(self.vol + tail));
            }
        }
        None
    }

    /// True once the goal's valve acts open and every other one acts closed with nothing
    /// pending: the goal's line then only rises and the others only fall, so a lead it
    /// takes is for good. Before that, an old switch still in its dead time may flip the
    /// junction once more (A -> B -> A within a few dead times).
    fn settled(&self, to: usize) -> bool {
        self.lines.iter().enumerate().all(|(i, l)| {
            let pending_open = l.pending.iter().any(|&(_, o)| o);
            if i == to {
                l.open && l.pending.is_empty()
            } else {
                !l.open && !pending_open
            }
        })
    }

    /// (goal line's pressure, highest other line's pressure); `instant` gives the values
    /// right after this cycle's changes acted (instant lines jump).
    fn lead_margin(&self, to: usize, params: &[super::lines::LineParams<R>], instant: bool) -> (R, R) {
        let mut lead = R::ZERO;
        let mut other = R::ZERO;
        for (i, l) in self.lines.iter().enumerate() {
            let p = if instant { l.p_now(&params[i]) } else { l.p };
            if i == to {
                lead = p;
            } else {
                other = other.max(p);
            }
        }
        (lead, other)
    }

    /// Volume through the channel over a chunk with pressure impulse `imp`.
    fn chunk_volume(&self, model: &FlowModel<R, N>, feeding: usize, imp: R, span: R) -> R {
        let laws = model.laws();
        if model.all_linear() {
            let mut r0 = R::ZERO;
            for (law, &v) in laws.iter().zip(self.vin.iter()) {
                r0 += law.a * v;
            }
            let k = laws[feeding].a - laws[self.exit_material as usize].a;
            let disc = (r0 * r0 + R::TWO * k * imp).max(R::ZERO);
            R::TWO * imp / (r0 + disc.sqrt())
        } else {
            solve::flow(laws, &self.vin, imp / span, self.q) * span
        }
    }

    /// Moves `dv` of `feeding` into the channel copy and as much out at the exit.
    fn take(&mut self, feeding: u8, dv: R) {
        if dv <= R::ZERO {
            return;
        }
        if let Some(v) = self.vin.get_mut(feeding as usize) {
            *v += dv;
        }
        let mut left = dv;
        // Bounded: each pass either finishes or passes one of at most EXITS changes.
        for _ in 0..=EXITS {
            let room = if self.exit_next < self.n_exits {
                self.exits[self.exit_next].0 - self.exit_pos
            } else {
                left
            };
            let used = left.min(room.max(R::ZERO));
            if let Some(v) = self.vin.get_mut(self.exit_material as usize) {
                *v = (*v - used).max(R::ZERO);
            }
            self.exit_pos += used;
            left -= used;
            if left <= R::ZERO {
                break;
            }
            self.exit_material = self.exits[self.exit_next].1;
            self.exit_next += 1;
        }
    }
}
