//! Flow through a channel of mixed slugs: solves `sum_m V_m (a_m Q^n_m + b_m) = P` for Q.
//! Linear (Newtonian) content has a closed form; otherwise a bracketed Newton solve.

use crate::real::Real;
use crate::rheology::FlowLaw;

/// Newton iterations at most per solve. From a warm start (last cycle's flow) the solve
/// takes one or two; from cold, under ten. The bound only stops a pathological case.
pub const MAX_ITERATIONS: u32 = 30;

/// Relative error at which the full solve stops: 64 machine epsilons (7.6e-6 in f32,
/// 1.4e-14 in f64).
pub fn tolerance<R: Real>() -> R {
    R::EPSILON * R::of(64.0)
}

/// Flow (mm^3/s) through channel content `vin` (mm^3 of each material) at pressure `p`
/// (Pa). `guess` is a warm start (0 for none). Zero pressure or pressure below the total
/// yield term gives zero flow. With all laws shear-thinning or Newtonian (n <= 1, as
/// config validation enforces) the residual is increasing and concave in Q, so Newton
/// steps from below the root stay below it and converge monotonically; a step that leaves
/// the bracket is replaced by bisection.
pub fn flow<R: Real>(laws: &[FlowLaw<R>], vin: &[R], p: R, guess: R) -> R {
    flow_within(laws, vin, p, guess, tolerance::<R>(), MAX_ITERATIONS)
}

/// One Newton step of the flow solve from `q`: the form the control cycle and the
/// look-ahead use, whose starts are close enough to the root that one step does.
///
/// The per-cycle solve starts on the line through the last two cycles' answers; from
/// there one step nearly always reaches 1e-5 relative (with three steps allowed, 1 286 of
/// the power-law bench job's 147 845 solves took a second). Where it cannot, after a jump
/// in pressure or the first cycles of a flow starting from rest, the error still squares
/// from one cycle to the next (at most half its square: a 50 % jump leaves 12 %, 0.8 %,
/// 3e-5), and those few cycles move the head by well under a micrometre more or less
/// than the paste; the whole-job tests hold the bead section to 1 % through every switch
/// and start. The look-ahead starts each chunk from the last chunk's flow scaled by the
/// pressure ratio as the feeding paste's power law scales it, exact for content of one
/// paste; for mixed content one step leaves about (1 - n)/2 of the square of that
/// guess's error, a few parts in a thousand of the chunk's volume.
///
/// The residual is increasing and concave, so a step never lands above the root; one
/// that lands at or below zero (a start far above the root) is replaced by half the
/// start, as the bracketed solve would. Zero pressure, or pressure within the yield
/// terms, gives zero; a start of zero or less (nothing flowed yet) starts cold. This is
/// `flow_within` with one iteration, without its bracket bookkeeping.
pub fn flow_step<R: Real>(laws: &[FlowLaw<R>], vin: &[R], p: R, q: R) -> R {
    if !(q > R::ZERO && q.is_finite()) {
        return flow_within(laws, vin, p, q, tolerance::<R>(), 1);
    }
    let d = drops(laws, vin, q);
    // Below the yield terms (or with an empty channel) nothing flows.
    let target = p - d.yield_sum;
    if !d.any || target <= R::ZERO {
        return R::ZERO;
    }
    let g = d.sum - target;
    // dg = sum_n / q: the step is q (1 - g / sum_n).
    let newton = if d.sum_n > R::ZERO {
        q - g * q / d.sum_n
    } else {
        q * R::TWO
    };
    if newton > R::ZERO && newton.is_finite() {
        newton
    } else if g > R::ZERO {
        q * R::HALF
    } else {
        q * R::TWO
    }
}

/// `flow` with a given relative tolerance and iteration bound. `tol` bounds the relative
/// error of the answer: a Newton step `s` from `q` leaves an error of about
/// `|g''| / (2 g') s^2`, and for terms `V a Q^n` (n in (0, 1]) plus linear and yield terms
/// `|g''| / g' <= (1 - n) / Q <= 1 / Q`, so the step's answer is within `(s/Q)^2 / 2` of
/// the root and the solve stops once `(s/Q)^2 <= 2 tol`. From a warm start one step
/// usually suffices.
pub fn flow_within<R: Real>(
    laws: &[FlowLaw<R>],
    vin: &[R],
    p: R,
    guess: R,
    tol: R,
    max_iterations: u32,
) -> R {
    let (yield_sum, lin, nonlinear) = content_terms(laws, vin);
    let target = p - yield_sum;
    if target <= R::ZERO {
        return R::ZERO;
    }
    if !nonlinear {
        return if lin > R::ZERO { target / lin } else { R::ZERO };
    }
    let mut lo = R::ZERO;
    let mut hi: Option<R> = None;
    let mut q = if guess > R::ZERO && guess.is_finite() {
        guess
    } else {
        cold_guess(laws, vin, target)
    };
    // Every material's own closed form underflowed: the flow is below the float's range
    // (a vented line's subnormal residue of pressure). Iterating from the fallback start
    // instead gave half of 1 mm^3/s after one step, which is what made predictions after
    // a long pause or a long idle start from a phantom flow.
    if q <= R::ZERO {
        return R::ZERO;
    }
    let two_tol = tol * R::TWO;
    for _ in 0..max_iterations {
        let d = drops(laws, vin, q);
        let g = d.sum - target;
        let dg = d.sum_n / q;
        if g > R::ZERO {
            hi = Some(match hi {
                Some(h) if h < q => h,
                _ => q,
            });
        } else {
            lo = lo.max(q);
        }
        let newton = if dg > R::ZERO { q - g / dg } else { q * R::TWO };
        // Converged: the error left after this step is below the tolerance (checked
        // before the bracket, which a step this small may touch without leaving).
        let step = newton - q;
        if newton.is_finite() && step * step <= two_tol * newton * newton {
            return newton;
        }
        let inside = newton > lo && hi.is_none_or(|h| newton < h);
        let next = if inside && newton.is_finite() {
            newton
        } else {
            match hi {
                Some(h) => (lo + h) * R::HALF,
                None => q * R::TWO,
            }
        };
        q = next;
    }
    q
}

/// The content's pressure drop at flow `q > 0`, in the parts the solves need.
struct Drops<R> {
    /// `sum V a q^n` (`V a q` for linear content): the flow-dependent drop.
    sum: R,
    /// `sum n V a q^n`: q times the drop's derivative.
    sum_n: R,
    /// `sum V b`: the yield terms.
    yield_sum: R,
    /// Any content at all.
    any: bool,
}

/// `Drops` of content `vin` at flow `q > 0`; one logarithm serves every paste's power.
#[inline]
fn drops<R: Real>(laws: &[FlowLaw<R>], vin: &[R], q: R) -> Drops<R> {
    let log_q = q.log2_fast();
    let mut d = Drops {
        sum: R::ZERO,
        sum_n: R::ZERO,
        yield_sum: R::ZERO,
        any: false,
    };
    for (law, &v) in laws.iter().zip(vin) {
        if v > R::ZERO {
            d.any = true;
            d.yield_sum += v * law.b;
            let t = if law.linear {
                v * law.a * q
            } else {
                v * law.a * (law.n * log_q).exp2_fast()
            };
            d.sum += t;
            d.sum_n += law.n * t;
        }
    }
    d
}

/// What the channel's content adds up to: the yield terms' sum, the linear (Newtonian)
/// resistances' sum, and whether any non-linear paste is in it. Inlined: it sits on the
/// per-cycle path of `flow_within`.
#[inline(always)]
fn content_terms<R: Real>(laws: &[FlowLaw<R>], vin: &[R]) -> (R, R, bool) {
    let mut yield_sum = R::ZERO;
    let mut lin = R::ZERO;
    let mut nonlinear = false;
    for (law, &v) in laws.iter().zip(vin) {
        if v > R::ZERO {
            yield_sum += v * law.b;
            if law.linear {
                lin += v * law.a;
            } else {
                nonlinear = true;
            }
        }
    }
    (yield_sum, lin, nonlinear)
}

/// A start for `flow_step` with nothing to warm-start from: the content's own closed
/// forms at pressure `p` (see `cold_guess`); zero where nothing flows (pressure within
/// the yield terms, no content, or a flow below the float's range). The look-ahead works
/// this out as a unit of its own, so that no control cycle carries it and a Newton step.
pub fn cold_start<R: Real>(laws: &[FlowLaw<R>], vin: &[R], p: R) -> R {
    let (yield_sum, lin, nonlinear) = content_terms(laws, vin);
    let target = p - yield_sum;
    if target <= R::ZERO {
        R::ZERO
    } else if !nonlinear {
        if lin > R::ZERO {
            target / lin
        } else {
            R::ZERO
        }
    } else {
        cold_guess(laws, vin, target)
    }
}

/// A start for a cold solve: each material's own closed form for the whole channel,
/// weighted by its share of the volume. Zero when every closed form underflows (the
/// content's flow lies between the smallest and largest of them); 1 mm^3/s when there is
/// no content or a closed form overflows.
fn cold_guess<R: Real>(laws: &[FlowLaw<R>], vin: &[R], target: R) -> R {
    let mut total = R::ZERO;
    for &v in vin {
        total += v;
    }
    if total <= R::ZERO {
        return R::ONE;
    }
    let mut q = R::ZERO;
    for (law, &v) in laws.iter().zip(vin) {
        if v > R::ZERO {
            let full = (target / (total * law.a)).pow_fast(R::ONE / law.n);
            q += full * (v / total);
        }
    }
    if q.is_finite() {
        q
    } else {
        R::ONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rheology::Rheology;

    fn laws() -> [FlowLaw<f64>; 3] {
        [
            FlowLaw::new(
                &Rheology::Newtonian {
                    viscosity_pa_s: 1.41,
                },
                0.8,
            ),
            FlowLaw::new(
                &Rheology::PowerLaw {
                    consistency_pa_sn: 20.0,
                    flow_index: 0.45,
                },
                0.8,
            ),
            FlowLaw::new(
                &Rheology::HerschelBulkley {
                    yield_stress_pa: 30.0,
                    consistency_pa_sn: 8.0,
                    flow_index: 0.6,
                },
                0.8,
            ),
        ]
    }

    fn residual(l: &[FlowLaw<f64>], v: &[f64], q: f64) -> f64 {
        l.iter().zip(v).map(|(l, v)| v * l.drop_per_volume(q)).sum()
    }

    #[test]
    fn mixed_content_solves_to_the_pressure() {
        let l = laws();
        for v in [
            [0.4, 0.4, 0.4],
            [1.2, 0.0, 0.0],
            [0.0, 1.2, 0.0],
            [0.1, 0.0, 1.1],
        ] {
            for p in [500.0, 3000.0, 20000.0] {
                let q = flow(&l, &v, p, 0.0);
                let back = residual(&l, &v, q);
                assert!((back - p).abs() / p < 1e-10, "{v:?} {p}: {back}");
                // Warm start from far away converges to the same root.
                let q2 = flow(&l, &v, p, q * 7.0);
                assert!((q2 - q).abs() / q < 1e-10);
            }
        }
    }

    #[test]
    fn one_step_from_near_the_root_is_within_half_the_squared_step() {
        // The stopping rule's bound: a Newton step s from q leaves the answer within
        // (s/Q)^2 / 2 of the root, relative, for mixed power-law and yield content.
        let l = laws();
        for v in [
            [0.4, 0.4, 0.4],
            [0.0, 1.2, 0.0],
            [0.1, 0.0, 1.1],
            [0.6, 0.6, 0.0],
        ] {
            for p in [500.0, 3000.0, 20000.0] {
                let root = flow(&l, &v, p, 0.0);
                for off in [-0.2, -0.05, -3e-3, 1e-3, 0.04, 0.3] {
                    let q = root * (1.0 + off);
                    let one = flow_step(&l, &v, p, q);
                    let within = flow_within(&l, &v, p, q, 1e-30, 1);
                    assert!((one - within).abs() <= 1e-12 * root, "{one} {within}");
                    let s = (one - q) / one;
                    let err = ((one - root) / root).abs();
                    assert!(
                        err <= s * s / 2.0 * 1.01 + 1e-14,
                        "{v:?} {p} {off}: {err:e} {s:e}"
                    );
                }
            }
        }
    }

    #[test]
    fn zero_pressure_and_yield_give_zero_flow() {
        let l = laws();
        assert_eq!(flow(&l, &[0.4, 0.4, 0.4], 0.0, 1.0), 0.0);
        let below_yield = 0.5 * 1.2 * l[2].b;
        assert_eq!(flow(&l, &[0.0, 0.0, 1.2], below_yield, 0.0), 0.0);
    }

    #[test]
    fn f32_solve_agrees_with_f64() {
        let l64 = laws();
        let l32: [FlowLaw<f32>; 3] = [
            FlowLaw::new(
                &Rheology::Newtonian {
                    viscosity_pa_s: 1.41,
                },
                0.8,
            ),
            FlowLaw::new(
                &Rheology::PowerLaw {
                    consistency_pa_sn: 20.0,
                    flow_index: 0.45,
                },
                0.8,
            ),
            FlowLaw::new(
                &Rheology::HerschelBulkley {
                    yield_stress_pa: 30.0,
                    consistency_pa_sn: 8.0,
                    flow_index: 0.6,
                },
                0.8,
            ),
        ];
        let q64 = flow(&l64, &[0.3, 0.5, 0.4], 5000.0, 0.0);
        let q32 = flow(&l32, &[0.3f32, 0.5, 0.4], 5000.0, 0.0) as f64;
        assert!((q32 - q64).abs() / q64 < 2e-5, "{q32} {q64}");
    }
}
