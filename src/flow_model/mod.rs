//! The flow model: inlet lines (dead time, pressure rise/decay), the junction (the highest
//! line pressure feeds the channel), and the channel of slugs whose resistance sets the
//! flow. One `step` per control cycle gives the volume that left the nozzle. It knows
//! nothing of the head or the job; the executor turns volume into motion.

pub mod channel;
pub mod lag_fit;
pub mod lines;
pub mod predict;
pub mod solve;
pub mod syringe;

use crate::config::Machine;
use crate::real::Real;
use crate::rheology::FlowLaw;
use crate::vol::Vol;
use channel::{Channel, ChannelFull};
use lines::{Line, LineParams};
use syringe::{Plunger, Response};

/// Longest stretch, in cycles, that the predictor integrates in one piece.
pub const MAX_CHUNK: usize = 64;

/// Volume V with `r0 V + k V^2 / 2 = impulse`: Newtonian content whose resistance changes
/// by k per mm^3 that passes. In the cancellation-free form
/// `V = 2 impulse / (r0 + sqrt(r0^2 + 2 k impulse))`; where `x = 2 k impulse / r0^2` is
/// tiny (always within one control cycle) the series `impulse / r0 * (1 - x/4 + x^2/8 -
/// 5 x^3 / 64)` gives the same to under 3e-10 relative without a square root, which is
/// software on the M4F.
#[inline]
pub fn volume_for_impulse<R: Real>(r0: R, k: R, impulse: R) -> R {
    if r0 <= R::ZERO {
        return R::ZERO;
    }
    let base = impulse / r0;
    let x = R::TWO * k * base / r0;
    if x.abs() < R::of(0.01) {
        base * (R::ONE - x * (R::of(0.25) - x * (R::of(0.125) - x * R::of(5.0 / 64.0))))
    } else {
        let disc = (r0 * r0 + R::TWO * k * impulse).max(R::ZERO);
        R::TWO * impulse / (r0 + disc.sqrt())
    }
}

/// What one control cycle did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleFlow<R> {
    /// Volume that entered the channel (= left the nozzle = landed: plug flow).
    pub dv: Vol,
    /// Mean flow over the cycle, mm^3/s.
    pub q: R,
    /// Inlet that fed the channel, if anything flowed.
    pub feeding: Option<u8>,
    /// Material changes that landed on the plate during the cycle.
    pub landed_changes: u32,
}

/// Powers `(1 - alpha)^j` of a line's per-cycle decay factor, j = 0..=MAX_CHUNK, for the
/// rise (index 0) and decay (index 1) time constants.
pub type Powers<R> = [[R; MAX_CHUNK + 1]; 2];

/// The model of valves, lines and channel, stepped once per control cycle of `dt`.
#[derive(Clone, Debug)]
pub struct FlowModel<R, const N: usize> {
    params: heapless::Vec<LineParams<R>, N>,
    powers: heapless::Vec<Powers<R>, N>,
    lines: heapless::Vec<Line<R>, N>,
    laws: heapless::Vec<FlowLaw<R>, N>,
    channel: Channel<N>,
    dt: R,
    /// 1 / dt: divisions take 14 cycles on the M4F, multiplications one.
    inv_dt: R,
    next: u64,
    q: R,
    /// The solve's last two answers (unrounded: a tail too weak to move one volume unit a
    /// cycle still warm-starts the next solve), for the extrapolated warm start.
    solved: [R; 2],
    feeding: Option<u8>,
    all_linear: bool,
    commanded: u32,
    /// Syringe inlets (empty for a pneumatic machine): response tables and plungers.
    responses: heapless::Vec<Response<R>, N>,
    plungers: heapless::Vec<Plunger<R>, N>,
    rates: [R; N],
}

impl<R: Real, const N: usize> FlowModel<R, N> {
    /// A model of no machine (no inlets, no channel); `reset` gives it one. A constant
    /// constructor: the board builds its model at compile time, in a static.
    pub const fn unconfigured() -> Self {
        FlowModel {
            params: heapless::Vec::new(),
            powers: heapless::Vec::new(),
            lines: heapless::Vec::new(),
            laws: heapless::Vec::new(),
            channel: Channel::empty(),
            dt: R::ZERO,
            inv_dt: R::ZERO,
            next: 0,
            q: R::ZERO,
            solved: [R::ZERO; 2],
            feeding: None,
            all_linear: false,
            commanded: 0,
            responses: heapless::Vec::new(),
            plungers: heapless::Vec::new(),
            rates: [R::ZERO; N],
        }
    }

    /// A model at rest: valves shut, lines vented, channel and filament full of `material`.
    pub fn new(machine: &Machine<R, N>, material: u8) -> Self {
        let mut m = Self::unconfigured();
        m.reset(machine, material);
        m
    }

    /// Makes this the model `new(machine, material)` builds, in place: the model is 12 KiB
    /// (f32, four inlets), which the board's control interrupt must not build on its stack
    /// and move.
    pub fn reset(&mut self, machine: &Machine<R, N>, material: u8) {
        self.configure(machine);
        self.restart(machine, material);
    }

    /// What depends on the machine only: line parameters and decay powers, flow laws,
    /// syringe response tables and rates.
    fn configure(&mut self, machine: &Machine<R, N>) {
        let dt = machine.dt();
        self.params.clear();
        self.powers.clear();
        self.laws.clear();
        self.responses.clear();
        self.rates = [R::ZERO; N];
        self.all_linear = true;
        for (i, inlet) in machine.inlets.iter().enumerate() {
            if let Some(sy) = inlet.syringe.filter(|_| machine.syringes) {
                // Capacities equal the machine's, so these pushes cannot fail.
                if self.responses.push(Response::EMPTY).is_ok() {
                    if let Some(r) = self.responses.last_mut() {
                        r.fill(
                            sy.lag_k.to_f64(),
                            sy.lag_n.to_f64(),
                            machine.period_us as f64 * 1e-6,
                        );
                    }
                }
                self.rates[i] = sy.rate;
            }
            let p = LineParams::new(inlet, dt);
            if self.powers.push([[R::ONE; MAX_CHUNK + 1]; 2]).is_ok() {
                if let Some(pw) = self.powers.last_mut() {
                    for (row, a) in [p.alpha_rise, p.alpha_decay].into_iter().enumerate() {
                        for j in 1..=MAX_CHUNK {
                            pw[row][j] = pw[row][j - 1] * (R::ONE - a);
                        }
                    }
                }
            }
            let _ = self.params.push(p);
            let _ = self.laws.push(inlet.law);
            self.all_linear &= inlet.law.linear;
        }
        self.dt = dt;
        self.inv_dt = R::ONE / dt;
    }

    /// Back to rest for a new job on the same machine: valves shut, lines vented, plungers
    /// still, channel and filament full of `material`. Keeps what `configure` worked out
    /// (the syringe tables above all), so a job starts in a few microseconds.
    pub fn restart(&mut self, machine: &Machine<R, N>, material: u8) {
        self.lines.clear();
        self.plungers.clear();
        for _ in machine.inlets.iter() {
            let _ = self.lines.push(Line::default());
        }
        for _ in self.responses.iter() {
            let _ = self.plungers.push(Plunger::IDLE);
        }
        self.channel
            .refill(material, machine.v_channel, machine.v_hang);
        self.next = 0;
        self.q = R::ZERO;
        self.solved = [R::ZERO; 2];
        self.feeding = None;
        self.commanded = 0;
    }

    /// Commands the valves: bit i of `mask` opens inlet i. Acts after each valve's dead
    /// time, counted from the start of the next cycle.
    pub fn command(&mut self, mask: u32) {
        let mut m = 0;
        for (i, (line, p)) in self.lines.iter_mut().zip(self.params.iter()).enumerate() {
            line.command(mask & (1 << i) != 0, self.next, p);
            if line.commanded {
                m |= 1 << i;
            }
        }
        // A syringe's plunger starts or stops with the next cycle; its lag is in the cascade.
        for (i, pl) in self.plungers.iter_mut().enumerate() {
            pl.command(mask & (1 << i) != 0, self.rates[i]);
        }
        self.commanded = m;
    }

    /// True for a machine of syringe inlets.
    pub fn syringes(&self) -> bool {
        !self.plungers.is_empty()
    }
    /// Syringe response tables (empty when pneumatic).
    pub fn responses(&self) -> &[Response<R>] {
        &self.responses
    }
    /// Syringe plungers (empty when pneumatic).
    pub fn plungers(&self) -> &[Plunger<R>] {
        &self.plungers
    }
    /// Plunger rate of each syringe inlet while it feeds, mm^3/s.
    pub fn rates(&self) -> &[R; N] {
        &self.rates
    }

    /// One cycle of a syringe machine: every plunger's outflow at mid-cycle; the largest
    /// feeds the channel (a mixed zone is attributed to whichever supplies more).
    fn step_syringes(&mut self) -> Result<CycleFlow<R>, ChannelFull> {
        self.next += 1;
        let dt = self.dt;
        let mut total = R::ZERO;
        let mut best: Option<(usize, R)> = None;
        for (i, (pl, resp)) in self
            .plungers
            .iter_mut()
            .zip(self.responses.iter())
            .enumerate()
        {
            let q = pl.flow_mid(resp);
            total += q;
            if q > R::ZERO && best.is_none_or(|(_, b)| q > b) {
                best = Some((i, q));
            }
        }
        let dv = Vol::from_mm3(total * dt);
        let mut changes = 0;
        if let (Some((f, _)), true) = (best, dv.0 > 0) {
            self.channel.feed(f as u8)?;
            changes = self.channel.advance(dv);
            self.feeding = Some(f as u8);
        }
        self.q = dv.mm3::<R>() * self.inv_dt;
        Ok(CycleFlow {
            dv,
            q: self.q,
            feeding: best.map(|b| b.0 as u8),
            landed_changes: changes,
        })
    }

    /// True when the last step moved a slug start past the channel exit or onto the
    /// plate: the step's slow path, which the executor does not pile prediction work on.
    #[inline]
    pub fn crossed(&self) -> bool {
        self.channel.crossed()
    }

    /// The valve mask last commanded.
    #[inline]
    pub fn commanded(&self) -> u32 {
        self.commanded
    }

    /// Integrates one control cycle.
    pub fn step(&mut self) -> Result<CycleFlow<R>, ChannelFull> {
        self.channel.clear_crossed();
        if !self.plungers.is_empty() {
            return self.step_syringes();
        }
        let k = self.next;
        self.next += 1;
        let dt = self.dt;
        let mut best: Option<(usize, R)> = None;
        for (i, (line, p)) in self.lines.iter_mut().zip(self.params.iter()).enumerate() {
            line.apply_due(k);
            let imp = line.step(dt, p);
            let better = match best {
                None => imp > R::ZERO,
                Some((b, bi)) => imp > bi || (imp == bi && Some(i as u8) == self.feeding && b != i),
            };
            if better {
                best = Some((i, imp));
            }
        }
        let Some((f, impulse)) = best else {
            self.solved = [R::ZERO; 2];
            self.q = R::ZERO;
            return Ok(CycleFlow {
                dv: Vol::ZERO,
                q: R::ZERO,
                feeding: None,
                landed_changes: 0,
            });
        };
        let (dv, changes) = if self.all_linear {
            self.advance_linear(f, impulse)?
        } else {
            let vin = self.vin();
            // Warm start on the line through the last two flows: the flow changes smoothly
            // between content changes, so the guess is off by second-order terms only.
            let [last, before] = self.solved;
            let trend = last + (last - before);
            let guess = if trend > R::ZERO { trend } else { last };
            let q = solve::flow_step(&self.laws, &vin, impulse * self.inv_dt, guess);
            self.solved = [q, last];
            let dv = Vol::from_mm3(q * dt);
            if dv.0 > 0 {
                self.channel.feed(f as u8)?;
                (dv, self.channel.advance(dv))
            } else {
                (Vol::ZERO, 0)
            }
        };
        if dv.0 > 0 {
            self.feeding = Some(f as u8);
        }
        self.q = dv.mm3::<R>() * self.inv_dt;
        Ok(CycleFlow {
            dv,
            q: self.q,
            feeding: Some(f as u8),
            landed_changes: changes,
        })
    }

    /// Exact volume for Newtonian content: with R(V) = R0 + kV between exit changes,
    /// `R0 V + k V^2 / 2 = impulse`, solved in the cancellation-free form
    /// `V = 2 impulse / (R0 + sqrt(R0^2 + 2 k impulse))`.
    fn advance_linear(
        &mut self,
        feeding: usize,
        mut impulse: R,
    ) -> Result<(Vol, u32), ChannelFull> {
        let mut total = Vol::ZERO;
        let mut changes = 0;
        let a_in = self.laws[feeding].a;
        // Resistance grows by k per mm^3 that passes: summed once, then kept up to date.
        let mut r0 = self.resistance_linear();
        // Each pass crosses one slug boundary at the exit; bounded by the slug count.
        for pass in 0..=channel::SLUG_CAPACITY {
            let k = a_in - self.laws[self.channel.at_exit() as usize].a;
            let dv = volume_for_impulse(r0, k, impulse);
            let d = Vol::from_mm3(dv);
            if pass == 0 {
                // A slug starts only when something actually enters.
                if d.0 <= 0 {
                    return Ok((Vol::ZERO, 0));
                }
                self.channel.feed(feeding as u8)?;
            }
            // No slug start reaches the exit or the plate (nearly every cycle): the
            // exit's room is past `d` then, without working it out.
            if self.channel.clear_for(d) {
                changes += self.channel.advance(d);
                total += d;
                break;
            }
            match self.channel.exit_room() {
                Some(room) if d > room && room.0 > 0 => {
                    let rm: R = room.mm3();
                    impulse -= r0 * rm + k * rm * rm * R::HALF;
                    r0 += k * rm;
                    changes += self.channel.advance(room);
                    total += room;
                }
                _ => {
                    changes += self.channel.advance(d);
                    total += d;
                    break;
                }
            }
        }
        Ok((total, changes))
    }

    /// Channel resistance when all content is Newtonian, Pa s / mm^3.
    #[inline]
    pub fn resistance_linear(&self) -> R {
        let mut r = R::ZERO;
        for (law, v) in self.laws.iter().zip(self.channel.in_channel().iter()) {
            if v.0 != 0 {
                r += law.a * v.mm3::<R>();
            }
        }
        r
    }

    /// Per-material volume in the channel, mm^3.
    pub fn vin(&self) -> [R; N] {
        let mut out = [R::ZERO; N];
        self.vin_into(&mut out);
        out
    }

    /// `vin` written in place: the machine's inlets only (the rest of the capacity holds
    /// nothing and `out` keeps what it had there), without a copy of the array.
    pub fn vin_into(&self, out: &mut [R; N]) {
        let inlets = self.laws.len();
        for (o, v) in out[..inlets]
            .iter_mut()
            .zip(&self.channel.in_channel()[..inlets])
        {
            *o = v.mm3();
        }
    }

    /// Instantaneous flow at the current line pressures and channel content (or the
    /// syringes' outflow), mm^3/s.
    pub fn flow_now(&self) -> R {
        if !self.plungers.is_empty() {
            return self
                .plungers
                .iter()
                .map(|p| p.flow_now())
                .fold(R::ZERO, |a, b| a + b);
        }
        let p = self.junction_pa();
        if p <= R::ZERO {
            return R::ZERO;
        }
        let vin = self.vin();
        solve::flow(&self.laws, &vin, p, self.q)
    }

    /// Highest line pressure: the junction's, Pa.
    pub fn junction_pa(&self) -> R {
        let mut p = R::ZERO;
        for l in self.lines.iter() {
            p = p.max(l.p);
        }
        p
    }

    /// Mean flow over the last cycle, mm^3/s.
    pub fn q(&self) -> R {
        self.q
    }
    /// The channel and filament.
    pub fn channel(&self) -> &Channel<N> {
        &self.channel
    }
    /// Inlet lines.
    pub fn lines(&self) -> &[Line<R>] {
        &self.lines
    }
    /// Per-line constants.
    pub fn params(&self) -> &[LineParams<R>] {
        &self.params
    }
    /// Per-line powers of the decay factors.
    pub fn powers(&self) -> &[Powers<R>] {
        &self.powers
    }
    /// Flow laws per inlet.
    pub fn laws(&self) -> &[FlowLaw<R>] {
        &self.laws
    }
    /// True when every material is Newtonian.
    pub fn all_linear(&self) -> bool {
        self.all_linear
    }
    /// Index of the next cycle to integrate.
    pub fn next_cycle(&self) -> u64 {
        self.next
    }
    /// Cycle length, s.
    pub fn dt(&self) -> R {
        self.dt
    }
    /// Cycles per second.
    pub fn inv_dt(&self) -> R {
        self.inv_dt
    }
    /// Inlet that fed the channel last.
    pub fn feeding(&self) -> Option<u8> {
        self.feeding
    }
    /// True while some valve is open or a line still holds pressure above `p_min`.
    pub fn active(&self, p_min: R) -> bool {
        self.plungers.iter().any(|p| p.running || p.settling())
            || self
                .lines
                .iter()
                .any(|l| l.open || l.commanded || !l.pending.is_empty() || l.p > p_min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_and_square_root_forms_agree() {
        for &(r0, k, imp) in &[
            (336.6f64, 348.0, 0.32),
            (336.6, -250.0, 0.32),
            (336.6, 0.0, 0.32),
            (33.6, 3480.0, 3.2),
            (100.0, -1.0e4, 0.4),
        ] {
            let exact = 2.0 * imp / (r0 + (r0 * r0 + 2.0 * k * imp).sqrt());
            let v = volume_for_impulse(r0, k, imp);
            assert!(
                ((v - exact) / exact).abs() < 3e-10,
                "{r0} {k} {imp}: {v} vs {exact}"
            );
        }
    }
}
