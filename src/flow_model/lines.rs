//! Inlet lines: each valve's dead time and the first-order rise/decay of its line
//! pressure, stepped exactly over whole control cycles. Which line feeds the channel,
//! and what flows, is decided in `mod.rs`.

use crate::config::Inlet;
use crate::real::Real;
use heapless::Deque;

/// Valve changes a line remembers while their dead time runs. A fifth change within one
/// dead time replaces the oldest pending one (commands that fast cannot be honoured by a
/// real valve either).
pub const PENDING_CAP: usize = 4;

/// Per-line constants for a fixed cycle `dt`.
#[derive(Clone, Copy, Debug)]
pub struct LineParams<R> {
    /// Supply pressure, Pa.
    pub supply: R,
    /// Open dead time in whole cycles (rounded).
    pub open_delay: u32,
    /// Close dead time in whole cycles.
    pub close_delay: u32,
    /// Rise time constant, s.
    pub tau_rise: R,
    /// Decay time constant, s.
    pub tau_decay: R,
    /// Fraction of the gap to the target closed per cycle while open, `1 - exp(-dt/tau)`.
    pub alpha_rise: R,
    /// Same while closed.
    pub alpha_decay: R,
    /// `drive`'s answers, closed (0) and open (1): the cycle's step picks one by the
    /// valve's state with one index instead of three selects. Filled in by `new` (and
    /// `with_drives`, which a caller that changes the fields above calls again).
    drives: [(R, R, R); 2],
}

impl<R: Real> LineParams<R> {
    /// Constants of `inlet` for cycle length `dt` seconds.
    pub fn new(inlet: &Inlet<R>, dt: R) -> Self {
        let cycles = |s: R| -> u32 {
            let c = (s / dt).round_i64();
            c.clamp(0, u32::MAX as i64) as u32
        };
        LineParams {
            supply: inlet.supply_pa,
            open_delay: cycles(inlet.open_delay_s),
            close_delay: cycles(inlet.close_delay_s),
            tau_rise: inlet.rise_s,
            tau_decay: inlet.decay_s,
            alpha_rise: alpha(dt, inlet.rise_s),
            alpha_decay: alpha(dt, inlet.decay_s),
            drives: [(R::ZERO, R::ZERO, R::ZERO); 2],
        }
        .with_drives()
    }

    /// These constants with `drive`'s table filled in from them.
    pub fn with_drives(mut self) -> Self {
        self.drives = [
            (R::ZERO, self.tau_decay, self.alpha_decay),
            (self.supply, self.tau_rise, self.alpha_rise),
        ];
        self
    }

    /// (target, tau, alpha) for a valve state.
    #[inline]
    pub fn drive(&self, open: bool) -> (R, R, R) {
        self.drives[open as usize]
    }
}

/// `1 - exp(-dt/tau)`, 1 for an instant line.
pub fn alpha<R: Real>(dt: R, tau: R) -> R {
    if tau <= R::ZERO {
        R::ONE
    } else {
        R::ONE - (-(dt / tau)).exp()
    }
}

/// The state of one line.
#[derive(Clone, Debug)]
pub struct Line<R> {
    /// Line pressure, Pa.
    pub p: R,
    /// Valve state as it acts on the paste (after dead time).
    pub open: bool,
    /// Valve state last commanded.
    pub commanded: bool,
    /// Pending changes: (cycle index at which it acts, new state), in acting order.
    pub pending: Deque<(u64, bool), PENDING_CAP>,
}

impl<R: Real> Default for Line<R> {
    fn default() -> Self {
        Line {
            p: R::ZERO,
            open: false,
            commanded: false,
            pending: Deque::new(),
        }
    }
}

impl<R: Real> Line<R> {
    /// Records a command given before cycle `next` starts; it acts at `next + delay`.
    pub fn command(&mut self, open: bool, next: u64, params: &LineParams<R>) {
        if open == self.commanded {
            return;
        }
        self.commanded = open;
        let at = next
            + if open {
                params.open_delay
            } else {
                params.close_delay
            } as u64;
        // A later command that acts sooner supersedes changes still queued after it.
        while let Some(&(t, _)) = self.pending.back() {
            if t >= at {
                self.pending.pop_back();
            } else {
                break;
            }
        }
        if self.pending.is_full() {
            self.pending.pop_front();
        }
        let _ = self.pending.push_back((at, open));
    }

    /// Applies changes that act at or before cycle `k`.
    #[inline]
    pub fn apply_due(&mut self, k: u64) {
        while let Some(&(t, open)) = self.pending.front() {
            if t <= k {
                self.open = open;
                self.pending.pop_front();
            } else {
                break;
            }
        }
    }

    /// Advances one cycle of `dt`; returns the pressure impulse (integral of p, Pa s).
    #[inline]
    pub fn step(&mut self, dt: R, params: &LineParams<R>) -> R {
        let (g, tau, a) = params.drive(self.open);
        let gap = self.p - g;
        let impulse = g * dt + gap * tau * a;
        self.p = g + gap * (R::ONE - a);
        impulse
    }

    /// Pressure just after the changes of the current cycle acted: an instant line jumps.
    #[inline]
    pub fn p_now(&self, params: &LineParams<R>) -> R {
        let (g, tau, _) = params.drive(self.open);
        if tau <= R::ZERO {
            g
        } else {
            self.p
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(delay: u32, tau: f64) -> LineParams<f64> {
        let dt = 1e-4;
        LineParams {
            supply: 1000.0,
            open_delay: delay,
            close_delay: delay,
            tau_rise: tau,
            tau_decay: tau,
            alpha_rise: alpha(dt, tau),
            alpha_decay: alpha(dt, tau),
            drives: [(0.0, 0.0, 0.0); 2],
        }
        .with_drives()
    }

    #[test]
    fn rise_matches_the_exponential_and_its_integral() {
        let p = params(0, 0.03);
        let mut l = Line::<f64>::default();
        l.command(true, 0, &p);
        let mut imp = 0.0;
        for k in 0..500u64 {
            l.apply_due(k);
            imp += l.step(1e-4, &p);
        }
        let t: f64 = 0.05;
        let expect_p = 1000.0 * (1.0 - (-t / 0.03).exp());
        let expect_imp = 1000.0 * (t - 0.03 * (1.0 - (-t / 0.03).exp()));
        assert!((l.p - expect_p).abs() < 1e-9, "{} {}", l.p, expect_p);
        assert!((imp - expect_imp).abs() < 1e-9, "{imp} {expect_imp}");
    }

    #[test]
    fn dead_time_holds_the_old_state_for_whole_cycles() {
        let p = params(100, 0.0);
        let mut l = Line::<f64>::default();
        l.command(true, 10, &p);
        for k in 10..110u64 {
            l.apply_due(k);
            assert_eq!(l.step(1e-4, &p), 0.0, "cycle {k}");
        }
        l.apply_due(110);
        assert!((l.step(1e-4, &p) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_sooner_acting_command_supersedes() {
        let mut p = params(0, 0.0);
        p.open_delay = 50;
        p.close_delay = 5;
        let mut l = Line::<f64>::default();
        l.command(true, 0, &p); // acts at 50
        l.command(false, 1, &p); // acts at 6: the open never happens
        assert_eq!(l.pending.len(), 1);
        for k in 0..100 {
            l.apply_due(k);
            assert!(!l.open);
        }
    }
}
