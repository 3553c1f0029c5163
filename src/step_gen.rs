//! Step generation: the planned position each cycle becomes whole microsteps per axis,
//! rounded, so the commanded position is always within half a step of the plan. It refuses
//! (rather than emits) more steps in one cycle than the drivers' maximum rate allows.
//! Pulse timing inside the cycle is the firmware's.

use crate::outputs::{Axis, Outputs};
use crate::real::Real;

/// A cycle needed more steps than the rate limit allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepRateExceeded {
    /// The axis.
    pub axis: Axis,
    /// Steps the cycle needed.
    pub steps: u32,
    /// Steps a cycle may have.
    pub max: u32,
}

/// Turns positions into step pulses for X, Y, Z.
#[derive(Clone, Debug)]
pub struct StepGen<R> {
    steps_per_mm: [R; 3],
    max_per_cycle: u32,
    position: [i64; 3],
    /// The Z position (mm) the Z steps were last computed for (NaN before any).
    last_z: R,
}

impl<R: Real> StepGen<R> {
    /// A generator of no machine (all zero); `new` makes a working one.
    pub const fn idle() -> Self {
        StepGen {
            steps_per_mm: [R::ZERO; 3],
            max_per_cycle: 0,
            position: [0; 3],
            last_z: R::ZERO,
        }
    }

    /// A generator whose axes stand at `position` steps.
    pub const fn new(steps_per_mm: [R; 3], max_per_cycle: u32, position: [i64; 3]) -> Self {
        StepGen {
            steps_per_mm,
            max_per_cycle,
            position,
            last_z: R::NAN,
        }
    }

    /// Current position, steps.
    pub fn position(&self) -> [i64; 3] {
        self.position
    }

    /// Current position, mm.
    pub fn position_mm(&self) -> [R; 3] {
        let mut p = [R::ZERO; 3];
        for (a, v) in p.iter_mut().enumerate() {
            *v = R::from_i64(self.position[a]) / self.steps_per_mm[a];
        }
        p
    }

    /// The step position nearest `mm` on each axis.
    pub fn target(&self, mm: [R; 3]) -> [i64; 3] {
        let mut t = [0i64; 3];
        for (a, v) in t.iter_mut().enumerate() {
            *v = (mm[a] * self.steps_per_mm[a]).round_i64();
        }
        t
    }

    /// Checks that reaching `mm` within `cycles` cycles stays within the rate limit,
    /// without stepping.
    pub fn check(&self, mm: [R; 3], cycles: u32) -> Result<[i64; 3], StepRateExceeded> {
        let t = self.target(mm);
        let max = self.max_per_cycle.saturating_mul(cycles.max(1));
        for (a, axis) in Axis::ALL.iter().enumerate() {
            let d = (t[a] - self.position[a]).unsigned_abs();
            if d > max as u64 {
                return Err(StepRateExceeded {
                    axis: *axis,
                    steps: d.min(u32::MAX as u64) as u32,
                    max,
                });
            }
        }
        Ok(t)
    }

    /// Steps to the position nearest `mm` over one cycle, or refuses without stepping.
    pub fn move_to(&mut self, mm: [R; 3], out: &mut impl Outputs) -> Result<(), StepRateExceeded> {
        self.move_over(mm, 1, out)
    }

    /// Steps to the position nearest `mm` over `cycles` cycles (a late tick catching up),
    /// or refuses without stepping any axis. The per-cycle path: one pass computes and
    /// checks every axis before any steps (no `target`/`check` round trip through arrays).
    pub fn move_over(
        &mut self,
        mm: [R; 3],
        cycles: u32,
        out: &mut impl Outputs,
    ) -> Result<(), StepRateExceeded> {
        let max = self.max_per_cycle.saturating_mul(cycles.max(1)) as u64;
        // Step positions fit i32 (2^31 microsteps is kilometres), so the narrow rounding;
        // a planned position beyond it saturates into a step-rate fault. Z stands still
        // between layers: skip its conversion while its position does.
        let dz = if mm[2] == self.last_z {
            0
        } else {
            (mm[2] * self.steps_per_mm[2]).round_i32() as i64 - self.position[2]
        };
        let d = [
            (mm[0] * self.steps_per_mm[0]).round_i32() as i64 - self.position[0],
            (mm[1] * self.steps_per_mm[1]).round_i32() as i64 - self.position[1],
            dz,
        ];
        // Axis by axis, not in a loop: the three axes' checks and steps in line (a loop
        // of three is not unrolled at opt-level "s").
        if d[0].unsigned_abs() > max || d[1].unsigned_abs() > max || d[2].unsigned_abs() > max {
            return Err(rate_exceeded(d, max));
        }
        self.step_axis(0, d[0], out);
        self.step_axis(1, d[1], out);
        self.step_axis(2, d[2], out);
        self.last_z = mm[2];
        Ok(())
    }

    /// Axis `a`'s `d` steps, if any.
    #[inline(always)]
    fn step_axis(&mut self, a: usize, d: i64, out: &mut impl Outputs) {
        if d != 0 {
            out.step(Axis::ALL[a], d > 0, d.unsigned_abs() as u32);
            self.position[a] += d;
        }
    }
}

/// The first axis whose `d` steps exceed `max` (`move_over`'s refusal; out of line).
#[cold]
#[inline(never)]
fn rate_exceeded(d: [i64; 3], max: u64) -> StepRateExceeded {
    let a = d.iter().position(|x| x.unsigned_abs() > max).unwrap_or(0);
    StepRateExceeded {
        axis: Axis::ALL[a],
        steps: d[a].unsigned_abs().min(u32::MAX as u64) as u32,
        max: max as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outputs::RecordingOutputs;

    #[test]
    fn long_move_gives_exact_step_count_and_tracks_within_half_a_step() {
        let spm = 80.0f32;
        let mut g = StepGen::new([spm, spm, 400.0], 5, [0; 3]);
        let mut out = RecordingOutputs::default();
        // 150 mm at 40 mm/s, 10 kHz: 37 500 cycles.
        let n = 37_500;
        for i in 1..=n {
            let x = 150.0f64 * i as f64 / n as f64;
            g.move_to([x as f32, 0.0, 0.0], &mut out).unwrap();
            let err = out.position[0] as f64 / spm as f64 - x;
            assert!(err.abs() <= 0.5 / spm as f64 + 1e-5, "cycle {i}: {err}");
        }
        assert_eq!(out.position[0], 12_000);
        assert_eq!(out.pulses[0], 12_000);
        assert_eq!(out.reversals[0], 0);
    }

    #[test]
    fn reversals_lose_no_steps() {
        let mut g = StepGen::new([100.0f64, 100.0, 100.0], 10, [0; 3]);
        let mut out = RecordingOutputs::default();
        let mut x = 0.0;
        for i in 0..200_000u32 {
            // A triangle wave of 3 mm amplitude, 0.003 mm per cycle.
            let phase = (i % 2000) as f64;
            x = if phase < 1000.0 {
                phase * 0.003
            } else {
                (2000.0 - phase) * 0.003
            };
            g.move_to([x, -x, 0.0], &mut out).unwrap();
        }
        assert_eq!(out.position[0], (x * 100.0f64).round() as i64);
        assert_eq!(out.position[1], -out.position[0]);
        // 100 full periods, 300 steps each way.
        assert_eq!(out.pulses[0], 100 * 600);
        assert_eq!(out.reversals[0], 2 * 100 - 1);
    }

    #[test]
    fn too_fast_is_refused_without_stepping() {
        let mut g = StepGen::new([80.0f32, 80.0, 400.0], 5, [0; 3]);
        let mut out = RecordingOutputs::default();
        let e = g.move_to([0.05, 0.1, 0.0], &mut out).unwrap_err();
        assert_eq!(e.axis, Axis::Y);
        assert_eq!(e.steps, 8);
        assert_eq!(out.pulses[..3], [0, 0, 0]);
    }
}
